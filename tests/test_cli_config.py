"""Every CLI is generated from its config dataclass (`scenes.config`): a flag per field, help from the field's
docstring, defaults written once (in the dataclass), one set of option checks."""
from __future__ import annotations

import argparse
import importlib

import pytest

from scenes.cli import UsageError, UsageErrorParser, check_output_folder, make_output_folder
from scenes.config import (check_choice, check_int, check_number, config_from_args, flag_name, flagged_fields,
                           given_flags, is_switch, undocumented_fields)

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
}


@pytest.mark.parametrize("module", sorted(CLIS))
def test_every_field_is_documented_and_is_a_flag_with_the_dataclass_default(module):
    mod = importlib.import_module(module)
    cls = getattr(mod, CLIS[module])
    assert undocumented_fields(cls) == []
    parser = mod.build_parser()
    assert isinstance(parser, UsageErrorParser)  # errors are one line, never argparse's usage + exit
    actions = {a.dest: a for a in parser._actions}
    for f, default in flagged_fields(cls):
        action = actions.get(f.name)
        assert action is not None, f"{module}: {f.name} has no flag"
        assert flag_name(f) in action.option_strings or not action.option_strings, (module, f.name)
        if is_switch(f):
            assert action.default is (default is True), (module, f.name)
        elif isinstance(default, (list, tuple)):
            assert list(action.default) == list(default), (module, f.name)
        else:
            assert action.default == default, (module, f.name)
        assert action.help, (module, f.name)


def test_rerender_and_refine_defaults_come_from_the_fit_config():
    """No default restated by hand: the fitted mode's flags are FitConfig's fields, in both CLIs."""
    from validate import refine, rerender
    from validate.fit import FitConfig

    for mod in (rerender, refine):
        actions = {a.dest: a for a in mod.build_parser()._actions}
        for name in ("steps", "max_pixels", "light_model", "seed"):
            assert actions[name].default == getattr(FitConfig(), name), (mod.__name__, name)
    assert "floor_maps" not in {a.dest for a in refine.build_parser()._actions}  # refine computes no floor
    opts = config_from_args(refine.RefineOptions, refine.build_parser().parse_args(
        ["--data", "d", "--normals", "n", "--steps", "7", "--refine-steps", "3", "--holdout", "0.2", "--no-shadows"]))
    assert (opts.refine.fit.steps, opts.refine.refine_steps, opts.refine.holdout_fraction) == (7, 3, 0.2)
    assert opts.refine.fit.shadows is False and opts.refine.fit.specular is True
    opts = config_from_args(rerender.RerenderOptions, rerender.build_parser().parse_args(
        ["--data", "d", "--normals", "n", "--floor-maps", "constant,silhouette", "--supersample", "3", "--no-floors"]))
    assert opts.fitted.floor_maps == ("constant", "silhouette") and opts.check.visibility.supersample == 3
    assert opts.check.floors is False


def test_generator_fields_without_a_flag_before_have_one_and_reach_the_config():
    from wildgen.make import build_parser, options_from_args

    opts = options_from_args(build_parser().parse_args(
        ["--out", "o", "--margin", "0.1", "--max-backfacing", "0.25", "--res", "48", "--lights", "point",
         "--lights", "hdri,mixed", "--variant", "auto"]))
    gen = opts.gen.validate()
    assert (gen.margin, gen.max_backfacing, gen.width, gen.height) == (0.1, 0.25, 48, 48)
    assert gen.lights == ["point", "hdri", "mixed"] and gen.variant is None  # a repeated list replaces the default
    assert options_from_args(build_parser().parse_args(["--out", "o"])).gen.lights == ["near_area"]
    assert given_flags(build_parser, ["--out", "o", "--margin", "0.1", "--quiet"]) == {"out", "margin", "quiet"}


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
    from unips.train import build_parser

    with pytest.raises(UsageError, match="--steps"):
        build_parser().parse_args(["--data", "d", "--out", "o", "--steps", "many"])
    with pytest.raises(UsageError, match="--counts"):
        importlib.import_module("orchestrate.benchmark").build_parser().parse_args(["--counts", "1,x"])
    assert isinstance(build_parser(), argparse.ArgumentParser)
