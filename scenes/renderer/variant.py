"""The Mitsuba variant: chosen at entry points (never at import time), checked where Mitsuba objects are made.

`choose_variant` sets it; `require_variant` / `require_jit_variant` / `require_ad_variant` are the only checks
that one is set (`scenes.renderer.build`, `scenes.renderer.render`, `validate.known.normal_bsdf` and
`validate.fitted.fit` call them).
"""
from __future__ import annotations

import logging
import os
import warnings
from typing import Any

log = logging.getLogger(__name__)

PREFERENCE = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
LLVM_FIX = "install Debian's libllvm19 (apt-get install -y libllvm19) for the ~3x faster llvm_ad_rgb variant"


def llvm_fix() -> str:
    """How to get the llvm variants: Debian's libllvm19, or, where DRJIT_LIBLLVM_PATH names a library Dr.Jit could
    not load, that variable (it is tried instead of the system's)."""
    path = os.environ.get("DRJIT_LIBLLVM_PATH")
    if path:
        return (f"DRJIT_LIBLLVM_PATH={path!r} names no libLLVM Dr.Jit can load: unset it, or point it at one "
                "(Debian's libllvm19), for the ~3x faster llvm_ad_rgb variant")
    return LLVM_FIX


def _usable(variant: str) -> bool:
    import mitsuba as mi

    if variant not in mi.variants():
        return False
    from scenes.files import caught_stderr

    try:
        with caught_stderr() as said:  # Dr.Jit's own lines on a missing library or driver: said once, by llvm_fix
            mi.set_variant(variant)
            if variant.startswith("cuda"):
                import drjit as dr

                dr.zeros(dr.cuda.Float, 1)  # raises without a usable GPU/driver
            elif variant.startswith("llvm"):
                import drjit as dr

                dr.eval(dr.llvm.Float([1.0]) + 1)  # raises without a usable libLLVM
        return True
    except Exception as exc:  # the backends report missing drivers/libraries in various ways
        log.debug("variant %s is not usable: %s (%s)", variant, exc, " / ".join(said))
        return False


def choose_variant(requested: str | None = None, jit: bool = False) -> str:
    """Set and return a Mitsuba variant: `requested` if given, else cuda, llvm, scalar in that order.

    `requested` None or "auto" chooses; falling back to scalar warns with the fix, or, for a command that needs a
    JIT variant (`jit`: the re-render check), is a ValueError with it. A variant outside
    `PREFERENCE` (the RGB variants the scenes are built for: a mono or spectral variant would fail inside
    Dr.Jit), or one this machine cannot run, is a ValueError naming --variant.
    """
    import mitsuba as mi

    if not callable(getattr(mi, "variants", None)):  # e.g. a carried package of that name that is not Mitsuba 3
        raise ValueError(f"the 'mitsuba' package found ({getattr(mi, '__file__', None)!r}) is not Mitsuba 3 (it has "
                         "no variants()); install mitsuba==3.9.1, or pack its real wheel")
    if requested == "auto":
        requested = None
    if requested:
        if requested not in PREFERENCE:
            raise ValueError(
                f"--variant: {requested!r} is not supported, expected auto or one of {', '.join(PREFERENCE)} "
                "(the scenes use RGB colours)"
            )
        if requested not in mi.variants():
            raise ValueError(
                f"--variant: {requested!r} is not built into this Mitsuba, expected one of {', '.join(mi.variants())}"
            )
        if not _usable(requested):
            hint = f"; {llvm_fix()}" if requested.startswith("llvm") else ""
            raise ValueError(f"--variant: {requested!r} cannot run on this machine{hint}")
        if jit and requested.startswith("scalar"):  # the flag asked for it: named, not left to require_jit_variant
            raise ValueError(f"--variant: {requested!r} is a scalar variant; this command needs llvm_ad_rgb or "
                             "cuda_ad_rgb")
        return requested
    for variant in PREFERENCE:
        if _usable(variant):
            if variant.startswith("scalar") and jit:
                raise ValueError(f"--variant: only scalar_rgb runs on this machine; this command needs llvm_ad_rgb or "
                                 f"cuda_ad_rgb ({llvm_fix()})")
            if variant.startswith("scalar"):
                warnings.warn(
                    f"Mitsuba falls back to the slow scalar_rgb variant: {llvm_fix()}", RuntimeWarning, stacklevel=2
                )
            return variant
    raise RuntimeError("no usable Mitsuba variant among " + ", ".join(PREFERENCE))


def set_jit_threads(threads: int | None) -> None:
    """Set Dr.Jit's worker thread count (None: leave its default, one per core). The fitted mode and the
    refinement (`validate.fitted.fit`, `validate.refine`) are byte-identical run to run only with 1: with more, the
    reverse-mode derivatives of gathers are atomic scatter-adds whose order varies between runs, so the last
    float bits of gradients, and hence of every later step, change."""
    if threads is None:
        return
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"--threads: expected a positive integer, got {threads!r}")
    import drjit as dr

    dr.set_thread_count(threads)


def jit_threads() -> int:
    """Dr.Jit's current worker thread count (recorded in the fit and refine reports)."""
    import drjit as dr

    return int(dr.thread_count())


def require_variant() -> Any:
    """The `mitsuba` module, after checking that a variant is set."""
    import mitsuba as mi

    if mi.variant() is None:
        raise RuntimeError(
            "no Mitsuba variant is set: call scenes.renderer.variant.choose_variant() in the entry point"
        )
    return mi


def require_jit_variant() -> Any:
    """The `mitsuba` module, after checking that a JIT variant (llvm_* or cuda_*) is set."""
    mi = require_variant()
    variant = mi.variant()
    if not (variant.startswith("llvm") or variant.startswith("cuda")):
        raise ValueError(f"variant: {variant!r} is a scalar variant; the re-render check needs llvm_ad_rgb or "
                         f"cuda_ad_rgb ({llvm_fix()})")
    return mi


def require_ad_variant() -> Any:
    """The `mitsuba` module, after checking that an automatic-differentiation JIT variant (llvm_ad_*,
    cuda_ad_*) is set: the fitted mode of the re-render check differentiates through Mitsuba."""
    import mitsuba as mi

    v = mi.variant()
    if v is None or "_ad_" not in v:
        raise ValueError(
            f"--variant: fitted mode needs llvm_ad_rgb or cuda_ad_rgb (automatic differentiation), got {v!r}"
        )
    return mi
