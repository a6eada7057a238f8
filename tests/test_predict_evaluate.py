"""The predict and evaluate CLIs end to end on object folders written here."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest
from fixtures import write_predict_diligent, write_predict_ours

from scenes.images import read_normals, write_normal_exr, write_normal_map
from scenes.metrics import mean_angular_error
from unips import evaluate as ev
from unips import predict as pr


@pytest.fixture
def dataset(tmp_path):
    root = tmp_path / "data"
    truth = {"alpha": write_predict_ours(root / "alpha.data"),
             "beta": write_predict_ours(root / "beta.data", seed=1, family="hdri"),
             "gamma": write_predict_diligent(root / "gamma")}
    return root, truth


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


@pytest.mark.parametrize("method,tol", [("least-squares", 1.0), ("sh-uncalibrated", 5.0)])
def test_predict_then_evaluate(dataset, tmp_path, method, tol, capsys):
    root, truth = dataset
    out = tmp_path / "pred"
    assert pr.main(["--method", method, "--input", str(root), "--out", str(out)]) == 0
    for name, (n, mask) in truth.items():
        d = out / name
        for f in ("normal.png", "normal.exr", "normal_vis.png", "predict.json"):
            assert (d / f).is_file(), d / f
        info = json.loads((d / "predict.json").read_text())
        assert info["method"] == method and info["num_images"] == 8 and len(info["images_used"]) == 8
        assert info["time_s"] >= 0 and info["checkpoint"] is None
        png = read_normals(d / "normal.png")
        exr = read_normals(d / "normal.exr")
        assert png.shape == n.shape and np.all(exr[~mask] == 0) and np.all(png[~mask] == 0)
        assert np.abs(png - exr).max() <= 1.0 / 65535 + 1e-6
        raw = cv2.imread(str(d / "normal.png"), cv2.IMREAD_UNCHANGED)
        assert raw.dtype == np.uint16 and np.all(raw[~mask] == 32768)
        assert mean_angular_error(exr, n, mask) < tol
    capsys.readouterr()
    assert ev.main(["--pred", str(out), "--gt", str(root)]) == 0
    table = capsys.readouterr().out
    assert "alpha" in table and "mean" in table
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics["objects"]) == {"alpha", "beta", "gamma"}
    assert metrics["objects"]["beta"]["light_family"] == "hdri"
    assert metrics["objects"]["gamma"]["light_family"] == "directional"
    assert metrics["per_family"]["directional"]["n_objects"] == 2
    assert metrics["mean_mae_deg"] < tol and metrics["missing"] == []
    for name, (n, mask) in truth.items():
        assert metrics["objects"][name]["n_pixels"] == int(mask.sum())
        assert (out / name / "error_map.png").is_file()
    rows = list(csv.DictReader(open(out / "metrics.csv")))
    assert [r["object"] for r in rows] == ["alpha", "beta", "gamma"]


def test_predict_max_images_and_single_object(dataset, tmp_path):
    root, _ = dataset
    out = tmp_path / "p1"
    assert pr.main(["--method", "least-squares", "--input", str(root / "alpha.data"), "--out", str(out),
                    "--max-images", "4"]) == 0
    info = json.loads((out / "alpha" / "predict.json").read_text())
    assert info["images_used"] == [f"L{i:03d}.png" for i in range(4)]
    assert sorted(p.name for p in out.iterdir()) == ["alpha"]


def _rotated(n: np.ndarray, mask: np.ndarray, deg: float) -> np.ndarray:
    """Each normal rotated by exactly ``deg`` about an axis perpendicular to it."""
    axis = np.cross(n, np.array([0.2, -0.4, 0.9]))
    axis /= np.maximum(np.linalg.norm(axis, axis=2, keepdims=True), 1e-12)
    t = np.radians(deg)
    out = n * np.cos(t) + np.cross(axis, n) * np.sin(t)
    out[~mask] = 0
    return out


def test_evaluate_known_answer(dataset, tmp_path, capsys):
    root, truth = dataset
    pred = tmp_path / "rot"
    for name, (n, mask) in truth.items():
        write_normal_exr(pred / name / "normal.exr", _rotated(n, mask, 10.0))
    assert ev.main(["--pred", str(pred), "--gt", str(root)]) == 0
    m = json.loads((pred / "metrics.json").read_text())
    for name in truth:
        o = m["objects"][name]
        assert abs(o["mae_deg"] - 10.0) < 1e-3 and abs(o["median_deg"] - 10.0) < 1e-3
        assert o["pct_below_11_25"] == 100.0 and o["pct_below_30"] == 100.0
    assert abs(m["mean_mae_deg"] - 10.0) < 1e-3
    # The error map: 10/90 of the colour scale inside, black outside.
    img = cv2.imread(str(pred / "alpha" / "error_map.png"))
    n, mask = truth["alpha"]
    s = ev.error_map_scale(mask.shape[0])
    h, w = mask.shape
    assert s > 1 and img.shape[0] >= ev.ERROR_MAP_MIN_HEIGHT and img.shape[1] > w * s  # enlarged, bar on the right
    expected = cv2.applyColorMap(np.full((1, 1), round(10 / 90 * 255), np.uint8), cv2.COLORMAP_JET)[0, 0]
    big = np.repeat(np.repeat(mask, s, 0), s, 1)
    assert np.all(img[:h * s, :w * s][big] == expected) and np.all(img[:h * s, :w * s][~big] == 0)
    bar = img[:h * s, w * s:]
    blue, red = cv2.applyColorMap(np.array([[0, 255]], np.uint8), cv2.COLORMAP_JET)[0]
    assert (bar == blue).all(-1).any() and (bar == red).all(-1).any()  # the colour scale 0..90 deg is drawn
    # 16-bit PNG predictions give the same answer within quantisation.
    png_dir = tmp_path / "rot_png"
    for name, (n, mask) in truth.items():
        write_normal_map(png_dir / name / "normal.png", _rotated(n, mask, 10.0))
    capsys.readouterr()
    assert ev.main(["--pred", str(png_dir), "--gt", str(root)]) == 0
    assert abs(json.loads((png_dir / "metrics.json").read_text())["mean_mae_deg"] - 10.0) < 0.01


def test_evaluate_missing_prediction(dataset, tmp_path, capsys):
    root, truth = dataset
    pred = tmp_path / "partial"
    n, mask = truth["alpha"]
    write_normal_exr(pred / "alpha" / "normal.exr", n)
    assert ev.main(["--pred", str(pred), "--gt", str(root)]) == 1
    captured = capsys.readouterr()
    assert "MISSING" in captured.out and "beta" in captured.err and "gamma" in captured.err
    assert json.loads((pred / "metrics.json").read_text())["missing"] == ["beta", "gamma"]
    # An earlier evaluation's metrics are replaced only with --overwrite (the rule of every command).
    assert ev.main(["--pred", str(pred), "--gt", str(root), "--allow-missing"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert ev.main(["--pred", str(pred), "--gt", str(root), "--allow-missing", "--overwrite"]) == 0
    assert json.loads((pred / "metrics.json").read_text())["objects"]["alpha"]["mae_deg"] < 1e-3


def test_cli_bad_input(dataset, tmp_path, capsys, monkeypatch):
    root, truth = dataset
    assert pr.main(["--method", "least-squares", "--input", str(tmp_path / "nope"), "--out", str(tmp_path)]) == 2
    assert "nope" in _one_line_error(capsys)
    assert pr.main(["--method", "magic", "--input", str(root), "--out", str(tmp_path)]) == 2
    assert "magic" in _one_line_error(capsys)
    assert pr.main(["--method", "least-squares", "--checkpoint", "x.safetensors", "--input", str(root),
                    "--out", str(tmp_path / "o")]) == 2
    assert "--checkpoint" in _one_line_error(capsys)
    assert pr.main(["--method", "least-squares", "--input", str(root), "--out", str(tmp_path / "o"),
                    "--max-images", "0"]) == 2
    _one_line_error(capsys)
    # A UniPS folder has no calibrated lights.
    uni = tmp_path / "uni"
    uni.mkdir()
    for f in (root / "alpha.data").glob("L*.png"):
        (uni / f.name).write_bytes(f.read_bytes())
    assert pr.main(["--method", "least-squares", "--input", str(uni), "--out", str(tmp_path / "o")]) == 2
    assert "calibrated" in _one_line_error(capsys)
    # Model without a checkpoint while the shipped model's weights file is missing: refused, never fresh weights.
    from unips.models import DEFAULT_MODEL, Pretrained, registry

    monkeypatch.setitem(registry._PRETRAINED, DEFAULT_MODEL, Pretrained(weights=str(tmp_path / "gone.safetensors"),
                                                                        card=str(tmp_path / "gone.json")))
    assert pr.main(["--method", "model", "--input", str(root), "--out", str(tmp_path / "o")]) == 2
    assert "no shipped weights" in _one_line_error(capsys)
    assert not (tmp_path / "o").exists()
    assert pr.main(["--method", "model", "--checkpoint", str(tmp_path / "none.safetensors"),
                    "--input", str(root), "--out", str(tmp_path / "o")]) == 2
    assert "none.safetensors" in _one_line_error(capsys)
    # Evaluate: missing dirs and a prediction of the wrong size.
    assert ev.main(["--pred", str(tmp_path / "nodir"), "--gt", str(root)]) == 2
    _one_line_error(capsys)
    bad = tmp_path / "bad"
    write_normal_exr(bad / "alpha" / "normal.exr", np.zeros((5, 5, 3)))
    assert ev.main(["--pred", str(bad), "--gt", str(root / "alpha.data")]) == 2
    assert "shape" in _one_line_error(capsys)


def test_predict_model_checkpoint(dataset, tmp_path):
    torch = pytest.importorskip("torch")
    from unips.checkpoint import save_checkpoint
    from unips.models import create_model

    torch.manual_seed(0)
    ckpt = save_checkpoint(tmp_path / "test.safetensors", create_model("glc-test"))
    root, truth = dataset
    outs = []
    for res, out in ((None, tmp_path / "m1"), ("32", tmp_path / "m2")):
        argv = ["--method", "model", "--checkpoint", str(ckpt), "--input", str(root / "alpha.data"),
                "--out", str(out), "--max-images", "3"]
        if res:
            argv += ["--res", res]
        assert pr.main(argv) == 0
        info = json.loads((out / "alpha" / "predict.json").read_text())
        assert info["model_name"] == "glc-test" and info["checkpoint"] == str(ckpt.resolve())
        n = read_normals(out / "alpha" / "normal.exr")
        _, mask = truth["alpha"]
        assert n.shape == mask.shape + (3,)
        assert np.allclose(np.linalg.norm(n[mask], axis=1), 1.0, atol=1e-4) and np.all(n[~mask] == 0)
        outs.append(n)
    # Same weights, same input: deterministic.
    assert pr.main(["--method", "model", "--checkpoint", str(ckpt), "--input", str(root / "alpha.data"),
                    "--out", str(tmp_path / "m3"), "--max-images", "3"]) == 0
    assert np.array_equal(read_normals(tmp_path / "m3" / "alpha" / "normal.exr"), outs[0])
