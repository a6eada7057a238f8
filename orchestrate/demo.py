"""`python -m orchestrate.demo`: the whole story on embedded defaults, in a few minutes on a CPU.

    python -m orchestrate.demo [--out demo_out] [--objects 4] [--images 8] [--res 64] [--spp 32] [--seed 0]
                               [--checkpoint CKPT] [--baseline {sh-uncalibrated,least-squares}]

1. `wildgen.make` renders a small dataset (light families near_area, hdri, mixed, directional cycled);
2. `wildgen.preview` writes contact sheets;
3. `unips.predict` estimates normals with the shipped model and with a classical baseline;
4. `unips.evaluate` compares both with the ground truth (error maps);
5. `validate.rerender` re-renders every object with each prediction and compares with the inputs;
6. a table per object (angular error and re-render residual of both methods) and the figure paths.

Every step is the real CLI run as a subprocess, so this is also an end-to-end check of the commands a
user types; every step's arguments are checked before the first runs, and a failed step is reported as one
line. Re-running with the same --out resumes a dataset a demo interrupted while rendering left; once a later step
has written (previews, predictions), an earlier demo's output is replaced only with --overwrite.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

from orchestrate.steps import StepFailed, check_step, run_step
from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.options import Command, arg, check_fields, option
from scenes.cli.outputs import check_output_folder, claim_outputs
from scenes.files import atomic_write_text, read_json
from scenes.report.tables import markdown_table

FAMILIES = "near_area,hdri,mixed,directional"


def _reports(folder: Path) -> dict[str, dict]:
    """validate.rerender's reports by object name (the folder name minus .data, as unips.evaluate keys them)."""
    reports = (read_json(p) for p in sorted(folder.glob("*/report.json")))
    return {rep["object"]: rep for rep in reports}


def _rel_cell(report: dict) -> str:
    """The re-render residual, with the prediction's coverage of the mask when it is not complete."""
    rel, cov = report.get("rel_l1"), report.get("coverage")
    if rel is None:
        return "-"
    return f"{rel:.3f}" + (f" ({cov:.0%} covered)" if cov is not None and cov < 1 else "")


def summary_table(out: Path, methods: list[str]) -> str:
    """Per-object markdown table: MAE and re-render residual of each method, plus the GT-normals floor."""
    metrics = {m: read_json(out / "pred" / m / "metrics.json") for m in methods}
    reports = {m: _reports(out / "rerender" / m) for m in methods}
    names = sorted({n for m in methods for n in metrics[m]["objects"]})
    head = (
        ["object", "family"]
        + [f"{m} MAE (deg)" for m in methods]
        + [f"{m} re-render rel. L1" for m in methods]
        + ["GT normals rel. L1"]
    )
    rows = []

    def cell(v, fmt):
        return "-" if v is None else format(v, fmt)

    for n in names:
        objs = {m: metrics[m]["objects"].get(n) for m in methods}
        fam = next((o["light_family"] for o in objs.values() if o), "?")
        maes = [cell(objs[m]["mae_deg"] if objs[m] else None, ".1f") for m in methods]
        rels = [_rel_cell(reports[m].get(n, {})) for m in methods]
        gt = next((reports[m][n].get("gt_rel_l1") for m in methods if n in reports[m]), None)
        rows.append([n, fam, *maes, *rels, cell(gt, ".3f")])
    means = [cell(metrics[m]["mean_mae_deg"], ".1f") for m in methods]
    rel_means = []
    for m in methods:
        vals = [r["rel_l1"] for r in reports[m].values() if r.get("rel_l1") is not None]
        rel_means.append(cell(sum(vals) / len(vals) if vals else None, ".3f"))
    rows.append(["**mean**", "", *means, *rel_means, ""])
    return "\n".join([markdown_table(head, rows), "", *SUMMARY_COLUMNS])


