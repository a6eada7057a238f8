"""Where the light changes the picture: the light variation, the seed Otsu's threshold cuts from it, and the object
GrabCut grows from a seed. `validate.diagnosis.usable.auto_mask` reads the mask from them; `mask_doubts` reads the
variation a second way to see whether the mask depends on how it was read.

Two readings of one variation. The first cuts the variation itself (over its 99.5th percentile): a strong class
(the object) against a weak one (the background). Where a shiny object's highlights vary far more than its body, that
cut keeps the highlights and calls the body background; the second reading cuts the logarithm of the variation,
where the body (a little light) and the background (none) lie apart. Neither is always right (the logarithm lifts a
lit floor or the sensor's noise with the object); a mask that changes with the reading is doubted.
"""
from __future__ import annotations

import numpy as np

LOG_FLOOR = 1e-4
"""The second reading's logarithm starts here (variation over its 99.5th percentile): four decades."""


def gray(images: np.ndarray) -> np.ndarray:
    return images.mean(axis=-1)  # (K, H, W)


def all_black(images: np.ndarray) -> str | None:
    """Why no mask can be found where every image is all but black over the whole frame (its 99th percentile
    below one 8-bit step: a lens cap, a lamp that never fired), else None."""
    level = float(np.percentile(gray(images), 99, axis=(1, 2)).max())
    if level >= 1.0 / 255:
        return None
    return (f"every image is all but black (its bright part at most {level:.4f} of the full scale, below one 8-bit "
            "step): light the object, or expose longer (16-bit files holding an 8-bit range: write them at full scale)")


def variation_map(images: np.ndarray) -> np.ndarray:
    """(H, W) float32: standard deviation over the images of each pixel's gray value, over the capture's bright
    level (99.5th percentile of the mean image), so about 0 for what the light does not change."""
    g = gray(images)
    level = max(float(np.percentile(g.mean(axis=0), 99.5)), 1e-6)
    return (g.std(axis=0) / level).astype(np.float32)


def otsu(values: np.ndarray) -> tuple[float, float]:
    """(threshold, separability) of Otsu's method on `values` in [0, 1] (256 bins)."""
    hist, edges = np.histogram(np.clip(values, 0, 1), bins=256, range=(0, 1))
    p = hist / max(hist.sum(), 1)
    centers = (edges[:-1] + edges[1:]) / 2
    w0 = np.cumsum(p)
    mu = np.cumsum(p * centers)
    total = mu[-1]
    between = (total * w0 - mu) ** 2 / np.maximum(w0 * (1 - w0), 1e-12)
    k = int(np.argmax(between))
    var = float(np.sum(p * (centers - total) ** 2))
    return float(centers[k]), float(between[k] / var) if var > 0 else 0.0


def variation_seed(images: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(light variation over its 99.5th percentile, Otsu's threshold on it, Otsu's separability): above the
    threshold is the seed of the automatic mask."""
    var = variation_map(images)
    scaled = var / max(float(np.percentile(var, 99.5)), 1e-6)
    threshold, separability = otsu(scaled)
    return scaled, threshold, separability


def log_seed(scaled: np.ndarray) -> np.ndarray:
    """The second reading's seed (module doc): Otsu's threshold on the variation's logarithm (from `LOG_FLOOR`)."""
    decades = -np.log10(LOG_FLOOR)
    t, _ = otsu((np.log10(np.clip(scaled, LOG_FLOOR, None)) + decades) / decades)
    return scaled > 10 ** (t * decades - decades)


def border_ring(shape: tuple[int, int]) -> np.ndarray:
    """The frame's border, 3 % of its shorter side wide: taken as background."""
    ring = np.zeros(shape, bool)
    b = max(1, round(0.03 * min(shape)))
    ring[:b], ring[-b:], ring[:, :b], ring[:, -b:] = True, True, True, True
    return ring


HOLE_LEVEL = 0.25
"""A hole inside the object is kept open where 90 % of it varies less than this share of Otsu's threshold: the
background seen through it (a ring's or a handle's opening). Holes that vary more are filled: a dark pocket of an
object still catches some light (measured below `validate.diagnosis.usable.mask_doubts`'s constants)."""


def largest_filled(mask: np.ndarray, scaled: np.ndarray | None = None, threshold: float = 0.0,
                   touching: np.ndarray | None = None) -> np.ndarray:
    """The largest connected part of `mask` (with `touching`: every part that overlaps it) with its holes filled,
    except those through which the background shows (`HOLE_LEVEL`, where the variation `scaled` and its
    `threshold` are given)."""
    import cv2
    from scipy import ndimage

    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros_like(mask, bool)
    if touching is None:
        part = labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    else:
        part = np.isin(labels, np.setdiff1d(np.unique(labels[touching]), [0]))
    filled = ndimage.binary_fill_holes(part)
    if scaled is None:
        return filled
    holes, count = ndimage.label(filled & ~part)
    for i in range(1, count + 1):
        hole = holes == i
        if np.percentile(scaled[hole], 90) < HOLE_LEVEL * threshold:
            filled &= ~hole
    return filled


def grown_object(images: np.ndarray, seed: np.ndarray, scaled: np.ndarray | None = None,
                 threshold: float = 0.0, touching: np.ndarray | None = None) -> np.ndarray:
    """The object GrabCut grows from `seed` on the brightest picture (the border ring outside the seed is sure
    background), its largest part (or the parts `touching` a given mask) with holes filled but those the
    background shows through (`largest_filled`)."""
    import cv2

    bright = gray(images).max(axis=0)
    top = max(float(np.percentile(bright, 99.5)), 1e-6)
    picture = (np.clip(bright / top, 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)
    gc = np.where(seed, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
    gc[border_ring(seed.shape) & ~seed] = cv2.GC_BGD
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.grabCut(np.repeat(picture[..., None], 3, axis=2), gc, None, bgd, fgd, 5, cv2.GC_INIT_WITH_MASK)
    return largest_filled(np.isin(gc, (cv2.GC_FGD, cv2.GC_PR_FGD)), scaled, threshold, touching)
