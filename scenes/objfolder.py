"""The object folder `<name>.data/`: the one module that knows its layout and its files.

Everything that reads or writes an object folder goes through here: `wildgen` writes it, `unips` loads it
for the model, `validate` loads it for the re-render check, `wildgen.preview` shows it, the tests build
synthetic ones. Plain NumPy / OpenCV / OpenEXR (no Mitsuba). Layout (see ARCHITECTURE.md):

- `L000.png ... L{K-1}.png`: 16-bit linear RGB, `round(clip(radiance * exposure, 0, 1) * 65535)`;
- `mask.png`: 8-bit gray, 255 inside the object, 0 outside. Reading follows the official UniPS loaders:
  any channel > 0 is foreground (`MASK_RULE`);
- `normal.tif`: 16-bit RGB `round((n + 1) / 2 * 65535)`, camera frame x right, y up, z toward the camera;
  background n = 0 is 32768 in every channel;
- `scene.json`: the `SceneDescription` JSON plus extra top-level keys (`SCENE_EXTRAS`: `camera_lights`,
  `format_version`, ...), split apart only by `split_scene_extras`;
- `aux/`: float EXR ground truth, the mesh and textures used.

Predictions (what `unips.predict` writes, what `unips.evaluate` and `validate.rerender` read) are
`PRED/<object>/normal.<ext>`, looked up in the order of `PREDICTION_FILES`: the lossless float EXR first,
then the 16-bit PNG, then `.npy` and TIFF. `<object>` is `object_name(folder)`.

Normal-map files: 16-bit PNG / TIFF as above (written with OpenCV in BGR order, so RGB-aware readers
get RGB), 8-bit PNG (DiLiGenT's `Normal_gt.png`, visualisations) `(n + 1) / 2 * 255`, float EXR
(channels R, G, B), `.npy` and MATLAB `.mat` holding n itself.
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

# ------------------------------------------------------------------------------------------ layout

OBJECT_SUFFIX = ".data"
SCENE_FILE = "scene.json"
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
SCENE_EXTRAS = ("camera_lights", "format_version", "sensor")
"""Top-level scene.json keys written next to the SceneDescription fields."""
PREDICTION_FILES = ("normal.exr", "normal.png", "normal.npy", "normal.tif", "normal.tiff")
"""File names of a prediction folder, in lookup order (lossless float first)."""
PREDICTION_INFO = "predict.json"
"""What `unips.predict` records beside a prediction (method, model, images used)."""
MASK_RULE = "any channel > 0 is foreground (as the official UniPS loaders)"
BACKGROUND_16 = 32768
"""Encoded value of n = 0 in a 16-bit normal map."""
_IMAGE_RE = re.compile(r"^L(\d+)\.png$")


def image_name(index: int) -> str:
    """File name of input image `index` (L000.png ...)."""
    return f"L{index:03d}.png"


def radiance_name(index: int) -> str:
    """File name, inside `AUX_DIR`, of the float radiance of image `index` before its exposure."""
    return f"radiance_{index:03d}.exr"


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file, read in 1 MiB chunks (the checksums of manifests and shard indexes)."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def object_name(path: str | Path) -> str:
    """Name of an object folder: its name minus a trailing `.data` (`foo.data` -> `foo`, `ballPNG` stays)."""
    name = Path(path).resolve().name
    return name[: -len(OBJECT_SUFFIX)] if name.endswith(OBJECT_SUFFIX) and len(name) > len(OBJECT_SUFFIX) else name


def image_files(folder: str | Path) -> list[Path]:
    """The `L<i>.png` images of an object folder in index order; ValueError when indices have gaps."""
    folder = Path(folder)
    found = {}
    for p in folder.iterdir():
        m = _IMAGE_RE.match(p.name)
        if m:
            found[int(m.group(1))] = p
    indices = sorted(found)
    if indices != list(range(len(indices))):
        missing = sorted(set(range(max(indices, default=-1) + 1)) - set(indices))
        raise ValueError(f"images: {str(folder)!r} has L*.png files with gaps (missing indices {missing[:10]})")
    return [found[i] for i in indices]


def list_object_folders(dataset: str | Path) -> list[Path]:
    """Object folders (`*.data` with a scene.json) of a dataset folder, sorted by name."""
    dataset = Path(dataset)
    folders = sorted(p for p in dataset.iterdir()
                     if p.is_dir() and p.name.endswith(OBJECT_SUFFIX) and not p.name.startswith("."))
    if not folders:
        raise FileNotFoundError(f"--data: {str(dataset)!r} has no scene.json and no *.data object folders")
    for f in folders:
        if not (f / SCENE_FILE).is_file():
            raise FileNotFoundError(f"--data: object folder {str(f)!r} has no scene.json")
    return folders


# ------------------------------------------------------------------------------------- scene.json


def read_scene_dict(folder_or_file: str | Path) -> dict[str, Any]:
    """scene.json as a plain dict (description fields and extras); FileNotFoundError / ValueError."""
    path = Path(folder_or_file)
    if path.is_dir():
        path = path / SCENE_FILE
    if not path.is_file():
        raise FileNotFoundError(f"scene.json: {str(path)!r} does not exist (is this an object folder?)")
    try:
        d = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"scene file {path}: cannot be parsed as JSON ({exc})") from exc
    if not isinstance(d, dict):
        raise ValueError(f"scene file {path}: expected a JSON object, got {type(d).__name__}")
    return d


def split_scene_extras(d: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(SceneDescription fields, everything else) of a scene.json dict."""
    from dataclasses import fields

    from scenes.description import SceneDescription

    known = {f.name for f in fields(SceneDescription)}
    return {k: v for k, v in d.items() if k in known}, {k: v for k, v in d.items() if k not in known}


