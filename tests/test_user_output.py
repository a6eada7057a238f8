"""What a user sees: degenerate maps are flagged, tables explain their columns."""
from __future__ import annotations

import numpy as np
from fixtures import sphere


def _tilt(n: np.ndarray, deg: np.ndarray) -> np.ndarray:
    """Each normal turned by its own angle about the x axis."""
    a = np.radians(deg)[..., None]
    out = n.copy()
    out[..., 1] = n[..., 1] * np.cos(a[..., 0]) - n[..., 2] * np.sin(a[..., 0])
    out[..., 2] = n[..., 1] * np.sin(a[..., 0]) + n[..., 2] * np.cos(a[..., 0])
    return out


def test_near_constant_maps_are_flagged_and_real_surfaces_are_not(np_rng):
    from unips.predict import constant_map

    n, mask = sphere(32)
    assert not constant_map(n, mask)  # a sphere deviates by tens of degrees
    flat = np.zeros_like(n)
    flat[mask] = (0, 0, 1)
    assert constant_map(flat, mask)
    # mean deviation ~0.45 deg, with a few pixels off by 5 deg: a maximum rule (every pixel within
    # CONSTANT_DEG) misses it, the mean rule flags it
    deg = np.abs(np_rng.normal(0, 0.5, mask.shape))
    ys, xs = np.nonzero(mask)
    deg[ys[:3], xs[:3]] = 5.0
    near = _tilt(flat, deg)
    assert constant_map(near, mask)
    gentle = _tilt(flat, np.where(mask, np.linspace(-15, 15, mask.shape[0])[:, None] * np.ones(mask.shape), 0))
    assert not constant_map(gentle, mask)  # a gently curved surface (+-15 deg) is not constant


def test_demo_summary_explains_every_column(tmp_path):
    import json

    from orchestrate.demo import summary_table

    for m in ("model", "least-squares"):
        (tmp_path / "pred" / m).mkdir(parents=True)
        (tmp_path / "pred" / m / "metrics.json").write_text(json.dumps(
            {"objects": {"00000": {"mae_deg": 12.5, "light_family": "directional"}}, "mean_mae_deg": 12.5}))
        (tmp_path / "rerender" / m / "00000").mkdir(parents=True)
        (tmp_path / "rerender" / m / "00000" / "report.json").write_text(json.dumps(
            {"object": "00000", "rel_l1": 0.05, "coverage": 0.9, "gt_rel_l1": 0.01}))
    table = summary_table(tmp_path, ["model", "least-squares"])
    header = [c.strip() for c in table.splitlines()[0].strip("| ").split(" | ")]
    explained = "\n".join(line for line in table.splitlines() if line.startswith("- "))
    for column in header:
        generic = column.replace("least-squares", "<method>").replace("model", "<method>")
        assert f"**{generic}**" in explained, column
    assert "(90% covered)" in table and "90% covered" in explained


