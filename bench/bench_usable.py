"""Which warnings `validate.diagnosis.usable.capture_warnings` raises on real and rendered captures whose faults are
known: the `camera_moved` and `frontal_light` targets of the capture checks, and no false warning on good captures.

    python bench/bench_usable.py [--data ../shared/data/diligent] [--suite DIR ...] [--out bench/results/usable.json]
                                 [--objects ball,cat] [--encodings linear16,jpeg] [--subsets 96,48,16,8]
                                 [--shifts 2,3,4,6] [--directions x,y,diag] [--halves alternate,second]

DiLiGenT ball and cat (96 photos of 612 x 512 px, the true mask.png):

- as taken, all 96 images, every 2nd, and 16 and 8 evenly spaced: neither camera_moved nor frontal_light;
- the same with half of the images (every other one, or the second half) moved by 2, 3, 4 and 6 px in x, in y
  and diagonally (both x and y): camera_moved. Every image is cut from the frame with a margin of 8 px, the moved
  ones from a window moved by the shift, so nothing wraps around and the mask stays the unmoved images';
- the lights within 15 and within 10 deg of the viewing direction (light_directions.txt): frontal_light;
- each as 16-bit linear (the PNGs as stored) and as 8-bit sRGB JPEG (exposed so that 0.1 % of the object's
  values clip, OpenCV quality 95, read back by `scenes.folder.photos.read_photos`, the toolkit's linearisation;
  the moved images are moved before encoding, so the JPEG blocks stay on the frame).

Rendered object folders (`--suite`, each a `wildgen.make` dataset; no camera motion, the true mask): no
camera_moved, and frontal_light exactly where every image's lights are within 20 deg of the viewing direction
seen from the object's centre (scene.json; `true_max_polar` says how environment and uniform lights count).
A case is a row: what was expected, what was raised, and whether that is right.
"""
from __future__ import annotations

import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # this tree's toolkit, not another checkout's installed one

from bench.cli_common import (  # noqa: E402
    DILIGENT,
    check_diligent,
    check_suites,
    claim_result,
    parse,
    run_main,
    write_jpeg_photos,
    write_result,
)
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import CommaList, Command, UseAppendAction, arg, check_fields, comma_list, option  # noqa: E402
from scenes.files import read_json, reading_record  # noqa: E402
from validate.judgeable import MIN_IMAGES  # noqa: E402

MARGIN = 8
"""Pixels cut from each side of DiLiGenT's frames, so that a moved window stays inside the photo."""
DIRECTIONS = {"x": (1, 0), "y": (0, 1), "diag": (1, 1)}
"""A shift of s px moves the picture by s times these (columns, rows)."""
FRONTAL_TRUE_DEG = 20.0
"""A rendered capture is frontal when every image's lights are within this angle of the viewing direction."""
WATCHED = ("camera_moved", "frontal_light")


def _crop(images: np.ndarray, dx: int = 0, dy: int = 0) -> np.ndarray:
    """The frame less MARGIN on each side, its content moved by (dx columns right, dy rows down)."""
    h, w = images.shape[1:3]
    return images[:, MARGIN - dy:h - MARGIN - dy, MARGIN - dx:w - MARGIN - dx]


def _jpeg_round_trip(images: np.ndarray, scale: float, work: Path) -> np.ndarray:
    """The images as 8-bit sRGB JPEG files (quality 95, linear values times `scale`), read back by read_photos."""
    from scenes.folder.photos import read_photos

    folder = Path(tempfile.mkdtemp(dir=work))
    write_jpeg_photos(folder, images, scale)
    photos = read_photos(folder)
    for f in folder.iterdir():
        f.unlink()
    folder.rmdir()
    return photos.images


def _subsets(k: int, sizes: list[int]) -> dict[str, np.ndarray]:
    out = {}
    for n in sizes:
        if n >= k:
            out[f"all {k}"] = np.arange(k)
        elif n == k // 2:
            out[f"every 2nd ({n})"] = np.arange(0, k, 2)
        else:
            out[f"{n} even"] = np.unique(np.linspace(0, k - 1, n).round().astype(int))
    return out