def read_scene(folder_or_file: str | Path):
    """(validated SceneDescription, extras dict) of an object folder's scene.json."""
    from scenes.description import SceneDescription

    desc_dict, extras = split_scene_extras(read_scene_dict(folder_or_file))
    return SceneDescription.from_dict(desc_dict).validate(), extras


def scene_json_text(desc, extras: dict[str, Any] | None = None) -> str:
    """The bytes of scene.json: description plus extras, sorted keys, no NaN."""
    scene = desc.to_dict()
    for key, value in (extras or {}).items():
        scene[key] = value
    return json.dumps(scene, indent=1, sort_keys=True, allow_nan=False)


def write_scene(folder: str | Path, desc, extras: dict[str, Any] | None = None) -> Path:
    """Write `folder/scene.json` (extras get `format_version` unless given)."""
    extras = dict(extras or {})
    extras.setdefault("format_version", FORMAT_VERSION)
    path = Path(folder) / SCENE_FILE
    atomic_write_text(path, scene_json_text(desc, extras))
    return path


# ------------------------------------------------------------------------------------ image files


def to_uint16(x: np.ndarray) -> np.ndarray:
    """Linear [0, 1] floats to uint16, clipped and rounded."""
    return np.round(np.clip(x, 0.0, 1.0) * 65535.0).astype(np.uint16)


def _temporary(path: Path) -> Path:
    """A hidden name beside `path` with the same extension (image writers choose the format by it)."""
    return path.with_name(f".{path.stem}.tmp{os.getpid()}{path.suffix}")


