"""Light models of the fitted re-render scene, their closed-form start, and their report form.

All in the camera frame (x right, y up, z toward the camera), scene units of `validate.fitted.heightfield`
(the image spans [-1, 1] along its longer side). Pixel values are modelled as
    I = albedo * (D * E * V + A * ao + indirect) + S * E * V
with D, S the diffuse and specular parts of the BSDF (cosine included), E the light's irradiance (RGB)
at the point, V its visibility (cast shadows), A the ambient radiance, ao the cosine-weighted unoccluded
fraction of the hemisphere. For a Lambertian surface D = max(0, n . l) / pi (Mitsuba's convention:
radiance = albedo / pi * E * cos).

Models (`LIGHT_MODELS`):
- `directional`: per image a direction toward the light d_k and an irradiance E_k, plus ambient A_k;
- `point`: per image a point light at p_k with intensity I_k (E = I_k / r^2 along l = (p_k - x) / r),
  plus ambient A_k;
- `environment`: per image a low-order environment (spherical harmonics up to order 2, 9 RGB
  coefficients) whose Lambertian irradiance uses Ramamoorthi and Hanrahan's closed form; no specular.

Report form (report.json `lights`, one list per image): `{"type": "directional", "direction_to_light": [x, y, z],
"irradiance": [r, g, b]}` (`scenes.lights.camera_directional`, the form of scene.json `camera_lights` too),
`{"type": "ambient", "radiance": [r, g, b]}`, `{"type": "point",
"position": [x, y, z], "intensity": [r, g, b]}`, `{"type": "environment_sh2", "coefficients": 9 x [r, g, b]}`,
in image units with the albedo normalised so that its mean over the mask is 0.5.
"""
from __future__ import annotations

import logging

import numpy as np

from scenes.lights import camera_directional

log = logging.getLogger(__name__)

LIGHT_MODELS = ("directional", "point", "environment")
POINT_START_DISTANCES = (1.25, 1.6, 2.0, 2.5, 3.2, 4.0, 5.0, 6.5, 8.0, 12.0, 20.0, 40.0)
"""Distances, in object radii from the object's centre, of the point-light start's grid search (Adam moves a
position by about its learning rate per step, so a near light must be found before it)."""
POINT_START_DIRECTIONS = 256
"""Directions of that grid (a Fibonacci sphere, those at most 20 deg below the image plane)."""

# Ramamoorthi & Hanrahan (2001): irradiance E(n) = sum_lm A_l L_lm Y_lm(n), A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4.
SH_BAND_WEIGHT = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)


def sh_basis(n: np.ndarray) -> np.ndarray:
    """Real SH basis up to order 2 at unit vectors n (..., 3) -> (..., 9)."""
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    return np.stack(
        [
            0.282095 * np.ones_like(x),
            0.488603 * y,
            0.488603 * z,
            0.488603 * x,
            1.092548 * x * y,
            1.092548 * y * z,
            0.315392 * (3 * z * z - 1),
            1.092548 * x * z,
            0.546274 * (x * x - y * y),
        ],
        -1,
    )


