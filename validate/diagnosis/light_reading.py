"""Each photo's light read from the shading of the whole object under a normal map (the capture's light warnings,
`validate.diagnosis.usable.light_warnings`).

A photo's light is the direction l that best explains its gray values I over the object as a diffuse term and a
specular lobe, I = c_d albedo max(0, n . l) + c_s max(0, n . h)^e (h the half vector between l and the viewing
direction, c_d, c_s >= 0, the lobe's exponent e one of `LOBES`), searched over `CANDIDATES` directions spread evenly
over the hemisphere in front of the object and then on a finer grid around the best one; the least squares of the
two coefficients are closed-form for every candidate at once. The per-pixel albedo comes first, from a Lambertian
fit (I = albedo n . b over the lit pixels, albedo and b in turns). A diffuse-only reading (the Lambertian b) read
the lights of metal objects, whose photos are a highlight on a dark surface, up to 50 deg off (90 % of photos
within 36-49 deg); the lobe reads them within 10-16 deg. A near or environment light gives its mean direction.

Measured on 62 rendered objects of 3 light families and three material classes under their true normals (every
third object of orchestrate.error_calibration's renders): the direction 2 to 6 deg off for directional and grid
lights (median per family and material; 90 % within 10 to 44 deg, the tail on diffuse objects with deep shadows),
9 to 16 deg for point lights near the object, whose direction changes over it.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from validate.diagnosis.mask_seed import gray as mean_gray

LIT_SHARE = 0.2
"""The Lambertian albedo fit uses the pixels brighter than this share of the photo's 95th percentile (the attached
shadow and its dim edge, where I = n . b does not hold, left out)."""
LOBES = (8.0, 32.0, 128.0)
"""Exponents of the specular lobe tried (broad to sharp highlights)."""
CANDIDATES = 400
"""Light directions tried first, spread evenly over the hemisphere in front of the object (about 7 deg apart; the
finer grid reaches 6 deg around the best). Against 800 candidates and 4000 pixels: the same accuracy (medians within
1 deg, 90th percentiles within 3) in a third of the time, 0.13 s a photo on 2 busy cores."""
FINE_STEP_DEG, FINE_REACH = 1.5, 4
"""The finer grid around the best candidate: this step, this many steps each way in two directions."""
SAMPLE_PIXELS = 2000
"""The object's pixels used in the search (evenly strided; all when fewer)."""


@lru_cache(maxsize=1)
def _hemisphere(count: int = CANDIDATES) -> np.ndarray:
    """(count, 3) directions with z > 0 spread evenly (a Fibonacci lattice, equal areas)."""
    i = np.arange(count) + 0.5
    z = i / count
    phi = np.pi * (1 + 5 ** 0.5) * i
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


def _around(direction: np.ndarray) -> np.ndarray:
    """The finer grid of directions around `direction` (z > 0 kept)."""
    side = np.array([1.0, 0, 0]) if abs(direction[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(direction, side)
    u /= np.linalg.norm(u)
    v = np.cross(direction, u)
    t = np.radians(FINE_STEP_DEG) * np.arange(-FINE_REACH, FINE_REACH + 1)
    du, dv = np.meshgrid(t, t)
    c = direction[None] + du.reshape(-1, 1) * u + dv.reshape(-1, 1) * v
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    return c[c[:, 2] > 0]


def lambertian_albedo(gray: np.ndarray, n: np.ndarray, rounds: int = 4) -> np.ndarray:
    """(P,) per-pixel albedo (median 1) of gray values (K, P) under unit normals (P, 3): I = albedo n . b fitted in
    turns over each photo's lit pixels (`LIT_SHARE`)."""
    k = len(gray)
    top = np.percentile(gray, 95, axis=1)
    use = (gray > LIT_SHARE * top[:, None]) & (top[:, None] > 0)  # (K, P)
    albedo = np.ones(gray.shape[1])
    b = np.zeros((k, 3))
    for _ in range(rounds):
        for i in range(k):
            if use[i].sum() >= 10:
                b[i] = np.linalg.lstsq(n[use[i]], gray[i, use[i]] / albedo[use[i]], rcond=None)[0]
        shade = np.where(use, np.clip(b @ n.T, 0, None), 0.0)  # (K, P)
        energy = (shade ** 2).sum(0)
        albedo = np.where(energy > 0, (gray * shade).sum(0) / np.maximum(energy, 1e-12), 1.0)
        albedo = np.clip(albedo / max(float(np.median(albedo)), 1e-12), 0.05, 20.0)
    return albedo


def _best(y: np.ndarray, n: np.ndarray, albedo: np.ndarray, dirs: np.ndarray) -> tuple[float, np.ndarray]:
    """(residual, direction) of the candidate in `dirs` (G, 3) that explains y (P,) best (module doc)."""
    diffuse = (np.clip(n @ dirs.T, 0, None) * albedo[:, None]).astype(np.float32)  # (P, G)
    half = dirs + np.array([0.0, 0.0, 1.0])
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    cos_h = np.clip(n @ half.T, 0, None).astype(np.float32)  # (P, G)
    yy, dd, dy = float(y @ y), (diffuse * diffuse).sum(0), diffuse.T @ y
    best_res, best_dir = np.inf, dirs[0]
    for e in LOBES:
        s = cos_h ** np.float32(e)
        ss, ds, sy = (s * s).sum(0), (diffuse * s).sum(0), s.T @ y
        det = dd * ss - ds * ds + 1e-12
        c_d, c_s = (ss * dy - ds * sy) / det, (dd * sy - ds * dy) / det
        both = yy - 2 * (c_d * dy + c_s * sy) + c_d * c_d * dd + 2 * c_d * c_s * ds + c_s * c_s * ss
        # where one coefficient would be negative, the better of the two single terms (each clipped at 0)
        only_d = yy - np.clip(dy / np.maximum(dd, 1e-12), 0, None) * dy
        only_s = yy - np.clip(sy / np.maximum(ss, 1e-12), 0, None) * sy
        res = np.where((c_d >= 0) & (c_s >= 0), both, np.minimum(only_d, only_s))
        j = int(np.argmin(res))
        if res[j] < best_res:
            best_res, best_dir = float(res[j]), dirs[j]
    return best_res, best_dir


def shading_light_angles(images: np.ndarray, mask: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per image: (angle from the viewing direction, azimuth), degrees, of the light read from the shading of the
    whole object under a normal map (module doc). NaN for an image with fewer than 10 lit pixels."""
    gray = mean_gray(images)[:, mask].astype(np.float64)  # (K, P)
    n = normals[mask].astype(np.float64)  # (P, 3)
    k, p = gray.shape
    polar, azimuth = np.full(k, np.nan), np.full(k, np.nan)
    if p == 0:
        return polar, azimuth
    albedo = lambertian_albedo(gray, n)
    pick = np.unique(np.linspace(0, p - 1, min(p, SAMPLE_PIXELS)).astype(np.int64))
    g, n, albedo = gray[:, pick], n[pick], albedo[pick]
    top = np.percentile(gray, 95, axis=1)
    for i in range(k):
        if top[i] <= 0 or (gray[i] > LIT_SHARE * top[i]).sum() < 10:
            continue
        y = g[i].astype(np.float32)
        _, d = _best(y, n, albedo, _hemisphere())
        _, d = _best(y, n, albedo, _around(d))
        polar[i], azimuth[i] = np.degrees(np.arccos(np.clip(d[2], -1, 1))), np.degrees(np.arctan2(d[1], d[0]))
    return polar, azimuth
