"""Command lines generated from config dataclasses, and the one set of option checks every config uses.

A CLI describes its options as a dataclass: one field per option, its documentation the string literal
under the field (an attribute docstring), its checks and command-line details in `option(...)`. A field
whose default is another config dataclass is nested: its fields become flags of the same command line
(a CLI that combines two configs, e.g. the re-render check and the scene fit). Then

    parser = config_parser(Options, prog="python -m pkg.cli", description="...")
    opts = config_from_args(Options, parser.parse_args(argv))   # an Options instance, nested configs built
    opts.validate()                                              # check_fields(self) + cross-field rules

`--help` shows every field's docstring and its default, so a default is written once, in the dataclass.
Checks (`check_fields`, or `check_int` / `check_number` / `check_choice` on a single value) raise
ValueError with one line naming the flag, the value and what was expected, e.g.
`--steps: got 0, expected an integer >= 1`; `scenes.cli.report_error` prints it.
"""
from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import math
import numbers
import textwrap
from typing import Any, Callable, Iterable, Sequence

_KEY = "scenes.config"  # the dataclass-field metadata key of `option`


def option(default: Any = dataclasses.MISSING, *, default_factory: Any = dataclasses.MISSING,
           flag: str | None = None, minimum: float | None = None, maximum: float | None = None,
           above: float | None = None, below: float | None = None, choices: Sequence[Any] | None = None,
           required: bool = False, positional: bool = False, cli: bool = True, sep: str | None = None,
           repeat: bool = False, parse: Callable[[str], Any] | None = None, metavar: str | None = None,
           default_text: str | None = None, expose: Sequence[str] | None = None,
           group: str | None = None, short: str | None = None, argparse_kwargs: dict | None = None) -> Any:
    """A dataclass field with its command-line details and checks.

    flag: the option name (default `--field-name`; a bool field whose default is True gets `--no-field-name`).
    minimum / maximum: inclusive bounds; above / below: exclusive bounds (numbers are also checked finite).
    choices: allowed values (of each element for a list). required / positional: as in argparse.
    cli: False keeps the field off the command line. sep: a list option's values are split at `sep`
    (default ','; '' keeps each value whole); repeat: the flag may be given several times, the values add up
    (the first use replaces the default).
    parse: converts the string the user typed (the default of a flag is shown as the dataclass default).
    default_text: what `--help` says for the default instead of the value (e.g. "the recorded spp").
    expose: for a nested config, the names of its fields that become flags (default: all of them).
    group: the title of the `--help` section of the flag (of every flag of a nested config).
    short: a one-letter alias such as "-v".
    """
    meta = {"flag": flag, "minimum": minimum, "maximum": maximum, "above": above, "below": below,
            "choices": tuple(choices) if choices is not None else None, "required": required,
            "positional": positional, "cli": cli, "sep": sep,
            "repeat": repeat, "parse": parse, "metavar": metavar, "default_text": default_text,
            "expose": tuple(expose) if expose is not None else None, "group": group, "short": short,
            "argparse": dict(argparse_kwargs or {})}
    kwargs: dict[str, Any] = {"metadata": {_KEY: meta}}
    if default_factory is not dataclasses.MISSING:
        kwargs["default_factory"] = default_factory
    else:
        kwargs["default"] = default
    return dataclasses.field(**kwargs)


def _meta(f: dataclasses.Field) -> dict:
    return f.metadata.get(_KEY, {})


def flag_name(f: dataclasses.Field) -> str:
    """The command-line name of a field (`--out`, `--no-floors`, or the positional's name)."""
    meta = _meta(f)
    if meta.get("flag"):
        return meta["flag"]
    if meta.get("positional"):
        return f.name.upper()
    name = f.name.replace("_", "-")
    return f"--no-{name}" if _base_type(f) == "bool" and _default(f) is True else f"--{name}"


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        return f.default_factory()  # type: ignore[misc]
    return None


