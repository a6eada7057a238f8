"""The inputs of the integrator, checked: a normal map, its mask and the camera's intrinsics.

Each check raises a ValueError whose message starts with the flag the value came from and says what was
expected, so that a command turns it into one line (`scenes.cli.errors.report_error`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from scenes.files import not_a_file
from scenes.images import UNIT_TOLERANCE
from scenes.surface.integrate import Intrinsics, facing_away

UNIT_SHARE = 0.99
"""The share of the mask's normals that must be unit length (within `scenes.images.UNIT_TOLERANCE`); the rest (a
resampled outline) are renormalised."""
FACING_AWAY_LIMIT = 0.2
"""The largest share of mask pixels whose normal may face away from the camera (the integrator leaves their
equations out); above it a user's map is refused: it is not in the camera frame x right, y up, z toward the camera
(a map with z away faces away almost everywhere). A predicted map tilts a few percent past its silhouette: the
capture's own map read 3.5% under a strong perspective (sweep 31), which is no reason to refuse it."""
MIN_PIXELS = 4
"""The fewest mask pixels worth integrating."""
CENTRE_SLACK = 0.25
"""The principal point may lie this fraction of the image size from the image centre; further, the intrinsics
are taken to belong to another image size."""


def check_normals(normals: np.ndarray, mask: np.ndarray, flag: str = "--normals") -> np.ndarray:
    """Unit camera-frame normals over `mask` (H, W, 3) float64: NaN or a map that is not unit length is refused
    (normals facing away: `check_facing`, once the camera is known)."""
    n = np.asarray(normals, np.float64)
    inside = n[mask]
    bad = ~np.isfinite(inside).all(axis=1)
    if bad.any():
        raise ValueError(f"{flag}: {int(bad.sum())} normal(s) inside the mask are NaN or infinite; expected finite "
                         "unit vectors over the whole mask")
    length = np.linalg.norm(inside, axis=1)
    unit = np.abs(length - 1.0) <= UNIT_TOLERANCE
    if unit.mean() < UNIT_SHARE:
        rest = np.abs(np.linalg.norm(n[~mask], axis=1) - 1.0) <= UNIT_TOLERANCE
        inverted = "; the map's unit normals lie outside the mask: is --mask inverted (the object black on white)?" \
            if rest.size and rest.mean() >= UNIT_SHARE else ""
        if not inverted and (zero := float(np.mean(length == 0))) > 0:  # no normal there: the mask reaches past it
            inverted = f"; {100 * zero:.1f}% of them are 0 (no normal): does --mask cover more than the map's object?"
        raise ValueError(f"{flag}: {100 * (1 - unit.mean()):.1f}% of the normals inside the mask are not unit "
                         f"length (median length {np.median(length):.3f}); expected unit vectors (a 16-bit map "
                         f"stores (n + 1) / 2){inverted}")
    out = np.zeros_like(n)
    out[mask] = inside / np.maximum(length, 1e-12)[:, None]
    return out


def check_facing(normals: np.ndarray, mask: np.ndarray, intrinsics: Intrinsics | None,
                 flag: str = "--normals") -> None:
    """Refuse a map whose normals face away from the camera (`integrate.facing_away`, with its camera) on more than
    `FACING_AWAY_LIMIT` of the mask."""
    away = facing_away(normals, mask, intrinsics)
    if away.mean() > FACING_AWAY_LIMIT:
        raise ValueError(f"{flag}: {100 * away.mean():.1f}% of the normals inside the mask face away from the camera "
                         f"(at most {100 * FACING_AWAY_LIMIT:.0f}% may); expected the camera frame x right, y up, z "
                         "toward the camera")


def check_mask(mask: np.ndarray, shape: tuple[int, int], flag: str = "--mask") -> np.ndarray:
    """A (H, W) bool mask of the normal map's size with at least `MIN_PIXELS` pixels and one neighbour pair."""
    mask = np.asarray(mask)
    if mask.shape != tuple(shape):
        raise ValueError(f"{flag}: mask is {'x'.join(map(str, mask.shape))}, the normal map {shape[0]}x{shape[1]}; "
                         "expected the same height and width")
    mask = mask.astype(bool)
    if int(mask.sum()) < MIN_PIXELS:
        raise ValueError(f"{flag}: the mask has {int(mask.sum())} pixel(s); expected at least {MIN_PIXELS}")
    if not ((mask[:, 1:] & mask[:, :-1]).any() or (mask[1:] & mask[:-1]).any()):
        raise ValueError(f"{flag}: no two mask pixels are neighbours; expected a region, not scattered pixels")
    return mask


