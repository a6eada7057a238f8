"""Scores, report.json, figure and summary table of the known-scene re-render check (`validate.rerender`)."""
from __future__ import annotations

import csv
import io
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from scenes.files import atomic_write_text, to_plain
from scenes.metrics import mean_angular_error
from validate.known.rerender_passes import RenderPasses, RerenderConfig
from validate.observations import Capture
from validate.residuals import mean_or_none, psnr, rel_l1, relative_residual_map

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


def score_images(
    passes: RenderPasses, inputs: np.ndarray, mask: np.ndarray, desc: Any, seeds: list[int]
) -> list[dict[str, Any]]:
    """Per-image scores of every pass against the input images."""
    per_image = []
    for i, image in enumerate(desc.images):
        r, g, f, p = passes.renders, passes.gt, passes.floor, passes.reproduce
        per_image.append({
            "index": i,
            "seed": int(image.seed),
            "rerender_seed": seeds[i],
            "exposure": float(image.exposure),
            "rel_l1": to_plain(rel_l1(r[i], inputs[i], mask)),
            "psnr": to_plain(psnr(r[i], inputs[i], mask)),
            "gt_rel_l1": to_plain(rel_l1(g[i], inputs[i], mask)) if g is not None else None,
            "gt_psnr": to_plain(psnr(g[i], inputs[i], mask)) if g is not None else None,
            "noise_floor_rel_l1": to_plain(rel_l1(f[i], inputs[i], mask)) if f is not None else None,
            "reproduce_rel_l1": to_plain(rel_l1(p[i], inputs[i], mask)) if p is not None else None,
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


def build_report(data: Capture, pred: np.ndarray, valid: np.ndarray, source: str, passes: RenderPasses,
                 per_image: list[dict[str, Any]], threshold: float | None, threshold_source: str | None,
                 frac: float | None, config: RerenderConfig, spp: int, variant: str) -> dict[str, Any]:
    """The report.json of one object (total_s is filled in by the caller)."""
    desc, mask = data.desc, data.mask

    def avg(key: str) -> float | None:
        return mean_or_none([e[key] for e in per_image])

    t_orig_med = float(np.median(passes.original_s)) if passes.original_s else None
    t_re_med = float(np.median(passes.rerender_s))
    from scenes.geometry import lights_in_camera_frame

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
        "missing_scoring": ("a pixel without an estimate scores max(|render - input|, |input|) "
                            "(a black render or worse)"),
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
        "lights": lights_in_camera_frame(desc, exposures),
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


def _figure_rows(k: int, n: int) -> list[int]:
    return sorted(set(np.linspace(0, k - 1, min(k, n)).round().astype(int).tolist()))


def write_figure(path: Path, report: dict[str, Any], inputs: np.ndarray, passes: RenderPasses, mask: np.ndarray,
                 res_map: np.ndarray, gt_map: np.ndarray | None, pred: np.ndarray, rows: int) -> None:
    """figure.png of one object: inputs, re-renders, residual maps, the prediction."""
    from scenes.folder.format import prediction_label
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
        title=f"{report['object']}, {prediction_label(report['prediction'])} (known scene): "
        f"rel_l1 {report['rel_l1']:.4f}, "
        f"coverage {report['coverage']:.1%}"
        + (f" (GT normals {report['gt_rel_l1']:.4f})" if report["gt_rel_l1"] is not None else "")
        + (f", MAE {report['mae_deg']:.2f} deg" if report["mae_deg"] is not None else ""),
    )


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
    table = io.StringIO(newline="")
    writer = csv.DictWriter(table, fieldnames=list(SUMMARY_COLUMNS))
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    atomic_write_text(path, table.getvalue())  # a kill or a full disk never leaves half a table


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
