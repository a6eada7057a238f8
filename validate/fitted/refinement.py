"""Refine a normal map by differentiable rendering (library and CLI `python -m validate.refine`).

Starting from any prediction: (1) the scene is fitted around the normal map held fixed (`validate.fitted.fit`;
with `--lights calibrated` the calibrated directional lights of the folder, DiLiGenT's files or scene.json's
`camera_lights`, are used and held fixed instead: the known-scene mode of refinement); (2) the normals are
optimised together with the lights by Adam through the same Mitsuba shading, with the albedo re-solved in
closed form at every refresh, under a regulariser (`validate.fitted.regulariser`): smoothness (squared differences of
4-neighbour normals), integrability (squared curl of the gradient field p = -nx/nz, q = ny/nz over 2x2 blocks) and the
silhouette (normals at the mask boundary may not point inward, and no normal may face away from the
camera). A fraction of the images is held out: their residual is measured at every refresh and the normals
of the best held-out residual are kept (early stopping after `patience` refreshes without improvement).
The geometry (mesh for shadows) is the integral of the starting map.

Refinement runs at the fitting resolution; the change it made is upsampled (bilinear) and applied to the
full-resolution input map. Before / after scores are fresh fits (fitted mode, same budget and seed) with
the starting and the refined map held fixed.

Usage:
    python -m validate.refine --data OBJ --normals PRED/OBJ/normal.png --out DIR
writes DIR/<object>/normal.png (16-bit, (n + 1) / 2, background 32768: the layout unips.evaluate reads)
and DIR/<object>/refine_report.json.
"""
from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np

from scenes.cli.options import NotOnCommandLine, arg, check_fields, option
from scenes.renderer.variant import require_ad_variant
from validate.fitted.fit import fit_normals, run_fit
from validate.fitted.fit_report import (
    JudgedCapture,
    full_config_dict,
    judge_capture,
    provenance,
    saturated_fraction,
)
from validate.fitted.fit_scene import FitConfig, FitScene, Progress, lambertian_start, to_jit
from validate.fitted.regulariser import make_regulariser
from validate.fitted.rotation_search import search_rotation
from validate.fitted.verdict import TIES, judged_rel_l1, told_apart
from validate.judgeable import MIN_IMAGES

log = logging.getLogger(__name__)

LIGHT_SOURCES = ("fitted", "calibrated")
REFINE_OUTPUTS = ("normal.png", "refine_report.json")
"""What refinement writes into <out>/<object>/."""


@dataclass
class RefineFit(FitConfig):
    """The scene fit of refinement: `FitConfig` without the floor maps and the bas-relief score, which only the
    check computes."""

    floor_maps: Annotated[tuple[str, ...], NotOnCommandLine] = FitConfig.floor_maps
    """Not used by refinement."""
    bas_relief: Annotated[bool, NotOnCommandLine] = FitConfig.bas_relief
    """Not used by refinement."""


