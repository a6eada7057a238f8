"""The bench scripts read their command lines through the toolkit's tyro CLI (`scenes.cli.options.Command`): each
script's `--help` works, a bad option is one line, and every command line quoted for a script (in docs/, README.md
and the scripts' own docstrings) still parses, to the values its flags say; a bench stopped by a signal ends
through its own clean-up in one line."""
from __future__ import annotations

import ast
import dataclasses
import importlib
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
    proc = subprocess.Popen([sys.executable, "bench/bench_render.py", "--res", "64", "--spp", "16", "--images", "4",
                             "--objects", "5000", "--families", "directional"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "TMPDIR": str(tmp)})
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
