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
from fixtures import ellipsoid_normals, lambertian, ortho_sphere, random_lights, shading, train

from scenes.cli.options import field_docs
from unips.checkpoint import load_model, load_training_checkpoint, save_checkpoint
from unips.models import create_model
from unips.probes import probe_images, probe_object, summarise
from unips.train import COMMAND, TrainConfig, main
from unips.train_run import lr_factor

REPO = Path(__file__).resolve().parents[1]


def test_every_config_field_has_a_docstring_and_a_flag() -> None:
    docs = field_docs(TrainConfig)
    names = [f.name for f in dataclasses.fields(TrainConfig)]
    assert set(names) == set(docs), set(names) ^ set(docs)
    help_text = COMMAND.help()
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


def test_an_existing_run_is_never_overwritten_without_the_flag(train_dataset, tmp_path, capsys) -> None:
    out = tmp_path / "run"
    assert train(train_dataset, out, "--steps", "2") == 0
    before = _digest(out)
    assert train(train_dataset, out, "--steps", "3") == 2
    err = capsys.readouterr().err
    assert "--out" in err and "--resume" in err and "Traceback" not in err
    assert _digest(out) == before
    assert train(train_dataset, out, "--steps", "3", "--overwrite") == 0
    assert json.loads((out / "log.jsonl").read_text().splitlines()[-1])["step"] == 3


def test_init_from_takes_weights_only(train_dataset, tmp_path, capsys) -> None:
    torch.manual_seed(5)
    src = create_model("glc-test")
    save_checkpoint(tmp_path / "w.safetensors", src)
    out = tmp_path / "run"
    # --steps 1 with a tiny lr: the trained weights stay next to the initial ones, far from a fresh init.
    assert train(train_dataset, out, "--steps", "1", "--lr", "1e-9",
                 "--init-from", str(tmp_path / "w.safetensors")) == 0
    trained, _ = load_model(out / "final.safetensors")
    ref = src.state_dict()
    for k, v in trained.state_dict().items():
        assert torch.allclose(v, ref[k], atol=1e-6), k
    assert train(train_dataset, tmp_path / "r2", "--steps", "1", "--model", "glc-tiny",
                  "--init-from", str(tmp_path / "w.safetensors")) == 2
    assert "--model" in capsys.readouterr().err


def test_a_run_started_with_init_from_resumes_bit_for_bit(train_dataset, tmp_path) -> None:
    """--resume takes no --init-from (the weights come from last.pt); the resumed run ends where an
    uninterrupted one does and keeps the lineage."""
    torch.manual_seed(6)
    save_checkpoint(tmp_path / "w.safetensors", create_model("glc-test"))
    opts = ["--lr", "3e-3", "--ckpt-every", "2", "--init-from", str(tmp_path / "w.safetensors")]
    full, part = tmp_path / "full", tmp_path / "part"
    assert train(train_dataset, full, "--steps", "4", *opts) == 0
    assert train(train_dataset, part, "--steps", "2", *opts) == 0
    assert train(train_dataset, part, "--steps", "4", "--resume", *opts[:-2]) == 0
    a, b = load_training_checkpoint(full / "last.pt"), load_training_checkpoint(part / "last.pt")
    assert a["step"] == b["step"] == 4
    assert all(torch.equal(v, b["model"][k]) for k, v in a["model"].items())
    assert b["extra"]["train_args"]["init_from"] == str(tmp_path / "w.safetensors")


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


def test_probe_object_and_summary(np_rng) -> None:
    normals, mask = ellipsoid_normals(32, 32, 16, 16, 12, 12)
    imgs = lambertian(normals, mask, random_lights(np_rng, 4), np.ones((4, 3)) * 0.7)
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


