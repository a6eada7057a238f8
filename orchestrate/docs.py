"""Regenerate the generated blocks of README.md and docs/*.md from the code and the model card.

    python -m orchestrate.docs            rewrite every generated block in place
    python -m orchestrate.docs --check    change nothing; exit 1 when a file is out of date (names it)

A generated block lies between two markers, NAME being one of `BLOCKS` or `flags:MODULE`:

    <!-- BEGIN generated:NAME -->
    ...
    <!-- END generated:NAME -->

Flag tables come from each CLI's `COMMAND` (tyro's argparse form of its command line), imported at run time
(so a changed config changes the docs on the next run); result tables come from
`unips/weights/model_card.json`, the record of the shipped model. Everything outside the markers is written by
hand and left alone.
"""
from __future__ import annotations

import importlib
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from orchestrate.bench_docs import BENCH_BLOCKS, BENCH_TABLES
from scenes.cli.errors import UsageError, report_error
from scenes.cli.options import Command
from scenes.files import atomic_write_text, not_a_file, read_text_file, reading_record
from scenes.report.tables import markdown_table

REPO = Path(__file__).resolve().parents[1]
CARD = REPO / "unips" / "weights" / "model_card.json"

# Every command-line entry point of the packages, in the order a reader meets them. Each module has a
# `COMMAND` (`scenes.cli.options.Command`); each needs a `flags:MODULE` block somewhere in the docs (checked).
CLIS = (
    "wildgen.make", "wildgen.preview", "wildgen.sensor", "wildgen.export",
    "unips.train", "unips.predict", "unips.evaluate", "validate.rerender", "validate.refine",
    "orchestrate.demo", "orchestrate.benchmark", "orchestrate.train_recipe", "orchestrate.gpu_session",
    "orchestrate.ship", "orchestrate.error_calibration", "orchestrate.capture", "orchestrate.surface",
    "orchestrate.docs",
)

BEGIN = re.compile(r"^<!-- BEGIN generated:(?P<name>[\w.:-]+) -->$")
END = "<!-- END generated:{name} -->"
STRAY_END = re.compile(r"^<!-- END generated:")

# ---------------------------------------------------------------- flag tables


def _cell(text: str) -> str:
    """One table cell: pipes escaped, words holding `<...>` or `*` in backticks (Markdown would eat them)."""
    words = []
    for word in str(text).split():
        if ("<" in word or "*" in word) and "`" not in word and len(word) > 1:
            core = word.strip("(),;:").rstrip(".")  # a sentence's full stop stays outside the code span
            if core:
                start = word.index(core)
                word = f"{word[:start]}`{core}`{word[start + len(core):]}"
        words.append(word)
    return " ".join(words).replace("|", "\\|")


def flag_table(module: str) -> str:
    """The flag table(s) of `module`'s command line: its own options, then one table per nested config."""
    cli = importlib.import_module(module)
    if not isinstance(getattr(cli, "COMMAND", None), Command):
        raise UsageError(f"generated:flags:{module}: {module} has no COMMAND (scenes.cli.options.Command)")
    groups: dict[str, list] = {}
    for flag in cli.COMMAND.options():
        groups.setdefault(flag.group, []).append(flag)
    out: list[str] = []
    for group, flags in groups.items():
        if group:
            out += ["", f"{group.replace('_', ' ').capitalize()} options:", ""]
        rows = [[f"`{f.invocation.replace('{None}|', '')}`", f"`{f.default}`", _cell(f.meaning)] for f in flags]
        out.append(markdown_table(["flag", "default", "meaning"], rows))
    return "\n".join(out)


# ---------------------------------------------------------------- result tables (from the model card)


def fmt(value: Any, digits: int = 1) -> str:
    """A card number as the tables show it: `digits` decimals, '-' where the card has none."""
    if value is None:
        return "-"
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    return f"{value:.{digits}f}"


def _families(card: dict, block: dict) -> list[str]:
    """The light families of a card block, in the order of the card's test-set table (the benchmark's
    order), then any other family of the block by name: none dropped, none listed here."""
    order = [f for f in card["test_set"]["mean_deg"]["model"] if f != "all"]
    names = [k for k in block if k != "all"]
    return [f for f in order if f in names] + sorted(f for f in names if f not in order)


