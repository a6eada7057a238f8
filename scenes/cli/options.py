"""Command lines of config dataclasses, parsed by tyro, and the one set of option checks every config uses.

A CLI's options are a dataclass: one field per option, its help the string literal under the field (an
attribute docstring), its default written once, in the dataclass. tyro turns the dataclass into the command
line: a flag per field (`--max-pixels` for `max_pixels`), the fields of a nested config flattened into the same
command line without a prefix, a pair of switches for a bool (`--floors` / `--no-floors`),
the choices of a `Literal`. What tyro cannot read from the type is written in the annotation with the markers
below (`CommaList`, `Repeatable`, `Positional`, `arg(metavar=...)`). Bounds and the choices of list items are
`option(...)` metadata, checked by `check_fields` whether the config came from a command line or from code.

    COMMAND = Command(Options, prog="python -m pkg.cli", description="...")
    opts = COMMAND.parse(argv).validate()      # a UsageError of one line on bad input, never a traceback

Errors name the flag, the value and what was expected, e.g. `--steps: got 0, expected an integer >= 1`;
`scenes.cli.errors.report_error` prints them.
"""
from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import os
import re
import textwrap
import types
import typing
import warnings
from typing import Any, Iterable, Literal, Sequence

import tyro
from tyro.constructors import PrimitiveConstructorSpec

from scenes.checks import check_choice, check_int64, check_number

_KEY = "scenes.cli.options"  # the dataclass-field metadata key of `option`

# tyro's behaviour for every CLI: nested configs without a prefix (their flags are the command's own).
MARKERS = (tyro.conf.OmitArgPrefixes,)

REQUIRED: Any = tyro.MISSING
"""The default of a field the command line must give (`--out`); a config built in code without it is refused
by `check_fields`."""
Positional = tyro.conf.Positional
"""A positional argument instead of a flag."""
UseAppendAction = tyro.conf.UseAppendAction
"""A list flag given once per value (`--model-option a=1 --model-option b=2`), added to the default."""
NotOnCommandLine = tyro.conf.Suppress
"""A field that has no flag (set by the program, not the user)."""
arg = tyro.conf.arg
"""Per-field details: `arg(metavar="DIR")`, `arg(aliases=("-v",))`, `arg(help_behavior_hint="(default: ...)")`
for a default that is computed at run time."""


def _split(tokens: list[str], item: Any = str) -> list:
    parts = [v.strip() for token in tokens for v in token.split(",")]
    values = [v for v in parts if v]
    if values and len(values) != len(parts):  # '1,,2' or 'a,': a value left out by mistake, never dropped
        raise ValueError(f"invalid value {','.join(tokens)!r}: an empty item between commas; expected "
                         f"{item.__name__} values separated by ','")
    try:
        return [item(v) for v in values]
    except ValueError:
        raise ValueError(f"invalid value {','.join(tokens)!r}: expected {item.__name__} values separated by ','") \
            from None


def comma_list(item: Any = str, metavar: str = "A,B", container: type = list) -> PrimitiveConstructorSpec:
    """A list option typed as one comma-separated value (`--lights near_area,hdri`)."""
    return PrimitiveConstructorSpec(
        nargs=1, metavar=metavar, instance_from_str=lambda tokens: container(_split(tokens, item)),
        is_instance=lambda value: isinstance(value, (list, tuple)),
        str_from_instance=lambda value: [",".join(map(str, value))])


CommaList = comma_list()
"""A list of strings typed as one comma-separated value."""


class _Repeatable:
    """Marker: the flag may be given several times, its values add up (the first use replaces the default)."""

    def __repr__(self) -> str:
        return "Repeatable"


Repeatable = _Repeatable()


def optional_value(const: str, metavar: str) -> PrimitiveConstructorSpec:
    """A flag whose value may be left out (`--ray` means `--ray auto`)."""
    def value(tokens: list) -> str:
        token = tokens[0] if tokens else []  # tyro hands a flag given without its value over as [[]]
        return token if isinstance(token, str) else (token[0] if token else const)

    return PrimitiveConstructorSpec(nargs="?", metavar=metavar, instance_from_str=value,
                                    is_instance=lambda value: value is None or isinstance(value, str),
                                    str_from_instance=lambda value: [str(value)])


