"""Dataset throughput: objects per hour for local workers and Ray, scaling efficiency, overhead share.

  python bench/bench_throughput.py                                   # 128x128, 64 spp, 10 images, 8 objects
  python bench/bench_throughput.py --objects 4 --engines w1t1,w2t1   # quicker
  python bench/bench_throughput.py --overhead-spp 256 --overhead-objects 3

Not a test: prints a table. Every engine runs the real CLI (`python -m wildgen.make`) in a
subprocess into a fresh folder, so the wall time includes starting Python, importing Mitsuba,
spawning workers (or starting Ray) and writing the manifest. Engines:
  w<W>t<T>  W local worker processes with T Dr.Jit threads each (w1t2 = one process using 2 cores)
  ray       one Ray task per object on a local Ray (started by the CLI), 1 thread per task
  inproc    --workers 0: everything in the CLI process (no isolation)
The fixed cost of a run (start-up, no real work) is measured with a 1-object 8x8 run per engine.
The overhead share (sampling, scene building, ground truth, file writing vs path tracing) comes from
the manifest timings of an extra run at --overhead-spp. All runs must give byte-identical objects;
the script checks the checksums in the manifests.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.cli_common import MIN_RES, check_given, check_work, parse, refusals, run_main  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import CommaList, Command, arg, check_fields, option  # noqa: E402
from wildgen.light_families import LIGHT_FAMILIES  # noqa: E402


def engine_flags(name: str) -> list[str]:
    """wildgen.make's flags of an engine (--engines); a UsageError naming --engines for anything else."""
    if name == "ray":
        return ["--ray"]
    if name == "inproc":
        return ["--workers", "0"]
    w, _, t = name[1:].partition("t")
    if name.startswith("w") and w.isdigit() and t.isdigit() and int(w) >= 1 and int(t) >= 1:
        return ["--workers", str(int(w)), "--threads", str(int(t))]
    raise UsageError(f"--engines: got {name!r}, expected w<W>t<T> (W workers, T threads, each >= 1), ray or inproc")


def run_cli(out: Path, flags: list[str]) -> tuple[float, dict]:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "wildgen.make", "--out", str(out), "--quiet", *flags], cwd=REPO,
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(
            f"error: wildgen.make {' '.join(flags)} failed ({r.returncode}): {r.stderr.strip().splitlines()[-1:]}"
        )
    return wall, json.loads((out / "manifest.json").read_text())


def checksums(manifest: dict) -> dict:
    return {e["index"]: e.get("files") for e in manifest["objects"]}


def overhead_table(manifest: dict, label: str) -> None:
    keys = ("sampling", "build_s", "ground_truth_s", "render_s", "write_s")
    sums = dict.fromkeys(keys, 0.0)
    done = [e for e in manifest["objects"] if e["status"] == "done"]
    for e in done:
        t = e["timings"]
        for k in keys[1:]:
            sums[k] += t[k]
        sums["sampling"] += t["total_s"] - sum(t[k] for k in keys[1:])
    total = sum(sums.values())
    parts = ", ".join(f"{k.replace('_s', '')} {100 * v / total:.1f} %" for k, v in sums.items())
    print(f"{label}: {total / max(len(done), 1):.2f} s per object in the worker: {parts}")


@dataclass
class Options:
    """The command line of bench/bench_throughput.py."""

    res: int = option(128, minimum=MIN_RES)
    """Image side in pixels."""
    spp: int = option(64, minimum=1)
    """Samples per pixel."""
    images: int = option(10, minimum=1)
    """Images per object."""
    objects: int = option(8, minimum=1)
    """Objects of each engine's dataset."""
    engines: Annotated[list[str], CommaList] = field(default_factory=lambda: ["w1t1", "w1t2", "w2t1", "ray"])
    """Engines, comma-separated: w<W>t<T> (W local worker processes with T Dr.Jit threads each), ray or inproc."""
    overhead_spp: int = option(256, minimum=1)
    """Samples per pixel of the overhead-share run."""
    overhead_objects: int = option(3, minimum=1)
    """Objects of the overhead-share run."""
    lights: Annotated[list[str], CommaList, arg(help_behavior_hint="(default: all)")] = option(
        default_factory=lambda: list(LIGHT_FAMILIES), choices=tuple(LIGHT_FAMILIES))
    """light families for wildgen.make"""
    keep: Annotated[str | None, arg(metavar="DIR")] = None
    """keep the datasets in this folder"""

    def validate(self) -> "Options":
        check_fields(self)
        check_given(self, "engines")
        for engine in self.engines:
            engine_flags(engine)
        return self


