"""Every photometric-stereo folder layout in one table, and the one reader of all of them.

`LAYOUT_TABLE` describes each layout a user may hand us: how it is recognised, how its images are listed (and in
which order), which files hold its calibration and its ground-truth normals, and whether a mask file is required.
`read_folder` reads any of them into one plain structure, `FolderData`; the model's loader (`unips.data`), the
fitted re-render check (`validate.observations`) and the known-scene check (`validate.io`) are thin views of it,
so a folder means the same thing to all of them. Adding a layout is one `Layout` entry (plus its tests).

Layouts, detected in table order:

- ``"ours"``: the project's object folder (`scenes.folder.format` owns its files): ``L000.png ...`` (no gaps),
  ``mask.png`` (required), ``normal.tif``, ``scene.json`` (light family; calibrated lights from its
  ``camera_lights`` when every image has exactly one directional light and nothing else).
- ``"diligent"``: DiLiGenT ``*PNG`` folders: ``001.png ...`` (order from ``filenames.txt`` when present),
  ``light_directions.txt``, ``light_intensities.txt`` (ones when absent), ``mask.png``, ``Normal_gt.mat`` or
  ``Normal_gt.png``. Both light files use the camera frame (x right, y up, z toward the camera): 3 numbers a row,
  one row per image, separated by spaces or commas (a spreadsheet's UTF-8 BOM and CRLF line ends are read too).
- ``"unips"``: official UniPS / SDM-UniPS folders: ``L*`` images (png, jpg, tif, bmp, 8 or 16 bit, or float
  EXR; natural order), optional ``mask.png`` (whole image when absent), optional ``normal.tif``,
  ``Normal_gt.png`` or ``Normal_gt.mat``. Our own folder with its scene file removed reads as this layout.

Rules shared by every layout (the divergences this module exists to prevent):

- images are linear as stored: 16-bit / 65535, 8-bit / 255, EXR as is; a float image must be finite and
  non-negative; a folder may not mix float EXR and integer images (their scales differ);
- a channel at an integer file's largest code is *saturated*: its true value is only known to be at least
  the stored one (`FolderData.saturated`);
- mask: binary, 0 outside and one other value on the object (`scenes.images.read_mask`: the alpha where it is not
  fully opaque, else the largest colour channel; the official loaders' "any channel > 0" agrees on every binary
  mask without a transparent alpha; one that is not binary is refused rather than read as they would);
- ground-truth normals: renormalised inside the mask; a vector shorter than `MIN_NORMAL_LENGTH` is "no normal" and
  becomes 0 (an encoded zero vector decodes to length < 0.5), counted and logged;
- calibration: light directions are unit vectors toward the light, a zero vector or one of no finite length is
  refused; intensities must lie in float32's normal range, 1.2e-38 to 1e30 (the images are divided by them).

Errors are FileNotFoundError / ValueError with one line naming the argument the folder came from (``arg``) or the
file at fault.
"""
from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from scenes.files import check_text_name, is_within, not_a_file, read_text_file
from scenes.folder.calibration import Lights, diligent_lights, no_lights, ours_lights
from scenes.folder.format import (
    DILIGENT_LIGHTS,
    MASK_FILE,
    NORMAL_FILE,
    SCENE_FILE,
    check_dataset_complete,
    check_listed_done,
    image_files,
    object_name,
    read_scene_dict,
    scene_file_present,
)
from scenes.images import read_image, read_mask, read_normals

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
"""Integer image suffixes of ``L*`` images (the official loaders' ``L*[!.txt]`` pattern, minus text files)."""
FLOAT_SUFFIXES = (".exr",)
"""Float image suffixes: linear radiance, not clipped, so never saturated."""
ALL_IMAGE_SUFFIXES = IMAGE_SUFFIXES + FLOAT_SUFFIXES
MIN_NORMAL_LENGTH = 0.5
"""A ground-truth vector shorter than this is "no normal" (16-bit 32768 and 8-bit 128 decode to length < 0.5)."""

DILIGENT_LISTING = "filenames.txt"
ONE_FOLDER = (
    "an object folder: L*.png + scene.json (ours), L* images (UniPS), or DiLiGenT 001.png... + light_directions.txt"
)
EXPECTED = f"{ONE_FOLDER}; or a directory of such folders"  # where a dataset is read (find_object_folders)


