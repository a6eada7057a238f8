"""The docs are true to the code and the model card.

- the generated blocks of README.md and docs/*.md are what `python -m orchestrate.docs` writes now;
- every number of a result table equals the model card's figure for that row and column (read here from
  the Markdown, independently of the generator's code);
- every flag of every CLI has a row in its flag table, with the default its parser holds and every default
  its `--help` states;
- the README is a front page (at most ~150 lines), its examples parse with the real parsers, and every
  relative link of the docs points to an existing file and heading;
- every `make TARGET` the docs name exists; `make test` leaves the tests marked slow out, `make test-slow`
  runs them, and CI runs both.
"""
from __future__ import annotations

import dataclasses
import importlib
import json
import re
import shlex
import shutil
from pathlib import Path

import pytest

from orchestrate import docs

REPO = Path(__file__).resolve().parents[1]
CARD = json.loads((REPO / "unips" / "weights" / "model_card.json").read_text())
README_MAX_LINES = 150


def _doc_texts() -> dict[str, str]:
    return {
        str(p.relative_to(REPO)): p.read_text() for p in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
    }


def _block(name: str) -> str:
    """The text between the markers of generated block `name` (it must exist exactly once)."""
    found = []
    for text in _doc_texts().values():
        found += re.findall(
            rf"<!-- BEGIN generated:{re.escape(name)} -->\n(.*?)\n<!-- END generated:{re.escape(name)} -->", text, re.S
        )
    assert len(found) == 1, f"generated:{name}: expected one block in README.md / docs/*.md, found {len(found)}"
    return found[0]


def _cells(line: str) -> list[str]:
    parts = re.split(r"(?<!\\)\|", line.strip())[1:-1]
    return [p.strip().replace("\\|", "|") for p in parts]


def _tables(text: str) -> list[list[dict[str, str]]]:
    """Every Markdown table of `text` as a list of {header: cell} rows."""
    tables, lines = [], text.split("\n")
    for i, line in enumerate(lines):
        if line.startswith("|") and i + 1 < len(lines) and re.fullmatch(r"\|(-{3,}\|)+", lines[i + 1].strip()):
            header = _cells(line)
            rows = []
            for row in lines[i + 2:]:
                if not row.startswith("|"):
                    break
                rows.append(dict(zip(header, _cells(row))))
            tables.append(rows)
    return tables


def _table(name: str) -> list[dict[str, str]]:
    tables = _tables(_block(name))
    assert len(tables) == 1 and tables[0], f"generated:{name}: expected one non-empty table"
    return tables[0]


def _equal(cell: str, value) -> bool:
    """A table cell shows the card's value at the cell's precision ('-' for none)."""
    cell = cell.strip("*` ")
    if value is None:
        return cell == "-"
    if not re.fullmatch(r"-?\d+(\.\d+)?", cell):
        return False
    decimals = len(cell.partition(".")[2])
    return round(float(value), decimals) == float(cell)


# ---------------------------------------------------------------- generated blocks are current


def test_generated_blocks_are_up_to_date():
    stale = docs.run(check=True)
    assert not stale, f"out of date: {[str(p) for p in stale]}; run python -m orchestrate.docs"
    assert docs.main(["--check"]) == 0


STALE = re.compile(r"\| all +\| 99 +\|")


def _make_stale(page: Path) -> None:
    """Change the object count of the first 'all' row of a results table from 100 to 99 (widths kept)."""
    text, n = re.subn(r"(\| all +\| )100( +\|)", r"\g<1>99 \2", page.read_text(), count=1)
    assert n == 1
    page.write_text(text)


def test_check_fails_on_a_stale_block_and_rewrite_fixes_it(tmp_path):
    shutil.copy(REPO / "README.md", tmp_path / "README.md")
    shutil.copytree(REPO / "docs", tmp_path / "docs")
    page = tmp_path / "docs" / "results.md"
    _make_stale(page)
    assert docs.run(check=True, root=tmp_path) == [page]
    assert STALE.search(page.read_text())  # --check changes nothing
    assert docs.run(check=False, root=tmp_path) == [page]
    assert docs.run(check=True, root=tmp_path) == []