COMMAND = Command(Options, prog="python bench/bench_throughput.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    check_work(args.keep, "--keep")
    engines, lights = list(args.engines), ",".join(args.lights)
    if "ray" in engines:
        try:
            import ray  # noqa: F401
        except ImportError:
            print("ray is not installed: skipping the ray engine (pip install 'unips-toolkit[ray]')")
            engines.remove("ray")
    with refusals():
        if not engines:
            raise UsageError("--engines: got 'ray', but ray is not installed (pip install 'unips-toolkit[ray]'); "
                             "expected w<W>t<T> or inproc too")
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_throughput_"))
    work.mkdir(parents=True, exist_ok=True)
    common = ["--lights", lights, "--res", str(args.res), "--spp", str(args.spp), "--images", str(args.images),
              "--objects", str(args.objects), "--seed", "0"]
    tiny = ["--lights", "directional", "--res", "8", "--spp", "1", "--images", "1", "--objects", "1", "--gt-spp", "1"]
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(
        f"{args.objects} objects, {args.res}x{args.res}, {args.spp} spp, {args.images} images/object, "
        f"lights {lights}; "
        f"{cores} cores, load average {os.getloadavg()[0]:.2f}"
    )
    print(f"{'engine':8s} {'wall s':>7s} {'fixed s':>8s} {'obj/hour':>9s} {'w/o fixed':>10s} {'speed-up':>9s}")
    rows, sums, manifests = {}, {}, {}
    try:
        for e in engines:
            fixed, _ = run_cli(work / f"fixed_{e}", tiny + engine_flags(e))
            wall, manifest = run_cli(work / e, common + engine_flags(e))
            done = sum(o["status"] == "done" for o in manifest["objects"])
            rows[e] = (wall, fixed, done)
            sums[e] = checksums(manifest)
            manifests[e] = manifest
        base = rows[engines[0]]
        for e, (wall, fixed, done) in rows.items():
            print(
                f"{e:8s} {wall:7.1f} {fixed:8.1f} {3600 * done / wall:9.0f} "
                f"{3600 * done / max(wall - fixed, 1e-9):10.0f} "
                f"{base[0] / wall:8.2f}x"
            )
        if "w1t1" in rows and "w2t1" in rows:
            eff = rows["w1t1"][0] / rows["w2t1"][0] / 2
            eff_net = (rows["w1t1"][0] - rows["w1t1"][1]) / (rows["w2t1"][0] - rows["w2t1"][1]) / 2
            print(
                f"scaling efficiency 2 workers vs 1 (1 thread each): {100 * eff:.0f} % "
                f"(without fixed costs {100 * eff_net:.0f} %)"
            )
        if "w1t2" in rows and "w2t1" in rows:
            print(f"2 workers x 1 thread vs 1 worker x 2 threads: {rows['w1t2'][0] / rows['w2t1'][0]:.2f}x")
        first = next(iter(sums.values()))
        same = all(s == first for s in sums.values())
        print(f"objects byte-identical across engines (manifest checksums): {'yes' if same else 'NO'}")

        label = "w1t2" if "w1t2" in manifests else engines[0]
        overhead_table(manifests[label], f"{label} at {args.spp} spp")
        over = [
            "--lights",
            lights,
            "--res",
            str(args.res),
            "--spp",
            str(args.overhead_spp),
            "--images",
            str(args.images),
            "--objects",
            str(args.overhead_objects),
            "--seed",
            "0",
            "--workers",
            "1",
        ]
        _, manifest = run_cli(work / "overhead", over)
        overhead_table(manifest, f"w1 at {args.overhead_spp} spp")
        print(f"load average now {os.getloadavg()[0]:.2f}")
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0 if rows else 1


if __name__ == "__main__":
    sys.exit(run_main(main))
