"""Learning curves of training runs: probes and photometric gain against steps and hours.

Reads the validation records of each run's `log.jsonl` (written by `unips.train` at every
validation) and prints one Markdown table per run: step, hours since the run started, error with
all images / one image / the mask only / shuffled observations, and the photometric gain
(mask only - all images), then the same per light family for the last validation. Usage:

    python bench/learning_curve.py RUN [RUN ...] [--families]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def validations(run: Path) -> list[dict]:
    """The validation records of a run folder, in step order."""
    log = run / "log.jsonl"
    if not log.is_file():
        raise FileNotFoundError(f"RUN: {str(run)!r} has no log.jsonl (expected a unips.train run folder)")
    out = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    return sorted((r for r in out if "val" in r), key=lambda r: r["step"])


def _cell(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def table(run: Path, families: bool = False) -> str:
    rows = validations(run)
    lines = [f"{run}", "", "| step | hours | all images | one image | mask only | shuffled | photometric gain |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        v, p = r["val"], r["val"].get("probes", {})
        lines.append(f"| {r['step']} | {v.get('elapsed_s', 0) / 3600:.2f} | {_cell(p.get('all'))} | "
                     f"{_cell(p.get('one'))} | {_cell(p.get('mask'))} | {_cell(p.get('shuffled'))} | "
                     f"{_cell(v.get('gain'))} |")
    if families and rows:
        from unips.probes import format_table

        last = rows[-1]["val"]  # unips.train.validate renames summarise's "mean" dict to "probes"
        lines += ["", f"per family at step {rows[-1]['step']}:", "", format_table({**last, "mean": last["probes"]})]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+", type=Path, help="unips.train run folders")
    p.add_argument("--families", action="store_true", help="also the per-family probes of the last validation")
    args = p.parse_args(argv)
    try:
        for run in args.runs:
            print(table(run, args.families), end="\n\n")
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