def test_unknown_block_is_refused_and_nothing_is_written(tmp_path):
    shutil.copy(REPO / "README.md", tmp_path / "README.md")
    shutil.copytree(REPO / "docs", tmp_path / "docs")
    before = {p: p.read_text() for p in tmp_path.rglob("*.md")}
    stale = tmp_path / "docs" / "results.md"
    _make_stale(stale)
    (tmp_path / "docs" / "zz.md").write_text(
        "<!-- BEGIN generated:results:nope -->\n<!-- END generated:results:nope -->\n"
    )
    with pytest.raises(docs.UsageError, match="results:nope"):
        docs.run(check=False, root=tmp_path)
    assert STALE.search(stale.read_text())  # the valid stale block was not rewritten either
    assert all(p.read_text() == t for p, t in before.items() if p != stale)


@pytest.mark.parametrize("check", [True, False])
def test_an_end_line_that_closes_no_block_is_named(tmp_path, check):
    """Sweep 39: a BEGIN line lost in an edit left its END line behind, and --check said the docs were up to
    date (the block it closed is no longer kept)."""
    shutil.copy(REPO / "README.md", tmp_path / "README.md")
    shutil.copytree(REPO / "docs", tmp_path / "docs")
    page = tmp_path / "docs" / "surface.md"
    text = page.read_text() + "\nmore words\n<!-- END generated:flags:orchestrate.surface -->\n"
    page.write_text(text)
    n = text.count("\n")
    with pytest.raises(docs.UsageError, match=rf"docs/surface.md: line {n} '<!-- END generated:flags:orchestrate"
                                              r"\.surface -->' closes no block"):
        docs.run(check=check, root=tmp_path)
    assert page.read_text() == text
    head, _, tail = text.rpartition("<!-- END")
    page.write_text(head + "```\n<!-- END" + tail + "```\n")  # inside fenced code: an example, no block
    assert docs.run(check=True, root=tmp_path) == []


def test_a_page_that_is_not_utf8_is_named_and_nothing_is_written(tmp_path):
    """Sweep 26: README.md holding a Latin-1 byte was `'utf-8' codec can't decode byte ...`, naming no file."""
    shutil.copy(REPO / "README.md", tmp_path / "README.md")
    shutil.copytree(REPO / "docs", tmp_path / "docs")
    (tmp_path / "README.md").write_bytes((REPO / "README.md").read_bytes() + b"\xe9t\xe9\n")
    stale = tmp_path / "docs" / "results.md"
    _make_stale(stale)
    with pytest.raises(ValueError, match=r"README.md' is not UTF-8 text \(byte 0xE9 at offset"):
        docs.run(check=False, root=tmp_path)
    assert STALE.search(stale.read_text())


# ---------------------------------------------------------------- result tables equal the model card


def test_headline_equals_card():
    rows = {r["mean angular error, degrees (lower is better)"]: r for r in _table("readme:headline")}
    test, dil = CARD["test_set"], CARD["diligent"]
    overall = next(r for k, r in rows.items() if k.startswith("synthetic test set, all"))
    assert _equal(overall["this model"], test["mean_deg"]["model"]["all"])
    directional = next(r for k, r in rows.items() if "directional" in k)
    assert _equal(directional["this model"], test["mean_deg"]["model"]["directional"])
    assert _equal(
        directional["calibrated least squares"], test["mean_deg"]["least squares (calibrated)"]["directional"]
    )
    for obj in ("ball", "cat"):
        row = next(r for k, r in rows.items() if k.startswith(f"DiLiGenT {obj}"))
        assert _equal(row["this model"], dil[obj]["model_deg_2dp"])
        assert _equal(row["calibrated least squares"], dil[obj]["least_squares_calibrated_deg"])
        assert _equal(row["published UniPS"], dil[obj]["published_unips_deg"])


