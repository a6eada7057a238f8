"""Re-render check of predicted normals (library and CLI `validate-rerender`).

For each object folder, the scene of every input image is rebuilt from scene.json and rendered again with
the shading normal of every camera-visible surface point replaced by the predicted normal of the pixel it
projects to (`validate.normal_bsdf`); hidden points keep their own normals, so shadows and
inter-reflections stay physical. The re-render uses each image's recorded seed (common random numbers,
`--seed-mode same`) and spp, gets the recorded exposure, and is compared in linear space with the input.

Reference levels written next to the score, all over the object mask:
- `gt_rel_l1`: the same re-render with the ground-truth normals of normal.tif (its pixel-grid
  discretisation is the floor a perfect prediction reaches);
- `noise_floor_rel_l1`: the original scene (no wrapper) rendered with an independent seed: pure noise;
- `reproduce_rel_l1`: the wrapper switched off, recorded seed: should be ~0 (checks that scene.json and
  this Mitsuba reproduce the stored images).

Usage:
    python -m validate.rerender --data OBJ.data --normals PRED/OBJ/normal.png --out DIR
    python -m validate.rerender --data DATASET --normals PRED --out DIR   # every *.data folder
"""
from __future__ import annotations

import argparse
import csv
import gc
import hashlib
import json
import logging
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from scenes.cli import UsageError, check_output_folder, progress_bar, report_error
from scenes.config import check_fields, config_parser, option
from scenes.config import config_from_args as parse_config
from scenes.objfolder import find_prediction, list_object_folders, mean_angular_error, object_name
from scenes.variant import require_jit_variant
from validate.fit import FitConfig
from validate.io import ObjectData, check_normals, load_object, read_prediction
from validate.metrics import expose, finite_or_none, mean_or_none, psnr, rel_l1, relative_residual_map
from validate.normal_bsdf import (
    MODE_PASSTHROUGH,
    MODE_PREDICTED,
    NormalSwap,
    VisibilityConfig,
    depth_map,
    wrapper_for,
)
from validate.projection import CameraProjection

log = logging.getLogger(__name__)

SEED_MODES = ("same", "independent")
MIN_COVERAGE = 0.9
"""Default smallest share of the mask a prediction must cover (--min-coverage): a sparser map is refused."""

SUMMARY_COLUMNS = (
    "object",
    "images",
    "mae_deg",
    "rel_l1",
    "coverage",
    "missing_pixels",
    "gt_rel_l1",
    "noise_floor_rel_l1",
    "reproduce_rel_l1",
    "psnr",
    "frac_above_threshold",
    "rerender_s",
    "original_render_s",
    "error",
)

Progress = Callable[[int, int, str], None]
"""progress(done, total, label): called after each render."""


@dataclass
class RerenderConfig:
    """Options of the re-render check."""

    spp: int | None = option(None, minimum=1, default_text="the recorded spp")
    """Samples per pixel; None = the recorded render.spp (required for common random numbers)."""
    seed_mode: str = option("same", choices=SEED_MODES)
    """'same': each image's recorded seed (noise largely cancels); 'independent': fresh seeds."""
    floors: bool = True
    """Also render the independent-seed noise floor and the reproduction check (2 more renders per image)."""
    visibility: VisibilityConfig = option(default_factory=VisibilityConfig, expose=("supersample",))
    """How camera visibility of surface points is decided (on the command line: the depth-map rays per pixel
    side; the tolerances are fixed)."""
    threshold: float | None = option(None, above=0, default_text="99th percentile of the noise-floor residual map")
    """Per-pixel relative residual counted in frac_above_threshold; None = 99th percentile of the
    noise-floor residual map (needs floors)."""
    figure_rows: int = option(4, minimum=1)
    """Images shown in figure.png."""
    save_renders: bool = False
    """Also write the re-rendered images as R000.png.. (16-bit, exposure applied)."""
    allow_missing: bool = False
    """Accept exactly-zero normals inside the mask as "no estimate" (counted in missing_pixels, coverage, and
    as 90 deg in mae_deg). They can never improve a score: such a point keeps the surface's own normal for
    light transport, but each of its pixels is scored as at least as wrong as a black render (relative residual
    >= 1, see `penalise_missing`). Otherwise they are an error."""
    min_coverage: float = option(MIN_COVERAGE, minimum=0, maximum=1)
    """Smallest share of the mask pixels that must hold an estimate (with allow_missing); a map below it is refused."""

    def validate(self) -> "RerenderConfig":
        check_fields(self)
        self.visibility.validate()
        return self


