"""Loading photometric-stereo objects from three folder layouts into one `PSObject`.

Layouts (detected automatically, or forced with ``layout=``):

- ``"ours"``: the project's ``<object>.data`` folder (`scenes.objfolder`, which owns its files, the
  mask rule and object naming): ``L000.png ...`` 16-bit linear RGB, ``mask.png``, ``normal.tif``,
  ``scene.json`` (light family and camera-frame lights).
- ``"unips"``: official UniPS / SDM-UniPS folders: images ``L*`` (png, jpg, tif, bmp; 8 or 16 bit),
  optional ``mask.png`` (any value > 0 is foreground; whole image when absent), optional ``normal.tif``
  or ``Normal_gt.png``.
- ``"diligent"``: DiLiGenT: ``001.png ...`` (order from ``filenames.txt`` when present),
  ``light_directions.txt``, ``light_intensities.txt``, ``mask.png``, ``Normal_gt.mat`` or
  ``Normal_gt.png``. Images are returned raw, as the camera recorded them (the UniPS papers' protocol
  for uncalibrated methods: a model never sees the calibration); the file's values are returned as
  ``light_intensities`` for calibrated methods, which divide by them (`unips.baselines`).

Images are returned linear in [0, 1] (16-bit / 65535, 8-bit / 255; 8-bit JPEGs are not linearised:
the official loaders do not either). Everything is RGB and in the camera frame x right, y up,
z toward the camera (DiLiGenT uses the same frame: its light directions and normals are consistent,
which the least-squares baseline reproducing the published errors confirms).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scenes.layouts import LAYOUTS, detect_layout, diligent_images, l_images, read_diligent_lights
from scenes.objfolder import MASK_FILE, NORMAL_FILE, SCENE_FILE, object_name, read_image, read_mask, read_normals, read_scene_dict

log = logging.getLogger(__name__)

EXPECTED = ("an object folder: L*.png + scene.json (ours), L* images (UniPS), or DiLiGenT "
            "001.png... + light_directions.txt; or a directory of such folders")


@dataclass
class PSObject:
    """One photometric-stereo object: K images of a static scene under changing lighting."""

    name: str  # folder name minus a trailing ".data" (e.g. "foo.data" -> "foo", "ballPNG" -> "ballPNG")
    images: np.ndarray  # (K, H, W, 3) float32, linear RGB
    mask: np.ndarray  # (H, W) bool, True on the object
    normals: np.ndarray | None  # (H, W, 3) float32 ground truth, unit inside mask, 0 outside; None if absent
    light_family: str | None  # "directional" | "point" | "near_area" | "hdri" | "mixed"; None if unknown
    light_directions: np.ndarray | None  # (K, 3) unit vectors toward the light (camera frame); directional only
    light_intensities: np.ndarray | None  # (K, 3) RGB intensity of each light as seen in `images`
    path: Path  # the object folder
    layout: str  # one of LAYOUTS
    image_names: list[str] = field(default_factory=list)  # file names of the K images, in order
    meta: dict[str, Any] = field(default_factory=dict)  # layout-specific extras (e.g. raw intensities)

    @property
    def num_images(self) -> int:
        return int(self.images.shape[0])


def find_objects(path: str | Path) -> list[Path]:
    """The object folders at ``path``: itself if it is one, else its sorted subfolders that are."""
    root = Path(path)
    if not root.exists():
        raise FileNotFoundError(f"path: {root} does not exist (expected {EXPECTED})")
    if detect_layout(root) is not None:
        return [root]
    if root.is_dir():
        found = [p for p in sorted(root.iterdir(), key=lambda p: p.name) if detect_layout(p) is not None]
        if found:
            return found
    raise FileNotFoundError(f"path: no object folder found at {root} (expected {EXPECTED})")


# ----------------------------------------------------------------------------------------- files


def _finish_normals(n: np.ndarray, mask: np.ndarray, path: Path) -> np.ndarray:
    """Check the size, zero the background and normalise inside the mask."""
    if n.ndim != 3 or n.shape[2] != 3:
        raise ValueError(f"normal file {path}: expected shape (H, W, 3), got {n.shape}")
    if n.shape[:2] != mask.shape:
        raise ValueError(f"normal file {path}: size {n.shape[1]}x{n.shape[0]} differs from the images' "
                         f"{mask.shape[1]}x{mask.shape[0]}")
    if not np.all(np.isfinite(n)):
        raise ValueError(f"normal file {path}: contains NaN or infinite values")
    n = n.astype(np.float32).copy()
    n[~mask] = 0.0
    norm = np.linalg.norm(n, axis=2, keepdims=True)
    n = np.where(norm > 1e-6, n / np.maximum(norm, 1e-12), 0.0).astype(np.float32)
    n_zero = int(np.sum(mask & (norm[..., 0] <= 1e-6)))
    if n_zero:
        log.warning("%s: %d mask pixels have a zero ground-truth normal", path, n_zero)
    return n


def read_normal_file(path: Path, mask: np.ndarray) -> np.ndarray:
    return _finish_normals(read_normals(path), mask, path)


def _load_stack(paths: list[Path]) -> np.ndarray:
    """(K, H, W, 3) float32 from image files that must all have the same size."""
    first = read_image(paths[0])
    stack = np.empty((len(paths),) + first.shape, dtype=np.float32)
    stack[0] = first
    for i, p in enumerate(paths[1:], start=1):
        img = read_image(p)
        if img.shape != first.shape:
            raise ValueError(f"image file {p}: size {img.shape[1]}x{img.shape[0]} differs from "
                             f"{paths[0].name}'s {first.shape[1]}x{first.shape[0]}")
        stack[i] = img
    return stack


def _take(paths: list[Path], max_images: int | None, folder: Path) -> list[Path]:
    if not paths:
        raise FileNotFoundError(f"path: no images found in {folder} (expected {EXPECTED})")
    if max_images is not None:
        if int(max_images) < 1:
            raise ValueError(f"max_images: must be >= 1, got {max_images}")
        paths = paths[: int(max_images)]
    return paths


# --------------------------------------------------------------------------------------- layouts


def _load_ours(folder: Path, max_images: int | None) -> PSObject:
    all_paths = l_images(folder)
    n_all = len(all_paths)
    paths = _take(all_paths, max_images, folder)
    images = _load_stack(paths)
    shape = images.shape[1:3]
    mask = read_mask(folder / MASK_FILE, shape)
    normals = read_normal_file(folder / NORMAL_FILE, mask) if (folder / NORMAL_FILE).is_file() else None
    scene_path = folder / SCENE_FILE
    scene = read_scene_dict(scene_path)
    family = scene.get("light_family")
    directions = intensities = None
    cam = scene.get("camera_lights")
    if cam is not None:
        if not isinstance(cam, list) or len(cam) != n_all:
            got = len(cam) if isinstance(cam, list) else type(cam).__name__
            raise ValueError(f"scene file {scene_path}: camera_lights has {got} entries, expected {n_all} "
                             "(one per image)")
        directions, intensities = _directional(cam[: len(paths)], scene_path)
    return PSObject(name=object_name(folder), images=images, mask=mask, normals=normals,
                    light_family=family, light_directions=directions, light_intensities=intensities,
                    path=folder, layout="ours", image_names=[p.name for p in paths])


def _directional(cam: list, scene_path: Path) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Directions and irradiances when every image has exactly one directional light and nothing else."""
    dirs, irr = [], []
    for i, entry in enumerate(cam):
        lights = entry.get("directional", []) if isinstance(entry, dict) else None
        if lights is None or len(lights) != 1 or entry.get("other", 0) != 0:
            return None, None
        try:
            d = np.asarray(lights[0]["direction_to_light"], dtype=np.float64)
            e = np.asarray(lights[0]["irradiance"], dtype=np.float64)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"scene file {scene_path}: camera_lights[{i}] is malformed ({exc})") from exc
        if d.shape != (3,) or e.shape != (3,) or not (np.all(np.isfinite(d)) and np.all(np.isfinite(e))):
            raise ValueError(f"scene file {scene_path}: camera_lights[{i}] needs finite 3-vectors, got "
                             f"direction {d.tolist()} irradiance {e.tolist()}")
        norm = np.linalg.norm(d)
        if norm < 1e-9:
            raise ValueError(f"scene file {scene_path}: camera_lights[{i}] has a zero direction")
        dirs.append(d / norm)
        irr.append(e)
    return np.asarray(dirs, np.float32), np.asarray(irr, np.float32)


