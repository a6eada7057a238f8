"""Making datasets at scale: workers, Ray, crashes, interrupts, resume, memory of a long-lived worker.

Every run here is the real CLI (`python -m wildgen.make` in a subprocess, or `main()` in this process)
on tiny objects (32x32, 4 spp, llvm). The reference is an uninterrupted run with 2 worker processes;
every other way of making the same dataset must give the same bytes in every object folder.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
from fixtures import (
    REPO,
    SCALE_FLAGS,
    SCALE_N,
    assert_same_dataset,
    dead_pid,
    interruptible,
    make_cli,
    make_command,
    use_variant,
)


def wait_for(predicate, timeout: float, what: str) -> None:
    t0 = time.monotonic()
    while not predicate():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.01)


def recorded(root: Path) -> int:
    """Objects the manifest records as done (it is replaced atomically, so reading it mid-run is safe)."""
    try:
        return sum(e["status"] == "done" for e in json.loads((root / "manifest.json").read_text())["objects"])
    except FileNotFoundError:
        return 0


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@contextmanager
def make_in_background(out: Path, *, output: bool = False):
    """`wildgen.make` with 2 workers started in its own process group (yielded); the whole group is killed on
    the way out if anything of it is still alive."""
    pipe = subprocess.PIPE if output else subprocess.DEVNULL
    proc = subprocess.Popen(make_command(out, "--workers", "2"), cwd=REPO, start_new_session=True,
                            preexec_fn=interruptible, stdout=pipe, stderr=pipe, text=output)
    try:
        yield proc
    finally:
        if group_alive(proc.pid):
            os.killpg(proc.pid, signal.SIGKILL)


def freeze_a_busy_worker(out: Path, timeout: float = 120) -> str:
    """SIGSTOP a worker while it is inside an object (its temporary folder, named with its pid, exists); its pid."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        for tmp in out.glob(".tmp-*.data.*"):
            pid = int(tmp.name.rsplit(".", 1)[1])
            try:
                os.kill(pid, signal.SIGSTOP)
            except ProcessLookupError:
                continue
            if tmp.exists():  # only the worker itself renames it: frozen inside this object
                return str(pid)
            os.kill(pid, signal.SIGCONT)
        time.sleep(0.005)
    raise AssertionError("no worker caught inside an object")


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """An uninterrupted run with 2 worker processes."""
    use_variant("llvm_ad_rgb")
    out = tmp_path_factory.mktemp("ref") / "data"
    r = make_cli(out, "--workers", "2")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1].startswith(f"{SCALE_N} done, 0 skipped, 0 failed"), r.stdout
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["run"]["workers"] == 2 and [e["status"] for e in manifest["objects"]] == ["done"] * SCALE_N
    return out


def test_one_worker_and_in_process_give_the_same_bytes(reference, tmp_path):
    r = make_cli(tmp_path / "w1", "--workers", "1", "--recycle-after", "2")  # 3 successive worker processes
    assert r.returncode == 0, r.stderr
    assert_same_dataset(reference, tmp_path / "w1")
    from wildgen.make import main

    assert main(["--out", str(tmp_path / "w0"), *SCALE_FLAGS, "--workers", "0"]) == 0
    assert_same_dataset(reference, tmp_path / "w0")


def test_sigkill_mid_run_then_same_command_resumes(reference, tmp_path):
    out = tmp_path / "killed"
    with make_in_background(out) as proc:
        wait_for(lambda: any(out.glob("*.data")) and recorded(out) > 0, 120, "the first object folder and its record")
        frozen = freeze_a_busy_worker(out)
        os.kill(proc.pid, signal.SIGKILL)  # the parent only: its workers must follow, even a stopped one
        proc.wait(10)
        wait_for(lambda: not group_alive(proc.pid), 20, "the workers to die with their parent")
    assert len(list(out.glob("*.data"))) < SCALE_N, "the kill came too late to test anything"
    assert any(p.name.endswith("." + frozen) for p in out.glob(".tmp-*")), (
        "the frozen worker's object should be left half-written"
    )

    r = make_cli(out, "--workers", "2")
    assert r.returncode == 0, r.stderr
    assert "already complete" in r.stdout
    assert_same_dataset(reference, out)


