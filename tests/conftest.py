"""Shared fixtures: the Mitsuba variants of the tests (generated from one list, skipped in one place), the optional
../shared folder, small rendered datasets and synthetic object folders. Analytic inputs (sphere, ellipsoid, light
draws) are plain factories in `tests/fixtures.py`."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"

os.environ.setdefault("DRJIT_CACHE_DIR", str(Path.home() / ".drjit"))

VARIANTS = ("llvm_ad_rgb", "scalar_rgb")
"""The Mitsuba variants the tests run on, fastest first: each gets a fixture `variant_<name>`, `any_variant` runs a
test on each, and `use_variant` is the one place that decides whether one is usable here."""


def use_variant(*variants: str) -> str:
    """Set the first of `variants` (default: any of `VARIANTS`) this machine can run and return its name; skip
    the calling test when it can run none. The only caller of `scenes.renderer.variant._usable` in the tests (the module
    has no public check that does not raise: `choose_variant` raises instead of skipping)."""
    from scenes.renderer.variant import _usable

    for variant in variants or VARIANTS:
        if _usable(variant):  # sets it
            return variant
    pytest.skip(f"Mitsuba variant {' / '.join(variants or VARIANTS)} is not usable on this machine")


def _variant_fixture(variant: str):
    @pytest.fixture(name=f"variant_{variant}")
    def fixture() -> str:
        return use_variant(variant)

    fixture.__doc__ = f"Set Mitsuba variant {variant} for the test (skipped where it is not usable)."
    return fixture


for _variant in VARIANTS:  # variant_llvm_ad_rgb, variant_scalar_rgb
    globals()[f"variant_{_variant}"] = _variant_fixture(_variant)


@pytest.fixture(params=VARIANTS)
def any_variant(request) -> str:
    """Run a test on each variant of `VARIANTS` (the physics must not depend on the backend)."""
    return use_variant(request.param)


def render_dataset(out: Path, *flags: str, variant: str | None = None) -> list[Path]:
    """Render a small dataset with `wildgen.make` in this process (`flags` as on its command line, plus --workers 0
    --quiet) and return its object folders, sorted; the test is skipped when `variant` (default: any of
    `VARIANTS`) is not usable. `variant` is only checked: pass --variant in `flags` to render with it."""
    use_variant(*([variant] if variant else []))
    from wildgen.make import main

    assert main([*flags, "--workers", "0", "--quiet", "--out", str(out)]) == 0
    return sorted(Path(out).glob("*.data"))


@pytest.fixture
def shared() -> Path:
    if not SHARED.is_dir():
        pytest.skip("../shared is not present")
    return SHARED


def write_synthetic_object(folder: Path, images: np.ndarray, mask: np.ndarray, normals: np.ndarray | None,
                           light_family: str | None = "directional", directions: np.ndarray | None = None,
                           irradiance: np.ndarray | None = None, other: int = 0) -> Path:
    """An object folder in our layout written through `scenes.folder.format` (no rendering): L*.png, mask.png,
    normal.tif and a partial scene.json (light family, camera-frame directional lights when given)."""
    from scenes.folder.format import write_object_folder

    scene: dict = {"light_family": light_family}
    if directions is not None:
        irr = np.ones((len(directions), 3)) if irradiance is None else np.asarray(irradiance)
        scene["camera_lights"] = [{"directional": [{"direction_to_light": np.asarray(d).tolist(),
                                                    "irradiance": np.asarray(e).tolist()}], "other": other}
                                  for d, e in zip(directions, irr)]
    return write_object_folder(folder, images, mask, normals, scene=scene)


@pytest.fixture
def synthetic_object(tmp_path) -> Path:
    """A Lambertian sphere (32 x 32, 6 directional lights) as an object folder `tmp_path/ball.data`."""
    from fixtures import sphere

    k = 6
    n, mask = sphere(32)
    th = np.radians(np.linspace(10, 40, k))
    ph = np.linspace(0, 2 * np.pi, k, endpoint=False)
    L = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)
    images = 0.8 * np.clip(np.einsum("hwc,kc->khw", n, L), 0, None)[..., None] * np.array([0.9, 0.7, 0.5])
    return write_synthetic_object(tmp_path / "ball.data", images, mask, n, directions=L)