SUMMARY_COLUMNS = (
    "Columns:",
    "- **object**, **family**: the rendered object and the kind of lighting of its images (light family).",
    "- **<method> MAE (deg)**: mean angle between the method's normals and the ground truth over the object's "
    "pixels (unips.evaluate); lower is better.",
    "- **<method> re-render rel. L1**: the physical check (validate.rerender): the scene re-rendered with the "
    "method's normals, mean |re-render - input| / mean input over the object; lower is better. \"(90% covered)\" "
    "means the method left 10 % of the pixels without an estimate, scored as a black render.",
    "- **GT normals rel. L1**: the same with the ground-truth normals: what a perfect map scores here (render "
    "noise and the shading normal's limits), the floor to compare the methods with.",
)
"""The explanation printed under the demo's table (summary.md)."""


@dataclass
class DemoOptions:
    """The command line of orchestrate.demo."""

    out: Path = Path("demo_out")
    """Output folder: data/, pred/, rerender/ and summary.md."""
    objects: int = option(4, minimum=1)
    """Objects to render."""
    images: int = option(8, minimum=4)
    """Images per object (at least 4: the spherical-harmonics baseline's ambient and three lighting terms)."""
    res: int = option(64, minimum=16, maximum=8192)
    """Square resolution."""
    spp: int = option(32, minimum=1)
    """Samples per pixel."""
    seed: int = option(0, minimum=0)
    """Dataset seed."""
    checkpoint: Annotated[
        Path | None, arg(help_behavior_hint="(default: the shipped weights of unips.models.DEFAULT_MODEL)")
    ] = None
    """Model file."""
    baseline: Literal["sh-uncalibrated", "least-squares"] = "sh-uncalibrated"
    """Classical baseline to compare with (least-squares needs directional lights only)."""
    overwrite: bool = False
    """Replace the output of an earlier demo in --out: every step replaces its own files (the dataset is rendered
    again); files the demo did not write are never touched. Without it, a dataset left by a demo interrupted while
    rendering is resumed, and anything a later step wrote is refused (previews, predictions, checks)."""

    def validate(self) -> "DemoOptions":
        """The flags and --out: an earlier demo's output is replaced only with --overwrite
        (`scenes.cli.outputs.claim_outputs`); the steps' own arguments: `check_steps`."""
        check_fields(self)
        if self.checkpoint is not None and self.checkpoint.is_dir():  # the published layout needs predict's --model
            raise UsageError(f"--checkpoint: {str(self.checkpoint)!r} is a folder; the demo takes a model file "
                             "(.safetensors or .pt): run published weights with unips.predict --model")
        directional = FAMILIES.split(",").index("directional")
        if self.baseline == "least-squares" and self.objects <= directional:  # object i is lit by family i mod 4
            raise UsageError(f"--baseline least-squares: needs directional lights, and with --objects {self.objects} "
                             f"no object gets them (the families cycle {FAMILIES}): --objects {directional + 1} or "
                             "more, or --baseline sh-uncalibrated")
        check_output_folder(self.out)
        claim_outputs([self.out / "summary.md"], self.overwrite, owner="orchestrate.demo")
        claim_outputs([self.out / "pred", self.out / "rerender", self.out / "data" / "preview"], self.overwrite,
                      owner="orchestrate.demo", folders=True)
        return self


def make_argv(args: DemoOptions) -> list[str]:
    """The wildgen.make command line (after `python -m wildgen.make`) of the demo's dataset."""
    return ["--lights", FAMILIES, "--objects", str(args.objects), "--images", str(args.images), "--res", str(args.res),
            "--spp", str(args.spp), "--seed", str(args.seed), "--out", str(args.out / "data"), *_again(args)]


def predict_argv(args: DemoOptions, method: str) -> list[str]:
    """The unips.predict command line of one method."""
    argv = ["--method", method, "--input", str(args.out / "data"), "--out", str(args.out / "pred" / method)]
    if method == "model" and args.checkpoint is not None:
        argv += ["--checkpoint", str(args.checkpoint)]
    return argv + _again(args)


