"""The GPU session (orchestrate.gpu_session) rehearsed on the CPU in miniature.

The whole path runs for real: 3 objects at 24 px rendered with llvm_ad_rgb, 2 of them rendered again with
scalar_rgb as the check's stand-in pair (on the GPU machine the pair is cuda_ad_rgb / llvm_ad_rgb), shards,
4 training steps of glc-test, the files that come back. llvm_ad_rgb and scalar_rgb draw different sub-pixel
samples, so their ground truth is NOT identical bit for bit (the mask's outline pixels and the normals, each a
footprint average, differ); the check must say so, and say that the masks differ only on the outline and that
the images agree within the noise of their spp.
"""
from __future__ import annotations

import json
import sys
import zipfile

import pytest

from orchestrate import curve, gpu_session


def test_whole_session_in_miniature(tmp_path, variant_llvm_ad_rgb):
    import torch

    from unips.models import create_model

    out, work = tmp_path / "out", tmp_path / "work"
    code = gpu_session.main(["--out", str(out), "--work", str(work), "--minutes", "3", "--reserve-s", "5",
                             "--objects", "3", "--images", "3", "--res", "24", "--spp", "8",
                             "--variant", "llvm_ad_rgb", "--check-variant", "scalar_rgb", "--check-objects", "2",
                             "--model", "glc-test", "--steps", "4", "--batch", "2", "--log-every", "1",
                             *([] if torch.cuda.is_available() else ["--cpu-rehearsal"])])
    assert code == 0
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert files == ["learning_curve.png", "model_card.json", "run/final.json", "run/final.safetensors",
                     "run/last.pt", "run/log.jsonl", "summary.json", "variant_check.json"]
    assert len(files) <= 8  # what the device tool brings back

    model = create_model("glc-test", checkpoint_path=out / "run" / "final.safetensors")
    assert sum(p.numel() for p in model.parameters()) == json.loads((out / "model_card.json").read_text())["parameters"]
    with torch.no_grad():
        assert all(torch.isfinite(p).all() for p in model.parameters())

    records = curve.curve_records(out / "run" / "log.jsonl")
    assert [r["step"] for r in records] == [1, 2, 3, 4]
    logged = [json.loads(line) for line in (out / "run" / "log.jsonl").read_text().splitlines()]
    (line,) = curve.curve_figure(records, "t").axes[0].get_lines()  # the curve plots the logged losses
    assert list(line.get_xdata()) == [1, 2, 3, 4]
    assert list(line.get_ydata()) == [r["loss"] for r in logged if "loss" in r and "val" not in r]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["variant"] == "llvm_ad_rgb" and summary["device"] == "cpu" and summary["steps"] == 4
    assert summary["curve_points"] == 4

    check = json.loads((out / "variant_check.json").read_text())
    assert check["variant"] == "llvm_ad_rgb" and check["check_variant"] == "scalar_rgb"
    assert [o["name"] for o in check["objects"]] == ["00000.data", "00001.data"]
    assert check["ground_truth_identical"] is False  # different samplers: see the module doc
    assert check["masks_differ_only_on_outline"] is True
    assert check["images_within_noise"] is True
    assert check["image_tolerance_rel_rms"] == pytest.approx(4 * (2 / 8) ** 0.5, abs=1e-4)
    # render speed of both variants from their manifests: the check's on one CPU core
    speed = check["speed"]
    assert sorted(speed) == ["llvm_ad_rgb", "scalar_rgb, one CPU core"] and summary["render_speed"] == speed
    assert speed["llvm_ad_rgb"]["objects"] == 3 and speed["scalar_rgb, one CPU core"]["objects"] == 2
    for v in speed.values():
        assert v["seconds_per_object"] > 0
        assert v["objects_per_hour_one_worker"] == pytest.approx(3600 / v["seconds_per_object"], rel=1e-2)
    assert 0 < speed["llvm_ad_rgb"]["objects_per_hour_run"] < speed["llvm_ad_rgb"]["objects_per_hour_one_worker"] * 2
    manifest = json.loads((work / "check" / "manifest.json").read_text())
    assert manifest["run"]["workers"] == 1 and manifest["run"]["threads_per_worker"] == 1

    # A folder compared with itself is identical.
    same = gpu_session.compare_datasets(work / "data", work / "data", ["00000.data"], spp=8, noise_cv=4)
    assert same["ground_truth_identical"] and same["images_within_noise"]

    # unips.train's --time-limit (the hook the session stops with): a limit that not one step fits is one line,
    # and nothing is written (tests/test_budgets.py: a limit that fits some steps holds).
    from unips.train import main as train_main

    run = tmp_path / "limited"
    assert train_main(["--data", str(work / "shards"), "--out", str(run), "--model", "glc-test", "--steps", "1000",
                       "--batch", "2", "--res", "24", "--max-images", "3", "--time-limit", "0.00001",
                       "--log-every", "1", "--no-progress"]) == 2
    assert not any(p.is_file() for p in run.rglob("*"))


