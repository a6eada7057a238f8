"""Light models of the fitted re-render scene, their closed-form start, and their report form.

All in the camera frame (x right, y up, z toward the camera), scene units of `validate.heightfield`
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

Report form (report.json `lights`, one list per image): `{"type": "directional", "direction": [x, y, z],
"irradiance": [r, g, b]}`, `{"type": "ambient", "radiance": [r, g, b]}`, `{"type": "point",
"position": [x, y, z], "intensity": [r, g, b]}`, `{"type": "environment_sh2", "coefficients": 9 x [r, g, b]}`,
in image units with the albedo normalised so that its mean over the mask is 0.5.
"""
from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger(__name__)

LIGHT_MODELS = ("directional", "point", "environment")
POINT_START_DISTANCE = 4.0
"""Distance (scene units) of a point light started from a directional fit."""

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


def closed_form_directional(
    normals: np.ndarray, images: np.ndarray, iterations: int = 6, lit_fraction: float = 0.2, trim: float = 0.1, ambient: bool = False,
    exclude: np.ndarray | None = None,
) -> dict:
    """Least-squares Lambertian fit with the normals held fixed (no shadows, no specular, no rendering).

    normals: (P, 3) unit; images: (K, P, 3). Model per image k: I_k(p) = albedo(p) * c_k * (n_p . b_k + a_k),
    alternating between b_k, a_k (per image, over pixels lit in that image, the worst `trim` fraction of
    residuals dropped: highlights, shadows) and the per-pixel albedo. Returns a dict with
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
    rho = np.maximum(np.percentile(g, 90, axis=0), 1e-6)
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
    return {
        "directions": dirs,
        "irradiance": np.pi * bn[:, None] * c,
        "ambient": amb[:, None] * c,
        "albedo": rho3,
    }


def angular_errors_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K,) angles in degrees between rows of two (K, 3) direction arrays."""
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip((a * b).sum(1), -1, 1)))


def report_lights(model: str, params: dict) -> list[list[dict]]:
    """One list of light dicts per image (see the module doc) from fitted parameter arrays."""
    out = []
    k = len(params["ambient"]) if "ambient" in params else len(params["sh"])
    for i in range(k):
        if model == "directional":
            d = np.asarray(params["directions"][i], np.float64)
            entry = [
                {"type": "directional", "direction": (d / np.linalg.norm(d)).tolist(), "irradiance": np.asarray(params["irradiance"][i]).tolist()},
                {"type": "ambient", "radiance": np.asarray(params["ambient"][i]).tolist()},
            ]
        elif model == "point":
            entry = [
                {"type": "point", "position": np.asarray(params["positions"][i]).tolist(), "intensity": np.asarray(params["intensity"][i]).tolist()},
                {"type": "ambient", "radiance": np.asarray(params["ambient"][i]).tolist()},
            ]
        else:
            entry = [{"type": "environment_sh2", "coefficients": np.asarray(params["sh"][i]).tolist()}]
        out.append(entry)
    return out


def directions_of(model: str, params: dict, centre: np.ndarray | None = None) -> np.ndarray:
    """(K, 3) unit directions toward the main light of each image (point lights: seen from `centre`)."""
    if model == "directional":
        d = np.asarray(params["directions"], np.float64)
    elif model == "point":
        d = np.asarray(params["positions"], np.float64) - (np.zeros(3) if centre is None else centre)
    else:
        d = np.asarray(params["sh"], np.float64).mean(-1)[:, [3, 1, 2]]  # first-order band: (x, y, z)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def known_scene_lights(desc, exposures: list[float]) -> list[list[dict]]:
    """report.json `lights` of a known scene (a `scenes.description.SceneDescription`): per image, its
    lights in the camera frame with the exposure applied. Directional: direction toward the light and
    irradiance x colour x exposure; point: position relative to the camera target and intensity; area:
    centre, normal and radiance; environment: scale and the rotation to the camera frame."""
    from scenes.geometry import camera_rotation

    cam = desc.camera
    R = camera_rotation(cam.origin, cam.target, cam.up)
    target = np.asarray(cam.target, np.float64)
    out = []
    for image, exp in zip(desc.images, exposures):
        entry = []
        for l in image.lights:
            rgb = lambda s: [float(s) * float(c) * float(exp) for c in l.color]  # noqa: E731
            if l.type == "directional":
                d = -(R @ np.asarray(l.direction, np.float64))
                entry.append({"type": "directional", "direction": (d / np.linalg.norm(d)).tolist(), "irradiance": rgb(l.irradiance)})
            elif l.type == "point":
                entry.append({"type": "point", "position": (R @ (np.asarray(l.position) - target)).tolist(), "intensity": rgb(l.intensity)})
            elif l.type == "area":
                nrm = R @ (np.asarray(l.target, np.float64) - np.asarray(l.position, np.float64))
                entry.append({"type": "area", "position": (R @ (np.asarray(l.position) - target)).tolist(),
                              "normal": (nrm / max(np.linalg.norm(nrm), 1e-12)).tolist(), "width": l.width, "height": l.height,
                              "radiance": rgb(l.radiance)})
            else:
                entry.append({"type": "environment", "scale": float(l.scale) * float(exp),
                              "to_camera": (R @ np.asarray(l.to_world, np.float64)[:3, :3]).tolist()})
        out.append(entry)
    return out
