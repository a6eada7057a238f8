"""The capture's map at the photos' own size when it worked on smaller copies (`--max-side`, by default
`DEFAULT_MAX_SIDE`).

The model, the check, the refinement, the expected error and the surface run at the working size, where 7 photos of
24 megapixels fit in a few GiB and minutes on 2 cores (docs/capture.md, "Big photos"). normal.png, normal.exr and
mask.png are then written at the photos' size (`upsample`): the mask guided by the photos themselves (He et al.'s
guided filter, OpenCV's `ximgproc.guidedFilter`, with the mean photo as the guide), so that the outline sits where
the photos put it; the normals upsampled linearly inside it. The upsampled map holds no detail finer than the working
size: a finer map asks for `--max-side 0` (the photos' own size, within the memory estimate).
"""
from __future__ import annotations

import math

import numpy as np

DEFAULT_MAX_SIDE = 1536
"""The working size's longer side by default (px): 7 JPEG photos of 25 megapixels take 116 s and 3.3 GiB on 2 cores
(bench/bench_capture.py). The shipped network was trained at 128 px: on held-out renders a map made at a quarter of
the photos' side is within 0.3 degree of one made at their side (bench/bench_full_size.py), while memory and time grow
with the pixels."""
GUIDE_EPS = 1e-3
"""The guided filter's regulariser on a guide scaled to [0, 1]: edges of the guide weaker than about its square root
(a contrast of 3 %) are smoothed over, stronger ones are kept in the mask."""
BYTES_PER_FULL_PIXEL = 48
"""Peak bytes per pixel of the photos' size beyond the working size's: one photo decoded at a time (its codes, its
float32 values, its clipped channels, the guide's sum) and the map and mask brought to that size and written
(measured: 46 bytes a pixel for `upsample` and the files at 25 megapixels); the memory estimate adds it
(`orchestrate.capture_estimate.estimate`)."""


def radius(working: tuple[int, int], full: tuple[int, int]) -> int:
    """The guided filter's radius (px of the photos): the upsampling factor, at least 2."""
    return max(2, math.ceil(max(full[0] / working[0], full[1] / working[1])))


def guide_image(mean_gray: np.ndarray) -> np.ndarray:
    """The guide: the mean photo (linear gray, (H, W)) compressed by a square root and scaled to [0, 1] (its 99.9th
    percentile is 1), so that dark and bright parts of the object have edges of comparable weight."""
    top = float(np.quantile(mean_gray[::7, ::7], 0.999)) or 1.0
    return np.sqrt(np.clip(mean_gray / top, 0.0, 1.0)).astype(np.float32)


def upsample(normals: np.ndarray, mask: np.ndarray, guide: np.ndarray,
             full_mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(unit normals (H, W, 3) float32, 0 outside the mask; mask (H, W) bool) at the guide's size (H, W) from the
    working map `normals` (h, w, 3) and `mask` (h, w).

    The mask is upsampled linearly and filtered with `guide` (He et al.'s guided filter), above one half: its outline
    follows the photos' edges (less than half the wrong outline pixels of a plain upsampling at a factor 4,
    `bench/bench_full_size.py`).
    The normals are upsampled linearly, each mask pixel's normal carried first to the background pixels nearest to
    it (so that none is missing at the new outline), and normalised: guiding them as well smoothed them over the
    filter's window and cost 0.1-1.3 deg on rendered objects. `full_mask`, the user's own mask at the photos' size,
    is kept as it is."""
    import cv2
    from scipy import ndimage

    h_full, w_full = guide.shape
    if full_mask is not None:
        out_mask = full_mask.astype(bool)
    else:
        big = cv2.resize(mask.astype(np.float32), (w_full, h_full), interpolation=cv2.INTER_LINEAR)
        out_mask = cv2.ximgproc.guidedFilter(guide, big, radius(mask.shape, guide.shape), GUIDE_EPS) > 0.5
        del big
    _, (iy, ix) = ndimage.distance_transform_edt(~mask, return_indices=True)
    filled = normals[iy, ix].astype(np.float32)  # (h, w, 3): every pixel the normal of its nearest mask pixel
    out = cv2.resize(filled, (w_full, h_full), interpolation=cv2.INTER_LINEAR)
    norm = np.linalg.norm(out, axis=-1)
    ok = out_mask & (norm > 1e-6)
    out /= np.maximum(norm, 1e-12)[..., None]
    out[~ok] = 0.0
    return out, ok


def downscale_mask(mask: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A mask at the photos' size brought to the working `shape` (area average above one half)."""
    import cv2

    return cv2.resize(mask.astype(np.float32), (shape[1], shape[0]), interpolation=cv2.INTER_AREA) > 0.5