def test_validation_logs_probes_and_gain(train_dataset, tmp_path) -> None:
    out = tmp_path / "run"
    assert train(train_dataset, out, "--steps", "2", "--val", str(train_dataset["val"]), "--val-every", "2",
                  "--val-pixels", "100") == 0
    rec = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines() if '"val"' in x][-1]["val"]
    assert {"all", "one", "mask", "shuffled"} <= set(rec["probes"]) and "gain" in rec
    assert set(rec["families"]) == {"directional", "point"} and "gain" in rec["families"]["point"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_torchrun_two_processes_gloo(train_dataset, tmp_path) -> None:
    """The CLI runs unchanged under torchrun (2 CPU processes, gloo); two runs give identical weights."""
    digests = []
    for name in ("a", "b"):
        out = tmp_path / name
        cmd = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2", "--master_addr", "127.0.0.1",
               "--master_port", str(_free_port()), "-m", "unips.train", "--data", str(train_dataset["train"]),
               "--val", str(train_dataset["val"]), "--val-every", "3", "--val-pixels", "50", "--model", "glc-test",
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


def write_bumpy_object(folder: Path, rng: np.random.Generator, size: int = 40, k: int = 8) -> None:
    """A Lambertian height field whose outline says little about its normals: an elliptic outline with a
    random depth scale plus random bumps, under k random directional lights (the layout of write_object)."""
    import cv2
    import tifffile

    i, j = np.mgrid[0:size, 0:size] + 0.5
    ri, rj = rng.uniform(0.3, 0.45, 2) * size
    x, y = (j - size / 2) / rj, -(i - size / 2) / ri
    q = 1 - x * x - y * y
    mask = q > 0.02
    z = rng.uniform(0.2, 1.2) * np.sqrt(np.clip(q, 0, None))
    for _ in range(3):
        f, ph = rng.uniform(2, 6, 2), rng.uniform(0, 2 * np.pi, 2)
        z = z + rng.uniform(0.02, 0.08) * np.sin(f[0] * np.pi * x + ph[0]) * np.sin(f[1] * np.pi * y + ph[1])
    # Normal of the height field in the camera frame (x right = columns, y up = -rows).
    n = np.stack([-np.gradient(z, axis=1) * size / 2, np.gradient(z, axis=0) * size / 2, np.ones_like(z)], -1)
    n = np.where(mask[..., None], n / np.linalg.norm(n, axis=-1, keepdims=True), 0.0)
    lights = random_lights(rng, k)
    images = lambertian(n, mask, lights, np.tile(rng.uniform(0.3, 0.9, 3), (k, 1)))
    folder.mkdir(parents=True)
    for t in range(k):
        rgb16 = np.round(np.clip(images[t].transpose(1, 2, 0), 0, 1) * 65535).astype(np.uint16)
        cv2.imwrite(str(folder / f"L{t:03d}.png"), rgb16[..., ::-1])
    cv2.imwrite(str(folder / "mask.png"), (mask * 255).astype(np.uint8))
    tifffile.imwrite(folder / "normal.tif", np.round((n + 1) / 2 * 65535).astype(np.uint16))
    (folder / "scene.json").write_text(json.dumps({"light_family": "directional"}))


@pytest.mark.slow
def test_training_learns_from_the_images_where_the_outline_is_not_enough(tmp_path) -> None:
    """End to end (data, augmentation, batches, loss, probes): on objects whose outline does not fix their
    normals, a short training run must gain clearly from the images. A pipeline that breaks the link
    between a pixel's intensities and its normal (a wrong augmentation sign, tokens that drop the pixel's
    observations) learns the outline only and fails here."""
    rng = np.random.default_rng(7)
    for t in range(64):
        write_bumpy_object(tmp_path / "train" / f"o{t}.data", rng, size=32)
    for t in range(12):
        write_bumpy_object(tmp_path / "val" / f"v{t}.data", rng, size=32)
    out = tmp_path / "run"
    assert main(["--data", str(tmp_path / "train"), "--val", str(tmp_path / "val"), "--model", "glc-test",
                 "--out", str(out), "--steps", "300", "--batch", "4", "--lr", "1e-3", "--warmup", "30", "--res", "32",
                 "--pixels", "200", "--canonical-points", "200", "--max-images", "8", "--val-every", "300",
                 "--val-pixels", "0", "--threads", "2", "--no-progress"]) == 0
    val = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines() if '"val"' in x][-1]["val"]
    print("probes after 300 steps:", {k: round(v, 1) for k, v in val["probes"].items()}, "gain", round(val["gain"], 1))
    assert val["gain"] > 5.0, val["probes"]
    assert val["probes"]["shuffled"] > val["probes"]["all"] + 2.0, val["probes"]