# -------------------------------------------------------------------------------------- listing


def natural_key(name: str) -> list[Any]:
    """Sort key so that L2 comes before L10; zero-padded names sort as usual."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


def l_images(folder: str | Path, suffixes: tuple[str, ...] = ALL_IMAGE_SUFFIXES) -> list[Path]:
    """Files ``L*`` with one of `suffixes`, in natural order; an entry of such a name that is not a readable file
    (a folder, a dangling link, a pipe) is refused, never skipped (one image fewer would go unnoticed)."""
    folder = Path(folder)
    named = [p for p in folder.iterdir() if p.name.startswith("L") and p.suffix.lower() in suffixes]
    if odd := next((p for p in named if not p.is_file()), None):
        raise ValueError(f"image {str(odd)!r} {not_a_file(odd)}")
    return sorted(named, key=lambda p: natural_key(p.name))


def digit_images(folder: str | Path) -> list[Path]:
    """DiLiGenT-style ``001.png ...`` (all-digit stems), in natural order."""
    folder = Path(folder)
    return sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() == ".png" and p.stem.isdigit()),
                  key=lambda p: natural_key(p.name))


def diligent_folders(root: Path, arg: str = "--diligent") -> list[Path]:
    """The `<object>PNG` object folders of a DiLiGenT folder (ValueError naming `arg` when there is none)."""
    if not Path(root).is_dir():
        raise ValueError(f"{arg}: {str(root)!r} is not a folder")
    folders = sorted(p for p in Path(root).iterdir() if p.is_dir() and p.name.endswith("PNG"))
    if not folders:
        raise ValueError(f"{arg}: no <object>PNG folders in {str(root)!r}")
    return folders


def diligent_images(folder: str | Path) -> list[Path]:
    """A DiLiGenT folder's images: in ``filenames.txt`` order when the file exists, else `digit_images`."""
    folder = Path(folder)
    listing = folder / DILIGENT_LISTING
    if listing.is_file():
        text = read_text_file(listing).removeprefix("\ufeff")  # a Windows editor's BOM and CRLF: not in the names
        names = [line.strip() for line in text.splitlines() if line.strip()]
        if not names:  # no order of the images, and no image
            raise ValueError(f"{listing} lists no image; expected the names of its images (001.png ...), one a line")
        twice = next((n for n, name in enumerate(names) if name in names[:n]), None)  # two observations of one light
        if twice is not None:
            raise ValueError(f"{listing} lists {names[twice]} twice, entries {names.index(names[twice]) + 1} and "
                             f"{twice + 1}")
        outside = next((name for name in names if Path(name).name != name or name in (".", "..")), None)
        if outside is not None:  # a name read from a file stays inside its folder
            raise ValueError(f"{listing} lists {outside!r}, not a file name in that folder; expected the names of its "
                             "images (001.png ...)")
        other = next((name for name in names if name in (MASK_FILE, "Normal_gt.png", "Normal_gt.mat")), None)
        if other is not None:  # the mask or the ground truth taken as a photo would be a light that never was
            raise ValueError(f"{listing} lists {other!r}, the folder's mask or ground truth, not one of its images "
                             "(001.png ...)")
        return [folder / name for name in names]
    return digit_images(folder)


# ---------------------------------------------------------------------------------- the table


@dataclass(frozen=True)
class Layout:
    """One folder layout: everything the reader needs to know about it."""

    name: str
    """Short name, recorded in what the readers return (`FolderData.layout`)."""
    description: str
    """One line for users: what the layout is and where it comes from."""
    detect: Callable[[Path], bool]
    """True when a folder is of this layout (tried in table order, so later entries may be looser)."""
    images: Callable[[Path], list[Path]]
    """The folder's image files in loader order (the order of lights, reports and `--max-images`)."""
    ground_truth: tuple[str, ...]
    """Ground-truth normal-map file names, the first present one is read."""
    mask_required: bool
    """True: a missing ``mask.png`` is an error; False: the whole image is the object."""
    lights: Callable[[Path, int, dict | None], Lights]
    """Calibration and light family for the folder's N image files (and its scene.json, parsed once, or None)."""


