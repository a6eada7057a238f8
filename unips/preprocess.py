"""Preprocessing as in UniPS: square crop around the object, per-image normalisation, resizing.

- Crop: the bounding box of the mask grown by ``margin`` pixels on every side, then the shorter side
  grown (centred) to make a square of side S. The square may extend past the image: those pixels are
  zero (image, mask and normals).
- Normalisation: each image is divided by its mean over the masked pixels and the three channels
  (a scalar per image; not zero-mean, which would amplify dark, noisy regions). Pixels outside the mask
  keep their (scaled) values: the model multiplies by the mask itself.
- `uncrop` puts an (S, S, 3) prediction back into the original (H, W) frame, background 0.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from unips.data import PSObject


@dataclass(frozen=True)
class CropInfo:
    """Where the square crop lies in the original image."""

    y0: int  # row of the crop's top-left corner in the original image (may be negative)
    x0: int  # column of the crop's top-left corner (may be negative)
    size: int  # side S of the square crop, in original pixels
    full_shape: tuple[int, int]  # (H, W) of the original image


@dataclass
class Prepared:
    """An object ready for a network: cropped, normalised, possibly resized to a working resolution."""

    images: np.ndarray  # (K, R, R, 3) float32, each image divided by its masked mean
    mask: np.ndarray  # (R, R) bool
    normals: np.ndarray | None  # (R, R, 3) float32, unit inside mask, 0 outside; None without ground truth
    crop: CropInfo  # where the crop came from (always in original pixels; R may differ from crop.size)
    scales: np.ndarray  # (K,) float32, the divisor applied to each image

    @property
    def resolution(self) -> int:
        return int(self.mask.shape[0])


def crop_box(mask: np.ndarray, margin: int = 4) -> CropInfo:
    """Square crop around the mask's bounding box grown by ``margin``."""
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 2:
        raise ValueError(f"mask: expected a 2-D array, got shape {mask.shape}")
    if margin < 0:
        raise ValueError(f"margin: must be >= 0, got {margin}")
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        raise ValueError("mask: is empty, cannot crop around the object")
    r0, r1 = int(rows[0]) - margin, int(rows[-1]) + margin  # inclusive
    c0, c1 = int(cols[0]) - margin, int(cols[-1]) + margin
    h, w = r1 - r0 + 1, c1 - c0 + 1
    size = max(h, w)
    return CropInfo(y0=r0 - (size - h) // 2, x0=c0 - (size - w) // 2, size=size,
                    full_shape=(int(mask.shape[0]), int(mask.shape[1])))


def _overlap(crop: CropInfo) -> tuple[slice, slice, slice, slice]:
    """Slices (src rows, src cols) in the image and (dst rows, dst cols) in the crop that overlap."""
    H, W = crop.full_shape
    ys, xs = max(crop.y0, 0), max(crop.x0, 0)
    ye, xe = min(crop.y0 + crop.size, H), min(crop.x0 + crop.size, W)
    return (slice(ys, ye), slice(xs, xe), slice(ys - crop.y0, ye - crop.y0), slice(xs - crop.x0, xe - crop.x0))


def apply_crop(array: np.ndarray, crop: CropInfo, leading: int = 0) -> np.ndarray:
    """Crop an array whose axes ``leading`` and ``leading + 1`` are (H, W); zero outside the image."""
    if array.shape[leading:leading + 2] != crop.full_shape:
        raise ValueError(f"array: spatial shape {array.shape[leading:leading + 2]} differs from the crop's "
                         f"image shape {crop.full_shape}")
    out_shape = array.shape[:leading] + (crop.size, crop.size) + array.shape[leading + 2:]
    out = np.zeros(out_shape, dtype=array.dtype)
    sy, sx, dy, dx = _overlap(crop)
    idx_src = (slice(None),) * leading + (sy, sx)
    idx_dst = (slice(None),) * leading + (dy, dx)
    out[idx_dst] = array[idx_src]
    return out


def prepare(obj: PSObject, margin: int = 4) -> Prepared:
    """Crop ``obj`` to a square around its mask and divide each image by its masked mean."""
    crop = crop_box(obj.mask, margin)
    images = apply_crop(obj.images, crop, leading=1)  # (K, S, S, 3)
    mask = apply_crop(obj.mask, crop)
    normals = apply_crop(obj.normals, crop) if obj.normals is not None else None
    means = images[:, mask, :].mean(axis=(1, 2), dtype=np.float64)  # (K,)
    # An image that is black on the object has nothing to normalise: leave it as is.
    scales = np.where(means > 1e-8, means, 1.0).astype(np.float32)
    images = images / scales[:, None, None, None]
    return Prepared(images=images.astype(np.float32), mask=mask, normals=normals, crop=crop, scales=scales)


