"""The published SDM-UniPS preprocessing (the data loader of its `main.py`), for the models whose registry entry's
contract asks for it (`unips.models.contract`: preprocess "sdm-unips"); `unips.inference.run_model` dispatches
here.

- Crop: the mask's bounding box grown by `SDM_MARGIN` px, its shorter side grown by half the difference on each
  side (clipped to the image); when the grown box would touch the image border, the whole image instead (then
  not square: it is stretched by the resize, as published).
- Resize: the crop to a square of side floor(longest side / 512) x 512, within [512, `largest`]
  (bicubic; the mask bicubic then > 0.5).
- Normalisation: each image divided by the maximum over the masked pixels of its channel mean (+ 1e-6).
- Images: at most `SDM_MAX_IMAGES` (10), a seeded random subset when there are more (the published loader
  draws one at random on every run).
- `--scalable` (`scalable_forward`): the working image split into its (side / `SDM_PATCH`)^2 interleaved sub-images
  `x[i::m, j::m]` (each of side `SDM_PATCH`, each the whole object at a coarser sampling, not a spatial piece),
  each predicted on its own as a working image of side `SDM_PATCH` (the encoder at the canonical resolution and
  its own 2 x 2 interleaved tiles), sub-images without object pixels skipped, the maps put back in their
  interleaved places (no overlap, no blending). The network's memory is then that of a `SDM_PATCH` image.
- Back: the network's map (zero outside the resized mask) resized bicubically to the crop, kept where its
  length is within 0.5 of 1, normalised, put into the full frame; zero outside the object's mask.

What is not bit-exact: the published loader resizes the 8/16-bit integer images, which OpenCV rounds to integers
and clips to their range; here the reader's float images are resized and clipped to [0, 1] (integer files only),
so values differ by at most half a code (1/510 of the range for 8-bit files, 1/131070 for 16-bit ones).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scenes.folder.layouts import FLOAT_SUFFIXES
from unips.data import PSObject
from unips.models.contract import SDM_UNIPS_INPUTS

SDM_MARGIN = SDM_UNIPS_INPUTS.margin
"""Pixels around the mask's bounding box (the published --mask_margin; the registry entry's contract)."""
SDM_STEP = 512
"""The working side is a multiple of this."""
SDM_LARGEST = 4096
"""Largest working side (the published --max_image_res)."""
SDM_MAX_IMAGES = SDM_UNIPS_INPUTS.max_images
"""Most images the network sees (the published --max_image_num; the contract's)."""
SDM_PATCH = SDM_UNIPS_INPUTS.patch
"""Side of the sub-images of `--scalable` (fixed at 512 in the published code; the contract's `patch`; a
parameter of `scalable_forward`, for tests)."""


@dataclass(frozen=True)
class SDMCrop:
    """Rows [r0, r1) and columns [c0, c1) of the original image, and the square side the crop is resized to."""

    r0: int
    r1: int
    c0: int
    c1: int
    side: int


def sdm_crop(mask: np.ndarray, margin: int = SDM_MARGIN, largest: int = SDM_LARGEST) -> SDMCrop:
    """The published crop of `mask (H, W)` and its working side."""
    h, w = mask.shape
    rows, cols = np.nonzero(mask)
    if rows.size == 0:
        raise ValueError("mask: is empty, cannot crop around the object")
    rmin, rmax, cmin, cmax = int(rows.min()), int(rows.max()), int(cols.min()), int(cols.max())
    tall, wide = rmax - rmin, cmax - cmin
    if rmin - margin <= 0 or rmax + margin > h or cmin - margin <= 0 or cmax + margin > w:
        r0, r1, c0, c1 = 0, h, 0, w
    elif tall > wide:
        grow = (tall - wide) // 2
        r0, r1, c0, c1 = rmin - margin, rmax + margin, max(cmin - grow - margin, 0), min(cmax + grow + margin, w)
    else:
        grow = (wide - tall) // 2
        r0, r1, c0, c1 = max(rmin - grow - margin, 0), min(rmax + grow + margin, h), cmin - margin, cmax + margin
    side = min(max(max(r1 - r0, c1 - c0) // SDM_STEP * SDM_STEP, SDM_STEP), largest)
    return SDMCrop(r0, r1, c0, c1, side)


def image_subset(k: int, max_images: int, seed: int) -> np.ndarray:
    """Indices of the images a published network reads: all K, or a seeded random `max_images` of them in
    their order (the authors draw an unseeded subset; ours is repeatable)."""
    if k <= max_images:
        return np.arange(k)
    return np.sort(np.random.default_rng(seed).permutation(k)[:max_images])


def sdm_inputs(obj: PSObject, crop: SDMCrop, max_images: int = SDM_MAX_IMAGES,
               seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """images `(K, S, S, 3)` float32 (normalised) and mask `(S, S)` float32 in {0, 1} of the crop."""
    import cv2

    chosen = image_subset(obj.num_images, max_images, seed)
    s = crop.side
    mask = cv2.resize(obj.mask[crop.r0:crop.r1, crop.c0:crop.c1].astype(np.float32), (s, s),
                      interpolation=cv2.INTER_CUBIC) > 0.5
    if not mask.any():
        raise ValueError(f"mask: {obj.name}'s object vanishes at the working side {s} px")
    images = np.stack([cv2.resize(obj.images[i, crop.r0:crop.r1, crop.c0:crop.c1], (s, s),
                                  interpolation=cv2.INTER_CUBIC) for i in chosen])  # (K, S, S, 3)
    if not any(Path(name).suffix.lower() in FLOAT_SUFFIXES for name in obj.image_names):
        images = np.clip(images, 0.0, 1.0)  # bicubic overshoot, saturated as OpenCV does for integer images
    brightest = images.mean(axis=3)[:, mask].max(axis=1)  # (K,): max over the object of the channel mean
    return (images / (brightest[:, None, None, None] + 1e-6)).astype(np.float32), mask.astype(np.float32)


def sdm_output(normals: np.ndarray, crop: SDMCrop, mask: np.ndarray) -> np.ndarray:
    """The network's `(S, S, 3)` map (zero outside its mask) back in the frame of `mask (H, W)`: `(H, W, 3)`."""
    import cv2

    n = cv2.resize(normals.astype(np.float32), (crop.c1 - crop.c0, crop.r1 - crop.r0), interpolation=cv2.INTER_CUBIC)
    length = np.linalg.norm(n, axis=2, keepdims=True)
    n = np.where(np.abs(1 - length) < 0.5, n / (length + 1e-12), 0.0)
    out = np.zeros(mask.shape + (3,), np.float32)
    out[crop.r0:crop.r1, crop.c0:crop.c1] = n
    return np.where(mask[..., None], out, 0.0).astype(np.float32)


def scalable_forward(model: Any, images: Any, mask: Any, patch: int = SDM_PATCH, rng: Any = None) -> Any:
    """The published `--scalable` prediction: `model` (an `SDMUniPS`) run on each of the (S / patch)^2 interleaved
    sub-images of images `(B, K, 3, S, S)` and mask `(B, 1, S, S)` (S a multiple of `patch`), in row-major order
    of their offsets, skipping those with no mask pixel; returns `(B, 3, S, S)`, each sub-image's normals in its
    interleaved places. `rng` (default: a generator seeded with 0) is shared by the sub-images in turn, as the
    published code shares numpy's global one."""
    side = images.shape[-1]
    if patch <= 0 or side % patch:
        raise ValueError(f"patch: {patch} does not divide the working side {side}; expected a divisor such as "
                         f"{SDM_PATCH} of a side that is a multiple of it")
    m = side // patch
    rng = np.random.default_rng(0) if rng is None else rng
    out = images.new_zeros(images.shape[0], 3, side, side)
    for i in range(m):
        for j in range(m):
            sub_mask = mask[..., i::m, j::m]
            if sub_mask.any():
                out[..., i::m, j::m] = model(images[..., i::m, j::m].contiguous(), sub_mask.contiguous(), rng=rng)
    return out