def test_every_command_says_what_it_does_and_where_it_wrote(synthetic_object, tmp_path, capsys):
    """One line when the work starts, even without a progress bar (`unips.train --no-progress` used to print
    nothing for minutes), and where the outputs went when it ends."""
    from unips.evaluate import main as evaluate
    from unips.predict import main as predict
    from unips.train import main as train

    capsys.readouterr()
    # the object folder as --data: the run folder may not lie inside what it reads
    assert train(["--data", str(synthetic_object), "--out", str(tmp_path / "run"), "--model", "glc-test", "--steps",
                  "1", "--no-progress"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("training glc-test for 1 steps") and str(tmp_path / "run") in out[0]
    assert out[-1].startswith(f"wrote {tmp_path / 'run' / 'final.safetensors'}")
    # the object folder, not its parent: --out inside --input is refused (a command never writes into what it reads)
    assert predict(["--method", "least-squares", "--input", str(synthetic_object), "--out",
                    str(tmp_path / "pred")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("predicting 1 object(s) with --method least-squares into") and out[-1].startswith("wrote")
    assert evaluate(["--pred", str(tmp_path / "pred"), "--gt", str(synthetic_object)]) == 0  # --pred apart from --gt
    assert capsys.readouterr().out.splitlines()[-1].startswith(f"wrote {tmp_path / 'pred' / 'metrics.json'}")


def test_a_python_without_the_packages_gets_one_line_not_a_traceback():
    """`python -m wildgen.make` with the system Python used to end in a ModuleNotFoundError traceback. Here a
    Python started without site-packages (-S) stands in for it."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    r = subprocess.run([sys.executable, "-S", "-m", "wildgen.make", "--help"], cwd=root, capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert "lacks numpy" in r.stderr and ".venv/bin/activate" in r.stderr


def test_markdown_tables_keep_cells_as_written():
    """The one table writer (scenes.report.tables): cells exactly as formatted by the caller (no number re-parsing:
    "12.0" stays "12.0", "007" stays "007"), unpadded, a row of the wrong length refused."""
    import pytest

    from scenes.report.tables import markdown_table

    text = markdown_table(["name", "deg"], [["ball", "12.0"], ["**mean**", "007"], ["x", 3]])
    lines = text.splitlines()
    assert lines == ["| name | deg |", "|---|---|", "| ball | 12.0 |", "| **mean** | 007 |", "| x | 3 |"]
    assert [[c.strip() for c in line.strip("|").split("|")] for line in lines[2:]] == [
        ["ball", "12.0"], ["**mean**", "007"], ["x", "3"]]
    with pytest.raises(ValueError, match="2 cells, the header 3"):
        markdown_table(["a", "b", "c"], [["1", "2"]])


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_progress_is_a_bar_on_a_terminal_and_plain_lines_in_a_log():
    """scenes.cli.progress.Progress: without a terminal, one line DESC: DONE/TOTAL UNIT at most every PLAIN_EVERY_S
    seconds and a last one at the end, never a carriage return; on a terminal, tqdm's bar; disabled, nothing."""
    import io

    from scenes.cli.progress import PLAIN_EVERY_S, Progress

    clock, log = _Clock(), io.StringIO()
    with Progress("train", "step", total=30, stream=log, clock=clock) as shown:
        for step in range(30):
            clock.t = step * PLAIN_EVERY_S / 4  # four updates per interval
            shown.update(step + 1, postfix={"loss": f"{1 / (step + 1):.3f}"})
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert lines[0] == "train: 5/30 step, loss=0.200, 10 s" and lines[-1].startswith("train: 30/30 step, loss=0.033")
    assert len(lines) == 8  # at 10, 20, ..., 70 s, and the end (72.5 s)

    quick = io.StringIO()  # shorter than one interval: nothing at all
    with Progress("x", "obj", total=3, stream=quick, clock=_Clock()) as shown:
        shown.advance(3)
    assert quick.getvalue() == ""

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    term = Terminal()
    with Progress("x", "obj", total=3, stream=term) as shown:
        shown.advance(3)
    assert "\r" in term.getvalue() and "0/3 [" in term.getvalue()  # tqdm drew (and cleared) its bar
    off = Terminal()
    with Progress("x", "obj", total=3, stream=off, enabled=False) as shown:
        shown.advance(3)
    assert off.getvalue() == ""


def test_a_cli_writing_to_a_log_file_leaves_no_bar_redraws(tmp_path, monkeypatch):
    """A real wildgen.make run with stderr redirected to a file: plain progress lines (every update here, the
    interval set to 0), no carriage return of a bar redraw."""
    import sys

    import scenes.cli.progress
    from wildgen.make import main

    monkeypatch.setattr(scenes.cli.progress, "PLAIN_EVERY_S", 0.0)
    with open(tmp_path / "stderr.log", "w") as err:
        monkeypatch.setattr(sys, "stderr", err)
        assert main(["--out", str(tmp_path / "o"), "--objects", "2", "--images", "2", "--res", "16", "--spp", "1",
                     "--gt-spp", "1", "--workers", "0", "--seed", "5"]) == 0
    text = (tmp_path / "stderr.log").read_text()
    assert "\r" not in text
    lines = [line for line in text.splitlines() if line.startswith("wildgen: ")]
    assert lines[0].startswith("wildgen: 1/2 obj, done=") and lines[-1].startswith("wildgen: 2/2 obj, done=")


def test_a_training_run_logged_to_a_file_writes_a_few_plain_lines(tmp_path):
    """Issue 40: a real `unips.train` subprocess with its progress on (the default) and stderr a file: no bar redraw
    (no carriage return), and only plain lines: the run's log records and at most one progress line per
    PLAIN_EVERY_S seconds of the run plus the last (the issue saw about 125 KB of redraws in such a file)."""
    import os
    import re
    import subprocess
    import sys
    import time
    from pathlib import Path

    from scenes.cli.progress import PLAIN_EVERY_S
    from wildgen.make import main as make

    repo = Path(__file__).resolve().parents[1]
    assert make(["--out", str(tmp_path / "ds"), "--objects", "2", "--images", "3", "--res", "16", "--spp", "1",
                 "--gt-spp", "1", "--workers", "0", "--quiet", "--lights", "directional"]) == 0
    log = tmp_path / "stderr.log"
    t0 = time.monotonic()
    with open(log, "w") as err:
        r = subprocess.run([sys.executable, "-m", "unips.train", "--data", str(tmp_path / "ds"), "--out",
                            str(tmp_path / "run"), "--model", "glc-test", "--steps", "40", "--res", "16", "--threads",
                            "1", "--log-every", "1"], stdout=subprocess.DEVNULL, stderr=err, cwd=repo,
                           env={**os.environ, "PYTHONPATH": str(repo)}, timeout=600)
    seconds = time.monotonic() - t0
    text = log.read_text()
    assert r.returncode == 0, text[-2000:]
    assert "\r" not in text and "\x1b" not in text
    lines = text.splitlines()
    progress = [line for line in lines if line.startswith("train: ")]
    assert all(re.fullmatch(r"train: \d+/40 step, loss=[\d.]+, k=\d+, \d+ s", line) for line in progress), progress
    assert len(progress) <= seconds / PLAIN_EVERY_S + 1
    others = [line for line in lines if not line.startswith("train: ")]
    assert all(re.match(r"(INFO|WARNING) [\w.]+: ", line) for line in others), others
    assert len(text) < 200 * (len(progress) + len(others)) < 4000


def test_a_stage_says_it_is_alive_and_when_it_ended_once_it_lasts():
    """A stage with no steps of its own (a forward pass) still prints a line at least every `every_s`; one shorter
    than that prints nothing (a bad input refused at once stays one line)."""
    import io
    import time

    from scenes.cli.progress import stage

    out = io.StringIO()
    with stage("capture", "the model", 12.0, every_s=0.05, stream=out):
        time.sleep(0.32)
    lines = out.getvalue().splitlines()
    assert lines[-1].startswith("capture: the model done in ")
    alive = lines[:-1]
    assert len(alive) >= 3 and all(line.startswith("capture: the model (about 12 s), ") and "so far" in line
                                   for line in alive)
    quiet = io.StringIO()
    with stage("capture", "fast", stream=quiet):
        pass
    assert quiet.getvalue() == ""


def test_a_heartbeat_covers_the_whole_run_between_and_across_stages():
    """Inside `heartbeat`, short stages and the work between them share one clock: no silence longer than every_s
    (plus scheduling), the running stage named, `working` between stages; a run shorter than every_s prints nothing."""
    import io
    import threading
    import time

    from scenes.cli.progress import heartbeat, stage

    class Stamped(io.StringIO):  # each line with the time it was written
        def __init__(self) -> None:
            super().__init__()
            self.times: list[float] = []
            self.lock = threading.Lock()

        def write(self, text: str) -> int:
            with self.lock:
                self.times += [time.monotonic()] * text.count("\n")
                return super().write(text)

    out, every = Stamped(), 0.1
    t0 = time.monotonic()
    with heartbeat("capture", every_s=every, stream=out):
        for i in range(4):  # stages each shorter than every_s, with work between them: silent one by one
            with stage("capture", f"step {i}", stream=out):
                time.sleep(0.07)
            time.sleep(0.07)
        with stage("capture", "the long one", 3.0, stream=out):
            time.sleep(0.35)
    t1 = time.monotonic()
    lines = out.getvalue().splitlines()
    gaps = [b - a for a, b in zip([t0, *out.times], [*out.times, t1])]
    assert max(gaps) < every + 0.08, (gaps, lines)
    assert any(line.startswith("capture: the long one (about 3 s), ") for line in lines), lines
    assert lines[-1].startswith("capture: the long one done in ")
    assert any(line.startswith("capture: step ") or line.startswith("capture: working") for line in lines), lines
    quiet = io.StringIO()
    with heartbeat("capture", every_s=5.0, stream=quiet):
        with stage("capture", "fast", stream=quiet):
            pass
    assert quiet.getvalue() == ""