def _is_ours(folder: Path) -> bool:
    return bool(l_images(folder)) and (folder / SCENE_FILE).is_file()


def _is_diligent(folder: Path) -> bool:
    return (folder / DILIGENT_LIGHTS).is_file() and (
        (folder / DILIGENT_LISTING).is_file() or bool(digit_images(folder))
    )


def _is_unips(folder: Path) -> bool:
    return bool(l_images(folder))


LAYOUT_TABLE: tuple[Layout, ...] = (
    Layout(
        "ours",
        "this toolkit's object folder (wildgen.make): L000.png.., mask.png, normal.tif, scene.json",
        _is_ours,
        image_files,
        (NORMAL_FILE,),
        True,
        ours_lights,
    ),
    Layout(
        "diligent",
        "DiLiGenT benchmark folder: 001.png.., light_directions.txt, light_intensities.txt, mask.png, Normal_gt.mat",
        _is_diligent,
        diligent_images,
        ("Normal_gt.mat", "Normal_gt.png"),
        False,
        diligent_lights,
    ),
    Layout(
        "unips",
        "official UniPS / SDM-UniPS folder: L* images (8/16-bit or EXR), optional mask.png and normal.tif",
        _is_unips,
        l_images,
        (NORMAL_FILE, "Normal_gt.png", "Normal_gt.mat"),
        False,
        no_lights,
    ),
)
LAYOUTS = tuple(layout.name for layout in LAYOUT_TABLE)
_BY_NAME = {layout.name: layout for layout in LAYOUT_TABLE}


def layout_named(name: str) -> Layout:
    """The table entry called `name`; ValueError naming the known ones."""
    if name not in _BY_NAME:
        raise ValueError(f"layout: unknown layout {name!r}, expected one of {', '.join(LAYOUTS)}")
    return _BY_NAME[name]


def detect_layout(path: str | Path) -> str | None:
    """Layout name of an object folder (the first entry of `LAYOUT_TABLE` that matches), or None."""
    folder = Path(path)
    return next((layout.name for layout in LAYOUT_TABLE if layout.detect(folder)), None) if folder.is_dir() else None


def has_scene(folder: str | Path) -> bool:
    """True when an object folder has a scene file (the known-scene re-render check is possible); anything else
    under that name is refused (`scenes.folder.format.scene_file_present`)."""
    return scene_file_present(Path(folder) / SCENE_FILE)


def find_object_folders(path: str | Path, arg: str = "path") -> list[Path]:
    """The object folders at `path`: itself if it is one, else its subfolders that are, sorted by name."""
    root = Path(path)
    if not root.exists():
        raise FileNotFoundError(f"{arg}: {root} does not exist (expected {EXPECTED})")
    if detect_layout(root) is not None:
        return [root]
    if root.is_dir():
        check_dataset_complete(root, arg)
        entries = sorted(root.iterdir(), key=lambda p: p.name)
        if (gone := next((p for p in entries if p.is_symlink() and not p.exists()), None)) is not None:  # never skipped
            raise FileNotFoundError(f"{arg}: {gone} is a link to {os.readlink(gone)}, which does not exist")
        if found := [p for p in entries if detect_layout(p) is not None]:
            real: dict[str, Path] = {}
            for p in found:  # two links to one folder elsewhere: read twice under two names (a link to a sibling is
                # that object's own fault, `check_own_files`: the rest goes on)
                if p.is_symlink() and (first := real.setdefault(os.path.realpath(p), p)) is not p:
                    raise ValueError(f"{arg}: {str(first)!r} and {str(p)!r} are one object folder (links to "
                                     f"{os.path.realpath(p)!r}): it would be read twice under two names; remove one")
            return found
    raise FileNotFoundError(f"{arg}: no object folder found at {root} (expected {EXPECTED})")


# ---------------------------------------------------------------------------------- the reader


