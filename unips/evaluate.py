"""Compare predicted normal maps with ground truth.

    python -m unips.evaluate --pred DIR --gt PATH [--allow-missing]

``--gt`` is an object folder or a dataset directory (any layout `unips.data` reads). Predictions are
looked up as ``DIR/<object>/normal.*`` in the order of `scenes.folder.format.PREDICTION_FILES` (``.exr``
first, then ``.png``), ``<object>`` being the ground-truth folder's name minus a trailing ``.data``
(what `unips.predict` writes). Writes ``DIR/metrics.json``,
``DIR/metrics.csv`` and ``DIR/<object>/error_map.png`` (angular error, colour-mapped, clipped at
90 degrees, background black) and prints a table. Metrics per object: mean and median angular error
(degrees) over the ground-truth mask, the percentage of pixels under 11.25 and 30 degrees, the light
family and the pixel count; means over objects overall and per light family. A ground-truth object
without a prediction is listed as missing and makes the exit status 1 unless ``--allow-missing``.
"""

from __future__ import annotations

import contextlib
import csv
import io
import logging
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scenes.cli.errors import UsageError, one_line, report_error
from scenes.cli.options import REQUIRED, Command
from scenes.cli.outputs import check_not_being_written, check_output_folder, claim_outputs, output_lock
from scenes.files import atomic_write_text, shown_name, write_json
from scenes.folder.format import PREDICTION_FILES, object_name, prediction_file
from scenes.folder.layouts import detect_layout
from scenes.images import check_unit_length, read_normals
from scenes.metrics import angular_error_deg
from unips.data import find_objects, load_ground_truth

log = logging.getLogger(__name__)

ERROR_CLIP_DEG = 90.0
METRICS_JSON, METRICS_CSV, ERROR_MAP = "metrics.json", "metrics.csv", "error_map.png"
"""The files unips.evaluate writes: into --pred, and into each <object>/ folder of it."""
METRICS_KEYS = ("objects", "missing", "failed", "gt")
"""Keys every metrics.json of this command holds (what marks an earlier evaluation's files)."""
CSV_FIELDS = ("object", "light_family", "n_pixels", "mae_deg", "median_deg", "pct_below_11_25", "pct_below_30")


