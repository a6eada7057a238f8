"""Reading a photometric-stereo capture that may have no scene.json (fitted mode of the re-render check).

Layouts (`scenes.layouts` detects them and lists their files):
- `ours`: our object folder (`L000.png..`, `mask.png`, optional `normal.tif`, `scene.json`); with the
  scene file removed it reads like `unips`. Calibrated lights come from `scene.json`'s `camera_lights`
  when every image has exactly one directional light.
- `diligent`: DiLiGenT `*PNG` folders: `001.png..` in `filenames.txt` order, `light_directions.txt`,
  `light_intensities.txt` (each image channel is divided by its row), `mask.png`, `Normal_gt.mat` or
  `Normal_gt.png`. Both files use the camera frame x right, y up, z toward the camera (checked by
  Lambertian least squares against the ground-truth normals in tests/test_fit.py and bench/bench_fit.py).
- `unips`: official UniPS `.data` folders: `L*` images (natural sort), `mask.png`, optional `normal.tif`
  or `Normal_gt.png`.

Normal maps (`read_normals`): 16-bit or 8-bit PNG / TIFF storing (n + 1) / 2 (the 32768 / 128 code is
background), float EXR, `.npy` (H, W, 3) or DiLiGenT `.mat`, camera frame; background decoded to 0.

Everything here is NumPy; errors are FileNotFoundError / ValueError with one line naming the argument.
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from scenes.layouts import ALL_IMAGE_SUFFIXES, detect_layout, diligent_images, l_images, read_diligent_lights
from scenes.objfolder import object_name, read_mask
from validate.io import read_normal_map, read_prediction

log = logging.getLogger(__name__)


@dataclass
class Capture:
    """One object's images with what is known about them (no scene description needed)."""

    name: str
    """Object name: folder name without a trailing '.data'."""
    folder: Path
    """The object folder."""
    layout: str
    """One of `scenes.layouts.LAYOUTS`."""
    images: np.ndarray
    """(K, H, W, 3) float32 linear images (DiLiGenT: divided by the light intensities)."""
    mask: np.ndarray
    """(H, W) bool object mask."""
    image_names: list[str]
    """File name of each image, in loader order (the order of report.json's `lights`)."""
    normal_gt: np.ndarray | None = None
    """(H, W, 3) float32 ground-truth camera-frame normals (0 outside the mask), when the folder has them."""
    light_directions: np.ndarray | None = None
    """(K, 3) calibrated unit directions toward the light, camera frame, when known."""
    light_irradiance: np.ndarray | None = None
    """(K, 3) calibrated RGB irradiance in image units, when known (DiLiGenT: ones after the division)."""
    has_scene: bool = False
    """True when the folder has a scene.json (known-scene mode is possible)."""
    downsample: int = 1
    """Factor by which images, mask and normals were reduced from the files (1 = as stored)."""
    meta: dict = field(default_factory=dict)
    """Layout-specific extras (e.g. DiLiGenT's raw light intensities)."""
    saturated: np.ndarray | None = None
    """(K, H, W, 3) bool: channels stored at the file's largest code (8/16-bit files), whose true value is
    only known to be at least the stored one; None when no channel is saturated (or the files are float)."""

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.mask.shape)  # type: ignore[return-value]


def read_image(path: Path) -> np.ndarray:
    """(H, W, 3) float32 linear RGB: `scenes.objfolder.read_image`, plus float EXR inputs."""
    from scenes.objfolder import read_exr
    from scenes.objfolder import read_image as read_ldr

    if Path(path).suffix.lower() == ".exr":
        img = read_exr(path)
        return np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img[:, :, :3]
    return read_ldr(path)


def unit_normals(n: np.ndarray, mask: np.ndarray, what: str = "--normals") -> np.ndarray:
    """Check shape against the mask, renormalise inside it, zero outside. Zero normals inside the mask
    (no estimate) become (0, 0, 1) with a warning."""
    if n.ndim != 3 or n.shape[2] != 3 or n.shape[:2] != mask.shape:
        raise ValueError(f"{what}: normal map has shape {n.shape}, expected {mask.shape + (3,)} (the size of the input images)")
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    missing = mask & (norm[..., 0] < 0.5)
    if missing.any():
        log.warning("%s: %d pixels inside the mask have no normal; using (0, 0, 1) there", what, int(missing.sum()))
    out = np.where(norm > 0.5, n / np.maximum(norm, 1e-12), np.array([0.0, 0.0, 1.0]))
    return np.where(mask[..., None], out, 0.0).astype(np.float32)


def load_with_normals(folder: str | Path, normals: str | Path | np.ndarray) -> tuple[Capture, np.ndarray, str]:
    """An object folder and the normal map to judge: (capture, unit normals inside its mask, source), where
    `normals` is an (H, W, 3) array or a file / prediction folder (the source is then its path)."""
    cap = load_capture(folder)
    normals, source = read_prediction(normals, cap.name)
    return cap, unit_normals(normals, cap.mask), source


