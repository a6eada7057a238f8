"""The fitted re-render check's view of a capture: an object folder that may have no scene.json.

Every layout (ours with or without scene.json, official UniPS `.data`, DiLiGenT `*PNG`) is read by the one
reader, `scenes.folder.layouts.read_folder` (its table lists each layout's files and the shared rules); this
module repackages the result as a `Capture`: DiLiGenT images divided by their light intensities (so a
calibrated irradiance is one), saturated channels kept as lower bounds, and the downsampling of the fit.

Normal maps to judge (`load_with_normals`): 16-bit or 8-bit PNG / TIFF storing (n + 1) / 2 (the 32768 / 128
code is background), float EXR, `.npy` (H, W, 3) or DiLiGenT `.mat`, camera frame; background decoded to 0.

Everything here is NumPy; errors are FileNotFoundError / ValueError with one line naming the argument.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from scenes.description import SceneDescription
from scenes.folder.format import SCENE_FILE, read_scene_dict, scene_from_dict
from scenes.folder.layouts import layout_named, read_folder
from validate.io import check_normals, read_prediction

log = logging.getLogger(__name__)


@dataclass
class Capture:
    """One object's images with what is known about them (no scene description needed)."""

    name: str
    """Object name: folder name without a trailing '.data'."""
    folder: Path
    """The object folder."""
    layout: str
    """One of `scenes.folder.layouts.LAYOUTS`, or "memory" for a capture built from arrays."""
    images: np.ndarray
    """(K, H, W, 3) float32 linear images (DiLiGenT: divided by the light intensities); None only for a known scene
    read without them (`load_known_scene(images=False)`, the checks before any rendering)."""
    mask: np.ndarray
    """(H, W) bool object mask (None only for photos read before their mask is found: `orchestrate.capture`)."""
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
    desc: SceneDescription | None = None
    """The scene of the K images, for the known-scene check (`load_known_scene`); None otherwise."""

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.mask.shape)  # type: ignore[return-value]


def unit_normals(n: np.ndarray, mask: np.ndarray, what: str = "--normals") -> np.ndarray:
    """The one check of a normal map to judge (`validate.io.check_normals`, the known-scene check's rule:
    finite, unit within `validate.io.UNIT_TOLERANCE` and renormalised, anything else refused naming `what`
    and the count), zero outside the mask. Exactly-zero normals inside the mask (no estimate) are allowed
    and become (0, 0, 1) with a warning."""
    out, valid = check_normals(n, mask, what, allow_missing=True)
    if mask.any() and not valid.any():  # a map of (0, 0, 1) made up here would be judged as if predicted
        raise ValueError(f"{what}: every normal inside the mask ({int(mask.sum())} pixels) is exactly 0, no estimate "
                         "anywhere; expected a normal map of the object")
    missing = mask & ~valid
    if missing.any():
        log.warning("%s: %d pixels inside the mask have no normal; using (0, 0, 1) there", what, int(missing.sum()))
        out[missing] = np.float32([0.0, 0.0, 1.0])
    return out


def capture_from_arrays(
    name: str,
    images: np.ndarray,
    mask: np.ndarray | None,
    image_names: list[str],
    saturated: np.ndarray | None = None,
    folder: str | Path = ".",
    meta: dict | None = None,
) -> Capture:
    """A capture held in memory (no object folder on disk): linear images (K, H, W, 3), mask (H, W) (None: not
    found yet), and the clipped channels (K, H, W, 3) kept exactly as given, so that a channel clipped in the photo
    stays a lower bound whatever scaling the images went through (codes re-derived from a rescaled file would not
    say it)."""
    k = len(images)
    if images.ndim != 4 or images.shape[-1] != 3 or (mask is not None and images.shape[1:3] != mask.shape):
        raise ValueError(f"images: shape {images.shape} with mask {None if mask is None else mask.shape}, expected "
                         "(K, H, W, 3) and (H, W)")
    if saturated is not None and saturated.shape != images.shape:
        raise ValueError(f"saturated: shape {saturated.shape}, expected that of the images {images.shape}")
    if len(image_names) != k:
        raise ValueError(f"image_names: {len(image_names)} names for {k} images")
    return Capture(
        name=name,
        folder=Path(folder),
        layout="memory",
        images=np.asarray(images, np.float32),
        mask=None if mask is None else np.asarray(mask, bool),
        image_names=list(image_names),
        saturated=saturated if saturated is not None and saturated.any() else None,
        meta=dict(meta or {}),
    )