def object_metrics(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> tuple[dict[str, float], np.ndarray]:
    """Metrics of one object and its (H, W) error map in degrees."""
    if not mask.any():
        raise ValueError("mask: is empty, nothing to evaluate")
    err_map = angular_error_deg(pred, gt, mask)
    err = err_map[mask].astype(np.float64)
    return {
        "mae_deg": float(err.mean()),
        "median_deg": float(np.median(err)),
        "pct_below_11_25": float(100.0 * np.mean(err < 11.25)),
        "pct_below_30": float(100.0 * np.mean(err < 30.0)),
        "n_pixels": int(mask.sum()),
    }, err_map


ERROR_MAP_MIN_HEIGHT = 192
"""error_map.png is enlarged by an integer factor (nearest neighbour) to at least this height, so that its
colour bar (degrees) is legible."""


def error_map_image(err_map: np.ndarray, mask: np.ndarray, clip_deg: float = ERROR_CLIP_DEG) -> np.ndarray:
    """BGR image: the colour-mapped (JET) error, 0 -> blue, clip_deg and above -> red, background black,
    enlarged by `error_map_scale`, with a colour bar in degrees on the right."""
    import cv2

    from scenes.report.charts import colorbar

    level = np.round(np.clip(err_map / clip_deg, 0.0, 1.0) * 255.0).astype(np.uint8)
    img = cv2.applyColorMap(level, cv2.COLORMAP_JET)
    img[~mask] = 0
    s = error_map_scale(mask.shape[0])
    img = np.repeat(np.repeat(img, s, axis=0), s, axis=1)
    bar = colorbar(img.shape[0], clip_deg, cv2.COLORMAP_JET, "angle (deg)", ticks=3, fmt="{:.0f}")
    if bar.shape[0] > img.shape[0]:
        img = np.concatenate([img, np.zeros((bar.shape[0] - img.shape[0],) + img.shape[1:], np.uint8)], axis=0)
    return np.concatenate([img, bar], axis=1)


def error_map_scale(height: int) -> int:
    """The integer enlargement of error_map.png for a map `height` pixels high."""
    return max(1, -(-ERROR_MAP_MIN_HEIGHT // max(int(height), 1)))


def write_error_map(path: Path, err_map: np.ndarray, mask: np.ndarray, clip_deg: float = ERROR_CLIP_DEG) -> None:
    """Write `error_map_image` as PNG: the map occupies the top-left (H * s, W * s) pixels, s = error_map_scale(H)."""
    from scenes.images import write_picture

    write_picture(path, error_map_image(err_map, mask, clip_deg))


def evaluate(pred_dir: str | Path, gt: str | Path, write: bool = True, overwrite: bool = False) -> dict[str, Any]:
    """Evaluate every ground-truth object at ``gt`` against ``pred_dir``; returns the metrics dict. With
    `write`, the outputs (metrics.json, metrics.csv, <object>/error_map.png) are checked before any work: the
    folder must be writable and an earlier run's outputs are replaced only with `overwrite`
    (`scenes.cli.outputs.claim_outputs`)."""
    pred_dir = Path(pred_dir)
    if not pred_dir.is_dir():
        state = "is not a folder" if os.path.lexists(pred_dir) else "does not exist"
        raise FileNotFoundError(f"--pred: {str(pred_dir)!r} {state}; expected the folder unips.predict wrote")
    folders = find_objects(gt, arg="--gt")
    single = detect_layout(gt) is not None
    seen: set[str] = set()
    for folder in folders:
        name = object_name(folder)
        if name in seen:
            raise ValueError(f"--gt: two ground-truth folders are named {name!r}")
        seen.add(name)
    earlier: list[Path] = []  # an earlier run's outputs, replaced (--overwrite)
    if write:
        check_output_folder(pred_dir, "--pred")
        map_paths = [pred_dir / name / ERROR_MAP for name in sorted(seen) if (pred_dir / name).is_dir()]
        # an earlier evaluation's files only where its metrics.json says it was one
        earlier = claim_outputs([pred_dir / METRICS_JSON, pred_dir / METRICS_CSV, *map_paths], overwrite, "--pred",
                                "unips.evaluate", marker=pred_dir / METRICS_JSON,
                                signed={pred_dir / METRICS_JSON: METRICS_KEYS})
    summary, maps = _evaluate_all(folders, gt, pred_dir, single)  # every object scored before anything is written
    if not summary["objects"]:  # nothing scored: nothing written (an earlier evaluation stays whole)
        failed, missing = summary["failed"], summary["missing"]
        if not failed:
            raise ValueError(f"--pred: no prediction in {str(pred_dir)!r} for any of the {len(missing)} object(s) of "
                             f"--gt (first, {ascii(missing[0])}: is --pred the right folder, are the names the same "
                             "characters?); nothing was written")
        raise ValueError(f"--gt: none of the {len(failed) + len(missing)} object(s) could be scored against --pred "
                         f"(first, {next(iter(failed))}: {next(iter(failed.values()))}); nothing was written")
    if write:
        # the mark of this run before its first error map (a run killed mid-way leaves maps known as its own)
        write_json(pred_dir / METRICS_JSON, {**summary, "objects": {}, "mean_mae_deg": None, "per_family": {},
                                             "complete": False}, indent=2, sort_keys=True)
        try:
            _write_all(pred_dir, summary, maps, earlier)
        except BaseException:  # a run that ends in an error leaves no mark of a run
            (pred_dir / METRICS_JSON).unlink(missing_ok=True)
            raise
    return summary


def _write_all(pred_dir: Path, summary: dict[str, Any], maps: dict[str, tuple[np.ndarray, np.ndarray]],
               earlier: list[Path]) -> None:
    """The error maps, then metrics.json and metrics.csv. An earlier run's map of an object this run does not
    score (no prediction, no ground truth) is removed; one of an object that failed is kept (the user's to judge)."""
    for name, (err_map, scored) in maps.items():
        write_error_map(pred_dir / name / ERROR_MAP, err_map, scored)
    for path in earlier:
        if path.name == ERROR_MAP and path.parent.name not in summary["objects"] | summary["failed"]:
            path.unlink(missing_ok=True)
    table = io.StringIO(newline="")
    writer = csv.DictWriter(table, fieldnames=CSV_FIELDS)
    writer.writeheader()
    for name, m in summary["objects"].items():
        writer.writerow({"object": name, **{k: m[k] for k in CSV_FIELDS[1:]}})
    write_json(pred_dir / METRICS_JSON, summary, indent=2, sort_keys=True)
    atomic_write_text(pred_dir / METRICS_CSV, table.getvalue())


def _evaluate_all(folders: list[Path], gt: str | Path, pred_dir: Path,
                  single: bool) -> tuple[dict[str, Any], dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Every object scored (one that fails is recorded): the summary, and {name: (error map, scored pixels)}."""
    results: dict[str, dict[str, Any]] = {}
    missing: list[str] = []
    no_gt: list[str] = []
    failed: dict[str, str] = {}
    maps: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for folder in folders:
        name = object_name(folder)
        try:
            _evaluate_one(folder, pred_dir, results, missing, no_gt, maps)
        except (ValueError, OSError) as exc:  # one bad object: recorded, the others go on
            if single:
                raise
            failed[shown_name(name)] = one_line(exc)
            log.debug("%s failed", name, exc_info=True)
    if not results and not missing and not failed:
        raise ValueError(f"--gt: no object at {gt} has ground-truth normals (skipped: {no_gt})")
    per_family: dict[str, dict[str, Any]] = {}
    for name, m in results.items():
        if m["light_family"] is not None:
            per_family.setdefault(m["light_family"], {"objects": []})["objects"].append(name)
    for fam, entry in per_family.items():
        entry["mean_mae_deg"] = float(np.mean([results[n]["mae_deg"] for n in entry["objects"]]))
        entry["n_objects"] = len(entry["objects"])
    summary = {
        "objects": results,
        "mean_mae_deg": float(np.mean([m["mae_deg"] for m in results.values()])) if results else None,
        "per_family": per_family,
        "missing": missing,
        "failed": failed,
        "no_ground_truth": no_gt,
        "gt": str(Path(gt).resolve()),
        "complete": True,
    }
    return summary, maps


def holds_floats(path: Path) -> bool:
    """Whether a normal-map file holds float vectors (EXR, NPY, MAT, a float TIFF), which must be of unit length; an
    8 or 16-bit image holds encoded unit vectors, (n + 1) / 2, decoded by its reader."""
    if path.suffix.lower() not in (".tif", ".tiff"):
        return path.suffix.lower() in (".exr", ".npy", ".mat")
    import tifffile

    try:  # the header only: the pixels were read (and checked) by read_normals
        with tifffile.TiffFile(path) as tif:
            return tif.pages[0].dtype is None or tif.pages[0].dtype.kind == "f"
    except (tifffile.TiffFileError, OSError, ValueError, IndexError):
        return True  # not known: the check costs an encoded map nothing (its vectors decode to unit length)


def _evaluate_one(folder: Path, pred_dir: Path, results: dict, missing: list, no_gt: list, maps: dict) -> None:
    truth = load_ground_truth(folder, arg="--gt")
    if truth.normals is None:
        no_gt.append(truth.name)
        log.warning("%s has no ground-truth normals; skipped", folder)
        return
    pred_path = prediction_file(pred_dir / truth.name)
    if pred_path is None:
        missing.append(truth.name)
        return
    pred = read_normals(pred_path, "--pred")
    if pred.shape != truth.normals.shape:
        raise ValueError(f"--pred: {pred_path} has shape {'x'.join(map(str, pred.shape))}, the ground truth "
                         f"{folder} has {'x'.join(map(str, truth.normals.shape))}")
    scored = truth.mask & np.any(truth.normals != 0, axis=-1)  # a mask pixel without a true normal scores nothing
    floats = holds_floats(pred_path)
    if floats:  # float vectors must be directions: over the whole map (an encoded map's background may be black)
        check_unit_length(pred, f"--pred: normal map {pred_path}")
    check_unit_length(pred[scored], f"--pred: normal map {pred_path} (inside the ground truth's mask)", not floats)
    if not scored.any():
        no_gt.append(truth.name)
        log.warning("%s has no ground-truth normal inside its mask; skipped", folder)
        return
    if not np.any(pred[scored] != 0):  # a blank map is no estimate, not one 90 deg off everywhere
        raise ValueError(f"--pred: normal map {pred_path} holds no normal where the ground truth is known (every "
                         "vector there is 0); expected the object's predicted normals")
    metrics, err_map = object_metrics(pred, truth.normals, scored)
    results[truth.name] = {**metrics, "light_family": truth.light_family, "prediction": str(pred_path)}
    maps[truth.name] = (err_map, scored)



def format_table(summary: dict[str, Any]) -> str:
    lines = [f"{'object':<24} {'family':<12} {'pixels':>8} {'MAE':>7} {'median':>7} {'<11.25%':>8} {'<30%':>7}"]
    for name, m in summary["objects"].items():
        lines.append(f"{name:<24} {str(m['light_family'] or '-'):<12} {m['n_pixels']:>8d} {m['mae_deg']:>7.2f} "
                     f"{m['median_deg']:>7.2f} {m['pct_below_11_25']:>8.1f} {m['pct_below_30']:>7.1f}")
    if summary["mean_mae_deg"] is not None:
        lines.append(f"{'mean':<24} {'':<12} {'':>8} {summary['mean_mae_deg']:>7.2f}")
    for fam, entry in sorted(summary["per_family"].items()):
        lines.append(f"{'mean ' + fam:<24} {'':<12} {entry['n_objects']:>8d} {entry['mean_mae_deg']:>7.2f}")
    for name in summary["missing"]:
        lines.append(f"{name:<24} MISSING prediction")
    for name, why in summary.get("failed", {}).items():
        lines.append(f"{name:<24} FAILED: {why}")
    return "\n".join(lines)


@dataclass
class EvaluateOptions:
    """The command line of unips.evaluate."""

    pred: Path = REQUIRED
    """Directory written by unips.predict (<pred>/<object>/normal.*); metrics.json, metrics.csv and the error
    maps are written into it."""
    gt: Path = REQUIRED
    """Object folder or dataset directory with the ground truth."""
    allow_missing: bool = False
    """Exit 0 even when some ground-truth objects have no prediction."""
    overwrite: bool = False
    """Replace the metrics and error maps of an earlier evaluation in --pred (nothing else is touched)."""


COMMAND = Command(EvaluateOptions, prog="python -m unips.evaluate", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        args = COMMAND.parse(argv)
        with contextlib.ExitStack() as held:
            if Path(args.pred).is_dir():  # one writer in --pred (a missing one is evaluate's one-line error)
                held.enter_context(output_lock(args.pred, "--pred", inputs={"--gt": args.gt}))
            check_not_being_written(args.gt, "--gt")  # a dataset wildgen.make is still rendering
            summary = evaluate(args.pred, args.gt, overwrite=args.overwrite)
    except (UsageError, ValueError, FileNotFoundError, OSError) as exc:
        return report_error(exc)
    print(format_table(summary))
    print(f"wrote {args.pred / METRICS_JSON}, {METRICS_CSV} and {len(summary['objects'])} error map(s) "
          f"{args.pred}/<object>/{ERROR_MAP}")
    status = 0
    known = {*summary["objects"], *summary["missing"], *summary["failed"], *summary["no_ground_truth"]}
    unscored = sorted(p.name for p in Path(args.pred).iterdir() if p.is_dir() and p.name not in known
                      and prediction_file(p) is not None)  # what would be scored, were it an object of --gt
    if unscored:  # a prediction of an object --gt does not have: never dropped without a word
        print(f"warning: --pred: {len(unscored)} prediction(s) of no object of --gt, not scored: "
              f"{', '.join(unscored[:10])}{' ...' if len(unscored) > 10 else ''}", file=sys.stderr)
    if summary["failed"]:
        for name, why in summary["failed"].items():
            print(f"failed {name}: {why}", file=sys.stderr)
        print(f"error: {len(summary['failed'])} object(s) could not be evaluated: {', '.join(summary['failed'])} "
              "(the others are in metrics.json)", file=sys.stderr)
        status = 1
    if summary["missing"] and not args.allow_missing:
        print(f"error: --pred: no prediction in {str(args.pred)!r} for {len(summary['missing'])} object(s): "
              f"{', '.join(summary['missing'])} (expected <object>/normal.png or another of "
              f"{', '.join(PREDICTION_FILES)} for each object of --gt; use --allow-missing to accept)", file=sys.stderr)
        status = 1
    return status


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    stopped = "interrupted: what evaluate wrote into --pred is whole (each file at once); run it again with --overwrite"
    sys.exit(run_supervised("unips.evaluate", main, stopped))
