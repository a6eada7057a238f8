"""Rendering speed and memory of the generator, per light family. Not a test: prints a table.

  python bench/bench_render.py                      # 256x256, 64 spp, 10 images, every family
  python bench/bench_render.py --res 128 --images 4 --families near_area
  python bench/bench_render.py --res 64 --spp 16 --images 8 --objects 4 --rounds 3 \
      --families near_area,verse,flash,frontal,grid96,light_stage,display   # new families vs the default
  python bench/bench_render.py --res 64 --spp 16 --images 8 --objects 4 --rounds 3 --families near_area \
      --features default,perspective,focal,detail,cluster   # generator features (FEATURES) vs today's default

Per family: seconds per object (wall clock, and CPU seconds of all threads: `cpu s/obj`, less sensitive to
other work on a shared machine) and per image, the CPU cost per object relative to the first family listed
(`x first`), compile (first image) vs steady-state render time, ground-truth pass, scene building and file
writing, peak RSS of the process.
"""
from __future__ import annotations

import json
import resource
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import MIN_RES, parse, run_main  # noqa: E402
from scenes.checks import check_choice  # noqa: E402
from scenes.cli.options import CommaList, Command, arg, check_fields, option  # noqa: E402
from scenes.renderer.variant import PREFERENCE as VARIANTS  # noqa: E402
from wildgen.light_families import LIGHT_FAMILIES  # noqa: E402

FEATURES = {
    "default": {},
    "perspective": {"camera": "perspective"},
    "focal": {"camera": "perspective", "focal": "15-300"},
    "detail": {"detail": 1.0},
    "cluster": {"cluster": "2-4"},
}
"""Generator features measured against the default (`--features`): GenConfig overrides."""

COLUMNS = ("s_per_object", "cpu_s_per_object", "s_per_image", "first_image_s", "later_image_s", "gt_s", "build_s",
           "write_s")


def measure(family: str, args, tmp: Path, overrides: dict | None = None) -> dict[str, list[float]]:
    """One round of `args.objects` objects of `family` (GenConfig `overrides` on top): per object, each column."""
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_image
    from wildgen.assets import AssetLibrary
    from wildgen.config import GenConfig
    from wildgen.sampling import sample_object
    from wildgen.writer import _localise, make_object

    cfg = GenConfig(lights=[family], objects=args.objects, images=args.images, width=args.res, height=args.res,
                    spp=args.spp, seed=1, **(overrides or {})).validate()
    lib = AssetLibrary.scan(None)
    out: dict[str, list[float]] = {c: [] for c in COLUMNS}
    for i in range(args.objects):
        t0, c0 = time.perf_counter(), time.process_time()
        entry = make_object(cfg, i, tmp / family, lib)
        out["s_per_object"].append(time.perf_counter() - t0)
        out["cpu_s_per_object"].append(time.process_time() - c0)
        t = entry["timings"]
        out["gt_s"].append(t["ground_truth_s"])
        out["build_s"].append(t["build_s"])
        out["write_s"].append(t["write_s"])
        out["s_per_image"].append(t["render_s"] / args.images)
        # Compile vs steady state: time image renders individually on a fresh scene object.
        s = sample_object(cfg, i + 1000, lib)
        d = tmp / "probe"
        shutil.rmtree(d, ignore_errors=True)
        (d / "aux").mkdir(parents=True)
        built = build_scene(_localise(s.desc, s, d), base_dir=d)
        times = []
        for k in range(min(3, args.images)):
            t1 = time.perf_counter()
            render_image(built, k)
            times.append(time.perf_counter() - t1)
        out["first_image_s"].append(times[0])
        out["later_image_s"].append(sum(times[1:]) / max(1, len(times) - 1))
    shutil.rmtree(tmp / family, ignore_errors=True)  # the next round writes the same objects again
    return out


