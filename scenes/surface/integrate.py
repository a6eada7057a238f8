"""Normal integration: a normal map and its mask -> depth along the optical axis, keeping depth jumps.

The model is the bilateral one of Cao et al. (ECCV 2022): every mask pixel has up to four one-sided equations,
forward and backward along each image axis, that tie its depth difference to a neighbour to its normal;
the two sides of an axis share a weight w and 1 - w, re-estimated after each solve from which side is the
smoother one, so that a depth jump ends up carried by no equation instead of being smeared over its
neighbours (iteratively reweighted least squares). Our own derivation and solver:

- Camera frame x right, y up, z toward the camera; pixel (row v, column u) has its centre at (u, v) in
  OpenCV's pixel coordinates, which `Intrinsics` (fx, fy, cx, cy) use. Depth Z > 0 along the optical axis.
- Orthographic: nz * (Z[u+1] - Z[u]) = nx and nz * (Z[v+1] - Z[v]) = -ny (depth in pixel widths).
- Perspective, with t = log Z: a_u * (t[u+1] - t[u]) = nx and a_v * (t[v+1] - t[v]) = -ny, where
  a_u = fx nz - nx (u - cx) + ny (v - cy) fx / fy and a_v = fy nz - nx (u - cx) fy / fx + ny (v - cy)
  (the tangency of the normal to the back-projected surface, multiplied through so that it stays finite
  where the surface turns away from the camera: a -> 0 makes the equation void, not infinite).
- Each neighbour pair is one edge of a weighted graph: the two one-sided equations on it sum to
  c_e (t_j - t_i - h_e / c_e)^2, so each solve is a weighted graph Laplacian L t = B^T h, solved by conjugate
  gradients preconditioned with classical algebraic multigrid (pyamg), warm-started from the previous solve; the
  multigrid hierarchy is rebuilt only when the weights have drifted enough to slow the solve.
- Every connected part of the mask has its own free offset (its own scale in perspective): each part is placed
  at the same median depth, and the report says how many parts there were.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

CUT_WEIGHT = 0.1
"""An edge between two pixels is a depth discontinuity when its two equations' weights sum to less than this
(a smooth edge has 0.5 + 0.5)."""


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole camera in OpenCV's pixel convention (pixel centres at integer coordinates, rows down)."""

    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_matrix(cls, k: np.ndarray) -> Intrinsics:
        k = np.asarray(k, np.float64)
        return cls(float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]))

    @classmethod
    def from_focal(cls, focal_px: float, height: int, width: int) -> Intrinsics:
        """Square pixels, the principal point at the image centre."""
        return cls(float(focal_px), float(focal_px), (width - 1) / 2.0, (height - 1) / 2.0)

    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class IntegrationConfig:
    """Settings of the integrator; the defaults are the ones every caller uses."""

    k: float = 2.0
    """Sharpness of the side weights: w = sigmoid(k * (backward^2 - forward^2)) of the one-sided equations'
    left-hand sides; 0 gives the smooth least-squares surface (no discontinuities)."""
    max_iter: int = 150
    """Most reweighting iterations."""
    tol: float = 1e-4
    """Stop when the energy changes by less than this fraction between two iterations ..."""
    weight_tol: float = 0.05
    """... and no side weight changed by more than this in the last iteration."""
    cg_rtol: float = 1e-3
    """Relative residual of each conjugate-gradient solve (against the right-hand side). Measured on the bench's 22
    renders (sum of MADE): 1e-4 1.418, 1e-3 1.419, 1e-2 1.405 (better on the orthographic clusters, worse on the
    rest), 3e-2 1.513, 1e-1 1.826; 1e-3 (the reference's own tolerance) costs 30 % less time than 1e-4 and stays
    clear of the cliff above 1e-2."""
    cg_max_iter: int = 500
    """Most conjugate-gradient steps of one solve."""


@dataclass
class Surface:
    """An integrated surface over the mask pixels."""

    depth: np.ndarray
    """(H, W) float64 depth along the optical axis, > 0, NaN outside the mask (orthographic: pixel widths;
    perspective: unit median depth of every connected part; both up to one global scale)."""
    mask: np.ndarray
    """(H, W) bool."""
    intrinsics: Intrinsics | None
    """None: orthographic."""
    weight_u: np.ndarray
    """(H, W) forward weight along the columns (1: the right neighbour carries the pixel, 0: the left one,
    0.5: both; a pixel with a right neighbour only: at most 0.5, less the steeper its equation), NaN outside the mask
    or without a right neighbour."""
    weight_v: np.ndarray
    """(H, W) the same along the rows (1: the neighbour below)."""
    edge_cut_u: np.ndarray
    """(H, W) bool: the pixel and its right neighbour are separated by a depth discontinuity."""
    edge_cut_v: np.ndarray
    """(H, W) bool: the pixel and the one below it are separated by a depth discontinuity."""
    info: dict = field(default_factory=dict)
    """Solver record: iterations, energy, residual (RMS of the weighted equations), cg_steps, amg_builds,
    parts, facing_away_pixels, seconds."""

    def points(self) -> np.ndarray:
        """(P, 3) float64 points of the mask pixels (row-major) in the camera frame x right, y up, z toward the
        camera (the camera at the origin looking down -z; orthographic: pixel widths, image centre on the axis)."""
        h, w = self.mask.shape
        v, u = np.nonzero(self.mask)
        z = self.depth[v, u]
        if self.intrinsics is None:
            x, y = u - (w - 1) / 2.0, (h - 1) / 2.0 - v
        else:
            k = self.intrinsics
            x, y = (u - k.cx) / k.fx * z, -(v - k.cy) / k.fy * z
        return np.stack([x, y, -z], 1).astype(np.float64)


