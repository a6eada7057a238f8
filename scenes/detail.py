"""Procedural surface detail: tangent-space normal maps from periodic height fields (`MaterialDesc.detail`).

A detail map perturbs the shading normal the camera sees without changing the geometry (Mitsuba's
`normalmap` BSDF), as PS-Verse does for its detailed copies. The height field h(u, v) of a kind in
`DETAIL_KINDS` is periodic on the UV square (no seams); its tangent-space normal is
    n_t = normalize(-k dh/du, -k dh/dv, 1)
(OpenGL convention: x along the UV u direction, y along v, z the base normal), with k chosen so that the
95th percentile of the tilt acos(n_t . z) equals `strength_deg`. Arrays are in Mitsuba's texture orientation
(row 0 is v = 0), encoded (n + 1) / 2 like every normal map file.
"""
from __future__ import annotations

from typing import Callable

import numpy as np


def _grid(res: int) -> tuple[np.ndarray, np.ndarray]:
    v, u = np.meshgrid((np.arange(res) + 0.5) / res, (np.arange(res) + 0.5) / res, indexing="ij")
    return u, v


def _wrap(d: np.ndarray) -> np.ndarray:
    return d - np.round(d)  # periodic difference in [-0.5, 0.5]


def _bumps(res: int, scale: float, rng: np.random.Generator) -> np.ndarray:
    """Round bumps and dents of random sizes (hammered metal, orange peel)."""
    u, v = _grid(res)
    h = np.zeros_like(u)
    n = max(4, int(scale * scale * 2))
    for cu, cv, r, a in zip(
        rng.uniform(0, 1, n), rng.uniform(0, 1, n), rng.uniform(0.3, 1.0, n) / scale, rng.uniform(-1, 1, n)
    ):
        h += a * np.exp(-(_wrap(u - cu) ** 2 + _wrap(v - cv) ** 2) / (2 * (0.5 * r) ** 2))
    return h


def _scratches(res: int, scale: float, rng: np.random.Generator) -> np.ndarray:
    """Thin straight grooves of random direction and length (worn plastic or metal)."""
    u, v = _grid(res)
    h = np.zeros_like(u)
    width = 0.6 / res + 0.004
    for _ in range(max(3, int(scale * 3))):
        cu, cv = rng.uniform(0, 1, 2)
        ang = rng.uniform(0, np.pi)
        half = rng.uniform(0.1, 0.4)
        du, dv = _wrap(u - cu), _wrap(v - cv)
        along = du * np.cos(ang) + dv * np.sin(ang)
        across = -du * np.sin(ang) + dv * np.cos(ang)
        h -= np.exp(-(across / width) ** 2) * (np.abs(along) < half) * rng.uniform(0.3, 1.0)
    return h


def _fabric(res: int, scale: float, rng: np.random.Generator) -> np.ndarray:
    """A plain weave: threads along u and v passing over and under each other in a checkerboard (smooth and
    periodic: an even number of threads; deterministic, no draw)."""
    u, v = _grid(res)
    f = 2 * max(1, int(round(scale)))
    over = 0.5 + 0.5 * np.tanh(3.0 * np.sin(np.pi * f * u) * np.sin(np.pi * f * v))  # 1 where the warp is on top
    warp = np.sin(np.pi * f * v) ** 2  # a thread along u, rounded across v
    weft = np.sin(np.pi * f * u) ** 2
    return over * (warp + 0.3 * weft) + (1 - over) * (weft + 0.3 * warp)


def _stone(res: int, scale: float, rng: np.random.Generator) -> np.ndarray:
    """Cracked stone: cells (Worley F2 - F1, small near the cracks between cells) with a rough face."""
    u, v = _grid(res)
    n = max(4, int(scale * scale))
    pts = rng.uniform(0, 1, (n, 2))
    d = np.sort(np.stack([np.hypot(_wrap(u - px), _wrap(v - py)) for px, py in pts]), axis=0)
    crack = np.minimum((d[1] - d[0]) * scale * 4, 1.0)
    rough = np.zeros_like(u)
    for _ in range(6):
        kx, ky = rng.integers(-4 * int(scale), 4 * int(scale) + 1, 2)
        rough += np.sin(2 * np.pi * (kx * u + ky * v) + rng.uniform(0, 2 * np.pi))
    return crack + 0.05 * rough


DETAIL_KINDS: dict[str, Callable[[int, float, np.random.Generator], np.ndarray]] = {
    "bumps": _bumps,
    "scratches": _scratches,
    "fabric": _fabric,
    "stone": _stone,
}
"""Procedural detail patterns: name -> height field (res, res), periodic, rows along v."""
TILT_PERCENTILE = 95.0
"""The percentile of the tilt that `strength_deg` sets (a few steeper texels do not decide the strength)."""


def tangent_normals_from_height(h: np.ndarray, strength_deg: float) -> np.ndarray:
    """(res, res, 3) unit tangent-space normals of a periodic height field h (rows along v), scaled so that the
    `TILT_PERCENTILE` percentile of the tilt is `strength_deg` (a flat field gives (0, 0, 1) everywhere)."""
    res = h.shape[0]
    hu = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) * res / 2.0
    hv = (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0)) * res / 2.0
    g = np.hypot(hu, hv)
    ref = float(np.percentile(g, TILT_PERCENTILE))
    k = np.tan(np.radians(strength_deg)) / ref if ref > 1e-12 else 0.0
    n = np.stack([-k * hu, -k * hv, np.ones_like(h)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def realize_detail(detail) -> np.ndarray:
    """The normal map of a `DetailDesc` as a texture array (res, res, 3) float32, (n + 1) / 2."""
    if detail.kind not in DETAIL_KINDS:
        raise ValueError(f"material.detail.kind: unknown {detail.kind!r}, expected one of {', '.join(DETAIL_KINDS)}")
    h = DETAIL_KINDS[detail.kind](detail.resolution, detail.scale, np.random.default_rng(detail.seed))
    return ((tangent_normals_from_height(h, detail.strength_deg) + 1.0) / 2.0).astype(np.float32)
