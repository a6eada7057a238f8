"""Time and peak memory of `python -m orchestrate.capture` by the number of photos K and their long side:
reading, prediction, the physical check and refinement, the surface, next to the command's own estimate, and the
longest silence on stderr (no progress line for that long).

    python bench/bench_capture.py --out bench/results/capture.json [--images 4,16,96] [--sides 256,512,1024]
    python bench/bench_capture.py --out bench/results/capture.json --images 7 --sides 5760 --format jpeg --append
    python bench/bench_capture.py --reestimate bench/results/capture.json   # the estimate columns from today's code

Each case is a synthetic capture written as photos (16-bit PNG, 8-bit JPEG or camera RAW DNG, `--format`; photos
larger than the default working size are worked on at it and the map written back at their size; an ellipsoid
with a bumpy surface, Lambertian,
distant lights spread around the camera, a dark background; no mask, so the automatic mask runs too) at an
aspect of 4:3, run as a real subprocess with one Dr.Jit thread; its peak memory is the process's maximum
resident set size (`resource.getrusage` of the child). The table of docs/capture.md is generated from the
output file by `python -m orchestrate.docs`.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))  # the DNG writer of the RAW tests

from bench.cli_common import check_given, claim_result, machine, need_path, parse, run_main, write_result  # noqa: E402
from orchestrate.capture import MIN_SIDE  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.needs import Needs  # noqa: E402
from scenes.cli.options import Command, arg, check_fields, comma_list, option  # noqa: E402
from scenes.files import read_json, reading_record  # noqa: E402
from validate.judgeable import MIN_IMAGES  # noqa: E402

RESULT_KEYS = ("machine", "rows")
"""The keys of every result (--out, --reestimate): a file without them is not this bench's and is never replaced."""


def synthetic_capture(folder: Path, k: int, side: int, seed: int = 0, fmt: str = "png") -> None:
    """K photos (side x 3/4 side) of a bumpy ellipsoid under distant lights: 16-bit PNG, 8-bit sRGB JPEG (quality
    95) with `fmt` 'jpeg', or camera RAW with 'dng' (uncompressed Bayer DNG, tests/dng.py)."""
    h, w = round(side * 3 / 4), side
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float32) + 0.5
    x, y = (cols - w / 2) / (0.38 * w), -(rows - h / 2) / (0.42 * h)
    del rows, cols
    q = 1 - x * x - y * y
    mask = q > 0.01
    bump = 0.05 * np.sin(9 * x) * np.cos(7 * y)
    n = np.stack([x + bump, y - bump, np.sqrt(np.clip(q, 0, None)) + 0.2], -1)
    del x, y, q, bump
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rng = np.random.default_rng(seed)
    polar, azimuth = np.radians(rng.uniform(20, 55, k)), np.radians(np.linspace(0, 360, k, endpoint=False))
    lights = np.stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)], -1)
    albedo = np.array([0.7, 0.55, 0.4])
    folder.mkdir(parents=True, exist_ok=True)
    for i, l in enumerate(lights):
        img = np.clip(np.clip(n @ l.astype(np.float32), 0, None)[..., None] * albedo * mask[..., None] + 0.002, 0, 1)
        if fmt == "dng":  # camera RAW: the linear values as a Bayer mosaic of 12-bit sensor values
            from dng import BLACK, NEUTRAL, WHITE, mosaic_of, write_dng

            write_dng(folder / f"DSC{i + 1:05d}.dng", mosaic_of(img * (WHITE - BLACK) * np.array(NEUTRAL)))
        elif fmt == "jpeg":
            srgb = np.where(img <= 0.0031308, 12.92 * img, 1.055 * img ** (1 / 2.4) - 0.055)
            cv2.imwrite(str(folder / f"DSC{i + 1:05d}.jpg"), np.round(srgb * 255).astype(np.uint8)[..., ::-1],
                        [cv2.IMWRITE_JPEG_QUALITY, 95])
        else:
            cv2.imwrite(str(folder / f"DSC{i + 1:05d}.png"), np.round(img * 65535).astype(np.uint16)[..., ::-1])


def run_case(k: int, side: int, work: Path, fmt: str = "png") -> dict:
    photos, out = work / f"k{k}_s{side}_{fmt}", work / f"out_k{k}_s{side}_{fmt}"
    synthetic_capture(photos, k, side, fmt=fmt)
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "orchestrate.capture", "--input", str(photos), "--out", str(out),
                             "--threads", "1", "--overwrite"], cwd=REPO, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    seen, lines = [t0], []
    for line in proc.stderr:  # the progress lines as they come: the longest silence is measured, not assumed
        seen.append(time.perf_counter())
        lines.append(line.rstrip())
    proc.wait()
    wall = time.perf_counter() - t0
    seen.append(t0 + wall)
    if proc.returncode != 0:
        return {"images": k, "side": side, "error": (lines or ["(no message)"])[-1]}
    report = json.loads((out / "report.json").read_text())
    t = report["timings"]
    import shutil

    shutil.rmtree(photos)  # 24-megapixel cases take room
    return {"images": k, "side": side, "format": fmt, "size": report["input"]["size"],
            "working_size": report["input"]["working_size"], "wall_s": round(wall, 1),
            "prepare_s": round(t["read_s"] + t["mask_and_checks_s"], 2),
            "predict_s": round(t["predict_s"], 2), "check_and_refine_s": round(t["check_and_refine_s"], 2),
            "surface_s": round(t["surface_s"], 2), "refined": report["verdict"]["refined"],
            "peak_mib": round(report["peak_memory_mib"]), "longest_silence_s": round(float(np.diff(seen).max()), 1),
            "estimate_mib": report["estimate"]["peak_mib"], "estimate_s": report["estimate"]["seconds"]}


