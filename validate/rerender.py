"""Re-render check of predicted normals (library and CLI `validate-rerender`).

For each object folder, the scene of every input image is rebuilt from scene.json and rendered again with
the shading normal of every camera-visible surface point replaced by the predicted normal of the pixel it
projects to (`validate.known.normal_bsdf`); hidden points keep their own normals, so shadows and
inter-reflections stay physical. The re-render uses each image's recorded seed (common random numbers,
`--seed-mode same`) and spp, gets the recorded exposure, and is compared in linear space with the input.

Reference levels written next to the score, all over the object mask:
- `gt_rel_l1`: the same re-render with the ground-truth normals of normal.tif (its pixel-grid
  discretisation is the floor a perfect prediction reaches);
- `noise_floor_rel_l1`: the original scene (no wrapper) rendered with an independent seed: pure noise;
- `reproduce_rel_l1`: the wrapper switched off, recorded seed: should be ~0 (checks that scene.json and
  this Mitsuba reproduce the stored images).

The renders are `validate.known.rerender_passes` (with the options, `RerenderConfig`), the scores, report,
figure and summary table `validate.known.rerender_report`; this module checks the inputs, runs one object or a
dataset, and is the CLI (which also dispatches the fitted mode, `validate.fitted.fit_report`).

Usage:
    python -m validate.rerender --data OBJ.data --normals PRED/OBJ/normal.png --out DIR
    python -m validate.rerender --data DATASET --normals PRED --out DIR   # every *.data folder
"""
from __future__ import annotations

import logging
import sys
import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np

from scenes.cli.errors import UsageError, report_error
from scenes.cli.limits import check_threads
from scenes.cli.needs import Needs
from scenes.cli.options import REQUIRED, Command, arg, check_fields, option
from scenes.cli.outputs import (
    check_listed,
    check_output_folder,
    claim_outputs,
    holds_keys,
    listed_names,
    output_lock,
)
from scenes.cli.progress import progress_bar
from scenes.cli.supervise import run_supervised
from scenes.files import shown_name, write_json
from scenes.folder.format import SCENE_FILE, find_prediction, list_object_folders, object_name
from scenes.renderer.variant import require_jit_variant
from validate.fitted.fit import FIT_NEEDS
from validate.fitted.fit_scene import FitConfig
from validate.io import check_normals, read_prediction
from validate.known.rerender_passes import MIN_COVERAGE, Progress, RerenderConfig, independent_seed, render_passes
from validate.known.rerender_report import (
    build_report,
    coverage,
    format_table,
    penalise_missing,
    score_images,
    score_maps,
    write_figure,
    write_summary,
)
from validate.observations import Capture, load_known_scene

log = logging.getLogger(__name__)


REPORT, FIGURE, SUMMARY = "report.json", "figure.png", "summary.csv"
"""What the check writes: <out>/<object>/report.json and figure.png (and R000.png.. with --save-renders), and
<out>/summary.csv (known-scene mode)."""


def claim_check_outputs(out: str | Path, names: list[str], overwrite: bool, summary: bool = True,
                        renders: bool = False) -> None:
    """The outputs of the check of objects `names` in `out`, claimed before any work
    (`scenes.cli.outputs.claim_outputs`: an earlier run's are replaced only with --overwrite, other files never)."""
    out = Path(out)
    for n in names:  # an object folder is the check's only where its report.json is one (`REPORT_KEYS`)
        report = out / n / REPORT
        renders_there = sorted((out / n).glob("R[0-9][0-9][0-9].png")) if renders else []
        claim_outputs([report, out / n / FIGURE, *renders_there], overwrite, owner="validate.rerender",
                      marker=report, signed={report: REPORT_KEYS})
        check_listed(renders_there, report, "renders", "validate.rerender")  # a render it never saved: the user's
    if summary and (out / SUMMARY).exists() and overwrite and not any(
            holds_keys(p, REPORT_KEYS) for p in out.glob(f"*/{REPORT}")):
        raise UsageError(f"--out: {str(out / SUMMARY)!r} exists, but no object folder beside it holds a report of "
                         "validate.rerender: it is not an earlier check's and is never replaced; move it away or use "
                         "another --out")
    claim_outputs([out / SUMMARY] if summary else [], overwrite, owner="validate.rerender")


def earlier_renders(report: Path) -> set[str]:
    """The render files (R000.png ...) an earlier check listed in its report (`renders`); none when unreadable. A
    name read from a file is untrusted: only plain render names (`R` and three digits) are taken."""
    import re

    return {r for r in listed_names(report, "renders") if re.fullmatch(r"R\d{3}\.png", r)}