def _base_type(f: dataclasses.Field) -> str:
    """'int', 'float', 'str', 'bool', 'list' (of str) or 'nested' (a config dataclass), from the annotation."""
    if dataclasses.is_dataclass(_default(f)):
        return "nested"
    text = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))
    parts = [p.strip() for p in text.split("|") if p.strip() != "None"]
    base = parts[0] if parts else "str"
    if base.startswith(("list", "tuple", "Sequence")):
        return "list"
    return base if base in ("int", "float", "bool") else "str"


def _item_type(f: dataclasses.Field) -> str:
    """'int', 'float' or 'str': the element type of a list field (from its annotation)."""
    text = f.type if isinstance(f.type, str) else str(f.type)
    inner = text[text.find("[") + 1:] if "[" in text else ""
    return next((t for t in ("int", "float") if inner.startswith(t)), "str")


def field_docs(cls: type) -> dict[str, str]:
    """Attribute docstrings of a dataclass (the string literal after each field), by field name; the
    dataclasses it inherits from are read too."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass) or klass is object:
            continue
        try:
            source = textwrap.dedent(inspect.getsource(klass))
        except (OSError, TypeError):
            continue
        body = ast.parse(source).body[0].body  # type: ignore[attr-defined]
        for prev, node in zip(body, body[1:]):
            if (isinstance(prev, ast.AnnAssign) and isinstance(prev.target, ast.Name) and isinstance(node, ast.Expr)
                    and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)):
                docs[prev.target.id] = " ".join(node.value.value.split())
    return docs


def undocumented_fields(cls: type) -> list[str]:
    """Fields of `cls` and of its nested configs without a docstring (a test keeps this empty)."""
    docs = field_docs(cls)
    missing = [f"{cls.__name__}.{f.name}" for f in dataclasses.fields(cls) if f.name not in docs]
    for f in dataclasses.fields(cls):
        if _base_type(f) == "nested":
            missing += undocumented_fields(type(_default(f)))
    return missing


def flagged_fields(cls: type, only: Sequence[str] | None = None) -> Iterable[tuple[dataclasses.Field, Any]]:
    """(field, its default) of every field of `cls` that has a flag, the fields of nested configs included."""
    for f in dataclasses.fields(cls):
        meta = _meta(f)
        if not meta.get("cli", True) or (only is not None and f.name not in only):
            continue
        if _base_type(f) == "nested":
            yield from flagged_fields(type(_default(f)), meta.get("expose"))
        else:
            yield f, _default(f)


def is_switch(f: dataclasses.Field) -> bool:
    """A bool field: a flag without a value."""
    return _base_type(f) == "bool"


# ---------------------------------------------------------------- checks


def check_int(value: Any, name: str, minimum: float | None = None, maximum: float | None = None) -> int:
    """`value` if it is an integer (not a bool) within [minimum, maximum], else ValueError naming `name`."""
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if not ok or (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        if minimum is not None and maximum is not None:
            what = f"an integer from {minimum:g} to {maximum:g}"
        elif minimum is not None:
            what = f"an integer >= {minimum:g}"
        elif maximum is not None:
            what = f"an integer <= {maximum:g}"
        else:
            what = "an integer"
        raise ValueError(f"{name}: got {value!r}, expected {what}")
    return int(value)


def check_number(value: Any, name: str, minimum: float | None = None, maximum: float | None = None,
                 above: float | None = None, below: float | None = None) -> float:
    """`value` if it is a finite number within the bounds (inclusive minimum / maximum, exclusive above /
    below), else ValueError naming `name`."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
    if ok:
        ok = ((minimum is None or value >= minimum) and (maximum is None or value <= maximum)
              and (above is None or value > above) and (below is None or value < below))
    if not ok:
        lo = f"[{minimum:g}" if minimum is not None else f"({above:g}" if above is not None else None
        hi = f"{maximum:g}]" if maximum is not None else f"{below:g})" if below is not None else None
        if lo and hi:
            what = f"a number in {lo}, {hi}"
        elif lo:
            what = f"a number {'>=' if minimum is not None else '>'} {lo[1:]}"
        elif hi:
            what = f"a number {'<=' if maximum is not None else '<'} {hi[:-1]}"
        else:
            what = "a finite number"
        raise ValueError(f"{name}: got {value!r}, expected {what}")
    return float(value)