@dataclass
class Options:
    """The command line of bench/bench_render.py."""

    res: int = option(256, minimum=MIN_RES)
    """Image side in pixels."""
    spp: int = option(64, minimum=1)
    """Samples per pixel."""
    images: int = option(10, minimum=1)
    """Images per object."""
    objects: int = option(2, minimum=1)
    """objects per family"""
    families: Annotated[list[str], CommaList, arg(help_behavior_hint="(default: all)")] = option(
        default_factory=lambda: list(LIGHT_FAMILIES), choices=tuple(LIGHT_FAMILIES))
    """light families, comma-separated"""
    rounds: int = option(1, minimum=1)
    """rounds over all families; each figure is the smallest of its rounds (robust to other load)"""
    features: Annotated[list[str], CommaList] = field(default_factory=list)
    """generator features, comma-separated (default, perspective, focal, detail, cluster): one row per family and
    feature"""
    variant: str | None = option(None, choices=("auto", *VARIANTS))
    """Mitsuba variant (default: cuda, llvm, scalar, the first this machine runs)."""

    def validate(self) -> "Options":
        check_fields(self)
        for feature in self.features:  # none given: the default only (a choice list may not be empty)
            check_choice(feature, "--features", FEATURES)
        return self


COMMAND = Command(Options, prog="python bench/bench_render.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)

    from scenes.renderer.variant import choose_variant
    from wildgen.assets import AssetLibrary
    from wildgen.config import GenConfig
    from wildgen.writer import make_object

    variant = choose_variant(args.variant)
    features = args.features or [None]
    setups = {
        (f if feat is None else f"{f}+{feat}"): (f, FEATURES.get(feat, {}))
        for f in args.families
        for feat in features
    }
    families = list(setups)
    print(f"variant {variant}, {args.res}x{args.res}, {args.spp} spp, {args.images} images/object, "
          f"{args.objects} objects/family, min of {args.rounds} round(s)")
    tmp = Path(tempfile.mkdtemp(prefix="bench_render_"))
    rounds: dict[str, list[dict[str, list[float]]]] = {f: [] for f in families}
    try:
        # One object first, not timed: the first render of a process compiles kernels and fills caches, which
        # would be charged to whichever family comes first.
        warm = GenConfig(
            lights=[setups[families[0]][0]],
            objects=1,
            images=args.images,
            width=args.res,
            height=args.res,
            spp=args.spp,
            seed=99,
        ).validate()
        make_object(warm, 0, tmp / "warmup", AssetLibrary.scan(None))
        for _ in range(args.rounds):  # interleaved, so slow periods of a shared machine hit every family
            for family in families:
                rounds[family].append(measure(setups[family][0], args, tmp, setups[family][1]))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    w = max(12, *map(len, families))
    print(f"{'setup':{w}s} {'s/object':>9s} {'cpu s/obj':>9s} {'x first':>8s} {'s/image':>8s} {'1st img':>8s} "
          f"{'later':>7s} {'gt':>6s} {'build':>6s} {'write':>6s}")
    rows = {}
    for family in families:
        # Per object and column the smallest over the rounds (the same objects every round), then the mean.
        r = {c: sum(map(min, zip(*(m[c] for m in rounds[family])))) / args.objects for c in COLUMNS}
        r["vs_first"] = r["cpu_s_per_object"] / (rows[families[0]] if rows else r)["cpu_s_per_object"]
        rows[family] = r
        print(f"{family:{w}s} {r['s_per_object']:9.2f} {r['cpu_s_per_object']:9.2f} {r['vs_first']:8.2f} "
              f"{r['s_per_image']:8.3f} {r['first_image_s']:8.3f} {r['later_image_s']:7.3f} {r['gt_s']:6.3f} "
              f"{r['build_s']:6.3f} {r['write_s']:6.3f}")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {peak_mb:.0f} MB")
    print(json.dumps({"variant": variant, "res": args.res, "spp": args.spp, "images": args.images,
                      "rounds": args.rounds, "rows": rows, "peak_rss_mb": peak_mb}))
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