@dataclass
class FolderData:
    """One object folder of any layout, read (see the module doc for the rules)."""

    name: str
    """Object name: the folder name minus a trailing '.data' (`scenes.folder.format.object_name`)."""
    path: Path
    """The object folder."""
    layout: str
    """One of `LAYOUTS`."""
    image_paths: list[Path]
    """The K image files read, in loader order."""
    num_files: int
    """Image files in the folder (K is smaller when `max_images` kept the first ones)."""
    shape: tuple[int, int]
    """(H, W) of the images."""
    images: np.ndarray | None
    """(K, H, W, 3) float32 linear RGB as stored (DiLiGenT: raw, not divided by the intensities); None when
    read with images=False."""
    saturated: np.ndarray | None
    """(K, H, W, 3) bool: channels at an integer file's largest code; None when there are none (or no images)."""
    mask: np.ndarray
    """(H, W) bool object mask."""
    mask_file: Path | None
    """The mask file, None when the layout allows none and the whole image is the object."""
    normals: np.ndarray | None
    """(H, W, 3) float32 ground-truth camera-frame normals, unit inside the mask where known, 0 elsewhere."""
    normals_file: Path | None
    """The ground-truth file read, or None."""
    lights: Lights
    """Light family and calibration, cut to the K images read."""
    has_scene: bool
    """True when the folder has a scene file."""
    sensor: Any = None
    """The camera sensor the folder records (`scenes.camera_sensor.Sensor`; ours only), None for a linear file (no
    record, or the `ideal` sensor): then `images` are light. With a sensor they are file values; `linear()`
    undoes the sensor's deterministic steps."""

    def linear(self) -> np.ndarray | None:
        """The images as light (`scenes.camera_sensor.linearize` when a sensor is recorded, else `images`)."""
        if self.images is None or self.sensor is None:
            return self.images
        from scenes.camera_sensor import linearize

        return linearize(self.images, self.sensor)

    @property
    def image_names(self) -> list[str]:
        return [p.name for p in self.image_paths]


def finish_normals(n: np.ndarray, mask: np.ndarray, path: Path) -> np.ndarray:
    """A ground-truth map checked against the mask: unit inside it where the vector is at least
    `MIN_NORMAL_LENGTH` long, 0 elsewhere (float64 arithmetic, so huge values do not overflow)."""
    if n.ndim != 3 or n.shape[2] != 3:
        raise ValueError(f"normal file {path}: expected shape (H, W, 3), got {n.shape}")
    if n.shape[:2] != mask.shape:
        raise ValueError(f"normal file {path}: size {n.shape[1]}x{n.shape[0]} differs from the images' "
                         f"{mask.shape[1]}x{mask.shape[0]}")
    n = np.asarray(n, np.float64)
    if not np.all(np.isfinite(n)):
        raise ValueError(f"normal file {path}: contains NaN or infinite values")
    scale = np.max(np.abs(n), axis=2, keepdims=True)  # divide first: squares of 1e200 overflow
    scaled = n / np.maximum(scale, 1e-300)
    scaled_norm = np.linalg.norm(scaled, axis=2, keepdims=True)
    keep = mask[..., None] & (scaled_norm * scale >= MIN_NORMAL_LENGTH)
    out = np.where(keep, scaled / np.maximum(scaled_norm, 1e-300), 0.0)
    missing = int(np.sum(mask & ~keep[..., 0]))
    if missing:
        log.warning(
            "%s: %d mask pixels have no ground-truth normal (shorter than %.1f)", path, missing, MIN_NORMAL_LENGTH
        )
    return out.astype(np.float32)


def check_read_normals(normals: np.ndarray | None, mask: np.ndarray, where: str) -> None:
    """Normals (H, W, 3) as `finish_normals` leaves them, stored elsewhere (a decoded shard; None: none stored): unit
    inside `mask` or zero where the truth is missing, zero outside; anything else is a ValueError naming `where`.
    Mask pixels without a normal are warned of as the folder reader does (an object without any still loads, by
    the reader's rule too)."""
    if normals is None:
        return
    length = np.linalg.norm(normals.astype(np.float64), axis=-1)
    inside = length[mask]
    if not (np.isfinite(length).all() and (length[~mask] == 0).all() and (abs(inside - 1) <= 1e-3)[inside != 0].all()):
        raise ValueError(f"{where} holds vectors neither of unit length nor zero")
    missing = int(np.sum(inside == 0))
    if missing:
        log.warning("%s: %d mask pixels have no ground-truth normal", where, missing)