def _lambertian_sphere(size: int, lights: np.ndarray) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Analytic Lambertian sphere filling a size x size frame: images (K, 3, H, W), mask, normals."""
    points, r2 = ortho_sphere(size, 1.0)
    inside = r2 < 0.95 ** 2
    n = points.transpose(2, 0, 1) * inside  # (3, H, W)
    shade = shading(n.transpose(1, 2, 0), lights) * inside  # (K, H, W)
    images = np.repeat(shade[:, None], 3, axis=1) * np.array([0.8, 0.5, 0.3])[None, :, None, None]
    return (torch.from_numpy(images).float(), torch.from_numpy(inside[None].astype(np.float32)),
            torch.from_numpy(n).float())


def test_interior_crop_keeps_images_and_normals_consistent_and_drops_the_outline(np_rng) -> None:
    from unips.augment import interior_crop

    lights = np.array([[0.0, 0.0, 1.0], [0.5, 0.3, 0.81], [-0.4, 0.2, 0.89]])
    lights /= np.linalg.norm(lights, axis=1, keepdims=True)
    images, mask, normals = _lambertian_sphere(96, lights)
    for _ in range(5):
        crop, m, n = interior_crop(images, mask, normals, np_rng)
        assert crop.shape == images.shape and m.shape == mask.shape and n.shape == normals.shape
        assert torch.all(m == 1)  # no outline left
        assert torch.allclose(n.norm(dim=0), torch.ones(96, 96), atol=1e-5)
        assert torch.allclose(crop.mean(dim=(1, 2, 3)), torch.ones(3), atol=1e-5)  # re-normalised per image
        # Physics still holds in the crop: each image / (n . l) is one constant per image and channel.
        for k in range(3):
            shade = torch.einsum("c,chw->hw", torch.from_numpy(lights[k]).float(), n)
            lit = shade > 0.3
            ratio = crop[k, 0][lit] / shade[lit]
            assert float(ratio.std() / ratio.mean()) < 0.01
    # A mask too small for the smallest square: no crop.
    tiny = torch.zeros_like(mask)
    tiny[:, 40:50, 40:50] = 1
    assert interior_crop(images, tiny, normals, np_rng, min_fraction=16 / 96) is None


def test_interior_crop_enters_batches_only_when_asked(train_dataset) -> None:
    from unips.train_data import load_samples, make_batch

    samples = load_samples(train_dataset["train"], 32)
    kw = dict(seed=3, batch=2, min_images=2, max_images=4, pixels=50, canonical=16)
    plain, none = make_batch(samples, 5, **kw), make_batch(samples, 5, interior_crop=0.0, **kw)
    assert torch.equal(plain.images, none.images)  # probability 0 draws nothing: old trajectories kept
    every = make_batch(samples, 5, interior_crop=1.0, **kw)
    assert torch.all(every.mask == 1)
    with pytest.raises(ValueError, match="--interior-crop"):
        TrainConfig(data="d", out="o", interior_crop=1.5).validate()


def test_a_data_folder_whose_name_holds_a_comma_is_one_entry(tmp_path):
    """--data separates datasets with commas; an existing folder named 'set,1' is that one folder (sweep 19: it was
    split and '.../set' reported missing), while 'a,b' of two folders is two entries."""
    from unips.train_data import data_roots

    for name in ("set,1", "a", "b"):
        (tmp_path / name).mkdir()
    assert data_roots(tmp_path / "set,1") == [tmp_path / "set,1"]
    assert data_roots(f"{tmp_path / 'a'},{tmp_path / 'b'}") == [tmp_path / "a", tmp_path / "b"]
