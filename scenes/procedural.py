"""Seeded procedural surfaces with rich normal variety, as triangle meshes with UVs.

Every generator maps a (u, v) grid to positions, so texture coordinates come for free. Vertex normals are
area-weighted face normals accumulated on welded vertices (seams and poles share one normal), so
shading is smooth across the parameterisation's seams.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class MeshData:
    """A triangle mesh in plain arrays."""

    positions: np.ndarray  # (N, 3) float32
    faces: np.ndarray  # (F, 3) int32
    normals: np.ndarray  # (N, 3) float32, unit
    uvs: np.ndarray  # (N, 2) float32 in [0, 1]


def _grid(rings: int, segments: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v) in [0,1]^2 on a (rings+1) x (segments+1) grid, and the triangle indices."""
    v, u = np.meshgrid(np.linspace(0, 1, rings + 1), np.linspace(0, 1, segments + 1), indexing="ij")
    idx = np.arange((rings + 1) * (segments + 1)).reshape(rings + 1, segments + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    faces = np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)])
    return u.ravel(), v.ravel(), faces


def smooth_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals, with coincident vertices (seams) welded."""
    key = np.round(positions.astype(np.float64), 6)
    _, weld = np.unique(key, axis=0, return_inverse=True)
    weld = weld.ravel()
    p = positions.astype(np.float64)
    fn = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])  # (F, 3), 2x area
    acc = np.zeros((weld.max() + 1, 3))
    for k in range(3):
        np.add.at(acc, weld[faces[:, k]], fn)
    n = acc[weld]
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return (n / np.maximum(norm, 1e-12)).astype(np.float32)


def _drop_degenerate(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    p = positions.astype(np.float64)
    area = np.linalg.norm(np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]]), axis=1)
    return faces[area > 1e-12]


def _sphere_dirs(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    theta, phi = np.pi * v, 2 * np.pi * u
    return np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], 1)


def _finish(positions: np.ndarray, faces: np.ndarray, u: np.ndarray, v: np.ndarray) -> MeshData:
    faces = _drop_degenerate(positions, faces).astype(np.int32)
    # Outward orientation: flip if the signed volume is negative.
    p = positions.astype(np.float64)
    vol = np.einsum("ij,ij->i", p[faces[:, 0]], np.cross(p[faces[:, 1]], p[faces[:, 2]])).sum()
    if vol < 0:
        faces = faces[:, ::-1].copy()
    normals = smooth_normals(positions, faces)
    return MeshData(positions.astype(np.float32), faces, normals, np.stack([u, v], 1).astype(np.float32))


def _param(params: dict, name: str, rng: np.random.Generator, lo: float, hi: float) -> float:
    """A parameter from `params`, else drawn uniformly (the draw happens either way: stable streams)."""
    drawn = float(rng.uniform(lo, hi))
    return float(params.get(name, drawn))


def blob(seed: int, resolution: int, params: dict | None = None) -> MeshData:
    """Star-shaped blob: unit sphere plus a few seeded Gaussian lumps and dents."""
    params = params or {}
    rng = np.random.default_rng(seed)
    n = int(_param(params, "lumps", rng, 3, 9))
    amp = _param(params, "amplitude", rng, 0.2, 0.5)
    u, v, faces = _grid(resolution, 2 * resolution)
    d = _sphere_dirs(u, v)
    centres = rng.normal(size=(n, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    widths = rng.uniform(0.25, 0.8, n)
    heights = rng.uniform(-0.6, 1.0, n) * amp
    r = np.ones(len(d))
    for c, w, h in zip(centres, widths, heights):
        r += h * np.exp(-np.sum((d - c) ** 2, 1) / (w * w))
    r = np.maximum(r, 0.3)
    stretch = rng.uniform(0.7, 1.3, 3)
    return _finish(d * r[:, None] * stretch, faces, u, v)


def bumpy_sphere(seed: int, resolution: int, params: dict | None = None) -> MeshData:
    """Sphere displaced by a sum of seeded 3D sinusoids (medium to high frequency bumps)."""
    params = params or {}
    rng = np.random.default_rng(seed)
    amp = _param(params, "amplitude", rng, 0.03, 0.1)
    freq = _param(params, "frequency", rng, 3.0, 8.0)
    waves = int(_param(params, "waves", rng, 4, 10))
    u, v, faces = _grid(resolution, 2 * resolution)
    d = _sphere_dirs(u, v)
    r = np.ones(len(d))
    for _ in range(waves):
        k = rng.normal(size=3)
        k *= freq / np.linalg.norm(k)
        r += amp / np.sqrt(waves) * np.sin(d @ k + rng.uniform(0, 2 * np.pi))
    return _finish(d * r[:, None], faces, u, v)


def superquadric(seed: int, resolution: int, params: dict | None = None) -> MeshData:
    """Superellipsoid with seeded exponents (boxy to pinched) and axis lengths."""
    params = params or {}
    rng = np.random.default_rng(seed)
    e1 = _param(params, "e1", rng, 0.3, 2.0)
    e2 = _param(params, "e2", rng, 0.3, 2.0)
    ax = [_param(params, f"a{i}", rng, 0.6, 1.0) for i in range(3)]
    u, v, faces = _grid(resolution, 2 * resolution)
    eta, omega = np.pi * (v - 0.5), 2 * np.pi * u - np.pi

    def spow(x: np.ndarray, e: float) -> np.ndarray:
        return np.sign(x) * np.abs(x) ** e

    x = ax[0] * spow(np.cos(eta), e1) * spow(np.cos(omega), e2)
    y = ax[1] * spow(np.sin(eta), e1)
    z = ax[2] * spow(np.cos(eta), e1) * spow(np.sin(omega), e2)
    return _finish(np.stack([x, y, z], 1), faces, u, v)


def torus(seed: int, resolution: int, params: dict | None = None) -> MeshData:
    """Torus with seeded radii and optional small bumps along the tube."""
    params = params or {}
    rng = np.random.default_rng(seed)
    big = _param(params, "major", rng, 0.6, 0.75)
    small = _param(params, "minor", rng, 0.2, 0.35)
    bumps = _param(params, "bumps", rng, 0.0, 0.04)
    u, v, faces = _grid(resolution, 2 * resolution)
    phi, theta = 2 * np.pi * u, 2 * np.pi * v
    rr = small * (1 + bumps / small * np.sin(5 * phi + 3 * theta))
    x = (big + rr * np.cos(theta)) * np.cos(phi)
    z = (big + rr * np.cos(theta)) * np.sin(phi)
    y = rr * np.sin(theta)
    return _finish(np.stack([x, y, z], 1), faces, u, v)


def plane(seed: int, resolution: int, params: dict | None = None) -> MeshData:
    """Flat square in the xy plane facing +z (the entropy rule must reject it)."""
    u, v, faces = _grid(resolution, resolution)
    pos = np.stack([2 * u - 1, 2 * v - 1, np.zeros_like(u)], 1)
    faces = _drop_degenerate(pos, faces).astype(np.int32)
    # Face +z: counter-clockwise seen from +z.
    p = pos[faces]
    if np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2].mean() < 0:
        faces = faces[:, ::-1].copy()
    normals = np.tile(np.float32([0, 0, 1]), (len(pos), 1))
    return MeshData(pos.astype(np.float32), faces, normals, np.stack([u, v], 1).astype(np.float32))


GENERATORS = {
    "blob": blob,
    "bumpy_sphere": bumpy_sphere,
    "superquadric": superquadric,
    "torus": torus,
    "plane": plane,
}


PARAMETERS: dict[str, dict[str, tuple[float, float]]] = {
    "blob": {"lumps": (1, 64), "amplitude": (0, 2)},
    "bumpy_sphere": {"amplitude": (0, 1), "frequency": (0, 100), "waves": (1, 64)},
    "superquadric": {"e1": (0.05, 10), "e2": (0.05, 10), "a0": (0.01, 10), "a1": (0.01, 10), "a2": (0.01, 10)},
    "torus": {"major": (0.01, 10), "minor": (0.01, 10), "bumps": (0, 1)},
    "plane": {},
}
"""The parameters each generator reads, with the values a scene may give them (wider than the seeded draws; the
counts bound the work). A shape that is not procedural (mesh, sphere) reads none."""


def check_params(kind: str, params: dict) -> None:
    """ValueError naming `shape.params.NAME` for a parameter the shape's generator does not read (a typo would
    silently be a seeded random value) or a value outside its range."""
    from scenes.checks import check_number

    known = PARAMETERS.get(kind, {})
    for name, value in params.items():
        if name not in known:
            expected = f"one of {', '.join(known)}" if known else "none: it reads no parameters"
            raise ValueError(f"shape.params.{name}: kind {kind!r} has no parameter {name!r}, expected {expected}")
        check_number(value, f"shape.params.{name}", *known[name])


def generate(kind: str, seed: int, resolution: int, params: dict | None = None) -> MeshData:
    """Procedural mesh of `kind` (one of GENERATORS), deterministic in (seed, resolution, params)."""
    if kind not in GENERATORS:
        raise ValueError(f"shape.kind: {kind!r} is not procedural, expected one of {', '.join(GENERATORS)}")
    return GENERATORS[kind](seed, resolution, params)