def _ball_cat(d: dict, key: str) -> Any:
    """A DiLiGenT figure, with two decimals where the card records them."""
    return d.get(key + "_2dp", d.get(key))


def readme_headline(card: dict) -> str:
    test, dil = card["test_set"], card["diligent"]
    model = test["mean_deg"]["model"]
    ls = test["mean_deg"].get("least squares (calibrated)", {})
    probes = test["per_family_probes"]
    rows = [
        [f"synthetic test set, all {sum(p['n'] for p in probes.values())} objects", fmt(model["all"]), "-", "-"],
        [
            f"synthetic test set, its {probes['directional']['n']} directional-light objects",
            fmt(model["directional"]),
            fmt(ls.get("directional")),
            "-",
        ],
    ]
    for obj in ("ball", "cat"):
        o = dil[obj]
        rows.append([f"DiLiGenT {obj} ({o['images']} images)", fmt(_ball_cat(o, "model_deg"), 2),
                     fmt(o["least_squares_calibrated_deg"]), fmt(o["published_unips_deg"])])
    return markdown_table(
        ["mean angular error, degrees (lower is better)", "this model", "calibrated least squares", "published UniPS"],
        rows,
    )


def test_set_methods(card: dict) -> str:
    mean = card["test_set"]["mean_deg"]
    fams = _families(card, mean["model"])
    rows = [[name, *(fmt(v.get(f)) for f in fams), fmt(v.get("all"))] for name, v in mean.items()]
    n = card["test_set"]["per_family_probes"]
    header = ["method", *(f"{f} ({n[f]['n']})" if f in n else f for f in fams), "all"]
    return markdown_table(header, rows)


def test_set_probes(card: dict) -> str:
    test = card["test_set"]
    return _probe_table(card, test["per_family_probes"], test["probes_deg"], test["photometric_gain_deg"])


def validation_probes(card: dict) -> str:
    v = card["probes_fixed_validation"]
    return _probe_table(card, v["per_family"], v["probes_deg"], v["photometric_gain_deg"])


def _probe_table(card: dict, per_family: dict, overall: dict, gain: float) -> str:
    rows = [[f, str(p["n"]), fmt(p["all"]), fmt(p["one"]), fmt(p["mask"]), fmt(p["shuffled"]), fmt(p["gain"])]
            for f, p in ((f, per_family[f]) for f in _families(card, per_family))]
    rows.append(["all", str(sum(p["n"] for p in per_family.values())), fmt(overall["all"]), fmt(overall["one"]),
                 fmt(overall["mask"]), fmt(overall["shuffled"]), fmt(gain)])
    return markdown_table(
        ["family", "objects", "all images", "one image", "mask only", "shuffled", "photometric gain"], rows
    )


def image_count(card: dict) -> str:
    test = card["test_set"]
    counts = [k for k in next(iter(test["vs_image_count_deg"].values()))
              if any(v.get(k) is not None for v in test["vs_image_count_deg"].values())]
    rows = [[name, *(fmt(v.get(k)) for k in counts), fmt(test["mean_deg"].get(name, {}).get("all"))]
            for name, v in test["vs_image_count_deg"].items()]
    return markdown_table(["method", *(f"K={k}" for k in counts), "all images"], rows)


def diligent(card: dict) -> str:
    d = card["diligent"]
    rows = []
    for obj in ("ball", "cat"):
        o = d[obj]
        rows.append(
            [
                obj,
                str(o["images"]),
                fmt(_ball_cat(o, "model_deg"), 2),
                fmt(o["model_k16_mean_deg"]),
                fmt(o["model_mask_only_deg"]),
                fmt(o["model_seconds"]),
                fmt(o["least_squares_calibrated_deg"]),
                fmt(o["published_l2_deg"], 2),
                fmt(o["published_unips_deg"]),
            ]
        )
    return markdown_table(
        [
            "object",
            "images",
            "this model",
            "this model, 16 images",
            "mask only",
            "seconds",
            "calibrated least squares",
            "published least squares",
            "published UniPS",
        ],
        rows,
    )


