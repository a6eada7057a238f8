"""Flags that act only together with another setting (`--decay-every` with `--schedule step`, `--rotation-search`
with the refinement on): a command lists them as `Needs` in its `Command`, and a command line giving such a flag
without what it needs is refused in one line, never run with the flag dropped without a word.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Needs:
    """A flag (its field) that acts only where `acts(config, given)` holds (`given`: the fields on the command
    line); `only` says where, after "used only" ("with --schedule step", "without --suite")."""

    field: str
    acts: Callable[[Any, set[str]], bool]
    only: str
    anyway: tuple = ()
    """Values that ask for what happens anyway where the rule does not hold (`--loader-workers 0`: no worker
    process, as in-memory data has): given, they pass."""


def check_needs(needs: Iterable[Needs], cfg: Any, given: set[str], flags: dict[str, str]) -> None:
    """A UsageError naming the first flag of `given` whose `Needs` does not hold (`flags`: field -> the flag as
    typed). A flag given at its default asks for nothing the command would not do anyway and passes
    (`--no-rotation-search` with `--no-refine`), except a switch turned on (`--interreflection` with `--ao-rays 0`
    asks for what cannot happen)."""
    from scenes.cli.errors import UsageError

    defaults = _defaults(cfg)
    for need in needs:
        if need.field in given and not need.acts(cfg, given):
            value = value_of(cfg, need.field)
            if value in need.anyway:
                continue
            if need.field in defaults and value == defaults[need.field] and value is not True:
                continue
            if isinstance(value, (list, tuple)):  # a comma list, as typed
                value = ",".join(map(str, value))
            shown = "" if isinstance(value, bool) else f" {value:g}" if isinstance(value, float) else f" {value}"
            raise UsageError(f"{flags[need.field]}{shown}: used only {need.only}, so here it would do nothing; leave "
                             "it out, or give what it needs")


def value_of(cfg: Any, name: str) -> Any:
    """The value of field `name` of `cfg` or of a config nested in it (None when there is none)."""
    if hasattr(cfg, name):
        return getattr(cfg, name)
    nested = (v for v in vars(cfg).values() if dataclasses.is_dataclass(v))
    return next((v for v in (value_of(n, name) for n in nested) if v is not None), None)


def _defaults(cfg: Any) -> dict[str, Any]:
    """Field name -> default of every field of the config `cfg` and of the configs nested in it."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        if dataclasses.is_dataclass(value):
            out.update(_defaults(value))
        elif f.default is not dataclasses.MISSING:
            out.setdefault(f.name, f.default)
        elif f.default_factory is not dataclasses.MISSING:
            out.setdefault(f.name, f.default_factory())
    return out
