"""Test-time augmentation: the eight views of the square, their inverses on normals, and the network's
averaged prediction (`unips.inference.model_normals`) through the library and the predict CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from fixtures import ellipsoid_normals, lambertian, random_lights, write_predict_ours

from unips.augment import DIHEDRAL, apply_augmentation, invert_normals
from unips.checkpoint import save_checkpoint
from unips.inference import DEFAULT_TTA, check_tta, model_normals
from unips.models import create_model


def _matrices(views) -> list[np.ndarray]:
    return [a.vector_matrix() for a in views]


def _closed(mats: list[np.ndarray]) -> bool:
    return all(any(np.allclose(a @ b, c) for c in mats) for a in mats for b in mats)


def test_the_views_are_the_eight_symmetries_of_the_square_with_closed_prefixes() -> None:
    mats = _matrices(DIHEDRAL)
    assert len(mats) == 8 and np.allclose(mats[0], np.eye(3))
    assert all(not np.allclose(a, b) for i, a in enumerate(mats) for b in mats[i + 1:])  # all distinct
    assert all(np.allclose(m @ m.T, np.eye(3)) for m in mats)
    # Averaging over a group (not just a set) is what makes the average equivariant.
    assert _closed(mats[:2]) and _closed(mats[:4]) and _closed(mats)


@pytest.mark.parametrize("aug", DIHEDRAL, ids=lambda a: f"t{int(a.transpose)}h{int(a.hflip)}v{int(a.vflip)}")
def test_invert_normals_undoes_the_augmentation(aug) -> None:
    """On a non-square field of an analytic ellipsoid, so a swapped axis or a wrong sign cannot pass."""
    n, mask = ellipsoid_normals(9, 13, 4.5, 6.0, 3.5, 5.0)
    normals = torch.from_numpy(n.transpose(2, 0, 1).astype(np.float32))  # (3, H, W)
    images = torch.rand(2, 3, 9, 13)
    m = torch.from_numpy(mask.astype(np.float32))[None]
    _, _, aug_n = apply_augmentation(aug, images, m, normals)
    back = invert_normals(aug, aug_n)
    assert back.shape == normals.shape and torch.allclose(back, normals, atol=1e-6)


@pytest.fixture(scope="module")
def lit_ellipsoid():
    rng = np.random.default_rng(4)
    n, mask = ellipsoid_normals(32, 32, 15.0, 17.0, 11.0, 8.0)
    imgs = lambertian(n, mask, random_lights(rng, 5), np.tile([0.8, 0.6, 0.5], (5, 1)))
    return torch.from_numpy(imgs.astype(np.float32)), torch.from_numpy(mask.astype(np.float32))[None]


def test_the_eight_view_average_is_equivariant_and_one_view_is_the_network(lit_ellipsoid) -> None:
    """Flipping / transposing the input flips / transposes the 8-view prediction exactly (the average over
    the group is equivariant); the network alone is not, so the check can fail."""
    torch.manual_seed(0)
    model = create_model("glc-test").eval()
    images, mask = lit_ellipsoid
    with torch.no_grad():
        plain = model(images[None], mask[None])[0]
    assert torch.equal(model_normals(model, images, mask, tta=1), plain)
    base8 = model_normals(model, images, mask, tta=8)
    base1 = plain
    worst1 = 0.0
    for aug in DIHEDRAL[1:]:
        x, m, expect8 = apply_augmentation(aug, images, mask, base8)
        got8 = model_normals(model, x, m, tta=8)
        inside = m[0] > 0.5
        assert torch.allclose(got8[:, inside], expect8[:, inside], atol=1e-4)
        _, _, expect1 = apply_augmentation(aug, images, mask, base1)
        got1 = model_normals(model, x, m, tta=1)
        worst1 = max(worst1, float((got1 - expect1)[:, inside].abs().max()))
    assert worst1 > 1e-3


@pytest.mark.parametrize("bad", [0, 3, 16, -1, True, 2.0, "4"])
def test_bad_view_counts_are_refused(bad) -> None:
    with pytest.raises(ValueError, match="tta"):
        check_tta(bad)


def test_predict_cli_records_the_views(tmp_path, capsys) -> None:
    from scenes.images import read_normals
    from unips import predict as pr

    torch.manual_seed(0)
    ckpt = save_checkpoint(tmp_path / "w.safetensors", create_model("glc-test"))
    _, mask = write_predict_ours(tmp_path / "data" / "alpha.data")
    maps = {}
    for tta in (None, "1", "4"):
        out = tmp_path / f"p{tta}"
        argv = ["--method", "model", "--checkpoint", str(ckpt), "--input", str(tmp_path / "data" / "alpha.data"),
                "--out", str(out)] + (["--tta", tta] if tta else [])
        assert pr.main(argv) == 0
        info = json.loads((out / "alpha" / "predict.json").read_text())
        assert info["tta"] == (int(tta) if tta else DEFAULT_TTA)
        n = read_normals(out / "alpha" / "normal.exr")
        assert np.allclose(np.linalg.norm(n[mask], axis=1), 1.0, atol=1e-4) and np.all(n[~mask] == 0)
        maps[tta] = n
    assert DEFAULT_TTA == 2 and not np.allclose(maps[None], maps["1"], atol=1e-4)
    assert not np.allclose(maps["1"], maps["4"], atol=1e-4)
    capsys.readouterr()
    assert pr.main(["--method", "model", "--checkpoint", str(ckpt), "--input", str(tmp_path / "data"),
                    "--out", str(tmp_path / "bad"), "--tta", "3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--tta" in err[0] and "3" in err[0]
    assert not (tmp_path / "bad").exists()