def independent_seed(seed: int) -> int:
    """A seed unrelated to `seed` (hash), deterministic, in Mitsuba's uint32 range."""
    return int.from_bytes(hashlib.sha256(f"rerender-independent:{seed}".encode()).digest()[:4], "little")


def _render_all(built: Any, indices: range, spp: int, seeds: list[int], exposures: list[float], tick: Callable[[str], None], label: str) -> tuple[np.ndarray, list[float]]:
    from scenes.render import render_image

    out, times = [], []
    for i in indices:
        t0 = time.perf_counter()
        radiance = render_image(built, i, spp=spp, seed=seeds[i])
        times.append(time.perf_counter() - t0)
        out.append(expose(radiance, exposures[i]))
        tick(f"{label} {i:03d}")
    return np.stack(out), times


def _figure_rows(k: int, n: int) -> list[int]:
    return sorted(set(np.linspace(0, k - 1, min(k, n)).round().astype(int).tolist()))


def check_inputs(
    folder: str | Path, normals: np.ndarray | str | Path, allow_missing: bool = False,
    min_coverage: float = MIN_COVERAGE,
) -> tuple[ObjectData, np.ndarray, np.ndarray, str]:
    """Load an object folder and its prediction and check them against each other (no rendering).

    Returns (object data, normals (renormalised where valid, 0 elsewhere), valid mask, where they came from).
    A map covering less than `min_coverage` of the mask is a ValueError."""
    data = load_object(folder)
    normals, source = read_prediction(normals, data.name)
    what = f"--normals ({source})" if source != "array" else "--normals"
    pred, valid = check_normals(normals, data.mask, what, allow_missing)
    cov = coverage(valid, data.mask)
    if cov < min_coverage:
        raise ValueError(f"{what}: covers {cov:.1%} of the object's {int(data.mask.sum())} mask pixels "
                         f"({int(data.mask.sum() - valid.sum())} without an estimate), below --min-coverage {min_coverage:g}")
    return data, pred, valid, source


def coverage(valid: np.ndarray, mask: np.ndarray) -> float:
    """Share of the mask pixels that hold an estimate."""
    n = int(mask.sum())
    return float(valid[mask].sum() / n) if n else 0.0