def check_intrinsics(k: np.ndarray, shape: tuple[int, int], flag: str = "--intrinsics") -> Intrinsics:
    """A 3 x 3 pinhole matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] for an image of `shape` (H, W)."""
    k = np.asarray(k, np.float64)
    if k.shape != (3, 3):
        raise ValueError(f"{flag}: intrinsics of shape {'x'.join(map(str, k.shape))}; expected a 3 x 3 matrix "
                         "[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]")
    if not np.isfinite(k).all():
        raise ValueError(f"{flag}: the intrinsics hold NaN or infinite values; expected a finite 3 x 3 matrix")
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        raise ValueError(f"{flag}: focal lengths fx = {k[0, 0]:g}, fy = {k[1, 1]:g}; expected both above 0 (pixels)")
    if abs(k[0, 1]) > 1e-9 or k[1, 0] or k[2, 0] or k[2, 1] or abs(k[2, 2] - 1) > 1e-9:
        raise ValueError(f"{flag}: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), got "
                         f"{np.array2string(k, separator=', ')}")
    h, w = shape
    _check_focal(min(k[0, 0], k[1, 1]), max(k[0, 0], k[1, 1]), shape, flag)
    cx, cy = k[0, 2], k[1, 2]
    if abs(cx - (w - 1) / 2) > CENTRE_SLACK * w or abs(cy - (h - 1) / 2) > CENTRE_SLACK * h:
        raise ValueError(f"{flag}: principal point ({cx:g}, {cy:g}) is far from the centre of the {w} x {h} normal "
                         "map; expected intrinsics for this image size")
    return Intrinsics.from_matrix(k)


def read_intrinsics(path: str | Path, shape: tuple[int, int], flag: str = "--intrinsics") -> Intrinsics:
    """Intrinsics from a text file of 3 rows of 3 numbers (np.savetxt of K)."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{flag}: {str(path)!r} is a folder; expected a text file of 3 rows of 3 numbers")
    if why := not_a_file(path):
        raise FileNotFoundError(f"{flag}: {str(path)!r} {why}")
    import warnings

    try:
        with warnings.catch_warnings():  # an empty file: numpy warns, then the shape check below says it
            warnings.simplefilter("ignore", UserWarning)
            k = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"{flag}: cannot read {path} as numbers ({exc}); expected 3 rows of 3 numbers") from None
    return check_intrinsics(k, shape, f"{flag}: {str(path)!r}")


def focal_intrinsics(focal_px: float, shape: tuple[int, int], flag: str = "--focal-px") -> Intrinsics:
    """Square pixels of focal length `focal_px`, the principal point at the image centre."""
    if not np.isfinite(focal_px) or focal_px <= 0:
        raise ValueError(f"{flag}: {focal_px!r}; expected a focal length above 0 in pixels")
    _check_focal(focal_px, focal_px, shape, flag)
    return Intrinsics.from_focal(focal_px, *shape)


FOCAL_RANGE = (0.05, 1e5)
"""Focal lengths in image diagonals: below the first the view is wider than about 170 deg (no pinhole camera),
above the second narrower than 0.001 deg, where a perspective solve loses its precision (leave the intrinsics out:
orthographic)."""


def _check_focal(low: float, high: float, shape: tuple[int, int], flag: str) -> None:
    diagonal = float(np.hypot(*shape))
    if low < FOCAL_RANGE[0] * diagonal or high > FOCAL_RANGE[1] * diagonal:
        bad = low if low < FOCAL_RANGE[0] * diagonal else high
        raise ValueError(f"{flag}: a focal length of {bad:g} px for a {shape[1]} x {shape[0]} map; expected "
                         f"{FOCAL_RANGE[0] * diagonal:g} to {FOCAL_RANGE[1] * diagonal:g} px (without intrinsics the "
                         "camera is orthographic)")


FULL_FRAME_DIAGONAL_MM = float(np.hypot(36.0, 24.0))
"""The diagonal of a 35 mm frame: a 35 mm-equivalent focal length is relative to it."""


def intrinsics_from_35mm(focal_35mm: float, shape: tuple[int, int]) -> Intrinsics:
    """A camera from a 35 mm-equivalent focal length (EXIF FocalLengthIn35mmFilm): the same field of view across the
    image's diagonal, square pixels, the principal point at the centre (an uncropped photo, any size)."""
    h, w = shape
    return Intrinsics.from_focal(focal_35mm * float(np.hypot(h, w)) / FULL_FRAME_DIAGONAL_MM, h, w)
