"""The expected error of a map (unips.expected_error): its evidence against analytic answers, the fit against a
known law, the tie to its weights, the files, and its calibration rule on rendered objects with known normals."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from scenes.metrics import angles_deg
from tests.fixtures import render_dataset
from unips.expected_error import (
    FEATURES,
    FILES,
    ErrorModel,
    evidence_from,
    fit,
    for_weights,
    halves,
    model_path,
    sha256,
)


def _rotate_x(n: np.ndarray, deg: float) -> np.ndarray:
    t = np.radians(deg)
    r = np.array([[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    return n @ r.T


def _sphere(size: int = 24) -> tuple[np.ndarray, np.ndarray]:
    y, x = np.mgrid[-1:1:size * 1j, -1:1:size * 1j]
    mask = x ** 2 + y ** 2 < 0.8
    z = np.sqrt(np.clip(1 - x ** 2 - y ** 2, 0, 1))
    return np.where(mask[..., None], np.stack([x, -y, z], -1), 0.0).astype(np.float32), mask


def test_evidence_measures_the_angles_it_is_given():
    n, mask = _sphere()
    images = np.random.default_rng(0).uniform(0.2, 1.0, (6,) + mask.shape + (3,)).astype(np.float32)
    ev = evidence_from(n, [n, _rotate_x(n, 7.0)], (n, _rotate_x(n, 20.0)), images, mask)

    def turned(deg: float) -> np.ndarray:  # the angle a rotation by `deg` about x turns each unit normal by
        nx2 = n[mask][:, 0] ** 2
        return np.degrees(np.arccos(nx2 + (1 - nx2) * np.cos(np.radians(deg))))

    assert np.allclose(ev.views_deg[mask], turned(7.0), atol=1e-2)
    assert np.allclose(ev.halves_deg[mask], turned(20.0), atol=1e-2) and ev.halves_deg[mask].max() > 19.9
    assert np.all(ev.views_deg[~mask] == 0)
    assert np.allclose(ev.grazing[mask], 1 - n[mask][:, 2], atol=1e-6)
    # the outline distance of the centre pixel is the disc's radius in pixels, about
    c = mask.shape[0] // 2
    assert abs(ev.edge_px[c, c] - np.sqrt(0.8) * (mask.shape[0] - 1) / 2) < 1.5
    assert ev.features().shape == (mask.sum(), len(FEATURES))


def test_lit_share_counts_images_above_the_shadow_threshold():
    mask = np.ones((2, 2), bool)
    images = np.zeros((4, 2, 2, 3), np.float32)
    images[0] = 1.0
    images[1] = 0.5
    images[2] = 0.05  # below 10 % of the brightest: in shadow
    ev = evidence_from(np.dstack([np.zeros((2, 2, 2)), np.ones((2, 2))]).astype(np.float32),
                       [np.ones((2, 2, 3))] * 2, (np.ones((2, 2, 3)),) * 2, images, mask)
    assert np.allclose(ev.lit, 0.5)


def test_halves_are_disjoint_deterministic_and_cover_the_images():
    a, b = halves(10)
    assert len(a) == len(b) == 5 and not set(a) & set(b) and set(a) | set(b) == set(range(10))
    assert np.array_equal(halves(10)[0], a) and not np.array_equal(halves(10, seed=1)[0], a)
    a, b = halves(7)
    assert len(a) == len(b) == 3 and not set(a) & set(b)


def test_fit_recovers_a_known_log_linear_law():
    """Errors drawn with E[err] = exp(1 + 0.6 f0 - 0.3 f1): the fit finds those coefficients (in raw units)."""
    rng = np.random.default_rng(3)
    samples = []
    for _ in range(30):
        f = rng.normal(size=(400, 2))
        mu = np.exp(1.0 + 0.6 * f[:, 0] - 0.3 * f[:, 1])
        samples.append((f, rng.gamma(4.0, mu / 4.0)))
    w, b, mean, std = fit(samples, ridge=0.0)
    raw = w / std
    assert np.allclose(raw, [0.6, -0.3], atol=0.05), raw
    assert abs(b - raw @ mean - 1.0) < 0.05


def _model(**kw) -> ErrorModel:
    base = dict(weights_sha256="0" * 64, model_name="glc-tiny", features=list(FEATURES), mean=[0.0] * len(FEATURES),
                std=[1.0] * len(FEATURES), coef=[0.0] * len(FEATURES), intercept=float(np.log(10.0)), scale=1.0,
                ratio_quantiles=[0.8, 1.3])
    return ErrorModel(**{**base, **kw})


def test_a_model_states_its_mean_and_interval():
    n, mask = _sphere()
    images = np.ones((4,) + mask.shape + (3,), np.float32)
    ev = evidence_from(n, [n, n], (n, n), images, mask)
    st = _model().state(ev)
    assert np.allclose(st.per_pixel[mask], 10.0) and np.isnan(st.per_pixel[~mask]).all()
    assert st.mean == pytest.approx(10.0) and st.interval_80 == pytest.approx((8.0, 13.0))
    # disagreement raises the stated error where the coefficient says so
    worse = evidence_from(n, [n, n], (n, _rotate_x(n, 30.0)), images, mask)
    assert _model(coef=[0.5] + [0.0] * (len(FEATURES) - 1)).state(worse).mean > 10.0 * 1.5
    with pytest.raises(ValueError, match="features"):
        _model(features=["other"]).state(ev)


def test_the_object_stage_recovers_a_known_law_and_scales_the_map():
    from unips.expected_error import fit_object_stage

    u, k = np.geomspace(2.0, 60.0, 25), np.tile([4, 8, 16, 32, 96], 5)
    assert np.allclose(fit_object_stage(u, k, np.exp(1.0 + 0.4 * np.log(u) - 0.2 * np.log(k))), [1.0, 0.4, -0.2])
    n, mask = _sphere()
    images = np.ones((4,) + mask.shape + (3,), np.float32)
    ev = evidence_from(n, [n, n], (n, _rotate_x(n, 30.0)), images, mask)
    em = _model(coef=[0.5] + [0.0] * (len(FEATURES) - 1))
    raw = em.per_pixel(ev)
    st = _model(coef=em.coef, object_coef=[1.0, 0.4, -0.2]).state(ev)
    want = np.exp(1.0 + 0.4 * np.log(np.nanmean(raw)) - 0.2 * np.log(4))
    assert st.mean == pytest.approx(want, rel=1e-5) and st.interval_80 == pytest.approx((0.8 * want, 1.3 * want))
    # the same map, scaled: its order is kept (the sparsification), its mean is the stated one
    assert np.allclose(st.per_pixel[mask], raw[mask] * want / np.nanmean(raw), rtol=1e-5)
    # the image count's term stays within the counts it was measured on
    held = _model(coef=em.coef, object_coef=[1.0, 0.4, -0.2], object_images=[6, 16])
    assert held.state(ev).mean == pytest.approx(np.exp(1.0 + 0.4 * np.log(np.nanmean(raw)) - 0.2 * np.log(6)))
    assert held.object_mean(10.0, 96) == pytest.approx(held.object_mean(10.0, 16))


def test_the_image_counts_effect_is_measured_within_objects():
    """Objects given more images are also harder in a way the pixel map does not show (as the calibration's rows
    are: level 3 has 16 images and the most complex shapes): pooled, the law's c2 = -0.3 reads as no effect;
    measured within objects (each also seen with fewer images) it is found."""
    from unips.expected_error import fit_object_stage

    rng = np.random.default_rng(2)
    u, k, t, g = [], [], [], []
    for i in range(60):
        k0 = int(rng.choice([4, 8, 16]))
        unseen = 0.5 * np.log(k0) + rng.normal(0, 0.05)  # difficulty the pixel map misses, larger with more images
        for kk in (k0, max(2, k0 // 2), 3):
            pix = float(np.exp(2.0 + rng.normal(0, 0.3)))
            u.append(pix)
            k.append(kk)
            t.append(np.exp(0.5 + 0.8 * np.log(pix) - 0.3 * np.log(kk) + unseen))
            g.append(i)
    u, k, t = map(np.array, (u, k, t))
    pooled = fit_object_stage(u, k, t)
    within = fit_object_stage(u, k, t, np.array(g))
    assert abs(within[2] + 0.3) < 0.03 and abs(within[1] - 0.8) < 0.05, within
    assert pooled[2] > -0.1, pooled  # the confounded estimate the within-object one avoids


def test_calibrate_fits_both_stages_and_an_out_of_fold_interval(tmp_path):
    """Synthetic objects whose true error per pixel is 1.5 x the halves' angle times a per-object factor (log-normal,
    sd 0.2): the stated means follow the truth on new objects, and the out-of-fold interval holds the truth about 8
    times in 10."""
    from orchestrate.error_calibration import calibrate

    n, mask = _sphere(16)
    images = np.ones((6,) + mask.shape + (3,), np.float32)
    rng = np.random.default_rng(5)

    def sample(i: int) -> dict:
        deg = float(rng.uniform(3.0, 40.0))
        ev = evidence_from(n, [n, _rotate_x(n, deg / 3)], (n, _rotate_x(n, deg)), images, mask)
        err = 1.5 * ev.halves_deg[mask] * np.exp(rng.normal(0, 0.2)) * rng.gamma(8.0, 1 / 8.0, mask.sum())
        return {"features": ev.features(), "error": err, "true_mean": float(err.mean()), "evidence": ev,
                "name": f"o{i}"}

    w = tmp_path / "net.safetensors"
    w.write_bytes(b"weights")
    em = calibrate([sample(i) for i in range(60)], w, "glc-tiny", {})
    new = [sample(100 + i) for i in range(40)]
    stated = np.array([em.state(s["evidence"]).mean for s in new])
    true = np.array([s["true_mean"] for s in new])
    assert np.median(np.abs(np.log(stated / true))) < 0.2, (stated, true)
    lo, hi = em.ratio_quantiles
    assert 0.6 < lo < 1.0 < hi < 1.6, em.ratio_quantiles
    covered = np.mean((stated * lo <= true) & (true <= stated * hi))
    assert 0.6 <= covered <= 0.95, covered
    assert em.calibration["out_of_fold"]["folds"] == 5 and em.calibration["objects"] == 60


def test_the_error_model_belongs_to_its_weights(tmp_path):
    w = tmp_path / "net.safetensors"
    w.write_bytes(b"weights")
    em, why = for_weights(w)
    assert em is None and "no error model" in why
    _model(weights_sha256=sha256(w)).save(model_path(w))
    assert model_path(w).name == "net.expected_error.json"
    em, why = for_weights(w)
    assert em is not None and why is None
    w.write_bytes(b"other weights")
    em, why = for_weights(w)
    assert em is None and "other weights" in why


def test_the_shipped_weights_have_their_error_model():
    from unips.models import DEFAULT_MODEL
    from unips.models.registry import pretrained_entry

    weights = pretrained_entry(DEFAULT_MODEL).weights_path
    em, why = for_weights(weights)
    assert em is not None, why
    cal = em.calibration
    assert cal["objects"] >= 40 and cal["assets"] == "training split"
    lo, hi = em.ratio_quantiles
    assert lo < 1.0 < hi


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Six objects with exact normals, the five light families, 10 images (rendered once for the module)."""
    out = tmp_path_factory.mktemp("experr")
    return render_dataset(out / "ds", "--lights", "directional,point,near_area,hdri,mixed", "--objects", "6",
                          "--images", "10", "--res", "64", "--spp", "8", "--seed", "31")