def _load_unips(folder: Path, max_images: int | None) -> PSObject:
    paths = _take(l_images(folder), max_images, folder)
    images = _load_stack(paths)
    shape = images.shape[1:3]
    mask_path = folder / "mask.png"
    mask = read_mask(mask_path, shape) if mask_path.is_file() else np.ones(shape, dtype=bool)
    normals = None
    for gt_name in ("normal.tif", "Normal_gt.png"):
        if (folder / gt_name).is_file():
            normals = read_normal_file(folder / gt_name, mask)
            break
    return PSObject(name=object_name(folder), images=images, mask=mask, normals=normals, light_family=None,
                    light_directions=None, light_intensities=None, path=folder, layout="unips",
                    image_names=[p.name for p in paths])


def _load_diligent(folder: Path, max_images: int | None) -> PSObject:
    all_paths = diligent_images(folder)
    n_all = len(all_paths)
    paths = _take(all_paths, max_images, folder)
    directions, raw_int = read_diligent_lights(folder, n_all)
    directions, raw_int = directions[: len(paths)], raw_int[: len(paths)]
    images = _load_stack(paths)  # raw: the calibration stays out of what a model sees
    shape = images.shape[1:3]
    mask_path = folder / "mask.png"
    mask = read_mask(mask_path, shape) if mask_path.is_file() else np.ones(shape, dtype=bool)
    normals = None
    if (folder / "Normal_gt.mat").is_file():
        normals = read_normal_file(folder / "Normal_gt.mat", mask)
    elif (folder / "Normal_gt.png").is_file():
        normals = read_normal_file(folder / "Normal_gt.png", mask)
    return PSObject(name=object_name(folder), images=images, mask=mask, normals=normals,
                    light_family="directional", light_directions=directions.astype(np.float32),
                    light_intensities=raw_int.astype(np.float32), path=folder, layout="diligent",
                    image_names=[p.name for p in paths], meta={"light_intensities_file": raw_int})