def penalise_missing(renders: np.ndarray, inputs: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """The renders as scored: at the `missing` pixels (no estimate) every channel whose residual is below the
    input's own value is set to 0 (a black render), so a missing pixel's residual is max(|render - input|,
    |input|): never below 1 relative to the input, never better than the ground truth or any estimate within
    100 % of it. Elsewhere the renders are unchanged."""
    if not missing.any():
        return renders
    out = renders.copy()
    r, i = out[:, missing], inputs[:, missing]
    out[:, missing] = np.where(np.abs(r - i) >= np.abs(i), r, 0.0)
    return out


@dataclass
class RenderPasses:
    """The images of one re-render check (each (K, H, W, 3), exposure applied) and their timings."""

    renders: np.ndarray
    """With the predicted normals (the score)."""
    rerender_s: list[float]
    """Per-image time of those renders."""
    gt: np.ndarray | None = None
    """With the ground-truth normals (when the folder has them)."""
    floor: np.ndarray | None = None
    """The original scene with independent seeds (noise floor)."""
    original_s: list[float] = field(default_factory=list)
    """Per-image time of the original scene's renders."""
    reproduce: np.ndarray | None = None
    """The wrapper switched off with the recorded seeds (should reproduce the inputs)."""
    build_s: float = 0.0
    depth_map_s: float = 0.0


def render_passes(data: ObjectData, pred: np.ndarray, valid: np.ndarray, config: RerenderConfig, spp: int,
                  seeds: list[int], fresh: list[int], tick: Callable[[str], None]) -> RenderPasses:
    """Render every pass of the check for one object (Mitsuba work only; no scoring)."""
    from scenes.mitsuba_build import build_scene

    desc, k = data.desc, len(data.desc.images)
    exposures = [float(im.exposure) for im in desc.images]
    recorded = [int(im.seed) for im in desc.images]
    reproduce = config.floors and spp == desc.render.spp

    # 1. The original scene with independent seeds: noise floor and the original render time. It is
    #    released before the wrapped scene is built (live Python BSDFs are traced into every kernel).
    floor_imgs, t_orig = None, []
    if config.floors:
        built = build_scene(desc, data.folder)
        floor_imgs, t_orig = _render_all(built, range(k), spp, fresh, exposures, tick, "noise floor")
        del built
        gc.collect()

    # 2. The wrapped scene: one build, normals and mode swapped through mi.traverse.
    t0 = time.perf_counter()
    camera = CameraProjection.from_camera(desc.camera)
    built = build_scene(desc, data.folder, bsdf_wrapper=wrapper_for(camera, config.visibility))
    swap = NormalSwap.attach(built.params, camera, config.visibility)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    built.park_lights()  # area-light rectangles out of the way: the depth map holds the object only
    swap.set_depth(depth_map(built.scene, camera, config.visibility.supersample))
    built.apply_image(0)
    t_depth = time.perf_counter() - t0

    repro_imgs = None
    if reproduce:
        swap.set_mode(MODE_PASSTHROUGH)
        repro_imgs, _ = _render_all(built, range(k), spp, recorded, exposures, tick, "reproduce")
    swap.set_normals(pred, valid)
    swap.set_mode(MODE_PREDICTED)
    renders, t_re = _render_all(built, range(k), spp, seeds, exposures, tick, "re-render")
    gt_imgs = None
    if data.normal_gt is not None:
        swap.set_normals(data.normal_gt, data.mask)
        gt_imgs, _ = _render_all(built, range(k), spp, seeds, exposures, tick, "GT normals")
    del swap, built
    gc.collect()
    return RenderPasses(renders=renders, rerender_s=t_re, gt=gt_imgs, floor=floor_imgs, original_s=t_orig,
                        reproduce=repro_imgs, build_s=t_build, depth_map_s=t_depth)


def score_images(passes: RenderPasses, inputs: np.ndarray, mask: np.ndarray, desc: Any, seeds: list[int]) -> list[dict[str, Any]]:
    """Per-image scores of every pass against the input images."""
    per_image = []
    for i, image in enumerate(desc.images):
        r, g, f, p = passes.renders, passes.gt, passes.floor, passes.reproduce
        per_image.append({
            "index": i,
            "seed": int(image.seed),
            "rerender_seed": seeds[i],
            "exposure": float(image.exposure),
            "rel_l1": rel_l1(r[i], inputs[i], mask),
            "psnr": finite_or_none(psnr(r[i], inputs[i], mask)),
            "gt_rel_l1": rel_l1(g[i], inputs[i], mask) if g is not None else None,
            "gt_psnr": finite_or_none(psnr(g[i], inputs[i], mask)) if g is not None else None,
            "noise_floor_rel_l1": rel_l1(f[i], inputs[i], mask) if f is not None else None,
            "reproduce_rel_l1": rel_l1(p[i], inputs[i], mask) if p is not None else None,
            "rerender_s": passes.rerender_s[i],
            "original_render_s": passes.original_s[i] if passes.original_s else None,
        })
    return per_image


def score_maps(passes: RenderPasses, inputs: np.ndarray, mask: np.ndarray,
               threshold: float | None) -> tuple[np.ndarray, np.ndarray | None, float | None, str | None, float | None]:
    """(residual map, GT-normals residual map, threshold, its source, share of mask pixels above it)."""
    res_map = relative_residual_map(passes.renders, inputs, mask)
    gt_map = relative_residual_map(passes.gt, inputs, mask) if passes.gt is not None else None
    source = "given"
    if threshold is None and passes.floor is not None:
        threshold = float(np.percentile(relative_residual_map(passes.floor, inputs, mask)[mask], 99))
        source = "99th percentile of the noise-floor residual map"
    frac = float(np.mean(res_map[mask] > threshold)) if threshold is not None else None
    return res_map, gt_map, threshold, source if threshold is not None else None, frac


def build_report(data: ObjectData, pred: np.ndarray, valid: np.ndarray, source: str, passes: RenderPasses,
                 per_image: list[dict[str, Any]], threshold: float | None, threshold_source: str | None,
                 frac: float | None, config: RerenderConfig, spp: int, variant: str) -> dict[str, Any]:
    """The report.json of one object (total_s is filled in by the caller)."""
    desc, mask = data.desc, data.mask

    def avg(key: str) -> float | None:
        return mean_or_none([e[key] for e in per_image])

    t_orig_med = float(np.median(passes.original_s)) if passes.original_s else None
    t_re_med = float(np.median(passes.rerender_s))
    from validate.lights import known_scene_lights

    exposures = [float(im.exposure) for im in desc.images]
    return {
        "mode": "known_scene",
        "object": data.name,
        "folder": str(data.folder),
        "prediction": source,
        "images_count": len(desc.images),
        "mask_pixels": int(mask.sum()),
        "missing_pixels": int(mask.sum() - valid.sum()),
        "coverage": coverage(valid, mask),
        "min_coverage": config.min_coverage,
        "missing_scoring": "a pixel without an estimate scores max(|render - input|, |input|) (a black render or worse)",
        "rel_l1": avg("rel_l1"),
        "psnr": avg("psnr"),
        "gt_rel_l1": avg("gt_rel_l1"),
        "gt_psnr": avg("gt_psnr"),
        "noise_floor_rel_l1": avg("noise_floor_rel_l1"),
        "reproduce_rel_l1": avg("reproduce_rel_l1"),
        "mae_deg": mean_angular_error(pred, data.normal_gt, mask) if data.normal_gt is not None else None,
        "frac_above_threshold": frac,
        "threshold": threshold,
        "threshold_source": threshold_source,
        "images": per_image,
        "lights": known_scene_lights(desc, exposures),
        "timings": {
            "original_render_s": t_orig_med,
            "rerender_s": t_re_med,
            "rerender_over_original": (t_re_med / t_orig_med) if t_orig_med else None,
            "build_s": passes.build_s,
            "depth_map_s": passes.depth_map_s,
            "total_s": None,  # filled by rerender_object
            "note": "per-image medians (the first render of a scene includes kernel compilation)",
        },
        "config": {
            "spp": spp,
            "recorded_spp": desc.render.spp,
            "seed_mode": config.seed_mode,
            "common_random_numbers": config.seed_mode == "same" and spp == desc.render.spp,
            "variant": variant,
            "visibility": asdict(config.visibility),
        },
    }


def write_figure(path: Path, report: dict[str, Any], inputs: np.ndarray, passes: RenderPasses, mask: np.ndarray,
                 res_map: np.ndarray, gt_map: np.ndarray | None, pred: np.ndarray, rows: int) -> None:
    """figure.png of one object: inputs, re-renders, residual maps, the prediction."""
    from scenes.objfolder import prediction_label
    from validate.figures import rerender_figure

    rerender_figure(
        path,
        inputs,
        passes.renders,
        mask,
        _figure_rows(len(inputs), rows),
        res_map,
        gt_map,
        pred,
        title=f"{report['object']}, {prediction_label(report['prediction'])} (known scene): rel_l1 {report['rel_l1']:.4f}, "
        f"coverage {report['coverage']:.1%}"
        + (f" (GT normals {report['gt_rel_l1']:.4f})" if report["gt_rel_l1"] is not None else "")
        + (f", MAE {report['mae_deg']:.2f} deg" if report["mae_deg"] is not None else ""),
    )


def rerender_object(
    folder: str | Path,
    normals: np.ndarray | str | Path,
    config: RerenderConfig | None = None,
    out_dir: str | Path | None = None,
    progress: Progress | None = None,
) -> dict:
    """Re-render one object folder with predicted normals; return the report (and write it to
    `out_dir/<object>/` with figure.png when out_dir is given).

    normals: camera-frame normal map (H, W, 3), or a normal-map file, or a folder holding one.
    Raises FileNotFoundError / ValueError for bad inputs (missing files, wrong sizes, bad normals).
    """
    config = (config or RerenderConfig()).validate()
    mi = require_jit_variant()
    t_start = time.perf_counter()
    data, pred, valid, source = check_inputs(folder, normals, config.allow_missing, config.min_coverage)
    desc, mask = data.desc, data.mask
    k = len(desc.images)
    spp = int(config.spp or desc.render.spp)
    recorded = [int(im.seed) for im in desc.images]
    fresh = [independent_seed(s) for s in recorded]
    seeds = recorded if config.seed_mode == "same" else fresh
    reproduce = config.floors and spp == desc.render.spp
    total = k * (1 + (data.normal_gt is not None) + config.floors + reproduce)
    done = 0

    def tick(label: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total, f"{data.name}: {label}")

    passes = render_passes(data, pred, valid, config, spp, seeds, fresh, tick)
    passes.renders = penalise_missing(passes.renders, data.images, mask & ~valid)
    per_image = score_images(passes, data.images, mask, desc, seeds)
    res_map, gt_map, threshold, threshold_source, frac = score_maps(passes, data.images, mask, config.threshold)
    report = build_report(data, pred, valid, source, passes, per_image, threshold, threshold_source, frac, config,
                          spp, mi.variant())
    if out_dir is not None:
        target = Path(out_dir) / data.name
        target.mkdir(parents=True, exist_ok=True)
        write_figure(target / "figure.png", report, data.images, passes, mask, res_map, gt_map, pred,
                     config.figure_rows)
        if config.save_renders:
            from scenes.objfolder import write_png16

            for i in range(k):
                write_png16(target / f"R{i:03d}.png", passes.renders[i])
        report["timings"]["total_s"] = time.perf_counter() - t_start
        (target / "report.json").write_text(json.dumps(report, indent=1, allow_nan=False))
    else:
        report["timings"]["total_s"] = time.perf_counter() - t_start
    return report


def rerender_dataset(
    data_dir: str | Path,
    pred_dir: str | Path,
    config: RerenderConfig | None = None,
    out_dir: str | Path | None = None,
    progress: Progress | None = None,
    failed: dict[str, str] | None = None,
) -> list[dict]:
    """Run `rerender_object` on every `*.data` folder of `data_dir` with `pred_dir/<object>/normal.*`;
    write `out_dir/summary.csv`. Every prediction is located and checked before anything is rendered.

    An object whose prediction is missing or unusable, or whose check fails, is recorded in `failed`
    (object name -> reason) and the others go on; without a `failed` dict the first failure raises."""
    config = (config or RerenderConfig()).validate()
    folders = list_object_folders(data_dir)
    errors: dict[str, str] = {}
    preds = {}
    for f in folders:  # every input is checked before the first (slow) render
        try:
            preds[f] = find_prediction(Path(pred_dir) / object_name(f))
            check_inputs(f, preds[f], config.allow_missing, config.min_coverage)
        except (ValueError, FileNotFoundError) as exc:
            if failed is None:
                raise
            preds.pop(f, None)
            errors[object_name(f)] = " ".join(str(exc).split())
    reports = []
    for f in folders:
        if f not in preds:
            continue
        try:
            reports.append(rerender_object(f, preds[f], config, out_dir, progress))
        except (ValueError, FileNotFoundError, RuntimeError) as exc:  # RuntimeError: Mitsuba on this scene
            if failed is None:
                raise
            errors[object_name(f)] = " ".join(str(exc).split())
    if failed is not None:
        failed.update(errors)
    if out_dir is not None:
        write_summary(Path(out_dir) / "summary.csv", reports, errors)
    return reports


def summary_row(report: dict) -> dict:
    return {
        "object": report["object"],
        "images": report["images_count"],
        "mae_deg": report["mae_deg"],
        "rel_l1": report["rel_l1"],
        "coverage": report.get("coverage"),
        "missing_pixels": report.get("missing_pixels"),
        "gt_rel_l1": report["gt_rel_l1"],
        "noise_floor_rel_l1": report["noise_floor_rel_l1"],
        "reproduce_rel_l1": report["reproduce_rel_l1"],
        "psnr": report["psnr"],
        "frac_above_threshold": report["frac_above_threshold"],
        "rerender_s": report["timings"]["rerender_s"],
        "original_render_s": report["timings"]["original_render_s"],
        "error": None,
    }


def failed_row(name: str, error: str) -> dict:
    """A summary row of an object whose check failed: no scores, the reason in `error`."""
    return {**{c: None for c in SUMMARY_COLUMNS}, "object": name, "error": error}


def write_summary(path: str | Path, reports: list[dict], failed: dict[str, str] | None = None) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [summary_row(r) for r in reports] + [failed_row(n, e) for n, e in (failed or {}).items()]
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(SUMMARY_COLUMNS))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: ("" if v is None else v) for k, v in row.items()})