def _recorded_sensor(folder: Path, scene: dict | None, num_images: int):
    """The sensor an object folder of ours records in its scene.json (parsed: `scene`; None when absent or
    `ideal`), checked against its first image's pixel type (`scenes.camera_sensor.check_file_bits`)."""
    if scene is None:
        return None
    from scenes.camera_sensor import SCENE_KEY, SENSORS, check_file_bits, read_sensor_record
    from scenes.folder.format import split_scene_extras

    _, extras = split_scene_extras(scene)
    if SCENE_KEY not in extras:
        return None
    sensor = read_sensor_record(extras, num_images, where := f"scene file {folder / SCENE_FILE}").sensor
    return None if sensor == SENSORS["ideal"] else check_file_bits(sensor, image_files(folder)[:1], where)


def _read_stack(paths: list[Path], white: float = 1.0) -> tuple[np.ndarray, np.ndarray | None]:
    """(K, H, W, 3) float32 images that must all have one size, and their saturated channels (at or above
    `white`, the file value of the largest code) or None."""
    kinds = {p.suffix.lower() in FLOAT_SUFFIXES for p in paths}
    if len(kinds) > 1:
        flt = next(p for p in paths if p.suffix.lower() in FLOAT_SUFFIXES)
        integer = next(p for p in paths if p.suffix.lower() not in FLOAT_SUFFIXES)
        raise ValueError(f"images: {paths[0].parent} mixes float EXR ({flt.name}) and integer ({integer.name}) images; "
                         "expected one kind (their value scales differ)")
    first = read_image(paths[0])
    stack = np.empty((len(paths),) + first.shape, dtype=np.float32)
    for i, p in enumerate(paths):
        img = first if i == 0 else read_image(p)
        if img.shape != first.shape:
            raise ValueError(f"image file {p}: size {img.shape[1]}x{img.shape[0]} differs from "
                             f"{paths[0].name}'s {first.shape[1]}x{first.shape[0]}")
        stack[i] = img
    if kinds == {True}:
        return stack, None
    saturated = stack >= white  # integer files clip: the largest code is a lower bound, not a value
    return stack, (saturated if saturated.any() else None)


def _check_informative(
    images: np.ndarray, saturated: np.ndarray | None, mask: np.ndarray, folder: Path, arg: str
) -> None:
    """Refuse a capture in which no image carries information about the object: every image constant inside
    the mask (all black, or one flat value), or every object pixel clipped in every image."""
    inside = images[:, mask]  # (K, P, 3)
    if np.all(inside.max(axis=1) == inside.min(axis=1)):
        value = float(inside.flat[0]) if inside.size else 0.0
        what = "black" if value == 0.0 else f"one flat value ({value:.3g})"
        raise ValueError(f"{arg}: every image of {folder} is {what} inside the object mask; expected photographs of "
                         "the object under changing light")
    if saturated is not None and np.all(saturated[:, mask]):
        raise ValueError(f"{arg}: every object pixel of every image of {folder} is saturated (at the file's largest "
                         "code); expected an exposure that leaves the object below white")


def check_own_files(folder: Path, arg: str) -> None:
    """ValueError naming `arg` when a file of `folder` is a link into another object folder: two objects would
    share an image or a ground truth without a word (a link to a photo kept elsewhere is the user's own); or when
    `folder` itself is a link to another object folder beside it (one object read twice, under two names)."""
    real = Path(os.path.realpath(folder))
    if folder.is_symlink() and real.parent == Path(os.path.realpath(folder.parent)) and real.name != folder.name \
            and detect_layout(real) is not None:
        raise ValueError(f"{arg}: {str(folder)!r} is a link to {str(real)!r}, another object folder beside it (one "
                         "object would be read twice, under two names): copy the folder, or remove the link")
    for p in folder.iterdir():
        if not p.is_symlink() or is_within(p, folder):
            continue
        real = Path(os.path.realpath(p))
        other = next((d for d in list(real.parents)[:3] if detect_layout(d) is not None), None)
        if other is not None:
            raise ValueError(f"{arg}: {str(p)!r} is a link to {str(real)!r}, a file of the object folder "
                             f"{str(other)!r}; each object's files are its own: copy the file in, or remove the link")