REPORT_KEYS = ("mode", "object", "folder", "prediction")
"""What every report.json of the check holds (known-scene and fitted): the mark of an earlier check's folder."""


def check_inputs(
    folder: str | Path, normals: np.ndarray | str | Path, allow_missing: bool = False,
    min_coverage: float = MIN_COVERAGE, images: bool = True,
) -> tuple[Capture, np.ndarray, np.ndarray, str]:
    """Load an object folder (its images too unless `images` is False) and its prediction and check them against
    each other (no rendering).

    Returns (object data, normals (renormalised where valid, 0 elsewhere), valid mask, where they came from).
    A map covering less than `min_coverage` of the mask is a ValueError."""
    data = load_known_scene(folder, images=images)
    normals, source = read_prediction(normals, data.name)
    what = f"--normals ({source})" if source != "array" else "--normals"
    pred, valid = check_normals(normals, data.mask, what, allow_missing)
    cov = coverage(valid, data.mask)
    if cov < min_coverage:
        raise ValueError(
            f"{what}: covers {cov:.1%} of the object's {int(data.mask.sum())} mask pixels "
            f"({int(data.mask.sum() - valid.sum())} without an estimate), below --min-coverage {min_coverage:g}"
        )
    return data, pred, valid, source


_SAID_SPP: set = set()
"""(object folder, spp) already warned about (`rerender_object`)."""


def rerender_object(
    folder: str | Path,
    normals: np.ndarray | str | Path,
    config: RerenderConfig | None = None,
    out_dir: str | Path | None = None,
    progress: Progress | None = None,
    inputs: tuple[Capture, np.ndarray, np.ndarray, str] | None = None,
) -> dict:
    """Re-render one object folder with predicted normals; return the report (and write it to
    `out_dir/<object>/` with figure.png when out_dir is given).

    normals: camera-frame normal map (H, W, 3), or a normal-map file, or a folder holding one.
    inputs: what `check_inputs` returned for them, when the caller checked them already (read once).
    Raises FileNotFoundError / ValueError for bad inputs (missing files, wrong sizes, bad normals).
    """
    config = (config or RerenderConfig()).validate()
    mi = require_jit_variant()
    t_start = time.perf_counter()
    if inputs is None or inputs[0].images is None:
        inputs = check_inputs(folder, normals, config.allow_missing, config.min_coverage)
    data, pred, valid, source = inputs
    desc, mask = data.desc, data.mask
    k = len(desc.images)
    spp = int(config.spp or desc.render.spp)
    recorded = [int(im.seed) for im in desc.images]
    fresh = [independent_seed(s) for s in recorded]
    seeds = recorded if config.seed_mode == "same" else fresh
    if config.seed_mode == "same" and spp != desc.render.spp and (folder, spp) not in _SAID_SPP:
        _SAID_SPP.add((folder, spp))  # the recorded seeds cancel the noise only at the recorded spp: never silently
        print(f"warning: --spp {spp}: {Path(folder).name} was rendered at {desc.render.spp} spp; with another count "
              "the recorded seeds no longer cancel the Monte Carlo noise (report.json: common_random_numbers false); "
              "leave --spp out for that, or say --seed-mode independent", file=sys.stderr)
    reproduce = config.floors and spp == desc.render.spp
    total = k * (1 + (data.normal_gt is not None) + config.floors + reproduce)
    done = 0

    def tick(label: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total, f"{data.name}: {label}")

    passes = render_passes(data, pred, valid, config, spp, seeds, fresh, tick)
    if not all(np.isfinite(r).all() for r in passes.renders):  # no score means anything then
        raise ValueError(f"--data: {str(data.folder / SCENE_FILE)!r} renders to infinite or NaN values (its light "
                         "strengths or exposures overflow single precision); expected the scene a render wrote")
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
        for name in earlier_renders(target / REPORT):  # an earlier check's renders (claimed): not this one's
            (target / name).unlink(missing_ok=True)
        report["renders"] = [f"R{i:03d}.png" for i in range(k)] if config.save_renders else []
        if config.save_renders:
            from scenes.images import write_png16

            for i in range(k):
                write_png16(target / report["renders"][i], passes.renders[i])
        report["timings"]["total_s"] = time.perf_counter() - t_start
        write_json(target / REPORT, report, indent=1)
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
    for f in folders:  # every input is checked before the first (slow) render; the images are read at its turn
        try:
            preds[f] = find_prediction(Path(pred_dir) / object_name(f))
            check_inputs(f, preds[f], config.allow_missing, config.min_coverage, images=False)
        except (ValueError, FileNotFoundError) as exc:
            if failed is None:
                raise
            preds.pop(f, None)
            errors[shown_name(object_name(f))] = shown_name(" ".join(str(exc).split()))
    reports = []
    for f in folders:
        if f not in preds:
            continue
        try:
            reports.append(rerender_object(f, preds[f], config, out_dir, progress))
        except (ValueError, FileNotFoundError, RuntimeError) as exc:  # RuntimeError: Mitsuba on this scene
            if failed is None:
                raise
            errors[shown_name(object_name(f))] = shown_name(" ".join(str(exc).split()))
    if failed is not None:
        failed.update(errors)
    if out_dir is not None:
        write_summary(Path(out_dir) / "summary.csv", reports, errors)
    return reports


