"""`orchestrate.capture` on DiLiGenT objects turned into photos, in this tree and in a baseline commit: which
outputs moved, and by how much, when a change should leave them alone or fixes something.

    python bench/bench_capture_trees.py --baseline 4694c24 [--objects ball,cat] [--out bench/results/capture_trees.json]

Each object (96 photos of 612 x 512 px) is written as 8-bit sRGB JPEG files (quality 95, exposed so that 0.1 % of
the object's values clip, as docs/capture.md's table), with its true mask as --mask; the same folder is captured by
both trees (each in a fresh process, `--threads 1`: byte-identical run to run). Per object and tree: the mean angular
error of the model's map and of the final map against the ground truth, the check's saturated fraction, judged
residual and verdict, whether the refinement was accepted, and the largest angle between the two trees' maps.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # this tree's toolkit, not another checkout's installed one

from bench.cli_common import (  # noqa: E402
    DILIGENT,
    check_diligent,
    check_given,
    check_revision,
    claim_result,
    clipping_scale,
    parse,
    run_main,
    write_jpeg_photos,
    write_result,
)
from scenes.cli.options import REQUIRED, CommaList, Command, check_fields  # noqa: E402

CLIP_FRACTION = 0.001
"""Fraction of the object's values (all images) that clip in the JPEG files."""


@dataclass
class Options:
    """The command line of bench_capture_trees."""

    baseline: str = REQUIRED
    """Commit to compare with (checked out into a temporary git worktree, removed after)."""
    data: str = str(DILIGENT)
    """Folder of DiLiGenT objects (<name>PNG)."""
    objects: Annotated[list[str], CommaList] = field(default_factory=lambda: ["ball", "cat"])
    """Comma-separated DiLiGenT objects (folders NAMEPNG under --data)."""
    out: str = "bench/results/capture_trees.json"
    """Where the table goes (JSON)."""

    def validate(self) -> "Options":
        check_fields(self)
        check_given(self, "objects")
        return self


COMMAND = Command(Options, prog="python bench/bench_capture_trees.py", description=__doc__.split("\n\n")[0])
RESULT_KEYS = ("baseline", "rows")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def write_photos(folder: Path, images: np.ndarray, mask: np.ndarray) -> None:
    """The images as 8-bit sRGB JPEG files, exposed so that CLIP_FRACTION of the object's values clip."""
    folder.mkdir(parents=True)
    write_jpeg_photos(folder, images, clipping_scale(images, mask, CLIP_FRACTION))


def capture(tree: Path, photos: Path, mask: Path, out: Path) -> dict:
    """Run the tree's orchestrate.capture in a fresh process; its report.json and check report."""
    cmd = [sys.executable, "-m", "orchestrate.capture", "--input", str(photos), "--out", str(out), "--mask",
           str(mask), "--threads", "1"]
    r = subprocess.run(cmd, cwd=tree, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{tree}: {r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
    report = json.loads((out / "report.json").read_text())
    check = json.loads((out / "check" / photos.name / "report.json").read_text())
    return {"report": report, "check": check}


def main(argv: list[str] | None = None) -> int:
    from scenes.folder.layouts import read_folder
    from scenes.images import read_normals, write_mask
    from scenes.metrics import angular_error_deg, mean_angular_error

    opts = parse(COMMAND, argv)
    check_diligent(opts.data, [f"{name}PNG" for name in opts.objects])
    check_revision(opts.baseline)
    claim_result(opts.out, RESULT_KEYS, COMMAND, inputs={"--data": opts.data})
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base = tmp / "baseline"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "-q", "--detach", str(base), opts.baseline],
                       check=True)
        try:
            for name in opts.objects:
                fd = read_folder(Path(opts.data) / f"{name}PNG", arg="--data")
                photos, mask = tmp / name / name, tmp / name / "mask.png"
                write_photos(photos, fd.images, fd.mask)
                write_mask(mask, fd.mask)
                maps = {}
                for label, tree in (("baseline", base), ("this tree", REPO)):
                    out = tmp / name / label.replace(" ", "_")
                    r = capture(tree, photos, mask, out)
                    final, model = read_normals(out / "normal.png"), read_normals(out / "normal_model.png")
                    maps[label] = final
                    v, c = r["report"]["verdict"], r["check"]
                    row = {"object": name, "tree": label,
                           "mae_model_deg": mean_angular_error(model, fd.normals, fd.mask),
                           "mae_final_deg": mean_angular_error(final, fd.normals, fd.mask),
                           "saturated_fraction": c["saturated_fraction"], "judged_rel_l1": c["judged_rel_l1"],
                           "images_can_judge": v["images_can_judge"], "refined": v["refined"],
                           "seconds": r["report"]["timings"]["total_s"]}
                    rows.append(row)
                    print(json.dumps(row), flush=True)
                diff = angular_error_deg(maps["baseline"], maps["this tree"], fd.mask)[fd.mask]
                rows.append({"object": name, "final_maps_max_angle_deg": float(diff.max()),
                             "final_maps_mean_angle_deg": float(diff.mean())})
                print(json.dumps(rows[-1]), flush=True)
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(base)], check=False)
    write_result(Path(opts.out), {"baseline": opts.baseline, "rows": rows}, indent=1, newline=True)
    print(f"wrote {opts.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
