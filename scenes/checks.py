"""The one set of value checks: every option of a command line (`scenes.cli.options.check_fields`) and every
field of the plain scene data (`scenes.description`, `scenes.lights`) is checked here, and each refusal is one
ValueError `NAME: got VALUE, expected WHAT` naming the flag or the field (`owner.field`) and the value; and the
size of a file read whole (`check_read_whole`)."""
from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import os
import types
import typing
from typing import Any, Iterable


def check_int(value: Any, name: str, minimum: float | None = None, maximum: float | None = None) -> int:
    """`value` if it is an integer (not a bool) within [minimum, maximum], else ValueError naming `name`."""
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if not ok or (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        def n(bound: float) -> str:  # integers in full (2147483645, not 2.14748e+09)
            return str(int(bound)) if isinstance(bound, int) or float(bound).is_integer() else f"{bound:g}"

        if minimum is not None and maximum is not None:
            what = f"an integer from {n(minimum)} to {n(maximum)}"
        elif minimum is not None:
            what = f"an integer >= {n(minimum)}"
        elif maximum is not None:
            what = f"an integer <= {n(maximum)}"
        else:
            what = "an integer"
        shown = repr(value)
        raise ValueError(f"{name}: got {shown if len(shown) <= 40 else shown[:24] + '...'}, expected {what}")
    return int(value)


INT64 = (-(2**63), 2**63 - 1)
"""The widest integer an option takes: JSON records (scenes.files.read_json) and numpy refuse integers beyond 64
bits, so a seed of 2**64 would be recorded in a manifest its own reader refuses (sweep 39)."""


def check_int64(value: Any, name: str, minimum: float | None = None, maximum: float | None = None) -> int:
    """`check_int`, and within `INT64`."""
    value = check_int(value, name, minimum, maximum)
    if not INT64[0] <= value <= INT64[1]:
        shown = str(value) if len(str(value)) <= 24 else str(value)[:20] + "..."
        raise ValueError(f"{name}: got {shown}, beyond 64 bits; expected an integer from -2^63 to 2^63 - 1")
    return value


FLOAT32_MAX = 3.4028234663852886e38
"""The largest finite float32: a scene's numbers are rendered in single precision."""
FLOAT32_TINY = 1.1754943508222875e-38
"""The smallest normal float32: a number nearer 0 (but not 0) loses its precision there, and what divides by it
overflows."""


def check_number(value: Any, name: str, minimum: float | None = None, maximum: float | None = None,
                 above: float | None = None, below: float | None = None) -> float:
    """`value` if it is a finite number within the bounds (inclusive minimum / maximum, exclusive above /
    below), else ValueError naming `name`."""
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    try:
        big = real and math.isfinite(value) and abs(float(value)) > FLOAT32_MAX  # 1e308 is infinite in float32
        tiny = real and 0 < abs(float(value)) < FLOAT32_TINY  # 1e-39 is a subnormal: 0 to what divides by it
    except OverflowError:  # an integer of hundreds of digits
        big, tiny = True, False
    ok = real and not big and not tiny and math.isfinite(value)
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
        if big:
            what += f" (at most {FLOAT32_MAX:.3g}: rendered in single precision)"
        if tiny:
            what += f" (none nearer 0 than {FLOAT32_TINY:.3g}: rendered in single precision)"
        shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:40] + "..."
        raise ValueError(f"{name}: got {shown}, expected {what}")
    return float(value)


def check_choice(value: Any, name: str, choices: Iterable[Any]) -> Any:
    """`value` if it is one of `choices`, else ValueError naming `name` and listing them."""
    choices = tuple(choices)
    if value not in choices:
        raise ValueError(f"{name}: got {value!r}, expected one of {', '.join(map(str, choices))}")
    return value


def check_finite(value: Any, name: str) -> None:
    """`value`, a number or a nested list of numbers, holds only finite numbers."""
    if isinstance(value, (list, tuple)):
        for v in value:
            check_finite(v, name)
        return
    check_number(value, name)


def check_vector(value: Any, name: str, n: int = 3) -> None:
    """A list of `n` finite numbers."""
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise ValueError(f"{name}: got {value!r}, expected a list of {n} numbers")
    check_finite(value, name)