PROBE_COLUMNS = {"objects": "n", "all images": "all", "one image": "one", "mask only": "mask", "shuffled": "shuffled",
                 "photometric gain": "gain"}


@pytest.mark.parametrize("name,block", [("results:test-set-probes", CARD["test_set"]),
                                        ("results:validation-probes", CARD["probes_fixed_validation"])])
def test_probe_tables_equal_card(name, block):
    per_family = block.get("per_family_probes") or block["per_family"]
    rows = _table(name)
    assert {r["family"] for r in rows} == {*per_family, "all"}  # no family dropped
    for row in rows:
        for column, key in PROBE_COLUMNS.items():
            if row["family"] != "all":
                want = per_family[row["family"]][key]
            elif key == "gain":
                want = block["photometric_gain_deg"]
            elif key == "n":
                want = sum(f["n"] for f in per_family.values())
            else:
                want = block["probes_deg"][key]
            assert _equal(row[column], want), f"{name} {row['family']} / {column}: {row[column]} vs card {want}"


def test_method_table_equals_card():
    mean = CARD["test_set"]["mean_deg"]
    rows = _table("results:test-set-methods")
    assert [r["method"] for r in rows] == list(mean)
    for row in rows:
        for column, cell in row.items():
            if column != "method":
                family = column.split(" (")[0]
                assert _equal(cell, mean[row["method"]].get(family)), f"{row['method']} / {column}"


def test_image_count_table_equals_card():
    test = CARD["test_set"]
    for row in _table("results:image-count"):
        for column, cell in row.items():
            if column.startswith("K="):
                assert _equal(cell, test["vs_image_count_deg"][row["method"]][column[2:]]), (
                    f"{row['method']} / {column}"
                )
            elif column == "all images":
                assert _equal(cell, test["mean_deg"][row["method"]]["all"])


def test_diligent_table_equals_card():
    columns = {
        "images": "images",
        "this model": "model_deg_2dp",
        "this model, 16 images": "model_k16_mean_deg",
        "mask only": "model_mask_only_deg",
        "seconds": "model_seconds",
        "calibrated least squares": "least_squares_calibrated_deg",
        "published least squares": "published_l2_deg",
        "published UniPS": "published_unips_deg",
    }
    rows = _table("results:diligent")
    assert {r["object"] for r in rows} == {"ball", "cat"}
    for row in rows:
        assert set(row) == {"object", *columns}
        for column, key in columns.items():
            assert _equal(row[column], CARD["diligent"][row["object"]][key]), f"{row['object']} / {column}"


def test_lineage_tables_equal_card():
    stages = {s["stage"]: s for s in CARD["lineage"]}
    rows = _table("results:lineage")
    assert [r["stage"] for r in rows] == list(stages)
    for row in rows:
        stage = stages[row["stage"]]
        assert _equal(row["steps"], stage["steps"]) and _equal(row["hours"], stage["hours"])
        best = stage.get("fixed_validation") or next(c for c in stage["curve"] if c["step"] == stage["best_step"])
        assert _equal(row["validation: all images"], best["all"]) and _equal(row["photometric gain"], best["gain"])
    for row in _table("results:lineage-families"):
        for family, cell in row.items():
            if family != "stage":
                assert _equal(cell, stages[row["stage"]]["per_family_at_best"][family]["all"])


def _card_numbers(node) -> list[float]:
    if isinstance(node, dict):
        return [x for v in node.values() for x in _card_numbers(v)]
    if isinstance(node, list):
        return [x for v in node for x in _card_numbers(v)]
    return [float(node)] if isinstance(node, (int, float)) and not isinstance(node, bool) else []