def test_sigint_stops_cleanly_and_resume_flag_continues(reference, tmp_path):
    from wildgen.dataset import verify_object

    out = tmp_path / "interrupted"
    with make_in_background(out, output=True) as proc:
        wait_for(lambda: recorded(out) > 0, 120, "the first recorded object")
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err
    assert not list(out.glob(".tmp-*")) and not (out / ".wildgen.lock").exists()
    done = [e for e in json.loads((out / "manifest.json").read_text())["objects"] if e["status"] == "done"]
    assert done and all(verify_object(out, e) is None for e in done)
    assert sorted(p.name for p in out.glob("*.data")) == sorted(e["folder"] for e in done)

    # --resume alone takes the configuration from the manifest.
    r = subprocess.run([sys.executable, "-m", "wildgen.make", "--out", str(out), "--resume", "--quiet"], cwd=REPO,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert_same_dataset(reference, out)


def test_killed_worker_is_retried(reference, tmp_path):
    """SIGKILL one worker in the middle of an object: the object is retried elsewhere, the run completes."""
    out = tmp_path / "crash"
    with make_in_background(out, output=True) as proc:
        os.kill(int(freeze_a_busy_worker(out)), signal.SIGKILL)
        stdout, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert "attempt 1 failed (worker process killed by SIGKILL" in err
    assert stdout.strip().splitlines()[-1].startswith(f"{SCALE_N} done, 0 skipped, 0 failed")
    assert_same_dataset(reference, out)


def test_corrupt_and_missing_objects_are_rendered_again(reference, tmp_path):
    out = tmp_path / "damaged"
    shutil.copytree(reference, out)
    png = out / "00001.data" / "L001.png"
    data = bytearray(png.read_bytes())
    data[-20] ^= 0xFF
    png.write_bytes(bytes(data))
    shutil.rmtree(out / "00002.data")
    (out / f".tmp-00003.data.{dead_pid()}" / "aux").mkdir(parents=True)  # an interrupted object's leftovers
    r = make_cli(out, "--workers", "1")
    assert r.returncode == 0, r.stderr
    assert "checksum mismatch in L001.png" in r.stderr and "its folder '00002.data' is missing" in r.stderr
    assert r.stdout.strip().splitlines()[-1].startswith(f"2 done, {SCALE_N - 2} skipped, 0 failed")
    assert_same_dataset(reference, out)


def test_other_config_in_the_folder_is_refused_unless_overwrite(tmp_path, capsys, variant_llvm_ad_rgb):
    from wildgen.make import main

    out = tmp_path / "d"
    small = [*SCALE_FLAGS, "--workers", "0", "--objects", "1"]
    assert main(["--out", str(out), *small]) == 0
    capsys.readouterr()
    assert main(["--out", str(out), *small, "--spp", "8"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --out:") and "spp: 4 -> 8" in err and "\n" not in err
    assert main(["--out", str(out), *small, "--spp", "8", "--overwrite"]) == 0
    assert json.loads((out / "manifest.json").read_text())["config"]["spp"] == 8
    # More objects extend the dataset: object i depends on (seed, i) only.
    assert main(["--out", str(out), *small[:-2], "--objects", "2", "--spp", "8"]) == 0
    assert "1 done, 1 skipped" in capsys.readouterr().out
    assert main(["--out", str(tmp_path / "none"), "--resume"]) == 2
    assert "--resume" in capsys.readouterr().err


def _write_assets(root: Path) -> None:
    import trimesh

    (root / "meshes").mkdir(parents=True)
    trimesh.creation.icosphere(subdivisions=3).export(root / "meshes" / "good.ply")
    (root / "meshes" / "bad.obj").write_bytes(b"v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")


def test_bad_asset_is_refused_up_front(tmp_path, capsys):
    """Assets are decoded once before any render: a bad mesh is named in one line and nothing is written
    (it would fail every object that draws it, the same way each time)."""
    from wildgen.make import main

    assets = tmp_path / "assets"
    _write_assets(assets)
    out = tmp_path / "d"
    rc = main(
        ["--out", str(out), *SCALE_FLAGS, "--assets", str(assets), "--shapes", "mesh", "--workers", "2",
         "--max-retries", "1"]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert err.startswith("error: --assets:") and "bad.obj" in err and "non-finite" in err and "\n" not in err
    assert not out.exists()


def test_ray_local_gives_the_same_bytes(reference, tmp_path):
    pytest.importorskip("ray")
    r = make_cli(tmp_path / "ray", "--ray")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "ray" / "manifest.json").read_text())["run"]["engine"] == "ray"
    assert_same_dataset(reference, tmp_path / "ray")


def test_ray_missing_is_one_line(tmp_path, capsys, monkeypatch):
    from wildgen.make import main

    monkeypatch.setitem(sys.modules, "ray", None)  # makes `import ray` fail as if it were not installed
    assert main(["--out", str(tmp_path / "o"), "--objects", "1", "--ray"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --ray:") and "pip install" in err and "\n" not in err


RSS_SCRIPT = r"""
import sys, tempfile
from pathlib import Path
from scenes.renderer.variant import choose_variant
choose_variant("llvm_ad_rgb")
from wildgen.assets import AssetLibrary
from wildgen.config import GenConfig
from wildgen.light_families import LIGHT_FAMILIES
from wildgen.writer import make_object

def rss_mb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024

cfg = GenConfig(lights=list(LIGHT_FAMILIES), objects=200, images=1, width=16,
                height=16, spp=1, gt_spp=1, texture_resolution=16, env_width=16).validate()
lib = AssetLibrary.scan(None)
out = Path(sys.argv[1])
done = 0
for i in range(200):
    done += make_object(cfg, i, out, lib)["status"] == "done"
    if i + 1 in (20, 200):
        print(i + 1, rss_mb(), flush=True)
print("done", done)
"""


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc (Linux)")
def test_worker_memory_stays_bounded_over_200_scenes(tmp_path, variant_llvm_ad_rgb):
    r = subprocess.run(
        [sys.executable, "-c", RSS_SCRIPT, str(tmp_path)], cwd=REPO, capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, r.stderr
    lines = dict(line.split() for line in r.stdout.strip().splitlines())
    rss20, rss200 = float(lines["20"]), float(lines["200"])
    assert int(lines["done"]) > 150  # most objects were really rendered
    assert rss200 <= 1.25 * rss20, (rss20, rss200)


def test_scene_build_order_does_not_depend_on_process_history(variant_llvm_ad_rgb):
    """Same description, different allocation histories: the scene's shapes keep the description's order."""
    import mitsuba as mi

    from scenes.description import ImageDesc, SceneDescription, ShapeDesc
    from scenes.lights import AreaLight
    from scenes.renderer.build import build_scene

    areas = [AreaLight(position=[2.0 * k - 2.0, 1.0, 3.0], target=[0.0, 0.0, 0.0], width=0.5, height=0.5,
                       radiance=5.0) for k in range(3)]
    desc = SceneDescription(shape=ShapeDesc(kind="sphere"), images=[ImageDesc(lights=areas)])
    keep, orders = [], set()
    for k in range(12):
        keep.append([mi.load_dict({"type": "point"}) for _ in range(k % 5)])  # vary what is allocated before
        if k % 3 == 0:
            keep.pop(0)
        built = build_scene(desc)
        orders.add(tuple(shape.id() for shape in built.scene.shapes()))
        del built
    assert orders == {("object", "light_area_0", "light_area_1", "light_area_2")}, orders
