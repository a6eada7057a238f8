"""Write an integrated surface: depth arrays, the discontinuity picture, meshes and the report
(`SURFACE_FILES`), as `orchestrate.surface` and `orchestrate.capture` do."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from scenes.surface.integrate import Surface
from scenes.surface.mesh import surface_mesh, write_mesh

SURFACE_FILES = ("depth.npy", "depth.exr", "discontinuities.png", "report.json")
"""The surface integrated from a normal map (`scenes.surface`, `orchestrate.surface`): float32 (H, W) depth along the
optical axis, NaN outside the mask, as NumPy and EXR arrays; the depth discontinuities drawn over the mask; the
solver's record. The mesh is `SURFACE_MESH` with the extension of its format (`scenes.surface.mesh.MESH_FORMATS`)."""

SURFACE_MESH = "mesh"
"""Stem of the integrated surface's mesh file (mesh.ply, .obj, .glb); `orchestrate.capture` writes all of them into
its SURFACE_DIR."""

SURFACE_DIR = "surface"
"""The folder of a capture's surface, beside its normal map."""

REPORT_KEYS = ("camera", "solver", "depth")
"""Keys every surface report.json holds: an existing report.json without them is not the surface's (never replaced,
`scenes.cli.outputs.claim_outputs`)."""


def surface_outputs(folder: str | Path, mesh_formats: tuple[str, ...]) -> list[Path]:
    """Every file `write_surface` writes into `folder`."""
    folder = Path(folder)
    return [folder / f for f in SURFACE_FILES] + [folder / f"{SURFACE_MESH}.{fmt}" for fmt in mesh_formats]


def discontinuity_picture(surface: Surface) -> np.ndarray:
    """(H, W, 3) uint8 BGR: background white, the mask grey, pixels beside a depth discontinuity red."""
    m = surface.mask
    img = np.full(m.shape + (3,), 255, np.uint8)
    img[m] = 170
    cut = surface.edge_cut_u | surface.edge_cut_v
    cut[:, 1:] |= surface.edge_cut_u[:, :-1]  # both pixels of a cut pair
    cut[1:, :] |= surface.edge_cut_v[:-1, :]
    img[cut & m] = (0, 0, 220)
    return img


def write_surface(surface: Surface, folder: str | Path, mesh_formats: tuple[str, ...], record: dict) -> dict:
    """Write everything into `folder`; `record` (inputs, camera) goes into the report with the solver's info."""
    from scenes.files import atomic_write, write_json
    from scenes.images import write_exr, write_picture

    folder = Path(folder)
    meshes = [f"{SURFACE_MESH}.{fmt}" for fmt in mesh_formats]
    method = ("bilateral normal integration, conjugate gradients with algebraic multigrid "
              "(scenes.surface.integrate)")
    # the mark of this run before its first file (a run killed mid-way leaves files a later --overwrite knows)
    write_json(folder / SURFACE_FILES[3], {**record, "depth": None, "meshes": meshes, "solver": {"method": method},
                                           "complete": False}, indent=1)
    depth = surface.depth.astype(np.float32)
    atomic_write(folder / SURFACE_FILES[0], lambda tmp: np.save(tmp, depth))
    write_exr(folder / SURFACE_FILES[1], depth)
    write_picture(folder / SURFACE_FILES[2], discontinuity_picture(surface))
    mesh = surface_mesh(surface)  # built once for every format
    for fmt in mesh_formats:
        write_mesh(mesh, folder / f"{SURFACE_MESH}.{fmt}")
    finite = depth[surface.mask]
    report = {
        **record,
        "pixels": int(surface.mask.sum()),
        "depth": {"min": float(finite.min()), "median": float(np.median(finite)), "max": float(finite.max())},
        "discontinuity_pixels": int((surface.edge_cut_u | surface.edge_cut_v).sum()),
        "triangles": len(mesh.faces),
        "meshes": meshes,
        "solver": {"method": method, **surface.info},
        "complete": True,
    }
    write_json(folder / SURFACE_FILES[3], report, indent=1)
    return report