def _camera_lights(folder: Path, k: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    try:
        scene = json.loads((folder / "scene.json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"--data: {str(folder / 'scene.json')!r} cannot be read as JSON ({exc})") from exc
    cam = scene.get("camera_lights") if isinstance(scene, dict) else None
    if not isinstance(cam, list) or len(cam) != k:
        return None, None
    dirs, irr = [], []
    for entry in cam:
        lights = entry.get("directional", []) if isinstance(entry, dict) else []
        if len(lights) != 1 or entry.get("other", 0):
            return None, None
        d = np.asarray(lights[0]["direction_to_light"], np.float64)
        dirs.append(d / np.linalg.norm(d))
        irr.append(np.asarray(lights[0]["irradiance"], np.float64))
    return np.asarray(dirs, np.float32), np.asarray(irr, np.float32)


def load_capture(folder: str | Path, max_images: int | None = None) -> Capture:
    """Load an object folder of any layout (see the module doc)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"--data: {str(folder)!r} is not a folder")
    layout = detect_layout(folder)
    if layout is None:
        raise FileNotFoundError(f"--data: {str(folder)!r} has no L*.png images and no DiLiGenT light_directions.txt")
    dirs = irr = None
    meta: dict = {}
    if layout == "diligent":
        paths = diligent_images(folder)
        dirs, raw = read_diligent_lights(folder, len(paths))
        dirs = dirs.astype(np.float32)
        meta["light_intensities_file"] = raw.tolist()
        irr = np.ones((len(paths), 3), np.float32)
    else:
        paths = l_images(folder, ALL_IMAGE_SUFFIXES)
        raw = None
    full_k = len(paths)  # before --max-images: scene.json's camera_lights has one entry per file
    if max_images is not None:
        paths = paths[: int(max_images)]
        dirs = dirs[: len(paths)] if dirs is not None else None
        irr = irr[: len(paths)] if irr is not None else None
        raw = raw[: len(paths)] if raw is not None else None
    first = read_image(paths[0])
    images = np.empty((len(paths),) + first.shape, np.float32)
    for i, p in enumerate(paths):
        img = first if i == 0 else read_image(p)
        if img.shape != first.shape:
            raise ValueError(f"images: {str(p)!r} has shape {img.shape}, expected {first.shape} like {paths[0].name}")
        images[i] = img
    # Integer files clip: a channel at the largest code (1.0 after read_image) is a lower bound, not a value.
    clipped = np.array([p.suffix.lower() != ".exr" for p in paths])
    saturated = (images >= 1.0) & clipped[:, None, None, None]
    if raw is not None:
        images /= raw[:, None, None, :].astype(np.float32)
    shape = first.shape[:2]
    mask = read_mask(folder / "mask.png", shape) if (folder / "mask.png").is_file() else np.ones(shape, bool)
    gt = None
    for gname in ("normal.tif", "Normal_gt.mat", "Normal_gt.png"):
        if (folder / gname).is_file():
            g = read_normal_map(folder / gname, "ground truth")
            if g.shape[:2] != shape:
                raise ValueError(f"ground truth: {str(folder / gname)!r} has shape {g.shape}, expected {shape + (3,)}")
            norm = np.linalg.norm(g, axis=-1, keepdims=True)
            gt = np.where(mask[..., None] & (norm > 0.5), g / np.maximum(norm, 1e-12), 0.0).astype(np.float32)
            break
    if layout == "ours":
        d2, i2 = _camera_lights(folder, full_k)
        if d2 is not None:
            dirs, irr = d2[: len(paths)], i2[: len(paths)]
    return Capture(
        name=object_name(folder),
        folder=folder,
        layout=layout,
        images=images,
        mask=mask,
        image_names=[p.name for p in paths],
        normal_gt=gt,
        light_directions=dirs,
        light_irradiance=irr,
        has_scene=(folder / "scene.json").is_file(),
        meta=meta,
        saturated=saturated if saturated.any() else None,
    )


def box_downsample(x: np.ndarray, f: int) -> np.ndarray:
    """Mean over f x f blocks of the two leading spatial axes of (H, W, ...) (cropped to a multiple of f)."""
    if f == 1:
        return x
    h, w = (x.shape[0] // f) * f, (x.shape[1] // f) * f
    x = x[:h, :w]
    return x.reshape(h // f, f, w // f, f, *x.shape[2:]).mean(axis=(1, 3))


def downsample_capture(cap: Capture, f: int) -> Capture:
    """A copy reduced by `f` (box filter; mask: pixels fully inside; normals renormalised; a reduced channel
    is saturated when any of its f x f sources was: its mean is then a lower bound too)."""
    if f == 1:
        return cap
    imgs = np.stack([box_downsample(im, f) for im in cap.images]).astype(np.float32)
    sat = None
    if cap.saturated is not None:
        sat = np.stack([box_downsample(s.astype(np.float32), f) > 0 for s in cap.saturated])
    cover = box_downsample(cap.mask.astype(np.float32), f)
    mask = cover > 0.999
    gt = None
    if cap.normal_gt is not None:
        gt = _downsample_normals(cap.normal_gt, mask, f)
    return Capture(
        name=cap.name, folder=cap.folder, layout=cap.layout, images=imgs, mask=mask, image_names=cap.image_names,
        normal_gt=gt, light_directions=cap.light_directions, light_irradiance=cap.light_irradiance,
        has_scene=cap.has_scene, downsample=cap.downsample * f, meta=cap.meta, saturated=sat,
    )


def _downsample_normals(n: np.ndarray, mask: np.ndarray, f: int) -> np.ndarray:
    s = box_downsample(n.astype(np.float64), f)
    norm = np.linalg.norm(s, axis=-1, keepdims=True)
    return np.where(mask[..., None] & (norm > 1e-6), s / np.maximum(norm, 1e-12), 0.0).astype(np.float32)


def downsample_normals(n: np.ndarray, mask_small: np.ndarray, f: int) -> np.ndarray:
    """A normal map (H, W, 3) reduced by `f` to the size of `mask_small` (renormalised, 0 outside)."""
    return n.astype(np.float32) if f == 1 else _downsample_normals(n, mask_small, f)