def test_the_input_contract_table_is_the_registry_entries():
    from unips.models import input_contract, list_models

    rows = _table("model:inputs")
    assert [r["model (default for)"].split("`")[1] for r in rows] == list_models()
    for row in rows:
        contract = input_contract(row["model (default for)"].split("`")[1])
        assert row["preprocessing"] == contract.preprocess and row["views"] == str(contract.views)
        assert row["images"] == str(contract.max_images or "all")


def test_every_number_of_every_result_table_is_a_card_figure():
    """Catch-all for a result table added later: each numeric cell is one of the card's figures."""
    numbers = _card_numbers(CARD)
    checked = 0
    for name in docs.BLOCKS:
        if name in docs.BENCH_BLOCKS or name == "model:inputs":  # a benchmark's output / the registry: checked apart
            continue
        for table in _tables(_block(name)):
            for row in table:
                for column, cell in row.items():
                    value = cell.strip("*` ")
                    # object counts are sums over families (checked per table above), not card figures
                    if column != "objects" and re.fullmatch(r"-?\d+(\.\d+)?", value):
                        assert any(_equal(value, x) for x in numbers), (
                            f"generated:{name} {column}: {value} is not in the model card"
                        )
                        checked += 1
    assert checked > 100


def test_benchmark_tables_equal_the_recorded_output():
    """A table generated from a benchmark's output holds that output's figures, rows in its order."""
    for name, path in docs.BENCH_BLOCKS.items():
        recorded = json.loads(path.read_text())
        numbers = _card_numbers(recorded)
        rows = [r for t in _tables(_block(name)) for r in t]
        assert len(rows) == len(recorded["rows"]) > 0
        for row, want in zip(rows, recorded["rows"]):
            if "cache" in want:  # the shards table's row key
                assert row["cache"] == want["cache"]
            for cell in row.values():
                value = cell.strip("*` x")
                if re.fullmatch(r"-?\d+(\.\d+)?", value):
                    assert any(_equal(value, x) for x in numbers), f"generated:{name}: {value} is not in {path.name}"


# ---------------------------------------------------------------- flag tables match the parsers and --help


def _flag_rows(module: str) -> dict[str, dict[str, str]]:
    rows = {}
    for table in _tables(_block(f"flags:{module}")):
        for row in table:
            invocation = row["flag"].strip("`")
            for name in invocation.split(", "):
                rows[name.split(" ")[0]] = row
    return rows


