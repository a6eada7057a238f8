"""How `validate.diagnosis.usable.mask_doubts` (the `doubtful_mask` warning of `orchestrate.capture --mask auto`)
reads good and wrong masks of rendered objects: where its thresholds come from.

    python bench/bench_doubtful_mask.py --suite DIR [--suite DIR ...] [--out FILE]

Each --suite is a `wildgen.make` dataset (its object folders' images and true mask.png); the module constants'
numbers were measured on five of them, 128 px (each with `--out DIR --assets ../shared/assets`):

    python -m wildgen.make --objects 6 --res 128 --images 12 --spp 16 --lights directional,point,near_area,hdri,mixed
    python -m wildgen.make --objects 16 --res 128 --images 12 --spp 16 --seed 7 --sensor phone
        --lights directional,point,near_area,hdri,mixed,flash,grid96,verse
    python -m wildgen.make --objects 8 --res 128 --images 12 --spp 16 --seed 11 --cluster 2-4 --materials any
        --lights directional,point,near_area,hdri,mixed
    python -m wildgen.make --objects 20 --res 128 --images 12 --spp 16 --seed 23 --sensor machine-vision
        --materials any --lights directional,point,grid96,near_area,mixed
    python -m wildgen.make --objects 12 --res 128 --images 16 --spp 16 --seed 31 --level 4
        --lights directional,point,grid96

Per object, the masks (a row each: its group, IoU with the true mask, the three measurements, whether it fires):

- `true`: the true mask; `auto`: `auto_mask`'s (good at IoU 0.9 or more with the true mask, wrong below 0.8);
- `grown`: the true mask dilated by 15, 30, 50 % of the object's equivalent radius; `shifted`: moved by 25 and 50 %
  of it, sideways and diagonally;
- a lit cushion under the object: a flat ellipse below the object's centre, behind it and off the frame's border
  ring, shaded per image by the light each image's outline says (`light_angles`), turned 0, 30 and 60 deg from the
  camera toward the top, albedo 0.4 and 0.8 of the object's bright level, a fixed fabric texture, with and without
  the object's cast shadow; on it the true mask (`cushion_true`), the true mask and the cushion
  (`cushion_union`), and `auto_mask`'s (`cushion_auto`, good and wrong as above).

Only objects on which `auto_mask` finds a mask count for the `true`, `grown`, `shifted` and `cushion_` rows made
from the true mask (where it refuses, the rule is never asked); `cushion_auto` rows count wherever it finds one.
"""
from __future__ import annotations

import sys
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # this tree's toolkit, not another checkout's installed one

from bench.cli_common import check_suites, claim_result, need_path, parse, refusals, run_main, write_result  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.needs import Needs  # noqa: E402
from scenes.cli.options import Command, UseAppendAction, arg, option  # noqa: E402
from scenes.files import read_figures, read_json, reading_record  # noqa: E402

GROWN = (0.15, 0.3, 0.5)
"""Dilations of the true mask, as fractions of the object's equivalent radius."""
SHIFTED = (0.25, 0.5)
"""Shifts of the true mask, as fractions of the object's equivalent radius (sideways, and diagonally)."""
CUSHIONS = [(tilt, albedo, shadow) for tilt in (0, 30, 60) for albedo in (0.4, 0.8) for shadow in (False, True)]
"""(turned from the camera toward the top in deg, albedo over the object's bright level, cast shadow) of the
painted cushions."""
GOOD_IOU, WRONG_IOU = 0.9, 0.8
"""An automatic mask is good at this IoU with the true mask or more, wrong below the second."""