def atomic_write(path: str | Path, write) -> None:
    """Call `write(tmp)` on a temporary name beside `path`, then rename it to `path`: a kill or a full disk
    never leaves a truncated file under the real name (the temporary one is removed on failure)."""
    path = Path(path)
    tmp = _temporary(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        if str(path) in str(exc):
            raise
        raise OSError(exc.errno, f"could not write {str(path)!r}: {exc.strerror or exc}") from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _imwrite(path: Path, image: np.ndarray, mkdir: bool = False) -> None:
    import cv2

    if mkdir:
        path.parent.mkdir(parents=True, exist_ok=True)

    # Encoded in memory and written by Python: cv2.imwrite reports success on a full disk (0-byte file).
    ok, data = cv2.imencode(path.suffix, image)
    if not ok:
        raise OSError(f"could not encode {str(path)!r} (unsupported extension {path.suffix!r})")
    atomic_write(path, lambda tmp: tmp.write_bytes(data.tobytes()))


def write_picture(path: str | Path, bgr: np.ndarray) -> None:
    """Write a picture for people (figure, contact sheet, error map: 8-bit BGR as OpenCV draws it; the format
    from the extension) atomically, detecting a full disk."""
    _imwrite(Path(path), np.ascontiguousarray(bgr), mkdir=True)


def write_png16(path: str | Path, rgb: np.ndarray) -> None:
    """(H, W, 3) float in [0, 1] or uint16 -> 16-bit RGB PNG (no gamma: linear values)."""
    data = rgb if rgb.dtype == np.uint16 else to_uint16(rgb)
    _imwrite(Path(path), np.ascontiguousarray(data[:, :, ::-1]))


def write_instances(path: str | Path, ids: np.ndarray) -> None:
    """(H, W) integer ids -> one-channel 16-bit PNG (`INSTANCES_FILE`)."""
    ids = np.asarray(ids)
    if ids.min(initial=0) < 0 or ids.max(initial=0) > 65535:
        raise ValueError(f"instance ids: expected values in [0, 65535], got [{ids.min()}, {ids.max()}]")
    _imwrite(Path(path), np.ascontiguousarray(ids.astype(np.uint16)), mkdir=True)


def read_instances(path: str | Path) -> np.ndarray:
    """(H, W) uint16 instance ids of `write_instances`."""
    img = _read_raw(Path(path), "instance-id")
    if img.ndim != 2 or img.dtype != np.uint16:
        raise ValueError(f"{path}: expected a one-channel 16-bit PNG of instance ids, got {img.dtype} {img.shape}")
    return img


def _read_raw(path: Path, what: str = "image"):
    import cv2

    if not path.is_file():
        raise FileNotFoundError(f"{what} file {path} does not exist")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"{what} file {path}: cannot be read (corrupt or unsupported format)")
    return img


def _check_float_image(img: np.ndarray, path: Path) -> np.ndarray:
    """A float image is radiance: finite and non-negative, or it is refused by name."""
    if not np.all(np.isfinite(img)):
        raise ValueError(f"image file {path}: contains NaN or infinite values")
    if np.any(img < 0):
        raise ValueError(f"image file {path}: has negative values (min {float(img.min()):.3g}); expected radiance >= 0")
    return img


def read_image(path: str | Path) -> np.ndarray:
    """Read one image as (H, W, 3) float32 linear RGB (uint16 / 65535, uint8 / 255, float EXR as is; gray
    repeated to RGB, alpha dropped). Float images must be finite and non-negative."""
    path = Path(path)
    if path.suffix.lower() == ".exr":
        if not path.is_file():
            raise FileNotFoundError(f"image file {path} does not exist")
        img = read_exr(path)
        img = np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img[:, :, :3]
        if img.shape[2] != 3:
            raise ValueError(f"image file {path}: expected a gray or RGB EXR, got {img.shape[2]} channels")
        return _check_float_image(np.ascontiguousarray(img, dtype=np.float32), path)
    img = _read_raw(path)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3]  # drop alpha
    elif img.ndim == 3 and img.shape[2] == 1:
        img = np.repeat(img, 3, axis=2)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image file {path}: expected a gray, RGB or RGBA image, got shape {img.shape}")
    img = np.ascontiguousarray(img[..., ::-1])  # BGR -> RGB
    if img.dtype in (np.float32, np.float64):
        return _check_float_image(img.astype(np.float32), path)
    if img.dtype not in CODE_SCALES:
        raise ValueError(f"image file {path}: unsupported pixel type {img.dtype} (expected 8 or 16 bit)")
    return codes_to_linear(img)


CODE_SCALES = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}
"""Largest code of each integer pixel type: a file value v is the linear value v / scale."""


def codes_to_linear(codes: np.ndarray) -> np.ndarray:
    """Integer file values (uint8 / uint16, any shape) -> float32 in [0, 1]: the one conversion every reader of
    integer images uses (`read_image`, and decoded shards, `scenes.shards`), so both give the same bits."""
    return codes.astype(np.float32) / CODE_SCALES[codes.dtype]


