"""`orchestrate.capture` on the real DiLiGenT objects turned into what a user has (docs/capture.md, "How well it
works"): the final map's and the model's map's mean angular error, which map was kept and why.

    python bench/bench_capture_diligent.py --work /tmp/capdil --out bench/results/capture_diligent.json

Per object of `--objects` (DiLiGenT folders under `--data`), three captures of all 96 photos, each a whole run of
the command (`--threads 1`, default flags otherwise):

- `jpeg_true`: 8-bit sRGB JPEG files `IMG_0001.jpg` ... (quality 95), every photo scaled by one factor so that
  `CLIP_SHARE` of the object's values clip (one exposure for all, their relative brightness kept), no light files,
  the true mask given as a file;
- `jpeg_auto`: the same photos with `--mask auto` (the mask's IoU with the true one recorded);
- `png_true`: the folder's own 16-bit linear PNG files copied as photos, the true mask given.

Per capture: the final map's error and the model's map's (`normal_model.png`), whether the refined map was kept, its
own error, the judged and held-out residuals before and after, wall time and peak memory. The refinement's rule of
keeping (`validate.fitted.refinement`) is judged on them: on every capture, was the kept map the better one?
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.cli_common import (  # noqa: E402
    DILIGENT,
    check_diligent,
    check_given,
    check_work,
    claim_result,
    clipping_scale,
    machine,
    parse,
    run_main,
    write_jpeg_photos,
    write_result,
)
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import CommaList, Command, arg, check_fields  # noqa: E402

CLIP_SHARE = 0.001
"""Share of the object's values (all photos) above the JPEG's largest code: a user's exposure, bright but not blown."""
CASES = ("jpeg_true", "jpeg_auto", "png_true")
RESULT_KEYS = ("command", "clip_share", "rows")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def _photos(obj, folder: Path, case: str, source: Path) -> None:
    """Write the photos of `case` into `folder` (module doc)."""
    folder.mkdir(parents=True, exist_ok=True)
    if case == "png_true":
        for i, f in enumerate(sorted(p for p in source.glob("*.png") if p.stem.isdigit()), 1):
            shutil.copyfile(f, folder / f"{i:03d}.png")
        return
    write_jpeg_photos(folder, obj.images, clipping_scale(obj.images, obj.mask, CLIP_SHARE))


def run_case(obj, source: Path, case: str, work: Path) -> dict:
    """One whole capture of `case` (module doc) and what it measured against the truth."""
    from scenes.images import read_mask, read_normals, write_mask
    from scenes.metrics import mean_angular_error

    name = f"{source.name.removesuffix('PNG')}_{case}"
    photos, out, mask_file = work / name / "photos", work / name / "out", work / name / "mask.png"
    present = list(photos.iterdir()) if photos.is_dir() else None
    if present is not None and len(present) != len(obj.images):  # an older run's partial set: written again
        if any(not (p.is_file() and p.stem.removeprefix("IMG_").isdigit() and p.suffix in (".png", ".jpg"))
               for p in present):
            raise UsageError(f"--work: {str(photos)!r} holds {len(present)} files, not the {len(obj.images)} "
                             "photos this bench writes, and files it does not write; move it away")
        shutil.rmtree(photos)
    if not photos.is_dir():  # written whole under a temporary name: an interrupted run leaves no partial set
        part = photos.with_name("photos.part")
        if part.exists():
            shutil.rmtree(part)  # this bench's own, left by a stopped run
        part.mkdir(parents=True)
        try:
            _photos(obj, part, case, source)
        except BaseException:  # a stop or a failure: nothing half-written stays behind
            shutil.rmtree(part, ignore_errors=True)
            raise
        part.rename(photos)
    write_mask(mask_file, obj.mask)
    mask_arg = "auto" if case == "jpeg_auto" else str(mask_file)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "orchestrate.capture", "--input", str(photos), "--out", str(out),
                           "--mask", mask_arg, "--threads", "1", "--overwrite"], cwd=REPO, capture_output=True,
                          text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return {"object": source.name, "case": case, "error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    report = json.loads((out / "report.json").read_text())
    truth = obj.mask & np.any(obj.normals != 0, axis=-1)
    final = mean_angular_error(read_normals(out / "normal.png"), obj.normals, truth)
    model = mean_angular_error(read_normals(out / "normal_model.png"), obj.normals, truth)
    row = {"object": source.name.removesuffix("PNG"), "case": case, "final_deg": round(final, 2),
           "model_deg": round(model, 2), "wall_s": round(wall, 1), "peak_mib": round(report["peak_memory_mib"]),
           "verdict": report["verdict"].get("level"), "refined_kept": bool(report["verdict"]["refined"])}
    if case == "jpeg_auto":
        auto = read_mask(out / "mask.png")
        row["mask_iou"] = round(float((auto & obj.mask).sum() / (auto | obj.mask).sum()), 4)
    refine = next(iter((out / "refine").glob("*/refine_report.json")), None)
    if refine is not None:
        r = json.loads(refine.read_text())
        held = r.get("holdout_judged") or {}
        refined_map = read_normals(refine.parent / "normal.png")
        row.update({"refined_deg": round(mean_angular_error(refined_map, obj.normals, truth), 2)
                    if r["accepted"] else None, "why": r["why"],
                    "judged_before": r["judged_before_rel_l1"], "judged_after": r["judged_after_rel_l1"],
                    "held_before": held.get("before_rel_l1"), "held_after": held.get("after_rel_l1")})
    return row


@dataclass
class Options:
    """The command line of bench/bench_capture_diligent.py."""

    work: Annotated[Path, arg(metavar="DIR")] = Path("/tmp/capdil")
    """Folder of the photo folders and the captures' outputs (photos reused when there)."""
    out: Annotated[Path, arg(metavar="FILE")] = REPO / "bench" / "results" / "capture_diligent.json"
    """Write the rows as JSON here."""
    data: Annotated[Path, arg(metavar="DIR", help_behavior_hint="(default: ../shared/data/diligent)")] = DILIGENT
    """Folder holding the DiLiGenT objects."""
    objects: Annotated[list[str], CommaList] = field(default_factory=lambda: ["ballPNG", "catPNG"])
    """DiLiGenT folders under --data, comma-separated."""

    def validate(self) -> "Options":
        check_fields(self)
        check_given(self, "objects")
        return self


COMMAND = Command(Options, prog="python bench/bench_capture_diligent.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    from unips.data import load_object

    args = parse(COMMAND, argv)
    sources = check_diligent(args.data, args.objects)
    check_work(args.work, inputs={"--data": args.data})
    claim_result(args.out, RESULT_KEYS, COMMAND, inputs={"--data": args.data})
    rows = []
    for source in sources:
        obj = load_object(source)
        for case in CASES:
            rows.append(run_case(obj, source, case, args.work))
            print(json.dumps(rows[-1]), flush=True)
    write_result(args.out, {"command": "python bench/bench_capture_diligent.py --work WORK", "clip_share": CLIP_SHARE,
                          "rows": rows, "machine": machine()}, indent=1, newline=True)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