def check_choice(value: Any, name: str, choices: Iterable[Any]) -> Any:
    """`value` if it is one of `choices`, else ValueError naming `name` and listing them."""
    choices = tuple(choices)
    if value not in choices:
        raise ValueError(f"{name}: got {value!r}, expected one of {', '.join(map(str, choices))}")
    return value


def check_fields(cfg: Any) -> Any:
    """Check every field of a config against its annotation and `option` bounds and choices (None passes
    where the annotation allows it); nested configs are checked by their own `validate`. Returns `cfg`."""
    for f in dataclasses.fields(cfg):
        meta, kind, value = _meta(f), _base_type(f), getattr(cfg, f.name)
        name = flag_name(f)
        optional = isinstance(f.type, str) and "None" in f.type
        if value is None and optional or kind == "nested":
            continue
        bounds = {k: meta.get(k) for k in ("minimum", "maximum")}
        if kind == "int":
            check_int(value, name, **bounds)
        elif kind == "float":
            check_number(value, name, **bounds, above=meta.get("above"), below=meta.get("below"))
        elif kind == "bool" and not isinstance(value, bool):
            raise ValueError(f"{name}: got {value!r}, expected true or false")
        elif kind == "list" and _item_type(f) != "str":
            check = check_int if _item_type(f) == "int" else check_number
            for v in value:
                check(v, name, **bounds)
        if meta.get("choices") is not None:
            for v in (value if kind == "list" else [value]):
                check_choice(v, name, meta["choices"])
    return cfg


def parse_range(text: Any, name: str, minimum: float, maximum: float, what: str, integer: bool = False) -> tuple:
    """'A-B' (or one value 'A') -> (A, B) with minimum <= A <= B <= maximum; ValueError naming the flag."""
    parts = str(text).split("-")
    try:
        vals = [int(p) if integer else float(p) for p in parts]
    except ValueError:
        vals = []
    if len(vals) == 1:
        vals = vals * 2
    if len(vals) != 2 or not all(math.isfinite(v) for v in vals) or not minimum <= vals[0] <= vals[1] <= maximum:
        raise ValueError(f"{name}: {text!r} is not a range A-B with {minimum:g} <= A <= B <= {maximum:g} ({what})")
    return tuple(vals)


# ---------------------------------------------------------------- parser


