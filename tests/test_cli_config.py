"""Every CLI is its config dataclass read by tyro (`scenes.cli.options.Command`): a flag per field, help from the
field's docstring, defaults written once (in the dataclass), one set of option checks, errors of one line."""
from __future__ import annotations

import dataclasses
import importlib
import typing

import pytest
import tyro

from scenes.checks import check_choice, check_int, check_number
from scenes.cli.errors import UsageError
from scenes.cli.options import Command, undocumented_fields
from scenes.cli.outputs import check_listed, check_output_folder, listed_names, make_output_folder

# Each CLI module and the dataclass its command line is generated from.
CLIS = {
    "wildgen.make": "MakeOptions",
    "wildgen.preview": "PreviewOptions",
    "wildgen.sensor": "SensorOptions",
    "wildgen.export": "ExportOptions",
    "unips.train": "TrainConfig",
    "unips.predict": "PredictOptions",
    "unips.evaluate": "EvaluateOptions",
    "validate.rerender": "RerenderOptions",
    "validate.refine": "RefineOptions",
    "orchestrate.benchmark": "BenchmarkOptions",
    "orchestrate.train_recipe": "RecipeOptions",
    "orchestrate.demo": "DemoOptions",
    "orchestrate.gpu_session": "SessionOptions",
    "orchestrate.error_calibration": "CalibrationOptions",
}


def _leaves(cls: type) -> dict[str, object]:
    """Field name -> default of every non-nested field of `cls` and of its nested configs."""
    out = {}
    for f in dataclasses.fields(cls):
        value = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        out.update(_leaves(type(value)) if dataclasses.is_dataclass(value) else {f.name: value})
    return out


@pytest.mark.parametrize("module", sorted(CLIS))
def test_every_field_is_documented_and_the_empty_command_line_gives_the_dataclass_defaults(module):
    mod = importlib.import_module(module)
    cls = getattr(mod, CLIS[module])
    assert undocumented_fields(cls) == []
    assert isinstance(mod.COMMAND, Command) and mod.COMMAND.config is cls
    required = [name for name, value in _leaves(cls).items() if value is tyro.MISSING]
    if required:  # a command line without them is one UsageError naming each
        with pytest.raises(UsageError, match="required: " + ".*".join("--" + n.replace("_", "-") for n in required)):
            mod.COMMAND.parse([])
    given = {n: _a_value(cls, n) for n in required}
    parsed = _leaves_of(mod.COMMAND.parse([a for n, v in given.items() for a in ("--" + n.replace("_", "-"), v)]))
    for name, value in _leaves(cls).items():
        assert parsed[name] == value or str(parsed[name]) == given.get(name), (module, name)
    flags = mod.COMMAND.flags()
    assert all(flag.startswith("--") or flag.isupper() for flag in flags.values()), flags
    for flag in flags.values():  # every flag is in --help
        assert flag in mod.COMMAND.help() or flag.isupper(), (module, flag)


def _a_value(cls: type, name: str) -> str:
    """A value a required field accepts: its first choice when it has choices, else 'x'."""
    hint = typing.get_type_hints(cls, include_extras=True)[name]
    return str(typing.get_args(hint)[0]) if typing.get_origin(hint) is typing.Literal else "x"


def _leaves_of(cfg) -> dict[str, object]:
    out = {}
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        out.update(_leaves_of(value) if dataclasses.is_dataclass(value) else {f.name: value})
    return out


