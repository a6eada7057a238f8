"""Ctrl-C through `scenes.cli.supervise`: the command's work runs in a child of its own session, killed whole on a
stop signal; one line, exit 130 (SIGTERM: 143), the child's temporaries removed, finished files kept, no orphan.
The child here is a real Python process that installs a C-level SIGINT handler of its own that swallows the signal,
as Mitsuba's render binding does while it renders: the stop must not depend on the child's handlers."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from fixtures import interruptible

REPO = Path(__file__).resolve().parents[1]

WORK = """
import ctypes, os, signal, subprocess, sys, time
from pathlib import Path
from scenes.cli.supervise import die_with_parent, run_supervised
from scenes.files import atomic_write_text

def main():
    out = Path(sys.argv[sys.argv.index("--out") + 1])
    atomic_write_text(out / "finished.txt", "whole")
    (out / "pid").write_text(str(os.getpid()))
    # a step the work runs, as a pipeline's (gpu_session's wildgen.make): it goes when the work is stopped
    me = os.getpid()
    step = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"],
                            preexec_fn=lambda: die_with_parent(me))  # as orchestrate.steps.run_step starts steps
    (out / "step_pid").write_text(str(step.pid))
    # a native handler that swallows SIGINT, as a render in progress would have installed
    handler = ctypes.CFUNCTYPE(None, ctypes.c_int)(lambda _s: None)
    ctypes.CDLL(None).signal(signal.SIGINT, handler)
    # a file half written, under the name atomic_write gives it, when the stop comes
    (out / f".normal.tmp{os.getpid()}.png").write_bytes(b"half")
    # an object folder half written (wildgen.sensor's), and a user's folder named alike but of no pid of the work
    (out / f".tmp-00000.data.{os.getpid()}").mkdir()
    (out / f".tmp-00000.data.{os.getpid()}" / "image0.png").write_bytes(b"half")
    (out / ".tmp-notes.1").mkdir()
    import tempfile  # a scratch folder of the work's (ship's scoring has one): the stop must not leave it
    Path(tempfile.mkdtemp(prefix="scratch-"), "half.npy").write_bytes(b"half")
    if "--held" in sys.argv:  # a folder the work holds under another flag, with the step's half-written file too
        from scenes.cli.outputs import output_lock

        held = sys.argv[sys.argv.index("--held") + 1]
        with output_lock(held, "--held"):
            Path(held, f".a.tmp{os.getpid()}.png").write_bytes(b"half")
            Path(held, f".b.tmp{step.pid}.png").write_bytes(b"half")
            (out / "started").write_text("")
            time.sleep(120)
    (out / "started").write_text("")
    time.sleep(120)
    return 0

if __name__ == "__main__":
    sys.exit(run_supervised("slowwork", main, "interrupted: one line"))
"""


@pytest.fixture
def slow_command(tmp_path):
    mod = tmp_path / "mods"
    mod.mkdir()
    (mod / "slowwork.py").write_text(textwrap.dedent(WORK))
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "tmp").mkdir()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(mod), str(REPO)]), "TMPDIR": str(tmp_path / "tmp")}
    return [sys.executable, "-m", "slowwork", "--out", str(out)], out, env


def _start(cmd, out, env):
    proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=interruptible)
    t0 = time.monotonic()
    while not (out / "started").exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < 60
        time.sleep(0.05)
    return proc, int((out / "pid").read_text())


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie is dead work: only its parent (here: gone) could still reap it
    stat = Path(f"/proc/{pid}/stat")
    return not (stat.exists() and stat.read_text().split(")")[-1].split()[0] == "Z")


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_stop_kills_the_work_whole_in_one_line(slow_command, sig, code):
    cmd, out, env = slow_command
    proc, child = _start(cmd, out, env)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == code, err
    assert err.strip().splitlines() == ["interrupted: one line"], err
    assert (out / "finished.txt").read_text() == "whole"  # what was finished stays
    assert not list(out.glob(".*.tmp*")), sorted(p.name for p in out.iterdir())  # the half-written file goes
    assert sorted(p.name for p in out.glob(".tmp-*")) == [".tmp-notes.1"]  # and the half-written object folder
    assert not list(Path(env["TMPDIR"]).iterdir())  # and the work's own TMPDIR, its scratch folders in it
    step = int((out / "step_pid").read_text())
    t0 = time.monotonic()
    while (_alive(child) or _alive(step)) and time.monotonic() - t0 < 10:
        time.sleep(0.05)
    assert not _alive(child) and not _alive(step)  # the work's own steps too: its whole session is killed


def test_the_terminal_ctrl_c_reaches_only_the_supervisor_and_a_kill_of_it_takes_the_work_along(slow_command):
    cmd, out, env = slow_command
    proc, child = _start(cmd, out, env)
    assert os.getpgid(child) != os.getpgid(proc.pid)  # its own session: the terminal's Ctrl-C goes to the parent
    proc.kill()  # the supervisor itself killed: the child must not go on as an orphan
    proc.communicate(timeout=30)
    t0 = time.monotonic()
    while _alive(child) and time.monotonic() - t0 < 10:
        time.sleep(0.05)
    assert not _alive(child)


OUTER = """
import os, subprocess, sys, time
from pathlib import Path
from scenes.cli.supervise import run_supervised

def main():
    out = Path(sys.argv[sys.argv.index("--out") + 1])
    # a step started plainly (as the benches start theirs), itself a supervised command
    step = subprocess.Popen([sys.executable, "-m", "slowwork", "--out", str(out / "step")])
    (out / "step_supervisor").write_text(str(step.pid))
    (out / "pid").write_text(str(os.getpid()))
    time.sleep(120)
    return 0

