"""Training: analytic Lambertian objects on disk, loss decrease, exact resume, augmentation physics,
checkpoint files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from fixtures import ellipsoid_normals, lambertian, random_lights, train

from unips.augment import (
    HFLIP_MATRIX,
    TRANSPOSE_MATRIX,
    VFLIP_MATRIX,
    Augmentation,
    apply_augmentation,
    augment,
    sample_augmentation,
)
from unips.checkpoint import load_model, load_training_checkpoint, save_checkpoint, sidecar_path
from unips.models import create_model
from unips.train import main
from unips.train_data import load_samples, make_batch

# -- helpers --------------------------------------------------------------------------------

def _log(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]


# -- training -------------------------------------------------------------------------------

def test_samples_load_from_disk(train_dataset) -> None:
    samples = load_samples(train_dataset["train"], 32)
    assert len(samples) == 6
    s = samples[0]
    assert tuple(s.images.shape) == (6, 3, 32, 32) and tuple(s.mask.shape) == (1, 32, 32)
    norms = s.normals.norm(dim=0)[s.mask[0] > 0]
    assert torch.allclose(norms, torch.ones_like(norms), atol=1e-4)
    assert s.light_family == "directional"


def test_several_data_directories_are_pooled(train_dataset) -> None:
    both = f"{train_dataset['train']},{train_dataset['val']}"
    samples = load_samples(both, 32)
    assert [s.name for s in samples] == [f"train/obj{i}" for i in range(6)] + ["val/val0", "val/val1"]
    assert torch.equal(samples[0].images, load_samples(train_dataset["train"], 32)[0].images)
    with pytest.raises(ValueError, match="same name"):
        load_samples(f"{train_dataset['train']},{train_dataset['train']}", 32)
    with pytest.raises(FileNotFoundError, match="nowhere"):
        load_samples(f"{train_dataset['train']},{train_dataset['train'].parent / 'nowhere'}", 32)


def test_batches_are_a_function_of_seed_and_step(train_dataset) -> None:
    samples = load_samples(train_dataset["train"], 32)
    kw = dict(seed=3, batch=2, min_images=2, max_images=4, pixels=50, canonical=32)
    a, b, c = make_batch(samples, 5, **kw), make_batch(samples, 5, **kw), make_batch(samples, 6, **kw)
    assert torch.equal(a.images, b.images) and torch.equal(a.coords, b.coords)
    assert not (a.images.shape == c.images.shape and torch.equal(a.images, c.images))
    valid = a.weight > 0
    norms = a.target.norm(dim=-1)[valid]
    assert torch.allclose(norms, torch.ones_like(norms), atol=1e-4)
    # At working resolution == canonical, the canonical part is exactly the interior mask pixels.
    n_can = int(a.is_canonical.sum())
    assert n_can >= int(a.weight[0, a.is_canonical].sum()) > 100


def test_training_reduces_the_loss(train_dataset, tmp_path) -> None:
    out = tmp_path / "run"
    assert train(train_dataset, out, "--steps", "40", "--lr", "3e-3", "--val", str(train_dataset["val"]),
                  "--val-every", "40", "--ckpt-every", "40") == 0
    records = _log(out)
    losses = [r["loss"] for r in records if "loss" in r]
    assert len(losses) == 40
    first, last = np.mean(losses[:5]), np.mean(losses[-10:])
    print(f"loss first 5 steps {first:.4f}, last 10 steps {last:.4f}")
    assert last < 0.6 * first
    val = [r["val"] for r in records if "val" in r]
    assert len(val) == 1 and set(val[0]["families"]) == {"directional", "point"}
    assert 0 < val[0]["mean"] < 90
    for name in ("last.pt", "final.safetensors", "final.json", "best.safetensors", "best.json"):
        assert (out / name).is_file(), name
    model, meta = load_model(out / "best.safetensors")
    assert meta["model_name"] == "glc-test" and meta["extra"]["step"] == 40


def test_resume_is_bit_for_bit(train_dataset, tmp_path) -> None:
    # Dropout and drop path on, so the torch RNG matters too.
    opts = ["--model-option", "dropout=0.1", "--model-option", "swin_drop_path=0.1", "--lr", "3e-3",
            "--schedule", "step", "--decay-every", "2", "--ckpt-every", "3", "--val", str(train_dataset["val"]),
            "--val-every", "2"]
    full, part = tmp_path / "full", tmp_path / "part"
    assert train(train_dataset, full, "--steps", "6", *opts) == 0
    assert train(train_dataset, part, "--steps", "3", *opts) == 0
    seconds_at_3 = load_training_checkpoint(part / "last.pt")["extra"]["elapsed_s"]
    assert train(train_dataset, part, "--steps", "6", "--resume", *opts) == 0
    a = load_training_checkpoint(full / "last.pt")
    b = load_training_checkpoint(part / "last.pt")
    assert a["step"] == b["step"] == 6
    for key, value in a["model"].items():
        assert torch.equal(value, b["model"][key]), key
    for sa, sb in zip(a["optimizer"]["state"].values(), b["optimizer"]["state"].values()):
        assert all(torch.equal(sa[k], sb[k]) for k in sa)
    def losses(out):
        return [(r["step"], r["loss"], r["lr"], r["k"]) for r in _log(out) if "loss" in r]

    assert losses(full) == losses(part) and len(losses(full)) == 6
    # The log's elapsed time goes on from the checkpoint's at a resume instead of restarting at 0.
    times = {r["step"]: r["elapsed_s"] for r in _log(part) if "loss" in r}
    assert 0 < seconds_at_3 <= times[4] <= times[5] <= times[6] <= b["extra"]["elapsed_s"]
    # And training did change the weights.
    fresh = create_model("glc-test", dropout=0.1, swin_drop_path=0.1).state_dict()
    assert any(not torch.equal(v, fresh[k]) for k, v in a["model"].items())
    # Changing a trajectory setting on resume is refused.
    assert train(train_dataset, part, "--steps", "8", "--resume", *opts, "--seed", "9") == 2


def test_resume_refuses_data_changed_under_the_same_names(train_dataset, tmp_path, capsys) -> None:
    """Sweep 26: two objects swapped under their names, or an image fewer in every object, was resumed without a
    word (only the names were compared): a run trained half on one dataset and half on another. Both refused now;
    the same data copied elsewhere still resumes (the digest is of the decoded contents, not of paths)."""
    import shutil

    data = tmp_path / "train"
    shutil.copytree(train_dataset["train"], data)
    here = {"train": data}
    run = tmp_path / "run"
    assert train(here, run, "--steps", "1") == 0
    moved = shutil.move(data, tmp_path / "moved")
    assert train({"train": Path(moved)}, run, "--steps", "2", "--resume") == 0  # same contents at another path
    shutil.move(moved, data)
    (data / "obj0.data").rename(tmp_path / "t")
    (data / "obj1.data").rename(data / "obj0.data")
    (tmp_path / "t").rename(data / "obj1.data")
    capsys.readouterr()
    assert train(here, run, "--steps", "3", "--resume") == 2
    assert "differ from the checkpoint's (the same names hold other images" in capsys.readouterr().err
    for obj in data.iterdir():  # back in place, then one image fewer in each (its light too)
        (obj / "L005.png").unlink()
        scene = json.loads((obj / "scene.json").read_text())
        (obj / "scene.json").write_text(json.dumps({**scene, "camera_lights": scene["camera_lights"][:5]}))
    (data / "obj0.data").rename(tmp_path / "t")
    (data / "obj1.data").rename(data / "obj0.data")
    (tmp_path / "t").rename(data / "obj1.data")
    assert train(here, run, "--steps", "3", "--resume") == 2
    assert "'obj0' has 5 images, 6 in the checkpoint" in capsys.readouterr().err


def test_cli_errors_are_one_line(train_dataset, tmp_path, capsys) -> None:
    assert main(["--data", str(tmp_path / "nope"), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "nope" in err[0]
    assert train(train_dataset, tmp_path / "o2", "--steps", "0") == 2
    assert "--steps" in capsys.readouterr().err
    assert train(train_dataset, tmp_path / "o3", "--steps", "2", "--resume") == 2
    assert "last.pt" in capsys.readouterr().err


# -- augmentation physics -------------------------------------------------------------------

def _transformed_params(aug: Augmentation, h: int, w: int, p: tuple[float, float, float, float]):
    """Ellipsoid image-space parameters after the augmentation, by image geometry alone."""
    ci, cj, ri, rj = p
    if aug.transpose:  # rows <-> columns
        ci, cj, ri, rj, h, w = cj, ci, rj, ri, w, h
    if aug.hflip:  # column j -> W - j
        cj = w - cj
    if aug.vflip:  # row i -> H - i
        ci = h - ci
    return h, w, (ci, cj, ri, rj)


@pytest.mark.parametrize("aug", [
    Augmentation(hflip=True), Augmentation(vflip=True), Augmentation(transpose=True),
    Augmentation(transpose=True, hflip=True, vflip=True, channel_perms=((2, 0, 1), (0, 1, 2), (1, 2, 0))),
])
def test_augmentation_matches_rendering_the_transformed_scene(aug: Augmentation) -> None:
    rng = np.random.default_rng(7)
    h, w, k = 36, 44, 3
    params = (15.3, 25.1, 11.0, 16.5)  # off-centre, elongated: no symmetry hides a sign error
    normals, mask = ellipsoid_normals(h, w, *params)
    lights = random_lights(rng, k)
    albedo = rng.uniform(0.2, 1.0, (k, 3))
    images = lambertian(normals, mask, lights, albedo)

    def t(a):
        return torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32))

    aug_images, aug_mask, aug_normals = apply_augmentation(
        aug, t(images), t(mask[None]), t(normals.transpose(2, 0, 1)))

    # (a) the augmented normals are those of the geometrically transformed ellipsoid
    h2, w2, params2 = _transformed_params(aug, h, w, params)
    expected_n, expected_m = ellipsoid_normals(h2, w2, *params2)
    assert np.array_equal(aug_mask[0].numpy() > 0.5, expected_m)
    assert np.allclose(aug_normals.numpy().transpose(1, 2, 0), expected_n, atol=1e-5)

    # (b) the augmented images are a rendering of them under the reflected lights
    perms = aug.channel_perms or ((0, 1, 2),) * k
    albedo2 = np.stack([albedo[i, list(p)] for i, p in enumerate(perms)])
    lights2 = lights @ aug.vector_matrix().T
    rendered = lambertian(expected_n, expected_m, lights2, albedo2)
    assert np.allclose(aug_images.numpy(), rendered, atol=1e-5)


def test_the_physics_check_detects_a_wrong_transpose_sign() -> None:
    h, w = 36, 44
    normals, _ = ellipsoid_normals(h, w, 15.3, 25.1, 11.0, 16.5)
    expected, m = ellipsoid_normals(w, h, 25.1, 15.3, 16.5, 11.0)
    swapped = normals.transpose(1, 0, 2)
    naive = swapped[..., [1, 0, 2]]  # (n_y, n_x, n_z): the wrong sign convention
    right = swapped @ TRANSPOSE_MATRIX.T
    assert np.allclose(right[m], expected[m], atol=1e-6)
    assert not np.allclose(naive[m], expected[m], atol=1e-2)
    assert np.allclose(HFLIP_MATRIX @ VFLIP_MATRIX, np.diag([-1.0, -1.0, 1.0]))


def test_augmentation_sampling_is_seeded_and_uses_p() -> None:
    a = [sample_augmentation(np.random.default_rng(s), 4) for s in range(200)]
    b = [sample_augmentation(np.random.default_rng(s), 4) for s in range(200)]
    assert a == b
    frac = np.mean([x.hflip for x in a] + [x.vflip for x in a] + [x.transpose for x in a])
    assert 0.4 < frac < 0.6
    assert all(not (x.hflip or x.vflip or x.transpose) for x in
               (sample_augmentation(np.random.default_rng(s), 2, p=0.0) for s in range(20)))
    g1, g2 = torch.Generator().manual_seed(5), torch.Generator().manual_seed(5)
    assert sample_augmentation(g1, 3) == sample_augmentation(g2, 3)
    x = torch.rand(3, 3, 8, 8)
    out, _, none = augment(x, torch.ones(1, 8, 8), None, np.random.default_rng(0))
    assert none is None and out.shape == x.shape
    with pytest.raises(ValueError, match="rng"):
        sample_augmentation("seed", 3)


# -- checkpoints ----------------------------------------------------------------------------

def test_checkpoint_round_trip_and_mismatch(tmp_path) -> None:
    torch.manual_seed(1)
    model = create_model("glc-test", uniform_context=True).eval()
    path = save_checkpoint(tmp_path / "w.safetensors", model, {"note": "x"})
    loaded, meta = load_model(path)
    assert meta["model_name"] == "glc-test" and meta["extra"] == {"note": "x"}
    assert loaded.config == model.config
    x, m = torch.rand(1, 2, 3, 32, 32), torch.ones(1, 1, 32, 32)
    with torch.no_grad():
        assert torch.equal(loaded(x, m), model(x, m))

    side = sidecar_path(path)
    meta_json = json.loads(side.read_text())
    meta_json["config"]["context_dim"] = 24
    side.write_text(json.dumps(meta_json))
    with pytest.raises(ValueError, match=r"tensor \S+ has shape [\dx]+ in the file but [\dx]+ in the model"):
        load_model(path)
    with pytest.raises(FileNotFoundError, match="missing.safetensors"):
        load_model(tmp_path / "missing.safetensors")
    side.unlink()
    with pytest.raises(FileNotFoundError, match="w.json"):
        load_model(path)