def load_with_normals(folder: str | Path, normals: str | Path | np.ndarray) -> tuple[Capture, np.ndarray, str]:
    """An object folder and the normal map to judge: (capture, unit normals inside its mask, source), where
    `normals` is an (H, W, 3) array or a file / prediction folder (the source is then its path)."""
    cap = load_capture(folder)
    normals, source = read_prediction(normals, cap.name)
    return cap, unit_normals(normals, cap.mask, f"--normals ({source})" if source != "array" else "--normals"), source


def load_capture(folder: str | Path, max_images: int | None = None, arg: str = "--data") -> Capture:
    """Load an object folder of any layout (`scenes.folder.layouts.read_folder`) for the fitted check; `arg`: the
    flag that named it, in errors."""
    fd = read_folder(folder, max_images=max_images, arg=arg)
    images = fd.linear()  # the check compares light: a recorded sensor's response and black level undone
    meta: dict = {}
    dirs, irr = fd.lights.directions, fd.lights.intensities
    if fd.layout == "diligent":
        # Calibrated methods divide by the intensity file; after it every light has unit irradiance.
        meta["light_intensities_file"] = irr.tolist()
        images = images / irr[:, None, None, :].astype(np.float32)
        irr = np.ones_like(irr)
    return Capture(
        name=fd.name,
        folder=fd.path,
        layout=fd.layout,
        images=images.astype(np.float32, copy=False),
        mask=fd.mask,
        image_names=fd.image_names,
        normal_gt=fd.normals,
        light_directions=None if dirs is None else dirs.astype(np.float32),
        light_irradiance=None if irr is None else irr.astype(np.float32),
        has_scene=fd.has_scene,
        meta=meta,
        saturated=fd.saturated,
    )


def load_known_scene(folder: str | Path, images: bool = True) -> Capture:
    """An object folder with its scene, for the known-scene check (`scenes.folder.layouts.read_folder`, layout
    "ours"; scene.json parsed once): linear images (exposure applied, a recorded camera sensor undone), mask,
    ground truth and `desc`. FileNotFoundError / ValueError naming what is missing or inconsistent with scene.json.
    images: False reads only the first image (its size): what the checks before any rendering need."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"--data: {str(folder)!r} is not a folder")
    scene = read_scene_dict(folder)
    desc = scene_from_dict(scene, folder / SCENE_FILE)
    files = layout_named("ours").images(folder)  # counted first: a missing image is named as such
    if len(files) != len(desc.images):
        raise ValueError(f"images: {str(folder)!r} has {len(files)} L*.png files but scene.json describes "
                         f"{len(desc.images)} images")
    fd = read_folder(folder, layout="ours", arg="--data", images=images, scene=scene)
    h, w = desc.camera.height, desc.camera.width
    if fd.shape != (h, w):
        raise ValueError(f"images: {str(fd.image_paths[0])!r} are {fd.shape[1]}x{fd.shape[0]}, expected {w}x{h} "
                         f"from the camera of {str(folder / SCENE_FILE)!r}")
    return Capture(name=fd.name, folder=fd.path, layout=fd.layout, images=fd.linear() if images else None,
                   mask=fd.mask, image_names=fd.image_names, normal_gt=fd.normals, has_scene=True,
                   saturated=fd.saturated, desc=desc)


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