def rerender_argv(args: DemoOptions, method: str) -> list[str]:
    """The validate.rerender command line of one method. --allow-missing: a baseline may leave pixels without an
    estimate (zero normals); the check counts them, reports the coverage and scores them as no better than a
    black render."""
    return ["--data", str(args.out / "data"), "--normals", str(args.out / "pred" / method), "--out",
            str(args.out / "rerender" / method), "--allow-missing", *_again(args)]


def _again(args: DemoOptions) -> list[str]:
    return ["--overwrite"] if args.overwrite else []


def check_steps(args: DemoOptions) -> None:
    """Every step's arguments before the first runs (`orchestrate.steps.check_step`): the dataset's flags and
    memory, the model file loaded, the other steps' flags."""
    check_step("wildgen.make", make_argv(args))
    check_step("wildgen.preview", [str(args.out / "data"), *_again(args)])
    for m in ("model", args.baseline):
        check_step("unips.predict", predict_argv(args, m))
        check_step(
            "unips.evaluate", ["--pred", str(args.out / "pred" / m), "--gt", str(args.out / "data"), *_again(args)]
        )
        check_step("validate.rerender", rerender_argv(args, m))


COMMAND = Command(DemoOptions, prog="python -m orchestrate.demo", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    """A failed step is one line naming the step and its own error (`orchestrate.steps`), exit status its own."""
    try:
        args = COMMAND.parse(argv).validate()
        from scenes.cli.outputs import output_lock

        with output_lock(args.out):  # one demo per folder (its steps hold their own subfolders too)
            check_steps(args)  # under the hold: the steps' folders lie inside it
            return demo(args)
    except StepFailed as exc:
        return report_error(exc, code=exc.code)
    except (*INPUT_ERRORS, OSError) as exc:
        return report_error(exc)


def demo(args: DemoOptions) -> int:
    """The steps of the demo (see the module doc), after the options and steps were checked."""
    py = [sys.executable, "-m"]
    out: Path = args.out
    data = out / "data"
    print(f"demo in {out}: {args.objects} objects rendered, predicted by the model and {args.baseline}, evaluated "
          "and re-rendered", flush=True)
    run_step(py + ["wildgen.make", *make_argv(args)])
    run_step(py + ["wildgen.preview", str(data), *_again(args)])
    methods = ["model", args.baseline]
    for m in methods:
        pred = out / "pred" / m
        complete = run_step(py + ["unips.predict", *predict_argv(args, m)], partial_ok=True)
        if not complete and not any(pred.glob("*/predict.json")):  # nothing to evaluate or re-render
            flag = "--checkpoint" if m == "model" else f"--baseline {m}"
            raise UsageError(f"{flag}: predicted none of the {args.objects} object(s) (why is above); expected a "
                             "method that runs on these renders: raise --res or --images, or choose another --baseline")
        run_step(py + ["unips.evaluate", "--pred", str(pred), "--gt", str(data), *_again(args)]
                 + ([] if complete else ["--allow-missing"]), partial_ok=True)
        run_step(py + ["validate.rerender", *rerender_argv(args, m)], partial_ok=True)
    if any(not (out / "pred" / m / "metrics.json").is_file() for m in methods):
        raise UsageError("orchestrate.demo: no metrics.json was written; see the errors above")
    table = summary_table(out, methods)
    atomic_write_text(out / "summary.md", table + "\n")
    print()
    print(table)
    print()
    print(f"previews:        {data / 'preview' / 'overview.png'} (and one PNG per object)")
    for m in methods:
        print(f"{m + ':':<16} normals {out / 'pred' / m}/<object>/normal.png, error maps .../error_map.png, "
              f"re-render figures {out / 'rerender' / m}/<object>/figure.png")
    print(f"table:           {out / 'summary.md'}")
    return 0


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    sys.exit(run_supervised("orchestrate.demo", main))
