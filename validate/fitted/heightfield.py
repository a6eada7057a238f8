"""Normal map -> height field -> triangle mesh (orthographic camera), for the fitted re-render scene.

Frame: camera frame x right, y up, z toward the camera; pixel (i, j) (row i from the top) has its centre
at x = (j + 0.5 - W / 2) * s, y = (H / 2 - i - 0.5) * s, with s = 2 / max(H, W) (the image spans [-1, 1]
along its longer side). Heights are in the same units.

Integration is least squares over the mask: for horizontal neighbours z[i, j+1] - z[i, j] equals the mean
of -nx / nz at the two pixels, for vertical neighbours z[i+1, j] - z[i, j] the mean of +ny / nz (rows go
down, y goes up); nz is clamped to `min_nz` so that slopes at the silhouette stay finite. A tiny pull to 0
fixes the free offset of each connected region.
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


def integrate(normals: np.ndarray, mask: np.ndarray, min_nz: float = 0.15, damping: float = 1e-6) -> np.ndarray:
    """Least-squares height field (H, W) in pixel units from camera-frame normals (H, W, 3) over `mask`."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    h, w = mask.shape
    idx = -np.ones((h, w), np.int64)
    idx[mask] = np.arange(int(mask.sum()))
    nz = np.maximum(normals[..., 2].astype(np.float64), min_nz)
    p = -normals[..., 0] / nz  # dz / dx (x right), per pixel
    q = normals[..., 1] / nz  # dz / d(row) (rows go down, y up)
    rows, cols, vals, rhs = [], [], [], []
    r = 0
    for di, dj, g in ((0, 1, p), (1, 0, q)):
        a = mask[: h - di, : w - dj] & mask[di:, dj:]
        ia, ja = np.nonzero(a)
        i0, i1 = idx[ia, ja], idx[ia + di, ja + dj]
        n = len(i0)
        eq = np.arange(r, r + n)
        rows += [eq, eq]
        cols += [i1, i0]
        vals += [np.ones(n), -np.ones(n)]
        rhs.append(0.5 * (g[ia, ja] + g[ia + di, ja + dj]))
        r += n
    m = int(mask.sum())
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(r, m))
    b = np.concatenate(rhs) if rhs else np.zeros(0)
    z = spsolve((A.T @ A + damping * sp.identity(m)).tocsc(), A.T @ b)
    out = np.zeros((h, w))
    out[mask] = z - np.median(z)
    return out


def build(normals: np.ndarray, mask: np.ndarray, min_nz: float = 0.15, max_step: float = 3.0) -> HeightField:
    """Integrate `normals` (H, W, 3) over `mask` and triangulate the mask pixel centres.

    Triangles with a height step above `max_step` pixels between two of their corners are left out: they
    are the walls a continuous height field puts across depth discontinuities (e.g. a head in front of a
    body), which would otherwise cast false shadows (seen on DiLiGenT cat)."""
    h, w = mask.shape
    z_px = integrate(normals, mask, min_nz)
    xy, ij, s = pixel_positions(mask)
    z = z_px * s
    idx = -np.ones((h, w), np.int64)
    idx[mask] = np.arange(int(mask.sum()))
    positions = np.concatenate([xy, z[mask][:, None]], 1).astype(np.float32)
    tl, tr = idx[:-1, :-1], idx[:-1, 1:]
    bl, br = idx[1:, :-1], idx[1:, 1:]
    faces = []
    full = (tl >= 0) & (tr >= 0) & (bl >= 0) & (br >= 0)
    faces.append(np.stack([tl[full], bl[full], br[full]], 1))
    faces.append(np.stack([tl[full], br[full], tr[full]], 1))
    for a, b, c, sel in (  # blocks with exactly three mask pixels: one triangle
        (tl, bl, br, (tr < 0) & (tl >= 0) & (bl >= 0) & (br >= 0)),
        (tl, br, tr, (bl < 0) & (tl >= 0) & (br >= 0) & (tr >= 0)),
        (tl, bl, tr, (br < 0) & (tl >= 0) & (bl >= 0) & (tr >= 0)),
        (bl, br, tr, (tl < 0) & (bl >= 0) & (br >= 0) & (tr >= 0)),
    ):
        faces.append(np.stack([a[sel], b[sel], c[sel]], 1))
    faces_arr = np.concatenate(faces).astype(np.int64)
    zf = z_px[mask][faces_arr]  # (F, 3) corner heights in pixels
    keep = (zf.max(1) - zf.min(1)) <= max_step
    faces_arr = faces_arr[keep].astype(np.uint32)
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
