"""Can the images separate a map from its generalized bas-relief transforms? (report.json `ambiguity`)

Under distant lights, a Lambertian surface z = f(x, y) and its generalized bas-relief (GBR) transform
z' = lambda f + mu x + nu y give the same images, shadows included, with the lights and albedo transformed to
match (Belhumeur, Kriegman and Yuille, 1999): the depth scale (lambda) and a global tilt (mu, nu) are not
decided by the images. Only what the Lambertian model lacks (a specular lobe, an ambient term, near lights)
can break the tie. So instead of trusting one map of the family, the check fits two transforms of the judged
map, each started from the transformed fit (lights d' = G d, albedo times |G^-T n|, where the Lambertian part
is exactly as good as the map's; the better of that start and a short fit from it), and reports whether they
score worse by more than `validate.fitted.verdict.TIES['bas_relief']`. When they do not,
the report says that the images cannot decide the map's depth scale or tilt: the score judges the map up to that
family.

Normals transform as n' ~ (lambda n_x - mu n_z, lambda n_y - nu n_z, n_z) (camera frame, z toward the camera).
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from validate.fitted.verdict import TIES, Explanation, judged_rel_l1

VARIANTS = ((0.7, 0.0, 0.0), (1.0, 0.2, 0.0))
"""(lambda, mu, nu) of the transforms tested: a flatter relief, and a tilt about the y axis (about 11 degrees at
the image centre). Each costs one short fit."""
STEPS_FRACTION = 4
"""Each transform's fit runs steps / STEPS_FRACTION Adam steps (it starts where the Lambertian part is optimal)."""


def _scaled_gbr(n: np.ndarray, lam: float, mu: float, nu: float) -> np.ndarray:
    """lambda G^-T n for normals n (..., 3): (lambda n_x - mu n_z, lambda n_y - nu n_z, n_z)."""
    return np.stack([lam * n[..., 0] - mu * n[..., 2], lam * n[..., 1] - nu * n[..., 2], n[..., 2]], -1)


def gbr_normals(n: np.ndarray, lam: float, mu: float, nu: float) -> np.ndarray:
    """Unit normals (..., 3) of the GBR-transformed surface; zero vectors stay zero."""
    m = _scaled_gbr(n, lam, mu, nu)
    norm = np.linalg.norm(m, axis=-1, keepdims=True)
    return np.where(norm > 0, m / np.maximum(norm, 1e-12), 0.0)


def gbr_start(params: dict, albedo: np.ndarray, normals: np.ndarray, lam: float, mu: float, nu: float) -> dict:
    """The directional fit (`light_params` with directions, irradiance, ambient; albedo (P, 3); normals (P, 3))
    carried to the transformed map: n' . d' E' a' = n . d E a for every pixel and image."""
    g = np.array([[1.0, 0, 0], [0, 1.0, 0], [mu, nu, lam]])
    d = np.asarray(params["directions"], np.float64) @ g.T  # (K, 3) = G d
    dn = np.linalg.norm(d, axis=1, keepdims=True)
    gtn = (
        np.linalg.norm(_scaled_gbr(np.asarray(normals, np.float64), lam, mu, nu), axis=1, keepdims=True) / lam
    )  # |G^-T n|
    return {"directions": d / dn, "irradiance": np.asarray(params["irradiance"]) * dn,
            "ambient": np.asarray(params["ambient"]), "albedo": np.asarray(albedo, np.float64) * gtn}


def bas_relief_test(images: np.ndarray, mask: np.ndarray, normals: np.ndarray, fit: Any, judged: float, ex: Explanation,
                    config: Any, saturated: np.ndarray | None = None, progress: Any = None) -> dict:
    """report.json `ambiguity` for a map (H, W, 3) whose directional fit is `fit` (a `validate.fitted.fit.FitResult`)
    with judged residual `judged`, at the fitting resolution."""
    from validate.fitted.fit import fit_normals

    short = dataclasses.replace(config, light_model="directional", steps=max(1, config.steps // STEPS_FRACTION))
    observed = images[:, mask]
    rows = []
    for lam, mu, nu in VARIANTS:
        nv = np.where(mask[..., None], gbr_normals(normals, lam, mu, nu), 0).astype(np.float32)
        start = gbr_start(fit.light_params, fit.albedo, normals[mask], lam, mu, nu)
        # The transformed start itself (albedo and lobe re-solved, no Adam step), then a short fit from it: the
        # better of the two (Adam's first steps move every parameter by about its learning rate, even at an optimum).
        score = min(judged_rel_l1(fit_normals(images, mask, nv, s, progress, f"bas-relief {lam:g},{mu:g},{nu:g}",
                                              saturated, start=start).render, observed, ex)
                    for s in (dataclasses.replace(short, steps=0), short))
        cos = np.clip(np.sum(nv[mask] * normals[mask], 1), -1, 1)
        rows.append({"lambda": lam, "mu": mu, "nu": nu, "mean_angle_deg": float(np.degrees(np.arccos(cos)).mean()),
                     "judged_rel_l1": score, "relative_change": score / judged - 1 if judged > 0 else float("nan")})
    tie = TIES["bas_relief"]
    ties = [r for r in rows if tie.same(judged, r["judged_rel_l1"])]
    better = [r for r in rows if not tie.same(judged, r["judged_rel_l1"]) and r["judged_rel_l1"] < judged]
    if better:
        note = ("a bas-relief transform of the map scores better than the tie tolerance"
                ": the map's depth scale or tilt is not the one the images prefer")
    elif ties:
        note = (
            f"{len(ties)} of {len(rows)} bas-relief transforms (up to {max(r['mean_angle_deg'] for r in ties):.1f} deg "
            f"from the map) score within the tie tolerance of it: the images cannot decide the map's depth scale "
            "or global tilt, the score judges the map up to that family"
        )
    else:
        note = ("every bas-relief transform tested scores worse by more than the tie tolerance: the images (specular "
                "lobe, ambient, shadows) decide the depth scale and tilt here")
    return {"family": "generalized bas-relief", "tested": True, "variants": rows, "separated": not ties and not better,
            "tolerance": {"relative": tie.relative, "absolute": tie.absolute}, "note": note}


def not_tested(why: str) -> dict:
    return {"family": "generalized bas-relief", "tested": False, "note": why}
