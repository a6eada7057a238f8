"""Cost of thread-independent rendering (issue 14). Not a test: prints a table.

  python bench/bench_determinism.py          # 128x128 / 64 spp, 32x32 / 4 spp, 64x64 / 32 spp; 1 and 2 threads
  python bench/bench_determinism.py --sizes 64:32 --images 6 --repeats 3

Old: `mi.render` (atomic scatter-add into the film; bytes depend on the thread count). New:
`scenes.renderer.render.render_film` (each sample to its own slot, each pixel summed in sample order by one Dr.Jit
lane). Both render the same images of one `mixed`-light object, interleaved image by image in one process so that load
from other processes hits both alike; the first image of each (compilation) is not timed. Also reports
whether each path gave identical bytes with 1 and 2 threads.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import check_given, parse, run_main  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import Command, check_fields, comma_list, option  # noqa: E402
from scenes.renderer.variant import PREFERENCE as VARIANTS  # noqa: E402


def size_of(text: str) -> tuple[int, int]:
    """(RES, SPP) of one item `RES:SPP` of --sizes, each a value `wildgen.config.GenConfig` takes for --width /
    --height and --spp; a UsageError naming --sizes otherwise."""
    from wildgen.config import GenConfig

    parts = text.split(":")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise UsageError(f"--sizes: got {text!r}, expected RES:SPP (two whole numbers, e.g. 64:32), comma-separated")
    res, spp = (int(p) for p in parts)
    try:
        GenConfig(lights=["mixed"], objects=1, images=1, width=res, height=res, spp=spp).validate()
    except ValueError as exc:  # the generator's own bounds (`--width: got 4, expected ...`), said for this flag
        part = "SPP" if str(exc).startswith("--spp") else "RES"
        raise UsageError(f"--sizes: got {text!r}, expected RES:SPP with {part} {str(exc).split('expected ', 1)[-1]}") \
            from None
    return res, spp


@dataclass
class Options:
    """The command line of bench/bench_determinism.py."""

    sizes: Annotated[list[str], comma_list(str, "RES:SPP,RES:SPP")] = field(
        default_factory=lambda: ["128:64", "32:4", "64:32"])
    """comma-separated RES:SPP (64:32 is 35 multijitter samples: pixels straddle thread blocks)"""
    images: int = option(6, minimum=2)
    """Images of the object per size, at least 2 (the first, compilation, is not timed)."""
    repeats: int = option(2, minimum=1)
    """timed renders of every image per path"""
    threads: Annotated[list[int], comma_list(int, "T,T")] = option(default_factory=lambda: [1, 2], minimum=1)
    """Dr.Jit thread counts, comma-separated."""
    variant: str = option("llvm_ad_rgb", choices=("auto", *VARIANTS))
    """Mitsuba variant."""

    def validate(self) -> "Options":
        check_fields(self)
        check_given(self, "sizes", "threads")
        for text in self.sizes:
            size_of(text)
        return self


COMMAND = Command(Options, prog="python bench/bench_determinism.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)

    from scenes.renderer.variant import choose_variant

    choose_variant(args.variant)
    import drjit as dr
    import mitsuba as mi

    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_film
    from wildgen.assets import AssetLibrary
    from wildgen.config import GenConfig
    from wildgen.sampling import sample_object

    rows = []
    for size in args.sizes:
        res, spp = size_of(size)
        cfg = GenConfig(lights=["mixed"], objects=1, images=args.images, width=res, height=res, spp=spp)
        desc = sample_object(cfg, 0, AssetLibrary.scan(None)).desc
        built = build_scene(desc)
        paths = {
            "old": lambda i: np.array(
                mi.render(built.scene, spp=desc.render.spp, seed=desc.images[i].seed), np.float32
            ),
            "new": lambda i: render_film(built.scene, desc.render.spp, desc.images[i].seed),
        }
        outputs: dict[tuple[str, int], list[np.ndarray]] = {}
        for threads in args.threads:
            dr.set_thread_count(threads)
            times = {name: [] for name in paths}
            for name, fn in paths.items():  # warm-up: compile both kernels
                built.apply_image(0)
                fn(0)
            for i in range(len(desc.images)):
                built.apply_image(i)
                for _ in range(args.repeats):
                    for name, fn in paths.items():
                        t0 = time.perf_counter()
                        fn(i)
                        times[name].append(time.perf_counter() - t0)
                for name, fn in paths.items():
                    outputs.setdefault((name, threads), []).append(fn(i))
            old, new = np.median(times["old"]), np.median(times["new"])
            rows.append((f"{res}x{res}", desc.render.spp, threads, old, new, new / old))
        thread_list = args.threads
        for name in paths:
            same = all(
                np.array_equal(a, b) for a, b in zip(outputs[(name, thread_list[0])], outputs[(name, thread_list[-1])])
            )
            rows.append(
                (
                    f"{res}x{res}",
                    desc.render.spp,
                    f"{name}: {thread_list[0]} vs {thread_list[-1]} threads identical",
                    same,
                )
            )
    print(f"variant {args.variant}, {args.images} images, median seconds per image over {args.repeats} renders each")
    from scenes.report.tables import markdown_table

    print(markdown_table(["size", "spp", "threads", "old mi.render (s)", "new render_film (s)", "new / old"],
                         [[*r[:3], f"{r[3]:.4f}", f"{r[4]:.4f}", f"{r[5]:.2f}"] for r in rows if len(r) == 6]))
    for r in rows:
        if len(r) == 4:
            print(f"{r[0]} spp {r[1]}: {r[2]}: {r[3]}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
