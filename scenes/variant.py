"""Choosing the Mitsuba variant at entry points (never at import time)."""
from __future__ import annotations

import logging
import warnings

log = logging.getLogger(__name__)

PREFERENCE = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
LLVM_FIX = "install Debian's libllvm19 (apt-get install -y libllvm19) for the ~3x faster llvm_ad_rgb variant"


def _usable(variant: str) -> bool:
    import mitsuba as mi

    if variant not in mi.variants():
        return False
    try:
        mi.set_variant(variant)
        if variant.startswith("cuda"):
            import drjit as dr

            dr.zeros(dr.cuda.Float, 1)  # raises without a usable GPU/driver
        elif variant.startswith("llvm"):
            import drjit as dr

            dr.eval(dr.llvm.Float([1.0]) + 1)  # raises without a usable libLLVM
        return True
    except Exception as exc:  # the backends report missing drivers/libraries in various ways
        log.debug("variant %s is not usable: %s", variant, exc)
        return False


def choose_variant(requested: str | None = None) -> str:
    """Set and return a Mitsuba variant: `requested` if given, else cuda, llvm, scalar in that order.

    Falling back to scalar warns with the fix. An unknown or unusable requested variant is a ValueError.
    """
    import mitsuba as mi

    if requested:
        if requested not in mi.variants():
            raise ValueError(f"--variant: {requested!r} is not built into this Mitsuba, expected one of {', '.join(mi.variants())}")
        if not _usable(requested):
            hint = f"; {LLVM_FIX}" if requested.startswith("llvm") else ""
            raise ValueError(f"--variant: {requested!r} cannot run on this machine{hint}")
        return requested
    for variant in PREFERENCE:
        if _usable(variant):
            if variant.startswith("scalar"):
                warnings.warn(f"Mitsuba falls back to the slow scalar_rgb variant: {LLVM_FIX}", RuntimeWarning, stacklevel=2)
            return variant
    raise RuntimeError("no usable Mitsuba variant among " + ", ".join(PREFERENCE))