def _written_default(value) -> str:
    """A dataclass default as a reader types it, computed here (not with the docs generator's code)."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, (list, tuple)):
        return ",".join(str(v) for v in value) or "-"
    return "-" if value in (None, "") else str(value)


@pytest.mark.parametrize("module", docs.CLIS)
def test_flag_table_has_every_flag_of_help_with_the_dataclass_default(module):
    """Every flag `--help` prints has a row, and the row's default is the config dataclass's own default (or
    `required`, or the run-time default `--help` states in words)."""
    import tyro

    from scenes.cli.options import field_docs

    command = importlib.import_module(module).COMMAND
    help_text = "".join(command.help().split())  # what `--help` prints, without the wrapping and the frames
    rows = _flag_rows(module)
    invocations = [re.split(r"\s{2,}", m.group(1))[0] for line in command.help().splitlines()
                   if (m := re.match(r"^(?:│ |  )(-\S.*)", line))]  # the flag column of --help's option sections
    flags = [t for inv in invocations for t in re.findall(r"--[a-z][a-z0-9-]*", inv) if t != "--help"]
    assert flags, module
    for flag in flags:
        assert flag in rows, f"{module}: {flag} (in --help) has no row in docs"

    def defaults(cls, out):
        for f in dataclasses.fields(cls):
            value = f.default if f.default is not dataclasses.MISSING else f.default_factory()
            if dataclasses.is_dataclass(value):
                defaults(type(value), out)
            else:
                out[f.name] = (value, field_docs(cls).get(f.name, ""))
        return out

    for name, (value, doc) in defaults(command.config, {}).items():
        flag = "--" + name.replace("_", "-")
        if flag not in rows:  # a positional or a field kept off the command line
            assert flag not in flags, (module, flag)
            continue
        cell = rows[flag]["default"].strip("`")
        if value is tyro.MISSING:
            assert cell == "required", (module, flag, cell)
        elif _written_default(value) != cell:  # a default chosen at run time: --help states the same words
            assert value is None and "".join(cell.split()) in help_text, (module, flag, cell, value)
        assert "".join(doc.replace("`", "").split())[:40] in "".join(rows[flag]["meaning"].replace("`", "").split()), \
            (module, flag)


def test_every_cli_has_a_flag_table_and_is_documented_once():
    text = "\n".join(_doc_texts().values())
    for module in docs.CLIS:
        assert text.count(f"<!-- BEGIN generated:flags:{module} -->") == 1, module


# ---------------------------------------------------------------- README and links


def test_readme_is_a_front_page():
    readme = (REPO / "README.md").read_text()
    lines = readme.splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f"README.md has {len(lines)} lines; keep it a front page (move details to docs/)"
    )
    for needed in ("make setup", "source .venv/bin/activate", "make demo", "make test", "GB"):
        assert needed in readme, needed
    for page in sorted((REPO / "docs").glob("*.md")):
        assert f"(docs/{page.name})" in readme, f"README.md does not link docs/{page.name}"
    assert "(ARCHITECTURE.md)" in readme


def test_table_cells_quote_placeholders_without_the_full_stop():
    """A help text's `<...>` and `*` words become code spans (Markdown would eat them as HTML or emphasis);
    the sentence's full stop and brackets stay outside, a pipe is escaped."""
    assert docs._cell("dataset: folder with <object>/normal.*.") == "dataset: folder with `<object>/normal.*`."
    assert docs._cell("(<out>/<object>/report.json, figure.png)") == "(`<out>/<object>/report.json`, figure.png)"
    assert docs._cell("a | b") == "a \\| b"


def _make_recipes() -> dict[str, str]:
    """Makefile target -> its recipe (the tab-indented lines under it, continuation lines joined)."""
    recipes: dict[str, str] = {}
    target = None
    for line in (REPO / "Makefile").read_text().replace("\\\n", " ").splitlines():
        m = re.match(r"^([\w-]+):", line)
        if m:
            target = m.group(1)
            recipes[target] = ""
        elif line.startswith("\t") and target:
            recipes[target] += line.strip() + "\n"
        elif line.strip():  # a variable, a comment or the next rule ends the recipe
            target = None
    return recipes


def test_make_targets_named_in_the_docs_exist_and_the_slow_marker_splits_the_run():
    recipes = _make_recipes()
    named = {(page, t) for page, text in _doc_texts().items()
             for t in re.findall(r"(?<![\w.])make ([a-z][\w-]*)", text)}
    missing = sorted(f"{page}: make {t}" for page, t in named if t not in recipes)
    assert not missing, f"the docs name make targets the Makefile lacks: {missing}"
    assert '-m "not slow"' in recipes["test"] and "-m slow" in recipes["test-slow"]
    ci = [line for line in (REPO / ".ci" / "run").read_text().splitlines() if line and not line.startswith("#")]
    assert "set -euo pipefail" in ci and any(l.endswith("make test") for l in ci) \
        and any(l.endswith("make test-slow") for l in ci), ci


def _readme_commands() -> list[list[str]]:
    readme = (REPO / "README.md").read_text()
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", readme, re.S):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if words[:2] == ["python", "-m"]:
                commands.append(words[2:])
    return commands


def test_readme_has_one_example_per_cli_and_each_parses():
    commands = _readme_commands()
    assert {c[0] for c in commands} >= set(docs.CLIS), (
        f"no README example for {set(docs.CLIS) - {c[0] for c in commands}}"
    )
    for module, *argv in commands:
        try:
            importlib.import_module(module).COMMAND.parse(argv)
        except (SystemExit, Exception) as exc:  # a bad command line is a UsageError
            pytest.fail(f"README example python -m {module} {' '.join(argv)} does not parse: {exc}")


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    text = heading.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    return {_slug(h) for h in re.findall(r"^#+ (.+)$", text, re.M)}