def format_table(reports: list[dict], failed: dict[str, str] | None = None) -> str:
    """Plain-text table of the summary rows (None shown as '-'); failed objects are listed below it."""
    rows = [summary_row(r) for r in reports]
    cols = [c for c in SUMMARY_COLUMNS if c != "error"]

    def fmt(v: Any) -> str:
        if v is None:
            return "-"
        if isinstance(v, float):
            return f"{v:.4g}"
        return str(v)

    cells = [[fmt(r[c]) for c in cols] for r in rows]
    widths = [max(len(c), *(len(row[j]) for row in cells)) if cells else len(c) for j, c in enumerate(cols)]
    lines = ["  ".join(c.ljust(wd) for c, wd in zip(cols, widths))]
    lines += ["  ".join(v.ljust(wd) for v, wd in zip(row, widths)) for row in cells]
    lines += [f"{name}  FAILED: {why}" for name, why in (failed or {}).items()]
    return "\n".join(lines)


FITTED_GROUP = "fitted mode (folders without scene.json, or --fit): light and reflectance fitted to the images"


@dataclass
class RerenderOptions:
    """The command line of validate.rerender: the known-scene check (`RerenderConfig`) and the fitted mode
    (`validate.fit.FitConfig`)."""

    data: str = option("", required=True)
    """Object folder (with scene.json) or dataset folder of *.data folders."""
    normals: str = option("", required=True)
    """Object: normal map file (.png/.exr/.npy/.tif) or its folder; dataset: folder with <object>/normal.*."""
    out: str = "rerender"
    """Output folder: <out>/<object>/report.json, figure.png; summary.csv."""
    variant: str | None = option(None, default_text="cuda_ad_rgb, then llvm_ad_rgb")
    """Mitsuba variant."""
    check: RerenderConfig = option(default_factory=RerenderConfig)
    """The known-scene check."""
    fit: bool = option(False, group=FITTED_GROUP)
    """Use the fitted mode even when the folder has a scene.json."""
    fitted: FitConfig = option(default_factory=FitConfig, group=FITTED_GROUP)
    """The scene fit of the fitted mode."""
    threads: int | None = option(None, minimum=1, default_text="one per core")
    """Dr.Jit threads of the fitted mode; with 1 the fit is byte-identical run to run (with more, gradients are
    summed in a varying order)."""
    overwrite: bool = False
    """Replace an existing <out>/<object>/report.json of the fitted mode."""
    verbose: bool = option(False, short="-v")
    """Debug logging."""

    def validate(self) -> "RerenderOptions":
        check_fields(self)
        self.check.validate()
        self.fitted.validate()
        check_output_folder(self.out)
        return self