def model_facts(card: dict) -> str:
    t = card["training"]
    rows = [
        ["model", f"`{card['model']}` ({card['parameters']:,} parameters), `{card['weights']}`"],
        ["training data", f"{card['train_objects']} rendered objects (see the lineage below)"],
        ["steps in all", f"{card['steps']} (last stage {t['steps']}, weights of its step {card['best_step']})"],
        ["training time in all", f"{card['wall_time_s'] / 3600:.2f} h on {card['hardware']}"],
        ["fixed validation set", f"{fmt(card['validation_mean_deg'], 2)} deg mean angular error"],
        [
            "held-out test set",
            f"{fmt(card['test_set']['mean_deg']['model']['all'])} deg, photometric gain "
            f"{fmt(card['test_set']['photometric_gain_deg'])} deg ({card['test_set']['views']} views)",
        ],
    ]
    return markdown_table(["", "shipped model"], rows)


def model_inputs(card: dict) -> str:
    """Each registered model's data contract, read from its registry entry (`unips.models.input_contract`)."""
    from unips.models import DEFAULT_MODEL, DEFAULT_TRAIN_MODEL, input_contract, list_models

    def px(v: int | None, none: str) -> str:
        return none if v is None else f"{v} px"

    rows = [[f"`{n}`" + {DEFAULT_MODEL: " (predict)", DEFAULT_TRAIN_MODEL: " (train)"}.get(n, ""), c.preprocess,
             f"{c.margin} px", px(c.side, "the crop's" if c.preprocess == "unips" else "512 x n"),
             str(c.max_images or "all"), str(c.views), px(c.patch, "-"), px(c.train_resolution, "-")]
            for n in list_models() for c in [input_contract(n)]]
    return markdown_table(["model (default for)", "preprocessing", "crop margin", "working side", "images",
                           "views", "--scalable", "trained at"], rows)


def _at_best(stage: dict) -> dict:
    """A lineage stage's fixed-validation probes at its best step."""
    if "fixed_validation" in stage:
        return stage["fixed_validation"]
    return next((c for c in stage.get("curve", []) if c["step"] == stage.get("best_step")), {})


def lineage(card: dict) -> str:
    rows = []
    for stage in card["lineage"]:
        fv = _at_best(stage)
        shipped = "no" if stage.get("shipped") is False or "not shipped" in stage["stage"] else "yes"
        rows.append(
            [
                _cell(stage["stage"]),
                _cell(stage.get("init_from") or "random"),
                str(stage["steps"]),
                fmt(stage.get("hours"), 2),
                fmt(fv.get("all"), 2),
                fmt(fv.get("gain"), 2),
                shipped,
                _cell(stage["data"]),
            ]
        )
    return markdown_table(
        ["stage", "started from", "steps", "hours", "validation: all images", "photometric gain", "shipped", "data"],
        rows,
    )


def lineage_families(card: dict) -> str:
    stages = [s for s in card["lineage"] if s.get("per_family_at_best")]
    fams = _families(card, {f: None for s in stages for f in s["per_family_at_best"]})
    rows = [[_cell(s["stage"]), *(fmt(s["per_family_at_best"].get(f, {}).get("all"), 2) for f in fams)] for s in stages]
    return markdown_table(["stage", *fams], rows)


def sensor_presets(card: dict) -> str:
    """The table of camera sensor presets, from `scenes.camera_sensor.SENSORS` (the card is not used)."""
    from scenes.camera_sensor import SENSORS

    rows = []
    for s in SENSORS.values():
        depth = f"{s.bits} in 16" if s.bits == 12 else str(s.bits)
        rows.append(
            [f"`{s.name}`", s.about, f"{depth}-bit {s.response}" + (f" {s.gamma:g}" if s.response == "gamma" else "")]
        )
    return markdown_table(["preset", "imitates", "file"], rows)


def capture_presets(card: dict) -> str:
    """The table of capture presets, from `wildgen.presets.PRESETS` (the card is not used)."""
    from wildgen.presets import PRESETS

    rows = [[f"`{name}`", p.about, ", ".join(f"`{f}`" for f in p.config.lights),
             f"{p.config.images} images of {p.config.width} x {p.config.height} px", p.config.camera,
             f"`{p.config.sensor}`"] for name, p in PRESETS.items()]
    return markdown_table(["preset", "imitates", "lights", "images", "camera", "sensor"], rows)


