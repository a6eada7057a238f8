"""The relay of short GPU runs (issue 41) on the CPU: --init (continue, never restart), the packed assets (training
split only, within the upload limit), the ship rule both ways and its one-line refusals.

The ship tests work on a copy of the registry's weights folder (`unips.models.registry.WEIGHTS_DIR` patched),
so the shipped weights in unips/weights/ are never touched: the copy "ships" the shipped weights perturbed, and
a candidate holding the real shipped weights is better than it, a perturbed one worse.
"""
from __future__ import annotations

import json
import shutil
import tarfile
from pathlib import Path

import pytest
from fixtures import render_dataset

from orchestrate import asset_pack, relay, ship
from orchestrate.asset_split import split_plan
from scenes.cli.errors import UsageError

REPO = Path(__file__).resolve().parents[1]
SHARED_ASSETS = REPO.parent / "shared" / "assets"


def _perturbed(src: Path, dst: Path, scale: float, seed: int = 0) -> Path:
    import torch

    from unips.models import load_model
    from unips.models.builder import save_checkpoint

    model, meta = load_model(src)
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(torch.randn(p.shape, generator=g) * scale * (p.std() if p.numel() > 1 else 1.0))
    return save_checkpoint(dst, model, extra=meta.get("extra"))


@pytest.fixture
def registry(tmp_path, monkeypatch):
    """A copy of unips/weights/ whose glc-tiny weights are the shipped ones perturbed (worse)."""
    from unips.models import registry as reg

    real = reg.WEIGHTS_DIR / "glc-tiny.safetensors"
    copy = tmp_path / "weights"
    shutil.copytree(reg.WEIGHTS_DIR, copy)
    _perturbed(real, copy / "glc-tiny.safetensors", 0.3)
    monkeypatch.setattr(reg, "WEIGHTS_DIR", copy)
    return {"real": real, "dir": copy}


def _candidate(folder: Path, weights: Path) -> Path:
    from unips.models.builder import sidecar_path

    (folder / "run").mkdir(parents=True)
    shutil.copyfile(weights, folder / "run" / "final.safetensors")
    shutil.copyfile(sidecar_path(weights), folder / "run" / "final.json")
    (folder / "model_card.json").write_text(json.dumps({
        "init_from": "shipped", "hardware": "NVIDIA H100 80GB HBM3, torch 2.11.0", "train_minutes": 7.5,
        "steps": 1234, "batch": 16, "data": "wildgen.make seed 5000, 300 objects, packed training split"}))
    (folder / "summary.json").write_text(json.dumps({"wall_s": 531.0}))
    return folder


@pytest.fixture(scope="module")
def val_set(tmp_path_factory):
    out = tmp_path_factory.mktemp("val") / "val"
    render_dataset(out, "--objects", "2", "--images", "3", "--res", "32", "--spp", "4", "--seed", "4000")
    return out


def test_ship_rule_both_ways(tmp_path, registry, val_set, capsys):
    from unips.models import registry as reg

    card_before = json.loads((registry["dir"] / "model_card.json").read_text())
    shipped_bytes = (registry["dir"] / "glc-tiny.safetensors").read_bytes()

    # Worse than what is shipped: not shipped, but recorded.
    worse = _candidate(tmp_path / "worse", _perturbed(registry["real"], tmp_path / "w" / "worse.safetensors", 1.0, 1))
    assert ship.main(["--candidate", str(worse), "--val", str(val_set), "--diligent", "none", "--threads", "1"]) == 0
    assert "not shipped" in capsys.readouterr().out
    assert (registry["dir"] / "glc-tiny.safetensors").read_bytes() == shipped_bytes
    card = json.loads((registry["dir"] / "model_card.json").read_text())
    assert len(card["lineage"]) == len(card_before["lineage"]) + 1
    rec = card["lineage"][-1]
    assert rec["shipped"] is False and rec["hardware"].startswith("NVIDIA H100") and rec["steps"] == 1234
    assert rec["minutes"] == 7.5 and "300 objects" in rec["data"]
    assert set(rec["fixed_validation"]["probes"]) == {"all", "one", "mask"}
    assert rec["fixed_validation"]["all"] > rec["shipped_model_fixed_validation"]
    assert card["validation_mean_deg"] == card_before["validation_mean_deg"]  # the shipped model's figures stay

    # Better (the real shipped weights against their perturbed copy): shipped and recorded.
    better = _candidate(tmp_path / "better", registry["real"])
    assert ship.main(["--candidate", str(better), "--val", str(val_set), "--diligent", "none", "--threads", "1"]) == 0
    assert "-> shipped" in capsys.readouterr().out
    assert (registry["dir"] / "glc-tiny.safetensors").read_bytes() == registry["real"].read_bytes()
    card = json.loads((registry["dir"] / "model_card.json").read_text())
    rec = card["lineage"][-1]
    assert rec["shipped"] is True and len(card["lineage"]) == len(card_before["lineage"]) + 2
    assert card["validation_mean_deg"] == rec["fixed_validation"]["all"] < rec["shipped_model_fixed_validation"]
    assert reg.pretrained_weights("glc-tiny").stat().st_size < ship.SHIP_LIMIT


