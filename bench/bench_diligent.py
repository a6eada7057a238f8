"""Classical baselines on the real DiLiGenT objects (ball, cat): mean angular error and time.

    python bench/bench_diligent.py [--data ../shared/data/diligent] [--max-images K]

Prints, per object, the calibrated least-squares error (published DiLiGenT "L2 baseline": ball 4.10,
cat 8.41) and the uncalibrated sh-uncalibrated error, with load and solve times (CPU, wall clock).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import DILIGENT, check_diligent, need_path, parse, run_main  # noqa: E402
from scenes.cli.options import Command, arg, option  # noqa: E402

PUBLISHED = {"ball": 4.10, "cat": 8.41}


@dataclass
class Options:
    """The command line of bench/bench_diligent.py."""

    data: Annotated[Path, arg(metavar="DIR", help_behavior_hint="(default: ../shared/data/diligent)")] = DILIGENT
    """folder holding ballPNG/ and catPNG/"""
    max_images: Annotated[int | None, arg(metavar="K", help_behavior_hint="(default: all 96)")] = option(
        None, minimum=4
    )
    """first K images only (at least 4: sh-uncalibrated fits an ambient and three lighting components)"""


COMMAND = Command(Options, prog="python bench/bench_diligent.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    from scenes.metrics import mean_angular_error
    from unips.baselines import least_squares, sh_uncalibrated
    from unips.data import load_object

    args = parse(COMMAND, argv)
    need_path(args.data, "--data", "the DiLiGenT folder (ballPNG/, catPNG/)")
    folders = check_diligent(args.data, [f"{name}PNG" for name in PUBLISHED])
    print(f"{'object':<8} {'K':>3} {'pixels':>7} {'load s':>7} {'LS deg':>7} {'publ.':>6} {'LS s':>6} "
          f"{'SH deg':>7} {'SH s':>6}")
    for name, folder in zip(PUBLISHED, folders):
        t0 = time.perf_counter()
        obj = load_object(folder, max_images=args.max_images, arg="--data")
        t1 = time.perf_counter()
        ls_err = mean_angular_error(least_squares(obj), obj.normals, obj.mask)
        t2 = time.perf_counter()
        sh_err = mean_angular_error(sh_uncalibrated(obj), obj.normals, obj.mask)
        t3 = time.perf_counter()
        print(f"{name:<8} {obj.num_images:>3} {int(obj.mask.sum()):>7} {t1 - t0:>7.2f} {ls_err:>7.2f} "
              f"{PUBLISHED[name]:>6.2f} {t2 - t1:>6.2f} {sh_err:>7.2f} {t3 - t2:>6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
