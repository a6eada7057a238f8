"""Analytic inputs of the tests, one factory per concept: the sphere and the ellipsoid on a pixel grid, draws of
light directions, Lambertian shading. Camera frame throughout: x right (columns), y up (-rows), z toward the
camera; pixel (i, j) has its centre at (i + 0.5, j + 0.5). Written from the geometry, not from the code under test."""
from __future__ import annotations

import numpy as np


def sphere(size: int = 32, pad: float = 2, center: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (size, size, 3) of a sphere filling a size x size image (radius size / 2 - pad pixels, centre
    (row, column) `center`, default the image centre), zero off it, and its mask."""
    cy, cx = center if center is not None else (size / 2, size / 2)
    rows, cols = np.mgrid[0:size, 0:size]
    r = size / 2 - pad
    x = (cols + 0.5 - cx) / r
    y = -(rows + 0.5 - cy) / r  # image rows grow downward, y grows upward
    mask = x * x + y * y < 1.0
    n = np.zeros((size, size, 3))
    n[..., 0], n[..., 1] = x, y
    n[..., 2] = np.sqrt(np.clip(1.0 - x * x - y * y, 0.0, None))
    n[~mask] = 0.0
    return n, mask


def ortho_sphere(res: int, half: float = 1.1, samples: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The unit sphere at the origin as an orthographic camera on the z axis with half size `half` sees it on a
    res x res grid (the scenes' default camera: camera frame = world frame): per pixel the front-surface point
    (x, y, sqrt(1 - x^2 - y^2)), which is also its normal (z = 0 off the sphere), and x^2 + y^2 (< 1 on it);
    shapes (res, res, 3) and (res, res). With `samples`: at samples x samples sub-pixel centres per pixel,
    shapes (res, res, samples^2, 3) and (res, res, samples^2)."""
    s = samples or 1
    n = res * s
    c = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(c * half, -c * half)
    r2 = x * x + y * y
    points = np.stack([x, y, np.sqrt(np.clip(1 - x * x - y * y, 0, None))], -1)
    if samples is None:
        return points, r2
    points = points.reshape(res, s, res, s, 3).transpose(0, 2, 1, 3, 4).reshape(res, res, s * s, 3)
    return points, r2.reshape(res, s, res, s).transpose(0, 2, 1, 3).reshape(res, res, s * s)


def ellipsoid_normals(h: int, w: int, ci: float, cj: float, ri: float, rj: float) -> tuple[np.ndarray, np.ndarray]:
    """Normals (H, W, 3) and mask of an ellipsoid seen orthographically, from image-space parameters.

    Centre (row ci, column cj) in continuous pixel units, semi-axes ri along the rows and rj along the columns,
    depth semi-axis 0.7 min(ri, rj).
    """
    i, j = np.mgrid[0:h, 0:w] + 0.5
    x, y = j - cj, -(i - ci)
    c = 0.7 * min(ri, rj)
    q = 1.0 - (x / rj) ** 2 - (y / ri) ** 2
    mask = q > 0.02
    z = c * np.sqrt(np.clip(q, 0.0, None))
    n = np.stack([x / rj ** 2, y / ri ** 2, z / c ** 2], axis=-1)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(mask[..., None], n, 0.0), mask


def cone_lights(k: int, seed: int = 0, max_deg: float = 40.0, min_deg: float = 5.0) -> np.ndarray:
    """k unit directions toward the light, zenith uniform in [min_deg, max_deg] degrees, azimuth uniform."""
    rng = np.random.default_rng(seed)
    th = np.radians(rng.uniform(min_deg, max_deg, k))
    ph = rng.uniform(0.0, 2.0 * np.pi, k)
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=1)


def random_lights(rng: np.random.Generator, k: int) -> np.ndarray:
    """k unit directions toward the light in the upper hemisphere (z >= 0.5 before normalising: none grazing)."""
    v = rng.normal(size=(k, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.5
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def shading(normals: np.ndarray, lights: np.ndarray) -> np.ndarray:
    """(K, H, W) max(0, n . l_k): Lambertian shading with attached shadows."""
    return np.clip(np.einsum("hwc,kc->khw", normals, lights), 0.0, None)


def lambertian(normals: np.ndarray, mask: np.ndarray, lights: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """Images (K, 3, H, W): albedo[k] * max(0, n . l_k) inside the mask."""
    return (shading(normals, lights) * mask)[:, None] * albedo[:, :, None, None]
