"""Did the camera move between the photos of a capture? From the images alone (`validate.diagnosis.usable` raises the
`camera_moved` warning from it).

A change of light changes the shading smoothly, so the log ratio of two photos taken by a still camera is smooth
(the albedo, texture and outline cancel); a camera that moved between them puts the outline and the texture of
one beside those of the other, and their ratio gets edges. For pairs of photos whose light is alike (their
brightness leans the same way), `pair_shift` finds the shift of one photo that leaves the least edge energy in
the ratio; `camera_motion` takes a motion as real only when one shift (the same within a pixel, seen from either
side) is found in a good share of the pairs: a still camera's pairs leave no shift, or chance ones that disagree.

The photos are cut to the object with a margin and kept at full resolution where the object is at most
`WORK_SIDE` pixels across (brought to it otherwise), so that a shift of 2 px stays 2 px.
"""
from __future__ import annotations

import numpy as np

WORK_SIDE = 384
"""Objects larger than this many pixels across are compared at a resolution that brings them to it."""
REACH = 5
"""The shifts searched: up to this many pixels on the halved images (twice as many at the working resolution)."""
PAIR_CUT = 0.9
"""A pair's shift counts when it leaves less than this share of the edge energy of the pair as taken."""
LOG_FLOOR = 0.02
"""Added to the images (times the capture's bright level) before the log: dark pixels and noise stay smooth."""
NEXT_LEAN = 0.1
"""A photo is also compared with the next one taken when their light leans (`light_leans`) differ by at most this
(in object radii): a rig that steps its lamp little by little, like DiLiGenT's, then pairs photos across a motion
of every other one; far apart lights would only add chance minima."""
MIN_SUPPORT = 0.5
"""A motion is taken when its shift is found in two pairs at least and in at least this share of the pairs that show
a shift: a still camera leaves a few chance shifts that disagree."""


def _gradients(x: np.ndarray) -> np.ndarray:
    gy, gx = np.gradient(x)
    return np.stack([gx, gy])


def _energies(ga: np.ndarray, gb: np.ndarray, centre: tuple[int, int], reach: int) -> dict[tuple[int, int], float]:
    """Per shift (dx, dy) within `reach` of `centre` (columns right, rows down): the mean edge energy
    |grad log b(moved back by the shift) - grad log a| over the frame less the border the search needs, from the
    gradients (2, H, W) of two log images."""
    r = reach + max(abs(centre[0]), abs(centre[1]))
    h, w = ga.shape[1] - 2 * r, ga.shape[2] - 2 * r
    a = ga[:, r:r + h, r:r + w]
    energy = {}
    for dy in range(centre[1] - reach, centre[1] + reach + 1):
        for dx in range(centre[0] - reach, centre[0] + reach + 1):
            d = gb[:, r + dy:r + dy + h, r + dx:r + dx + w] - a
            energy[(dx, dy)] = float(np.hypot(d[0], d[1]).mean())
    return energy


