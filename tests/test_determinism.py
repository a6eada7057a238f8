"""The same seed gives the same bytes whatever the Dr.Jit thread count and the number of workers.

`mi.render` adds the samples of a pixel into the film with atomic scatter-adds; where the samples of one pixel
fall into the work blocks of two threads, their float sum depends on which thread adds first. At the size used
here (64x64, 32 spp -> 35 multijitter samples, so pixels straddle the blocks of 2 threads) the old path gave
different radiance EXRs between --threads 1 and --threads 2. `scenes.renderer.render.render_film` writes each sample
to its own slot and sums each pixel in a fixed order instead (one Dr.Jit lane per pixel, `pixel_sums`).
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SPLIT = ["--lights", "mixed,near_area", "--objects", "2", "--images", "3", "--res", "64", "--spp", "32",
         "--gt-spp", "16", "--seed", "5", "--variant", "llvm_ad_rgb", "--quiet"]


def _make(out: Path, *extra: str) -> None:
    proc = subprocess.run([sys.executable, "-m", "wildgen.make", "--out", str(out), *SPLIT, *extra], cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


def object_files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes()
        for d in sorted(root.glob("*.data"))
        for p in sorted(d.rglob("*"))
        if p.is_file()
    }


def assert_same_dataset(a: Path, b: Path) -> None:
    fa, fb = object_files(a), object_files(b)
    assert sorted(fa) == sorted(fb)
    different = [rel for rel in fa if fa[rel] != fb[rel]]
    assert not different, f"{len(different)} files differ: {different[:6]}"


def test_threads_and_workers_give_the_same_bytes(tmp_path, variant_llvm_ad_rgb):
    """Every file of every object folder (radiance EXRs, PNGs, ground truth) is byte-identical between one
    process with 1 thread, one process with 2 threads, and 2 workers with 1 thread each."""
    _make(tmp_path / "t1", "--workers", "0", "--threads", "1")
    _make(tmp_path / "t2", "--workers", "0", "--threads", "2")
    _make(tmp_path / "w2", "--workers", "2", "--threads", "1")
    exrs = sorted((tmp_path / "t1").glob("*.data/aux/radiance_*.exr"))
    assert len(exrs) == 6
    assert_same_dataset(tmp_path / "t1", tmp_path / "t2")
    assert_same_dataset(tmp_path / "t1", tmp_path / "w2")


def _built(res: int, spp: int):
    from scenes.renderer.build import build_scene
    from wildgen.assets import AssetLibrary
    from wildgen.config import GenConfig
    from wildgen.sampling import sample_object

    cfg = GenConfig(lights=["mixed"], objects=1, images=1, width=res, height=res, spp=spp, gt_spp=spp)
    return build_scene(sample_object(cfg, 0, AssetLibrary.scan(None)).desc)


def test_render_film_matches_mi_render(variant_llvm_ad_rgb):
    """Same samples and channel layout as mi.render: bit-identical at 1 spp (no sum), equal up to the rounding
    of the sum at more (path tracer and the ground-truth aov pass)."""
    import mitsuba as mi

    from scenes.renderer.render import render_film

    built = _built(32, 16)
    seed = built.desc.images[0].seed
    for spp in (1, 16):
        ours, theirs = render_film(built.scene, spp, seed), np.array(mi.render(built.scene, spp=spp, seed=seed))
        assert ours.shape == theirs.shape
        if spp == 1:
            assert np.array_equal(ours, theirs)
        assert np.allclose(ours, theirs, rtol=1e-5, atol=1e-6)
    aov = mi.load_dict({"type": "aov", "aovs": "nn:sh_normal,pp:position,uv:uv", "integrator": {"type": "depth"}})
    built.park_lights()
    ours, theirs = render_film(built.scene, 1, 0, aov), np.array(mi.render(built.scene, integrator=aov, spp=1, seed=0))
    assert ours.shape == theirs.shape == (32, 32, 12)
    assert np.array_equal(ours, theirs)


def test_passes_are_deterministic_and_unbiased(variant_llvm_ad_rgb, monkeypatch):
    """Above MAX_SAMPLES_PER_PASS the samples are split into passes (the sampler advances between them, as in
    Mitsuba's own multi-pass render): still independent of the thread count, and the same noise level."""
    import drjit as dr

    import scenes.renderer.render as render

    built = _built(32, 16)
    seed = built.desc.images[0].seed
    single = render.render_film(built.scene, 16, seed)
    monkeypatch.setattr(render, "MAX_SAMPLES_PER_PASS", 32 * 32 * 4)  # 4 channels: passes of 4 spp
    before = dr.thread_count()
    try:
        dr.set_thread_count(1)
        one = render.render_film(built.scene, 16, seed)
        dr.set_thread_count(2)
        two = render.render_film(built.scene, 16, seed)
    finally:
        dr.set_thread_count(before)
    assert np.array_equal(one, two)
    ref = render.render_film(built.scene, 512, 777)[..., :3]
    rmse = lambda x: float(np.sqrt(((x[..., :3] - ref) ** 2).mean()))  # noqa: E731
    assert rmse(one) < 1.5 * rmse(single) + 1e-6
    assert abs(float(one[..., :3].mean() - single[..., :3].mean())) < 0.05 * float(abs(ref).mean()) + 1e-6


@pytest.mark.parametrize("threads", [1, 2])
def test_ground_truth_is_thread_independent(variant_llvm_ad_rgb, threads):
    import drjit as dr

    from scenes.renderer.render import render_ground_truth

    built = _built(64, 16)
    before = dr.thread_count()
    try:
        dr.set_thread_count(1)
        a = render_ground_truth(built)
        dr.set_thread_count(threads)
        b = render_ground_truth(built)
    finally:
        dr.set_thread_count(before)
    for name in ("normal", "coverage", "depth", "base_color", "roughness", "metallic", "uv"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_new_generator_features_are_byte_identical_across_workers(tmp_path, variant_llvm_ad_rgb):
    """Clusters, surface detail, focal lengths and levels draw from the object's seed only: every file (instance
    ids, normal_base.tif, view.exr, the detail's normal-map texture included) is the same in one process with 2
    threads and in 2 workers."""
    extra = ["--level", "5", "--camera", "perspective", "--focal", "15-300", "--res", "32", "--spp", "8",
             "--gt-spp", "4"]
    _make(tmp_path / "t2", *extra, "--workers", "0", "--threads", "2")
    _make(tmp_path / "w2", *extra, "--workers", "2", "--threads", "1")
    assert list((tmp_path / "t2").glob("*.data/aux/instances.png"))
    assert_same_dataset(tmp_path / "t2", tmp_path / "w2")


def test_pixel_sums_add_in_sample_order_whatever_the_threads(variant_llvm_ad_rgb):
    """The film's per-pixel reduction inside Dr.Jit gives exactly the float64 sum NumPy takes over the sample axis
    (one addition after the other in sample order), with 1 and 2 Dr.Jit threads, on 256x256 pixels (many more
    lanes than one thread's block, so the threads split them). The samples span ten orders of magnitude, so any
    other order of the additions changes low bits."""
    import drjit as dr
    import mitsuba as mi

    from scenes.renderer.render import pixel_sums

    rng = np.random.default_rng(3)
    h, w, per, c = 256, 256, 16, 4
    x = (rng.random((h, w, per, c), dtype=np.float32) * 10.0 ** rng.uniform(-5, 5, (h, w, per, c))).astype(np.float32)
    expected = x.sum(axis=2, dtype=np.float64)
    shuffled = np.flip(x, axis=2).sum(axis=2, dtype=np.float64)
    assert not np.array_equal(expected, shuffled)  # the data can tell the order apart
    channels = [mi.Float(np.ascontiguousarray(x[..., k].reshape(-1))) for k in range(c)]
    before = dr.thread_count()
    try:
        for threads in (1, 2):
            dr.set_thread_count(threads)
            got = pixel_sums(mi, channels, per, h * w).reshape(h, w, c)
            assert np.array_equal(got, expected), f"{threads} thread(s)"
    finally:
        dr.set_thread_count(before)
