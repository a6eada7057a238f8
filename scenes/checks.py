"""The one set of value checks: every option of a command line (`scenes.cli.options.check_fields`) and every
field of the plain scene data (`scenes.description`, `scenes.lights`) is checked here, and each refusal is one
ValueError `NAME: got VALUE, expected WHAT` naming the flag or the field (`owner.field`) and the value."""
from __future__ import annotations

import math
import numbers
from typing import Any, Iterable


def check_int(value: Any, name: str, minimum: float | None = None, maximum: float | None = None) -> int:
    """`value` if it is an integer (not a bool) within [minimum, maximum], else ValueError naming `name`."""
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if not ok or (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        def n(bound: float) -> str:  # integers in full (2147483645, not 2.14748e+09)
            return str(int(bound)) if float(bound).is_integer() else f"{bound:g}"

        if minimum is not None and maximum is not None:
            what = f"an integer from {n(minimum)} to {n(maximum)}"
        elif minimum is not None:
            what = f"an integer >= {n(minimum)}"
        elif maximum is not None:
            what = f"an integer <= {n(maximum)}"
        else:
            what = "an integer"
        raise ValueError(f"{name}: got {value!r}, expected {what}")
    return int(value)


FLOAT32_MAX = 3.4028234663852886e38
"""The largest finite float32: a scene's numbers are rendered in single precision."""


def check_number(value: Any, name: str, minimum: float | None = None, maximum: float | None = None,
                 above: float | None = None, below: float | None = None) -> float:
    """`value` if it is a finite number within the bounds (inclusive minimum / maximum, exclusive above /
    below), else ValueError naming `name`."""
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    try:
        big = real and math.isfinite(value) and abs(float(value)) > FLOAT32_MAX  # 1e308 is infinite in float32
    except OverflowError:  # an integer of hundreds of digits
        big = True
    ok = real and not big and math.isfinite(value)
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