FITTED_GROUP = "fitted mode (folders without scene.json, or --fit): light and reflectance fitted to the images"


@dataclass
class RerenderOptions:
    """The command line of validate.rerender: the known-scene check (`RerenderConfig`) and the fitted mode
    (`validate.fitted.fit_scene.FitConfig`)."""

    data: str = REQUIRED
    """Object folder (with scene.json) or dataset folder of *.data folders."""
    normals: str = REQUIRED
    """Object: normal map file (.png/.exr/.npy/.tif) or its folder; dataset: folder with <object>/normal.*."""
    out: str = "rerender"
    """Output folder: <out>/<object>/report.json, figure.png; summary.csv."""
    variant: Annotated[str | None, arg(help_behavior_hint="(default: cuda_ad_rgb, then llvm_ad_rgb)")] = None
    """Mitsuba variant."""
    check: RerenderConfig = option(default_factory=RerenderConfig)
    """The known-scene check."""
    fit: bool = False
    """Use the fitted mode even when the folder has a scene.json."""
    fitted: FitConfig = field(default_factory=FitConfig)
    """The scene fit of the fitted mode."""
    threads: Annotated[int | None, arg(help_behavior_hint="(default: one per core)")] = option(None, minimum=1)
    """Dr.Jit threads of the fitted mode; with 1 the fit is byte-identical run to run (the report's timings
    aside); with more, gradients are summed in a varying order."""
    overwrite: bool = False
    """Replace the reports, figures and summary.csv of an earlier run in --out (nothing else is touched)."""
    verbose: Annotated[bool, arg(aliases=("-v",))] = False
    """Debug logging."""

    def validate(self) -> "RerenderOptions":
        check_fields(self)
        self.check.validate()
        self.fitted.validate()
        check_threads(self.threads)
        check_output_folder(self.out)
        return self


COMMAND = Command(
    RerenderOptions,
    prog="python -m validate.rerender",
    description="Re-render the known scenes of an object (or dataset) with predicted normals and "
    "compare with the inputs.",
    needs=(Needs("min_coverage", lambda c, _: c.check.allow_missing, "with --allow-missing (without it every mask "
                 "pixel needs an estimate)"), *FIT_NEEDS),
)


def _main_fitted(args: RerenderOptions) -> int:
    """Fitted mode (validate.fitted.fit): one object folder of any layout."""
    from scenes.renderer.variant import choose_variant, set_jit_threads
    from validate.fitted.fit_report import rerender_fitted

    config = args.fitted
    if not Path(args.normals).exists():
        raise FileNotFoundError(f"--normals: {args.normals!r} does not exist")
    choose_variant(args.variant, jit=True)  # before anything is claimed or said: a wrong --variant is refused first
    claim_check_outputs(args.out, [object_name(args.data)], args.overwrite, summary=False)
    print(f"checking {object_name(args.data)} in the fitted mode (light and reflectance fitted to the images) ...",
          flush=True)
    set_jit_threads(args.threads)
    with progress_bar("step") as progress:
        r = rerender_fitted(args.data, args.normals, config, args.out, progress, overwrite=args.overwrite)
    cal = r.get("calibrated_light_error_deg")
    print(
        f"{r['object']}: rel_l1 {r['rel_l1']:.4f}  floor {r['floor_rel_l1']:.4f}  "
        f"noise {r['noise_rel_l1'] or float('nan'):.4f}"
        + (f"  mae {r['mae_deg']:.2f} deg {r['mae_resolution']}" if r["mae_deg"] is not None else "")
        + (f"  light error vs calibration {cal['mean']:.2f} deg" if cal else "")
        + f"  ({r['note']}, {r['timings']['total_s']:.0f} s)"
    )
    judged = r["judged_rel_l1"]
    print(
        ("TRUSTED" if r["trusted"] else "NOT TRUSTED (the check abstains)")
        + f": {r['why']}"
        + (
            f"; judged rel_l1 {judged:.4f} (judged floor {r['judged_floor_rel_l1'] or float('nan'):.4f})"
            if judged is not None
            else ""
        )
    )
    if r["resolution"] is not None:
        print(f"resolution {r['resolution']:.4f}: judged scores of this capture closer than that are not told apart by "
              "the images (a refined map can score that far below the true surface)")
    if r["ambiguity"]["tested"]:
        print(f"bas-relief ambiguity: {r['ambiguity']['note']}")
    print(
        f"report in {args.out}/{r['object']}/report.json, where the check judges in "
        f"{args.out}/{r['object']}/explained.png"
    )
    return 0