def _disk(radius: float) -> np.ndarray:
    r = max(1, int(round(radius)))
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def with_cushion(images: np.ndarray, mask: np.ndarray, tilt_deg: float, albedo: float, shadow: bool,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(images, cushion region): the object in front of a lit flat cushion (module doc)."""
    from validate.diagnosis.usable import light_angles

    h, w = mask.shape
    rows, cols = np.nonzero(mask)
    r = np.sqrt(mask.sum() / np.pi)
    ii, jj = np.mgrid[0:h, 0:w]
    region = (((ii - rows.max() + 0.3 * r) / (0.9 * r)) ** 2 + ((jj - cols.mean()) / (1.9 * r)) ** 2 < 1) & ~mask
    b = max(1, round(0.03 * min(h, w))) + 1  # off auto_mask's border ring (a lit border makes it refuse)
    region[:b], region[-b:], region[:, :b], region[:, -b:] = False, False, False, False
    polar, azimuth = light_angles(images, mask)
    polar, azimuth = np.nan_to_num(np.radians(polar), nan=0.5), np.nan_to_num(np.radians(azimuth))
    lights = np.stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)], -1)
    t = np.radians(tilt_deg)
    shade = np.clip(lights @ np.array([0.0, np.sin(t), np.cos(t)]), 0, None)  # (K,)
    level = np.percentile(images[:, mask].mean(-1), 99)
    texture = 1 + 0.15 * cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0), 1.5)
    light = albedo * level * shade[:, None, None] * texture[None]
    if shadow:  # the object's own outline moved away from the light, longer for grazing light
        for k in range(len(images)):
            d = 0.6 * r * np.tan(min(polar[k], 1.3))
            dy, dx = int(round(d * np.sin(azimuth[k]))), int(round(-d * np.cos(azimuth[k])))
            light[k][np.roll(mask, (dy, dx), axis=(0, 1))] *= 0.1
    out = images.copy()
    out[:, region] = np.maximum(out[:, region], light[:, region][..., None] * np.array([0.9, 0.8, 0.7]))
    return out.astype(np.float32), region


def object_rows(folder: Path, rng: np.random.Generator, cushions: bool = True) -> list[dict]:
    """The rows of one rendered object (module doc)."""
    from unips.data import load_object
    from validate.diagnosis.usable import auto_mask, mask_doubts

    obj = load_object(folder)
    images, true = obj.images, obj.mask
    r = np.sqrt(true.sum() / np.pi)
    rows: list[dict] = []

    def add(group: str, kind: str, mask: np.ndarray, shown: np.ndarray = images) -> None:
        warning, facts = mask_doubts(shown, mask)
        rows.append({"object": f"{folder.parent.name}/{folder.name}", "lights": obj.light_family, "group": group,
                     "kind": kind, "iou_true": round(float((mask & true).sum() / (mask | true).sum()), 4), **facts})

    def add_auto(group: str, kind: str, shown: np.ndarray) -> bool:
        try:
            mask, _ = auto_mask(shown)
        except ValueError:
            rows.append({"object": f"{folder.parent.name}/{folder.name}", "lights": obj.light_family,
                         "group": f"{group}_refused", "kind": kind, "iou_true": None, "doubtful": None})
            return False
        iou = (mask & true).sum() / (mask | true).sum()
        add(f"{group}_{'good' if iou >= GOOD_IOU else 'wrong' if iou < WRONG_IOU else 'between'}", kind, mask, shown)
        return True

    if not add_auto("auto", "auto", images):
        found = False
    else:
        found = True
        add("true", "true", true)
        for f in GROWN:
            add("grown", f"grown {f}", cv2.dilate(true.astype(np.uint8), _disk(f * r)) > 0)
        for f in SHIFTED:
            add("shifted", f"shifted {f}", np.roll(true, int(round(f * r)), axis=1))
            add("shifted", f"shifted {f} diagonally", np.roll(true, (round(f * r * 0.7),) * 2, axis=(0, 1)))
    for tilt, albedo, shadow in CUSHIONS if cushions else ():
        shown, region = with_cushion(images, true, tilt, albedo, shadow, rng)
        kind = f"cushion {tilt} deg, albedo {albedo}{', shadow' if shadow else ''}"
        if found:
            add("cushion_true", kind, true, shown)
            add("cushion_union", kind, true | region, shown)
        add_auto("cushion_auto", kind, shown)
    return rows


def summary(rows: list[dict]) -> list[str]:
    """Per group: how many masks, how many the rule fires on, and min / median / max of each measurement."""
    groups: dict[str, list[dict]] = defaultdict(list)
    for row in rows:
        groups[row["group"]].append(row)
    keys = ("seed_agreement_iou", "varying_outside_share", "weak_inside_share")
    lines = [f"{'group':20s} {'masks':>5s} {'fires':>5s}  " + "  ".join(f"{k + ' min/med/max':>34s}" for k in keys)]
    for name in sorted(groups):
        rs = groups[name]
        if name.endswith("_refused"):
            lines.append(f"{name:20s} {len(rs):5d}")
            continue
        cells = []
        for k in keys:
            v = np.array([r[k] for r in rs])
            cells.append(f"{v.min():.3f} / {np.median(v):.3f} / {v.max():.3f}".rjust(34))
        lines.append(f"{name:20s} {len(rs):5d} {sum(r['doubtful'] for r in rs):5d}  " + "  ".join(cells))
    return lines


@dataclass
class Options:
    """The command line of bench/bench_doubtful_mask.py."""

    suite: Annotated[list[Path], arg(metavar="DIR"), UseAppendAction] = field(default_factory=list)
    """a wildgen.make dataset (repeatable)"""
    out: Annotated[Path | None, arg(metavar="FILE")] = None
    """write every row as JSON here"""
    seed: int = option(0, minimum=0)
    """seed of the cushions' fabric texture"""
    cushions: bool = True
    """also paint lit cushions under each object (module doc); off for suites rendered with `--floor`, whose
    surfaces are rendered"""
    record: Annotated[Path | None, arg(metavar="FILE")] = None
    """add the automatic masks' counts to FILE (bench/results/doubtful_mask.json, docs/capture.md's table) as the
    run of these suites, replacing an earlier run of the same suites and cushions"""
    rows_from: Annotated[Path | None, arg(metavar="FILE")] = None
    """read the rows of an earlier run's --out instead of measuring (with --record: its table, unmeasured again)"""


COMMAND = Command(Options, prog="python bench/bench_doubtful_mask.py", description=__doc__.split("\n\n")[0],
                  needs=(Needs("rows_from", lambda _, given: "suite" not in given,
                               "without --suite (its rows are read from FILE, nothing is measured)"),
                         *(Needs(f, lambda _, given: "rows_from" not in given, "without --rows-from (nothing is "
                                 "measured: the rows say whether cushions were painted)")
                           for f in ("seed", "cushions"))))
RESULT_KEYS = ("rows",)
"""The key of every result (--out, read back by --rows-from): a file without it is not this bench's."""
RECORD_KEYS = ("good_iou", "rows")
"""The keys of the record (--record): a file without them is not this bench's and is never replaced."""


def automatic_run(rows: list[dict]) -> dict:
    """One run's record (`--record`): its suites, whether cushions were painted, the automatic masks' counts (refused,
    good, good but doubted, below GOOD_IOU doubted or silent) and the silent ones."""
    auto = [r for r in rows if r["kind"] == "auto" or r["group"].startswith("cushion_auto")]
    found = [r for r in auto if r["iou_true"] is not None]
    silent = [r for r in found if r["iou_true"] < GOOD_IOU and not r["doubtful"]]
    return {"suites": sorted({r["object"].split("/")[0] for r in rows}),
            "cushions": any(r["group"].startswith("cushion_") for r in rows),
            "masks": len(auto), "refused": len(auto) - len(found),
            "good": sum(r["iou_true"] >= GOOD_IOU for r in found),
            "good_doubted": sum(r["iou_true"] >= GOOD_IOU and bool(r["doubtful"]) for r in found),
            "below_doubted": sum(r["iou_true"] < GOOD_IOU and bool(r["doubtful"]) for r in found),
            "below_silent": len(silent),
            "silent": [{"object": r["object"], "kind": r["kind"], "iou": r["iou_true"]} for r in silent]}


def _recorded_runs(path: Path) -> list[dict]:
    """The runs a --record file holds (none where there is no file yet), each an object with its suites and
    cushions; a ValueError naming the file otherwise, before any measurement."""
    if not path.is_file():
        return []
    with reading_record(path, "a record of this bench (--record)", flag="--record"):
        runs = read_json(path)["rows"]
        if not isinstance(runs, list) or not all(isinstance(r, dict) and "suites" in r and "cushions" in r
                                                 for r in runs):
            raise ValueError("its rows are not a list of runs, each with its suites and cushions")
        return runs


def record_run(path: Path, run: dict) -> None:
    """Add `run` to the results file `path`, replacing a run of the same suites and cushions."""
    runs = [r for r in _recorded_runs(path) if (r["suites"], r["cushions"]) != (run["suites"], run["cushions"])]
    runs.append(run)
    write_result(path, {"good_iou": GOOD_IOU, "rows": runs}, indent=1, newline=True)


ROW_KEYS = ("kind", "group", "object", "iou_true", "doubtful", "seed_agreement_iou", "weak_inside_share",
            "varying_outside_share")
"""The keys of every row this bench measures (what the summary and the record read)."""


def _earlier_rows(path: Path) -> list[dict]:
    """The rows of an earlier run's --out (--rows-from), each an object with `ROW_KEYS`, IoU a number or None; a
    ValueError naming the file otherwise (the summary would end in a traceback, or count a text as a figure)."""
    with reading_record(path, "an earlier run's --out", flag="--rows-from"):
        rows = read_figures(path)["rows"]
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise ValueError("its rows are not a list of objects")
        for r in rows:
            if missing := [k for k in ROW_KEYS if k not in r]:
                raise KeyError(missing[0])
            if not all(isinstance(r[k], str) for k in ("kind", "group", "object")):
                raise ValueError(f"a row's kind, group and object are {r['kind']!r}, {r['group']!r}, "
                                 f"{r['object']!r}; expected texts")
            if r["iou_true"] is not None and not isinstance(r["iou_true"], (int, float)):
                raise ValueError(f"a row's iou_true is {r['iou_true']!r}; expected a number or null")
            summary([r])  # every figure the summary reads is of its kind
        return rows


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    if args.rows_from is not None:
        from bench.cli_common import unreadable
        from scenes.cli.outputs import holds_keys

        earlier = "an earlier run's --out (a JSON object with rows)"
        need_path(args.rows_from, "--rows-from", earlier, folder=False)
        with refusals():
            if not holds_keys(args.rows_from, RESULT_KEYS):
                why = unreadable(args.rows_from)
                raise UsageError(f"--rows-from: got {str(args.rows_from)!r}, expected {earlier}"
                                 + (f" ({why})" if why else ""))
    else:
        with refusals():
            if not args.suite:  # checked here, not in validate: the docs quote --record alone
                raise UsageError("--suite: nothing to measure: expected --suite DIR (a wildgen.make dataset) or "
                                 "--rows-from FILE")
        check_suites(args.suite)
    claim_result(args.out, RESULT_KEYS, COMMAND, inputs={f"--suite {d}": d for d in args.suite})
    # the record is signed apart from --out's rows (both hold 'rows'): neither is ever taken for the other
    if claim_result(args.record, RECORD_KEYS, f"{COMMAND.prog} --record", "--record"):
        _recorded_runs(args.record)  # read now, not after the measurement
    rng = np.random.default_rng(args.seed)
    rows: list[dict] = _earlier_rows(args.rows_from) if args.rows_from else []
    for suite in [] if args.rows_from else args.suite:
        for folder in sorted(Path(suite).glob("*.data")):
            rows += object_rows(folder, rng, args.cushions)
    print("\n".join(summary(rows)) if rows else "no object folders (give --suite DIR)")
    auto = [r for r in rows if r["kind"] == "auto" or r["group"].startswith("cushion_auto")]
    silent = [r for r in auto if r["iou_true"] is not None and r["iou_true"] < GOOD_IOU and not r["doubtful"]]
    print(f"automatic masks: {len(auto)}; refused {sum(r['iou_true'] is None for r in auto)}, good (IoU >= "
          f"{GOOD_IOU}) {sum(r['iou_true'] is not None and r['iou_true'] >= GOOD_IOU for r in auto)}, flagged below it "
          f"{sum(r['iou_true'] is not None and r['iou_true'] < GOOD_IOU and bool(r['doubtful']) for r in auto)}, "
          f"silent below it {len(silent)}")
    for r in silent:
        print(f"silent: {r['object']} {r['kind']}: IoU {r['iou_true']}, seed agreement {r['seed_agreement_iou']}, "
              f"weak inside {r['weak_inside_share']}, varying outside {r['varying_outside_share']}")
    for row in rows:
        if row["doubtful"] and row["group"] in ("auto_good", "cushion_auto_good", "true"):
            print(f"fires on a good mask: {row['object']} {row['kind']}: seed agreement {row['seed_agreement_iou']}, "
                  f"weak inside {row['weak_inside_share']}, varying outside {row['varying_outside_share']}")
    if args.out:
        write_result(args.out, {"rows": rows}, indent=1, newline=True)
    if args.record and rows:
        record_run(args.record, automatic_run(rows))
        print(f"recorded in {args.record}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