def _wheel(path, members):
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)


def test_learning_curve_plots_loss_against_step(tmp_path):
    import cv2

    log = tmp_path / "log.jsonl"
    rows = [{"step": 20, "loss": 0.5}, {"step": 10, "loss": 0.9}, {"step": 20, "val": 1, "loss": 0.7},
            {"step": 30, "loss": 0.25}, {"step": 25, "lr": 1e-3}]
    log.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    records = curve.curve_records(log)  # training records only, in step order
    fig = curve.curve_figure(records, "glc-test, 3 objects, cpu")
    (ax,) = fig.axes
    (line,) = ax.get_lines()
    assert list(line.get_xdata()) == [10, 20, 30] and list(line.get_ydata()) == [0.9, 0.5, 0.25]
    assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_title(loc="left")) == ("step", "training loss",
                                                                            "glc-test, 3 objects, cpu")
    curve.plot_curve(records, tmp_path / "curve.png", "t")
    picture = cv2.imread(str(tmp_path / "curve.png"))
    assert picture is not None and picture.shape == (400, 640, 3)


def test_pack_keeps_the_needed_variants_and_checks_the_limit(tmp_path, capsys):
    import tarfile

    wheels = tmp_path / "whl"
    wheels.mkdir()
    _wheel(
        wheels / "mitsuba-3.9.1-cp312-cp312-manylinux_2_17_x86_64.whl",
        {
            "mitsuba/__init__.py": "",
            "mitsuba/libmitsuba.so": "x" * 100,
            "mitsuba/cuda_ad_rgb.cpython-312-x86_64-linux-gnu.so": "c",
            "mitsuba/cuda_ad_spectral.cpython-312-x86_64-linux-gnu.so": "s",
            "mitsuba/scalar_rgb.cpython-312-x86_64-linux-gnu.so": "r",
            "mitsuba/include/mitsuba.h": "h",
            "mitsuba/plugins/path.so": "p",
            "mitsuba/__init__.pyi": "",
        },
    )
    _wheel(wheels / "drjit-1.5.0-cp312-cp312-manylinux_2_17_x86_64.whl",
           {"drjit/__init__.py": "", "drjit/include/x.h": "h", "drjit/libdrjit-core.so": "d"})
    total = gpu_session.pack(tmp_path / "carry", wheels, tree=1000)
    with tarfile.open(tmp_path / "carry" / "site.tar.xz") as tar:
        names = sorted(tar.getnames())
    assert names == ["drjit/__init__.py", "drjit/libdrjit-core.so", "mitsuba/__init__.py",
                     "mitsuba/cuda_ad_rgb.cpython-312-x86_64-linux-gnu.so", "mitsuba/libmitsuba.so",
                     "mitsuba/plugins/path.so", "mitsuba/scalar_rgb.cpython-312-x86_64-linux-gnu.so"]
    assert total == (tmp_path / "carry" / "site.tar.xz").stat().st_size + 1000
    with pytest.raises(gpu_session.UsageError, match=r"--pack: what would travel is \d+ bytes = .* over the 100 bytes"):
        gpu_session.pack(tmp_path / "carry", wheels, limit=100, tree=1000, overwrite=True)
    assert sorted(p.name for p in (tmp_path / "carry").iterdir()) == []  # a pack over the limit is not left to carry
    assert gpu_session.main(["--pack", str(tmp_path / "c2"), "--wheels", str(tmp_path / "none")]) == 2
    assert "error: --wheels:" in capsys.readouterr().err


