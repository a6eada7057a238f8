"""Controlled errors on a normal map, for the tests and the bench of the re-render check.

- `random`: each pixel tilted by exactly `angle` toward an independent random tangent direction
  (mean angular error = angle);
- `smooth`: every pixel tilted by exactly `angle` toward a tangent direction taken from a smooth random
  vector field (a low-frequency error, mean angular error = angle);
- `bias`: the whole map rotated by `angle` about one random axis in the image plane (a constant
  calibration-like error; pixels close to the axis move less, so the mean error is below `angle`).
Only pixels inside the mask change; the background stays 0.
"""
from __future__ import annotations

import numpy as np

KINDS = ("random", "smooth", "bias")


def _tilt(n: np.ndarray, direction: np.ndarray, angle_rad: float) -> np.ndarray:
    """Tilt unit normals n (N, 3) by angle toward `direction` (N, 3) projected on their tangent plane."""
    t = direction - n * np.sum(direction * n, axis=1, keepdims=True)
    norm = np.linalg.norm(t, axis=1, keepdims=True)
    # Rare degenerate directions (parallel to n): any perpendicular will do.
    alt = np.cross(n, np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
    t = np.where(norm > 1e-6, t / np.maximum(norm, 1e-12), alt / np.linalg.norm(alt, axis=1, keepdims=True))
    return np.cos(angle_rad) * n + np.sin(angle_rad) * t


def perturb_normals(
    n: np.ndarray, mask: np.ndarray, kind: str, angle_deg: float, seed: int, smooth_sigma: float | None = None
) -> np.ndarray:
    """A perturbed copy of the camera-frame normal map n (H, W, 3), changed inside `mask` (H, W) only.

    smooth_sigma: Gaussian width (pixels) of the `smooth` field; default a sixth of the image size.
    """
    from scipy.ndimage import gaussian_filter

    if kind not in KINDS:
        raise ValueError(f"kind: {kind!r} is not a perturbation, expected one of {', '.join(KINDS)}")
    if not np.isfinite(angle_deg) or not 0 <= angle_deg <= 90:
        raise ValueError(f"angle_deg: expected a value in [0, 90], got {angle_deg!r}")
    rng = np.random.default_rng(seed)
    h, w = mask.shape
    base = n[mask].astype(np.float64)
    base /= np.maximum(np.linalg.norm(base, axis=1, keepdims=True), 1e-12)
    a = np.radians(angle_deg)
    if kind == "random":
        new = _tilt(base, rng.normal(size=base.shape), a)
    elif kind == "smooth":
        sigma = smooth_sigma if smooth_sigma is not None else max(h, w) / 6.0
        field = np.stack([gaussian_filter(rng.normal(size=(h, w)), sigma, mode="wrap") for _ in range(3)], -1)
        new = _tilt(base, field[mask], a)
    else:
        phi = rng.uniform(0, 2 * np.pi)
        axis = np.array([np.cos(phi), np.sin(phi), 0.0])
        # Rodrigues rotation of every normal about the same axis.
        c, s = np.cos(a), np.sin(a)
        new = base * c + np.cross(axis, base) * s + axis * (base @ axis)[:, None] * (1 - c)
    out = np.zeros_like(n, dtype=np.float32)
    out[mask] = (new / np.linalg.norm(new, axis=1, keepdims=True)).astype(np.float32)
    return out
