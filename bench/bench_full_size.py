"""What does working on smaller copies of the photos cost? (docs/capture.md, "Big photos")

    python bench/bench_full_size.py --work /tmp/fullbench --out bench/results/full_size.json

Renders `--objects` held-out objects (held-out meshes and HDR maps, directional, point and environment light, 12
images) at `--side` px, and for each working side of `--working` runs the shipped model on copies of the images
downscaled to it (area average), brings the map back to the rendered size as the capture does
(`orchestrate.capture_full.upsample`, the true mask given, as a user's own mask would be) and measures its mean
angular error against the exact normals at the rendered size; beside it, the automatic outline: the working mask
(the true one downscaled) brought back guided by the mean image, against a plain linear upsampling, as the share of
wrong pixels of the true mask's area.
"""
from __future__ import annotations

import dataclasses
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import check_given, check_work, claim_result, machine, parse, run_main, write_result  # noqa: E402
from orchestrate.capture import MIN_SIDE  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import Command, arg, check_fields, comma_list, option  # noqa: E402

RESULT_KEYS = ("command", "side", "objects", "rows")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


@dataclass
class Options:
    """bench_full_size: the error of maps made at a smaller working size and brought back to the photos' size."""

    work: Annotated[str, arg(metavar="DIR")] = "/tmp/fullbench"
    """Renders (resumed when run again)."""
    out: Annotated[str, arg(metavar="FILE")] = "bench/results/full_size.json"
    """Where the results are written (JSON)."""
    objects: int = option(9, minimum=1)
    """Objects rendered."""
    side: int = option(512, minimum=64)
    """The rendered (photos') side in pixels."""
    working: Annotated[list[int], comma_list(int, "N,N")] = option(
        default_factory=lambda: [64, 128, 256, 512], minimum=MIN_SIDE)
    """Working sides, comma-separated, at most --side (the rendered side itself: no downscaling)."""
    seed: int = option(9700)
    """Render seed (none the model was trained, validated or tested on)."""

    def validate(self) -> "Options":
        check_fields(self)
        check_given(self, "working")
        if max(self.working) > self.side:
            raise UsageError(f"--working: got {max(self.working)}, expected working sides of at most --side "
                             f"{self.side} (a working copy is the photos downscaled)")
        return self


COMMAND = Command(Options, prog="python bench/bench_full_size.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    import subprocess

    import cv2
    import torch

    from orchestrate.asset_split import split_assets
    from orchestrate.capture_full import downscale_mask, guide_image, upsample
    from scenes.folder.layouts import find_object_folders
    from scenes.metrics import angles_deg
    from unips.data import load_object
    from unips.inference import load_network, run_model

    opts = parse(COMMAND, argv)
    check_work(opts.work)
    claim_result(opts.out, RESULT_KEYS, COMMAND)
    torch.set_num_threads(2)
    work = Path(opts.work)
    work.mkdir(parents=True, exist_ok=True)
    assets = ROOT.parent / "shared" / "assets"
    held = ["--assets", str(split_assets(assets, work)[1])] if assets.is_dir() else []
    t0 = time.time()
    subprocess.run([sys.executable, "-m", "wildgen.make", "--lights", "directional,point,hdri", "--images", "12",
                    "--res", str(opts.side), "--spp", "16", "--objects", str(opts.objects), "--seed", str(opts.seed),
                    "--out", str(work / "renders"), "--quiet", *held], cwd=ROOT, check=True)
    net = load_network(None)
    sides = opts.working
    errors: dict[int, list[float]] = {s: [] for s in sides}
    outline: dict[int, list[tuple[float, float]]] = {s: [] for s in sides if s < opts.side}
    for folder in find_object_folders(work / "renders", "--work"):
        obj = load_object(folder)
        full_mask, truth = obj.mask, obj.normals
        guide = guide_image(obj.images.mean(axis=(0, -1)))
        for s in sides:
            size = (s, s)
            small = np.stack([cv2.resize(im, size, interpolation=cv2.INTER_AREA) for im in obj.images])
            mask = downscale_mask(full_mask, size)
            normals = run_model(net, dataclasses.replace(obj, images=small, mask=mask, normals=None))
            if s < opts.side:
                _, guided = upsample(normals, mask, guide)  # the outline the capture draws without a mask file
                normals, _ = upsample(normals, mask, guide, full_mask=full_mask)
                plain = cv2.resize(mask.astype(np.float32), full_mask.shape[::-1], interpolation=cv2.INTER_LINEAR)
                area = float(full_mask.sum())
                outline[s].append((float((guided ^ full_mask).sum()) / area,
                                   float(((plain > 0.5) ^ full_mask).sum()) / area))
            errors[s].append(float(angles_deg(normals[full_mask], truth[full_mask]).mean()))
        print(f"{folder.name}: " + ", ".join(f"{s} px {errors[s][-1]:.2f} deg" for s in sides), flush=True)
    rows = [{"working_side": s, "mean_error_deg": round(float(np.mean(errors[s])), 3),
             "per_object_deg": [round(e, 2) for e in errors[s]],
             **({"outline_wrong_guided": round(float(np.mean([g for g, _ in outline[s]])), 4),
                 "outline_wrong_linear": round(float(np.mean([p for _, p in outline[s]])), 4)} if s in outline else {})}
            for s in sides]
    result = {"command": f"python bench/bench_full_size.py --work WORK --objects {opts.objects} --side {opts.side} "
                         f"--working {','.join(map(str, sides))} --seed {opts.seed}",
              "side": opts.side, "objects": opts.objects, "rows": rows, "seconds": round(time.time() - t0, 1),
              "machine": machine()}
    write_result(Path(opts.out), result, indent=1)
    for r in rows:
        print(r["working_side"], r["mean_error_deg"], r.get("outline_wrong_guided"), r.get("outline_wrong_linear"))
    print(f"wrote {opts.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
