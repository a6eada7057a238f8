"""`python -m validate.refine`: refine a normal map by differentiable rendering (the library:
`validate.fitted.refinement`).

Usage:
    python -m validate.refine --data OBJ --normals PRED/OBJ/normal.png --out DIR
writes DIR/<object>/normal.png (16-bit, (n + 1) / 2, background 32768: the layout unips.evaluate reads)
and DIR/<object>/refine_report.json.
"""

from __future__ import annotations

import logging
import sys
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.limits import check_threads
from scenes.cli.needs import Needs
from scenes.cli.options import REQUIRED, Command, arg, check_fields, option
from scenes.cli.outputs import check_output_folder, claim_outputs, output_lock
from scenes.cli.progress import progress_bar
from scenes.cli.supervise import run_supervised
from scenes.files import read_json
from scenes.folder.format import EXPECTED_ERROR_FILES, stated_error
from validate.fitted.fit import FIT_NEEDS
from validate.fitted.refinement import REFINE_OUTPUTS, RefineConfig, refine_object


@dataclass
class RefineOptions:
    """The command line of validate.refine: the refinement (`RefineConfig`, with its scene fit) and where it
    reads and writes."""

    data: str = REQUIRED
    """Object folder: ours (with or without scene.json), UniPS .data, or DiLiGenT *PNG."""
    normals: str = REQUIRED
    """Starting normal map file (.png/.exr/.npy/.tif) or a folder with <object>/normal.*."""
    out: str = "refined"
    """Output folder: <out>/<object>/normal.png and refine_report.json."""
    refine: RefineConfig = option(default_factory=RefineConfig)
    """The refinement."""
    variant: Annotated[str | None, arg(help_behavior_hint="(default: cuda_ad_rgb if usable, else llvm_ad_rgb)")] = None
    """Mitsuba variant (one with automatic differentiation)."""
    threads: Annotated[int | None, arg(help_behavior_hint="(default: one per core)")] = option(None, minimum=1)
    """Dr.Jit threads; with 1 the maps and pictures are byte-identical run to run, the report's figures too (its
    timings aside); with more, gradients are summed in a varying order."""
    overwrite: bool = False
    """Replace the refined map and report of an earlier run in --out (nothing else is touched)."""
    verbose: Annotated[bool, arg(aliases=("-v",))] = False
    """Debug logging."""

    def validate(self) -> "RefineOptions":
        check_fields(self)
        self.refine.validate()
        check_threads(self.threads)
        check_output_folder(self.out)
        return self


COMMAND = Command(
    RefineOptions,
    prog="python -m validate.refine",
    description="Refine a normal map by fitting light, reflectance and normals to the images through Mitsuba.",
    needs=(Needs("rotation_search", lambda c, _: c.refine.lights == "fitted" and c.refine.rounds > 1,
                 "with --lights fitted and --rounds 2 or more (it turns the fitted lights from the second round)"),
           Needs("rotation_search", lambda c, _: c.refine.fit.light_model != "environment",
                 "with --light-model directional, point or auto (an environment light has no tilt it could search)"),
           Needs("update_lights", lambda c, _: c.refine.lights == "fitted",
                 "with --lights fitted (calibrated lights are held fixed)"),
           Needs("rotation_steps", lambda c, _: c.refine.rotation_search, "with --rotation-search"),
           Needs("patience", lambda c, _: c.refine.holdout_fraction > 0, "with --holdout above 0 (the held-out "
                 "residual it waits on)"), *FIT_NEEDS),
)


def input_error(normals: str, name: str) -> tuple[Path, dict] | None:
    """(the prediction folder, its predict.json `expected_error_deg`) when --normals is a prediction of unips.predict
    that states one, else None."""

    from scenes.folder.format import PREDICTION_INFO, find_prediction

    try:
        folder = find_prediction(normals, name).parent
        info = read_json(folder / PREDICTION_INFO)
    except (OSError, ValueError, AttributeError):
        return None
    if not isinstance(info, dict):  # not a record predict wrote: it states nothing
        return None
    stated = stated_error(info.get("expected_error_deg"))
    # the prediction's own files only: a link (to anything of the machine) is never copied beside the refined map
    if not stated or not all((folder / f).is_file() and not (folder / f).is_symlink() for f in EXPECTED_ERROR_FILES):
        return None
    import numpy as np

    from scenes.images import read_normals

    try:  # another map's error (another size) is not this map's: stated nowhere, rather than beside it
        if np.load(folder / EXPECTED_ERROR_FILES[0], allow_pickle=False).shape[:2] != read_normals(
                find_prediction(normals, name)).shape[:2]:
            return None
    except (OSError, ValueError):
        return None
    return folder, stated