def read_folder(path: str | Path, max_images: int | None = None, layout: str | None = None, images: bool = True,
                arg: str = "path", scene: dict | None = None) -> FolderData:
    """Read one object folder of any layout in `LAYOUT_TABLE`.

    max_images: keep the first K images in loader order (deterministic). layout: force one (else detected).
    images: False reads only the first image (for its size): mask, ground truth and lights for evaluation.
    arg: the argument the folder came from, named first in every error about the folder or a file in it (which
    --val, --data or --input holds the bad file). scene: its scene.json as `read_scene_dict` returned it, when the
    caller already read it (every reader parses it once).
    """
    try:
        return _read_folder(Path(path), max_images, layout, images, arg, scene)
    except (ValueError, FileNotFoundError) as exc:
        if arg == "path" or str(exc).startswith(f"{arg}:"):
            raise
        raise (FileNotFoundError if isinstance(exc, FileNotFoundError) else ValueError)(f"{arg}: {exc}") from None


def _read_folder(folder: Path, max_images: int | None, layout: str | None, images: bool, arg: str,
                 scene: dict | None) -> FolderData:
    if not folder.is_dir():
        raise FileNotFoundError(f"{arg}: object folder {folder} does not exist (expected {ONE_FOLDER})")
    check_text_name(folder, arg)  # every output named after the object takes its name as text
    if layout is None:
        layout = detect_layout(folder)
        if layout is None:
            inside = next((p for p in sorted(folder.iterdir()) if p.is_dir() and detect_layout(p)), None)
            raise FileNotFoundError(f"{arg}: {folder} is not an object folder (expected {ONE_FOLDER})"
                                    + (f"; it holds object folders: pass one of them, e.g. {inside}" if inside else ""))
    entry = layout_named(layout)
    check_listed_done(folder, arg)  # whatever the layout: a folder without its scene.json too
    if max_images is not None and (isinstance(max_images, bool) or int(max_images) != max_images or max_images < 1):
        raise ValueError(f"max_images: must be an integer >= 1, got {max_images!r}")
    try:
        all_paths = entry.images(folder)
    except ValueError as exc:
        raise ValueError(f"{arg}: {exc}") from None
    if not all_paths:
        raise FileNotFoundError(f"{arg}: no images found in {folder} (expected {ONE_FOLDER})")
    for p in all_paths:
        check_text_name(p, arg)
    check_own_files(folder, arg)
    paths = all_paths[: int(max_images)] if max_images is not None else all_paths
    if scene is None and layout == "ours":
        scene = read_scene_dict(folder / SCENE_FILE)
    lights = entry.lights(folder, len(all_paths), scene)
    k = len(paths)
    # Cut the per-image calibration to the K images read; every other field is kept as the layout gave it.
    lights = replace(lights, directions=None if lights.directions is None else lights.directions[:k],
                     intensities=None if lights.intensities is None else lights.intensities[:k])
    sensor = _recorded_sensor(folder, scene if layout == "ours" else None, len(all_paths))
    if images:
        from scenes.camera_sensor import saturation_value

        stack, saturated = _read_stack(paths, saturation_value(sensor) if sensor is not None else 1.0)
        shape = stack.shape[1:3]
    else:
        stack = saturated = None
        shape = read_image(paths[0]).shape[:2]
    mask_path = folder / MASK_FILE
    if os.path.lexists(mask_path):  # read (or refused by name) whatever it is
        mask, mask_file = read_mask(mask_path, shape), mask_path
    elif entry.mask_required:
        raise FileNotFoundError(f"mask file {mask_path} does not exist (the {layout!r} layout needs one: white "
                                "object on black)")
    else:
        mask, mask_file = np.ones(shape, dtype=bool), None
    if stack is not None:
        _check_informative(stack, saturated, mask, folder, arg)
    normals = normals_file = None
    for name in entry.ground_truth:
        if os.path.lexists(folder / name):  # a pipe, a device or a folder too: refused by name, never "no truth"
            normals_file = folder / name
            normals = finish_normals(read_normals(normals_file, arg), mask, normals_file)
            break
    return FolderData(name=object_name(folder), path=folder, layout=layout, image_paths=list(paths),
                      num_files=len(all_paths), shape=tuple(shape), images=stack, saturated=saturated, mask=mask,
                      mask_file=mask_file, normals=normals, normals_file=normals_file, lights=lights,
                      has_scene=has_scene(folder), sensor=sensor)
