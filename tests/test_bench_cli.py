"""The bench scripts read their command lines through the toolkit's tyro CLI (`scenes.cli.options.Command`): each
script's `--help` works, a bad option is one line, and every command line quoted for a script (in docs/, README.md
and the scripts' own docstrings) still parses, to the values its flags say; a bench stopped by a signal ends
through its own clean-up in one line."""
from __future__ import annotations

import ast
import dataclasses
import importlib
import os
import re
import sys
from pathlib import Path

import pytest
import tyro

from scenes.cli.options import Command

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # the bench scripts are imported as bench.NAME

MAIN = re.compile(r"sys\.exit\((main\(\)|run_main\(main\))\)")
SCRIPTS = sorted(p.stem for p in (ROOT / "bench").glob("*.py") if MAIN.search(p.read_text()))
"""The scripts with a main (bench/train_recipe.py runs orchestrate.train_recipe's)."""
QUOTED = re.compile(r"python\s+bench/(\w+)\.py\b")
PLACEHOLDER = re.compile(r"^[A-Z][A-Z_]*$")
"""A value written as a name in capitals (`--threads T`, `CAPTURE`): the docs' placeholder for a value."""


def _module(stem: str):
    return importlib.import_module(f"bench.{stem}")


def _command(stem: str) -> Command:
    """The script's COMMAND (bench/train_recipe.py keeps the command of the module whose main it runs)."""
    mod = _module(stem)
    command = getattr(mod, "COMMAND", None) or sys.modules[mod.main.__module__].COMMAND
    assert isinstance(command, Command), stem
    return command


def _normalise(text: str) -> str:
    """A quoted command as a shell would split it: continuations joined, comments, optional-part brackets and
    `...` (more of the same) dropped."""
    text = text.replace("\\\n", " ")
    text = "\n".join(line.split("  #")[0] for line in text.splitlines())
    return " ".join(text.replace("[", " ").replace("]", " ").replace("...", " ").split())


def _quoted() -> list[tuple[str, str, list[str]]]:
    """(where, script, argv) of every command line quoted for a bench script: in backticks in docs/*.md and
    README.md, on its own lines in the bench scripts' docstrings."""
    out = []
    for md in [*sorted((ROOT / "docs").rglob("*.md")), ROOT / "README.md"]:
        out += [(md.name, span) for span in re.findall(r"`(python\s+bench/[^`]*)`", md.read_text())]
    for script in sorted((ROOT / "bench").glob("*.py")):
        doc = ast.get_docstring(ast.parse(script.read_text())) or ""
        for block in re.split(r"\n(?=\s*python\s+bench/)", doc):
            start = QUOTED.search(block)
            if start and block[:start.start()].strip() == "":
                lines = block.splitlines()
                keep = [lines[0]]
                for line in lines[1:]:  # the continuation lines of a command written over several
                    if not keep[-1].rstrip().endswith("\\") and not line.startswith(" " * 8):
                        break
                    keep.append(line)
                out.append((script.name, "\n".join(keep)))
    found = []
    for where, text in out:
        stem, *argv = _normalise(text).split(" ")[1:]
        found.append((where, stem.removeprefix("bench/").removesuffix(".py"), argv))
    return found


QUOTED_COMMANDS = _quoted()


def _leaves(cfg) -> dict[str, object]:
    out = {}
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        out.update(_leaves(value) if dataclasses.is_dataclass(value) else {f.name: value})
    return out


def _leaf_types(cls: type) -> dict[str, object]:
    import typing

    out = {}
    for name, tp in typing.get_type_hints(cls).items():
        if dataclasses.is_dataclass(tp):
            out.update(_leaf_types(tp))
        else:
            out[name] = tp
    return out


def _expected(command: Command, argv: list[str]) -> tuple[list[str], dict[str, list[str] | bool], list[str]]:
    """(argv with placeholders given a value of their field's type, field -> what the flags say, the positional
    values)."""
    types = _leaf_types(command.config)
    flags = command.flags()
    by_flag = {flag: name for name, flag in flags.items() if flag.startswith("--")}
    positional = next((name for name, flag in flags.items() if not flag.startswith("--")), None)
    argv, said, rest = list(argv), {}, []
    i = 0
    while i < len(argv):
        token = argv[i]
        name = by_flag.get(token)
        negated = by_flag.get("--" + token.removeprefix("--no-")) if token.startswith("--no-") else None
        if name is not None and types[name] is bool:
            said[name] = True
        elif name is None and negated is not None and types[negated] is bool:
            said[negated] = False
        elif name is not None:
            assert i + 1 < len(argv), f"{token} without a value"
            if PLACEHOLDER.match(argv[i + 1]) and re.search(r"\bint\b|\bfloat\b", str(types[name])):
                argv[i + 1] = "2"
            said.setdefault(name, []).append(argv[i + 1])
            i += 1
        else:
            assert not token.startswith("-"), f"unknown flag {token}"
            rest.append(token)
        i += 1
    assert not rest or positional is not None, f"positional values {rest} for a command without any"
    return argv, said, rest


def _matches(value, given: list[str]) -> bool:
    """Whether a parsed value is what the flag's value(s) on the command line say."""
    if isinstance(value, (list, tuple)):
        items = [v for g in given for v in g.split(",")] if len(given) == 1 else given
        return len(value) == len(items) and all(_matches(v, [s]) for v, s in zip(value, items))
    (text,) = given[-1:]
    if isinstance(value, float):
        return value == float(text)
    return str(value) == text