def test_rerender_and_refine_defaults_come_from_the_fit_config():
    """No default restated by hand: the fitted mode's flags are FitConfig's fields, in both CLIs."""
    from validate import refine, rerender
    from validate.fitted.fit import FitConfig

    for mod in (rerender, refine):
        opts = mod.COMMAND.parse(["--data", "d", "--normals", "n"])
        fit = opts.fitted if mod is rerender else opts.refine.fit
        for name in ("steps", "max_pixels", "light_model", "seed"):
            assert getattr(fit, name) == getattr(FitConfig(), name), (mod.__name__, name)
    assert "floor_maps" not in refine.COMMAND.flags()  # refine computes no floor
    with pytest.raises(UsageError, match="--floor-maps"):
        refine.COMMAND.parse(["--data", "d", "--normals", "n", "--floor-maps", "constant"])
    opts = refine.COMMAND.parse(
        ["--data", "d", "--normals", "n", "--steps", "7", "--refine-steps", "3", "--holdout", "0.2", "--no-shadows"])
    assert (opts.refine.fit.steps, opts.refine.refine_steps, opts.refine.holdout_fraction) == (7, 3, 0.2)
    assert opts.refine.fit.shadows is False and opts.refine.fit.specular is True
    opts = rerender.COMMAND.parse(
        ["--data", "d", "--normals", "n", "--floor-maps", "constant,silhouette", "--supersample", "3", "--no-floors"])
    assert opts.fitted.floor_maps == ("constant", "silhouette") and opts.check.visibility.supersample == 3
    assert opts.check.floors is False
    with pytest.raises(UsageError, match="--base-tolerance"):  # the visibility tolerances are not flags
        rerender.COMMAND.parse(["--data", "d", "--normals", "n", "--base-tolerance", "1"])


def test_generator_fields_reach_the_config_and_a_repeated_list_flag_adds_up():
    from wildgen.make import COMMAND, options_from_args

    argv = ["--out", "o", "--margin", "0.1", "--max-backfacing", "0.25", "--res", "48", "--lights", "point",
            "--lights", "hdri,mixed", "--variant", "auto", "--ray"]
    opts = options_from_args(argv)
    gen = opts.gen.validate()
    assert (gen.margin, gen.max_backfacing, gen.width, gen.height) == (0.1, 0.25, 48, 48)
    assert gen.lights == ["point", "hdri", "mixed"] and gen.variant is None  # a repeated list replaces the default
    assert opts.ray == "auto"  # --ray without its value
    assert options_from_args(["--out", "o", "--ray", "h:1"]).ray == "h:1"
    assert options_from_args(["--out", "o"]).gen.lights == ["near_area"]
    assert COMMAND.given(["--out", "o", "--margin=0.1", "--quiet"]) == {"out", "margin", "quiet"}


def test_a_command_line_read_from_sys_argv_keeps_its_given_flags(monkeypatch):
    """`python -m wildgen.make` reads sys.argv: the flags typed there win over a preset, as with an argv list."""
    from wildgen.make import COMMAND, _explicit_flags, options_from_args

    argv = ["--out", "o", "--preset", "phone-flash", "--images", "4"]
    monkeypatch.setattr("sys.argv", ["python -m wildgen.make", *argv])
    assert COMMAND.given(None) == {"out", "preset", "images"} == _explicit_flags(None)
    gen = options_from_args(None, _explicit_flags(None)).gen.validate()
    assert gen.images == 4 and gen.lights == ["flash"]


def test_one_set_of_checks_names_the_flag_the_value_and_what_was_expected():
    assert check_int(3, "--n", minimum=1) == 3
    for bad in (0, 2.5, True, "3", None):
        with pytest.raises(ValueError, match=r"^--n: got .*, expected an integer >= 1$"):
            check_int(bad, "--n", minimum=1)
    with pytest.raises(ValueError, match=r"^--p: got nan, expected a number in \[0, 0.5\)$"):
        check_number(float("nan"), "--p", minimum=0, below=0.5)
    with pytest.raises(ValueError, match=r"^--lr: got 0, expected a number > 0$"):
        check_number(0, "--lr", above=0)
    with pytest.raises(ValueError, match=r"^--m: got 'x', expected one of a, b$"):
        check_choice("x", "--m", ("a", "b"))


