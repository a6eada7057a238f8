"""Writes go through a temporary name: a failure (disk full, a kill) never leaves a truncated file under the
real name, and a rerun of unips.predict recovers from a run that was stopped half-way."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from scenes.files import atomic_write
from scenes.images import read_normals, write_exr, write_normal_map

ROOT = Path(__file__).resolve().parents[1]


def test_a_failed_write_leaves_neither_the_file_nor_its_temporary(tmp_path):
    target = tmp_path / "normal.png"

    def half(tmp: Path) -> None:
        tmp.write_bytes(b"\x89PNG half")  # what a full disk leaves
        raise OSError("No space left on device")

    with pytest.raises(OSError, match="No space"):
        atomic_write(target, half)
    assert list(tmp_path.iterdir()) == []
    target.write_bytes(b"old")
    with pytest.raises(OSError):
        atomic_write(target, half)
    assert target.read_bytes() == b"old"  # the previous file is intact
    assert [p.name for p in tmp_path.iterdir()] == ["normal.png"]


def test_a_name_of_the_longest_length_is_written_through_a_temporary_that_fits(tmp_path):
    from scenes.files import temporary_writer

    target = tmp_path / ("\u00e9" * 100 + "L" * 50 + ".png")  # 254 bytes: the file system's limit is 255
    seen = []
    atomic_write(target, lambda tmp: (seen.append(tmp.name), tmp.write_bytes(b"x")))
    assert target.read_bytes() == b"x" and len(seen[0].encode()) <= 255 and seen[0].endswith(".png")
    assert temporary_writer(seen[0]) is not None  # a killed writer's leftover is still found by its pid


def test_image_and_exr_writers_are_atomic(tmp_path, monkeypatch):
    n = np.zeros((8, 8, 3), np.float32)
    n[..., 2] = 1
    write_normal_map(tmp_path / "n.png", n)
    before = (tmp_path / "n.png").read_bytes()
    real = Path.write_bytes

    def full_disk(self, data):
        real(self, data[:10])  # part of the file, then the disk is full
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_bytes", full_disk)
    with pytest.raises(OSError, match="could not write .*n.png.*No space"):
        write_normal_map(tmp_path / "n.png", -n)
    assert (tmp_path / "n.png").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["n.png"]
    monkeypatch.undo()
    write_exr(tmp_path / "n.exr", n)
    assert np.array_equal(read_normals(tmp_path / "n.exr"), n)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["n.exr", "n.png"]


def test_predict_killed_mid_write_recovers_on_rerun(tmp_path, synthetic_object):
    out = tmp_path / "pred"
    # A child process that is SIGKILLed while writing normal.exr (after predict.json and normal.png).
    script = textwrap.dedent(f"""
        import os, signal, sys
        import unips.predict as up
        def killed(path, data):
            os.kill(os.getpid(), signal.SIGKILL)
        up.write_normal_exr = lambda path, n: killed(path, n)
        sys.exit(up.main(["--method", "least-squares", "--input", {str(synthetic_object)!r}, "--out", {str(out)!r}]))
    """)
    r = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == -signal.SIGKILL
    folder = out / "ball"
    assert (folder / "predict.json").is_file()  # the folder is marked as this command's
    assert not (folder / "normal.exr").exists()
    assert not [p for p in folder.iterdir() if p.stat().st_size == 0]  # nothing truncated under a real name
    from unips.predict import main

    # predict.json marks the folder as this command's: the rerun replaces what the killed run left, with
    # --overwrite as every command does (without it, the refusal names --overwrite)
    assert main(["--method", "least-squares", "--input", str(synthetic_object), "--out", str(out)]) == 2
    assert main(["--method", "least-squares", "--input", str(synthetic_object), "--out", str(out), "--overwrite"]) == 0
    assert read_normals(folder / "normal.exr").shape == (32, 32, 3)
    assert json.loads((folder / "predict.json").read_text())["method"] == "least-squares"


@pytest.fixture
def tiny_disk(tmp_path):
    """A 4 KiB tmpfs (root only; skipped where mounting is not allowed): room for predict.json, not for a map."""
    mnt = tmp_path / "tiny"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4k", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here: {r.stderr.strip()}")
    yield mnt
    subprocess.run(["umount", str(mnt)], check=False)


def test_full_disk_leaves_no_truncated_file_and_the_summary_says_none_was_written(
    tiny_disk, tmp_path, synthetic_object
):
    import shutil

    from unips.predict import main

    data = tmp_path / "data"
    data.mkdir()
    shutil.copytree(synthetic_object, data / "a.data")
    shutil.copytree(synthetic_object, data / "b.data")
    r = subprocess.run([sys.executable, "-m", "unips.predict", "--method", "least-squares", "--input", str(data),
                        "--out", str(tiny_disk / "pred")], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stderr
    assert "none was written" in r.stderr and "No space left" in r.stderr and "normal.png" in r.stderr
    files = [p for p in (tiny_disk / "pred").rglob("*") if p.is_file()]
    assert not files, files  # no map, no temporary, no predict.json of an unwritten map (taken back: sweep 42)
    assert main(["--method", "least-squares", "--input", str(synthetic_object), "--out", str(tiny_disk / "p2")]) == 2