def complexity_levels(card: dict) -> str:
    """The table of complexity levels, from `wildgen.levels.LEVELS` (the card is not used)."""
    from wildgen.levels import LEVELS

    rows = [[str(n), lv.about, ", ".join(f"`{f}`" for f in lv.config.lights), lv.config.materials,
             f"{lv.config.shapes} ({', '.join(lv.config.shape_kinds)})", f"{lv.config.detail:.0%}",
             lv.config.cluster or "1"] for n, lv in LEVELS.items()]
    return markdown_table(
        ["level", "scenes", "lights", "materials", "shapes (procedural kinds)", "detail", "objects"], rows
    )


def data_ab(card: dict) -> str:
    """The fixed-budget A/B of the training data (`bench/ab_data.py --record`, card entry `data_ab`)."""
    ab = card.get("data_ab")
    if not ab:
        return "No A/B of the training data is recorded in the model card."
    rows = []
    for name, r in ab["results"].items():
        fv, (l4, l5), d = r["fixed_validation"], r["new_kinds"], r["diligent"]
        arm, _, lr = name.partition("_lr")
        label = "shipped weights" if name == "shipped" else f"`{arm}`, lr {lr or '1.5e-4'}"
        rows.append(
            [
                label,
                fmt(fv["mean_deg"], 2),
                fmt(fv["gain_deg"], 2),
                fmt(l4["mean_deg"], 2),
                fmt(l5["mean_deg"], 2),
                fmt(d["ball"]["k96_deg"], 2),
                fmt(d["ball"]["k16_deg"], 2),
                fmt(d["cat"]["k96_deg"], 2),
                fmt(d["cat"]["k16_deg"], 2),
            ]
        )
    return markdown_table(
        [
            "model",
            "fixed validation",
            "photometric gain",
            "held-out level 4",
            "held-out level 5 (perspective)",
            "ball K=96",
            "ball K=16",
            "cat K=96",
            "cat K=16",
        ],
        rows,
    )


# Generated blocks other than flag tables: name -> renderer of the model card.
# Blocks from a benchmark's output (BENCH_BLOCKS, orchestrate.bench_docs) are in it too.
BLOCKS: dict[str, Callable[[dict], str]] = {
    "readme:headline": readme_headline,
    "model:facts": model_facts,
    "model:inputs": model_inputs,
    "results:test-set-methods": test_set_methods,
    "results:test-set-probes": test_set_probes,
    "results:image-count": image_count,
    "results:diligent": diligent,
    "results:validation-probes": validation_probes,
    "results:lineage": lineage,
    "results:lineage-families": lineage_families,
    "generator:sensors": sensor_presets,
    "generator:presets": capture_presets,
    "generator:levels": complexity_levels,
    "model:data-ab": data_ab,
    **{name: table for name, (_, table) in BENCH_TABLES.items()},
}


def render(name: str, card: dict, card_path: Path | None = None) -> str:
    """The block `name`: a flag table, or a result table from the model card (`card`, read from `card_path`) or a
    bench's output (`BENCH_BLOCKS`); a record of another shape is a ValueError naming its file."""
    if name.startswith("flags:"):
        module = name.removeprefix("flags:")
        if module not in CLIS:
            raise UsageError(f"generated:{name}: unknown CLI {module!r}, expected one of {', '.join(CLIS)}")
        return flag_table(module)
    if name not in BLOCKS:
        raise UsageError(f"generated:{name}: unknown block, expected flags:MODULE or one of {', '.join(BLOCKS)}")
    if name in BENCH_BLOCKS and not BENCH_BLOCKS[name].is_file():
        raise UsageError(f"generated:{name}: {BENCH_BLOCKS[name]} does not exist: run the benchmark that writes it")
    source, what, fix = ((BENCH_BLOCKS[name], "the output of its benchmark", "run the benchmark again")
                         if name in BENCH_BLOCKS else (card_path or CARD, "a model card", "restore it (git checkout)"))
    with reading_record(source, what, fix):
        return BLOCKS[name](card)


