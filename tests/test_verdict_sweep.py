"""The sweep of the verdict's constants (bench/bench_verdict_sweep.py): `VerdictRules` changes the verdict in the
expected direction, and without rules every function behaves as with the module's constants. Analytic captures
(a Lambertian sphere under 8 distant lights), no fits: the "renders" of the maps are their Lambertian images."""
from __future__ import annotations

import dataclasses
import importlib.util
import sys
from pathlib import Path

import numpy as np
from fixtures import TO_LIGHT, analytic_sphere

ROOT = Path(__file__).resolve().parents[1]


def _sweep_module():
    spec = importlib.util.spec_from_file_location("bench_verdict_sweep", ROOT / "bench" / "bench_verdict_sweep.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass resolves its annotations through sys.modules
    spec.loader.exec_module(module)
    return module


def _images(n: np.ndarray, mask: np.ndarray, lights: np.ndarray = TO_LIGHT, noise: float = 0.002,
            seed: int = 0) -> np.ndarray:
    """(K, H, W, 3) images of a Lambertian surface (albedo 0.7) under `lights`, Gaussian noise of `noise`."""
    shade = np.clip(np.einsum("hwc,kc->khw", n, lights), 0, None) * 0.84
    images = np.repeat(np.where(mask[None], shade, 0.0)[..., None], 3, axis=3)
    rng = np.random.default_rng(seed)
    return (images + rng.normal(0, noise, images.shape) * mask[None, ..., None]).astype(np.float32)


def test_default_rules_give_todays_explanation_and_verdict():
    from validate.fitted.verdict import VerdictRules, explain, select_observations, verdict

    n, mask = analytic_sphere()
    images = _images(n, mask)
    a, b = explain(images, mask), explain(images, mask, None, VerdictRules())
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        assert np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y, f.name
    assert verdict(a) == verdict(a, VerdictRules())
    obs = images[:, mask]
    assert np.array_equal(select_observations(obs), select_observations(obs, rules=VerdictRules()))


def test_each_constant_moves_the_verdict_the_expected_way():
    """MIN_EXPLAINED at 1.0 refuses the sphere (pixels lit in fewer than 5 images are never explained), at 0.0 it
    trusts a capture explained on less than half where its lights reach 3 dimensions; DIMENSION_NOISE far above the
    sphere's third light dimension refuses it; a tighter EXPLAINED_RELATIVE than the noise explains fewer pixels,
    a larger MIN_OBSERVATIONS too; a larger SHADOW_FRACTION keeps fewer observations. The bench's counts follow."""
    sweep = _sweep_module()
    from validate.fitted.verdict import VerdictRules, explain, select_observations, verdict

    n, mask = analytic_sphere()
    images = _images(n, mask, noise=0.004)
    ex = explain(images, mask)
    assert verdict(ex)[0] and 0.5 < ex.explained_fraction < 1.0
    assert not verdict(ex, sweep.rules_for("min_explained", 1.0))[0]
    assert not verdict(ex, sweep.rules_for("dimension_noise", 2 * max(ex.dimensions)))[0]
    assert verdict(ex, sweep.rules_for("dimension_noise", 0.0))[0]
    tight = explain(images, mask, None, sweep.rules_for("explained_relative", 0.001))
    assert tight.explained_fraction < 0.1 * ex.explained_fraction and not verdict(tight)[0]
    more = explain(images, mask, None, sweep.rules_for("min_observations", 8))
    assert more.explained_fraction < ex.explained_fraction
    assert isinstance(sweep.rules_for("min_observations", 8.0).min_observations, int)
    obs = images[:, mask]
    assert select_observations(obs, rules=sweep.rules_for("shadow_fraction", 0.5)).sum() < \
        select_observations(obs, rules=VerdictRules()).sum()

    # Shading the distant-light model cannot explain (a smooth per-image distortion, as of a near light) on the
    # upper half: about 44 % explained, the lights still reach 3 dimensions. Refused at the default MIN_EXPLAINED
    # 0.5, trusted from 0.4 down to 0; DIMENSION_NOISE above its third dimension refuses it again.
    k = np.arange(len(images))[:, None, None]
    warp = 1 + 0.5 * np.sin(1.7 * k + 6 * n[None, ..., 0] + 4 * n[None, ..., 1]) * (n[None, ..., 1] > 0)
    half = explain((images * warp[..., None]).astype(np.float32), mask)
    assert 0.4 <= half.explained_fraction < 0.5 and half.light_dimensions == 3, (half.explained_fraction,
                                                                                 half.dimensions)
    assert not verdict(half)[0]
    assert verdict(half, sweep.rules_for("min_explained", 0.4))[0]
    assert verdict(half, sweep.rules_for("min_explained", 0.0))[0]
    assert not verdict(half, dataclasses.replace(sweep.rules_for("min_explained", 0.0),
                                                 dimension_noise=2 * max(half.dimensions)))[0]

    # The cheap part of the bench on the sphere: the truth's render is its images without noise, a wrong map's
    # the images of the sphere's normals tilted by 20 degrees about the image's y axis.
    c, s = np.cos(np.radians(20)), np.sin(np.radians(20))
    tilted = np.where(mask[..., None], n @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]]), 0).astype(np.float32)
    renders = {"gt": _images(n, mask, noise=0.0)[:, mask], "tilted": _images(tilted, mask, noise=0.0)[:, mask]}
    plan = {"min_explained": (0.0, 0.5, 1.0), "explained_relative": (0.001, 0.05)}
    res = sweep.judge(images, mask, None, renders, plan)
    assert [res["min_explained"][v]["trusted"] for v in (0.0, 0.5, 1.0)] == [True, True, False]
    assert all(r["truth_first_told_apart"] for r in res["min_explained"].values())
    assert sweep.count([res], "min_explained", 1.0) == {"trusted": 0, "false_trust": 0, "false_trust_told_apart": 0,
                                                        "needless_abstention": 1}
    assert sweep.count([res], "min_explained", 0.5)["trusted"] == 1
    assert not res["explained_relative"][0.001]["trusted"]