def test_every_script_with_a_main_is_found_and_quoted_commands_name_real_scripts():
    assert len(SCRIPTS) >= 18 and "bench_fit" in SCRIPTS and "train_recipe" in SCRIPTS and "cli_common" not in SCRIPTS
    assert len(QUOTED_COMMANDS) > 40  # the docs and docstrings are read
    assert {stem for _, stem, _ in QUOTED_COMMANDS} <= set(SCRIPTS)


@pytest.mark.parametrize("stem", SCRIPTS)
def test_help_and_a_bad_option(stem, capsys):
    mod = _module(stem)
    with pytest.raises(SystemExit) as done:
        mod.main(["--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: python ")
    for flag in _command(stem).flags().values():
        assert flag in out or flag.isupper() or flag.startswith("--no-"), (stem, flag)
    flags = _command(stem).flags()
    given = [a for name in _required(_command(stem).config) for a in (flags[name], "X") if flags[name].startswith("--")]
    try:
        code = mod.main([*given, "--no-such-option", "1"])
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "--no-such-option" in err, err


def _required(cls: type) -> list[str]:
    """Fields of `cls` and of its nested configs that the command line must give."""
    out = []
    for f in dataclasses.fields(cls):
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if dataclasses.is_dataclass(default):
            out += _required(type(default))
        elif default is tyro.MISSING:
            out.append(f.name)
    return out


@pytest.mark.parametrize("where,stem,argv", QUOTED_COMMANDS,
                         ids=[f"{w}:{' '.join([s, *a])}"[:90] for w, s, a in QUOTED_COMMANDS])
def test_quoted_command_parses_to_what_its_flags_say(where, stem, argv):
    command = _command(stem)
    argv, said, rest = _expected(command, argv)
    flags = command.flags()
    for name in _required(command.config):  # prose that quotes one flag leaves the required values out
        if flags[name].startswith("--") and name not in said:
            argv += [flags[name], "X"]
        elif not flags[name].startswith("--") and not rest:
            argv.append("X")
    cfg = command.parse(argv)
    parsed = _leaves(cfg.validate() if hasattr(cfg, "validate") else cfg)
    for name, value in said.items():
        if isinstance(value, bool):
            assert parsed[name] is value, (where, name)
        else:
            assert _matches(parsed[name], value), (where, name, parsed[name], value)
    if rest:
        positional = next(name for name, flag in flags.items() if not flag.startswith("--"))
        assert [str(v) for v in parsed[positional]] == rest, (where, parsed[positional], rest)


@pytest.mark.parametrize("argv", [["--families", "bogus"], ["--families", ""], ["--variant", "bogus_rgb"]])
def test_render_bench_refuses_a_bad_family_or_variant_before_rendering(argv):
    import subprocess

    r = subprocess.run([sys.executable, "bench/bench_render.py", *argv], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith(f"error: {argv[0]}: got ") and "Traceback" not in r.stderr, r


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT"])
def test_a_stopped_bench_removes_its_temporary_folder(sig, tmp_path):
    """bench_render renders in a folder of TMPDIR: a stop mid-render (where Dr.Jit may swallow the interrupt) ends
    the bench with one line and 128 + the signal, not a traceback, its folders gone (`bench.cli_common.run_main`)."""
    import os
    import signal
    import subprocess
    import time

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    def as_a_terminal_starts_it() -> None:  # a run started in the background (`cmd &`) inherits SIGINT ignored
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, signal.SIG_DFL)

    proc = subprocess.Popen([sys.executable, "bench/bench_render.py", "--res", "64", "--spp", "16", "--images", "4",
                             "--objects", "5000", "--families", "directional"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "TMPDIR": str(tmp)},
                            preexec_fn=as_a_terminal_starts_it)
    assert proc.stdout.readline().startswith("variant "), proc.communicate()  # the header: rendering starts
    time.sleep(2.0)
    assert proc.poll() is None, proc.communicate()
    t0 = time.monotonic()
    proc.send_signal(getattr(signal, sig))
    out, err = proc.communicate(timeout=120)
    assert time.monotonic() - t0 < 60, err  # within the grace period and its clean-up
    assert proc.returncode == 128 + getattr(signal, sig), (out, err)
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("interrupted: "), err
    assert not any(tmp.iterdir()), sorted(p.name for p in tmp.iterdir())


# ---------------------------------------------------------------- bad values and outputs, refused before any work


@pytest.fixture
def places(tmp_path):
    """Paths the table's command lines name: a folder, a plain file, a user's own JSON file, a model card that is no
    card, an empty dataset, and a DiLiGenT folder with a (fake) ballPNG and no catPNG."""
    (tmp_path / "folder").mkdir()
    (tmp_path / "file.txt").write_text("a user's file\n")
    (tmp_path / "user.json").write_text('{"mine": 1}\n')
    (tmp_path / "junk.json").write_text("not json\n")
    (tmp_path / "empty_suite").mkdir()
    ball = tmp_path / "diligent" / "ballPNG"
    ball.mkdir(parents=True)
    for name in ("001.png", "light_directions.txt", "mask.png", "Normal_gt.png"):
        (ball / name).write_bytes(b"")
    for name in ("ballPNG", "catPNG"):  # a folder that names both objects (ab_data's check before any work)
        (tmp_path / "both" / name).mkdir(parents=True)
    (tmp_path / "suite" / "00000.data").mkdir(parents=True)  # a dataset as far as the checks before any work go
    return tmp_path


TINY_SHARDS = ["--objects", "1", "--images", "1", "--res", "8", "--shard-size", "1", "--repeats", "1"]
"""bench_shards at its cheapest (no rendering: a few seconds)."""
BAD = [
    ("bench_shards", ["--out", "{t}/folder", *TINY_SHARDS], ["--out: ", "existing folder"]),
    ("bench_shards", ["--out", "{t}/file.txt/x.json", *TINY_SHARDS], ["--out: ", "file.txt", "existing file"]),
    ("bench_shards", ["--out", "{t}/user.json", *TINY_SHARDS], ["--out: ", "user.json", "was not written by",
                                                                "never replaced"]),
    ("bench_shards", ["--res", "2", "--objects", "1", "--images", "1"], ["--res: got 2, expected an integer >= 8"]),
    ("bench_min_images", ["--out", "{t}/folder", "--draws", "1"], ["--out: ", "existing folder"]),
    ("bench_determinism", ["--sizes", "64x32"], ["--sizes: got '64x32', expected RES:SPP"]),
    ("bench_determinism", ["--sizes", "8:0"], ["--sizes: got '8:0', expected RES:SPP with SPP an integer >= 1"]),
    ("bench_determinism", ["--sizes", "4:1"], ["--sizes: got '4:1'", "RES an integer from 8"]),
    ("bench_determinism", ["--threads", "0", "--sizes", "8:1", "--images", "2", "--repeats", "1"],
     ["--threads: got 0, expected an integer >= 1"]),
    ("bench_determinism", ["--variant", "bogus_rgb", "--sizes", "8:1"],
     ["--variant: got 'bogus_rgb', expected one of"]),
    ("bench_rerender", ["--levels", "a", "--data", "{t}/empty_suite"], ["--levels: ", "'a'"]),
    ("bench_rerender", ["--levels", "95", "--data", "{t}/empty_suite"], ["--levels: got 95.0, expected a number in"]),
    ("bench_rerender", ["--kinds", "zigzag", "--data", "{t}/empty_suite"], ["--kinds: got 'zigzag', expected one of"]),
    ("bench_rerender", ["--json", "{t}/user.json", "--data", "{t}/empty_suite"], ["--json: ", "was not written by"]),
    ("bench_fit", ["--angles", "x", "--skip-diligent", "--synthetic", "0"], ["--angles: ", "'x'"]),
    ("bench_fit", ["--kinds", "zigzag", "--skip-diligent", "--synthetic", "0"], ["--kinds: got 'zigzag'"]),
    ("bench_fit", ["--tta", "5", "--skip-diligent", "--synthetic", "0"], ["--tta: got 5"]),
    ("bench_full_size", ["--working", "abc", "--side", "64", "--objects", "1", "--work", "{t}/w"], ["--working: ",
                                                                                                   "'abc'"]),
    ("bench_full_size", ["--working", "128", "--side", "64", "--objects", "1", "--work", "{t}/w", "--out",
                         "{t}/r.json"], ["--working: got 128, expected working sides of at most --side 64"]),
    ("bench_refine_rule", ["--seeds", "a"], ["--seeds: ", "'a'"]),
    ("bench_model", ["--case", "x"], ["--case: got 'x', expected infer MODEL RES K or train"]),
    ("bench_capture", ["--out", "{t}/r.json", "--sides", "big"], ["--sides: ", "'big'"]),
    ("bench_capture", ["--out", "{t}/r.json", "--images", "0", "--sides", "32"], ["--images: got 0, expected an "
                                                                                  "integer >= 3"]),
    ("bench_surface", ["--work", "{t}/file.txt"], ["--work: ", "file.txt", "existing file"]),
    ("bench_diligent", ["--data", "{t}/diligent", "--max-images", "4"], ["--data: ", "catPNG", "does not exist"]),
    ("bench_light_warnings", ["--suite", "{t}/no_suite", "--out", "{t}/r.json"], ["--suite: ", "no_suite",
                                                                                   "does not exist"]),
    ("bench_light_warnings", ["--suite", "{t}/empty_suite"], ["--suite: ", "holds no *.data"]),
    ("bench_usable", ["--subsets", "0", "--objects", ""], ["--subsets: got 0, expected an integer >= 3"]),
    ("bench_usable", ["--shifts", "9", "--objects", ""], ["--shifts: got 9, expected an integer from 1 to 8"]),
    ("bench_usable", ["--data", "{t}/diligent", "--encodings", "linear16"], ["--data: ", "catPNG"]),
    ("bench_usable", ["--objects", ""], ["--objects: got '' and no --suite: nothing to measure"]),
    ("bench_refine_rule", ["--seeds", "9500"], ["--seeds: got '9500', expected at least two seeds"]),
    ("ab_data", ["--work", "{t}/w", "--tag", "/../../out"], ["--tag: got '/../../out'", "folders' names"]),
    ("ab_data", ["--work", "{t}/folder", "--assets", "{t}/folder"], ["--work: ", "is --assets"]),
    ("bench_usable", ["--data", "{t}/diligent", "--objects", "ballPNG"], ["--objects: ", "one named ballPNG"]),
    ("bench_min_images", ["--draws", "100000000"], ["--draws: got 100000000, expected an integer from 1 to 1000"]),
    ("learning_curve", ["--card", "{t}/junk.json"], ["--card: got ", "junk.json", "expected a model card"]),
    ("learning_curve", ["--card", "{t}/user.json"], ["--card: got ", "user.json", "expected a model card"]),
    ("ab_data", ["--work", "{t}/file.txt", "--objects", "5"], ["--work: ", "existing file"]),
    ("ab_data", ["--work", "{t}/w", "--arms", "bogus"], ["--arms: got 'bogus', expected one of today, new, sensor"]),
    ("ab_data", ["--work", "{t}/w", "--assets", "{t}/folder", "--diligent", "{t}/no_diligent"],
     ["--diligent: ", "no_diligent", "does not exist"]),
    ("ab_data", ["--work", "{t}/w", "--assets", "{t}/folder", "--diligent", "{t}/diligent"],
     ["--diligent: ", "holds no catPNG"]),
    ("ab_data", ["--work", "{t}/w", "--assets", "{t}/folder", "--diligent", "{t}/both", "--record", "--steps", "7"],
     ["--record: the model card's A/B holds arms", "this run's --steps 7", "mix two budgets"]),
    ("bench_doubtful_mask", ["--suite", "{t}/suite", "--out", "{t}/suite/d.json"], ["--out: ", "lies inside --suite"]),
    ("bench_verdict", ["{t}/suite/00000.data", "--no-model", "--out", "{t}/suite/00000.data/v.json"],
     ["--out: ", "lies inside CAPTURE"]),
    ("bench_rerender", ["--data", "{t}/suite", "--json", "{t}/suite/r.json"], ["--json: ", "lies inside --data"]),
    ("bench_doubtful_mask", ["--suite", "{t}/empty_suite", "--seed", "-1"],
     ["--seed: got -1, expected an integer >= 0"]),
    ("bench_capture_diligent", ["--data", "{t}/diligent", "--objects", "nosuchPNG", "--work", "{t}/w", "--out",
                                "{t}/r.json"], ["--data: ", "nosuchPNG", "does not exist"]),
    ("bench_capture_diligent", ["--data", "{t}/diligent", "--objects", "ballPNG,../both/ballPNG", "--work", "{t}/w",
                                "--out", "{t}/r.json"], ["--objects: got '../both/ballPNG'", "directly under --data"]),
    ("bench_capture_diligent", ["--data", "{t}/diligent", "--objects", "ballPNG,ballPNG", "--work", "{t}/w", "--out",
                                "{t}/r.json"], ["--objects: got 'ballPNG'", "each once"]),
    ("bench_capture_trees", ["--baseline", "no-such-revision", "--objects", ""], ["--objects: got ''"]),
    ("bench_detail", ["--res", "2", "--objects", "1", "--images", "1", "--spp", "1"], ["--res: got 2"]),
    ("bench_detail", ["--lights", "zz"], ["--lights: got 'zz', expected one of"]),
    ("bench_doubtful_mask", ["--suite", "{t}/no_suite"], ["--suite: ", "no_suite", "does not exist"]),
    ("bench_expected_error", ["--work", "{t}/file.txt", "--assets", "none"], ["--work: ", "existing file"]),
    ("bench_profile", ["--lights", "bogus"], ["--lights: got 'bogus', expected one of"]),
    ("bench_render", ["--res", "2", "--objects", "1", "--images", "1", "--spp", "1", "--families", "directional"],
     ["--res: got 2, expected an integer >= 8"]),
    ("bench_throughput", ["--engines", "w0t1", "--objects", "1", "--res", "8", "--spp", "1", "--images", "1",
                          "--lights", "directional", "--overhead-objects", "1", "--overhead-spp", "1"],
     ["--engines: got 'w0t1', expected w<W>t<T>"]),
    ("bench_verdict", ["{t}/no_capture", "--out", "{t}/r.json"], ["CAPTURE: ", "no_capture", "does not exist"]),
    ("bench_verdict_sweep", ["--objects", "0", "--directional-objects", "0", "--out", "{t}/r.json"],
     ["--objects: got 0"]),
    ("bench_error_evidence", ["--work", "{t}/file.txt", "--out", "{t}/r.json"], ["--work: ", "existing file"]),
    # sweep 20: a flag that would do nothing with the others given is refused, never dropped without a word
    ("learning_curve", ["--target", "10", "{t}/folder"], ["--target 10: used only with --card"]),
    ("bench_capture", ["--reestimate", "{t}/user.json", "--append"], ["--append: used only without --reestimate"]),
    ("bench_capture", ["--reestimate", "{t}/user.json", "--out", "{t}/r.json"], ["--out ", "without --reestimate"]),
    ("bench_doubtful_mask", ["--suite", "{t}/suite", "--rows-from", "{t}/user.json"],
     ["--rows-from ", "used only without --suite"]),
    ("bench_verdict", ["{t}/suite/00000.data", "--no-model", "--refine"], ["--refine: used only with the model's map"]),
    ("learning_curve", [os.fsdecode(b"{t}/run\xe9")], ["RUN: ", "is not UTF-8 text", "rename it"]),
]
"""(script, argv with {t} for the fixture's folder, what the one line says): each refused before any work."""


def _run(stem: str, argv: list[str], capsys) -> tuple[object, str]:
    """(exit status, stderr) of the script's main on `argv`, run in this process."""
    try:
        code = _module(stem).main(argv)
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


@pytest.mark.parametrize("stem,argv,said", BAD, ids=[f"{s}:{' '.join(a)}"[:80] for s, a, _ in BAD])
def test_a_bad_value_is_one_line_naming_its_flag(stem, argv, said, places, capsys):
    code, err = _run(stem, [a.replace("{t}", str(places)) for a in argv], capsys)
    assert code == 2, (code, err)
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    for text in said:
        assert text in err, (text, err)
    assert (places / "user.json").read_text() == '{"mine": 1}\n'  # never replaced
    assert not (places / "w").exists() and not (places / "r.json").exists()  # nothing was made


@pytest.mark.parametrize("stem,argv", [("bench_shards", TINY_SHARDS), ("bench_fit", ["--skip-diligent", "--synthetic",
                                                                                    "0"]),
                                       ("bench_min_images", ["--draws", "1"])])
def test_a_users_file_at_out_is_kept(stem, argv, places, capsys):
    """A JSON file at --out that is no result of the bench (it lacks the keys each of its results writes) is never
    replaced: refused in one line before any work."""
    mine = places / "user.json"
    code, err = _run(stem, ["--out", str(mine), *argv], capsys)
    assert code == 2 and err.count("\n") == 1 and "was not written by python bench/" in err, err
    assert "move it away or use another --out" in err, err
    assert mine.read_text() == '{"mine": 1}\n'


def test_claim_result_replaces_an_earlier_result_and_refuses_the_rest(tmp_path, capsys):
    claim_result = _module("cli_common").claim_result

    earlier = tmp_path / "earlier.json"
    earlier.write_text('{"rows": [], "sizes": {}, "settings": {}}')
    assert claim_result(earlier, ("settings", "sizes", "rows"), "bench X") == earlier  # an earlier result: replaced
    assert claim_result(None, ("rows",), "bench X") is None
    new = tmp_path / "new" / "deeper" / "r.json"
    assert claim_result(new, ("rows",), "bench X") == new and new.parent.is_dir()  # its folder is made
    link = tmp_path / "link.json"
    link.symlink_to(earlier)
    for path, said in ((tmp_path, "existing folder"), (link, "is a link"), (tmp_path / "earlier.json", "lacks"),
                       (earlier / "x.json", "existing file")):
        with pytest.raises(SystemExit) as done:
            claim_result(path, ("rows", "lacks"), "bench X")
        err = capsys.readouterr().err
        assert done.value.code == 2 and err.count("\n") == 1 and err.startswith("error: --out: "), err
        assert said in err or "was not written by bench X" in err, (said, err)
    assert earlier.read_text() == '{"rows": [], "sizes": {}, "settings": {}}'


def test_an_earlier_result_of_the_bench_is_replaced(tmp_path, capsys):
    out = tmp_path / "shards.json"
    out.write_text('{"settings": {"res": 64}, "sizes": {}, "rows": []}')
    code, err = _run("bench_shards", ["--out", str(out), *TINY_SHARDS], capsys)
    assert code == 0, err
    import json

    assert json.loads(out.read_text())["settings"]["res"] == 8


def test_the_smallest_side_is_the_generators():
    MIN_RES = _module("cli_common").MIN_RES
    from wildgen.config import GenConfig

    meta = {f.name: f.metadata for f in dataclasses.fields(GenConfig)}["width"]
    assert MIN_RES in [m.get("minimum") for m in meta.values()]


def test_a_result_is_never_written_inside_a_held_folder_or_an_input(tmp_path, capsys):
    """claim_result refuses a result file inside a folder another run holds (its files would mix with that run's)
    and one inside what the bench reads, each in one line naming the flag, creating nothing."""
    import os

    from scenes.files import folder_lock

    claim_result = _module("cli_common").claim_result
    held = tmp_path / "held"
    held.mkdir()
    fd = folder_lock(held)  # another run's hold (a lock on its own descriptor)
    try:
        with pytest.raises(SystemExit) as stop:
            claim_result(held / "sub" / "r.json", ("rows",), "bench")
    finally:
        os.close(fd)
    assert stop.value.code == 2 and "which another run holds" in capsys.readouterr().err
    assert not (held / "sub").exists()
    (tmp_path / "suite").mkdir()
    with pytest.raises(SystemExit) as stop:
        claim_result(tmp_path / "suite" / "r.json", ("rows",), "bench", inputs={"--suite": tmp_path / "suite"})
    assert stop.value.code == 2 and "lies inside --suite" in capsys.readouterr().err


def test_a_work_folder_another_run_is_writing_is_refused(tmp_path, capsys):
    """check_work refuses a --work that another run holds (wildgen.make rendering into it): the bench's split and
    steps would write among that run's files. One line naming the flag; nothing is created."""
    import os

    from scenes.files import folder_lock

    held = tmp_path / "held"
    held.mkdir()
    fd = folder_lock(held)
    try:
        with pytest.raises(SystemExit) as stop:
            _module("cli_common").check_work(held, "--work")
    finally:
        os.close(fd)
    assert stop.value.code == 2 and "--work: " in (err := capsys.readouterr().err) and "another run" in err, err
    assert os.listdir(held) == []
    _module("cli_common").check_work(held, "--work")  # released: accepted


def test_the_widest_light_angle_of_a_scene_and_a_light_of_no_direction():
    """bench_usable's truth: the largest angle between the view (+z) and a light, from the object's centre; a
    directional light points from the light (its direction is negated). A light of zero length has no direction:
    refused (a ValueError the reader reports naming --suite and scene.json), never a NaN truth."""
    polar = _module("bench_usable").true_max_polar
    scene = {"images": [{"lights": [{"type": "directional", "direction": [0.0, 0.0, -1.0]}]},
                        {"lights": [{"type": "point", "position": [1.0, 0.0, 1.0]}]}]}
    assert polar(scene) == pytest.approx(45.0)
    scene["images"][1]["lights"][0]["position"] = [0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match=r"point light's position is \[0.0, 0.0, 0.0\]"):
        polar(scene)


def test_ab_data_record_keeps_the_arms_another_work_recorded(tmp_path, monkeypatch, capsys):
    """--record adds this WORK's arms to the card's A/B table of the same budget: the arms recorded earlier (from
    other WORK folders) stay, and the new arm's training is appended to the lineage once."""
    import json
    import shutil
    from types import SimpleNamespace

    ab = _module("ab_data")
    card = tmp_path / "model_card.json"
    shutil.copyfile(ab.CARD_PATH, card)
    monkeypatch.setattr(ab, "CARD_PATH", card)
    before = json.loads(card.read_text())
    run = tmp_path / "w" / "run_today_lr9"
    run.mkdir(parents=True)
    val = {"probes": {"all": 20.0, "mask": 30.0}, "gain": 10.0,
           "families": {"directional": {"mean": {"all": 20.0}, "gain": 10.0, "n": 2}}}
    (run / "log.jsonl").write_text(json.dumps({"step": 1, "loss": 1.0, "elapsed_s": 36.0}) + "\n"
                                   + json.dumps({"step": 1, "val": val}) + "\n")
    scores = {"fixed_validation": {"mean_deg": 20.0, "gain_deg": 10.0}, "new_kinds": [{"mean_deg": 25.0}] * 2,
              "diligent": {"ball": {"k96_deg": 5.0, "k16_deg": 6.0}, "cat": {"k96_deg": 9.0, "k16_deg": 10.0}}}
    args = SimpleNamespace(steps=before["data_ab"]["steps"], objects=before["data_ab"]["objects"], threads=1)
    ab.check_card_ab(args)
    ab.record({"shipped": scores, "today_lr9": scores}, tmp_path / "w", args)
    after = json.loads(card.read_text())
    assert set(after["data_ab"]["results"]) == set(before["data_ab"]["results"]) | {"today_lr9"}
    assert after["data_ab"]["results"]["today_lr9"] == scores
    assert [s["stage"] for s in after["lineage"][len(before["lineage"]):]] == ["data A/B: today, lr 9 (not shipped)"]


def test_ab_data_needs_diligent_only_for_an_arm_left_to_score(tmp_path, capsys):
    """A WORK whose ab.json holds every arm's scores (a resumed --record) is not refused for a missing DiLiGenT
    folder: nothing reads it; with an arm left to score it is refused before any work."""
    import json

    ab = _module("ab_data")
    (tmp_path / "assets").mkdir()
    (tmp_path / "w").mkdir()
    argv = ["--work", str(tmp_path / "w"), "--assets", str(tmp_path / "assets"), "--arms", "today", "--diligent",
            str(tmp_path / "none")]
    (tmp_path / "w" / "ab.json").write_text(json.dumps({"shipped": {}}))
    with pytest.raises(SystemExit) as stop:
        ab.before_work(ab.parse(ab.COMMAND, argv))
    assert stop.value.code == 2 and "--diligent: " in capsys.readouterr().err
    (tmp_path / "w" / "ab.json").write_text(json.dumps({"shipped": {}, "today": {}}))
    ab.before_work(ab.parse(ab.COMMAND, argv))  # all scored: accepted


def test_a_file_saved_at_out_during_the_run_is_kept(tmp_path, monkeypatch):
    """A result file absent at the claim that a user (or another program) saves during the run is never replaced:
    the result goes beside it and the run ends in one refusal naming both."""
    import scenes.report.tables as tables
    from scenes.cli.errors import UsageError

    shards = _module("bench_shards")
    out = tmp_path / "b.json"
    table = tables.markdown_table

    def user_saves(*a, **k):  # the user's file lands after the claim, before the result is written
        out.write_text("mine\n")
        return table(*a, **k)

    monkeypatch.setattr(tables, "markdown_table", user_saves)  # bench_shards prints its table with it
    with pytest.raises(UsageError) as refused:
        shards.main(["--out", str(out), *TINY_SHARDS])
    aside = tmp_path / "b.result-1.json"
    assert str(refused.value).startswith("--out: ") and "changed during the run" in str(refused.value)
    assert str(aside) in str(refused.value) and out.read_text() == "mine\n"
    import json

    assert json.loads(aside.read_text())["settings"]["res"] == 8


def test_a_bench_writes_its_result_again_and_every_result_through_write_result(tmp_path):
    """The bench's own writes do not count as another program's (bench_cycles writes its result after every
    resolution), and no bench script writes a claimed result but through write_result."""
    import re

    cli = _module("cli_common")
    out = cli.claim_result(tmp_path / "r.json", ("rows",), "bench X")
    for n in range(3):
        cli.write_result(out, {"rows": [n]})
    assert out.read_text().startswith('{\n "written_by": "bench X",\n "rows": [\n  2')
    for script in (ROOT / "bench").glob("*.py"):
        text = script.read_text()
        if "claim_result(" in text and script.name != "cli_common.py":
            writes = re.findall(r"write_json\((\w[^,]*),", text)
            assert all("work" in w or "job" in w for w in writes), (script.name, writes)


VALID_ROW = {"kind": "auto", "group": "auto_good", "object": "s/00000", "iou_true": 0.97, "doubtful": False,
             "seed_agreement_iou": 0.9, "weak_inside_share": 0.0, "varying_outside_share": 0.0}
RECORDS = [
    ("bench_capture", ["--reestimate", "{t}/r.json"], {"r.json": {"machine": {}, "rows": "abc"}},
     ["--reestimate: ", "r.json", "not a recorded output of this bench"]),
    ("bench_capture", ["--reestimate", "{t}/r.json"], {"r.json": {"machine": {}, "rows": [{"images": 4,
                                                                                             "size": [-64, 48]}]}},
     ["--reestimate: ", "r.json", "size is [-64, 48]"]),
    ("bench_capture", ["--reestimate", "{t}/r.json"], {"r.json": {"machine": {}, "rows": [], "commands": 5}},
     ["--reestimate: ", "r.json"]),
    ("bench_capture", ["--reestimate", "{t}/r.json"],
     {"r.json": '{"machine": {}, "rows": ' + "[" * 100000 + "]" * 100000 + "}"}, ["--reestimate: ", "r.json"]),
    ("learning_curve", ["{t}/run"], {"run/log.jsonl": "5\n"}, ["RUN: ", "log.jsonl", "not a unips.train log"]),
    ("learning_curve", ["{t}/run"], {"run/log.jsonl": ""}, ["RUN: ", "log.jsonl", "no validation record"]),
    ("learning_curve", ["{t}/run"], {"run/log.jsonl": '{"step": 1, "loss": 2.5}\n'},
     ["RUN: ", "log.jsonl", "no validation record"]),
    ("learning_curve", ["{t}/run"], {"run/log.jsonl": '{"step": 1, "val": 5}\n'}, ["RUN: ", "log.jsonl"]),
    ("learning_curve", ["{t}/run"], {"run/log.jsonl": b'\xff\xfe{"step": 1}\n'}, ["RUN: ", "log.jsonl"]),
    ("learning_curve", ["--card", "{t}/c.json"], {"c.json": {"lineage": [{"stage": "s1", "hours": "2"}]}},
     ["--card: ", "c.json", "not a model card"]),
    ("bench_doubtful_mask", ["--rows-from", "{t}/r.json"], {"r.json": {"rows": 5}}, ["--rows-from: ", "r.json"]),
    ("bench_doubtful_mask", ["--rows-from", "{t}/r.json"], {"r.json": {"rows": [{}]}},
     ["--rows-from: ", "r.json", "no 'kind'"]),
    ("bench_doubtful_mask", ["--rows-from", "{t}/r.json", "--record", "{t}/rec.json"],
     {"r.json": {"rows": [VALID_ROW]}, "rec.json": {"good_iou": 0.9, "rows": 5}}, ["--record: ", "rec.json"]),
    ("bench_light_warnings", ["--real", "{t}/real"], {"real/lights.txt": "6\n" + "0.1 0.2\n" * 6},
     ["--real: ", "lights.txt", "6x2 values"]),
    ("bench_light_warnings", ["--real", "{t}/real"], {"real/obj/a.txt": "no lights here\n"},
     ["--real: ", "holds no lights.txt"]),
    ("bench_verdict", ["{t}/pred", "--no-model", "--out", "{t}/v.json"], {"pred/normal.txt": "a prediction's\n"},
     ["CAPTURE: ", "pred"]),
]
"""(script, argv, files written under {t} first (JSON or text), what the one line says): a recorded file the bench
reads that is not of the shape its writer gives (edited, or from an older run) is refused naming its flag and file,
never a traceback (`scenes.files.reading_record`)."""


@pytest.mark.parametrize("stem,argv,files,said", RECORDS, ids=[f"{s}:{i}" for i, (s, *_) in enumerate(RECORDS)])
def test_a_recorded_file_of_another_shape_is_one_line_naming_it(stem, argv, files, said, tmp_path):
    import json
    import subprocess

    for name, content in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        data = content if isinstance(content, (str, bytes)) else json.dumps(content)
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
    before = {n: (tmp_path / n).read_bytes() for n in files}
    proc = subprocess.run([sys.executable, str(ROOT / "bench" / f"{stem}.py"),
                           *[a.replace("{t}", str(tmp_path)) for a in argv]], capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    err = proc.stderr.strip()
    assert proc.returncode == 2 and "Traceback" not in err and len(err.splitlines()) == 1, (proc.returncode, err)
    for text in said:
        assert text in err, (text, err)
    assert {n: (tmp_path / n).read_bytes() for n in files} == before  # nothing it read was rewritten


def test_append_to_the_benchs_own_output_adds_a_row(tmp_path):
    """--append onto the bench's own earlier output (which records its commands) adds the new row and command."""
    import json
    import subprocess

    out = tmp_path / "c.json"
    run = [sys.executable, str(ROOT / "bench" / "bench_capture.py"), "--out", str(out), "--images", "3", "--sides",
           "32", "--format", "png"]
    for extra in ([], ["--append"]):
        proc = subprocess.run([*run, *extra], capture_output=True, text=True, timeout=600, cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
    result = json.loads(out.read_text())
    assert len(result["rows"]) == 2 and len(result["commands"]) == 2, result


def test_a_result_of_another_bench_is_never_replaced(tmp_path, capsys):
    """Most results hold `rows`: the keys alone let one bench replace another's result (sweep 18: bench_doubtful_mask
    --out over bench_capture's). Each result names the bench that wrote it, and no other bench replaces it."""
    import json

    cli = _module("cli_common")
    out = cli.claim_result(tmp_path / "r.json", ("rows",), "python bench/bench_capture.py")
    cli.write_result(out, {"rows": [1]})
    assert json.loads(out.read_text())["written_by"] == "python bench/bench_capture.py"
    with pytest.raises(SystemExit) as stop:
        cli.claim_result(out, ("rows",), "python bench/bench_doubtful_mask.py")
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "was written by python bench/bench_capture.py" in err, err
    assert cli.claim_result(out, ("rows",), "python bench/bench_capture.py") == out  # its own: replaced


@pytest.mark.parametrize("result", sorted(p.name for p in (ROOT / "bench" / "results").glob("*.json")))
def test_a_committed_result_names_its_bench_and_no_other_bench_replaces_it(result, tmp_path, capsys):
    """Every committed result says which bench wrote it, a script that exists: a copy given to another bench's
    --out (or to bench_doubtful_mask's --out, for its --record file) is refused, never replaced."""
    import json
    import shutil

    writer = json.loads((ROOT / "bench" / "results" / result).read_text())["written_by"]
    script = writer.split()[1]
    assert writer.startswith("python bench/") and (ROOT / script).is_file(), writer
    copy = tmp_path / result
    shutil.copyfile(ROOT / "bench" / "results" / result, copy)
    other = ("python bench/bench_doubtful_mask.py" if script != "bench/bench_doubtful_mask.py" or "--record" in writer
             else "python bench/bench_capture.py")
    with pytest.raises(SystemExit) as stop:
        _module("cli_common").claim_result(copy, ("rows",), other)
    assert stop.value.code == 2 and f"was written by {writer}" in capsys.readouterr().err


def test_a_relative_path_is_the_folder_the_bench_was_started_in(tmp_path, monkeypatch):
    """Bench steps run with the repository as their working folder: a relative --work or --keep is made absolute
    against the folder the bench was started in before any step sees it (sweep 18: the suite landed in the repo)."""
    monkeypatch.chdir(tmp_path)
    cli = _module("cli_common")
    sweep = cli.parse(_command("bench_verdict_sweep"), ["--work", "w", "--out", "v.json"])
    assert sweep.work == str(tmp_path / "w") and Path(sweep.out) == tmp_path / "v.json"
    keep = cli.parse(_command("bench_throughput"), ["--keep", "k"])
    assert keep.keep == str(tmp_path / "k")


def test_learning_curve_reads_the_card_ship_writes(tmp_path):
    """A relay run's lineage entry (orchestrate.ship) records no hours or steps where the session did not: the
    curve counts none for it, where it refused the card ship itself wrote (sweep 18)."""
    import json
    import subprocess

    card = json.loads((ROOT / "unips" / "weights" / "model_card.json").read_text())
    card["lineage"].append({"stage": "GPU relay run (orchestrate.gpu_session, orchestrate.ship)", "hours": None,
                            "steps": None, "shipped": True})
    (tmp_path / "c.json").write_text(json.dumps(card))
    script = str(ROOT / "bench" / "learning_curve.py")
    proc = subprocess.run([sys.executable, script, "--card", str(tmp_path / "c.json")], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0 and "| GPU relay run" in proc.stdout, proc.stderr


def test_learning_curve_says_a_flat_trend_reaches_the_target_never_in_practice(tmp_path):
    """Three stages whose error falls by 1e-8 deg: the hours to the target overflow a float; the table says so
    ('over 1e18'), never calling the card damaged (sweep 18's re-run: 'not a model card ... OverflowError')."""
    import json
    import subprocess

    def stage(name, error):
        return {"stage": name, "hours": 1, "steps": 100, "data": "d", "fixed_validation": {"all": error, "gain": 1.0},
                "per_family_at_best": {"directional": {"all": error}}}

    card = {"lineage": [stage("s1", 20.0), stage("s2", 19.99999999), stage("s3", 19.99999998)]}
    (tmp_path / "c.json").write_text(json.dumps(card))
    script = str(ROOT / "bench" / "learning_curve.py")
    proc = subprocess.run([sys.executable, script, "--card", str(tmp_path / "c.json")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0 and "| directional | 20.00 | 0.00 |" in proc.stdout, proc.stderr
    assert "| over 1e18 |" in proc.stdout, proc.stdout


def test_a_pipe_given_for_a_recorded_file_is_said_as_such(tmp_path, capsys):
    """need_path said 'is a folder' of a named pipe (sweep 18); it names what the path is, never opening it."""
    import os

    os.mkfifo(tmp_path / "p.json")
    with pytest.raises(SystemExit) as stop:
        _module("cli_common").need_path(tmp_path / "p.json", "--reestimate", "a recorded output", folder=False)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "is neither a file nor a folder (a pipe" in err, err