def _refuse_other_mode(argv: list[str] | None, fitted: bool, data: str) -> None:
    """A flag of the mode not run would be silently ignored: refused in one line, with the way to the other mode."""
    other = COMMAND.given_flags(argv, RerenderConfig if fitted else FitConfig)
    if not fitted and "threads" in COMMAND.given(argv):  # the fitted mode's Dr.Jit threads
        other.append("--threads")
    if not other:
        return
    if fitted:
        raise UsageError(f"{other[0]}: an option of the known-scene check, but --data {data!r} is checked in the "
                         "fitted mode (no scene.json, or --fit): drop it")
    raise UsageError(f"{other[0]}: an option of the fitted mode, but --data {data!r} gets the known-scene check "
                     "(its scene.json): drop it, or add --fit to fit one object folder without its scene")


def _refuse_no_prediction(normals: str, folders: list[Path]) -> None:
    """One line, before any work, when --normals holds a normal map for none of the dataset's objects (a dataset
    given as --normals, say): not one "failed" line per object."""
    for f in folders:
        try:
            find_prediction(normals, object_name(f))
            return
        except FileNotFoundError:
            pass
    dataset = " (it is a dataset: <object>.data folders, not predictions)" if any(Path(normals).glob("*.data")) else ""
    raise UsageError(f"--normals: {normals!r} holds no normal map of any of the {len(folders)} object(s) of --data"
                     f"{dataset}; expected <object>/normal.* as unips.predict writes it")


def main(argv: list[str] | None = None) -> int:
    """One object: a failure is one line `error: ...`, exit 2. A dataset: a failed object is recorded (summary.csv
    row with its error), the others go on, the failures are listed at the end and the exit status is 1.
    A folder without scene.json (DiLiGenT, official UniPS layout) or `--fit`: the fitted mode
    (validate.fitted.fit_report). --out is held for the length of the run (`scenes.cli.outputs.output_lock`)."""
    with ExitStack() as held:
        return _main(argv, held)


def _main(argv: list[str] | None, held: ExitStack) -> int:
    failed: dict[str, str] = {}
    try:
        args = COMMAND.parse(argv).validate()
        held.enter_context(output_lock(args.out, inputs={"--data": args.data, "--normals": args.normals}))
        logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                            format="%(levelname)s %(name)s: %(message)s")
        from scenes.folder.layouts import detect_layout, has_scene

        if not Path(args.data).is_dir():
            raise FileNotFoundError(f"--data: {args.data!r} is not a folder")
        has_scene(args.data)  # a scene.json that is not a file is refused first, named
        fitted = args.fit or detect_layout(args.data) in ("diligent", "unips")
        _refuse_other_mode(argv, fitted, args.data)
        if fitted:
            return _main_fitted(args)
        config = args.check
        data = Path(args.data)
        single = has_scene(data)
        folders = [data] if single else list_object_folders(data)  # fails early with a clear message
        if not Path(args.normals).exists():
            raise FileNotFoundError(f"--normals: {args.normals!r} does not exist")
        if not single and not Path(args.normals).is_dir():  # one map cannot be every object's
            raise UsageError(f"--normals: {args.normals!r} is a file, but --data holds {len(folders)} object(s); "
                             "expected a folder with <object>/normal.* (or --data one object folder)")
        if not single:
            _refuse_no_prediction(args.normals, folders)
        from scenes.renderer.variant import choose_variant

        choose_variant(args.variant, jit=True)  # before anything is claimed: a wrong --variant is refused first
        claim_check_outputs(args.out, [object_name(f) for f in folders], args.overwrite, renders=config.save_renders)
        mi = require_jit_variant()
        mi.set_log_level(mi.LogLevel.Error)  # e.g. multijitter's per-render "sample count rounded up"

        print(
            f"re-rendering {len(folders)} object(s) with the normals of {args.normals} into {args.out} ...", flush=True
        )
        with progress_bar("render") as progress:
            if single:
                inputs = check_inputs(data, args.normals, config.allow_missing, config.min_coverage)
                reports = [rerender_object(data, args.normals, config, args.out, progress, inputs)]
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


if __name__ == "__main__":  # Ctrl-C kills the work whole (scenes.cli.supervise)
    sys.exit(run_supervised("validate.rerender", main))
