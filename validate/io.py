"""The normal maps the check judges: read (a file, an array or a prediction folder, located by
`scenes.folder.format`, the one owner of the folder layout and prediction lookup) and checked against a mask.

Normal maps: camera frame (x right, y up, z toward the camera), full frame, as `unips.predict` writes
them; read with `scenes.images.read_normals`.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from scenes.files import not_a_file
from scenes.folder.format import find_prediction
from scenes.images import UNIT_TOLERANCE, read_normals

log = logging.getLogger(__name__)

AWAY_SHARE = 0.5
"""Largest share of a judged map's normals inside the mask that may face away from the camera (n_z < 0): a poor
estimate tilts some past the silhouette, a map in another convention (z away from the camera) tilts most."""
MAX_NORMAL_VALUE = 1e6
"""Largest accepted |component| of a normal map to judge, inside the mask. Maps are unit vectors; a larger value
means a wrongly scaled or corrupt map, and squaring it in float32 overflows (a 1e30-scaled map became all
zeros and was scored)."""


def check_magnitude(inside: np.ndarray, what: str) -> None:
    """Refuse normals (N, 3) with non-finite components or components above `MAX_NORMAL_VALUE`, naming `what`."""
    bad = ~np.isfinite(inside).all(axis=1)
    if bad.any():
        raise ValueError(f"{what}: {int(bad.sum())} normal(s) inside the mask are NaN or infinite")
    big = np.abs(inside).max(axis=1) > MAX_NORMAL_VALUE
    if big.any():
        raise ValueError(f"{what}: {int(big.sum())} normal(s) inside the mask have components up to "
                         f"{float(np.abs(inside).max()):.3g}, above {MAX_NORMAL_VALUE:g}; expected unit vectors "
                         "(the map is scaled wrongly or corrupt)")


def read_normal_map(path: str | Path, what: str = "--normals") -> np.ndarray:
    """Normal-map file -> (H, W, 3) float32 camera-frame normals, background 0 (not checked against a
    mask here); `scenes.images.read_normals`, which rejects non-finite values anywhere in the map.
    Errors name `what` (the argument the file came from)."""
    path = Path(path)
    if why := not_a_file(path):
        raise FileNotFoundError(f"{what}: {str(path)!r} {why}")
    return read_normals(path, what)


def read_prediction(normals: str | Path | np.ndarray, name: str) -> tuple[np.ndarray, str]:
    """The normal map to judge and where it came from: an (H, W, 3) array as is ("array"), else the
    prediction file of object `name` found by `scenes.folder.format.find_prediction` (its path)."""
    if isinstance(normals, np.ndarray):
        return normals, "array"
    path = find_prediction(normals, name)
    return read_normal_map(path), str(path)


def check_normals(
    n: np.ndarray, mask: np.ndarray, source: str = "--normals", allow_missing: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Check a normal map against an object mask: the one rule of both modes of the check and of refinement
    (`validate.observations.unit_normals` is the fitted modes' view of it).

    Returns (normals renormalised where valid and 0 elsewhere, valid (H, W) bool). Valid is the mask,
    minus the exactly-zero normals inside it when `allow_missing` (a predictor's "no estimate", e.g.
    pixels dark in every image). Raises ValueError for a wrong shape, or NaN / infinite / overflowing
    (`MAX_NORMAL_VALUE`) / non-unit normals inside the mask.
    """
    n = np.asarray(n)
    if n.ndim != 3 or n.shape[2] != 3 or n.shape[:2] != mask.shape:
        raise ValueError(
            f"{source}: normal map has shape {n.shape}, expected {mask.shape + (3,)} (the size of the input images)"
        )
    valid = mask.copy()
    if allow_missing:
        valid &= np.any(n != 0, axis=-1)
    inside = n[valid].astype(np.float64)
    check_magnitude(inside, source)
    norm = np.linalg.norm(inside, axis=1)
    off = np.abs(norm - 1.0) > UNIT_TOLERANCE
    if off.any():
        zero = int(np.sum(norm[off] == 0))
        hint = (
            f"; {zero} of them are exactly 0 (no estimate): --allow-missing keeps the surface's own normal there"
            if zero
            else ""
        )
        raise ValueError(
            f"{source}: {int(off.sum())} normal(s) inside the mask are not unit length "
            f"(|n| from {norm.min():.3f} to {norm.max():.3f}, tolerance {UNIT_TOLERANCE}){hint}"
        )
    away = float(np.mean(inside[:, 2] < 0)) if len(inside) else 0.0
    if away > AWAY_SHARE:  # a convention error, not a poor estimate: it would be judged as a very wrong map
        raise ValueError(f"{source}: {100 * away:.0f}% of the normals inside the mask face away from the camera (n_z < "
                         "0), which no surface the camera sees does; expected the camera frame x right, y up, z toward "
                         "the camera (a map whose z points away: flip it)")
    out = np.zeros(mask.shape + (3,), np.float32)
    out[valid] = (inside / norm[:, None]).astype(np.float32)
    return out, valid