@pytest.fixture(scope="module")
def shipped():
    import torch

    from unips.expected_error import for_weights
    from unips.inference import load_network

    torch.set_num_threads(2)
    net = load_network(None)
    em, why = for_weights(net.checkpoint)
    assert em is not None, why
    return net, em


def _stated_and_true(net, em, obj):
    from unips.expected_error import gather

    normals, ev = gather(net, obj, tta=net.contract.views)
    st = em.state(ev)
    return st, float(angles_deg(normals[obj.mask], obj.normals[obj.mask]).mean())


@pytest.mark.slow
def test_the_stated_error_is_calibrated_on_renders_it_never_saw(rendered, shipped):
    """The calibration rule on a small rendered set (another seed than the fit's): the stated mean follows the true
    one (within a factor 2 on every object, the interval holding at least half of them), and ranks the objects."""
    from unips.data import load_object

    net, em = shipped
    stated, true, covered = [], [], 0
    for folder in rendered:
        st, t = _stated_and_true(net, em, load_object(folder))
        stated.append(st.mean)
        true.append(t)
        covered += st.interval_80[0] <= t <= st.interval_80[1]
    stated, true = np.array(stated), np.array(true)
    assert np.all((stated > true / 2) & (stated < true * 2)), (stated, true)
    assert covered >= len(true) // 2, (stated, true)


