"""The base of the model configurations (`GLCConfig`, `UniPS22Config`, `SDMConfig`): plain JSON-able dataclasses whose
tuple fields come back as tuples after a JSON round trip, checked on construction with one-line errors
(`Class.field=value: expected ...`), and built from a registered one with overrides (`config_with_overrides`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Mapping


@dataclass
class ModelConfig:
    """Shared normalisation and checks of a model configuration; subclasses declare their fields (every one with a
    default), name the fields of the shared checks and add their own checks in `check`."""

    POSITIVE: ClassVar[tuple[str, ...]] = ()
    """Fields that must be positive integers."""
    NON_NEGATIVE: ClassVar[tuple[str, ...]] = ()
    """Fields that must be non-negative integers (layer counts)."""
    PROBABILITIES: ClassVar[tuple[str, ...]] = ("dropout",)
    """Fields that must be probabilities in [0, 1)."""

    LARGEST: ClassVar[int] = 1 << 14
    """No width, count or size of a network is above this (a file's config asking for more is not a network, and
    building it could take all the memory); the run-time sizes (`*_chunk`, `*_samples`) only below 2**31."""

    def __post_init__(self) -> None:
        self._check_kinds()
        # JSON turns tuples into lists: normalise so configs compare equal after a round trip.
        for f in dataclasses.fields(self):
            if str(f.type).startswith("tuple"):
                setattr(self, f.name, tuple(int(v) for v in getattr(self, f.name)))
        self.validate()

    def _check_kinds(self) -> None:
        """Every field of the kind of its default (a config read from a file is untrusted): an integer field holds an
        integer (not a bool, not text), a tuple field a list of integers, each within `LARGEST`."""
        for f in dataclasses.fields(self):
            value, default = getattr(self, f.name), f.default
            if isinstance(default, bool):
                ok = isinstance(value, bool)
                what = "true or false"
            elif isinstance(default, int):
                top = (1 << 31) - 1 if f.name.endswith(("_chunk", "_samples")) else self.LARGEST
                ok = isinstance(value, int) and not isinstance(value, bool) and abs(value) <= top
                what = f"an integer of at most {top}"
            elif isinstance(default, float):
                ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
                what = "a finite number"
            elif isinstance(default, str):
                ok = isinstance(value, str)
                what = "text"
            elif isinstance(default, tuple) or str(f.type).startswith("tuple"):
                ok = isinstance(value, (list, tuple)) and all(
                    isinstance(v, int) and not isinstance(v, bool) and abs(v) <= self.LARGEST for v in value)
                what = f"a list of integers of at most {self.LARGEST}"
            else:
                continue
            if not ok:
                raise self.bad(f.name, what)

    def bad(self, name: str, expected: str) -> ValueError:
        """The one-line error of field `name`: `Class.name=value: expected ...`."""
        return ValueError(f"{type(self).__name__}.{name}={getattr(self, name)!r}: expected {expected}")

    def validate(self) -> None:
        """Raise ValueError naming the first inconsistent field: the checks every model shares (canonical resolution,
        positive widths, layer counts, pooled sizes, probabilities), then the model's own (`check`)."""
        if self.canonical_resolution <= 0 or self.canonical_resolution % 32:
            raise self.bad("canonical_resolution", "a positive multiple of 32")
        for name in self.POSITIVE:
            if int(getattr(self, name)) < 1:
                raise self.bad(name, "a positive integer")
        for name in self.NON_NEGATIVE:
            if getattr(self, name) < 0:
                raise self.bad(name, "a non-negative integer")
        if not self.ppm_scales or min(self.ppm_scales) < 1:
            raise self.bad("ppm_scales", "positive pooled sizes")
        for name in self.PROBABILITIES:
            if not 0.0 <= getattr(self, name) < 1.0:
                raise self.bad(name, "a probability in [0, 1)")
        self.check()

    def check(self) -> None:
        """The model's own checks (ValueError from `bad`); none here."""


def config_with_overrides(base: Any, overrides: Mapping[str, Any]) -> Any:
    """`base` (a config dataclass: GLCConfig, SDMConfig) with some fields replaced; an unknown key raises
    ValueError naming it."""
    known = {f.name for f in dataclasses.fields(base)}
    for key in overrides:
        if key not in known:
            raise ValueError(f"unknown model option {key!r}; known options: {', '.join(sorted(known))}")
    return dataclasses.replace(base, **dict(overrides))