def test_missing_mitsuba_is_one_line_naming_what_to_carry(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "mitsuba", None)  # import mitsuba raises ImportError, as on the GPU machine
    assert gpu_session.main(["--out", str(tmp_path / "o"), "--work", str(tmp_path / "w"), "--cpu-rehearsal"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: Mitsuba is not importable here") and "--pack" in err[0]
    assert not (tmp_path / "o").exists()


def test_asset_pack_carries_no_file_reached_through_a_link_out_of_the_asset_folder(tmp_path):
    """The pack leaves the machine: a mesh (or texture) of --assets that is a link to a file elsewhere is refused by
    name, and no archive is written; the same folder without the link packs."""
    import cv2
    import numpy as np
    import trimesh

    from orchestrate import asset_pack, relay

    assets = tmp_path / "A"
    (assets / "meshes").mkdir(parents=True)
    (assets / "hdri").mkdir()
    rng = np.random.default_rng(0)
    for i in range(4):
        trimesh.creation.icosphere(subdivisions=1).export(str(assets / "meshes" / f"m{i}.ply"))
    for i in range(5):
        cv2.imwrite(str(assets / "hdri" / f"h{i}.hdr"), (rng.random((8, 16, 3)) + 0.2).astype(np.float32))
    meshes = asset_pack.asset_choice(assets)[0]
    linked = meshes[0][0]
    (tmp_path / "secret.txt").write_text("not an asset\n")
    saved = linked.read_bytes()
    linked.unlink()
    linked.symlink_to(tmp_path / "secret.txt")
    with pytest.raises(relay.UsageError, match=rf"--assets: '{linked}' leads outside '{assets}' through a link"):
        relay.pack_assets(assets, tmp_path / "pack", 10**7)
    assert not (tmp_path / "pack" / relay.ASSET_ARCHIVE).exists()
    linked.unlink()
    linked.write_bytes(saved)
    assert relay.pack_assets(assets, tmp_path / "pack", 10**7)["bytes"] > 0


@pytest.mark.parametrize("manifest", ["[1, 2]", '{"assets": [1]}', '{"assets": {"meshes": 3}}', "{"])
def test_a_carry_manifest_that_is_not_a_packs_says_nothing_of_the_assets(tmp_path, manifest):
    """The model card's note on the assets reads the carry's manifest.json at the end of a session: one that is not a
    pack's (a list, assets not a mapping, counts not lists, not JSON) gives the plain asset path, not a traceback
    after the training."""
    from types import SimpleNamespace

    (tmp_path / "manifest.json").write_text(manifest)
    assert gpu_session._assets_note(SimpleNamespace(carry=str(tmp_path)), "/a") == "/a"
    (tmp_path / "manifest.json").write_text(json.dumps(
        {"assets": {"meshes": ["m"], "hdri": ["h", "i"], "texture_sets": [], "rule": "r"}}))
    assert gpu_session._assets_note(SimpleNamespace(carry=str(tmp_path)), "/a") == \
        "packed training split, 1 meshes, 2 HDR maps, 0 texture sets (r)"


def test_a_carry_manifest_that_is_a_pipe_is_not_waited_on(tmp_path):
    """Sweep 36 c36-carry-17: a manifest.json in --carry that is a FIFO hung the session at its very end (the card
    read it); it says nothing of the assets instead, at once."""
    import os
    import threading
    from types import SimpleNamespace

    os.mkfifo(tmp_path / "manifest.json")
    result = []
    reader = threading.Thread(target=lambda: result.append(
        gpu_session._assets_note(SimpleNamespace(carry=str(tmp_path)), "/a")), daemon=True)
    reader.start()
    reader.join(timeout=10)
    if reader.is_alive():  # release the blocked reader before failing
        with open(tmp_path / "manifest.json", "w"):
            pass
    assert result == ["/a"]