_LOADERS = {"ours": _load_ours, "unips": _load_unips, "diligent": _load_diligent}


def load_object(path: str | Path, max_images: int | None = None, layout: str | None = None) -> PSObject:
    """Load one object folder.

    max_images: keep the first K images in the folder's order (natural sort of names, or DiLiGenT's
    filenames.txt); deterministic. layout: force ``"ours"``, ``"unips"`` or ``"diligent"``.
    """
    folder = Path(path)
    if not folder.is_dir():
        raise FileNotFoundError(f"path: object folder {folder} does not exist (expected {EXPECTED})")
    if layout is None:
        layout = detect_layout(folder)
        if layout is None:
            raise FileNotFoundError(f"path: {folder} is not an object folder (expected {EXPECTED})")
    elif layout not in LAYOUTS:
        raise ValueError(f"layout: unknown layout {layout!r}, expected one of {LAYOUTS}")
    obj = _LOADERS[layout](folder, max_images)
    log.debug("loaded %s (%s): %d images %dx%d", folder, layout, obj.num_images, obj.images.shape[2],
              obj.images.shape[1])
    return obj


@dataclass
class GroundTruth:
    """What evaluation needs from an object folder, read without loading every image."""

    name: str  # object name (folder name minus a trailing ".data")
    mask: np.ndarray  # (H, W) bool
    normals: np.ndarray | None  # (H, W, 3) float32, unit inside mask; None when the folder has none
    light_family: str | None  # from scene.json ("ours"), "directional" for DiLiGenT, else None
    path: Path  # the object folder
    layout: str  # one of LAYOUTS


def load_ground_truth(path: str | Path, layout: str | None = None) -> GroundTruth:
    """Mask, ground-truth normals and light family of an object folder (reads one image for its size)."""
    folder = Path(path)
    if not folder.is_dir():
        raise FileNotFoundError(f"path: object folder {folder} does not exist (expected {EXPECTED})")
    layout = layout or detect_layout(folder)
    if layout is None:
        raise FileNotFoundError(f"path: {folder} is not an object folder (expected {EXPECTED})")
    if layout not in LAYOUTS:
        raise ValueError(f"layout: unknown layout {layout!r}, expected one of {LAYOUTS}")
    if layout == "diligent":
        images = diligent_images(folder)
        gt_names = ("Normal_gt.mat", "Normal_gt.png")
    else:
        images = l_images(folder)
        gt_names = ("normal.tif", "Normal_gt.png")
    if not images:
        raise FileNotFoundError(f"path: no images found in {folder} (expected {EXPECTED})")
    shape = read_image(images[0]).shape[:2]
    mask_path = folder / "mask.png"
    if mask_path.is_file():
        mask = read_mask(mask_path, shape)
    elif layout == "ours":
        raise FileNotFoundError(f"mask file {mask_path} does not exist")
    else:
        mask = np.ones(shape, dtype=bool)
    normals = None
    for gt_name in gt_names:
        if (folder / gt_name).is_file():
            normals = read_normal_file(folder / gt_name, mask)
            break
    family: str | None = None
    if layout == "ours":
        family = read_scene_dict(folder / SCENE_FILE).get("light_family")
    elif layout == "diligent":
        family = "directional"
    return GroundTruth(name=object_name(folder), mask=mask, normals=normals, light_family=family,
                       path=folder, layout=layout)