def _one_line(capsys, *needles):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    return err


def test_ship_refusals_are_one_line(tmp_path, registry, val_set, capsys, monkeypatch):
    from unips.models import create_model
    from unips.models.builder import save_checkpoint

    before = {p.name: p.read_bytes() for p in registry["dir"].iterdir()}
    val = ["--val", str(val_set), "--diligent", "none"]
    (tmp_path / "empty").mkdir()
    assert ship.main(["--candidate", str(tmp_path / "empty"), *val]) == 2
    _one_line(capsys, "--candidate", "run/final.safetensors", "expected")
    other = tmp_path / "other"
    save_checkpoint(other / "run" / "final.safetensors", create_model("glc-test"))
    assert ship.main(["--candidate", str(other), *val]) == 2
    _one_line(capsys, "--candidate", "'glc-test'")
    changed = tmp_path / "changed"
    save_checkpoint(changed / "run" / "final.safetensors", create_model("glc-tiny", decoder_layers=1))
    assert ship.main(["--candidate", str(changed), *val]) == 2
    _one_line(capsys, "--candidate", "decoder_layers", "expected the shipped architecture")
    monkeypatch.setattr(ship, "SHIP_LIMIT", 1000)
    assert ship.main(["--candidate", str(_candidate(tmp_path / "big", registry["real"])), *val]) == 2
    _one_line(capsys, "--candidate", "over the 1000 bytes")
    assert ship.main(["--candidate", str(tmp_path / "big"), "--val", str(tmp_path / "nope")]) == 2
    _one_line(capsys, "--val", "nope")
    assert {p.name: p.read_bytes() for p in registry["dir"].iterdir()} == before


def test_init_continues_the_shipped_model_or_refuses(tmp_path, registry):
    from unips.models import DEFAULT_TRAIN_MODEL, create_model
    from unips.models.builder import save_checkpoint

    path, name = relay.resolve_init("shipped", None)
    assert name == "glc-tiny" and Path(path) == registry["dir"] / "glc-tiny.safetensors"
    assert relay.resolve_init(str(registry["real"]), "glc-tiny") == (str(registry["real"]), "glc-tiny")
    assert relay.resolve_init(None, None) == (None, DEFAULT_TRAIN_MODEL)
    with pytest.raises(UsageError, match=r"^--init: .* holds a 'glc-tiny' model, but --model is 'glc-small'"):
        relay.resolve_init(str(registry["real"]), "glc-small")
    changed = save_checkpoint(tmp_path / "c.safetensors", create_model("glc-tiny", decoder_layers=1))
    with pytest.raises(UsageError, match=r"^--init: .* differs from the shipped weights' in decoder_layers"):
        relay.resolve_init(str(changed), None)
    other = save_checkpoint(tmp_path / "t.safetensors", create_model("glc-test"))
    with pytest.raises(UsageError, match=r"^--init: .* 'glc-test' model, which has no shipped weights"):
        relay.resolve_init(str(other), None)
    with pytest.raises(UsageError, match=r"^--init: .*nope.* is not a file"):
        relay.resolve_init(str(tmp_path / "nope"), None)
    with pytest.raises(UsageError, match=r"^--init: 'shipped', but --model 'glc-test' has no single shipped"):
        relay.resolve_init("shipped", "glc-test")


