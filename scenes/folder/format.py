"""The object folder `<name>.data/`: its file names, its scene.json and the lookup of predictions; the one module
that knows its layout.

Everything that reads or writes an object folder goes through `scenes.folder`: `wildgen` writes it, `unips` loads it
for the model, `validate` loads it for the re-render check, `wildgen.preview` shows it, the tests build
synthetic ones. Plain NumPy / OpenCV / OpenEXR (no Mitsuba). Layout (see ARCHITECTURE.md):

- `L000.png ... L{K-1}.png`: 16-bit linear RGB, `round(clip(radiance * exposure, 0, 1) * 65535)`;
- `mask.png`: 8-bit gray, 255 inside the object, 0 outside. Read by `scenes.images.read_mask`: binary, 0 and one
  other value (foreground), from the alpha where it is not fully opaque, else the largest colour channel;
- `normal.tif`: 16-bit RGB `round((n + 1) / 2 * 65535)`, camera frame x right, y up, z toward the camera;
  background n = 0 is 32768 in every channel;
- `scene.json`: the `SceneDescription` JSON plus extra top-level keys (`camera_lights`, `format_version`,
  `sensor`), split apart only by `split_scene_extras`;
- `aux/`: float EXR ground truth, the mesh and textures used.

Predictions (what `unips.predict` writes, what `unips.evaluate` and `validate.rerender` read) are
`PRED/<object>/normal.<ext>`, looked up in the order of `PREDICTION_FILES`: the lossless float EXR first,
then the 16-bit PNG, then `.npy` and TIFF. `<object>` is `object_name(folder)`. The pixel files themselves
are `scenes.images`.
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from scenes.files import atomic_write_text, json_text, read_json, reading_record, write_json
from scenes.images import write_mask, write_normal_map, write_png16

OBJECT_SUFFIX = ".data"

SCENE_FILE = "scene.json"
DILIGENT_LIGHTS = "light_directions.txt"
DILIGENT_INTENSITIES = "light_intensities.txt"
"""DiLiGenT's light files: unit directions toward the light, and RGB intensities, one row per image."""

MASK_FILE = "mask.png"

NORMAL_FILE = "normal.tif"

NORMAL_BASE_FILE = "normal_base.tif"
"""Normals of the geometry without its normal-mapped detail (objects with a normal map only); normal.tif holds
the shading normals the camera sees, detail included: what methods are scored on."""

AUX_DIR = "aux"

MESH_FILE = "mesh.ply"
"""In aux/: the object's mesh (a cluster's objects merged), as the generator writes it for re-rendering."""

INSTANCES_FILE = "instances.png"
"""In aux/ of a cluster: the 16-bit id of the object seen at each pixel centre (part i of scene.json `parts` is
i + 1; 0 is the background)."""

FORMAT_VERSION = 1
"""Written into scene.json as `format_version`."""

PREDICTION_FILES = ("normal.exr", "normal.png", "normal.npy", "normal.tif", "normal.tiff")
"""File names of a prediction folder, in lookup order (lossless float first)."""

PREDICTION_INFO = "predict.json"
"""What `unips.predict` records beside a prediction (method, model, images used)."""

EXPECTED_ERROR_FILES = ("expected_error_deg.npy", "expected_error_deg.exr", "expected_error.png")
"""A prediction's expected angular error (`unips.expected_error`): float32 (H, W) degrees, NaN outside the mask, as
NumPy and EXR arrays, and a picture; PREDICTION_INFO's `expected_error_deg` holds its mean and 80 % interval."""


def stated_error(record) -> dict | None:
    """PREDICTION_INFO's `expected_error_deg` read back: {"mean": m, "interval_80": [lo, hi]} of finite numbers, 0 <=
    lo <= hi <= 180 and m within [0, 180] (angles), as `unips.expected_error.Stated.summary` writes it; None for
    anything else (an edited record, or one of another kind, states nothing)."""
    import math

    if not isinstance(record, dict):
        return None
    mean, interval = record.get("mean"), record.get("interval_80")
    numbers = [mean, *interval] if isinstance(interval, list) and len(interval) == 2 else []
    if not numbers or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                              for v in numbers) or not 0 <= interval[0] <= interval[1] <= 180 or not 0 <= mean <= 180:
        return None
    return {**record, "mean": float(mean), "interval_80": [float(interval[0]), float(interval[1])]}


DATASET_MANIFEST = "manifest.json"
OBJECT_FOLDER = re.compile(r"^\d{5,}\.data$")
"""The names of the object folders wildgen writes (`wildgen.writer.index_name` + .data)."""
MANIFEST_VERSION = 1
"""`format_version` of the manifest.json wildgen.make and wildgen.sensor write."""