@dataclass
class RefineConfig:
    """Options of the refinement."""

    fit: RefineFit = field(default_factory=lambda: RefineFit())
    """Scene fit (light model, steps of the fixed-normal stage, resolution, seed); its floor maps are not used."""
    refine_steps: int = option(300, minimum=0, maximum=30000)
    """Adam steps of the joint stage (normals and lights; at most 100 times the default, a bound against typos)."""
    lights: Literal[LIGHT_SOURCES] = "fitted"
    """'fitted' (lights fitted to the images) or 'calibrated' (the folder's calibrated directional lights, held
    fixed)."""
    holdout_fraction: Annotated[float, arg(name="holdout")] = option(0.1, minimum=0, below=0.5)
    """Fraction of the images held out for early stopping (at least one when K >= 5, none below)."""
    patience: int = option(4, minimum=1)
    """Refreshes without a better held-out residual before stopping."""
    smoothness: float = option(0.02, minimum=0)
    """Weight of the smoothness term, relative to the mean input value."""
    integrability: float = option(0.002, minimum=0)
    """Weight of the integrability (curl) term, relative to the mean input value."""
    silhouette: float = option(1.0, minimum=0)
    """Weight of the silhouette / facing terms, relative to the mean input value."""
    rounds: int = option(3, minimum=1)
    """Alternations of (fit the lights to the current normals, then move the normals with the lights held)."""
    rotation_search: bool = False
    """Before each round's normal stage after the first, search a global tilt of the normals (the lights
    turned with them, then re-fitted) by residual. A per-pixel update with the lights re-fitted each round
    cannot remove a starting map's global tilt (lights and normals turn together), but where the images
    pin the orientation (highlights, which do not turn with the view; cast shadows) the residual prefers the
    right one (DiLiGenT cat, from the shipped model's map: docs/check.md, "How well it works"). Off by
    default: on a diffuse convex object nothing pins the tilt and the search moves the map by noise-level
    residual differences (the 32 px test sphere, tilted 10 deg about x: it leaves that tilt and adds 2-4 deg
    about y). A turn about the view axis is never searched: it leaves every image as it is. Directional and
    point lights."""
    rotation_steps: int = option(80, minimum=1, maximum=8000)
    """Adam steps of the light fit at each candidate rotation (at most 100 times the default)."""
    update_lights: bool = False
    """Keep optimising the lights while the normals move. Off by default: with the lights free, a Lambertian
    scene's normals and lights can drift together along the generalized bas-relief ambiguity (measured on
    the test sphere, 20 deg random error: 13 deg after refinement with free lights, < 1 deg with the lights of
    the first stage held)."""

    def validate(self) -> "RefineConfig":
        self.fit.validate()
        check_fields(self)
        if self.lights == "calibrated" and self.fit.light_model != "directional":
            raise ValueError("--lights calibrated needs --light-model directional")
        return self


@dataclass
class RefineResult:
    normals: np.ndarray
    """(H, W, 3) refined normals at the fitting resolution (0 outside the mask)."""
    holdout_curve: list[tuple[int, float]]
    """(step, held-out rel_l1) at each refresh of the joint stage."""
    best_step: int
    """Step whose normals were kept."""
    seconds: float
    light_model: str = "directional"
    """Light model used ('auto' resolved: the model with the lowest residual around the starting map)."""
    rotation: dict | None = None
    """The last rotation search (`search_rotation`'s record: chosen tilt, equally good tilts and their spread)."""
    holdout: tuple[int, ...] = ()
    """Indices of the images held out of every step that moves the normals (early stopping reads them): the
    check can judge the refined map on them."""