@pytest.mark.slow
def test_the_stated_error_rises_with_fewer_images_and_a_moved_camera(rendered, shipped):
    """3 of 10 images raise the stated error on every object; every second photo shifted by 3 px raises it on average
    and on most objects (bench_expected_error measures the shares on 50 held-out objects: 98 % and 88 %). A mask
    grown by 4 px into the background is not asserted: here it raised it on 3 of 6 objects only (78 % in the bench);
    a doubtful automatic mask keeps a capture's map from "usable" instead (validate.diagnosis.usable.mask_doubts,
    tests/test_capture.py test_the_verdict_level_follows_its_rule)."""
    from orchestrate.error_calibration import camera_moved, three_images
    from unips.data import load_object

    net, em = shipped
    base, few, moved = [], [], []
    for folder in rendered:
        obj = load_object(folder)
        base.append(_stated_and_true(net, em, obj)[0].mean)
        few.append(_stated_and_true(net, em, three_images(obj))[0].mean)
        moved.append(_stated_and_true(net, em, camera_moved(obj, 3))[0].mean)
    base, few, moved = map(np.array, (base, few, moved))
    assert np.all(few > base), (base, few)
    assert moved.mean() > base.mean() and (moved > base).sum() >= len(base) // 2 + 1, (base, moved)