if __name__ == "__main__":
    sys.exit(run_supervised("outer", main, "interrupted"))
"""


def test_a_step_of_a_work_killed_outright_is_no_orphan(slow_command):
    """A supervised command started as a step of another one's work (a bench's wildgen.make) dies with that work
    when the work is killed outright (kill -9 of its supervisor, the out-of-memory killer): it never goes on writing
    as an orphan (sweep 18: a wildgen.make rendered on into --work minutes after its bench was killed)."""
    cmd, out, env = slow_command
    mods = Path(env["PYTHONPATH"].split(os.pathsep)[0])
    (mods / "outer.py").write_text(textwrap.dedent(OUTER))
    (out / "step").mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "outer", "--out", str(out)], cwd=REPO, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=interruptible)
    t0 = time.monotonic()
    while not (out / "step" / "started").exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < 60
        time.sleep(0.05)
    pids = [int((out / name).read_text()) for name in ("pid", "step_supervisor", "step/pid", "step/step_pid")]
    proc.kill()
    proc.communicate(timeout=30)
    t0 = time.monotonic()
    while any(map(_alive, pids)) and time.monotonic() - t0 < 10:
        time.sleep(0.05)
    assert not any(map(_alive, pids)), [p for p in pids if _alive(p)]


def test_the_child_exit_status_passes_through(tmp_path):
    mod = tmp_path / "m"
    mod.mkdir()
    (mod / "fails.py").write_text("import sys\nfrom scenes.cli.supervise import run_supervised\n"
                                  "if __name__ == '__main__':\n"
                                  "    sys.exit(run_supervised('fails', lambda: print('bad --x: 3') or 2, 'stop'))\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(mod), str(REPO)])}
    r = subprocess.run([sys.executable, "-m", "fails"], cwd=REPO, env=env, capture_output=True, text=True,
                       timeout=60)
    assert (r.returncode, r.stdout.strip(), r.stderr) == (2, "bad --x: 3", "")


def test_every_command_but_wildgen_make_runs_supervised():
    """Ctrl-C in any command is one line and exit 130, never a traceback (sweep 6 found ten commands that printed
    Python's): each CLI's `python -m` entry runs its main under `run_supervised`; wildgen.make handles Ctrl-C
    itself (its work runs in worker processes)."""
    import importlib.util

    from orchestrate.docs import CLIS

    for module in CLIS:
        source = Path(importlib.util.find_spec(module).origin).read_text()
        entry = source[source.rindex('if __name__ == "__main__":'):]
        assert (f'run_supervised("{module}", main' in entry) != (module == "wildgen.make"), module


def test_ctrl_c_in_training_keeps_whole_checkpoints_and_resumes(tmp_path):
    """unips.train (newly supervised) stopped by the terminal's Ctrl-C once it has written a checkpoint: exit 130,
    the one line, no temporary left in --out, and --resume goes on from the checkpoint."""
    import numpy as np
    from fixtures import shading, sphere, write_synthetic_object

    n, mask = sphere(32)
    th, ph = np.radians(np.linspace(10, 40, 6)), np.linspace(0, 2 * np.pi, 6, endpoint=False)
    L = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)
    write_synthetic_object(tmp_path / "data" / "ball.data", 0.8 * shading(n, L)[..., None] * np.ones(3), mask, n,
                           directions=L)
    out = tmp_path / "run"
    argv = [sys.executable, "-m", "unips.train", "--data", str(tmp_path / "data"), "--out", str(out), "--model",
            "glc-test", "--res", "16", "--steps", "100000", "--no-progress", "--threads", "1", "--batch", "1",
            "--ckpt-every", "1"]
    proc = subprocess.Popen(argv, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(REPO)}, preexec_fn=interruptible,
                            start_new_session=True)
    deadline = time.monotonic() + 120
    while not (out / "last.pt").exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(1.0)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "Traceback" not in err, err
    assert err.strip().splitlines()[-1].startswith("interrupted: --out keeps the last whole checkpoint"), err
    assert not [p.name for p in out.iterdir() if ".tmp" in p.name]
    done = subprocess.run([*argv[:argv.index("--steps") + 1], "3", *argv[argv.index("--steps") + 2:], "--resume"],
                          cwd=REPO, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(REPO)},
                          timeout=300)
    assert done.returncode == 0, done.stderr


def test_a_stop_removes_the_temporaries_in_every_folder_the_work_held(slow_command, tmp_path):
    """The work holds a second folder under another flag (`output_lock`), where it and its step were writing: the
    supervisor learns of it from the child and removes both half-written files after the stop (the writers are
    dead; no other run may write in a held folder)."""
    cmd, out, env = slow_command
    held = tmp_path / "held"
    proc, _ = _start([*cmd, "--held", str(held)], out, env)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert held.is_dir() and not list(held.glob(".*.tmp*")), sorted(p.name for p in held.iterdir())


def test_a_pipeline_step_runs_in_the_users_folder(tmp_path, monkeypatch):
    """A step (orchestrate.steps.run_step) runs where the user typed the command, with the toolkit on PYTHONPATH: a
    relative path means what it meant to the user (sweep 7: error_calibration and gpu_session rendered a relative
    --work into the toolkit's own folder)."""
    from orchestrate.steps import run_step

    monkeypatch.chdir(tmp_path)
    assert run_step([sys.executable, "-m", "wildgen.make", "--out", "rel_o", "--objects", "1", "--images", "2",
                     "--res", "16", "--spp", "1", "--gt-spp", "1", "--workers", "0", "--quiet"])
    assert (tmp_path / "rel_o" / "manifest.json").is_file() and not (REPO / "rel_o").exists()