def write_mask(path: str | Path, mask: np.ndarray) -> None:
    """(H, W) bool -> 8-bit gray PNG, 255 inside, 0 outside."""
    _imwrite(Path(path), np.where(mask, 255, 0).astype(np.uint8))


def read_mask(path: str | Path, shape: tuple[int, int] | None = None) -> np.ndarray:
    """(H, W) bool mask by `MASK_RULE` (any channel > 0); its size must be `shape` when given."""
    path = Path(path)
    img = _read_raw(path, "mask")
    if img.ndim == 3:
        img = img.max(axis=2)
    if shape is not None and img.shape != tuple(shape):
        raise ValueError(f"mask file {path}: size {img.shape[1]}x{img.shape[0]} (WxH) differs from the "
                         f"images' {shape[1]}x{shape[0]}")
    mask = img > 0
    if not mask.any():
        raise ValueError(f"mask file {path}: is empty (no pixel > 0)")
    return mask


def write_exr(path: str | Path, data: np.ndarray) -> None:
    """float32 (H, W), (H, W, 1) or (H, W, 3) -> EXR with channels Y or R, G, B (ZIP compression)."""
    import OpenEXR

    data = np.asarray(data, np.float32)
    if data.ndim == 3 and data.shape[2] == 1:
        data = data[:, :, 0]
    if data.ndim == 2:
        channels = {"Y": np.ascontiguousarray(data)}
    elif data.ndim == 3 and data.shape[2] == 3:
        channels = {c: np.ascontiguousarray(data[:, :, i]) for i, c in enumerate("RGB")}
    else:
        raise ValueError(f"write_exr: data shape {data.shape} is not (H, W), (H, W, 1) or (H, W, 3)")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def write(tmp: Path) -> None:
        # OpenEXR replaces the dict's values with Channel objects: hand it a copy.
        try:
            with OpenEXR.File(header, dict(channels)) as f:
                f.write(str(tmp))
        except RuntimeError as exc:  # OpenEXR reports a full disk or an unwritable folder this way
            raise OSError(f"could not write {str(path)!r}: {exc}") from exc

    atomic_write(path, write)


def _exr_channels(path: Path) -> dict[str, np.ndarray]:
    import OpenEXR

    if not path.is_file():
        raise FileNotFoundError(f"EXR file {str(path)!r} does not exist")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            return {k: np.asarray(v.pixels, np.float32) for k, v in f.channels().items()}
    except Exception as exc:  # OpenEXR raises several types for corrupt files
        raise ValueError(f"cannot read EXR {str(path)!r}: {exc}") from exc


def read_exr(path: str | Path) -> np.ndarray:
    """EXR -> float32 (H, W, C): RGB when present, else its single channel, else all channels by name."""
    ch = _exr_channels(Path(path))
    if all(c in ch for c in "RGB"):
        return np.stack([ch["R"], ch["G"], ch["B"]], -1)
    if len(ch) == 1:
        return next(iter(ch.values()))[:, :, None]
    names = sorted(ch)
    return np.stack([ch[k] for k in names], -1)


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write a text file through a temporary name and rename, so readers never see half a file."""
    atomic_write(path, lambda tmp: tmp.write_text(text))


# -------------------------------------------------------------------------------- normal-map files


def check_normal_array(n: np.ndarray, what: str = "n") -> np.ndarray:
    """n as float32 (H, W, 3) after checking its shape and that it is finite."""
    n = np.asarray(n)
    if n.ndim != 3 or n.shape[2] != 3:
        raise ValueError(f"{what}: expected a normal map of shape (H, W, 3), got shape {n.shape}")
    if not np.issubdtype(n.dtype, np.number):
        raise ValueError(f"{what}: expected a numeric array, got dtype {n.dtype}")
    n = n.astype(np.float32)
    if not np.all(np.isfinite(n)):
        raise ValueError(f"{what}: normal map contains NaN or infinite values")
    return n


def _background(n: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels whose normal is exactly zero."""
    return ~np.any(n != 0, axis=2)