def test_scene_fields_are_checked_by_the_same_rule_as_flags():
    """A field of a scene description is refused in the same words as a flag: `owner.field: got X, expected Y`."""
    from scenes.description import CameraDesc, ImageDesc
    from scenes.lights import DirectionalLight

    with pytest.raises(ValueError, match=r"^camera.fov: got -1.0, expected a number > 0$"):
        CameraDesc(kind="perspective", fov=-1.0).validate()
    with pytest.raises(ValueError, match=r"^camera.kind: got 'fisheye', expected one of orthographic, perspective$"):
        CameraDesc(kind="fisheye").validate()
    with pytest.raises(ValueError, match=r"^images\[0\].lights\[0\].irradiance: got nan, expected a number >= 0$"):
        ImageDesc(lights=[DirectionalLight(irradiance=float("nan"))]).validate(0)
    with pytest.raises(
        ValueError, match=r"^images\[0\].lights\[0\].direction: got \[0, 0, 0\], expected a non-zero vector$"
    ):
        ImageDesc(lights=[DirectionalLight(direction=[0, 0, 0])]).validate(0)


def test_output_folder_is_checked_without_creating_anything(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(UsageError, match="--out: .*file.* is an existing file"):
        check_output_folder(tmp_path / "file")
    with pytest.raises(UsageError, match="--work: cannot create the folder .*is a file"):
        check_output_folder(tmp_path / "file" / "sub", "--work")
    assert check_output_folder(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists()
    make_output_folder(tmp_path / "new" / "deeper")
    assert (tmp_path / "new" / "deeper").is_dir()
    with pytest.raises(UsageError, match="--out: .*is an existing file"):
        make_output_folder(tmp_path / "file")


def test_a_config_error_in_a_parser_is_one_usage_error():
    from unips.train import COMMAND

    with pytest.raises(UsageError, match="--steps"):
        COMMAND.parse(["--data", "d", "--out", "o", "--steps", "many"])
    with pytest.raises(UsageError, match="--counts"):
        importlib.import_module("orchestrate.benchmark").COMMAND.parse(["--counts", "1,x"])
    with pytest.raises(UsageError, match="^unrecognized arguments: --colour$"):
        COMMAND.parse(["--data", "d", "--out", "o", "--colour"])
    with pytest.raises(UsageError, match="^--schedule: got 'linear', expected one of cosine, step$"):
        COMMAND.parse(["--data", "d", "--out", "o", "--schedule", "linear"])


def test_names_read_from_an_earlier_record_are_plain_names_and_only_listed_files_are_replaced(tmp_path):
    """An earlier run's record lists the files it wrote; a name read from it is untrusted (only a plain name in
    the folder counts), and an existing output it does not list is the user's: refused, even with --overwrite."""
    import json

    record = tmp_path / "report.json"
    record.write_text(json.dumps({"renders": ["R000.png", "../R001.png", "/tmp/R002.png", "a/R003.png", ".", "..",
                                              "", 7, "a\\R004.png"]}))
    assert listed_names(record, "renders") == {"R000.png"}
    assert listed_names(tmp_path / "none.json", "renders") == set()
    record.write_text('{"renders": "R000.png"}')  # not a list: nothing listed
    assert listed_names(record, "renders") == set()
    record.write_text('{"renders": ["R000.png"]}')
    (tmp_path / "R000.png").write_text("earlier")
    (tmp_path / "R001.png").write_text("the user's")
    assert check_listed([tmp_path / "R000.png"], record, "renders", "validate.rerender") == {"R000.png"}
    with pytest.raises(UsageError, match=r"^--out: .*R001.png' was not written by validate.rerender .*never replaced"):
        check_listed([tmp_path / "R000.png", tmp_path / "R001.png"], record, "renders", "validate.rerender")


def test_the_file_systems_root_is_never_an_output_folder(tmp_path):
    """`--out /` (or a link to it) would mix a command's files with the system's and hold '/' for every other run."""
    (tmp_path / "root").symlink_to("/")
    for path in ("/", tmp_path / "root"):
        with pytest.raises(UsageError, match=r"^--out: .* is the file system's root; expected a folder of its own"):
            check_output_folder(path)


@pytest.fixture
def mounted_twice(tmp_path):
    """(the folder, the same folder bind-mounted at another path); skipped where this process may not mount."""
    import shutil
    import subprocess

    folder, alias = tmp_path / "data", tmp_path / "alias"
    folder.mkdir()
    alias.mkdir()
    (folder / "input.txt").write_text("the user's input\n")
    if shutil.which("mount") is None or subprocess.run(["mount", "--bind", str(folder), str(alias)],
                                                       capture_output=True).returncode != 0:
        pytest.skip("cannot bind-mount here (needs root)")
    try:
        yield folder, alias
    finally:
        subprocess.run(["umount", str(alias)], check=False)


def test_an_output_inside_its_input_under_another_name_is_refused(mounted_twice):
    """A bind mount makes one folder two paths that no link tells apart (sweep 19: sensor --overwrite through the
    mount deleted its own input; predict and surface wrote into theirs). The output is compared with each input by
    device and inode too, for the output folder and every existing folder above it."""
    from scenes.cli.errors import UsageError
    from scenes.cli.outputs import check_apart, output_lock

    folder, alias = mounted_twice
    for out in (alias, alias / "p", alias / "p" / "q"):
        with pytest.raises(UsageError, match=r"^--out: .* --data .* under another name \(the same folder, "
                                             r"mounted twice\)"):
            check_apart(out, {"--data": folder})
        with pytest.raises(UsageError, match="under another name"):
            with output_lock(out, inputs={"--data": folder}):
                pass
    with pytest.raises(UsageError, match="is the folder --normals .* lies in"):  # beside an input file, by its mount
        check_apart(alias, {"--normals": folder / "input.txt"})
    assert sorted(p.name for p in folder.iterdir()) == ["input.txt"]  # nothing created in it
    check_apart(folder.parent / "elsewhere", {"--data": folder})  # a folder apart: accepted


def _commands() -> list[tuple[str, Command]]:
    """(name, COMMAND) of every CLI of the docs and every bench script."""
    from pathlib import Path

    from orchestrate.docs import CLIS

    bench = sorted(f"bench.{p.stem}" for p in (Path(__file__).resolve().parents[1] / "bench").glob("*.py")
                   if "\nCOMMAND = Command(" in p.read_text())
    return [(m, importlib.import_module(m).COMMAND) for m in (*CLIS, *bench)]


def test_every_needs_names_a_flag_of_its_command_and_reads_fields_it_has():
    """A `Needs` whose field is no flag of its command would never fire (a typo makes the rule inert), and one whose
    rule reads a field the config lacks would fail with a traceback only when its flag is given."""
    seen = 0
    for name, command in _commands():
        flags = command.flags()
        cfg = command.config()  # every field has a default (REQUIRED is a marker value)
        for need in command.needs:
            seen += 1
            assert need.field in flags, (name, need.field)
            assert isinstance(need.acts(cfg, {need.field}), bool), (name, need.field)
    assert seen >= 30


@pytest.mark.parametrize("module,argv,said", [
    ("unips.train", ["--data", "d", "--out", "o", "--val-every", "5"], "--val-every 5: used only with --val"),
    ("unips.train", ["--data", "d", "--out", "o", "--warmup", "5", "--schedule", "step"],
     "--warmup 5: used only with --schedule cosine"),
    ("unips.predict", ["--method", "least-squares", "--input", "i", "--out", "o", "--expected-error"],
     "--expected-error: used only with --method model"),
    ("wildgen.make", ["--out", "o", "--workers", "0", "--recycle-after", "3"], "--recycle-after 3: used only with "
     "worker processes"),
    ("wildgen.make", ["--out", "o", "--shapes", "mesh", "--shape-kinds", "blob"], "--shape-kinds blob"),
    ("wildgen.sensor", ["--data", "d", "--out", "o", "--sensor", "ideal", "--seed", "3"],
     "--seed 3: used only with a sensor that adds noise"),
    ("validate.refine", ["--data", "d", "--normals", "n", "--holdout", "0", "--patience", "2"],
     "--patience 2: used only with --holdout above 0"),
    ("validate.refine", ["--data", "d", "--normals", "n", "--downsample", "2", "--max-pixels", "100"],
     "--max-pixels 100: used only without --downsample"),
    ("validate.rerender", ["--data", "d", "--normals", "n", "--min-coverage", "0.5"],
     "--min-coverage 0.5: used only with --allow-missing"),
    ("orchestrate.benchmark", ["--diligent", "d", "--counts", "1,2"], "--counts 1,2: used only with --data"),
    ("bench.bench_rerender", ["--data", "d", "--res", "16"], "--res 16: used only without --data"),
    ("orchestrate.train_recipe", ["--work", "w", "--init-from", "m.safetensors", "--model", "glc-small"],
     "--model glc-small: used only without --init-from"),
    ("validate.rerender", ["--data", "d", "--normals", "n", "--fit", "--interreflection", "--ao-rays", "0"],
     "--interreflection: used only with --ao-rays above 0"),
    ("orchestrate.gpu_session", ["--out", "o", "--check-variant", "none", "--noise-cv", "2"],
     "--noise-cv 2: used only with the check on"),
    ("orchestrate.benchmark", ["--data", "d", "--diligent-subset", "4"], "--diligent-subset 4: used only with "
     "--diligent"),
])
def test_a_flag_that_would_do_nothing_is_refused_in_one_line(module, argv, said):
    """Sweeps 20 and 21: a flag given with settings under which it acts not at all was dropped without a word."""
    command = importlib.import_module(module).COMMAND
    with pytest.raises(UsageError) as caught:
        command.check_needs(command.parse(argv), argv)  # wildgen.make's parse leaves it to the resolved config
    assert str(caught.value).startswith(said), caught.value
    assert "leave it out" in str(caught.value)


def test_a_flag_given_at_its_default_passes_and_a_refusal_names_the_flag_as_typed():
    """Sweep 22's drafts: `--no-rotation-search --no-refine` asks for nothing the capture would not do and passes;
    a switch turned on that cannot act is refused, named as the user typed it (`--no-cushions`, not `--cushions`)."""
    from orchestrate.capture import COMMAND as CAPTURE

    assert not CAPTURE.parse(["--input", "i", "--out", "o", "--no-refine", "--no-rotation-search"]).rotation_search
    command = importlib.import_module("bench.bench_doubtful_mask").COMMAND
    with pytest.raises(UsageError, match=r"^--no-cushions: used only without --rows-from"):
        command.parse(["--rows-from", "r.json", "--no-cushions"])


def test_a_path_that_leads_to_a_name_that_is_not_text_is_refused(tmp_path, monkeypatch):
    """A link whose own name is text, to a folder named with a Latin-1 byte: refused naming the flag and where it
    leads (sweep 22's drafts: a capture through such a link died in matplotlib); and a TMPDIR so named."""
    import os

    from orchestrate.capture import COMMAND as CAPTURE

    real = os.fsdecode(os.fsencode(tmp_path) + b"/ph\xe9")
    os.mkdir(real)
    os.symlink(real, tmp_path / "plnk")
    with pytest.raises(UsageError, match=r"^--input: .*plnk' leads to .*is not UTF-8 text \(byte 0xE9\)"):
        CAPTURE.parse(["--input", str(tmp_path / "plnk"), "--out", "o"])
    monkeypatch.setenv("TMPDIR", real)
    with pytest.raises(UsageError, match=r"^TMPDIR \(environment\): .*rename it"):
        CAPTURE.parse(["--input", "i", "--out", "o"])
    with pytest.raises(SystemExit) as helped:  # --help reads no path: it prints the help whatever TMPDIR is named
        CAPTURE.parse(["--input", "i", "--help"])
    assert helped.value.code == 0