def check_direction(value: Any, name: str) -> None:
    """A non-zero finite 3-vector."""
    check_vector(value, name, 3)
    if sum(c * c for c in value) < 1e-12:
        raise ValueError(f"{name}: got {value!r}, expected a non-zero vector")


def check_matrix4(value: Any, name: str) -> None:
    """A 4x4 matrix of finite numbers (a list of 4 lists of 4)."""
    if not isinstance(value, (list, tuple)) or len(value) != 4 or any(
        not isinstance(r, (list, tuple)) or len(r) != 4 for r in value
    ):
        raise ValueError(f"{name}: got {value!r}, expected a 4x4 matrix (list of 4 lists of 4 numbers)")
    check_finite(value, name)
    import numpy as np

    if abs(float(np.linalg.det(np.asarray(value, np.float64)[:3, :3]))) < 1e-12:  # a placement must be invertible
        raise ValueError(f"{name}: a singular matrix (its 3x3 part has determinant 0); expected an invertible "
                         "placement (scale, rotation, translation)")
    if list(map(float, value[3])) != [0.0, 0.0, 0.0, 1.0]:  # a projective matrix places nothing
        raise ValueError(f"{name}: its last row is {value[3]!r}, expected [0, 0, 0, 1] (an affine placement)")


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


SEED_END = 2**32
"""Seeds are below this: Mitsuba's sampler seed is a 32-bit unsigned integer (numpy's generators take any)."""


def check_seed(value: Any, name: str) -> int:
    """A seed as a scene records it: an integer from 0 to 2^32 - 1."""
    return check_int(value, name, 0, SEED_END - 1)


def check_json_types(obj: Any, owner: str, given: Iterable[str]) -> None:
    """Each field of dataclass `obj` named in `given` (read from a file) holds a value of its annotated kind: an
    integer where an int is declared (not 1.5, '1' or true), true or false for a bool, a list of numbers for
    list[float]... (a field holding a dataclass is read, and checked, by its own reader). ValueError naming
    `owner.field`, the value and the kind expected."""
    hints = _hints(type(obj))
    for name in given:
        if not _fits(value := getattr(obj, name), hints[name]):
            raise ValueError(f"{owner + '.' if owner else ''}{name}: got {value!r:.80}, expected {_kind(hints[name])}")


@functools.lru_cache(maxsize=None)
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _fits(value: Any, hint: Any) -> bool:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        return any(_fits(value, a) for a in args)
    if origin is list:
        return isinstance(value, list) and all(_fits(v, args[0]) for v in value)
    if origin is dict:
        return isinstance(value, dict) and all(_fits(k, args[0]) and _fits(v, args[1]) for k, v in value.items())
    if hint is bool or hint is str or hint is type(None):
        return isinstance(value, hint)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return not (isinstance(hint, type) and dataclasses.is_dataclass(hint)) or isinstance(value, hint)


def _kind(hint: Any) -> str:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        return " or ".join(_kind(a) for a in args)
    if origin is list:
        return f"a list of ({_kind(args[0])})"
    if origin is dict:
        return f"an object of ({_kind(args[1])})"
    return {bool: "true or false", int: "an integer", float: "a number", str: "a string",
            type(None): "null"}.get(hint, getattr(hint, "__name__", str(hint)))


READ_WHOLE_LIMIT = 2**30
"""The largest file read whole into memory: a record (JSON, a light list), an image, a mesh, a NumPy map. A bigger
one (a sparse file, a disk image under a photo's name) is refused by its size before minutes of reading; a real
one beyond it (a 15-million-face mesh, a 170-megapixel 16-bit photo) is more than any of these commands uses."""


def check_read_whole(path: str | os.PathLike[str], where: str, size: int | None = None) -> None:
    """A ValueError beginning with `where` (the flag or field, and the file) for a file over READ_WHOLE_LIMIT;
    `size` when the caller already has it (an open descriptor's)."""
    size = os.stat(path).st_size if size is None else size
    if size > READ_WHOLE_LIMIT:
        raise ValueError(f"{where} is {size / 2**30:.1f} GiB, over the {READ_WHOLE_LIMIT // 2**30} GiB a file read "
                         "whole may be; expected the file its name says (a copy padded, or another file?)")
