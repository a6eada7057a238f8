"""Training configuration, schedule, --init-from, run-folder protection, probes and torchrun (gloo)."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from unips.checkpoint import load_model, save_checkpoint
from unips.models import create_model
from unips.probes import probe_images, probe_object, summarise
from unips.train import TrainConfig, build_parser, field_docs, lr_factor, main

from test_train import _train, dataset, write_object  # noqa: F401  (the module-scoped fixture)

REPO = Path(__file__).resolve().parents[1]


def test_every_config_field_has_a_docstring_and_a_flag() -> None:
    docs = field_docs(TrainConfig)
    names = [f.name for f in dataclasses.fields(TrainConfig)]
    assert set(names) == set(docs), set(names) ^ set(docs)
    help_text = build_parser().format_help()
    for name in names:
        assert "--" + name.replace("_", "-") in help_text


def test_warmup_cosine_schedule() -> None:
    cfg = TrainConfig(data="d", out="o", steps=1100, warmup=100, min_lr_ratio=0.1)
    assert lr_factor(cfg, 0) == pytest.approx(0.01)
    assert lr_factor(cfg, 99) == pytest.approx(1.0)
    assert lr_factor(cfg, 100) == pytest.approx(1.0)
    assert lr_factor(cfg, 600) == pytest.approx(0.1 + 0.9 * 0.5)  # half way through the cosine
    assert lr_factor(cfg, 1100) == pytest.approx(0.1)
    f = [lr_factor(cfg, s) for s in range(100, 1100)]
    assert all(a >= b for a, b in zip(f, f[1:]))
    step = TrainConfig(data="d", out="o", schedule="step", decay_every=10, decay=0.5)
    assert [lr_factor(step, s) for s in (0, 9, 10, 25)] == [1.0, 1.0, 0.5, 0.25]


def _digest(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def test_an_existing_run_is_never_overwritten_without_the_flag(dataset, tmp_path, capsys) -> None:
    out = tmp_path / "run"
    assert _train(dataset, out, "--steps", "2") == 0
    before = _digest(out)
    assert _train(dataset, out, "--steps", "3") == 2
    err = capsys.readouterr().err
    assert "--out" in err and "--resume" in err and "Traceback" not in err
    assert _digest(out) == before
    assert _train(dataset, out, "--steps", "3", "--overwrite") == 0
    assert json.loads((out / "log.jsonl").read_text().splitlines()[-1])["step"] == 3


def test_init_from_takes_weights_only(dataset, tmp_path, capsys) -> None:
    torch.manual_seed(5)
    src = create_model("glc-test")
    save_checkpoint(tmp_path / "w.safetensors", src)
    out = tmp_path / "run"
    # --steps 1 with a tiny lr: the trained weights stay next to the initial ones, far from a fresh init.
    assert _train(dataset, out, "--steps", "1", "--lr", "1e-9", "--init-from", str(tmp_path / "w.safetensors")) == 0
    trained, _ = load_model(out / "final.safetensors")
    ref = src.state_dict()
    for k, v in trained.state_dict().items():
        assert torch.allclose(v, ref[k], atol=1e-6), k
    assert _train(dataset, tmp_path / "r2", "--steps", "1", "--model", "glc-tiny",
                  "--init-from", str(tmp_path / "w.safetensors")) == 2
    assert "--model" in capsys.readouterr().err


def test_probes_remove_what_they_say() -> None:
    g = torch.Generator().manual_seed(0)
    images = torch.rand(5, 3, 8, 8, generator=g)
    mask = (torch.rand(1, 8, 8, generator=g) > 0.3).float()
    assert probe_images(images, mask, "one").shape == (1, 3, 8, 8)
    m = probe_images(images, mask, "mask")
    assert m.shape == images.shape and torch.equal(m, mask.expand(5, 3, 8, 8))
    s = probe_images(images, mask, "shuffled", seed=3)
    # Each pixel keeps its own observations (as RGB triples), in another order for most pixels.
    a = images.permute(2, 3, 0, 1).reshape(64, 5, 3)
    b = s.permute(2, 3, 0, 1).reshape(64, 5, 3)
    key = lambda t: t[..., 0] * 1e6 + t[..., 1] * 1e3 + t[..., 2]  # noqa: E731
    assert torch.equal(key(a).sort(dim=1).values, key(b).sort(dim=1).values)
    assert (key(a) != key(b)).any(dim=1).float().mean() > 0.5
    assert torch.equal(probe_images(images, mask, "shuffled", seed=3), s)


def test_probe_object_and_summary() -> None:
    from test_train import ellipsoid_normals, lambertian, random_lights

    normals, mask = ellipsoid_normals(32, 32, 16, 16, 12, 12)
    rng = np.random.default_rng(0)
    imgs = lambertian(normals, mask, random_lights(rng, 4), np.ones((4, 3)) * 0.7)
    model = create_model("glc-test").eval()
    args = (torch.from_numpy(imgs).float(), torch.from_numpy(mask[None]).float(),
            torch.from_numpy(normals.transpose(2, 0, 1)).float())
    res = probe_object(model, *args, pixels=50)
    assert set(res) == {"all", "one", "mask", "shuffled"} and all(0 <= v <= 180 for v in res.values())
    assert probe_object(model, *args, pixels=50) == res  # seeded pixel subset and shuffle
    one = probe_object(model, args[0][:1], *args[1:], pixels=50)
    assert "shuffled" not in one  # needs K >= 2
    summ = summarise({"a": {"all": 10.0, "mask": 25.0, "one": 20.0}, "b": {"all": 20.0, "mask": 25.0, "one": 22.0}},
                     {"a": "directional", "b": None})
    assert summ["gain"] == pytest.approx(10.0) and summ["one_minus_all"] == pytest.approx(6.0)
    assert summ["families"]["directional"]["gain"] == pytest.approx(15.0)
    assert summ["families"]["unknown"]["n"] == 1


def test_validation_logs_probes_and_gain(dataset, tmp_path) -> None:
    out = tmp_path / "run"
    assert _train(dataset, out, "--steps", "2", "--val", str(dataset["val"]), "--val-every", "2",
                  "--val-pixels", "100") == 0
    rec = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines() if '"val"' in x][-1]["val"]
    assert {"all", "one", "mask", "shuffled"} <= set(rec["probes"]) and "gain" in rec
    assert set(rec["families"]) == {"directional", "point"} and "gain" in rec["families"]["point"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_torchrun_two_processes_gloo(dataset, tmp_path) -> None:
    """The CLI runs unchanged under torchrun (2 CPU processes, gloo); two runs give identical weights."""
    digests = []
    for name in ("a", "b"):
        out = tmp_path / name
        cmd = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2", "--master_addr", "127.0.0.1",
               "--master_port", str(_free_port()), "-m", "unips.train", "--data", str(dataset["train"]),
               "--val", str(dataset["val"]), "--val-every", "3", "--val-pixels", "50", "--model", "glc-test",
               "--out", str(out), "--batch", "2", "--res", "32", "--pixels", "100", "--max-images", "4",
               "--threads", "1", "--no-progress", "--steps", "3", "--log-every", "1"]
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        r = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        log = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines()]
        assert [x["step"] for x in log if "loss" in x] == [1, 2, 3]  # rank 0 alone writes
        assert any("val" in x for x in log)
        digests.append(hashlib.sha256((out / "final.safetensors").read_bytes()).hexdigest())
    assert digests[0] == digests[1]