def manifest_problem(record: object) -> str | None:
    """Why a dataset's manifest.json as read is not one this toolkit can act on (None when it is, or when it is no
    manifest of ours at all: a JSON object without `objects`): its objects not a list, or a format_version that is
    not ours (a newer toolkit's, whose records this one would rewrite in its own)."""
    if not isinstance(record, dict) or "objects" not in record:
        return None
    if not isinstance(record["objects"], list):
        return f"its objects are {type(record['objects']).__name__}, expected a list of the objects' records"
    version = record.get("format_version", MANIFEST_VERSION)
    if version != MANIFEST_VERSION or isinstance(version, bool):
        return (f"its format_version is {version!r:.40}, expected {MANIFEST_VERSION} (written by another version of "
                "the toolkit: use that one)")
    config = record.get("config")
    count = config.get("objects") if isinstance(config, dict) else None
    if count is not None and not _whole(count):
        return f"its config records objects {count!r:.40}, expected a whole number"
    seen: set[int] = set()
    for e in record["objects"]:  # (a record that is no JSON object is said by the reader, with its place)
        if not isinstance(e, dict) or "index" not in e:
            continue
        index = e["index"]
        if not _whole(index) or (count is not None and index >= count):
            below = f" below its config's {count} objects" if count is not None else ""
            return f"an object's record has index {index!r:.40}, expected a whole number{below}"
        if index in seen:
            return f"it has two records for object {index}"
        seen.add(index)
    return None