def closed_form_directional(normals: np.ndarray, images: np.ndarray, iterations: int = 6, lit_fraction: float = 0.2,
                            trim: float = 0.1, ambient: bool = False, exclude: np.ndarray | None = None) -> dict:
    """Least-squares Lambertian fit with the normals held fixed (no shadows, no specular, no rendering).

    normals: (P, 3) unit; images: (K, P, 3). Model per image k: I_k(p) = albedo(p) * c_k * (n_p . b_k + a_k),
    alternating between b_k, a_k (per image, over pixels lit in that image, the worst `trim` fraction of
    residuals dropped: highlights, shadows) and the per-pixel albedo; an image with fewer usable pixels than
    unknowns gets no light (zero irradiance, direction (0, 0, 1)). Returns a dict with
    `directions` (K, 3) toward the light, `irradiance` (K, 3), `ambient` (K, 3), `albedo` (P, 3),
    normalised so that the mean albedo is 0.5. exclude: (K, P) bool observations left out of every fit
    (saturated ones, whose values are only lower bounds).
    """
    k, p, _ = images.shape
    g = images.mean(-1).astype(np.float64)  # (K, P)
    use = np.ones((k, p), bool) if exclude is None else ~np.asarray(exclude, bool)
    # Without `ambient` the constant column is left out: per-pixel albedo times a per-image ambient is a
    # rank-one term that the alternation drifts into (measured on DiLiGenT ball: 1 deg -> 75 deg).
    X = np.concatenate([normals.astype(np.float64), np.ones((p, 1 if ambient else 0))], 1)  # (P, 3 or 4)
    # The start of the per-pixel albedo from images brought to one brightness: the fit is invariant to a scale
    # per image (raw captures, unequal light intensities), and so must be its start (6 alternations do not
    # forget it: DiLiGenT cat in the uncalibrated layout 7.2 deg, divided by the intensity file 4.1).
    level = np.array([g[i][use[i]].mean() if use[i].any() else 0.0 for i in range(k)])  # (K,)
    ok = use & (level[:, None] > 0)  # an image without usable pixels (black, saturated) says nothing here
    normed = np.where(ok, g / np.where(level > 0, level, 1.0)[:, None], np.nan)
    with np.errstate(all="ignore"):
        rho = np.nanpercentile(np.where(ok.any(0)[None], normed, 0.0), 90, axis=0)
    rho = np.maximum(np.nan_to_num(rho, nan=1e-6), 1e-6)
    B = np.zeros((k, X.shape[1]))
    for it in range(iterations):
        ratio = g / rho[None]
        for i in range(k):
            r = ratio[i]
            lit = (r > lit_fraction * np.percentile(r, 95)) & use[i]
            if it > 0:
                lit &= (normals @ B[i, :3]) > 0.05 * np.linalg.norm(B[i, :3])
            if lit.sum() < 8:
                lit = (r > 0) & use[i]
            if lit.sum() < X.shape[1]:
                # Fewer usable pixels than unknowns (a black image, or one saturated wherever it is lit): no
                # light can be solved for; it starts as none (the fit may still light it).
                B[i] = 0.0
                continue
            sw = np.sqrt(rho[lit])  # weight by albedo: brighter pixels are less noisy relative to their value
            A, y = X[lit] * sw[:, None], r[lit] * sw
            b, *_ = np.linalg.lstsq(A, y, rcond=None)
            res = np.abs(A @ b - y)
            keep = res <= np.quantile(res, 1 - trim)
            if keep.sum() >= 8:
                b, *_ = np.linalg.lstsq(A[keep], y[keep], rcond=None)
            B[i] = b
        amb = np.maximum(B[:, 3], 0) if ambient else np.zeros(k)
        shade = np.maximum(X[:, :3] @ B[:, :3].T, 0) + amb[None]  # (P, K)
        rho = np.maximum((g.T * shade * use.T).sum(1) / np.maximum((shade * shade * use.T).sum(1), 1e-12), 1e-6)
    # Colour: per image c_k (3) and per pixel albedo (P, 3) with the gray shading fixed.
    shade = shade.T  # (K, P)
    rho3 = np.repeat(rho[:, None], 3, 1)
    c = np.ones((k, 3))
    w3 = use[..., None].astype(np.float64)  # (K, P, 1)
    for _ in range(4):
        m = rho3[None] * shade[..., None] * w3  # (K, P, 3)
        c = (images * m).sum(1) / np.maximum((m * m).sum(1), 1e-12)
        m = shade[..., None] * c[:, None, :] * w3
        rho3 = np.maximum((images * m).sum(0) / np.maximum((m * m).sum(0), 1e-12), 0)
    scale = 0.5 / max(float(rho3.mean()), 1e-12)
    rho3 *= scale
    c /= scale
    bn = np.linalg.norm(B[:, :3], axis=1)
    dirs = B[:, :3] / np.maximum(bn, 1e-12)[:, None]
    dirs[bn < 1e-12] = [0.0, 0.0, 1.0]
    return {"directions": dirs, "irradiance": np.pi * bn[:, None] * c, "ambient": amb[:, None] * c, "albedo": rho3}