@dataclass
class Options:
    """The command line of bench/bench_capture.py."""

    out: Annotated[Path | None, arg(metavar="FILE")] = None
    """Write the measurements as JSON here (required unless --reestimate)."""
    images: Annotated[list[int], comma_list(int, "K,K")] = option(
        default_factory=lambda: [4, 16, 96], minimum=MIN_IMAGES["photos"])
    """Numbers of photos K, comma-separated (at least 3: fewer do not determine a normal)."""
    sides: Annotated[list[int], comma_list(int, "N,N")] = option(
        default_factory=lambda: [256, 512, 1024], minimum=MIN_SIDE)
    """Long sides of the photos in pixels, comma-separated."""
    format: Literal["png", "jpeg", "dng"] = "png"
    """Photo files: png (16-bit), jpeg (8-bit sRGB, quality 95) or dng (camera RAW, developed by LibRaw)."""
    append: bool = False
    """Add the rows to those already in --out (its command is recorded after the earlier ones)."""
    reestimate: Annotated[Path | None, arg(metavar="FILE")] = None
    """rewrite the estimate columns of a recorded output with the command's current estimate (the measurements
    are kept as recorded)"""

    def validate(self) -> "Options":
        check_fields(self)
        if self.out is None and self.reestimate is None:
            raise UsageError("--out is required (unless --reestimate)")
        check_given(self, "images", "sides")
        return self


REWRITES = "without --reestimate (which rewrites its recorded FILE in place, measuring nothing)"
COMMAND = Command(Options, prog="python bench/bench_capture.py", description=__doc__.split("\n\n")[0],
                  needs=tuple(Needs(f, lambda c, _: c.reestimate is None, REWRITES)
                              for f in ("out", "append", "images", "sides", "format")))


def _count(value) -> int:
    """A recorded row's photo count: a whole number of at least 1 (a ValueError otherwise, said with the file)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"a row's images is {value!r}; expected a whole number of photos, at least 1")
    return value


def _photo_size(value) -> tuple[int, int]:
    """A recorded row's photo size (width, height): two whole numbers of at least 1 pixel."""
    if not isinstance(value, (list, tuple)) or len(value) != 2 or not all(
            isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in value):
        raise ValueError(f"a row's size is {value!r}; expected [width, height] in pixels, each at least 1")
    return int(value[0]), int(value[1])


def _earlier(path: Path) -> dict:
    """The rows and commands of this bench's earlier output at `path` (--append), each row an object; a ValueError
    naming the file otherwise."""
    with reading_record(path, "a recorded output of this bench", flag="--out"):
        before = read_json(path)
        earlier = before["commands"] if "commands" in before else [before["command"]]  # a record before 'commands'
        if not isinstance(before["rows"], list) or not all(isinstance(r, dict) for r in before["rows"]):
            raise ValueError("its rows are not a list of objects")
        if not isinstance(earlier, list) or not all(isinstance(c, str) for c in earlier):
            raise ValueError("its commands are not a list of command lines")
        return {"rows": before["rows"], "commands": earlier}


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    if args.reestimate:
        need_path(args.reestimate, "--reestimate", "a recorded output of this bench (--out)", folder=False)
        claim_result(args.reestimate, RESULT_KEYS, COMMAND, "--reestimate")
        from orchestrate.capture_estimate import estimate

        command = "python bench/bench_capture.py --reestimate " + str(args.reestimate)
        with reading_record(args.reestimate, "a recorded output of this bench (--out)", flag="--reestimate"):
            result = read_json(args.reestimate)
            for row in result["rows"]:
                if "error" not in row:
                    size = _photo_size(row["size"])
                    e = estimate(_count(row["images"]), *_photo_size(row.get("working_size", size)), full=size)
                    row["estimate_mib"], row["estimate_s"] = e["peak_mib"], e["seconds"]
            earlier = result["commands"] if "commands" in result else [result.get("command")]
            if not isinstance(earlier, list):
                raise ValueError(f"its commands are {type(earlier).__name__}, expected a list of command lines")
            result["commands"] = [str(c) for c in earlier if c not in (None, command)] + [command]
        write_result(args.reestimate, result, indent=1, newline=True)
        print(f"rewrote the estimates of {args.reestimate}")
        return 0
    claim_result(args.out, RESULT_KEYS, COMMAND)
    before = _earlier(args.out) if args.append and args.out.is_file() else None  # read before the measurement
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for side in args.sides:
            for k in args.images:
                row = run_case(k, side, Path(tmp), args.format)
                print(json.dumps(row), flush=True)
                rows.append(row)
    commands = ["python bench/bench_capture.py " + " ".join(argv or sys.argv[1:])]
    if before is not None:
        rows, commands = before["rows"] + rows, before["commands"] + commands
    result = {"machine": machine(),
              "commands": commands, "rows": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_result(args.out, result, indent=1, newline=True)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