def _whole(value: object) -> bool:
    """A count or an index as a manifest records it: an int from 0 up (not a bool, nor 1.0)."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 2**62
"""A dataset folder's record of the run that wrote it (wildgen.make, wildgen.sensor). `complete: false` while a
run writes it (true at its end): the object folders of a run stopped half-way are never read as a dataset."""

_IMAGE_RE = re.compile(r"^L(\d+)\.png$", re.IGNORECASE)  # a copy from a case-blind disk may say L000.PNG


def image_name(index: int) -> str:
    """File name of input image `index` (L000.png ...)."""
    return f"L{index:03d}.png"


def radiance_name(index: int) -> str:
    """File name, inside `AUX_DIR`, of the float radiance of image `index` before its exposure."""
    return f"radiance_{index:03d}.exr"


def object_name(path: str | Path) -> str:
    """Name of an object folder: its name minus a trailing `.data` (`foo.data` -> `foo`, `ballPNG` stays). The name
    it is given, not that of a folder a link leads to (`00002.data`, a link to another dataset's `00001.data`, is
    00002); `.` and `..` are the folders they stand for."""
    name = Path(os.path.abspath(path)).name
    stem = name[: -len(OBJECT_SUFFIX)] if name.endswith(OBJECT_SUFFIX) and len(name) > len(OBJECT_SUFFIX) else name
    return name if stem in (".", "..") else stem  # '...data' would name '..', a folder above the outputs


def image_files(folder: str | Path) -> list[Path]:
    """The `L<i>.png` images of an object folder in index order; ValueError when indices have gaps."""
    folder = Path(folder)
    found = {}
    for p in folder.iterdir():
        m = _IMAGE_RE.match(p.name)
        if m and (twin := found.setdefault(int(m.group(1)), p)) is not p:  # L000.png and L000.PNG, or L0 and L000
            raise ValueError(f"images: {str(folder)!r} has two files for image {int(m.group(1))}: {twin.name!r} and "
                             f"{p.name!r}; keep one")
    indices = sorted(found)
    if indices != list(range(len(indices))):
        missing = sorted(set(range(max(indices, default=-1) + 1)) - set(indices))
        raise ValueError(
            f"images: {str(folder)!r} has L*.png files with gaps (missing indices {', '.join(map(str, missing[:10]))})"
        )
    return [found[i] for i in indices]


def check_dataset_complete(dataset: str | Path, arg: str = "--data") -> None:
    """ValueError naming `arg` when the manifest of dataset folder `dataset` says a run still writes it or was
    stopped before its end (`complete: false`); a folder without such a record is taken as it is."""
    path = Path(dataset) / DATASET_MANIFEST
    try:
        complete = read_json(path).get("complete", True)
    except (OSError, ValueError, AttributeError):
        return
    if not isinstance(complete, bool):  # 'false' (text) is no answer: never read as a complete dataset
        raise ValueError(f"{arg}: {str(path)!r} records complete {complete!r:.40}, expected true or false (the "
                         "manifest wildgen.make writes); restore it, or run the command that wrote the dataset again")
    if complete is False:
        raise ValueError(f"{arg}: {str(dataset)!r} is an incomplete dataset ({DATASET_MANIFEST} says complete: "
                         "false: the command that writes it is still running or was stopped before its end); run it "
                         "again to finish the dataset, or pass a complete one")
    try:
        gone = sorted(n for n, status in _statuses(Path(dataset)).items() if status == "done"
                      and OBJECT_FOLDER.match(n)  # the names wildgen writes; odd ones: their own check
                      and not os.path.lexists(Path(dataset) / n))
    except ValueError:  # an unreadable manifest: said where the objects' statuses are read
        return
    if gone:  # a copy that lost objects would be read, and scored, as a smaller dataset
        more = f" (and {len(gone) - 1} more)" if len(gone) > 1 else ""
        raise ValueError(f"{arg}: {str(dataset)!r} lacks {gone[0]}{more}, which its {DATASET_MANIFEST} lists as "
                         "rendered ('done'); restore it (copy the dataset again), or pass a complete one")


def check_listed_done(folder: Path, arg: str) -> None:
    """ValueError naming `arg` when the manifest of the dataset holding object folder `folder` lists it with another
    status than 'done' (a render that failed or was skipped writes no folder: one there under its name is not the
    render's, and would be read as if it were). A folder the manifest does not list, or no manifest, passes; a
    manifest that cannot be read is refused beside folders named as ours (<name>.data), passed beside others."""
    try:
        status = _statuses(folder.parent).get(folder.name)
    except ValueError:
        if folder.name.endswith(OBJECT_SUFFIX):
            raise
        status = None  # another program's manifest.json beside the user's own folder
    if status not in (None, "done"):
        raise ValueError(f"{arg}: {str(folder)!r} is listed as {status!r} in {DATASET_MANIFEST} of its dataset (a "
                         "render that failed writes no folder; this one is not the render's): move it away, or render "
                         "the object again with wildgen.make")


def entry_folder(entry: dict) -> str:
    """The object folder a manifest entry names (its `folder`, else its name's)."""
    return str(entry.get("folder", f"{entry.get('name', '?')}.data"))


def _statuses(dataset: Path) -> dict[str, str]:
    """{object folder name: status} of a dataset's manifest ({} without one), read once per version of the file."""
    path = dataset / DATASET_MANIFEST
    try:
        st = os.stat(path)
    except OSError:
        return {}
    key = (str(path), st.st_mtime_ns, st.st_size)
    if key not in _STATUSES:
        # a manifest that cannot be read is said, never taken for none (its failed objects would pass as good)
        with reading_record(path, "a dataset's manifest", "restore it, or move it away to read the objects without "
                            "it"):
            record = read_json(path)
        if (problem := manifest_problem(record)) is not None:  # (another shape: not a manifest of ours, passed)
            raise ValueError(f"{str(path)!r} is not a manifest this toolkit can read: {problem}")
        entries = record.get("objects") if isinstance(record, dict) else None
        found = {os.path.normpath(entry_folder(e)): str(e["status"])
                 for e in (entries if isinstance(entries, list) else []) if isinstance(e, dict)
                 and e.get("status") is not None}  # './00001.data' is the folder 00001.data
        _STATUSES.clear()  # one dataset at a time: a long run over many never holds them all
        _STATUSES[key] = found
    return _STATUSES[key]


_STATUSES: dict[tuple[str, int, int], dict[str, str]] = {}


def list_object_folders(dataset: str | Path) -> list[Path]:
    """Object folders (`*.data` with a scene.json) of a complete dataset folder, sorted by name."""
    dataset = Path(dataset)
    check_dataset_complete(dataset)
    folders = sorted(p for p in dataset.iterdir()
                     if p.is_dir() and p.name.endswith(OBJECT_SUFFIX) and not p.name.startswith("."))
    if not folders and (dataset / SCENE_FILE).is_file():  # one object folder given for the dataset around it
        raise FileNotFoundError(f"--data: {str(dataset)!r} is one object folder; expected the dataset folder that "
                                f"holds such folders (here {str(dataset.parent)!r})")
    if not folders:
        raise FileNotFoundError(f"--data: {str(dataset)!r} has no scene.json and no *.data object folders")
    for f in folders:
        if not (f / SCENE_FILE).is_file():
            raise FileNotFoundError(f"--data: object folder {str(f)!r} has no scene.json")
    return folders


def check_not_in_object_folder(path: str | os.PathLike, flag: str = "--out") -> None:
    """Refuse a dataset's output folder that is, or lies inside, an object folder (one holding scene.json, however
    the path is spelled: `d/00001.data/../00000.data`): the objects written there would mix with that object's
    files, and its dataset's readers would take them for one object's."""
    from scenes.cli.errors import UsageError

    real = Path(os.path.realpath(path))
    held = next((p for p in (real, *real.parents)  # an object folder's: a scene file beside a mask (another tool's
                 if (p / SCENE_FILE).is_file() and (p / MASK_FILE).is_file()), None)  # scene.json alone is not one)
    if held is not None:
        where = "is" if held == real else f"lies inside {str(held)!r},"
        raise UsageError(f"{flag}: {str(path)!r} {where} an object folder (it holds {SCENE_FILE}); expected a "
                         "folder of its own for a dataset")


def scene_file_present(path: Path) -> bool:
    """Whether the scene file `path` is there: True for a file, False when nothing is under its name; anything else
    under that name (a folder, a device, a link to nothing) is a ValueError, never read as "no scene" (which would
    silently switch the check to its fitted mode)."""
    from scenes.files import not_a_file

    why = not_a_file(path)
    if os.path.lexists(path) and why:
        said = why.replace("expected a file", "expected the object's scene.json file")
        raise ValueError(f"scene file {path}: {said}")
    return not why


def read_scene_dict(folder_or_file: str | Path) -> dict[str, Any]:
    """scene.json as a plain dict (description fields and extras); FileNotFoundError / ValueError."""
    path = Path(folder_or_file)
    if path.is_dir():
        path = path / SCENE_FILE
    if not scene_file_present(path):
        raise FileNotFoundError(f"scene.json: {str(path)!r} does not exist (is this an object folder?)")
    try:
        d = read_json(path)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"scene file {path}: cannot be parsed as JSON ({exc})") from exc
    except RecursionError:  # nested deeper than the parser's stack: not a scene description
        raise ValueError(f"scene file {path}: nested too deeply to be a scene description") from None
    if not isinstance(d, dict):
        raise ValueError(f"scene file {path}: expected a JSON object, got {type(d).__name__}")
    version = d.get("format_version", FORMAT_VERSION)
    if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= FORMAT_VERSION:
        raise ValueError(f"scene file {path}: format_version {version!r}; this toolkit reads versions 1 to "
                         f"{FORMAT_VERSION} (a newer toolkit wrote it?)")
    try:
        check_scene_files(d, path)
    except RecursionError:
        raise ValueError(f"scene file {path}: nested too deeply to be a scene description") from None
    return d


ASSET_KEYS = ("file", "normal_map")
"""The keys of a scene.json whose string values name an asset file (meshes, textures, maps)."""


def check_scene_files(scene: Any, path: Path, where: str = "") -> None:
    """Every asset a scene.json names lies inside its object folder (the generator copies them to aux/).

    The file is untrusted: an absolute name, `..` or a link out would make a check read another object's mesh
    or any file of the machine while reporting on this one."""
    items = scene.items() if isinstance(scene, dict) else enumerate(scene) if isinstance(scene, list) else ()
    for key, value in items:
        here = f"{where}.{key}" if where else str(key)
        if key in ASSET_KEYS and isinstance(value, str):
            if "\x00" in value or len(value) > 4096:  # no file is named so (the system would refuse it unnamed)
                raise ValueError(f"scene file {path}: {here} names {value[:80]!r}{'...' if len(value) > 80 else ''}, "
                                 "not a file name (a NUL byte, or longer than 4096 characters); expected aux/...")
            folder = path.parent.resolve()
            target = (folder / value).resolve()
            if Path(value).is_absolute() or not target.is_relative_to(folder):
                raise ValueError(f"scene file {path}: {here} names {value!r}, outside the object folder; scene.json "
                                 "names its assets relative to its folder (aux/...)")
        else:
            check_scene_files(value, path, here)


SCENE_EXTRAS = ("camera_lights", "format_version", "sensor")
"""What a scene.json holds beside the description: the lights in the camera frame, its format version, and the
camera sensor applied (`scenes.camera_sensor.SCENE_KEY`)."""


def split_scene_extras(d: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(SceneDescription fields, everything else) of a scene.json dict."""
    from dataclasses import fields

    from scenes.description import SceneDescription

    known = {f.name for f in fields(SceneDescription)}
    return {k: v for k, v in d.items() if k in known}, {k: v for k, v in d.items() if k not in known}


def scene_from_dict(scene: dict[str, Any], path: str | Path | None = None):
    """The validated SceneDescription of a parsed scene.json (`read_scene_dict`), its extra keys left aside; a
    ValueError naming the file `path` (where given) and the field."""
    from scenes.description import SceneDescription

    try:
        fields_, extras = split_scene_extras(scene)
        if unknown := sorted(set(extras) - set(SCENE_EXTRAS)):  # a typo is never ignored
            raise ValueError(f"scene: unknown field(s) {', '.join(map(str, unknown))[:200]}, expected the "
                             f"description's and {', '.join(SCENE_EXTRAS)}")
        return SceneDescription.from_dict(fields_).validate()
    except (ValueError, TypeError, KeyError) as exc:
        said = str(exc) if not isinstance(exc, KeyError) else f"{exc.args[0]}: missing"
        if path is None or str(path) in said:
            raise
        raise ValueError(f"scene file {path}: {said}") from None


def read_scene(folder_or_file: str | Path):
    """(validated SceneDescription, extras dict) of an object folder's scene.json."""
    path = Path(folder_or_file)
    scene = read_scene_dict(path)
    return scene_from_dict(scene, path / SCENE_FILE if path.is_dir() else path), split_scene_extras(scene)[1]


def scene_json_text(desc, extras: dict[str, Any] | None = None) -> str:
    """The bytes of scene.json: description plus extras, sorted keys, no NaN."""
    scene = desc.to_dict()
    for key, value in (extras or {}).items():
        scene[key] = value
    return json_text(scene, indent=1, sort_keys=True, strict=True)


def write_scene(folder: str | Path, desc, extras: dict[str, Any] | None = None) -> Path:
    """Write `folder/scene.json` (extras get `format_version` unless given)."""
    extras = dict(extras or {})
    extras.setdefault("format_version", FORMAT_VERSION)
    path = Path(folder) / SCENE_FILE
    atomic_write_text(path, scene_json_text(desc, extras))
    return path


def prediction_file(folder: str | Path, flag: str = "--pred") -> Path | None:
    """The first of `PREDICTION_FILES` present in `folder`, or None; a ValueError when it is a link to the map of
    another object beside it (one map scored as two objects')."""
    folder = Path(folder)
    for fname in PREDICTION_FILES:
        path = folder / fname
        if os.path.lexists(path) and not path.is_dir():  # a device too: refused by name
            real, here = Path(os.path.realpath(path)), Path(os.path.realpath(folder))
            if path.is_symlink() and real.parent.parent == here.parent and real.parent != here:
                raise ValueError(f"{flag}: {str(path)!r} is a link to {str(real)!r}, the map of another object "
                                 "beside it: each object is scored on its own map; copy it in, or remove the link")
            return path
    return None


def find_prediction(pred: str | Path, name: str | None = None) -> Path:
    """The normal-map file of an object: `pred` itself if a file, else `prediction_file(pred/name)`,
    else `prediction_file(pred)`; FileNotFoundError when none."""
    pred = Path(pred)
    if os.path.lexists(pred) and not pred.is_dir():  # whatever it is, its reader refuses it by name
        return pred
    folders = [pred / name, pred] if name else [pred]
    for folder in folders:
        found = prediction_file(folder, "--normals")
        if found is not None:
            return found
    where = " or ".join(str(f) for f in folders)
    raise FileNotFoundError(f"--normals: no {'/'.join(PREDICTION_FILES)} in {where}")


def prediction_label(source: str | Path) -> str:
    """A short name of where a normal map came from, for titles: the method recorded in the prediction's
    `PREDICTION_INFO` ("model glc-tiny", "least-squares"), else the file's folder and name."""
    path = Path(source)
    info = path.parent / PREDICTION_INFO
    try:
        d = read_json(info)
        method = str(d["method"])
        model = d.get("model_name")
        return f"{method} {model}" if method == "model" and model else method
    except (OSError, ValueError, KeyError, TypeError):
        return f"{path.parent.name}/{path.name}" if path.parent.name else path.name


def write_object_folder(folder: str | Path, images: np.ndarray, mask: np.ndarray, normals: np.ndarray | None,
                        desc=None, extras: dict[str, Any] | None = None, scene: dict[str, Any] | None = None) -> Path:
    """Write the top level of an object folder: L*.png, mask.png, normal.tif (when given) and scene.json.

    scene.json is `desc` plus `extras` (`write_scene`), or the plain dict `scene` as is (synthetic folders
    of the tests, partial scene.json of other tools). Images are linear [0, 1] (K, H, W, 3)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for i, img in enumerate(images):
        write_png16(folder / image_name(i), img)
    write_mask(folder / MASK_FILE, mask)
    if normals is not None:
        write_normal_map(folder / NORMAL_FILE, np.where(np.asarray(mask)[..., None], normals, 0.0))
    if desc is not None:
        write_scene(folder, desc, extras)
    elif scene is not None:
        write_json(folder / SCENE_FILE, scene, indent=None)
    return folder