def test_relative_links_resolve():
    for name, text in {**_doc_texts(), "ARCHITECTURE.md": (REPO / "ARCHITECTURE.md").read_text()}.items():
        base = (REPO / name).parent
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+://", target):
                continue
            file, _, anchor = target.partition("#")
            path = (base / file).resolve() if file else REPO / name
            assert path.exists(), f"{name}: link to {target} (no such file)"
            if anchor:
                assert anchor in _anchors(path), f"{name}: link to {target} (no such heading)"


def test_a_truncated_model_card_is_one_line_naming_it(tmp_path):
    """Issue 40: a truncated model_card.json was a bare JSON error ('Expecting ...: line 5 column 1'), naming no
    file; orchestrate.docs and train_recipe --ship (before any work) read it through one reader that names it."""
    from orchestrate import docs
    from orchestrate.train_recipe import _card
    from unips.models.registry import read_model_card

    card = tmp_path / "model_card.json"
    card.write_bytes(docs.CARD.read_bytes()[:200])
    for call in (lambda: docs.run(True, card_path=card), lambda: read_model_card(card)):
        with pytest.raises(ValueError) as err:
            call()
        assert str(err.value).startswith(f"model card {str(card)!r} is not readable JSON") and "\n" not in str(
            err.value
        )
    with pytest.raises(ValueError, match=r"^--ship: model card .* is not readable JSON"):
        _card(card)
    card.write_text("[1, 2]\n")
    with pytest.raises(ValueError, match="holds a JSON list, expected an object"):
        read_model_card(card)
    assert read_model_card(tmp_path / "none.json") == {}


def test_readme_data_has_the_images_its_refine_example_needs():
    """Issue 40: the README's validate.refine example failed on the README's own 4-image data (refinement needs
    validate.judgeable.MIN_IMAGES['refine']); its data commands give each object that many images."""
    from validate.judgeable import MIN_IMAGES
    from wildgen.make import COMMAND as MAKE

    commands = _readme_commands()
    refine = next(argv for module, *argv in commands if module == "validate.refine")
    data = Path(refine[refine.index("--data") + 1]).parts[0]
    made = [MAKE.parse(argv) for module, *argv in commands if module == "wildgen.make"]
    source = next(opts for opts in made if Path(opts.out).parts[0] == data)
    assert source.gen.images >= MIN_IMAGES["refine"], (data, source.gen.images)


def test_a_benchmark_output_that_is_not_what_its_table_reads_is_named(tmp_path):
    """bench/results/*.json is read by one reader (`orchestrate.bench_docs.read_bench`): NaN would print as a figure,
    a missing key or a cut file said naming the file (sweep 9)."""
    import json

    from orchestrate.bench_docs import SHARDS_BENCH, read_bench

    good = json.loads(SHARDS_BENCH.read_text())
    bad = tmp_path / "shards.json"
    bad.write_text(SHARDS_BENCH.read_text()[:1])
    with pytest.raises(ValueError, match=r"shards.json: not valid JSON"):
        read_bench(bad)
    bad.write_text(json.dumps({**good, "x": float("nan")}))
    with pytest.raises(ValueError, match=r"shards.json': holds the number NaN; expected finite figures"):
        read_bench(bad)
    for figure in ("1e999", "1" + "0" * 400):  # inf as a figure; an integer no float holds
        bad.write_text(json.dumps(good).replace('"rows": [', f'"x": {figure}, "rows": [', 1))
        with pytest.raises(ValueError, match=r"shards.json': holds the number .*; expected finite figures"):
            read_bench(bad)
    outside = tmp_path / "outside.json"
    outside.write_text(json.dumps(good))
    link = tmp_path / "link.json"
    link.symlink_to(outside)
    with pytest.raises(ValueError, match=r"link.json' is a link"):  # never read through: it may be any file
        read_bench(link)
    bad.write_text(json.dumps({"rows": [{}]}))
    with pytest.raises(KeyError, match=r"shards.json: a record without 'cache'"):
        read_bench(bad)["rows"][0]["cache"]
    assert read_bench(SHARDS_BENCH) == good


