"""Shared fixtures: Mitsuba variants for physics tests, the optional ../shared folder."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"

os.environ.setdefault("DRJIT_CACHE_DIR", str(Path.home() / ".drjit"))


def set_variant_or_skip(variant: str) -> str:
    from scenes.variant import _usable

    if not _usable(variant):
        pytest.skip(f"Mitsuba variant {variant} is not usable on this machine")
    return variant


@pytest.fixture(params=["llvm_ad_rgb", "scalar_rgb"])
def any_variant(request) -> str:
    """Run a test on both CPU variants (the physics must not depend on the backend)."""
    return set_variant_or_skip(request.param)


@pytest.fixture
def llvm() -> str:
    """The fast CPU variant (determinism and dataset tests)."""
    return set_variant_or_skip("llvm_ad_rgb")


@pytest.fixture
def shared() -> Path:
    if not SHARED.is_dir():
        pytest.skip("../shared is not present")
    return SHARED