# ---------------------------------------------------------------- files


def doc_files(root: Path = REPO) -> list[Path]:
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


def regenerate(text: str, card: dict, where: str = "", card_path: Path | None = None) -> tuple[str, list[str]]:
    """`text` with every generated block rewritten, and the names of its blocks (markers inside fenced code
    blocks are examples, not blocks)."""
    lines = text.split("\n")
    out: list[str] = []
    names: list[str] = []
    fenced = False
    i = 0
    while i < len(lines):
        out.append(lines[i])
        if lines[i].lstrip().startswith("```"):
            fenced = not fenced
        m = None if fenced else BEGIN.match(lines[i].strip())
        i += 1
        if not m:
            if not fenced and STRAY_END.match(lines[i - 1].strip()):  # its BEGIN lost in an edit: a block unkept
                raise UsageError(f"{where}: line {i} {lines[i - 1].strip()!r} closes no block (expected a BEGIN "
                                 "line above it, or no END line)")
            continue
        name = m["name"]
        end = END.format(name=name)
        try:
            j = next(k for k in range(i, len(lines)) if lines[k].strip() == end)
        except StopIteration:
            raise UsageError(f"{where}: block generated:{name} has no closing line {end!r}") from None
        try:
            out += [render(name, card, card_path), end]
        except (UsageError, ValueError, KeyError) as exc:  # said with the file that holds the block
            said = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)  # no repr quotes
            raise UsageError(f"{where}: {said}") from None
        names.append(name)
        i = j + 1
    return "\n".join(out), names


def run(check: bool, root: Path = REPO, card_path: Path = CARD) -> list[Path]:
    """Regenerate (or, with check, compare) every doc file (result tables from the model card `card_path`); the
    files that were (or would be) changed."""
    from unips.models.registry import read_model_card

    card = read_model_card(card_path)
    if not card:
        raise FileNotFoundError(f"model card {str(card_path)!r} does not exist (the result tables come from it)")
    changed, seen = {}, set()
    for path in doc_files(root):
        if why := not_a_file(path):  # a link to a device is never read whole
            raise UsageError(f"{str(path.relative_to(root))} {why}")
        if path.is_symlink():  # written in place: through a link it would be somebody else's file
            raise UsageError(f"{str(path.relative_to(root))} is a link (to {os.readlink(path)!r}); the generated "
                             "blocks are written only into the repository's own files: replace the link by the file")
        text = read_text_file(path)  # (bytes that are not UTF-8 said naming the file)
        new, names = regenerate(text, card, str(path.relative_to(root)), card_path)
        seen.update(names)
        if new != text:
            changed[path] = new
    missing = [m for m in CLIS if f"flags:{m}" not in seen] + [b for b in BLOCKS if b not in seen]
    if missing:
        raise UsageError(f"no generated block for {', '.join(missing)} in README.md or docs/*.md")
    if not check:  # only once every block rendered: an error leaves every file as it was
        for path, new in changed.items():
            atomic_write_text(path, new)
    return list(changed)


@dataclass
class DocsOptions:
    """The command line of orchestrate.docs."""

    check: bool = False
    """Change nothing; exit 1 when a file is out of date."""


COMMAND = Command(DocsOptions, prog="python -m orchestrate.docs",
                  description="Rewrite the generated blocks (flag and result tables) of README.md and docs/*.md.")


def main(argv: list[str] | None = None) -> int:
    try:
        args = COMMAND.parse(argv)
        stale = run(args.check)
    except (UsageError, OSError, ValueError) as exc:
        return report_error(exc)
    names = ", ".join(str(p.relative_to(REPO)) for p in stale)
    if args.check:
        if stale:
            print(f"error: out of date: {names} (run python -m orchestrate.docs)", file=sys.stderr)
            return 1
        print("docs are up to date")
        return 0
    print(f"rewrote {names}" if stale else "docs are up to date")
    return 0


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    stopped = ("interrupted: every doc file is whole (each is written at once); run it again")
    sys.exit(run_supervised("orchestrate.docs", main, stopped))
