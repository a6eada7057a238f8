"""The tests' fixtures, and only fixtures (no test file imports this module; the helpers they share are in
tests/fixtures.py): the Mitsuba variants, set and cleaned up around each test as Mitsuba's own test fixtures do
(generated from one list, skipped in one place), a seeded numpy generator, the optional ../shared folder, and the
object folders and datasets that several test files read."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from fixtures import (
    SHARED,
    TO_LIGHT,
    VARIANTS,
    release_drjit,
    render_lambertian_sphere_folder,
    shading,
    sphere,
    use_variant,
    write_object,
    write_synthetic_object,
)

os.environ.setdefault("DRJIT_CACHE_DIR", str(Path.home() / ".drjit"))  # before any test imports Dr.Jit


def _variant_fixture(variant: str):
    @pytest.fixture(name=f"variant_{variant}")
    def fixture():
        # What earlier tests and module-scoped fixtures left, released once per test, before it, as Mitsuba's
        # fixtures do (after it as well doubled the cost: 0.2 s a release with torch and Mitsuba loaded).
        release_drjit()
        return use_variant(variant)

    fixture.__doc__ = (f"Set Mitsuba variant {variant} for the test (skipped where it is not usable); Dr.Jit's "
                       "caches and registry are released before it (`fixtures.release_drjit`).")
    return fixture


for _variant in VARIANTS:  # variant_llvm_ad_rgb, variant_scalar_rgb
    globals()[f"variant_{_variant}"] = _variant_fixture(_variant)


@pytest.fixture(params=VARIANTS)
def any_variant(request):
    """Run a test on each variant of `VARIANTS` (the physics must not depend on the backend), cleaned up as
    `variant_*`."""
    release_drjit()
    return use_variant(request.param)


@pytest.fixture
def jit(variant_llvm_ad_rgb):
    """The `mitsuba` module on llvm_ad_rgb (a JIT variant: the re-render check's Python BSDF and the fitted mode's
    derivatives need one; install libllvm19 where it is skipped)."""
    import mitsuba as mi

    return mi


@pytest.fixture
def np_rng() -> np.random.Generator:
    """A seeded numpy generator for a test's scratch data (seed 0, the one the tests used on their own)."""
    return np.random.default_rng(0)


@pytest.fixture
def shared() -> Path:
    if not SHARED.is_dir():
        pytest.skip("../shared is not present")
    return SHARED


@pytest.fixture
def synthetic_object(tmp_path) -> Path:
    """A Lambertian sphere (32 x 32, 6 directional lights) as an object folder `tmp_path/ball.data`."""
    k = 6
    n, mask = sphere(32)
    th = np.radians(np.linspace(10, 40, k))
    ph = np.linspace(0, 2 * np.pi, k, endpoint=False)
    L = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)
    images = 0.8 * shading(n, L)[..., None] * np.array([0.9, 0.7, 0.5])
    return write_synthetic_object(tmp_path / "ball.data", images, mask, n, directions=L)


@pytest.fixture(scope="module")
def lambertian_sphere_folder(tmp_path_factory) -> Path:
    """The fitted check's sphere: Lambertian (albedo 0.7) under 8 directional lights toward `fixtures.TO_LIGHT`
    (irradiance 2), 32x32, no scene.json (rendered on llvm_ad_rgb)."""
    from scenes.lights import DirectionalLight

    use_variant("llvm_ad_rgb")
    lights = [[DirectionalLight(direction=(-d).tolist(), irradiance=2.0)] for d in TO_LIGHT]
    return render_lambertian_sphere_folder(tmp_path_factory.mktemp("fit"), "lsphere", lights)


@pytest.fixture(scope="module")
def train_dataset(tmp_path_factory) -> dict[str, Path]:
    """Training objects (`fixtures.write_object`): 6 directional ones in "train", a directional and a point one in
    "val", 40x40, 6 images each."""
    root = tmp_path_factory.mktemp("data")
    rng = np.random.default_rng(123)
    for i in range(6):
        write_object(root / "train" / f"obj{i}.data", rng, 40, 6, "directional")
    for i, family in enumerate(["directional", "point"]):
        write_object(root / "val" / f"val{i}.data", rng, 40, 6, family)
    return {"train": root / "train", "val": root / "val"}