def auto_is_none(metavar: str) -> PrimitiveConstructorSpec:
    """A string option whose value `auto` stands for None (chosen at run time)."""
    return PrimitiveConstructorSpec(nargs=1, metavar=metavar,
                                    instance_from_str=lambda tokens: None if tokens[0] == "auto" else tokens[0],
                                    is_instance=lambda value: value is None or isinstance(value, str),
                                    str_from_instance=lambda value: ["auto" if value is None else str(value)])


def option(default: Any = dataclasses.MISSING, *, default_factory: Any = dataclasses.MISSING,
           minimum: float | None = None, maximum: float | None = None, above: float | None = None,
           below: float | None = None, choices: Sequence[Any] | None = None) -> Any:
    """A dataclass field with its checks (read by `check_fields`).

    minimum / maximum: inclusive bounds; above / below: exclusive bounds (numbers are also checked finite);
    choices: the allowed values of each element of a list (a single value's choices are its `Literal` type).
    """
    meta = {"minimum": minimum, "maximum": maximum, "above": above, "below": below,
            "choices": tuple(choices) if choices is not None else None}
    kwargs: dict[str, Any] = {"metadata": {_KEY: meta}}
    if default_factory is not dataclasses.MISSING:
        kwargs["default_factory"] = default_factory
    else:
        kwargs["default"] = default
    return dataclasses.field(**kwargs)


# ---------------------------------------------------------------- types of the fields


def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls, include_extras=True)


def _strip(tp: Any) -> tuple[Any, tuple]:
    """(the type without Annotated and None, the Annotated metadata)."""
    extras: tuple = ()
    while typing.get_origin(tp) is typing.Annotated:
        extras += tuple(tp.__metadata__)
        tp = typing.get_args(tp)[0]
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1:
            inner, more = _strip(args[0])
            return inner, extras + more
    return tp, extras


def _allows_none(tp: Any) -> bool:
    while typing.get_origin(tp) is typing.Annotated:
        tp = typing.get_args(tp)[0]
    return type(None) in typing.get_args(tp)


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        return f.default_factory()  # type: ignore[misc]
    return None


def _is_nested(tp: Any) -> bool:
    return dataclasses.is_dataclass(tp) and isinstance(tp, type)


def on_command_line(cls: type, f: dataclasses.Field) -> bool:
    _, extras = _strip(_hints(cls)[f.name])
    return not any(e is NotOnCommandLine or "Suppress" in repr(e) for e in extras)


def flag_name(cls: type, f: dataclasses.Field) -> str:
    """The command-line name of a field (`--out`, or a positional's metavar)."""
    _, extras = _strip(_hints(cls)[f.name])
    confs = [e for e in extras if type(e).__name__ == "_ArgConfig"]
    if any("Positional" in repr(e) for e in extras):
        return next((c.metavar for c in confs if c.metavar), f.name.upper())
    name = next((c.name for c in confs if c.name), f.name)
    return f"--{name.replace('_', '-')}"


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
    docs, hints = field_docs(cls), _hints(cls)
    missing = [f"{cls.__name__}.{f.name}" for f in dataclasses.fields(cls) if f.name not in docs]
    for f in dataclasses.fields(cls):
        tp, _ = _strip(hints[f.name])
        if _is_nested(tp):
            missing += undocumented_fields(tp)
    return missing