@pytest.mark.parametrize("edit", [lambda d: d.__setitem__("rows", 5), lambda d: d["rows"].__setitem__(0, [1, 2]),
                                  lambda d: d["rows"][0].__setitem__("folders_per_s", "fast"), lambda d: [1],
                                  "[" * 100000 + "]" * 100000, b"\xff\xfe{}"],
                         ids=["rows-a-number", "row-a-list", "figure-a-text", "a-list", "nested-deep", "bad-utf8"])
def test_a_benchmark_output_of_another_shape_is_one_line_naming_it(edit, tmp_path, monkeypatch):
    """Sweep 17: a bench output whose rows are a number, a row a list, a figure a text, the file a list, nested too
    deep or not UTF-8 ended in a TypeError / RecursionError traceback or named only the doc; now one line naming the
    file (`scenes.files.reading_record`)."""
    import json

    from orchestrate import bench_docs, docs

    data = json.loads(bench_docs.SHARDS_BENCH.read_text())
    bad = tmp_path / "shards.json"
    if isinstance(edit, (str, bytes)):
        bad.write_bytes(edit if isinstance(edit, bytes) else edit.encode())
    else:
        result = edit(data)
        bad.write_text(json.dumps(data if result is None else result))
    monkeypatch.setattr(bench_docs, "SHARDS_BENCH", bad)
    monkeypatch.setitem(docs.BENCH_BLOCKS, "model:shards-throughput", bad)
    with pytest.raises(docs.UsageError) as err:
        docs.run(True)
    assert str(bad) in str(err.value) and "\n" not in str(err.value), err.value


@pytest.mark.parametrize("edit", [lambda d: d["lineage"].append("a stage"),
                                  lambda d: d["lineage"].__setitem__(0, {**d["lineage"][0], "hours": [2]})],
                         ids=["lineage-item-a-text", "hours-a-list"])
def test_a_model_card_of_another_shape_is_one_line_naming_it(edit, tmp_path):
    import json

    from orchestrate import docs

    card = json.loads(docs.CARD.read_text())
    edit(card)
    path = tmp_path / "model_card.json"
    path.write_text(json.dumps(card))
    with pytest.raises(docs.UsageError) as err:
        docs.run(True, card_path=path)
    assert str(path) in str(err.value) and "not a model card" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("constant,block,edit", [
    ("DOUBTFUL_MASK_BENCH", "capture:doubtful-mask", lambda d: d["rows"][0].__setitem__("suites", "plain")),
    ("LIGHT_WARNINGS_BENCH", "capture:light-warnings",
     lambda d: next(r for r in d["rows"] if "real" in r).__setitem__("truth", "frontal_light")),
], ids=["doubtful-mask-suites-a-text", "light-warnings-truth-a-text"])
def test_a_list_of_names_given_as_one_text_is_named_not_spelled_out(constant, block, edit, tmp_path, monkeypatch):
    """Sweep 18: a record's suites or warning codes given as one text were joined letter by letter into the docs
    ('p, l, a, i, n'), exit 0; now one line naming the file and the field."""
    import json

    from orchestrate import bench_docs, docs

    data = json.loads(getattr(bench_docs, constant).read_text())
    edit(data)
    bad = tmp_path / "result.json"
    bad.write_text(json.dumps(data))
    monkeypatch.setattr(bench_docs, constant, bad)
    monkeypatch.setitem(docs.BENCH_BLOCKS, block, bad)
    with pytest.raises(docs.UsageError) as err:
        docs.run(True)
    assert str(bad) in str(err.value) and "expected a list of names" in str(err.value), err.value
