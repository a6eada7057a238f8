"""Classical photometric-stereo baselines: calibrated least squares and an uncalibrated SH method.

Both take a `PSObject` and return (H, W, 3) float32 unit normals in the camera frame (x right, y up,
z toward the camera), zero outside the mask.

``least-squares`` (Woodham 1980): Lambertian I = rho * L n per pixel, solved in the least-squares sense
with all K images, no shadow handling. The colour images are divided by the light intensities and
converted to gray with weights (0.2989, 0.5870, 0.1140). Needs calibrated directional lights.

``sh-uncalibrated``: needs no calibration, works for any lighting. Assumptions, all documented here
because they decide when it works:

1. Lambertian reflectance, orthographic camera, and per image a first-order spherical-harmonic
   lighting: I_pk = a_k + l_k . s_p with s_p = rho_p n_p (a_k is an additive, albedo-independent
   ambient term; l_k a direction times an intensity).
2. Attached shadows break the linear model; entries darker than ``shadow_threshold`` of each image's
   range above its 1st percentile are treated as missing.
3. The silhouette is an occluding contour: near the mask border the normal's image-plane part points
   outward, along the 2-D normal of the mask (image y flipped to our y-up frame). Only the direction of
   that projection is used, not n_z = 0, because the outermost pixel centres are not exactly on the
   contour.
4. Roughly uniform albedo: rho is constant (a robust Cauchy loss tolerates a minority of pixels that
   break this, e.g. highlights or a few painted parts).
5. Visible normals face the camera on average (n_z > 0).

Algorithm: (a) the rank-4 factorisation of the pixel x image matrix with one factor fixed to the
constant vector, I = 1 a^T + S L^T, by alternating least squares over the non-shadowed entries,
initialised by the SVD of the column-centred matrix; S is known up to an affine map s -> s G + h.
(b) The x and y columns of that map (8 numbers) are the null vector of the linear contour constraints
X c_y - Y c_x = 0 over a band of border pixels, signed so the projections point outward.
(c) The z column (4 numbers) comes from the unit-norm prior X^2 + Y^2 + Z^2 = rho^2: a linear
least-squares fit of the lifted quadratic form gives a starting point, refined by robust (Cauchy)
nonlinear least squares; its sign makes n_z positive on average. On noise-free Lambertian renders of a
uniform sphere this is exact with or without an ambient term and shadows; on real, shiny or textured
objects the uniform-albedo prior is the weak point (see bench/bench_diligent.py).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np

from unips.data import PSObject

log = logging.getLogger(__name__)

#: RGB -> gray weights (ITU-R BT.601), as used to reproduce DiLiGenT's least-squares figures.
GRAY_WEIGHTS = (0.2989, 0.5870, 0.1140)
#: Smallest share of the mask pixels that must be above black in at least one image for least squares to
#: write a map: a pixel black in every image gets no estimate (0), and a map of mostly no estimates (black
#: or nearly black images) is refused rather than written.
MIN_LS_COVERAGE = 0.5


def gray_matrix(obj: PSObject, divide_intensities: bool = True, chunk: int = 65536) -> np.ndarray:
    """(P, K) float32 gray values of the P masked pixels (row-major order) in the K images."""
    K = obj.images.shape[0]
    weights = np.tile(np.asarray(GRAY_WEIGHTS, np.float32), (K, 1))  # (K, 3)
    if divide_intensities and obj.light_intensities is not None:
        inten = np.asarray(obj.light_intensities, np.float32)
        if inten.shape != (K, 3):
            raise ValueError(f"obj.light_intensities: expected shape ({K}, 3), got {inten.shape}")
        if np.any(inten <= 0) or not np.all(np.isfinite(inten)):
            raise ValueError("obj.light_intensities: must be finite and > 0 to divide the images by them")
        weights = weights / inten
    ys, xs = np.nonzero(obj.mask)
    out = np.empty((ys.size, K), np.float32)
    for start in range(0, ys.size, chunk):
        sl = slice(start, start + chunk)
        pix = obj.images[:, ys[sl], xs[sl], :]  # (K, c, 3)
        out[sl] = np.einsum("kcj,kj->ck", pix, weights)
    return out


def _to_map(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    out = np.zeros(mask.shape + (3,), np.float32)
    out[mask] = values
    return out


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)


# ----------------------------------------------------------------------------------- least squares


LIGHT_SPREAD = 0.01
"""The least the third singular value of the light directions may be, relative to the first: below it the lights
lie nearly in one plane and least squares amplifies the images' noise across it a hundredfold and more (DiLiGenT
ball's first 4 lights, all at x = -0.06: 3e-5, an 87-degree map; sweep 41). A cone of lights 10 deg around the
view gives about 0.1."""


def least_squares(obj: PSObject, chunk: int = 65536) -> np.ndarray:
    """Calibrated Lambertian least-squares photometric stereo (all images, no shadow handling). A pixel
    black in every image gets no estimate (0); images leaving more than half the mask so are refused
    (`MIN_LS_COVERAGE`)."""
    if obj.light_directions is None:
        raise ValueError(f"--method least-squares: object {obj.name} has no light directions; it needs calibrated "
                         "directional lights (one directional light per image)")
    L = np.asarray(obj.light_directions, np.float64)  # (K, 3)
    K = obj.images.shape[0]
    if L.shape != (K, 3):
        raise ValueError(f"--method least-squares: object {obj.name}'s light directions have shape {L.shape}, "
                         f"expected ({K}, 3): one direction per image")
    spread = np.linalg.svd(L, compute_uv=False) if K >= 3 else np.zeros(1)
    if K < 3 or spread[2] < LIGHT_SPREAD * spread[0]:  # a plane of lights leaves the normal across it unknown
        from scenes.folder.format import DILIGENT_LIGHTS, SCENE_FILE

        src = next((str(obj.path / n) for n in (DILIGENT_LIGHTS, SCENE_FILE) if (obj.path / n).is_file()),
                   str(obj.path))
        rank = np.linalg.matrix_rank(L)
        what = (f"span only {rank} dimension(s)" if rank < 3 else "lie nearly in one plane (their third singular "
                f"value is {spread[2] / spread[0]:.2g} of the first, under {LIGHT_SPREAD:g}: the normal across that "
                "plane would be noise)")
        raise ValueError(f"--method least-squares: object {obj.name}'s {K} light directions ({src!r}) {what}; "
                         "expected at least 3 lights not in one plane")
    pinv = np.linalg.pinv(L)  # (3, K)
    gray = gray_matrix(obj, chunk=chunk)  # (P, K)
    seen = (gray > 0).any(axis=1)
    if seen.mean() < MIN_LS_COVERAGE:
        names = f" ({obj.image_names[0]} .. {obj.image_names[-1]})" if obj.image_names else ""
        raise ValueError(
            f"images: {obj.path}{names}: only {int(seen.sum())} of {seen.size} mask pixels are above black in "
            f"any image; least-squares needs at least {MIN_LS_COVERAGE:.0%} of them (black or nearly black "
            "images give no normals)"
        )
    if not seen.all():
        log.warning("least-squares: %s: %d of %d mask pixels are black in every image; they get no normal (0)",
                    obj.name, int((~seen).sum()), seen.size)
    b = np.empty((gray.shape[0], 3), np.float64)
    for start in range(0, gray.shape[0], chunk):
        sl = slice(start, start + chunk)
        b[sl] = gray[sl].astype(np.float64) @ pinv.T
    return _to_map(_unit_rows(b), obj.mask)


# --------------------------------------------------------------------------------- sh-uncalibrated


@dataclass
class SHUncalibratedConfig:
    """Settings of the uncalibrated first-order SH baseline."""

    shadow_threshold: float = (
        0.05  # fraction of each image's [1st, 99th] percentile range below which an entry is "shadow"
    )
    als_iterations: int = 50  # alternating least-squares sweeps of the factorisation
    band_width: int = 2  # width in pixels of the border band used for the contour constraint
    contour_sigma: float = 1.5  # Gaussian blur (pixels) of the mask before taking its gradient
    max_fit_pixels: int = 40000  # pixels used to fit the lighting and the gauge (evenly spaced subset)
    robust_scale: float = 0.1  # Cauchy loss scale for the unit-norm residual (relative to rho^2)
    min_band_pixels: int = 8  # fewer usable border pixels than this is an error


def contour_band(mask: np.ndarray, width: int = 2, sigma: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """Border band of the mask and the outward 2-D normal there.

    Returns ``band`` (H, W) bool and ``direction`` (H, W, 2) with unit (x, y) in our frame (x right,
    y up). Pixels on the image border are excluded: a mask cut by the frame is not an occluding contour.
    """
    import cv2

    m = mask.astype(np.uint8)
    eroded = cv2.erode(m, np.ones((3, 3), np.uint8), iterations=max(int(width), 1),
                       borderType=cv2.BORDER_CONSTANT, borderValue=0)
    band = mask & (eroded == 0)
    band[:1] = band[-1:] = False
    band[:, :1] = band[:, -1:] = False
    soft = cv2.GaussianBlur(m.astype(np.float32), (0, 0), float(sigma))
    g_row, g_col = np.gradient(soft)
    # The mask decreases outward: outward = -gradient; rows grow downward, our y grows upward.
    dx, dy = -g_col, g_row
    norm = np.hypot(dx, dy)
    band &= norm > 1e-6
    direction = np.stack([dx, dy], axis=-1) / np.maximum(norm, 1e-12)[..., None]
    return band, direction.astype(np.float64)


def _shadow_weights(M: np.ndarray, lo: np.ndarray, hi: np.ndarray, threshold: float) -> np.ndarray:
    """(P, K) 1.0 where an entry is trusted, 0.0 where it may be in attached shadow."""
    return (M > lo + threshold * (hi - lo)).astype(np.float64)


def _solve_pixels(M: np.ndarray, W: np.ndarray, a: np.ndarray, L: np.ndarray) -> np.ndarray:
    """Per-pixel weighted least squares for s_p in M_pk - a_k = s_p . L_k (P, 3)."""
    P, K = M.shape
    LL = (L[:, :, None] * L[:, None, :]).reshape(K, 9)
    A = (W @ LL).reshape(P, 3, 3) + 1e-10 * np.eye(3)
    b = (W * (M - a)) @ L
    return np.linalg.solve(A, b[..., None])[..., 0]


def _solve_images(M: np.ndarray, W: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-image weighted least squares for (a_k, L_k) in M_pk = a_k + S_p . L_k."""
    P, K = M.shape
    F = np.concatenate([np.ones((P, 1)), S], axis=1)  # (P, 4)
    FF = (F[:, :, None] * F[:, None, :]).reshape(P, 16)
    A = (W.T @ FF).reshape(K, 4, 4) + 1e-10 * np.eye(4)
    b = (W * M).T @ F  # (K, 4)
    X = np.linalg.solve(A, b[..., None])[..., 0]
    return X[:, 0], X[:, 1:]