def refine_normals(
    images: np.ndarray,
    mask: np.ndarray,
    normals: np.ndarray,
    config: RefineConfig | None = None,
    calibrated: tuple[np.ndarray, np.ndarray] | None = None,
    progress: Progress | None = None,
    saturated: np.ndarray | None = None,
) -> RefineResult:
    """Refine `normals` (H, W, 3) against images (K, H, W, 3) over mask (H, W), all at the fitting resolution.

    calibrated: (directions (K, 3) toward the light, irradiance (K, 3)) held fixed when config.lights is
    'calibrated'. saturated: (K, H, W, 3) bool censored observations (see `validate.fitted.fit_scene.FitScene`)."""
    # Over 80 lines on purpose: the rounds and the early-stopping callback share one state (best normals,
    # stale count, step offset); split apart, that state would travel through every piece.
    config = (config or RefineConfig()).validate()
    require_ad_variant()
    t0 = time.perf_counter()
    cfg = config.fit
    if cfg.light_model == "auto":
        # Chosen once, around the starting map, and then held: a model switching mid-way would make the
        # held-out curve and the before / after scores incomparable.
        cfg = replace(
            cfg, light_model=fit_normals(images, mask, normals, cfg, progress, "refine: light model", saturated).model
        )
        log.info("refine: light model %s (lowest residual around the starting map)", cfg.light_model)
    fs = FitScene(images, mask, normals, cfg, cfg.light_model, saturated)
    rotation: dict = {}
    start = lambertian_start(fs)
    fixed: set[str] = set()
    if config.lights == "calibrated":
        if calibrated is None:
            raise ValueError(
                "--lights calibrated: the folder has no calibrated directional lights (DiLiGenT files or scene.json "
                "camera_lights)"
            )
        start["directions"] = np.asarray(calibrated[0], np.float64)
        start["irradiance"] = np.asarray(calibrated[1], np.float64)
        fixed = {"dir", "log_e"}
    fs.init_params(start)
    base_list = fs.param_list
    light_keys = {"dir", "log_e", "pos", "log_a"} | {f"sh{j}" for j in range(9)}

    def only(exclude: set[str]):
        return lambda with_normals: [(n, v) for n, v in base_list(with_normals) if n not in exclude]

    k = fs.k
    enough = k >= MIN_IMAGES["holdout"]
    n_hold = int(round(config.holdout_fraction * k)) if enough else 0
    n_hold = max(n_hold, 1) if enough and config.holdout_fraction > 0 else n_hold
    holdout = np.sort(fs.rng.choice(k, size=n_hold, replace=False)) if n_hold else np.zeros(0, np.int64)
    best = {"score": np.inf, "normals": fs.n_np.copy(), "step": 0}
    curve: list[tuple[int, float]] = []
    stale = [0]
    offset = [0]

    def on_eval(step: int, score: float) -> bool:
        curve.append((offset[0] + step, score))
        if score < best["score"] - 1e-6:
            best.update(score=score, normals=fs.n_np.copy(), step=offset[0] + step)
            stale[0] = 0
        else:
            stale[0] += 1
        return stale[0] >= config.patience

    per_round = max(1, config.refine_steps // config.rounds)
    reg = make_regulariser(fs, config)
    for r in range(config.rounds):
        # Lights (and lobe, albedo) for the current normals, held fixed: errors-in-variables make lights fitted
        # to a noisy map biased, so they are re-fitted as the map improves.
        fs.param_list = only(fixed)  # type: ignore[method-assign]
        run_fit(
            fs,
            cfg.steps if r == 0 else max(1, cfg.steps // 2),
            progress=progress,
            label=f"refine: lights {r + 1}/{config.rounds}",
        )
        if config.rotation_search and not fixed and r > 0:
            rotation = {}
            search_rotation(fs, np.setdiff1d(np.arange(k), holdout), config, progress=progress,
                            label=f"refine: rotation {r + 1}/{config.rounds}", record=rotation)
        if len(holdout):
            on_eval(0, fs.score(fs.render(holdout), holdout))
        stale[0] = 0
        fs.param_list = only(fixed if config.update_lights else fixed | light_keys)  # type: ignore[method-assign]
        run_fit(
            fs,
            per_round,
            optimise_normals=True,
            regulariser=reg,
            holdout=holdout if len(holdout) else None,
            on_eval=on_eval if len(holdout) else None,
            progress=progress,
            label=f"refine: normals {r + 1}/{config.rounds}",
        )
        offset[0] += per_round
        if len(holdout):
            on_eval(0, fs.score(fs.render(holdout), holdout))
            fs.n_np = best["normals"].copy()  # continue from the best normals so far
            fs.normals = to_jit(fs.mi.Vector3f, fs.n_np.astype(np.float32))
    fs.param_list = base_list  # type: ignore[method-assign]
    if len(holdout):
        n_best = best["normals"]
    else:
        n_best = fs.n_np
    n_best = n_best / np.linalg.norm(n_best, axis=1, keepdims=True)
    out = np.zeros(mask.shape + (3,), np.float32)
    out[mask] = n_best
    return RefineResult(
        normals=out,
        holdout=tuple(int(i) for i in holdout),
        holdout_curve=curve,
        best_step=int(best["step"]) if len(holdout) else config.refine_steps,
        seconds=time.perf_counter() - t0,
        light_model=cfg.light_model,
        rotation=rotation or None,
    )


def upsample_change(
    full: np.ndarray, mask_full: np.ndarray, start_small: np.ndarray, refined_small: np.ndarray
) -> np.ndarray:
    """Apply the change refined_small - start_small (h, w, 3), upsampled bilinearly, to the full map (H, W, 3)."""
    import cv2

    if start_small.shape == full.shape:
        return refined_small
    h, w = mask_full.shape
    f = h // start_small.shape[0]
    delta = np.zeros((start_small.shape[0] * f, start_small.shape[1] * f, 3), np.float32)
    delta[:] = cv2.resize(
        (refined_small - start_small).astype(np.float32),
        (start_small.shape[1] * f, start_small.shape[0] * f),
        interpolation=cv2.INTER_LINEAR,
    )
    big = np.zeros_like(full)
    big[: delta.shape[0], : delta.shape[1]] = delta
    n = full + big
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    return np.where(mask_full[..., None], n, 0).astype(np.float32)


def _declined(jc: JudgedCapture, mae_in: float | None, t0: float) -> dict:
    """The report (written with the input map) of a capture the check does not judge."""
    report = {
        "mode": "refine",
        "object": jc.cap.name,
        "folder": str(jc.cap.folder),
        "prediction": jc.source,
        "accepted": False,
        "why": f"declined, the input map is kept: {jc.why}",
        "trusted": False,
        "explained_fraction": jc.explanation.explained_fraction,
        "refined_fraction": 0.0,
        "before": {"mae_deg": mae_in},
        "after": {"mae_deg": mae_in},
        "timings": {"total_s": time.perf_counter() - t0},
    }
    return report


def refine_object(
    data: str | JudgedCapture,
    normals: str | np.ndarray | None = None,
    config: RefineConfig | None = None,
    out_dir: str | None = None,
    progress: Progress | None = None,
    overwrite: bool = False,
) -> dict:
    """Refine the normal map of one object folder (or of a capture already judged: `validate.fitted.fit_report.judge`,
    shared with the check); write normal.png and refine_report.json under out_dir/<object>/."""
    config = (config or RefineConfig()).validate()
    jc, target = judge_capture(data, normals, config.fit, "refine", out_dir, REFINE_OUTPUTS, "validate.refine",
                               overwrite)
    report, refined = refine_judged(jc, config, progress)
    if target is not None:
        write_refined(target, refined, report)
    return report


def _verdict_words(judged_fell: bool, held: dict | None, apart: bool, before: float, after: float, ex) -> str:
    """refine_report.json `why`: what the judged and the held-out residuals did and what that says."""
    if not judged_fell:
        return (f"declined, the input map is kept: the judged residual did not fall by "
                f"{TIES['refinement'].relative:.0%} ({before:.4f} -> {after:.4f})")
    if held is None:
        return ("declined, the input map is kept: no image was held out of the refinement (fewer than "
                f"{MIN_IMAGES['holdout']} images, or --holdout 0), so nothing it was not fitted to confirms the judged "
                f"fall ({before:.4f} -> {after:.4f})")
    h0, h1 = held["before_rel_l1"], held["after_rel_l1"]
    if not _held_fell(held):
        return (f"declined, the input map is kept: the judged residual fell ({before:.4f} -> {after:.4f}) but on the "
                f"held-out images, which no step used, it did not fall by {TIES['refinement_holdout'].relative:.0%} "
                f"({h0:.4f} -> {h1:.4f}): the refinement may have fitted the other images' noise")
    within = ("" if apart else f", within the capture's resolution {ex.resolution:.4f}: the images do not tell the "
              "maps apart (the refined one fits the physics best, not shown closer to the surface)")
    return (f"the judged residual fell {before:.4f} -> {after:.4f} on the observations every map shares and "
            f"{h0:.4f} -> {h1:.4f} on the held-out images{within}; {ex.explained_fraction:.0%} of the object was "
            "refined, the rest keeps the input map")


def _held_fell(held: dict | None) -> bool:
    """The held-out residual fell by more than its tie (`TIES['refinement_holdout']`)."""
    if held is None:
        return False
    h0, h1 = held["before_rel_l1"], held["after_rel_l1"]
    return h1 < h0 and not TIES["refinement_holdout"].same(h0, h1)


def refine_judged(jc: JudgedCapture, config: RefineConfig, progress: Progress | None = None) -> tuple[dict, np.ndarray]:
    """Refine a judged capture's map: (report, the full-resolution map to keep: the refined one where accepted,
    else the input map; float, unit inside the mask)."""
    from scenes.metrics import mean_angular_error as mae_deg
    from validate.observations import downsample_normals

    mi = require_ad_variant()
    t0 = time.perf_counter()
    cap, full, small, n_small, ex, f = jc.cap, jc.full, jc.small, jc.normals, jc.explanation, jc.downsample
    mae_in = mae_deg(full, cap.normal_gt, cap.mask) if cap.normal_gt is not None else None
    if not jc.trusted:
        return _declined(jc, mae_in, t0), full
    calibrated = None
    if small.light_directions is not None and small.light_irradiance is not None:
        calibrated = (small.light_directions, small.light_irradiance)
    res = refine_normals(small.images, small.mask, n_small, config, calibrated, progress, small.saturated)
    # Only the pixels the physics explains may change; elsewhere the input map stays.
    unexplained = small.mask.copy()
    unexplained[small.mask] = ~ex.explained
    res.normals = np.where(unexplained[..., None], n_small, res.normals).astype(np.float32)
    refined_full = upsample_change(full, cap.mask, n_small, res.normals)
    refined_small = downsample_normals(refined_full, small.mask, f) if f > 1 else refined_full
    # Both scores with the light model the refinement used ('auto' resolved), so that they compare.
    fit_cfg = replace(config.fit, light_model=res.light_model)
    before, judged_before = jc.score(n_small, fit_cfg, progress, "score before")
    after, judged_after = jc.score(refined_small, fit_cfg, progress, "score after")
    apart = told_apart(judged_before, judged_after, ex)
    held = None if not res.holdout else {  # evidence the refined normals were never fitted to
        "images": list(res.holdout), "before_rel_l1": judged_rel_l1(before.render, jc.observed, ex, res.holdout),
        "after_rel_l1": judged_rel_l1(after.render, jc.observed, ex, res.holdout),
        "note": "judged on the held-out images only, which no step that moved the normals used"}
    # Kept only when the judged residual (observations every map shares) falls by more than its tie and the
    # held-out images' residual by more than theirs: the judged fall alone also rewards fitting noise.
    judged_fell = judged_after < judged_before and not TIES["refinement"].same(judged_before, judged_after)
    accepted = judged_fell and _held_fell(held)
    why = _verdict_words(judged_fell, held, apart, judged_before, judged_after, ex)
    # The refined map's own error (with ground truth), kept or not: what a rule of keeping is measured on.
    mae_refined = mae_deg(refined_full, cap.normal_gt, cap.mask) if cap.normal_gt is not None else None
    if not accepted:
        refined_full = full
    report: dict[str, Any] = {
        "mode": "refine",
        "accepted": accepted,
        "why": why,
        "trusted": True,
        "explained_fraction": ex.explained_fraction,
        "refined_fraction": ex.explained_fraction if accepted else 0.0,
        "judged_before_rel_l1": judged_before,
        "judged_after_rel_l1": judged_after,
        "resolution": ex.resolution,
        "told_apart": apart,
        "holdout_judged": held,
        "lights_source": config.lights,
        "light_model": res.light_model,
        "object": cap.name,
        "folder": str(cap.folder),
        "prediction": jc.source,
        "images_count": int(cap.images.shape[0]),
        "before": {"rel_l1": before.rel_l1, "mae_deg": mae_in},
        "after": {"rel_l1": after.rel_l1,
                  "mae_deg": mae_deg(refined_full, cap.normal_gt, cap.mask) if cap.normal_gt is not None else None},
        "refined_mae_deg": mae_refined,
        "rotation_search": res.rotation,
        "holdout_curve": [[int(s), float(v)] for s, v in res.holdout_curve],
        "best_step": res.best_step,
        "lights": after.lights,
        "fit_downsample": f,
        "saturated_fraction": saturated_fraction(small),
        "note": (
            f"refined and scored at 1/{f} resolution ({small.mask.shape[1]}x{small.mask.shape[0]}); the change is "
            "upsampled bilinearly onto the full-resolution input map"
            if f > 1
            else "refined and scored at full resolution"
        ),
        "config": {**{k: v for k, v in asdict(config).items() if k != "fit"}, "fit": full_config_dict(config.fit)},
        **provenance(mi),
        "timings": {"refine_s": res.seconds, "total_s": time.perf_counter() - t0},
    }
    return report, refined_full


def write_refined(target: Path, normals: np.ndarray, report: dict) -> None:
    """normal.png (the refined map, or the input map where refinement declined) and refine_report.json."""
    from scenes.files import write_json
    from scenes.images import write_normal_map

    target.mkdir(parents=True, exist_ok=True)
    write_normal_map(target / "normal.png", normals)
    write_json(target / "refine_report.json", report, indent=1)