def check_fields(cfg: Any) -> Any:
    """Check every field of a config against its type and `option` bounds and choices (None passes where the
    type allows it); nested configs are checked by their own `validate`. Returns `cfg`."""
    cls, hints = type(cfg), _hints(type(cfg))
    for f in dataclasses.fields(cfg):
        tp, _ = _strip(hints[f.name])
        meta, value, name = f.metadata.get(_KEY, {}), getattr(cfg, f.name), flag_name(cls, f)
        if value is tyro.MISSING:
            raise ValueError(f"{name}: required")
        if (value is None and _allows_none(hints[f.name])) or _is_nested(tp):
            continue
        bounds = {k: meta.get(k) for k in ("minimum", "maximum")}
        origin = typing.get_origin(tp)
        if tp is int:
            check_int64(value, name, **bounds)
            if f.name == "threads" or f.name.endswith("_threads"):  # one rule for every thread count: what the
                from scenes.cli.limits import check_threads  # machine can start (a huge count crashes torch)

                check_threads(value, name)
        elif tp is float:
            check_number(value, name, **bounds, above=meta.get("above"), below=meta.get("below"))
        elif tp is bool and not isinstance(value, bool):
            raise ValueError(f"{name}: got {value!r}, expected true or false")
        elif origin is Literal:
            check_choice(value, name, typing.get_args(tp))
        elif tp is str and isinstance(value, str):
            _check_no_link_loop(value, name)
        elif origin in (list, tuple):
            item = typing.get_args(tp)[0] if typing.get_args(tp) else str
            if item in (int, float):
                check = check_int64 if item is int else check_number
                if not value and any(v is not None for v in bounds.values()):  # bounded values: one or more meant
                    raise ValueError(f"{name}: got an empty list, expected one or more numbers, comma-separated")
                for v in value:
                    check(v, name, **bounds)
        if meta.get("choices") is not None:
            if origin in (list, tuple) and not value:  # a list of choices given empty ('') chooses nothing
                raise ValueError(f"{name}: got an empty list, expected one or more of "
                                 f"{', '.join(map(str, meta['choices']))}")
            for v in (value if origin in (list, tuple) else [value]):
                check_choice(v, name, meta["choices"])
    return cfg


def _check_no_link_loop(value: str, name: str) -> None:
    """A path option that is (or passes through) a loop of symbolic links: refused here, before any command
    resolves it (pathlib's resolve() would raise RuntimeError deep inside)."""
    import errno

    try:
        os.stat(value)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise ValueError(f"{name}: {value!r} is a loop of symbolic links; expected a file or a folder") from None
    except ValueError:  # an embedded NUL: the option's own checks say so
        pass


# ---------------------------------------------------------------- the command line


def _flag_tokens(argv: Sequence[str] | None, known: set[str]) -> list[tuple[str, str]]:
    """(as typed, its field's flag) of each token of a command line (`sys.argv` when None, as `Command.parse` reads
    it): `--no-x` is the flag `--x` unless `--no-x` is a flag of `known` (a field named no_x)."""
    import sys

    tokens = [t.split("=", 1)[0] for t in (sys.argv[1:] if argv is None else argv)]
    return [(t, t) if t in known else (t, "--" + t[5:] if t.startswith("--no-") else t) for t in tokens]


def _flat_fields(cls: type) -> Iterable[tuple[type, dataclasses.Field]]:
    """(owner class, field) of every field on the command line, the fields of nested configs included."""
    hints = _hints(cls)
    for f in dataclasses.fields(cls):
        tp, _ = _strip(hints[f.name])
        if not on_command_line(cls, f):
            continue
        if _is_nested(tp):
            yield from _flat_fields(tp)
        else:
            yield cls, f


def _usage_message(event: Any) -> str:
    """One line for a tyro parse error: the flag, the value and what was expected."""
    from tyro import _errors

    def flag(argument: Any) -> str:
        if argument is None:
            return "argument"
        names = argument.lowered.name_or_flags
        return names[-1] if names else argument.lowered.metavar or argument.field.intern_name

    if isinstance(event, _errors.MissingArgs):
        return "the following arguments are required: " + ", ".join(flag(a.arg) for a in event.missing_arguments)
    if isinstance(event, _errors.UnrecognizedArgs):
        return "unrecognized arguments: " + " ".join(event.tokens)
    if isinstance(event, _errors.InvalidChoice):
        return f"{flag(event.argument)}: got {event.value!r}, expected one of {', '.join(event.choices)}"
    if isinstance(event, _errors.BadValue):
        what = "expected a value" if event.offending_value is None else f"takes no value, got {event.offending_value!r}"
        return f"{flag(event.argument)}: {what}"
    if isinstance(event, _errors.InstantiationFailure):
        message = " ".join(str(event.message).split())
        kinds = {"INT": "an integer", "int": "an integer", "FLOAT": "a number", "float": "a number", "{None}": "None"}
        # a value of none of an optional field's types, or one int() / float() cannot read (Python's own words)
        if said := (re.match(r"no type matching (\S+) could be instantiated from \[(.*?)\]", message) or
                    re.match(r"invalid literal for (int|float)\(\)(?: with base 10)?: (.*)$", message)):
            message = f"got {said.group(2)}, expected {' or '.join(kinds.get(k, k) for k in said.group(1).split('|'))}"
        return f"{flag(event.argument)}: {message}" if event.argument is not None else message
    return f"bad command line ({type(event).__name__})"