def _halves(n: int, names: list[str]) -> dict[str, np.ndarray]:
    """Positions within a subset of n images that are moved."""
    table = {"alternate": np.arange(1, n, 2), "second": np.arange(n // 2, n)}
    return {name: table[name] for name in names}


def _raised(images: np.ndarray, mask: np.ndarray) -> tuple[list[str], dict]:
    from validate.diagnosis.usable import capture_warnings

    warnings, facts = capture_warnings(images, mask)
    return [w.code for w in warnings], facts


def _row(source: str, obj: str, encoding: str, subset: str, case: str, expect: set[str], codes: list[str],
         facts: dict, seconds: float) -> dict:
    raised = {c for c in codes if c in WATCHED}
    ok = raised == expect
    pairs = facts.get("camera_shift_pairs", [])
    return {"source": source, "object": obj, "encoding": encoding, "subset": subset, "case": case,
            "expected": sorted(expect), "raised": codes, "ok": ok, "camera_shift_px": facts.get("camera_shift_px"),
            "shifted_pairs": len(pairs),
            "max_light_polar_deg": (round(float(np.nanmax(facts["light_polar_deg"])), 1)
                                    if facts.get("light_polar_deg") else None), "seconds": round(seconds, 2)}


def _print(row: dict) -> None:
    print(
        f"{'ok ' if row['ok'] else 'BAD'} {row['source']:<9} {row['object']:<10} {row['encoding']:<8} "
        f"{row['subset']:<15} {row['case']:<24} expected {','.join(row['expected']) or '-':<14} raised "
        f"{','.join(row['raised']) or '-':<28} shifted pairs {row['shifted_pairs']:>2} "
        f"polar {row['max_light_polar_deg']} "
        f"({row['seconds']:.1f} s)",
        flush=True,
    )


def diligent_rows(folder: Path, args, work: Path) -> list[dict]:
    """Every DiLiGenT case of one object folder (module doc)."""
    from scenes.folder.layouts import read_folder

    fd = read_folder(folder)
    obj = fd.name.removesuffix("PNG")
    raw = fd.images
    polar = np.degrees(np.arccos(np.clip(fd.lights.directions[:, 2], -1, 1)))
    mask = _crop(fd.mask[None])[0]
    scale = 1.0 / float(np.percentile(raw[:, fd.mask], 99.9))
    rows = []

    def run(encoding, images_by_case):
        for subset, case, expect, images in images_by_case:
            t0 = time.perf_counter()
            codes, facts = _raised(images, mask)
            rows.append(_row("diligent", obj, encoding, subset, case, expect, codes, facts, time.perf_counter() - t0))
            _print(rows[-1])

    for encoding in args.encodings:
        def encode(images):
            return images if encoding == "linear16" else _jpeg_round_trip(images, scale, work)

        still = encode(_crop(raw))
        subsets = _subsets(len(raw), args.subsets)
        run(encoding, [(name, "as taken", set(), still[idx]) for name, idx in subsets.items()])
        near = []
        for deg in args.frontal:
            idx = np.nonzero(polar <= deg)[0]
            near.append((f"{len(idx)} within {deg:g} deg", "frontal", {"frontal_light"}, still[idx]))
        run(encoding, near)
        for s in args.shifts:
            for direction in args.directions:
                ux, uy = DIRECTIONS[direction]
                moved = encode(_crop(raw, s * ux, s * uy))
                cases = []
                for name, idx in subsets.items():
                    for half, pos in _halves(len(idx), args.halves).items():
                        images = still[idx].copy()
                        images[pos] = moved[idx[pos]]
                        cases.append((name, f"{half} moved {s} px {direction}", {"camera_moved"}, images))
                run(encoding, cases)
                del moved
    return rows


def true_max_polar(scene: dict) -> float:
    """Largest angle (deg) between the viewing direction and any light of any image, seen from the object's
    centre (the world origin, the camera on +z). A uniform light has no direction (it is left out); an environment
    map is light from all around (180), except the dim room (5-20 %) around the `flash` family's lamp at the
    camera, which the generator adds so that the images differ at all."""
    worst = 0.0
    for image in scene["images"]:
        for light in image["lights"]:
            kind = light["type"]
            if kind == "directional":
                d = -np.asarray(light["direction"], float)
            elif kind in ("point", "area"):
                d = np.asarray(light["position"], float)
            elif kind == "environment" and scene.get("light_family") != "flash":
                return 180.0
            else:
                continue
            length = float(np.linalg.norm(d))
            if not (np.isfinite(length) and length > 0):  # read inside reading_record: one line naming the scene
                raise ValueError(f"a {kind} light's {'direction' if kind == 'directional' else 'position'} is "
                                 f"{d.tolist()}; expected a finite vector of non-zero length")
            worst = max(worst, float(np.degrees(np.arccos(np.clip(d[2] / length, -1, 1)))))
    return worst


def suite_rows(suite: Path, shifts: list[int]) -> list[dict]:
    """Every object folder of a rendered dataset, as rendered, and with its second half of images moved down by each
    of `shifts` px (np.roll: the background is dark)."""
    from scenes.folder.layouts import read_folder

    rows = []
    for folder in sorted(suite.glob("*.data")):
        fd = read_folder(folder)
        with reading_record(folder / "scene.json", "a scene.json wildgen.make writes", "render the suite again",
                            flag="--suite"):
            scene = read_json(folder / "scene.json")
            truth = true_max_polar(scene)
        expect = {"frontal_light"} if truth <= FRONTAL_TRUE_DEG else set()
        t0 = time.perf_counter()
        codes, facts = _raised(fd.images, fd.mask)
        case = f"{scene.get('light_family', '?')} (true {truth:.0f} deg)"
        rows.append(_row("rendered", f"{suite.name}/{fd.name}", "as made", f"all {len(fd.images)}", case, expect,
                         codes, facts, time.perf_counter() - t0))
        _print(rows[-1])
        for s in shifts:
            moved = fd.images.copy()
            moved[len(moved) // 2:] = np.roll(moved[len(moved) // 2:], s, axis=1)
            t0 = time.perf_counter()
            codes, facts = _raised(moved, fd.mask)
            rows.append(_row("rendered", f"{suite.name}/{fd.name}", "as made", f"all {len(fd.images)}",
                             f"second moved {s} px y", expect | {"camera_moved"}, codes, facts,
                             time.perf_counter() - t0))
            _print(rows[-1])
    return rows


@dataclass
class Options:
    """The command line of bench/bench_usable.py."""

    data: Annotated[Path, arg(metavar="DIR", help_behavior_hint="(default: ../shared/data/diligent)")] = DILIGENT
    """folder holding ballPNG/ and catPNG/"""
    suite: Annotated[list[Path], UseAppendAction, arg(metavar="DIR")] = field(default_factory=list)
    """a wildgen.make dataset"""
    suite_shifts: Annotated[list[int], comma_list(int, "N,N")] = option(default_factory=lambda: [2, 4], minimum=1)
    """also each rendered object with its second half moved by these px"""
    out: Annotated[Path | None, arg(metavar="FILE")] = None
    """write every row as JSON here"""
    objects: Annotated[list[str], CommaList] = field(default_factory=lambda: ["ball", "cat"])
    """DiLiGenT objects (folders NAMEPNG/ under --data, each refused when missing; '' for none)."""
    encodings: Annotated[list[str], CommaList] = option(
        default_factory=lambda: ["linear16", "jpeg"], choices=("linear16", "jpeg")
    )
    """How the photos are written before the check reads them."""
    subsets: Annotated[list[int], comma_list(int, "N,N")] = option(default_factory=lambda: [96, 48, 16, 8],
                                                                    minimum=MIN_IMAGES["photos"])
    """Numbers of images of the light subsets (at least 3: fewer do not determine a normal)."""
    shifts: Annotated[list[int], comma_list(int, "N,N")] = option(default_factory=lambda: [2, 3, 4, 6], minimum=1,
                                                                   maximum=MARGIN)
    """Camera shifts in px, applied to half of the images (at most the 8 px margin cut from each side)."""
    directions: Annotated[list[str], CommaList] = option(
        default_factory=lambda: list(DIRECTIONS), choices=tuple(DIRECTIONS)
    )
    """Directions of the shifts."""
    halves: Annotated[list[str], CommaList] = option(
        default_factory=lambda: ["alternate", "second"], choices=("alternate", "second")
    )
    """Which half of the images is moved: every second one (alternate) or the second half (second)."""
    frontal: Annotated[list[float], comma_list(float, "DEG,DEG")] = option(default_factory=lambda: [15.0, 10.0],
                                                                           minimum=1, maximum=90)
    """also the lights within these degrees of the viewing direction"""

    def validate(self) -> "Options":
        check_fields(self)
        if not any(self.objects) and not self.suite:  # an empty table would be written as a measurement
            raise UsageError("--objects: got '' and no --suite: nothing to measure; expected DiLiGenT objects "
                             "(--objects ball,cat) or a rendered dataset (--suite DIR)")
        return self


COMMAND = Command(Options, prog="python bench/bench_usable.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    folders = check_diligent(args.data, [f"{obj}PNG" for obj in args.objects])  # --objects '': none
    check_suites(args.suite)
    claim_result(args.out, ("rows",), COMMAND,  # the key of every result
                 inputs={f"--suite {d}": d for d in args.suite} | {"--data": args.data if any(args.objects) else None})
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for folder in folders:
            rows += diligent_rows(folder, args, Path(tmp))
    for suite in args.suite:
        rows += suite_rows(suite, args.suite_shifts)
    bad = [r for r in rows if not r["ok"]]
    print(f"{len(rows) - len(bad)} of {len(rows)} cases right")
    for key in ("camera_moved", "frontal_light"):
        want = [r for r in rows if key in r["expected"]]
        got = [r for r in want if key in r["raised"]]
        false = [r for r in rows if key not in r["expected"] and key in r["raised"]]
        print(f"{key}: raised on {len(got)} of {len(want)} cases that should, falsely on {len(false)} of "
              f"{len(rows) - len(want)}")
    if args.out:
        write_result(args.out, {"rows": rows}, indent=1, newline=True)
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