def carry_error(stated: tuple[Path, dict], target: Path, report: dict) -> dict:
    """Copy the input map's expected error beside the refined map and say so in refine_report.json: the refinement's
    own error is not stated (no error model was fitted for refined maps); an accepted refinement explains the images
    better, so the input map's figure is the one to expect at worst."""
    import shutil

    from scenes.files import write_json

    folder, figure = stated
    for f in EXPECTED_ERROR_FILES:
        shutil.copyfile(folder / f, target / f)
    report = {**report, "expected_error_deg": {**figure, "map": "the input map, before refinement (the refined map's "
                                                           "own error is not stated)",
                                               "files": list(EXPECTED_ERROR_FILES)}}
    write_json(target / REFINE_OUTPUTS[1], report, indent=1)
    return report


def main(argv: list[str] | None = None) -> int:
    """The command; --out is held for the length of the run (`scenes.cli.outputs.output_lock`)."""
    with ExitStack() as held:
        return _main(argv, held)


def _main(argv: list[str] | None, held: ExitStack) -> int:
    try:
        args = COMMAND.parse(argv)
        logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                            format="%(levelname)s %(name)s: %(message)s")
        config = args.validate().refine
        held.enter_context(output_lock(args.out, inputs={"--data": args.data, "--normals": args.normals}))
        if not Path(args.normals).exists():
            raise FileNotFoundError(f"--normals: {args.normals!r} does not exist")
        if not Path(args.data).is_dir():
            raise FileNotFoundError(f"--data: {args.data!r} is not a folder")
        if config.lights == "calibrated":  # before any work: the fit would decline first and never say why
            from scenes.folder.layouts import read_folder

            if read_folder(args.data, images=False, arg="--data").lights.directions is None:
                raise ValueError(f"--lights calibrated: {args.data!r} has no calibrated directional lights (DiLiGenT "
                                 "light files or scene.json camera_lights with one distant light per image); expected "
                                 "them, or --lights fitted")
        from scenes.folder.format import object_name

        name = object_name(args.data)
        report = Path(args.out) / name / "refine_report.json"  # what marks the folder's files as refine's own
        claim_outputs([Path(args.out) / name / f for f in REFINE_OUTPUTS], args.overwrite, owner="validate.refine",
                      marker=report, signed={report: ("mode", "accepted", "why")})
        print(f"refining the normals of {name} (lights, reflectance and normals fitted to the images) ...", flush=True)
        from scenes.renderer.variant import choose_variant, set_jit_threads

        choose_variant(args.variant, jit=True)  # refine_object refuses a variant without automatic differentiation
        set_jit_threads(args.threads)
        stated = input_error(args.normals, name)
        earlier = claim_outputs([Path(args.out) / name / f for f in EXPECTED_ERROR_FILES], args.overwrite,
                                owner="validate.refine", marker=report)  # an earlier run's stated error, if any
        stated_before = read_json(report).get("expected_error_deg") if earlier else None  # (a report: claimed)
        listed = stated_before.get("files", []) if isinstance(stated_before, dict) else []
        if foreign := [p for p in earlier if p.name not in listed]:  # beside refine's files, yet not its own
            raise UsageError(f"--out: {str(foreign[0])!r} was not written by validate.refine (its refine_report.json "
                             "lists no such file); it is never replaced: move it away or use another --out")
        with progress_bar("step") as progress:
            r = refine_object(args.data, args.normals, config, args.out, progress, overwrite=args.overwrite)
        if stated:
            r = carry_error(stated, Path(args.out) / name, r)
        for path in [] if stated else earlier:  # not this map's input's error: never left beside it
            path.unlink()
    except (*INPUT_ERRORS, OSError) as exc:
        return report_error(exc)
    b, a = r["before"], r["after"]
    mae = f"  mae {b['mae_deg']:.2f} -> {a['mae_deg']:.2f} deg" if b["mae_deg"] is not None else ""
    if "rel_l1" in b:
        print(
            f"{r['object']}: rel_l1 {b['rel_l1']:.4f} -> {a['rel_l1']:.4f}{mae}  "
            f"({r['note']}, {r['timings']['total_s']:.0f} s)"
        )
    print(("accepted" if r["accepted"] else "NOT ACCEPTED") + f": {r['why']}" + (mae if "rel_l1" not in b else ""))
    if r.get("rotation_search"):
        rs = r["rotation_search"]
        print(f"rotation search: tilted by {rs['tilt_deg']:.1f} deg; {rs['note']}")
    if "expected_error_deg" in r:
        e = r["expected_error_deg"]
        print(f"expected error of the input map: about {e['mean']:.0f} deg (80 %: {e['interval_80'][0]:.0f}-"
              f"{e['interval_80'][1]:.0f} deg), copied beside the refined map ({', '.join(EXPECTED_ERROR_FILES)})")
    print(f"normals in {args.out}/{r['object']}/normal.png, report in {args.out}/{r['object']}/refine_report.json")
    return 0


if __name__ == "__main__":  # Ctrl-C kills the work whole (scenes.cli.supervise)
    sys.exit(run_supervised("validate.refine", main))
