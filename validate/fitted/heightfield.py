"""Normal map -> height field -> triangle mesh (orthographic camera), for the fitted re-render scene.

Frame: camera frame x right, y up, z toward the camera; pixel (i, j) (row i from the top) has its centre
at x = (j + 0.5 - W / 2) * s, y = (H / 2 - i - 0.5) * s, with s = 2 / max(H, W) (the image spans [-1, 1]
along its longer side). Heights are in the same units.

Integration is the toolkit's one integrator (`scenes.surface.integrate`, orthographic): bilateral normal
integration, which keeps depth jumps instead of smearing them; the mesh leaves out the triangles across them.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)


@dataclass
class HeightField:
    """A height field over the mask pixels and its mesh."""

    z: np.ndarray
    """(H, W) float64 heights in scene units (0 outside the mask)."""
    mask: np.ndarray
    """(H, W) bool."""
    pixel_size: float
    """Scene units per pixel (s in the module doc)."""
    positions: np.ndarray
    """(P, 3) float32 vertex positions, one per mask pixel in row-major order (the pixel centres)."""
    faces: np.ndarray
    """(F, 3) uint32 triangles over 2x2 pixel blocks, counter-clockwise seen from the camera (+z)."""
    pixel_index: np.ndarray
    """(H, W) int64: vertex index of each mask pixel, -1 elsewhere."""


def pixel_positions(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(P, 2) x, y of the mask pixel centres (row-major), and the pixel size s."""
    h, w = mask.shape
    s = 2.0 / max(h, w)
    ii, jj = np.nonzero(mask)
    return np.stack([(jj + 0.5 - w / 2) * s, (h / 2 - ii - 0.5) * s], 1), np.stack([ii, jj], 1), s


def integrate(normals: np.ndarray, mask: np.ndarray, min_nz: float = 0.15) -> tuple[np.ndarray, object]:
    """Height field (H, W) in pixel units (0 outside the mask, median 0) from camera-frame normals (H, W, 3), by the
    toolkit's one integrator (`scenes.surface.integrate`, orthographic, depth jumps kept), and its Surface.

    nz is raised to `min_nz` first (`FitConfig.min_nz`), as the check's own least squares did before: the judged
    map's grazing and back-facing normals make a steep silhouette instead of void equations, and the check's figures
    were measured so."""
    from scenes.surface.integrate import integrate as integrate_surface

    n = np.asarray(normals, np.float64).copy()
    n[..., 2] = np.maximum(n[..., 2], min_nz)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    surface = integrate_surface(n, mask)
    out = np.zeros(mask.shape)
    height = -surface.depth[mask]  # depth grows away from the camera, height toward it
    out[mask] = height - np.median(height)
    return out, surface


def build(normals: np.ndarray, mask: np.ndarray, min_nz: float = 0.15) -> HeightField:
    """Integrate `normals` (H, W, 3) over `mask` and triangulate the mask pixel centres.

    No triangle spans a depth discontinuity the integrator found (`scenes.surface.mesh.faces`): a wall across a
    jump (e.g. a head in front of a body) would otherwise cast false shadows (seen on DiLiGenT cat)."""
    from scenes.surface.mesh import faces

    h, w = mask.shape
    z_px, surface = integrate(normals, mask, min_nz)
    xy, ij, s = pixel_positions(mask)
    z = z_px * s
    idx = -np.ones((h, w), np.int64)
    idx[mask] = np.arange(int(mask.sum()))
    positions = np.concatenate([xy, z[mask][:, None]], 1).astype(np.float32)
    faces_arr = faces(mask, surface.edge_cut_u, surface.edge_cut_v).astype(np.uint32)
    return HeightField(z=z, mask=mask, pixel_size=s, positions=positions, faces=faces_arr, pixel_index=idx)


def normals_from_heights(z: np.ndarray, mask: np.ndarray, pixel_size: float) -> np.ndarray:
    """Camera-frame normals (H, W, 3) of a height field (central differences inside the mask)."""
    gy, gx = np.gradient(z / pixel_size)  # per pixel: d/drow, d/dcol
    n = np.stack([-gx, gy, np.ones_like(z)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(mask[..., None], n, 0.0).astype(np.float32)


def silhouette_normals(mask: np.ndarray) -> np.ndarray:
    """A normal map from the mask alone (no photometric information): the height sqrt(d (2R - d)) of a
    rounded inflation of the silhouette, d the distance to the boundary, R its largest value."""
    from scipy.ndimage import distance_transform_edt, gaussian_filter

    d = distance_transform_edt(mask)
    rmax = max(float(d.max()), 1.0)
    z = np.sqrt(np.clip(d * (2 * rmax - d), 0, None))
    z = gaussian_filter(z, 1.0)
    gy, gx = np.gradient(z)
    n = np.stack([-gx, gy, np.ones_like(z)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(mask[..., None], n, 0.0).astype(np.float32)