def _halve(x: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.resize(x, (x.shape[1] // 2, x.shape[0] // 2), interpolation=cv2.INTER_AREA)


def pair_shift(a: np.ndarray, b: np.ndarray, reach: int = REACH) -> tuple[tuple[int, int], float]:
    """((dx, dy), energy ratio): the shift of log image b (columns right, rows down) onto log image a that leaves the
    least edge energy in their difference, over the energy as taken. Searched within `reach` on both images halved,
    then to the pixel around twice that; a halved minimum on the border of the searched square (where the
    overlap shrinks, not a motion) gives ((0, 0), 1)."""
    coarse = _energies(_gradients(_halve(a)), _gradients(_halve(b)), (0, 0), reach)
    best = min(coarse, key=coarse.get)
    if best == (0, 0) or max(abs(best[0]), abs(best[1])) >= reach:
        return (0, 0), 1.0
    ga, gb = _gradients(a), _gradients(b)
    fine = _energies(ga, gb, (2 * best[0], 2 * best[1]), 1)
    shift = min(fine, key=fine.get)
    still = _energies(ga, gb, (0, 0), 0)[(0, 0)]
    return shift, fine[shift] / max(still, 1e-12)


def light_leans(images: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(K, 2) where each image's brightness leans on the object: its brightness-weighted centre less the object's,
    over the object's radius. Photos lit from about the same side lean alike; a shift of a few pixels hardly
    changes it."""
    gray = images.mean(axis=-1)[:, mask]
    rows, cols = np.nonzero(mask)
    offsets = np.stack([cols - cols.mean(), rows - rows.mean()], axis=1) / max(np.sqrt(mask.sum() / np.pi), 1.0)
    return (gray / np.maximum(gray.sum(axis=1, keepdims=True), 1e-12)) @ offsets


def partners(leans: np.ndarray, sample: int = 16, parts: int = 4) -> list[tuple[int, int]]:
    """Pairs (i, j), i < j, to compare: each of up to `sample` images spread over the capture with the image whose
    light leans most alike in each of `parts` stretches of the capture's order (a camera bumped at any time leaves
    pairs across the motion), and with the next image where its light leans alike (`NEXT_LEAN`)."""
    k = len(leans)
    checked = np.unique(np.linspace(0, k - 1, min(k, sample)).round().astype(int))
    bounds = np.linspace(0, k, min(k, parts) + 1).round().astype(int)
    pairs = {(int(i), int(i) + 1) for i in checked
             if i + 1 < k and np.linalg.norm(leans[i + 1] - leans[i]) <= NEXT_LEAN}
    for i in checked:
        for start, stop in zip(bounds[:-1], bounds[1:]):
            others = [j for j in range(start, stop) if j != i]
            if others:
                j = min(others, key=lambda j: float(np.linalg.norm(leans[j] - leans[i])))
                pairs.add((min(int(i), j), max(int(i), j)))
    return sorted(pairs)


def camera_shifts(images: np.ndarray, mask: np.ndarray | None = None, sample: int = 16,
                  parts: int = 4) -> tuple[list[tuple[int, int]], np.ndarray]:
    """(pairs (i, j), (M, 2) shift in pixels (x right, y up) of image j against image i, 0 where none cuts the
    edge energy below PAIR_CUT), on the pairs of `partners`; the object is `mask`, or what any image lights."""
    import cv2

    gray = images.mean(axis=-1)
    k = len(gray)
    level = max(float(np.percentile(gray, 99)), 1e-6)
    region = mask if mask is not None and mask.any() else (gray > 0.05 * level).any(axis=0)
    if k < 2 or not region.any():
        return [], np.zeros((0, 2))
    rows, cols = np.nonzero(region)
    f = max(1, int(np.ceil((max(np.ptp(rows), np.ptp(cols)) + 1) / WORK_SIDE)))
    m = 2 * f * (REACH + 4)
    gray = gray[:, max(rows.min() - m, 0):rows.max() + m + 1, max(cols.min() - m, 0):cols.max() + m + 1]
    if f > 1:
        gray = np.stack([cv2.resize(g, (g.shape[1] // f, g.shape[0] // f), interpolation=cv2.INTER_AREA) for g in gray])
    if min(gray.shape[1:]) < 4 * REACH + 4:  # too few pixels to search the shifts in: no motion can be told
        return [], np.zeros((0, 2))
    logs = np.log(np.maximum(gray, 0.0) + LOG_FLOOR * level).astype(np.float32)
    pairs = partners(light_leans(images, region), sample, parts)
    shifts = np.zeros((len(pairs), 2))
    for n, (i, j) in enumerate(pairs):
        (dx, dy), ratio = pair_shift(logs[i], logs[j])
        if ratio < PAIR_CUT:
            shifts[n] = (dx * f, -dy * f)
    return pairs, shifts


def camera_motion(
    pairs: list[tuple[int, int]], shifts: np.ndarray, min_px: float
) -> tuple[np.ndarray | None, np.ndarray]:
    """(the motion (x, y) in pixels, or None; the indices of the pairs that show it): the shift longer than `min_px`
    found (within a pixel, as s or -s) in the most pairs, taken when it parts the photos into two groups of at least
    two each (the photos shifted by s against those shifted by -s) and those pairs are at least MIN_SUPPORT of
    the pairs with a shift longer than `min_px`: one odd photo, or chance minima, do not."""
    long = np.nonzero(np.hypot(shifts[:, 0], shifts[:, 1]) > min_px)[0]
    best, support, _sides = None, np.zeros(0, int), (set(), set())
    for n in long:
        s = shifts[n]
        near = [m for m in long if min(np.abs(shifts[m] - s).max(), np.abs(shifts[m] + s).max()) <= 1]
        ahead = {pairs[m][1] if np.abs(shifts[m] - s).max() <= 1 else pairs[m][0] for m in near}
        behind = {pairs[m][0] if np.abs(shifts[m] - s).max() <= 1 else pairs[m][1] for m in near}
        if len(near) > len(support) and min(len(ahead), len(behind)) >= 2:
            best, support, _sides = s, np.array(near), (ahead, behind)
    if best is None or len(support) < MIN_SUPPORT * len(long):
        return None, np.zeros(0, int)
    return best, support