def _coefficients(n: np.ndarray, mask: np.ndarray, intr: Intrinsics | None):
    """Per mask pixel: (a_u, g_u, a_v, g_v) of the equations a * (t[next] - t[this]) = g (module doc)."""
    nx, ny, nz = (n[..., c][mask].astype(np.float64) for c in range(3))
    if intr is None:
        return nz, nx, nz, -ny
    v, u = np.nonzero(mask)
    du, dv = u - intr.cx, v - intr.cy
    a_u = intr.fx * nz - nx * du + ny * dv * (intr.fx / intr.fy)
    a_v = intr.fy * nz - nx * du * (intr.fy / intr.fx) + ny * dv
    return a_u, nx, a_v, -ny


def _away(a_u: np.ndarray, a_v: np.ndarray) -> np.ndarray:
    """The rule: a normal faces away when either of its equations' coefficients is not positive (wrong sign)."""
    return (a_u <= 0) | (a_v <= 0)


def facing_away(normals: np.ndarray, mask: np.ndarray, intrinsics: Intrinsics | None) -> np.ndarray:
    """(P,) bool per mask pixel (row-major): its normal faces away from the camera along its pixel's ray, so that its
    equations would have the wrong sign (a_u <= 0 or a_v <= 0; orthographic: n_z <= 0)."""
    a_u, _, a_v, _ = _coefficients(normals, mask, intrinsics)
    return _away(a_u, a_v)


def _edges(mask: np.ndarray, idx: np.ndarray, axis: int):
    """Neighbour pairs (i, j) along `axis` (1: columns, j the right neighbour; 0: rows, j the one below)."""
    if axis == 1:
        both = mask[:, :-1] & mask[:, 1:]
        r, c = np.nonzero(both)
        return idx[r, c], idx[r, c + 1]
    both = mask[:-1, :] & mask[1:, :]
    r, c = np.nonzero(both)
    return idx[r, c], idx[r + 1, c]


def _laplacian_pattern(i: np.ndarray, j: np.ndarray, n: int):
    """A CSR matrix with the pattern of the graph Laplacian of edges (i, j) over n nodes, and the sparse map
    M (nnz x E) with L.data = M @ c for edge weights c (off-diagonals -c, diagonals the sums)."""
    import scipy.sparse as sp

    e = len(i)
    rows = np.concatenate([i, j, i, j])
    cols = np.concatenate([j, i, i, j])
    sign = np.concatenate([-np.ones(2 * e), np.ones(2 * e)])
    edge = np.concatenate([np.arange(e)] * 4)
    # Duplicate (row, col) entries (the diagonals) are summed by the CSR conversion; the map follows them.
    order = np.lexsort((cols, rows))
    rows, cols, sign, edge = rows[order], cols[order], sign[order], edge[order]
    key = rows.astype(np.int64) * n + cols
    first = np.r_[True, key[1:] != key[:-1]]
    slot = np.cumsum(first) - 1
    nnz = int(slot[-1]) + 1 if len(slot) else 0
    pattern = sp.csr_matrix((np.zeros(nnz), cols[first], np.r_[0, np.cumsum(np.bincount(rows[first], minlength=n))]),
                            shape=(n, n))
    m = sp.csr_matrix((sign, (slot, edge)), shape=(nnz, e))
    return pattern, m


def _parts(mask: np.ndarray) -> tuple[np.ndarray, int]:
    from scipy.ndimage import label

    lab, count = label(mask)  # 4-connectivity: the neighbours the equations tie
    return lab[mask] - 1, int(count)


