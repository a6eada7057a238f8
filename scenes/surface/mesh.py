"""The triangle mesh of an integrated surface: one vertex per mask pixel, two triangles per 2 x 2 block of
pixels, none across a depth discontinuity (`Surface.edge_cut_u` / `edge_cut_v`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from scenes.surface.integrate import Surface

MESH_FORMATS = ("ply", "obj", "glb")
"""Mesh files the surface command writes (trimesh's exporters)."""


def faces(mask: np.ndarray, cut_u: np.ndarray | None = None, cut_v: np.ndarray | None = None) -> np.ndarray:
    """(F, 3) int64 vertex indices (row-major mask pixels), counter-clockwise seen from the camera.

    Each 2 x 2 block is split along the diagonal that keeps more triangles; a triangle is kept when its three
    pixels are in the mask and neither of its two axis-aligned edges is cut."""
    h, w = mask.shape
    cut_u = np.zeros((h, w), bool) if cut_u is None else cut_u
    cut_v = np.zeros((h, w), bool) if cut_v is None else cut_v
    idx = -np.ones((h, w), np.int64)
    idx[mask] = np.arange(int(mask.sum()))
    tl, tr, bl, br = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    # Uncut axis-aligned edges of each block: top, bottom, left, right.
    top = (tl >= 0) & (tr >= 0) & ~cut_u[:-1, :-1]
    bottom = (bl >= 0) & (br >= 0) & ~cut_u[1:, :-1]
    left = (tl >= 0) & (bl >= 0) & ~cut_v[:-1, :-1]
    right = (tr >= 0) & (br >= 0) & ~cut_v[:-1, 1:]
    split_a = [((tl, bl, br), left & bottom), ((tl, br, tr), top & right)]  # diagonal tl-br
    split_b = [((tl, bl, tr), left & top), ((bl, br, tr), bottom & right)]  # diagonal bl-tr
    use_a = (split_a[0][1].astype(int) + split_a[1][1]) >= (split_b[0][1].astype(int) + split_b[1][1])
    out = []
    for split, chosen in ((split_a, use_a), (split_b, ~use_a)):
        for (a, b, c), ok in split:
            sel = ok & chosen
            out.append(np.stack([a[sel], b[sel], c[sel]], 1))
    return np.concatenate(out).astype(np.int64)


def surface_mesh(surface: Surface):
    """The surface as a trimesh.Trimesh in the camera frame (x right, y up, z toward the camera)."""
    import trimesh

    return trimesh.Trimesh(vertices=surface.points(), faces=faces(surface.mask, surface.edge_cut_u,
                                                                   surface.edge_cut_v), process=False)


def write_mesh(mesh, path: str | Path) -> None:
    """Write a `surface_mesh` (the format from the extension, one of `MESH_FORMATS`) atomically."""
    from scenes.files import atomic_write

    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in MESH_FORMATS:
        raise ValueError(f"mesh format {fmt!r}; expected one of {', '.join(MESH_FORMATS)}")
    data = mesh.export(file_type=fmt)
    atomic_write(path, lambda tmp: Path(tmp).write_bytes(data if isinstance(data, bytes) else data.encode()))
