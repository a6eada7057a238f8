"""Shared fixtures: Mitsuba variants for physics tests, the optional ../shared folder, synthetic object folders."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"

os.environ.setdefault("DRJIT_CACHE_DIR", str(Path.home() / ".drjit"))


def set_variant_or_skip(variant: str) -> str:
    from scenes.variant import _usable

    if not _usable(variant):
        pytest.skip(f"Mitsuba variant {variant} is not usable on this machine")
    return variant


def render_dataset(out: Path, *flags: str) -> list[Path]:
    """Render a small dataset with `wildgen.make` in this process (`flags` as on its command line) and return its
    object folders, sorted; the test is skipped when no Mitsuba CPU variant is usable."""
    from scenes.variant import _usable

    if not _usable("llvm_ad_rgb") and not _usable("scalar_rgb"):
        pytest.skip("no Mitsuba variant usable here")
    from wildgen.make import main

    assert main([*flags, "--workers", "0", "--quiet", "--out", str(out)]) == 0
    return sorted(Path(out).glob("*.data"))


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


def write_synthetic_object(folder: Path, images: np.ndarray, mask: np.ndarray, normals: np.ndarray | None,
                           light_family: str | None = "directional", directions: np.ndarray | None = None,
                           irradiance: np.ndarray | None = None, other: int = 0) -> Path:
    """An object folder in our layout written through `scenes.objfolder` (no rendering): L*.png, mask.png,
    normal.tif and a partial scene.json (light family, camera-frame directional lights when given)."""
    from scenes.objfolder import write_object_folder

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
    size, k = 32, 6
    rows, cols = np.mgrid[0:size, 0:size]
    x, y = (cols + 0.5 - size / 2) / (size / 2 - 2), -(rows + 0.5 - size / 2) / (size / 2 - 2)
    mask = x * x + y * y < 1.0
    n = np.stack([x, y, np.sqrt(np.clip(1 - x * x - y * y, 0, None))], -1) * mask[..., None]
    th = np.radians(np.linspace(10, 40, k))
    ph = np.linspace(0, 2 * np.pi, k, endpoint=False)
    L = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)
    images = 0.8 * np.clip(np.einsum("hwc,kc->khw", n, L), 0, None)[..., None] * np.array([0.9, 0.7, 0.5])
    return write_synthetic_object(tmp_path / "ball.data", images, mask, n, directions=L)
