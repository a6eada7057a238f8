"""How much of a mask one flat surface explains: the table, cloth or backdrop an automatic mask can take for the object
(`validate.diagnosis.usable.mask_doubts`, `doubtful_mask`).

Under distant light a flat surface has one normal, so every pixel of it varies across the photos in the same way: its
gray values are one profile (K values, one per photo) times its albedo, whatever its texture. Where the object casts
a shadow on it, the pixel is dark in those photos and follows the profile in the others. `flat_share` finds the
profile that the most pixels of the mask follow (within `FLAT_ANGLE_DEG`, among evenly spaced candidate pixels) and
returns the share of the mask that follows it in every photo where it is not in shadow (darker than `FLAT_DARK` of
what the profile says). A curved object spreads its pixels over many profiles; a floor in the mask is one profile.

Measured: the true masks of 282 rendered objects (orchestrate.error_calibration's suites) read a median of 0.04, 99 %
below 0.34, one above 0.4 (a bright metal object under an environment map, 0.50); two thin flat swords in
bench/bench_doubtful_mask.py's suites 0.42 and 0.46; DiLiGenT ball and cat 0.07 and 0.11; the six real course
objects of ../shared/data/real/psm 0.04 to 0.14. Automatic masks that took a rendered floor (`wildgen.make --floor`)
with or for the object read 0.40 to 0.99. A light that does not move (a flash at the lens) lights every surface alike:
there every pixel follows one profile, and `mask_doubts` does not ask this measurement.
"""
from __future__ import annotations

import numpy as np

FLAT_ANGLE_DEG = 5.0
"""Two pixels' profiles (their gray values across the photos, as unit vectors) this close are one surface's."""
FLAT_DARK = 0.3
"""A photo where a pixel is below this share of what the flat surface's profile says is a shadow on it, left out."""
PIXELS = 20000
"""Mask pixels used (evenly strided; all when fewer): the share is a proportion, and this bounds the memory."""
CANDIDATES = 300
"""Pixels whose profile is tried as the flat surface's (evenly strided over the used pixels)."""


def flat_share(images: np.ndarray, mask: np.ndarray) -> float:
    """Share of `mask` that one flat surface under the photos' lights explains (module doc); 0 for fewer than 3
    photos or an empty mask."""
    gray = images.mean(axis=-1)[:, mask]  # (K, P)
    if images.shape[0] < 3 or gray.shape[1] == 0:
        return 0.0
    pick = np.unique(np.linspace(0, gray.shape[1] - 1, min(gray.shape[1], PIXELS)).astype(np.int64))
    return float(_follows(gray[:, pick].T.astype(np.float64)).mean())


def flat_outside_share(images: np.ndarray, mask: np.ndarray) -> float:
    """Share of `mask` that is flat (`flat_share`'s surface, small specks opened away) and lies outside the convex
    hull of the rest of it: a surface that reaches out beside and under the object, as a cushion or a table taken
    with it does. An object's own flat faces lie within its outline's hull. The mask is read on a grid of every
    f-th pixel (f so that at most `PIXELS` of it remain); 0 for fewer than 3 photos or an empty mask."""
    import cv2

    f = max(1, int(np.ceil(np.sqrt(mask.sum() / PIXELS))))
    mask = mask[::f, ::f]
    if images.shape[0] < 3 or not mask.any():
        return 0.0
    flat = np.zeros(mask.shape, np.uint8)
    flat[mask] = _follows(images[:, ::f, ::f].mean(axis=-1)[:, mask].T.astype(np.float64))
    flat = cv2.morphologyEx(flat, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)) > 0
    rest = np.argwhere(mask & ~flat)[:, ::-1].astype(np.int32)  # (N, 2) x, y
    if len(rest) < 3:
        return 0.0
    hull = np.zeros(mask.shape, np.uint8)
    cv2.fillConvexPoly(hull, cv2.convexHull(rest), 1)
    return float((flat & (hull == 0)).sum() / mask.sum())


def _follows(g: np.ndarray) -> np.ndarray:
    """(P,) bool: the pixels of `g` (P, K gray values across the photos) that follow the profile most of them follow
    (module doc)."""
    norm = np.linalg.norm(g, axis=1)
    lit = norm > 1e-6 * max(float(norm.max()), 1e-30)
    if not lit.any():
        return lit
    u = np.where(lit[:, None], g / np.maximum(norm, 1e-30)[:, None], 0.0)
    cos = np.cos(np.radians(FLAT_ANGLE_DEG))
    tried = np.nonzero(lit)[0][np.unique(np.linspace(0, lit.sum() - 1, min(int(lit.sum()), CANDIDATES)).astype(int))]
    profile = u[tried[int(np.argmax((u @ u[tried].T > cos).sum(0)))]]  # (K,) the profile most pixels follow
    strong = profile > 0.3 * profile.max()  # the photos that light the surface well
    m = profile[strong]
    scale = g[:, strong] @ m / max(float(m @ m), 1e-30)  # each pixel's albedo times the surface's brightness
    shadow = g[:, strong] < FLAT_DARK * np.maximum(scale[:, None] * m[None], 1e-30)  # (P, S)
    seen = np.where(shadow, 0.0, g[:, strong])
    along = seen @ m / np.maximum(np.linalg.norm(seen, axis=1) * np.sqrt(((~shadow) * m ** 2).sum(1)), 1e-30)
    return lit & (along > cos) & ((~shadow).sum(1) >= max(3, int(strong.sum()) // 2))
