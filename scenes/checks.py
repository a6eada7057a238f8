"""The field checks of the plain scene data (`scenes.description`, `scenes.lights`): each raises a ValueError
`owner.name: expected ..., got value` naming the field and the value it refused."""
from __future__ import annotations

import math
from typing import Any


def check_finite(owner: str, name: str, value: Any) -> None:
    """Raise ValueError if `value` (number or nested list of numbers) holds NaN/inf or anything not a number."""
    if isinstance(value, (list, tuple)):
        for v in value:
            check_finite(owner, name, v)
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{owner}.{name}: expected a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{owner}.{name}: expected a finite number, got {value!r}")


def check_vector(owner: str, name: str, value: Any, n: int = 3) -> None:
    """A list of `n` finite numbers."""
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise ValueError(f"{owner}.{name}: expected a list of {n} numbers, got {value!r}")
    check_finite(owner, name, value)


def check_direction(owner: str, name: str, value: Any) -> None:
    """A non-zero finite 3-vector."""
    check_vector(owner, name, value, 3)
    if sum(c * c for c in value) < 1e-12:
        raise ValueError(f"{owner}.{name}: expected a non-zero vector, got {value!r}")


def check_positive(owner: str, name: str, value: Any, allow_zero: bool = False) -> None:
    """A finite number > 0 (>= 0 with `allow_zero`)."""
    check_finite(owner, name, value)
    if value < 0 or (value == 0 and not allow_zero):
        raise ValueError(f"{owner}.{name}: expected a {'non-negative' if allow_zero else 'positive'} number, got {value!r}")


def check_non_negative(owner: str, name: str, value: Any) -> None:
    """A finite number >= 0."""
    check_positive(owner, name, value, allow_zero=True)


def check_matrix4(owner: str, name: str, value: Any) -> None:
    """A 4x4 matrix of finite numbers (a list of 4 lists of 4)."""
    if not isinstance(value, (list, tuple)) or len(value) != 4 or any(
        not isinstance(r, (list, tuple)) or len(r) != 4 for r in value
    ):
        raise ValueError(f"{owner}.{name}: expected a 4x4 matrix (list of 4 lists of 4 numbers), got {value!r}")
    check_finite(owner, name, value)


def check_choice(owner: str, name: str, value: Any, choices: tuple[str, ...]) -> None:
    """One of `choices`."""
    if value not in choices:
        raise ValueError(f"{owner}.{name}: unknown value {value!r}, expected one of {', '.join(choices)}")