def build_parser() -> argparse.ArgumentParser:
    return config_parser(RerenderOptions, prog="python -m validate.rerender",
                         description="Re-render the known scenes of an object (or dataset) with predicted normals and "
                                     "compare with the inputs.")


def _main_fitted(args: RerenderOptions) -> int:
    """Fitted mode (validate.fit): one object folder of any layout."""
    from scenes.variant import choose_variant, set_jit_threads
    from validate.fit import rerender_fitted

    config = args.fitted
    if not Path(args.normals).exists():
        raise FileNotFoundError(f"--normals: {args.normals!r} does not exist")
    choose_variant(args.variant)  # the fit itself refuses a variant without automatic differentiation
    set_jit_threads(args.threads)
    with progress_bar("step") as progress:
        r = rerender_fitted(args.data, args.normals, config, args.out, progress, overwrite=args.overwrite)
    cal = r.get("calibrated_light_error_deg")
    print(f"{r['object']}: rel_l1 {r['rel_l1']:.4f}  floor {r['floor_rel_l1']:.4f}  noise {r['noise_rel_l1'] or float('nan'):.4f}"
          + (f"  mae {r['mae_deg']:.2f} deg" if r["mae_deg"] is not None else "")
          + (f"  light error vs calibration {cal['mean']:.2f} deg" if cal else "")
          + f"  ({r['note']}, {r['timings']['total_s']:.0f} s)")
    print(f"report in {args.out}/{r['object']}/report.json")
    return 0


