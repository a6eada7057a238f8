"""Rendering speed and memory (issue 2 / 3 figures). Not a test: prints a table.

  python bench/bench_render.py                      # 256x256, 64 spp, 10 images, every family
  python bench/bench_render.py --res 128 --images 4 --families near_area

Per family: seconds per object and per image, compile (first image) vs steady-state render time,
ground-truth pass, scene building and file writing, peak RSS of the process.
"""
from __future__ import annotations

import argparse
import json
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

from wildgen.lighting import LIGHT_FAMILIES


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--images", type=int, default=10)
    p.add_argument("--objects", type=int, default=2, help="objects per family")
    p.add_argument("--families", default=",".join(LIGHT_FAMILIES), help="light families, comma-separated (default: all)")
    p.add_argument("--variant", default=None)
    args = p.parse_args()

    from scenes.variant import choose_variant
    from wildgen.assets import AssetLibrary
    from wildgen.config import GenConfig
    from wildgen.writer import make_object

    variant = choose_variant(args.variant)
    print(f"variant {variant}, {args.res}x{args.res}, {args.spp} spp, {args.images} images/object, {args.objects} objects/family")
    print(f"{'family':12s} {'s/object':>9s} {'s/image':>8s} {'1st img':>8s} {'later':>7s} {'gt':>6s} {'build':>6s} {'write':>6s}")
    tmp = Path(tempfile.mkdtemp(prefix="bench_render_"))
    rows = {}
    try:
        for family in args.families.split(","):
            cfg = GenConfig(lights=[family], objects=args.objects, images=args.images, width=args.res, height=args.res, spp=args.spp, seed=1).validate()
            lib = AssetLibrary.scan(None)
            totals, per_image, first, later, gt, build, write = [], [], [], [], [], [], []
            for i in range(args.objects):
                import numpy as np

                from scenes.mitsuba_build import build_scene
                from scenes.render import render_ground_truth, render_image
                from wildgen.sampling import sample_object

                t0 = time.perf_counter()
                entry = make_object(cfg, i, tmp, lib)
                totals.append(time.perf_counter() - t0)
                t = entry["timings"]
                gt.append(t["ground_truth_s"]); build.append(t["build_s"]); write.append(t["write_s"])
                per_image.append(t["render_s"] / args.images)
                # Compile vs steady state: time image renders individually on a fresh scene object.
                s = sample_object(cfg, i + 1000, lib)
                from wildgen.writer import _localise

                d = tmp / "probe"
                shutil.rmtree(d, ignore_errors=True)
                (d / "aux").mkdir(parents=True)
                built = build_scene(_localise(s.desc, s, d), base_dir=d)
                times = []
                for k in range(min(3, args.images)):
                    t1 = time.perf_counter()
                    render_image(built, k)
                    times.append(time.perf_counter() - t1)
                first.append(times[0]); later.append(sum(times[1:]) / max(1, len(times) - 1))
            mean = lambda v: sum(v) / len(v)  # noqa: E731
            rows[family] = dict(s_per_object=mean(totals), s_per_image=mean(per_image), first_image_s=mean(first), later_image_s=mean(later), gt_s=mean(gt), build_s=mean(build), write_s=mean(write))
            r = rows[family]
            print(f"{family:12s} {r['s_per_object']:9.2f} {r['s_per_image']:8.3f} {r['first_image_s']:8.3f} {r['later_image_s']:7.3f} {r['gt_s']:6.3f} {r['build_s']:6.3f} {r['write_s']:6.3f}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {peak_mb:.0f} MB")
    print(json.dumps({"variant": variant, "res": args.res, "spp": args.spp, "images": args.images, "rows": rows, "peak_rss_mb": peak_mb}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