def _unit(n: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(norm > 1e-8, n / np.maximum(norm, 1e-12), 0.0).astype(np.float32)


def resize_mask(mask: np.ndarray, size: int) -> np.ndarray:
    """(S, S) bool -> (size, size) bool: area average then threshold at 0.5."""
    import cv2

    m = cv2.resize(mask.astype(np.float32), (size, size), interpolation=cv2.INTER_AREA)
    return m > 0.5


def resize_normals(normals: np.ndarray, size: int, mask: np.ndarray | None = None) -> np.ndarray:
    """(S, S, 3) -> (size, size, 3): area (down) / linear (up) resampling, renormalised, 0 outside mask."""
    import cv2

    if normals.ndim != 3 or normals.shape[2] != 3:
        raise ValueError(f"normals: expected shape (S, S, 3), got {normals.shape}")
    interp = cv2.INTER_AREA if size < normals.shape[0] else cv2.INTER_LINEAR
    n = _unit(cv2.resize(normals.astype(np.float32), (size, size), interpolation=interp))
    if mask is not None:
        if mask.shape != (size, size):
            raise ValueError(f"mask: shape {mask.shape} differs from the target ({size}, {size})")
        n[~mask] = 0.0
    return n


def resize_prepared(p: Prepared, size: int, flag: str = "size") -> Prepared:
    """The same object at a working resolution ``size`` (images INTER_AREA, mask area + threshold); `flag`: the
    option that gave it, named in its errors."""
    import cv2

    if int(size) < 1:
        raise ValueError(f"{flag}: must be >= 1, got {size}")
    size = int(size)
    if size == p.resolution:
        return p
    images = np.stack([cv2.resize(im, (size, size), interpolation=cv2.INTER_AREA) for im in p.images])
    mask = resize_mask(p.mask, size)
    if not mask.any():
        raise ValueError(f"{flag}: {size} px is too small, the object's mask vanishes when resized to it; expected a "
                         "working resolution the object shows at")
    normals = resize_normals(p.normals, size, mask) if p.normals is not None else None
    return replace(p, images=images.astype(np.float32), mask=mask, normals=normals)


def uncrop(normals_crop: np.ndarray, crop: CropInfo | Prepared, full_shape: tuple[int, int] | None = None,
           mask: np.ndarray | None = None) -> np.ndarray:
    """Put (S, S, 3) normals predicted on a crop back into the (H, W, 3) original frame.

    ``crop`` is a CropInfo or a Prepared (whose mask then zeroes the background). Predictions at a
    working resolution other than S are resized first. ``mask`` (H, W), when given, zeroes the
    background in the original frame.
    """
    crop_mask = None
    if isinstance(crop, Prepared):
        crop_mask = crop.mask
        crop = crop.crop
    if full_shape is not None and tuple(full_shape) != crop.full_shape:
        raise ValueError(f"full_shape: {tuple(full_shape)} differs from the crop's image shape {crop.full_shape}")
    n = np.asarray(normals_crop, dtype=np.float32)
    if n.ndim != 3 or n.shape[2] != 3 or n.shape[0] != n.shape[1]:
        raise ValueError(f"normals_crop: expected shape (S, S, 3), got {n.shape}")
    if n.shape[0] != crop.size:
        n = resize_normals(n, crop.size)
        if crop_mask is not None:
            crop_mask = resize_mask(crop_mask, crop.size)
    if crop_mask is not None:
        if crop_mask.shape != n.shape[:2]:
            crop_mask = resize_mask(crop_mask, n.shape[0])
        n = np.where(crop_mask[..., None], n, 0.0).astype(np.float32)
    H, W = crop.full_shape
    out = np.zeros((H, W, 3), dtype=np.float32)
    sy, sx, dy, dx = _overlap(crop)
    out[sy, sx] = n[dy, dx]
    if mask is not None:
        if mask.shape != (H, W):
            raise ValueError(f"mask: shape {mask.shape} differs from the image shape {(H, W)}")
        out[~mask.astype(bool)] = 0.0
    return out
