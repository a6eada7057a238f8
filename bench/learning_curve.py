"""Learning curves of training runs: probes and photometric gain against steps and hours.

Reads the validation records of each run's `log.jsonl` (written by `unips.train` at every
validation) and prints one Markdown table per run: step, hours since the run started, error with
all images / one image / the mask only / shuffled observations, and the photometric gain
(mask only - all images), then the same per light family for the last validation. With `--card`, the
curve across the stages of the shipped model's lineage instead (`unips/weights/model_card.json`): the
fixed-validation error of each shipped stage, overall and per family, against the cumulative CPU hours and
steps that produced it, a least-squares fit error = a - b * log2(hours) per family over the stages at 128 px
(fine-tune 1 on), and the hours at which that trend would reach `--target` on the test set (the target
shifted by the shipped model's test - validation difference of the family). An extrapolation of a trend,
not a measurement: it says how far the remaining gap is at the rate measured so far. Usage:

    python bench/learning_curve.py RUN [RUN ...] [--families]
    python bench/learning_curve.py --card unips/weights/model_card.json [--target 15]
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import parse, run_main  # noqa: E402
from scenes.cli.needs import Needs  # noqa: E402
from scenes.cli.options import Command, Positional, arg, option  # noqa: E402
from scenes.files import read_figures, read_text_file, reading_record  # noqa: E402

LOG = "a unips.train log (one JSON object per line, each with its step)"
CARD = "a model card (a JSON object whose lineage is a list of stages, e.g. unips/weights/model_card.json)"


def validations(run: Path) -> list[dict]:
    """The validation records of a run folder, in step order."""
    log = run / "log.jsonl"
    if not log.is_file():
        raise FileNotFoundError(f"RUN: {str(run)!r} has no log.jsonl (expected a unips.train run folder)")
    with reading_record(log, LOG, flag="RUN"):
        out = [json.loads(line) for line in read_text_file(log).splitlines() if line.strip()]
        return sorted((r for r in out if "val" in r), key=lambda r: r["step"])


def _cell(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def table(run: Path, families: bool = False) -> str:
    from scenes.report.tables import markdown_table
    from unips.probes import PROBE_TITLES, format_table

    rows = validations(run)
    if not rows:  # an empty table would read as a curve of nothing
        raise ValueError(f"RUN: {str(run / 'log.jsonl')!r} holds no validation record (the run stopped before its "
                         "first validation, or ran without --val); expected a run that validated at least once")
    with reading_record(run / "log.jsonl", LOG, flag="RUN"):
        body = [
            [
                r["step"],
                f"{r['val'].get('elapsed_s', 0) / 3600:.2f}",
                *(_cell(r["val"].get("probes", {}).get(k)) for k in PROBE_TITLES),
                _cell(r["val"].get("gain")),
            ]
            for r in rows
        ]
        lines = [f"{run}", "", markdown_table(["step", "hours", *PROBE_TITLES.values(), "photometric gain"], body)]
        if families and rows:
            last = rows[-1]["val"]  # unips.train_data.probe_samples renames summarise's "mean" dict to "probes"
            lines += ["", f"per family at step {rows[-1]['step']}:", "", format_table({**last, "mean": last["probes"]})]
    return "\n".join(lines)


def read_card(path: Path) -> dict:
    """The model card at `path` (--card); FileNotFoundError / ValueError naming --card when it is none."""
    if not path.is_file():
        raise FileNotFoundError(f"--card: {str(path)!r} is not a file; expected {CARD}")
    try:
        card = read_figures(path)  # NaN or a figure past a float's range is no figure of a card
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise ValueError(f"--card: got {str(path)!r}, expected {CARD}: it is not JSON ({exc})") from None
    lineage = card.get("lineage") if isinstance(card, dict) else None
    if not isinstance(lineage, list) or not all(isinstance(s, dict) and isinstance(s.get("stage"), str)
                                                for s in lineage):
        raise ValueError(f"--card: got {str(path)!r}, expected {CARD}")
    return card


def shipped_chain(card: dict) -> list[dict]:
    """The lineage stages that produced the shipped weights, in order (runs marked 'not shipped' left out:
    their hours did not go into the shipped model)."""
    return [s for s in card.get("lineage", []) if "not shipped" not in s["stage"]]


def _stage_result(s: dict) -> tuple[float | None, float | None]:
    """(all images, gain) of a stage at its best step."""
    if s.get("curve"):
        best = s.get("best_step", s["curve"][-1]["step"])
        row = next((c for c in s["curve"] if c["step"] == best), s["curve"][-1])
        return row.get("all"), row.get("gain")
    fv = s.get("fixed_validation") or {}
    return fv.get("all"), fv.get("gain")


def fit_log2(hours: list[float], errors: list[float]) -> tuple[float, float]:
    """(a, b) of the least-squares line error = a - b * log2(hours)."""
    import numpy as np

    x = np.log2(np.asarray(hours, float))
    slope, intercept = np.polyfit(x, np.asarray(errors, float), 1)
    return float(intercept), float(-slope)


def card_table(card: dict, target: float) -> str:
    from scenes.report.tables import markdown_table

    chain = shipped_chain(card)
    if not chain:
        raise ValueError("--card: the model card has no lineage")
    fams = sorted({f for s in chain for f in s.get("per_family_at_best", {})})
    stages = []
    hours = steps = 0.0
    pts: dict[str, list[tuple[float, float]]] = {f: [] for f in fams + ["all"]}
    for s in chain:
        stage_hours = s.get("hours") if s.get("hours") is not None else 0.0  # unrecorded (a relay run): none counted
        if not isinstance(stage_hours, (int, float)) or stage_hours < 0:
            raise ValueError(f"stage {s['stage']!r}: hours {stage_hours!r}; expected a number >= 0")
        hours += stage_hours
        steps += s.get("steps") or 0
        a, g = _stage_result(s)
        pf = s.get("per_family_at_best", {})
        stages.append([s["stage"], s.get("steps") or 0, int(steps), f"{hours:.2f}", _cell(a), _cell(g),
                       *(_cell(pf.get(f, {}).get("all")) for f in fams)])
        if pf:  # the 128 px stages (the original trained at 64 px and has no per-family record)
            pts["all"].append((hours, a))
            for f in fams:
                pts[f].append((hours, pf[f]["all"]))
    test = card.get("test_set_deg") or {}
    val = {**(card.get("validation_per_family_deg") or {}), "all": card.get("validation_mean_deg")}
    trends = []
    out = [markdown_table(["stage", "steps", "cumulative steps", "cumulative hours", "all images", "photometric gain",
                           *fams], stages), "",
           f"trend error = a - b * log2(cumulative hours), fitted over the {len(pts['all'])} stages with per-family "
           f"records; hours at which it reaches {target:g} deg on the test set (the target shifted by the family's "
           "test - validation difference of the shipped model):", ""]
    for f in fams + ["all"]:
        pts[f] = [(h, e) for h, e in pts[f] if h > 0]  # log2 of no hours is no point of the trend
        if len({h for h, _ in pts[f]}) < 3:  # a line through fewer distinct hours is no trend
            continue
        h, e = zip(*pts[f])
        a, b = fit_log2(list(h), list(e))
        t_now, v_now = test.get(f), e[-1]
        # The target moved by the shipped model's test - validation difference (none when either is missing).
        need = target - (t_now - val[f] if t_now is not None and val.get(f) is not None else 0.0)
        if v_now <= need:
            hrs, ratio = "reached", "-"
        elif b <= 0:
            hrs, ratio = "never (no decrease)", "-"
        elif (a - need) / b > 60:  # over 2^60 hours: a slope this flat reaches the target never in practice
            hrs, ratio = "over 1e18", "-"
        else:
            hn = 2 ** ((a - need) / b)
            hrs, ratio = f"{hn:.0f}", f"{hn / h[-1]:.0f}"
        trends.append([f, f"{a:.2f}", f"{b:.2f}", f"{v_now:.2f}", _cell(t_now), f"{need:.2f}", hrs, ratio])
    out.append(markdown_table(["family", "a", "b (deg per doubling of hours)", "validation now", "test now",
                               "validation needed", "hours needed", "x hours so far"], trends))
    return "\n".join(out)


@dataclass
class Options:
    """The command line of bench/learning_curve.py."""

    runs: Positional[Annotated[list[Path], arg(metavar="RUN")]] = field(default_factory=list)
    """unips.train run folders"""
    families: bool = False
    """also the per-family probes of the last validation"""
    card: Annotated[Path | None, arg(metavar="CARD")] = None
    """a model card: the curve across its lineage's shipped stages"""
    target: float = option(15.0, above=0, below=180)
    """test-set error (deg) the --card trend is extrapolated to"""


COMMAND = Command(Options, prog="python bench/learning_curve.py", description=__doc__.split("\n\n")[0],
                  needs=(Needs("target", lambda c, _: c.card is not None, "with --card"),
                         Needs("families", lambda c, _: bool(c.runs), "with RUN folders (their last validation)")))


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    try:
        if not args.runs and args.card is None:
            raise ValueError("expected RUN folders or --card CARD")
        if args.card is not None:
            card = read_card(args.card)
            with reading_record(args.card, CARD, "give the card as unips.train's runs record it", "--card"):
                text = card_table(card, args.target)
            print(text, end="\n\n")
        for run in args.runs:
            print(table(run, args.families), end="\n\n")
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
