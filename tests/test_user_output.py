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


def test_near_constant_maps_are_flagged_and_real_surfaces_are_not():
    from unips.predict import CONSTANT_DEG, constant_map

    n, mask = sphere(32)
    assert not constant_map(n, mask)  # a sphere deviates by tens of degrees
    flat = np.zeros_like(n)
    flat[mask] = (0, 0, 1)
    assert constant_map(flat, mask)
    rng = np.random.default_rng(0)
    # mean deviation ~0.45 deg, with a few pixels off by 5 deg: a maximum rule (every pixel within
    # CONSTANT_DEG) misses it, the mean rule flags it
    deg = np.abs(rng.normal(0, 0.5, mask.shape))
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
    header = table.splitlines()[0].strip("| ").split(" | ")
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

    data = synthetic_object.parent
    capsys.readouterr()
    assert train(["--data", str(data), "--out", str(tmp_path / "run"), "--model", "glc-test", "--steps", "1",
                  "--no-progress"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("training glc-test for 1 steps") and str(tmp_path / "run") in out[0]
    assert out[-1].startswith(f"wrote {tmp_path / 'run' / 'final.safetensors'}")
    assert predict(["--method", "least-squares", "--input", str(data), "--out", str(tmp_path / "pred")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("predicting 1 object(s) with --method least-squares into") and out[-1].startswith("wrote")
    assert evaluate(["--pred", str(tmp_path / "pred"), "--gt", str(data)]) == 0
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