def encode_normals(n: np.ndarray) -> np.ndarray:
    """(H, W, 3) normals -> (H, W, 3) uint16 RGB, round((n + 1) / 2 * 65535), background (n = 0) 32768."""
    check_normal_array(n)
    n = np.asarray(n)
    n = n if np.issubdtype(n.dtype, np.floating) else n.astype(np.float32)  # float64 input stays float64
    enc = np.round((np.clip(n, -1.0, 1.0) + 1.0) * 0.5 * 65535.0).astype(np.uint16)
    enc[_background(n)] = BACKGROUND_16
    return enc


def decode_normal_image(img: np.ndarray, what: str) -> np.ndarray:
    """Decode an RGB integer normal image (uint8 or uint16) to float normals.

    Pixels whose decoded vector is shorter than 0.5 (the encoded zero vector, 32768 or 128) become 0.
    Float images are taken as n itself.
    """
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"{what}: expected a 3-channel normal image, got shape {img.shape}")
    if img.dtype == np.uint16:
        n = img.astype(np.float32) / 65535.0 * 2.0 - 1.0
    elif img.dtype == np.uint8:
        n = img.astype(np.float32) / 255.0 * 2.0 - 1.0
    elif np.issubdtype(img.dtype, np.floating):
        n = img.astype(np.float32)
    else:
        raise ValueError(f"{what}: unsupported normal image dtype {img.dtype} (expected uint8, uint16 or float)")
    if np.issubdtype(img.dtype, np.integer):
        n[np.linalg.norm(n, axis=2) < 0.5] = 0.0
    return n


def write_normal_map(path: str | Path, n: np.ndarray) -> None:
    """Write a 16-bit RGB normal map (PNG or TIFF, chosen by the extension; `normal.tif` of the folder)."""
    _imwrite(Path(path), np.ascontiguousarray(encode_normals(n)[..., ::-1]), mkdir=True)  # OpenCV writes BGR


def write_normal_exr(path: str | Path, n: np.ndarray) -> None:
    """Write normals as a float32 OpenEXR file with channels R, G, B."""
    n = check_normal_array(n)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_exr(path, n)


def normal_visual(n: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 RGB picture of the normals, (n + 1) / 2, background black."""
    n = check_normal_array(n)
    vis = np.round((np.clip(n, -1.0, 1.0) + 1.0) * 0.5 * 255.0).astype(np.uint8)
    vis[_background(n)] = 0
    return vis


def write_normal_visual(path: str | Path, n: np.ndarray) -> None:
    """Write an 8-bit RGB picture of the normals, (n + 1) / 2, background black."""
    _imwrite(Path(path), np.ascontiguousarray(normal_visual(n)[..., ::-1]), mkdir=True)


def _read_mat(path: Path) -> np.ndarray:
    import scipy.io

    try:
        data = scipy.io.loadmat(str(path))
    except Exception as exc:
        raise ValueError(f"path: cannot read MAT file {path}: {exc}") from exc
    arrays = {k: v for k, v in data.items() if not k.startswith("__")}
    for key in ("Normal_gt", "normal", "normals", "Normal_est", "N"):
        if key in arrays:
            return np.asarray(arrays[key], dtype=np.float32)
    if len(arrays) == 1:
        return np.asarray(next(iter(arrays.values())), dtype=np.float32)
    raise ValueError(f"path: MAT file {path} has no 'Normal_gt' key and several arrays {sorted(arrays)}")


def read_normals(path: str | Path) -> np.ndarray:
    """Read a normal map: .png/.tif/.tiff (8 or 16 bit), .exr, .npy, .mat.

    Returns (H, W, 3) float32; background pixels are 0. Raises FileNotFoundError for a missing file,
    ValueError for unreadable files, wrong shapes or non-finite values.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"path: normal map {path} does not exist")
    suffix = path.suffix.lower()
    if suffix in (".png", ".tif", ".tiff"):
        import cv2

        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise ValueError(f"path: cannot read image file {path} (corrupt or unsupported)")
        if img.ndim != 3 or img.shape[2] not in (3, 4):
            raise ValueError(f"path: normal image {path} must be RGB, got shape {img.shape}")
        n = decode_normal_image(np.ascontiguousarray(img[..., 2::-1]), f"path {path}")
    elif suffix == ".exr":
        try:
            ch = _exr_channels(path)
        except ValueError as exc:
            raise ValueError(f"path: cannot read EXR file {path}: {exc}") from exc
        missing = [c for c in "RGB" if c not in ch]
        if missing:
            raise ValueError(f"path: EXR file {path} lacks channels {missing} (has {sorted(ch)})")
        n = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float32)
    elif suffix == ".npy":
        try:
            n = np.load(path, allow_pickle=False)
        except Exception as exc:
            raise ValueError(f"path: cannot read NPY file {path}: {exc}") from exc
    elif suffix == ".mat":
        n = _read_mat(path)
    else:
        raise ValueError(f"path: unsupported normal-map extension {suffix!r} for {path} "
                         "(expected .png, .tif, .tiff, .exr, .npy or .mat)")
    return check_normal_array(n, f"normal map {path}")