def _fake_assets(root: Path) -> Path:
    import cv2
    import numpy as np

    for i in range(8):
        (root / "meshes" / f"m{i}").mkdir(parents=True)
        (root / "meshes" / f"m{i}" / f"m{i}.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n" * 50)
    (root / "hdri").mkdir()
    for i in range(10):
        cv2.imwrite(str(root / "hdri" / f"h{i}.hdr"), np.full((64, 128, 3), 0.5 + i, np.float32))
    for s in ("a", "b"):
        (root / "textures" / s).mkdir(parents=True)
        cv2.imwrite(str(root / "textures" / s / f"{s}_col.png"),
                    np.random.default_rng(0).integers(0, 255, (128, 128, 3), np.uint8))
    return root


def test_packed_assets_are_the_training_split_within_the_budget(tmp_path):
    assets = _fake_assets(tmp_path / "assets")
    m = relay.pack_assets(assets, tmp_path / "carry", budget=80_000)
    with tarfile.open(tmp_path / "carry" / relay.ASSET_ARCHIVE) as tar:
        names = tar.getnames()
    assert m["meshes"] == [f"m{i}" for i in range(6)] and len(m["hdri"]) == 8  # 2 of 8 meshes, 2 of 10 maps held out
    assert m["held_out_never_packed"] == ["hdri/h8.hdr", "hdri/h9.hdr", "meshes/m6", "meshes/m7"]
    assert not any(n.startswith(("assets/meshes/m6", "assets/meshes/m7", "assets/hdri/h8", "assets/hdri/h9"))
                   for n in names)
    assert m["texture_sets"] == ["textures/a"] and m["texture_sets_left_out"] == ["textures/b"]  # the budget
    assert (tmp_path / "carry" / relay.ASSET_ARCHIVE).stat().st_size == m["bytes"] <= 80_000
    with tarfile.open(tmp_path / "carry" / relay.ASSET_ARCHIVE) as tar:
        hdr = tar.extractfile("assets/hdri/h0.hdr").read()
    import cv2
    import numpy as np

    img = cv2.imdecode(np.frombuffer(hdr, np.uint8), cv2.IMREAD_UNCHANGED)
    assert img.shape == (asset_pack.HDR_WIDTH // 2, asset_pack.HDR_WIDTH, 3) and abs(float(img.mean()) - 0.5) < 0.01
    with pytest.raises(UsageError, match=r"^--assets: .* need \d+ bytes compressed, over the 100 bytes"):
        relay.pack_assets(assets, tmp_path / "c2", budget=100)


def test_a_pack_again_without_assets_leaves_no_earlier_assets_archive(tmp_path):
    """Sweep 37 (c37-pack-overwrite-assets-none-leaves-stale-assets): packing again with --overwrite and no assets
    left the earlier pack's assets.tar.xz beside a manifest that records none: the session unpacked and rendered
    with it, and the upload total left it out."""
    import zipfile

    wheels = tmp_path / "whl"
    wheels.mkdir()
    for name in ("mitsuba-3.9.1", "drjit-1.5.0"):
        with zipfile.ZipFile(wheels / f"{name}-cp312-cp312-manylinux_2_17_x86_64.whl", "w") as z:
            z.writestr(f"{name.split('-')[0]}/__init__.py", "")
    carry = tmp_path / "carry"
    relay.pack(carry, wheels, tree=1000, assets=_fake_assets(tmp_path / "assets"))
    assert (carry / relay.ASSET_ARCHIVE).is_file()
    total = relay.pack(carry, wheels, tree=1000, assets=None, overwrite=True)
    manifest = json.loads((carry / relay.MANIFEST).read_text())
    assert not (carry / relay.ASSET_ARCHIVE).exists() and "assets" not in manifest
    assert total == manifest["total_bytes"] == (carry / relay.SITE_ARCHIVE).stat().st_size + 1000


@pytest.mark.slow
@pytest.mark.skipif(not SHARED_ASSETS.is_dir(), reason="../shared/assets is not here")
def test_the_real_assets_fit_the_upload_next_to_mitsuba(tmp_path):
    tree = relay.tree_bytes()
    budget = relay.UPLOAD_LIMIT - relay.SITE_MEASURED - tree - relay.MARGIN
    m = relay.pack_assets(SHARED_ASSETS, tmp_path, budget)
    total = relay.SITE_MEASURED + tree + m["bytes"]
    print(f"assets.tar.xz {m['bytes'] / 2**20:.2f} MiB; with site {relay.SITE_MEASURED / 2**20:.1f} MiB and tree "
          f"{tree / 2**20:.2f} MiB: {total / 2**20:.2f} MiB of 64")
    assert total <= relay.UPLOAD_LIMIT
    held = {p.name for link, p in split_plan(SHARED_ASSETS, Path("/w")).items() if "heldout_assets" in link.parts}
    with tarfile.open(tmp_path / relay.ASSET_ARCHIVE) as tar:
        names = tar.getnames()
    packed = {n.split("/")[2] for n in names if n.startswith(("assets/meshes/", "assets/hdri/"))}
    assert held and not packed & held and not packed & {Path(h).stem + ".hdr" for h in held}
    assert len(m["meshes"]) == 14 and len(m["hdri"]) == 28  # every training mesh and map of the recipe's split


def test_an_asset_split_of_a_relative_folder_links_to_real_files(tmp_path, monkeypatch):
    """split_assets with a relative --assets (as users type it): every link resolves to the asset file. The links
    once kept the relative path, which a link reads from its own folder: every one of them was broken."""
    import os

    from orchestrate.asset_split import split_assets

    root = tmp_path / "assets"
    for i in range(4):
        (root / "meshes").mkdir(parents=True, exist_ok=True)
        (root / "meshes" / f"m{i}.obj").write_text("v 0 0 0\n")
    (root / "hdri").mkdir()
    for i in range(5):
        (root / "hdri" / f"h{i}.hdr").write_bytes(b"#?RADIANCE\n")
    monkeypatch.chdir(tmp_path)
    train, held = split_assets(Path("assets"), tmp_path / "work")
    links = [p for d in (train, held) for sub in ("meshes", "hdri") for p in (d / sub).iterdir()]
    assert len(links) == 9 and all(p.is_symlink() and os.path.isabs(os.readlink(p)) and p.exists() for p in links)
    assert sorted(p.name for p in (held / "meshes").iterdir()) == ["m3.obj"]


def test_wheels_that_unpack_beyond_what_the_gpu_machine_unpacks_are_refused_when_packed(tmp_path, monkeypatch):
    """Sweep 41: a wheel member inflating to 1.1 GiB of zeros packed into a 0.2 MiB site.tar.xz "within 64 MiB",
    exit 0, which the GPU machine's unpacking (`orchestrate.archives.UNPACKED_LIMIT`) then refuses: the sizes the
    kept members unpack to are summed when packing (the limit made small here)."""
    import zipfile

    from orchestrate import archives

    monkeypatch.setattr(archives, "UNPACKED_LIMIT", 5000)
    wheels = tmp_path / "whl"
    wheels.mkdir()
    for name in ("mitsuba-3.9.1", "drjit-1.5.0"):
        with zipfile.ZipFile(wheels / f"{name}-cp312-cp312-manylinux_2_17_x86_64.whl", "w",
                             zipfile.ZIP_DEFLATED) as z:
            z.writestr(f"{name.split('-')[0]}/__init__.py", "")
            if name.startswith("mitsuba"):
                z.writestr("mitsuba/zeros.bin", b"\0" * 6000)
    with pytest.raises(relay.UsageError, match=r"^--wheels: the wheels' kept members unpack to 6000 bytes, over the 0 "
                                               r"MiB .*'mitsuba/zeros.bin' in 'mitsuba-3.9.1"):
        relay.pack(tmp_path / "carry", wheels, tree=1000)
    assert not (tmp_path / "carry").exists()