@dataclasses.dataclass(frozen=True)
class Flag:
    """One option of a command line as the docs list it."""

    group: str
    """'' for the command's own options, else the field name of the nested config they belong to."""
    invocation: str
    """As `--help` shows it: `--out DIR`, `--floors, --no-floors`, or a positional's metavar."""
    default: str
    """`required`, `on` / `off` for a switch, the default value (lists comma-separated, `-` for none) or the
    text of a default chosen at run time."""
    meaning: str
    """The field's docstring."""


def _default_cell(f: dataclasses.Field, extras: tuple) -> str:
    hint = next((e.help_behavior_hint for e in extras if getattr(e, "help_behavior_hint", None)), None)
    value = _default(f)
    if value is tyro.MISSING:
        return "required"
    if hint:
        return re.sub(r"^\(default:?\s*(.*)\)$", r"\1", hint)
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, (list, tuple)):
        value = ",".join(map(str, value))
    return "-" if value in (None, "") else str(value)


@dataclasses.dataclass(frozen=True)
class Command:
    """A command line: the config dataclass it fills, how it is called and what it does (one line)."""

    config: type
    prog: str
    description: str
    needs: tuple = ()
    """`scenes.cli.needs.Needs` of the flags that act only together with another setting, checked by `parse`
    unless `needs_late`: then the command calls `check_needs` on the configuration it resolves (presets, a
    resumed manifest), since the parsed one is not yet what runs."""
    needs_late: bool = False

    def parse(self, argv: Sequence[str] | None = None) -> Any:
        """The config of `argv` (not validated: call its `validate()`); a bad command line is a UsageError of
        one line. `--help` prints tyro's help and exits 0."""
        import sys

        from tyro import _errors

        from scenes.cli.errors import UsageError, check_text_arguments, hold_standard_streams

        hold_standard_streams()

        def refuse(event: Any) -> None:
            raise UsageError(_usage_message(event))

        argv = list(sys.argv[1:] if argv is None else argv)
        if not {"-h", "--help"} & set(argv):  # --help reads no path (and TMPDIR's name is none of its business)
            check_text_arguments(argv, " or ".join(n for n in (flag_name(o, f) for o, f in _flat_fields(self.config))
                                                   if not n.startswith("--")) or "an argument")
        self._check_no_empty_path(argv)
        with _errors.on_parse_error(refuse):
            cfg = tyro.cli(self.config, args=self._join_repeated(argv), prog=self.prog,
                           description=self.description, config=MARKERS)
        if not self.needs_late:
            self.check_needs(cfg, argv)
        return cfg

    def check_needs(self, cfg: Any, argv: Sequence[str] | None) -> None:
        """A UsageError naming the first flag on `argv` that `cfg` (this command's config) would not use."""
        from scenes.cli.needs import check_needs

        typed = self.typed_flags(argv) if self.needs else {}
        check_needs(self.needs, cfg, set(typed), {**self.flags(), **typed})

    def _check_no_empty_path(self, argv: list[str]) -> None:
        """A path or text flag given an empty value is refused: '' would become the current folder ('.') without a
        word (`--out ''` from an unset shell variable), or a name that names nothing (`--model ''`)."""
        from pathlib import PurePath

        from scenes.cli.errors import UsageError

        wants = {}  # flag -> what it takes (its metavar where it has one)
        for owner, f in _flat_fields(self.config):
            kind, extras = _strip(_hints(owner)[f.name])
            path = isinstance(kind, type) and issubclass(kind, PurePath)
            if path or kind is str:
                shown = next((m for m in (getattr(e, "metavar", None) for e in extras) if m), None)
                wants[flag_name(owner, f)] = shown or ("a path" if path else "a non-empty value")
        for i, token in enumerate(argv):
            flag, eq, value = token.partition("=")
            if flag in wants and ((eq and not value.strip()) or (not eq and i + 1 < len(argv)
                                                                 and not argv[i + 1].strip())):
                raise UsageError(f"{flag}: got an empty value, expected {wants[flag]}")

    def parser(self) -> argparse.ArgumentParser:
        """tyro's argparse form of the command line (the flags, their help and groups), for the generated docs."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            return tyro.extras.get_parser(self.config, prog=self.prog, description=self.description,
                                          config=MARKERS)

    def help(self) -> str:
        """What `--help` prints."""
        import contextlib
        import io

        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            tyro.cli(self.config, args=["--help"], prog=self.prog, description=self.description, config=MARKERS)
        return out.getvalue()

    def options(self) -> list[Flag]:
        """Every option of the command line, in `--help`'s order, as the docs list them."""
        parser = self.parser()
        fields = {f.name: (owner, f) for owner, f in _flat_fields(self.config)}
        groups = {f.name for f in dataclasses.fields(self.config) if _is_nested(_strip(_hints(self.config)[f.name])[0])}
        out = []
        for action in parser._actions:
            if action.dest == "help":
                continue
            *prefix, name = action.dest.split(".")
            owner, f = fields[name.replace("-", "_")]
            extras = _strip(_hints(owner)[f.name])[1]
            metavar = f" {action.metavar}" if action.metavar and action.option_strings and action.nargs != 0 else ""
            if action.nargs == "?" and metavar:
                metavar = f" [{action.metavar}]"
            invocation = ", ".join(action.option_strings) + metavar if action.option_strings else action.metavar
            group = next((g for g in prefix if g in groups), prefix[0] if prefix else "")
            out.append(Flag(group, invocation, _default_cell(f, extras), field_docs(owner).get(f.name, "")))
        return out

    def flags(self) -> dict[str, str]:
        """Field name -> its flag, for every field on the command line."""
        return {f.name: flag_name(owner, f) for owner, f in _flat_fields(self.config)}

    def given(self, argv: Sequence[str] | None) -> set[str]:
        """Names of the fields whose flags are on the command line `argv` (not left at their defaults)."""
        return set(self.typed_flags(argv))

    def typed_flags(self, argv: Sequence[str] | None) -> dict[str, str]:
        """Field name -> its flag as typed on `argv` (`--no-x` for a switch turned off), for the flags given."""
        by_flag = {flag: name for name, flag in self.flags().items() if flag.startswith("-")}
        return {by_flag[flag]: typed for typed, flag in _flag_tokens(argv, set(by_flag)) if flag in by_flag}

    def given_flags(self, argv: Sequence[str] | None, within: type) -> list[str]:
        """The flags on `argv` of the fields of the nested config `within` (its own nested configs included)."""
        mine = {flag_name(owner, f) for owner, f in _flat_fields(within)}
        tokens = _flag_tokens(argv, set(self.flags().values()))
        return list(dict.fromkeys(typed for typed, flag in tokens if flag in mine))

    def _join_repeated(self, argv: list[str]) -> list[str]:
        """A `Repeatable` flag given several times becomes one comma-separated value (its uses add up)."""
        repeat = {flag_name(owner, f) for owner, f in _flat_fields(self.config)
                  if Repeatable in _strip(_hints(owner)[f.name])[1]}
        out: list[str] = []
        seen: dict[str, int] = {}
        i = 0
        while i < len(argv):
            token = argv[i]
            name, eq, value = token.partition("=")
            if name in repeat and (eq or i + 1 < len(argv)):
                if not eq:
                    value, i = argv[i + 1], i + 1
                if name in seen:
                    out[seen[name]] += "," + value
                else:
                    out += [name, value]
                    seen[name] = len(out) - 1
            else:
                out.append(token)
            i += 1
        return out