# ------------------------------------------------------------------------------------- predictions


def prediction_file(folder: str | Path) -> Path | None:
    """The first of `PREDICTION_FILES` present in `folder`, or None."""
    folder = Path(folder)
    for fname in PREDICTION_FILES:
        if (folder / fname).is_file():
            return folder / fname
    return None


def find_prediction(pred: str | Path, name: str | None = None) -> Path:
    """The normal-map file of an object: `pred` itself if a file, else `prediction_file(pred/name)`,
    else `prediction_file(pred)`; FileNotFoundError when none."""
    pred = Path(pred)
    if pred.is_file():
        return pred
    folders = [pred / name, pred] if name else [pred]
    for folder in folders:
        found = prediction_file(folder)
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
        d = json.loads(info.read_text())
        method = str(d["method"])
        model = d.get("model_name")
        return f"{method} {model}" if method == "model" and model else method
    except (OSError, ValueError, KeyError, TypeError):
        return f"{path.parent.name}/{path.name}" if path.parent.name else path.name


# ---------------------------------------------------------------------------------- angular error


def angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles in degrees between the vectors of two arrays of shape (..., 3), normalised first, in float64
    (light directions, normals): the one angle formula of the toolkit."""
    a = _unit(np.asarray(a, np.float64))
    b = _unit(np.asarray(b, np.float64))
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def _unit(n: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    return n / np.maximum(norm, 1e-12)


def angular_error_deg(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W) angular error in degrees inside mask, 0 outside.

    Both maps are normalised first; a zero predicted normal inside the mask counts as 90 degrees.
    """
    pred = check_normal_array(pred, "pred")
    gt = check_normal_array(gt, "gt")
    mask = np.asarray(mask)
    if pred.shape != gt.shape:
        raise ValueError(f"pred: shape {pred.shape} differs from gt shape {gt.shape}")
    if mask.shape != pred.shape[:2]:
        raise ValueError(f"mask: shape {mask.shape} differs from the normal maps' {pred.shape[:2]}")
    mask = mask.astype(bool)
    err = angles_deg(pred, gt)
    err[~mask] = 0.0
    return err.astype(np.float32)


def mean_angular_error(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> float:
    """Mean angular error in degrees over the mask (which must not be empty)."""
    mask = np.asarray(mask).astype(bool)
    if not mask.any():
        raise ValueError("mask: is empty, cannot average the angular error")
    err = angular_error_deg(pred, gt, mask)
    return float(np.mean(err[mask], dtype=np.float64))


def angular_errors_chw(pred, gt, mask) -> np.ndarray:
    """Angular errors in degrees of the pixels inside `mask`, as a flat float32 array, for channel-first
    maps (the training loop's layout): pred, gt (3, H, W), mask (1, H, W) with > 0.5 inside. NumPy arrays
    or CPU tensors; same rule as `angular_error_deg`."""
    m = np.asarray(mask)[0] > 0.5
    p = np.moveaxis(np.asarray(pred, dtype=np.float32), 0, -1)
    g = np.moveaxis(np.asarray(gt, dtype=np.float32), 0, -1)
    return angular_error_deg(p, g, m)[m]


# ---------------------------------------------------------------------------------- whole folders


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
        (folder / SCENE_FILE).write_text(json.dumps(scene))
    return folder