def test_predict_writes_the_expected_error(rendered, tmp_path):
    from scenes.images import read_exr, read_normals
    from unips.predict import main

    src = tmp_path / "obj.data"
    shutil.copytree(rendered[0], src)
    assert main(["--method", "model", "--input", str(src), "--out", str(tmp_path / "pred")]) == 0
    assert main(["--method", "model", "--input", str(src), "--out", str(tmp_path / "plain"),
                 "--no-expected-error"]) == 0
    folder = tmp_path / "pred" / "obj"
    info = json.loads((folder / "predict.json").read_text())
    e = info["expected_error_deg"]
    assert 0 < e["interval_80"][0] < e["mean"] < e["interval_80"][1]
    per = np.load(folder / FILES[0])
    mask = np.any(read_normals(folder / "normal.exr") != 0, axis=-1)
    assert per.dtype == np.float32 and np.isnan(per[~mask]).all() and np.isfinite(per[mask]).all()
    assert np.nanmean(per) == pytest.approx(e["mean"], abs=0.01)
    assert np.allclose(read_exr(folder / FILES[1])[..., 0], per, equal_nan=True)
    assert (folder / FILES[2]).stat().st_size > 0
    # stating the error leaves the map itself untouched, byte for byte
    assert (folder / "normal.png").read_bytes() == (tmp_path / "plain" / "obj" / "normal.png").read_bytes()
    plain = json.loads((tmp_path / "plain" / "obj" / "predict.json").read_text())
    assert plain["expected_error_deg"] is None and "--no-expected-error" in plain["expected_error_note"]
    assert not (tmp_path / "plain" / "obj" / FILES[0]).exists()


def test_a_baseline_states_no_error_and_says_why(rendered, tmp_path):
    from unips.predict import main

    assert main(["--method", "least-squares", "--input", str(rendered[0]), "--out", str(tmp_path / "p")]) == 0
    info = json.loads(next((tmp_path / "p").glob("*/predict.json")).read_text())
    assert info["expected_error_deg"] is None and "network" in info["expected_error_note"]



def test_refine_carries_the_input_maps_expected_error(jit, lambertian_sphere_folder, tmp_path):
    """validate.refine of a unips.predict prediction copies its expected error beside the refined map and says in
    refine_report.json which map it describes (the input's: no error model was fitted for refined maps)."""
    from unips.predict import main as predict
    from validate.refine import main as refine

    assert predict(["--method", "model", "--input", str(lambertian_sphere_folder), "--out", str(tmp_path / "p")]) == 0
    stated = json.loads((tmp_path / "p" / "lsphere" / "predict.json").read_text())["expected_error_deg"]
    assert refine(["--data", str(lambertian_sphere_folder), "--normals", str(tmp_path / "p"), "--out",
                   str(tmp_path / "r"), "--steps", "20", "--refine-steps", "10", "--rounds", "1",
                   "--threads", "1"]) == 0
    report = json.loads((tmp_path / "r" / "lsphere" / "refine_report.json").read_text())
    e = report["expected_error_deg"]
    assert e["mean"] == stated["mean"] and e["interval_80"] == stated["interval_80"] and "input map" in e["map"]
    for f in FILES:
        assert (tmp_path / "r" / "lsphere" / f).read_bytes() == (tmp_path / "p" / "lsphere" / f).read_bytes()