def integrate(normals: np.ndarray, mask: np.ndarray, intrinsics: Intrinsics | None = None,
              config: IntegrationConfig = IntegrationConfig()) -> Surface:
    """Integrate unit camera-frame normals (H, W, 3) over `mask` (H, W) into a surface (module doc).

    The caller has checked the inputs (`scenes.surface.inputs`); the equations of normals facing away from the
    camera (`facing_away`) are left out, and `info["facing_away_pixels"]` counts them."""
    from threadpoolctl import threadpool_limits

    # Vector operations on one thread: threaded BLAS made each solve 3-5 times slower on a busy 2-core machine.
    with threadpool_limits(limits=1):
        return _integrate(normals, mask, intrinsics, config)


@dataclass
class _System:
    """The graph of one integration: per edge (i, j) the forward equation of i and the backward one of j."""

    p: int
    i: np.ndarray
    j: np.ndarray
    nu: int
    """The first nu edges run along the columns, the rest along the rows."""
    a_f: np.ndarray
    g_f: np.ndarray
    a_b: np.ndarray
    g_b: np.ndarray
    has_f: np.ndarray
    """(2, P): the pixel has a forward neighbour along the columns (0) / rows (1)."""
    has_b: np.ndarray
    away: int
    """Pixels whose normal faces away from the camera (their equations are void)."""

    def edge_weights(self, wf: np.ndarray, wb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per edge: the weight of i's forward and of j's backward equation, from per-pixel (2, P) weights."""
        iu, iv, ju, jv = self.i[:self.nu], self.i[self.nu:], self.j[:self.nu], self.j[self.nu:]
        return np.concatenate([wf[0, iu], wf[1, iv]]), np.concatenate([wb[0, ju], wb[1, jv]])


def _system(normals: np.ndarray, mask: np.ndarray, intrinsics: Intrinsics | None) -> _System:
    h, w = mask.shape
    p = int(mask.sum())
    idx = -np.ones((h, w), np.int64)
    idx[mask] = np.arange(p)
    a_u, g_u, a_v, g_v = _coefficients(normals, mask, intrinsics)
    away = _away(a_u, a_v)  # facing_away's rule, on the coefficients at hand
    a_u, a_v = np.where(away, 0.0, a_u), np.where(away, 0.0, a_v)  # void equations, not wrong-signed ones
    iu, ju = _edges(mask, idx, 1)
    iv, jv = _edges(mask, idx, 0)
    has_f = np.zeros((2, p), bool)
    has_b = np.zeros((2, p), bool)
    has_f[0, iu], has_b[0, ju], has_f[1, iv], has_b[1, jv] = True, True, True, True
    return _System(p=p, i=np.concatenate([iu, iv]), j=np.concatenate([ju, jv]), nu=len(iu),
                   a_f=np.concatenate([a_u[iu], a_v[iv]]), g_f=np.concatenate([g_u[iu], g_v[iv]]),
                   a_b=np.concatenate([a_u[ju], a_v[jv]]), g_b=np.concatenate([g_u[ju], g_v[jv]]),
                   has_f=has_f, has_b=has_b, away=int(away.sum()))


def _amg(lap):
    import pyamg

    # Classical (Ruge-Stuben) multigrid with one forward and one backward Gauss-Seidel sweep: on the bench's cases the
    # same depth as smoothed aggregation with its symmetric sweeps, in 40 % less time (bench/bench_surface.py).
    return pyamg.ruge_stuben_solver(lap, max_coarse=500, presmoother=("gauss_seidel", {"sweep": "forward"}),
                                    postsmoother=("gauss_seidel", {"sweep": "backward"}))


def _solve(sy: _System, config: IntegrationConfig):
    """Reweighted least squares: (t, wf, wb, info) with t the (log) depth per pixel up to each part's offset."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import cg

    p = sy.p
    pattern, lmap = _laplacian_pattern(sy.i, sy.j, p)
    e = len(sy.i)
    bmat = sp.csr_matrix((np.r_[-np.ones(e), np.ones(e)], (np.r_[np.arange(e), np.arange(e)], np.r_[sy.i, sy.j])),
                         shape=(e, p))
    bt = bmat.T.tocsr()
    # Every side a pixel has starts at 0.5, a single side too: its weight then falls as its slope grows (the
    # missing side's left-hand side is 0), as in the model of Cao et al., so a steep equation at the outline counts
    # less. Keeping a single side whole instead was measured worse on the renders (bench/bench_surface.py: clusters
    # seen orthographically 0.118 -> 0.109, single objects 0.0033 -> 0.0030).
    wf = np.where(sy.has_f, 0.5, 0.0)
    wb = np.where(sy.has_b, 0.5, 0.0)
    t = np.zeros(p)
    energy, cg_steps, amg_builds, ml, first_steps, it = None, 0, 0, None, None, 0
    for it in range(1, config.max_iter + 1):
        ef, eb = sy.edge_weights(wf, wb)
        lap = pattern.copy()
        lap.data = lmap @ (ef * sy.a_f ** 2 + eb * sy.a_b ** 2)
        # A vanishing ridge makes the Laplacian definite (each part's offset is free) without moving the solution.
        lap = lap + sp.identity(p, format="csr") * (1e-9 * max(float(np.mean(lap.diagonal())), 1e-30))
        rhs = bt @ (ef * sy.a_f * sy.g_f + eb * sy.a_b * sy.g_b)
        if ml is None:
            ml, amg_builds = _amg(lap), amg_builds + 1
        steps = [0]
        t, _ = cg(lap, rhs, x0=t, rtol=config.cg_rtol, maxiter=config.cg_max_iter, M=ml.aspreconditioner(),
                  callback=lambda _x: steps.__setitem__(0, steps[0] + 1))
        cg_steps += steps[0]
        # A hierarchy built for other weights slows the solve: rebuild when a solve takes a fifth more steps than the
        # first one after the last build (measured: twice as many cost 10 % more time over the bench's cases, never
        # rebuilding twice the time, rebuilding every step twice too).
        first_steps = max(steps[0], 5) if first_steps is None else first_steps
        if steps[0] > 1.2 * first_steps:
            ml, first_steps = None, None
        d = bmat @ t  # t_j - t_i per edge
        new_energy = float((ef * (sy.a_f * d - sy.g_f) ** 2 + eb * (sy.a_b * d - sy.g_b) ** 2).sum())
        # The side weights from the one-sided left-hand sides: forward of i (a_f d), backward of j (a_b d).
        lf, lb = np.zeros((2, p)), np.zeros((2, p))
        nu = sy.nu
        lf[0, sy.i[:nu]], lf[1, sy.i[nu:]] = sy.a_f[:nu] * d[:nu], sy.a_f[nu:] * d[nu:]
        lb[0, sy.j[:nu]], lb[1, sy.j[nu:]] = sy.a_b[:nu] * d[:nu], sy.a_b[nu:] * d[nu:]
        s = 1.0 / (1.0 + np.exp(np.clip(-config.k * (lb ** 2 - lf ** 2), -700, 700)))
        new_wf = np.where(sy.has_f, s, 0.0)
        moved = float(np.abs(new_wf - wf).max()) if p else 0.0
        wf, wb = new_wf, np.where(sy.has_b, 1.0 - s, 0.0)
        # Stop when the energy has settled and the weights no longer move: a flat start (the smooth surface fits
        # well while the weights have barely begun to find a jump) must not pass for convergence.
        done = (energy is not None and abs(new_energy - energy) <= config.tol * max(energy, 1e-300)
                and moved <= config.weight_tol)
        energy = new_energy
        if done:
            break
    ef, eb = sy.edge_weights(wf, wb)
    info = {"iterations": it, "energy": energy, "residual": float(np.sqrt(energy / max(float((ef + eb).sum()), 1e-30))),
            "cg_steps": cg_steps, "amg_builds": amg_builds}
    return t, wf, wb, info


def _integrate(normals: np.ndarray, mask: np.ndarray, intrinsics: Intrinsics | None,
               config: IntegrationConfig) -> Surface:
    t0 = time.perf_counter()
    mask = np.asarray(mask, bool)
    h, w = mask.shape
    sy = _system(normals, mask, intrinsics)
    t, wf, wb, info = _solve(sy, config)
    part, parts = _parts(mask)
    for q in range(parts):  # every connected part at the same median (log) depth
        sel = part == q
        t[sel] -= np.median(t[sel])
    depth = np.full((h, w), np.nan)
    depth[mask] = t - t.min() + max(h, w) if intrinsics is None else np.exp(t)
    maps = []
    for axis in range(2):
        m = np.full((h, w), np.nan)
        m[mask] = np.where(sy.has_f[axis], wf[axis], np.nan)
        maps.append(m)
    ef, eb = sy.edge_weights(wf, wb)
    both = sy.has_f & sy.has_b
    nu = sy.nu
    # Cut: the edge carries under CUT_WEIGHT of the weight a smooth one does (0.5 + 0.5).
    cut = (ef + eb < CUT_WEIGHT) & np.concatenate([both[0, sy.i[:nu]] & both[0, sy.j[:nu]],
                                                  both[1, sy.i[nu:]] & both[1, sy.j[nu:]]])
    rr, cc = np.nonzero(mask)
    cuts = []
    for sel, start in ((cut[:nu], sy.i[:nu]), (cut[nu:], sy.i[nu:])):
        c = np.zeros((h, w), bool)
        c[rr[start[sel]], cc[start[sel]]] = True
        cuts.append(c)
    info.update(parts=parts, facing_away_pixels=sy.away, seconds=round(time.perf_counter() - t0, 3))
    return Surface(depth=depth, mask=mask, intrinsics=intrinsics, weight_u=maps[0], weight_v=maps[1],
                   edge_cut_u=cuts[0], edge_cut_v=cuts[1], info=info)
