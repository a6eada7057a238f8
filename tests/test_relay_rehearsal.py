"""The GPU part's one command (docs/model.md), run as written with --cpu-rehearsal and tiny sizes appended, in a
fresh environment that holds only what the GPU machine has (`orchestrate.relay.GPU_IMAGE`, linked from this
environment into a new venv without pip) and what the pack carries (a site.tar.xz of `relay.PACKED`'s packages,
assets.tar.xz of a tiny asset folder, the repository's tracked and untracked files): a package the pack lacks
fails here, not on the GPU machine.
"""
from __future__ import annotations

import importlib.metadata as md
import re
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

from orchestrate import relay

REPO = Path(__file__).resolve().parents[1]
REHEARSAL = ["--cpu-rehearsal", "--work", "{work}", "--minutes", "4", "--reserve-s", "5", "--objects", "2",
             "--images", "3", "--res", "64", "--spp", "4", "--variant", "llvm_ad_rgb", "--check-variant", "scalar_rgb",
             "--check-objects", "1", "--steps", "2", "--batch", "2", "--log-every", "1"]


def gpu_command() -> str:
    """The one command docs/model.md gives for the GPU machine (continuation lines joined)."""
    text = (REPO / "docs" / "model.md").read_text()
    block = text.split("On the GPU machine, one command (carry `.carry`", 1)[1].split("```bash\n", 1)[1].split("```")[0]
    return " ".join(line.rstrip("\\ ").strip() for line in block.strip().splitlines())


SAME_MODULE = {"opencv-python-headless": "opencv-contrib-python-headless"}
"""The image's package -> the one this environment provides the same module with: the GPU image's OpenCV is the
plain build, this project installs the contrib build (the same cv2 and more; only orchestrate.capture_full uses a
contrib module, and the GPU session never reaches it)."""


def _tops(name: str) -> list[Path]:
    name = re.split(r"[=<>]", name)[0]
    try:
        dist = md.distribution(name)
    except md.PackageNotFoundError:
        if name not in SAME_MODULE:
            raise
        dist = md.distribution(SAME_MODULE[name])
    tops = {f.parts[0] for f in dist.files or [] if f.parts[0] not in ("..", "__pycache__", "share", "bin")}
    return [Path(dist.locate_file(t)) for t in sorted(tops)]


BOOT = ("tyro==1.0.17", "docstring-parser", "typeguard")
"""What gpu_session needs before it can parse its arguments: packed as real files in the rehearsal's site.tar.xz
(the unpacking rule refuses links out of the archive, so the rest of the pack, hundreds of MiB, is linked into the
rehearsal's image instead)."""


def _image(dest: Path) -> None:
    dest.mkdir(parents=True)
    for name in relay.GPU_IMAGE + tuple(n for n in relay.PACKED if n not in BOOT):
        try:
            tops = _tops(name)
        except md.PackageNotFoundError:
            continue
        for top in tops:
            if top.exists() and not (dest / top.name).exists():
                (dest / top.name).symlink_to(top)


def _site(archive: Path) -> None:
    with tarfile.open(archive, "w:xz", preset=0) as tar:
        for name in BOOT:
            for top in _tops(name):
                if top.exists():
                    tar.add(top, arcname=top.name, filter=lambda ti: None if "__pycache__" in ti.name else ti)


def _assets(root: Path) -> Path:
    import cv2
    import numpy as np
    import trimesh

    for i, mesh in enumerate((trimesh.creation.icosphere(2), trimesh.creation.box(), trimesh.creation.capsule())):
        (root / "meshes").mkdir(parents=True, exist_ok=True)
        mesh.export(root / "meshes" / f"m{i}.obj")
    (root / "hdri").mkdir()
    for i in range(3):
        cv2.imwrite(str(root / "hdri" / f"h{i}.hdr"),
                    np.random.default_rng(i).uniform(0.2, 3.0, (64, 128, 3)).astype(np.float32))
    return root


@pytest.mark.slow
def test_the_gpu_command_runs_in_a_fresh_environment_of_the_pack(tmp_path, variant_llvm_ad_rgb):
    command = gpu_command()
    assert command.startswith("PYTHONUNBUFFERED=1 python3 -m orchestrate.gpu_session --carry .carry --init shipped")
    repo = tmp_path / "repo"
    names = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=REPO,
                           capture_output=True, check=True).stdout.decode().split("\0")
    for n in filter(None, names):
        if (REPO / n).is_file():
            (repo / n).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(REPO / n, repo / n)
    carry = repo / ".carry"
    carry.mkdir()
    _site(carry / relay.SITE_ARCHIVE)
    relay.write_manifest(carry, {"assets": relay.pack_assets(_assets(tmp_path / "assets"), carry, budget=2**20)})
    base = Path(getattr(sys, "_base_executable", sys.executable))
    subprocess.run([str(base), "-m", "venv", "--without-pip", str(tmp_path / "venv")], check=True)
    _image(tmp_path / "image")
    (site_packages,) = (tmp_path / "venv" / "lib").glob("python3*/site-packages")
    (site_packages / "gpu_image.pth").write_text(str(tmp_path / "image") + "\n")
    out = tmp_path / "out"
    env = {"PATH": f"{tmp_path / 'venv' / 'bin'}:/usr/bin:/bin", "HOME": str(tmp_path), "OUT": str(out)}
    rehearsal = " ".join(a.format(work=tmp_path / "work") for a in REHEARSAL)
    proc = subprocess.run(["bash", "-c", f"{command} {rehearsal}"], cwd=repo, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert "run/final.safetensors" in files and "run/last.pt" in files and len(files) <= 8
    import json

    card = json.loads((out / "model_card.json").read_text())
    assert card["model"] == "glc-tiny" and card["init_from"] == "shipped"
    assert "packed training split, 2 meshes, 2 HDR maps" in card["data"]
    assert not (REPO / "unips" / "weights").samefile(repo / "unips" / "weights")
