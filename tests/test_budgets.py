"""Time budgets hold: `unips.train --time-limit`, `orchestrate.gpu_session --minutes` (each stage checks what is
left; a render still running when only the reserve is left is stopped), counted from the command's start and
measured here from outside, as a user's clock would: no command ends more than 10 % past its budget. A GPU-only
command on a machine without a GPU stops at once unless --cpu-rehearsal asks for a CPU run; a budget not above
the reserve is refused before anything runs."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def timed(argv: list[str], timeout: float = 300) -> tuple[subprocess.CompletedProcess, float]:
    """Run `python -m ARGV`; its result and its wall time from launch to exit."""
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", *argv], cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO)},
                       capture_output=True, text=True, timeout=timeout)
    return r, time.monotonic() - t0


def one_error_line(r: subprocess.CompletedProcess) -> str:
    lines = [x for x in r.stderr.splitlines() if x.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    return lines[0]


def test_no_gpu_stops_at_once_without_the_rehearsal_flag(tmp_path):
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has a GPU")
    r, wall = timed(["orchestrate.gpu_session", "--out", str(tmp_path / "o"), "--work", str(tmp_path / "w")])
    assert r.returncode == 2
    line = one_error_line(r)
    assert line.startswith("error: --device: 'auto', but torch sees no GPU here") and "--cpu-rehearsal" in line
    assert r.stdout == "" and not (tmp_path / "o").exists() and not (tmp_path / "w").exists()
    assert wall < 30  # at once: the interpreter and torch's import, no render


def test_a_budget_not_above_the_reserve_is_refused_before_anything_runs(tmp_path):
    r, _ = timed(["orchestrate.gpu_session", "--out", str(tmp_path / "o"), "--work", str(tmp_path / "w"),
                  "--minutes", "0.5", "--cpu-rehearsal"])
    assert r.returncode == 2
    assert one_error_line(r) == ("error: --minutes: 0.5 min (30 s) is not above --reserve-s 45 s (expected a budget "
                                 "above the seconds kept for the last files)")
    assert not (tmp_path / "o").exists() and not (tmp_path / "w").exists()


@pytest.mark.slow
def test_train_time_limit_holds(train_dataset, tmp_path):
    limit = 0.25  # minutes
    out = tmp_path / "run"
    r, wall = timed(["unips.train", "--data", str(train_dataset["train"]), "--val", str(train_dataset["val"]),
                     "--val-every", "5",
                     "--model", "glc-test", "--out", str(out), "--batch", "2", "--res", "32", "--pixels", "100",
                     "--max-images", "4", "--threads", "1", "--no-progress", "--steps", "100000",
                     "--time-limit", str(limit)])
    assert r.returncode == 0, r.stderr[-2000:]
    print(f"unips.train --time-limit {limit * 60:g} s: ended after {wall:.1f} s")
    assert wall <= 1.1 * limit * 60
    assert "(--time-limit reached)" in r.stdout
    meta = json.loads((out / "final.json").read_text())
    assert 0 < meta["extra"]["step"] < 100000


SESSION = ["--images", "3", "--res", "24", "--spp", "2", "--variant", "llvm_ad_rgb", "--check-variant", "none",
           "--model", "glc-test", "--batch", "2", "--log-every", "1", "--cpu-rehearsal"]


@pytest.mark.slow
def test_gpu_session_stops_a_render_that_does_not_fit(tmp_path):
    minutes, work = 0.5, tmp_path / "w"
    r, wall = timed(["orchestrate.gpu_session", "--out", str(tmp_path / "o"), "--work", str(work), "--minutes",
                     str(minutes), "--reserve-s", "8", "--objects", "2000", "--steps", "4", *SESSION])
    print(f"gpu_session --minutes {minutes * 60:g} s, a render too long: ended after {wall:.1f} s")
    assert r.returncode == 2
    line = one_error_line(r)
    assert line.startswith("error: --minutes: 0.5 min, less --reserve-s 8 s, ran out while step wildgen.make") \
        and "lower --objects" in line
    assert wall <= 1.1 * minutes * 60
    data = work / "data"
    assert not list(data.glob(".tmp-*"))  # nothing half-written: finished objects only, the manifest says which
    done = [e for e in json.loads((data / "manifest.json").read_text())["objects"] if e["status"] == "done"]
    assert sorted(e["folder"] for e in done) == sorted(p.name for p in data.glob("*.data"))


@pytest.mark.slow
def test_gpu_session_training_ends_within_the_budget(tmp_path):
    minutes, out = 0.75, tmp_path / "o"
    r, wall = timed(["orchestrate.gpu_session", "--out", str(out), "--work", str(tmp_path / "w"), "--minutes",
                     str(minutes), "--reserve-s", "10", "--objects", "2", "--steps", "100000", *SESSION])
    print(f"gpu_session --minutes {minutes * 60:g} s, training too long: ended after {wall:.1f} s")
    assert r.returncode == 0, r.stderr[-2000:]
    assert wall <= 1.1 * minutes * 60
    summary = json.loads((out / "summary.json").read_text())
    assert 0 < summary["steps"] < 100000 and summary["wall_s"] <= minutes * 60


def _two_meshes(folder: Path) -> Path:
    import trimesh

    (folder / "meshes").mkdir(parents=True)
    for name in ("a.ply", "b.ply"):
        trimesh.creation.icosphere(subdivisions=1).export(folder / "meshes" / name)
    return folder


@pytest.mark.slow
def test_train_recipe_minutes_hold(tmp_path):
    """orchestrate.train_recipe --minutes: its 100-object validation set cannot be rendered in 40 s on a CPU; the
    step is stopped and the recipe ends with one line naming --minutes, within the budget + 10 %."""
    minutes, work = 40 / 60, tmp_path / "w"
    r, wall = timed(["orchestrate.train_recipe", "--work", str(work), "--assets", str(_two_meshes(tmp_path / "a")),
                     "--model", "glc-test", "--train-objects", "1", "--steps", "100000", "--minutes", f"{minutes:.6f}"])
    print(f"train_recipe --minutes {minutes * 60:g} s: ended after {wall:.1f} s")
    assert r.returncode == 2, r.stderr[-2000:]
    assert one_error_line(r).startswith("error: --minutes: 0.666667 min ran out"), r.stderr[-2000:]
    assert wall <= 1.1 * minutes * 60
    assert not (work / "runs" / "main" / "final.safetensors").exists()


@pytest.mark.slow
def test_recipe_resumes_a_run_its_clock_stopped(train_dataset, tmp_path):
    """A run whose final.safetensors was written before --steps (a time limit stopped it) is not finished: the
    recipe resumes it instead of keeping it, and keeps it once it reached --steps."""
    from orchestrate.train_recipe import COMMAND, train_argv, train_run, trained_steps
    from unips.train import main as train

    work = tmp_path / "w"
    run = work / "runs" / "main"
    (work / "runs").mkdir(parents=True)
    (work / "train5000").symlink_to(train_dataset["train"])
    (work / "val128").symlink_to(train_dataset["val"])
    args = COMMAND.parse(["--work", str(work), "--model", "glc-test", "--steps", "2", "--threads", "1"])
    first = COMMAND.parse(["--work", str(work), "--model", "glc-test", "--steps", "1", "--threads", "1"])
    assert train(train_argv(first, work, "main", [])) == 0  # the recipe's own run, its final written at step 1
    assert trained_steps(run) == 1  # final.safetensors written at step 1, as a run stopped by its clock
    train_run(sys.executable, work, "main", args, [])
    assert trained_steps(run) == 2
    before = (run / "final.safetensors").read_bytes()
    train_run(sys.executable, work, "main", args, [])
    assert (run / "final.safetensors").read_bytes() == before