def main(argv: list[str] | None = None) -> int:
    """One object: a failure is one line `error: ...`, exit 2. A dataset: a failed object is recorded (summary.csv
    row with its error), the others go on, the failures are listed at the end and the exit status is 1.
    A folder without scene.json (DiLiGenT, official UniPS layout) or `--fit`: the fitted mode (validate.fit)."""
    failed: dict[str, str] = {}
    try:
        args = parse_config(RerenderOptions, build_parser().parse_args(argv)).validate()
        logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                            format="%(levelname)s %(name)s: %(message)s")
        from scenes.layouts import detect_layout, has_scene

        if args.fit or (Path(args.data).is_dir() and detect_layout(args.data) in ("diligent", "unips")):
            return _main_fitted(args)
        config = args.check
        data = Path(args.data)
        if not data.is_dir():
            raise FileNotFoundError(f"--data: {str(data)!r} is not a folder")
        single = has_scene(data)
        if not single:
            list_object_folders(data)  # fails early with a clear message
        if not Path(args.normals).exists():
            raise FileNotFoundError(f"--normals: {args.normals!r} does not exist")

        from scenes.variant import choose_variant

        choose_variant(args.variant)
        mi = require_jit_variant()
        mi.set_log_level(mi.LogLevel.Error)  # e.g. multijitter's per-render "sample count rounded up"

        with progress_bar("render") as progress:
            if single:
                check_inputs(data, args.normals, config.allow_missing, config.min_coverage)
                reports = [rerender_object(data, args.normals, config, args.out, progress)]
                write_summary(Path(args.out) / "summary.csv", reports)
            else:
                reports = rerender_dataset(data, args.normals, config, args.out, progress, failed=failed)
    except (UsageError, ValueError, FileNotFoundError, FileExistsError, OSError) as exc:
        return report_error(exc)
    print(format_table(reports, failed))
    print(f"reports in {args.out}/<object>/report.json, table in {args.out}/summary.csv")
    if failed:
        for name, why in failed.items():
            print(f"failed {name}: {why}", file=sys.stderr)
        print(f"error: {len(failed)} of {len(failed) + len(reports)} object(s) failed: {', '.join(failed)} "
              "(the others were checked)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
