"""The regulariser of refinement (`validate.refine`): a penalty on a normal map that the images alone do not
pin, added to the image residual while the normals move.

Three terms, each weighted relative to the mean input value: smoothness (squared differences of 4-neighbour
normals), integrability (squared curl of the gradient field p = -nx/nz, q = ny/nz over 2x2 blocks) and the
silhouette (normals at the mask boundary may not point inward, and no normal may face away from the camera).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from validate.fitted.fit_scene import to_jit

if TYPE_CHECKING:
    from validate.fitted.fit_scene import FitScene


def _pairs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Index arrays over the mask pixels (row-major): horizontal pairs (a, b), vertical pairs (a, c), and
    2x2 blocks (tl, tr, bl, br) fully inside the mask."""
    idx = -np.ones(mask.shape, np.int64)
    idx[mask] = np.arange(int(mask.sum()))
    hz = mask[:, :-1] & mask[:, 1:]
    vt = mask[:-1, :] & mask[1:, :]
    blk = mask[:-1, :-1] & mask[:-1, 1:] & mask[1:, :-1] & mask[1:, 1:]
    horiz = np.stack([idx[:, :-1][hz], idx[:, 1:][hz]])
    vert = np.stack([idx[:-1, :][vt], idx[1:, :][vt]])
    block = np.stack([idx[:-1, :-1][blk], idx[:-1, 1:][blk], idx[1:, :-1][blk], idx[1:, 1:][blk]])
    return horiz, vert, block


def _boundary_outward(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mask-boundary pixels (indices into the mask pixels) and their outward 2D directions (x right, y up)."""
    from scipy.ndimage import binary_erosion, distance_transform_edt, gaussian_filter

    edge = mask & ~binary_erosion(mask)
    d = gaussian_filter(distance_transform_edt(mask), 1.0)
    gy, gx = np.gradient(d)
    o = np.stack([-gx, gy], -1)  # downhill of the distance = outward; rows go down, y up
    o /= np.maximum(np.linalg.norm(o, axis=-1, keepdims=True), 1e-12)
    idx = -np.ones(mask.shape, np.int64)
    idx[mask] = np.arange(int(mask.sum()))
    return idx[edge], o[edge]


def make_regulariser(fs: FitScene, config):
    """Dr.Jit function normals (Vector3f, width P) -> scalar penalty (see the module doc); the weights are
    `config.smoothness`, `config.integrability` and `config.silhouette` (`validate.refine.RefineConfig`)."""
    mi, dr = fs.mi, fs.dr
    horiz, vert, block = _pairs(fs.mask)
    bidx, outward = _boundary_outward(fs.mask)
    scale = float(np.abs(fs.images).mean())
    U = lambda a: to_jit(mi.UInt32, np.asarray(a, np.uint32))  # noqa: E731
    ha, hb, va, vb = U(horiz[0]), U(horiz[1]), U(vert[0]), U(vert[1])
    tl, tr, bl, br = (U(b) for b in block)
    bi = U(bidx)
    ox, oy = to_jit(mi.Float, outward[:, 0].astype(np.float32)), to_jit(mi.Float, outward[:, 1].astype(np.float32))

    def reg(normals):
        n = dr.normalize(normals)
        g = lambda i: dr.gather(mi.Vector3f, n, i)  # noqa: E731
        total = mi.Float(0.0)
        if config.smoothness > 0 and len(horiz[0]) + len(vert[0]):
            s = dr.sum(dr.squared_norm(g(ha) - g(hb))) + dr.sum(dr.squared_norm(g(va) - g(vb)))
            total += config.smoothness * scale * s / (len(horiz[0]) + len(vert[0]))
        if config.integrability > 0 and len(block[0]):
            def pq(v):
                nz = dr.maximum(v.z, 0.3)
                return -v.x / nz, v.y / nz

            p_tl, q_tl = pq(g(tl))
            p_tr, q_tr = pq(g(tr))
            p_bl, q_bl = pq(g(bl))
            p_br, q_br = pq(g(br))
            # d p / d row - d q / d col, each averaged over the block's two rows / columns
            curl = 0.5 * ((p_bl - p_tl) + (p_br - p_tr)) - 0.5 * ((q_tr - q_tl) + (q_br - q_bl))
            total += config.integrability * scale * dr.mean(curl * curl)
        if config.silhouette > 0:
            face = dr.maximum(-n.z, 0)
            total += config.silhouette * scale * dr.mean(face * face)
            if len(bidx):
                nb = g(bi)
                inward = dr.maximum(-(nb.x * ox + nb.y * oy), 0)
                total += config.silhouette * scale * dr.mean(inward * inward)
        return total

    return reg