def _fibonacci_directions(count: int, min_z: float) -> np.ndarray:
    i = np.arange(count) + 0.5
    z = 1 - 2 * i / count
    phi = np.pi * (1 + 5**0.5) * i
    r = np.sqrt(1 - z * z)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    return d[d[:, 2] >= min_z]


def _cone(d: np.ndarray, half_angle: float, count: int, rng: np.random.Generator) -> np.ndarray:
    """`count` unit vectors within `half_angle` (radians) of d, and d itself."""
    t = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(d, t)
    a = half_angle * np.sqrt(rng.uniform(size=count))
    phi = rng.uniform(0, 2 * np.pi, size=count)
    out = np.cos(a)[:, None] * d + np.sin(a)[:, None] * (np.cos(phi)[:, None] * t + np.sin(phi)[:, None] * b)
    return np.concatenate([d[None], out])


def point_start(normals: np.ndarray, positions: np.ndarray, images: np.ndarray, start: dict,
                exclude: np.ndarray | None = None, iterations: int = 3, max_pixels: int = 1000,
                seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closed-form start of the point-light model (Lambertian, no shadows, ambient of `start` held).

    Per image, a grid search over positions (directions x distances from the object's centre, see
    `POINT_START_DIRECTIONS` and `POINT_START_DISTANCES`; on at most `max_pixels` pixels) with the
    intensity in closed form per channel, the lowest squared residual kept; then the per-pixel albedo is
    re-solved, and the two alternate, later searches in a cone around the current light. The first search
    uses a uniform albedo: the directional start's albedo and directions have absorbed a near light's
    fall-off (measured on a sphere lit from 2 radii: the directional direction was 45 deg off, and with its
    albedo the true position fitted worse than a light 20 radii away).

    normals, positions: (P, 3); images: (K, P, 3); start: `closed_form_directional`'s dict; exclude: (K, P)
    bool observations left out. Returns positions (K, 3), intensities (K, 3) and albedo (P, 3)."""
    n = normals.astype(np.float64)
    x = positions.astype(np.float64)
    rng = np.random.default_rng(seed)
    centre = x.mean(0)
    radius = max(float(np.linalg.norm(x - centre, axis=1).max()), 1e-6)
    dist = radius * np.asarray(POINT_START_DISTANCES)  # (C,)
    grid = _fibonacci_directions(POINT_START_DIRECTIONS, -np.sin(np.radians(20)))
    k, p = images.shape[:2]
    sub = np.sort(rng.choice(p, size=min(p, max_pixels), replace=False))
    use = np.ones((k, p), bool) if exclude is None else ~np.asarray(exclude, bool)
    amb = np.asarray(start["ambient"], np.float64)  # (K, 3)
    albedo = np.full((p, 3), float(np.mean(start["albedo"])))
    pos = np.zeros((k, 3))

    def shading(lp: np.ndarray, pts: np.ndarray, nrm: np.ndarray) -> np.ndarray:
        v = lp[:, None, :] - pts[None]  # (C, P, 3)
        r2 = np.maximum((v * v).sum(-1), 1e-12)
        return np.maximum((v * nrm[None]).sum(-1), 0) / (np.sqrt(r2) * r2 * np.pi)  # (C, P): cos / (pi r^2)

    def best(lp: np.ndarray, s: np.ndarray, i: int) -> np.ndarray:
        """The candidate of lp (C, 3) with shading s (C, P') on the subsample whose render, intensity solved
        per channel, has the lowest squared residual: sum w y^2 - (s . w y a)^2 / (s^2 . w a^2)."""
        w = use[i, sub][:, None].astype(np.float64)
        a = albedo[sub]
        y = images[i, sub] - a * amb[i]  # (P', 3)
        num = s @ (w * y * a)  # (C, 3)
        den = np.maximum((s * s) @ (w * a * a), 1e-12)
        gain = np.where(num > 0, num * num / den, 0.0).sum(1)  # intensities are positive
        return lp[int(np.argmax(gain))]

    lp0 = (centre[None, None] + grid[:, None, :] * dist[None, :, None]).reshape(-1, 3)  # (C, 3)
    s0 = shading(lp0, x[sub], n[sub])  # the same grid for every image: its shading once
    for it in range(iterations):
        for i in range(k):
            if it == 0:
                pos[i] = best(lp0, s0, i)
            else:
                r0 = np.linalg.norm(pos[i] - centre)
                dirs = _cone((pos[i] - centre) / r0, np.radians(10), 48, rng)
                lp = (
                    centre[None, None] + dirs[:, None, :] * (r0 * np.array([0.8, 0.9, 1.0, 1.1, 1.25]))[None, :, None]
                ).reshape(-1, 3)
                pos[i] = best(lp, shading(lp, x[sub], n[sub]), i)
        shade = shading(pos, x, n)  # (K, P)
        # Intensity on all pixels, then the albedo.
        m = albedo[None] * shade[..., None] * use[..., None]
        inten = np.maximum(
            (m * (images - albedo[None] * amb[:, None, :])).sum(1) / np.maximum((m * m).sum(1), 1e-12), 1e-9
        )
        m = (shade[..., None] * inten[:, None, :] + amb[:, None, :]) * use[..., None]  # (K, P, 3)
        albedo = np.maximum((images * m).sum(0) / np.maximum((m * m).sum(0), 1e-12), 0)
    return pos, inten, albedo


def angular_errors_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K,) angles in degrees between rows of two (K, 3) direction arrays (`scenes.metrics.angles_deg`)."""
    from scenes.metrics import angles_deg

    return angles_deg(a, b)


def _check_model(model: str) -> None:
    if model not in LIGHT_MODELS:
        raise ValueError(f"light model: unknown model {model!r}, expected one of {', '.join(LIGHT_MODELS)}")


def report_lights(model: str, params: dict) -> list[list[dict]]:
    """One list of light dicts per image (see the module doc) from fitted parameter arrays."""
    _check_model(model)
    out = []
    k = len(params["ambient"]) if "ambient" in params else len(params["sh"])
    for i in range(k):
        if model == "directional":
            d = np.asarray(params["directions"][i], np.float64)
            entry = [
                {"type": "directional", **camera_directional(d / np.linalg.norm(d), params["irradiance"][i])},
                {"type": "ambient", "radiance": np.asarray(params["ambient"][i]).tolist()},
            ]
        elif model == "point":
            entry = [
                {
                    "type": "point",
                    "position": np.asarray(params["positions"][i]).tolist(),
                    "intensity": np.asarray(params["intensity"][i]).tolist(),
                },
                {"type": "ambient", "radiance": np.asarray(params["ambient"][i]).tolist()},
            ]
        else:
            entry = [{"type": "environment_sh2", "coefficients": np.asarray(params["sh"][i]).tolist()}]
        out.append(entry)
    return out


def directions_of(model: str, params: dict, centre: np.ndarray | None = None) -> np.ndarray:
    """(K, 3) unit directions toward the main light of each image (point lights: seen from `centre`)."""
    _check_model(model)
    if model == "directional":
        d = np.asarray(params["directions"], np.float64)
    elif model == "point":
        d = np.asarray(params["positions"], np.float64) - (np.zeros(3) if centre is None else centre)
    else:
        d = np.asarray(params["sh"], np.float64).mean(-1)[:, [3, 1, 2]]  # first-order band: (x, y, z)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