class _CommaList(argparse.Action):
    """A list option: each use gives values split at `sep`; the first use replaces the default."""

    def __init__(self, *args: Any, sep: str = ",", repeat: bool = False, item: Callable[[str], Any] = str,
                 **kwargs: Any) -> None:
        self.sep, self.repeat, self.item = sep, repeat, item
        super().__init__(*args, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        items = [v.strip() for v in (str(values).split(self.sep) if self.sep else [str(values)]) if v.strip()]
        try:
            items = [self.item(v) for v in items]
        except ValueError:
            raise argparse.ArgumentError(self, f"invalid value {values!r}: expected {self.item.__name__} values "
                                               f"separated by {self.sep!r}") from None
        current = getattr(namespace, self.dest, None)
        if not self.repeat or current is self.default or current is None:
            current = []
        setattr(namespace, self.dest, [*current, *items] if items or self.repeat else [])


def _show(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return ",".join(map(str, value))
    return str(value)


def add_config_arguments(parser: argparse.ArgumentParser, cls: type,
                         only: Sequence[str] | None = None, group: Any = None, seen: dict | None = None) -> None:
    """Add one flag per field of `cls` (and of its nested configs) to `parser`, help from the docstrings."""
    docs = field_docs(cls)
    target = group if group is not None else parser
    seen = {} if seen is None else seen
    for f in dataclasses.fields(cls):
        meta, kind = _meta(f), _base_type(f)
        if not meta.get("cli", True) or (only is not None and f.name not in only):
            continue
        default = _default(f)
        where = _group(parser, meta["group"]) if meta.get("group") else target
        if kind == "nested":
            add_config_arguments(parser, type(default), meta.get("expose"), where, seen)
            continue
        if f.name in seen:
            raise ValueError(f"{cls.__name__}.{f.name}: the option is defined twice ({seen[f.name]})")
        seen[f.name] = cls.__name__
        name = flag_name(f)
        help_text = docs.get(f.name, "").replace("%", "%%")  # argparse expands %(...)s in help texts
        kwargs: dict[str, Any] = {"help": help_text}
        empty = default is None or default is False or (isinstance(default, (str, list, tuple)) and not default)
        shown = meta.get("default_text") or (None if empty else _show(default))
        if kind == "bool":
            kwargs["action"] = "store_false" if default is True else "store_true"
            if default is True and not meta.get("flag"):  # --no-<field>: the docstring says what the field turns on
                kwargs["help"] = f"Switch off (on by default): {help_text[:1].lower()}{help_text[1:]}"
        else:
            if kind == "list":
                kwargs.update(action=_CommaList, sep="," if meta.get("sep") is None else meta["sep"],
                              item={"int": int, "float": float}.get(_item_type(f), str), repeat=meta.get("repeat", False),
                              default=list(default) if default is not None else None)
                kwargs["metavar"] = meta.get("metavar") or "A,B"
                if meta.get("choices"):
                    kwargs["help"] = f"{help_text} (from: {', '.join(map(str, meta['choices']))})"
            else:
                kwargs["type"] = meta.get("parse") or {"int": int, "float": float}.get(kind, str)
                kwargs["default"] = default
                choices = meta.get("choices")
                kwargs["metavar"] = meta.get("metavar") or ("{" + ",".join(map(str, choices)) + "}" if choices
                                                            else None)
            if meta.get("required"):
                kwargs["required"] = True
                shown = None
            if shown is not None:
                kwargs["help"] = f"{kwargs['help']} (default: {shown.replace('%', '%%')})"
        if meta.get("positional"):
            kwargs.pop("required", None)
            kwargs["metavar"] = meta.get("metavar") or name
            where.add_argument(f.name, **{**kwargs, **meta.get("argparse", {})})
        else:
            if kwargs.get("metavar") is None:
                kwargs.pop("metavar", None)
            names = [meta["short"], name] if meta.get("short") else [name]
            where.add_argument(*names, dest=f.name, **{**kwargs, **meta.get("argparse", {})})


def _group(parser: argparse.ArgumentParser, title: str) -> Any:
    """The argument group of `parser` titled `title` (created at its first use)."""
    for g in parser._action_groups:
        if g.title == title:
            return g
    return parser.add_argument_group(title)


def config_parser(cls: type, prog: str, description: str, **kwargs: Any) -> argparse.ArgumentParser:
    """The command line of config dataclass `cls`: a `scenes.cli.UsageErrorParser` (errors raise UsageError,
    one line) with one flag per field."""
    from scenes.cli import UsageErrorParser

    parser = UsageErrorParser(prog=prog, description=description, **kwargs)
    add_config_arguments(parser, cls)
    return parser


def config_from_args(cls: type, args: argparse.Namespace) -> Any:
    """An instance of `cls` (nested configs included) from parsed arguments; fields that are not on the
    command line keep their defaults. Not validated: call its `validate()`."""
    values = {}
    for f in dataclasses.fields(cls):
        meta, kind = _meta(f), _base_type(f)
        if kind == "nested":
            values[f.name] = config_from_args(type(_default(f)), args)
            continue
        if not meta.get("cli", True) or not hasattr(args, f.name):
            continue
        value = getattr(args, f.name)
        if kind == "list" and value is not None and isinstance(_default(f), tuple):
            value = tuple(value)
        values[f.name] = value
    return cls(**values)


def given_flags(build_parser: Callable[[], argparse.ArgumentParser], argv: Sequence[str] | None) -> set[str]:
    """Destinations of the options given on the command line (not defaulted): `argv` parsed again by a fresh
    parser from `build_parser` whose defaults are all left unset."""
    p = build_parser()
    for action in p._actions:
        action.default = argparse.SUPPRESS
        action.required = False
    return set(vars(p.parse_args(argv)))
