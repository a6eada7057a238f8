"""Importing the toolkit in a Python without its packages (`scenes.dependencies`) raises a catchable
ModuleNotFoundError with a one-line message and never exits the process; only an uncaught one ends a run, as the
one line `error: ...` and exit status 2 (tests/test_user_output.py runs `python -m wildgen.make` that way).
A Python started without site-packages (-S) stands in for the system Python."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CATCH = """
try:
    import wildgen.make
except ImportError as exc:
    print(type(exc).__name__, isinstance(exc, ModuleNotFoundError), exc.name)
    print(exc)
print("after the import")
"""


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-S", *args], cwd=ROOT, capture_output=True, text=True, timeout=60)


def test_importing_without_the_packages_raises_a_catchable_import_error_and_does_not_exit():
    r = _run("-c", CATCH)
    assert r.returncode == 0, r.stderr
    kind, message, after = r.stdout.strip().splitlines()
    assert kind == "MissingDependencyError True numpy"
    assert "lacks numpy" in message and "make setup" in message and ".venv/bin/activate" in message
    assert after == "after the import" and r.stderr == ""


def test_an_uncaught_missing_dependency_is_one_line_and_exit_status_2():
    r = _run("-c", "import unips")
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith("error: ") and len(r.stderr.strip().splitlines()) == 1 and "lacks numpy" in r.stderr


def test_other_uncaught_errors_keep_their_traceback():
    r = _run("-c", "try:\n    import scenes\nexcept ImportError:\n    pass\nraise KeyError('x')")
    assert r.returncode == 1 and "Traceback" in r.stderr and "KeyError: 'x'" in r.stderr


def test_the_cli_error_handlers_report_it_as_an_input_error(capsys):
    from scenes.cli.errors import EXIT_USAGE, INPUT_ERRORS, MissingDependencyError, report_error

    assert issubclass(MissingDependencyError, ModuleNotFoundError) and MissingDependencyError in INPUT_ERRORS
    assert report_error(MissingDependencyError("this Python lacks numpy: run `make setup`")) == EXIT_USAGE
    assert capsys.readouterr().err == "error: this Python lacks numpy: run `make setup`\n"


def test_a_command_run_from_a_deleted_folder_says_so_in_one_line(tmp_path):
    """A shell left in a folder that was deleted (sweep 35 a35-env-04): torch's MKL would die with "Cannot load
    libtorch_cpu.so", which sends the user to reinstall; importing `scenes` names the real cause first."""
    gone = tmp_path / "gone"
    gone.mkdir()
    child = subprocess.Popen([sys.executable, "-m", "unips.predict", "--method", "least-squares", "--input",
                              str(tmp_path / "nowhere"), "--out", str(tmp_path / "p")], cwd=gone,
                             env={**os.environ, "PYTHONPATH": str(ROOT)},
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             preexec_fn=lambda: gone.rmdir())
    out, err = child.communicate(timeout=120)
    assert child.returncode == 2, err
    assert err.startswith("error: the current folder no longer exists") and len(err.strip().splitlines()) == 1, err
    assert "MKL" not in err and not (tmp_path / "p").exists()