def _factorise(M: np.ndarray, W: np.ndarray, iterations: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Affine rank-3 factorisation M ~ 1 a^T + S L^T over the entries where W = 1."""
    P = M.shape[0]
    filled = np.where(W > 0, M, (W * M).sum(0) / np.maximum(W.sum(0), 1.0))
    centred = filled - filled.mean(axis=0)
    U, sv, _ = np.linalg.svd(centred, full_matrices=False)
    S = U[:, :3] * sv[:3] / np.sqrt(P)
    a = L = None
    for _ in range(max(int(iterations), 1)):
        a, L = _solve_images(M, W, S)
        S = _solve_pixels(M, W, a, L)
    a, L = _solve_images(M, W, S)
    return S, a, L


def _contour_columns(St: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(4, 2) map from [s, 1] to the (X, Y) normal components, from the contour constraint."""
    A = np.concatenate([St * c[:, 1:2], -St * c[:, 0:1]], axis=1)  # X c_y - Y c_x = 0
    _, sv, vt = np.linalg.svd(A, full_matrices=False)
    if sv[-2] < 1e-6 * sv[0]:
        log.warning("sh-uncalibrated: the contour constraint leaves more than one solution "
                    "(border directions too uniform); the result is unreliable")
    gxy = vt[-1].reshape(2, 4).T
    if np.sum((St @ gxy) * c) < 0:  # projections must point outward
        gxy = -gxy
    return gxy


def _z_start(St: np.ndarray, gxy: np.ndarray) -> tuple[np.ndarray, float]:
    """Closed-form start for the z column, consistent in scale with ``gxy``.

    With rho n = s A + t (A 3x3, t 3), unit norm makes the points s lie on an ellipsoid
    s B s^T + 2 s . w = 1, B = k A A^T, w = k A t (k > 0), a linear least-squares fit. The x and y
    columns of A are the contour's gxy up to one scale tau: B - tau gxy gxy^T = k a_z a_z^T has rank 1,
    which fixes tau through the generalised eigenvalues of (gxy gxy^T, B); then a_z, and t from w.
    """
    S = St[:, :3]
    i, j = np.triu_indices(3)
    F = np.concatenate([S[:, i] * S[:, j] * np.where(i == j, 1.0, 2.0), 2.0 * S], axis=1)
    sol = np.linalg.lstsq(F, np.ones(S.shape[0]), rcond=None)[0]
    B = np.zeros((3, 3))
    B[i, j] = sol[:6]
    B[j, i] = sol[:6]
    w = sol[6:]
    ev, evec = np.linalg.eigh(B)
    if ev[-1] <= 0:
        raise ValueError("sh-uncalibrated: the pixel factors do not lie on an ellipsoid (eigenvalues "
                         f"{ev.tolist()}); the images do not fit a Lambertian, uniform-albedo object")
    if ev[0] <= 1e-6 * ev[-1]:
        # Not an ellipsoid (real data far from the model): use the nearest one as a start only;
        # the robust refinement that follows does the fitting.
        log.warning("sh-uncalibrated: factor quadric is not an ellipsoid (eigenvalues %s); using the "
                    "nearest one as a start", ev.tolist())
        ev = np.maximum(ev, 1e-6 * ev[-1])
        B = (evec * ev) @ evec.T
    b_isqrt = evec @ np.diag(ev ** -0.5) @ evec.T
    g3 = gxy[:3]  # (3, 2)
    mu = np.linalg.eigvalsh(b_isqrt @ (g3 @ g3.T) @ b_isqrt)[-2:]  # the two nonzero ones
    tau = 2.0 / float(np.sum(mu))
    ev2, evec2 = np.linalg.eigh(B - tau * (g3 @ g3.T))
    a_z = evec2[:, -1] * np.sqrt(max(ev2[-1], 1e-300))
    A = np.column_stack([np.sqrt(tau) * g3, a_z])
    t = np.linalg.solve(A, w)
    gz = np.concatenate([a_z, [t[2]]]) / np.sqrt(tau)
    # rho^2 in gxy's scale: mean of |n rho|^2 over the pixels.
    c = float(np.sqrt(np.mean(np.sum((St @ gxy) ** 2, axis=1) + (St @ gz) ** 2)))
    return gz, c


def _z_column(St: np.ndarray, gxy: np.ndarray, robust_scale: float) -> np.ndarray:
    """(4,) map from [s, 1] to Z from the unit-norm prior X^2 + Y^2 + Z^2 = rho^2 (rho constant)."""
    from scipy.optimize import least_squares as nonlinear_lsq

    r2 = np.sum((St @ gxy) ** 2, axis=1)
    gz0, c0 = _z_start(St, gxy)
    scale = max(float(np.median(r2)), 1e-300)

    def residual(x: np.ndarray) -> np.ndarray:
        Z = St @ x[:4]
        return (r2 + Z * Z - x[4] ** 2) / scale

    # Robust refinement: pixels that break the uniform-albedo prior (highlights, paint) weigh less.
    fit = nonlinear_lsq(residual, np.concatenate([gz0, [c0]]), loss="cauchy", f_scale=robust_scale,
                        x_scale="jac", max_nfev=200)
    return fit.x[:4]


def sh_uncalibrated(obj: PSObject, config: SHUncalibratedConfig | None = None) -> np.ndarray:
    """Uncalibrated first-order SH Lambertian photometric stereo (see the module docstring)."""
    cfg = config or SHUncalibratedConfig()
    K = obj.images.shape[0]
    if K < 4:
        raise ValueError(f"--method sh-uncalibrated: object {obj.name} has {K} images; it needs at least 4 "
                         "(ambient + 3 lighting components)")
    mask = obj.mask
    band, direction = contour_band(mask, cfg.band_width, cfg.contour_sigma)
    in_band = band[mask]  # (P,) over masked pixels
    M_all = gray_matrix(obj, divide_intensities=False)  # (P, K); uncalibrated: intensities unknown
    P = M_all.shape[0]

    # Fit subset: evenly spaced pixels plus every band pixel (the contour step needs them all).
    n_fit = min(P, int(cfg.max_fit_pixels))
    fit_idx = np.union1d(np.linspace(0, P - 1, n_fit).round().astype(np.int64), np.flatnonzero(in_band))
    M = M_all[fit_idx].astype(np.float64)
    lo = np.percentile(M, 1, axis=0)
    hi = np.percentile(M, 99, axis=0)
    if np.all(hi - lo <= 0):
        raise ValueError(
            f"--method sh-uncalibrated: object {obj.name}: the images are constant on the object; nothing to fit"
        )
    W = _shadow_weights(M, lo, hi, cfg.shadow_threshold)
    S, a, L = _factorise(M, W, cfg.als_iterations)
    if np.linalg.matrix_rank(L, tol=1e-8 * max(np.abs(L).max(), 1e-30)) < 3:
        raise ValueError(
            f"--method sh-uncalibrated: object {obj.name}: the lighting varies in fewer than 3 independent ways across "
            "the images; normals cannot be recovered"
        )
    good = W.sum(axis=1) >= 4  # pixels whose factor rests on enough lit entries
    St = np.concatenate([S, np.ones((S.shape[0], 1))], axis=1)

    band_fit = in_band[fit_idx] & good
    if int(band_fit.sum()) < cfg.min_band_pixels:
        why = ("the mask must show the object's silhouette inside the image" if in_band.sum() < cfg.min_band_pixels
               else f"of its {int(in_band.sum())} contour pixels, only these are lit in at least 4 of the {K} images: "
                    "more images, lit from more sides, are needed")
        raise ValueError(f"--method sh-uncalibrated: object {obj.name}: only {int(band_fit.sum())} usable contour "
                         f"pixels (need {cfg.min_band_pixels}); {why}")
    ys, xs = np.nonzero(mask)
    c = direction[ys[fit_idx][band_fit], xs[fit_idx][band_fit]]
    gxy = _contour_columns(St[band_fit], c)
    gz = _z_column(St[good], gxy, cfg.robust_scale)

    # All pixels: per-pixel solve with the fitted lighting (chunked), then the gauge.
    out = np.empty((P, 3), np.float64)
    chunk = 65536
    for start in range(0, P, chunk):
        Mc = M_all[start:start + chunk].astype(np.float64)
        Wc = _shadow_weights(Mc, lo, hi, cfg.shadow_threshold)
        few = Wc.sum(axis=1) < 4
        Wc[few] = 1.0  # too few lit entries: use them all rather than an undetermined solve
        Sc = _solve_pixels(Mc, Wc, a, L)
        Stc = np.concatenate([Sc, np.ones((Sc.shape[0], 1))], axis=1)
        out[start:start + chunk] = np.concatenate([Stc @ gxy, (Stc @ gz)[:, None]], axis=1)
    if np.mean(out[:, 2]) < 0:
        out[:, 2] = -out[:, 2]  # the z sign is free: visible normals face the camera
    unit = _unit_rows(out)
    if np.median(np.abs(unit[:, 2])) < 0.05:
        log.warning("sh-uncalibrated: %s: the result is nearly flat (normals in the image plane); the "
                    "uniform-albedo prior failed on these images, do not trust it", obj.name)
    return _to_map(unit, mask)


METHODS: dict[str, Callable[[PSObject], np.ndarray]] = {
    "least-squares": least_squares,
    "sh-uncalibrated": sh_uncalibrated,
}


def run_baseline(method: str, obj: PSObject) -> np.ndarray:
    """Run a baseline by name (a key of METHODS)."""
    if method not in METHODS:
        raise ValueError(f"method: unknown baseline {method!r}, expected one of {', '.join(sorted(METHODS))}")
    return METHODS[method](obj)
