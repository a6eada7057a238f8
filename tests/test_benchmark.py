"""orchestrate.benchmark: probe table with the photometric gain, DiLiGenT under the uncalibrated protocol."""

from __future__ import annotations

import json

import numpy as np
import torch
from fixtures import write_diligent, write_synthetic_object

from unips.checkpoint import save_checkpoint
from unips.models import create_model


def test_benchmark_reports_probes_and_diligent_subsets(synthetic_object, tmp_path, caplog):
    from orchestrate.benchmark import main, probe_inputs
    from unips.data import load_object

    torch.manual_seed(0)
    weights = save_checkpoint(tmp_path / "w.safetensors", create_model("glc-test"))
    dil = tmp_path / "dil"
    write_diligent(dil / "sphPNG", k=8)
    out = tmp_path.with_name(tmp_path.name + "-bench")  # outside --data (tmp_path holds the objects)
    rc = main(["--data", str(synthetic_object.parent), "--checkpoint", str(weights), "--counts", "1,6,50",
               "--rerender-objects", "0", "--diligent", str(dil), "--diligent-subset", "4", "--diligent-subsets", "2",
               "--out", str(out)])
    assert rc == 0
    res = json.loads((out / "benchmark.json").read_text())
    probes = res["synthetic"]["probe_table"]["model"]
    assert set(probes["mean"]) == {"all", "one", "mask", "shuffled"}
    assert probes["gain"] == probes["mean"]["mask"] - probes["mean"]["all"]
    row = res["diligent"]["sph"]
    assert len(row["model_subsets"]["errors"]) == 2 and row["model_subsets"]["k"] == 4
    assert 0 <= row["model_mask_only"] <= 180
    tables = (out / "tables.md").read_text()
    assert "photometric gain" in tables and "model K=4" in tables and "mask only" in tables
    # A count beyond every object's 6 images would be a column of dashes: left out, and said.
    assert res["synthetic"]["counts"] == [1, 6] and "K=50" not in tables
    assert "--counts 50: more than the 6 image(s) of every object" in caplog.text

    # The mask-only probe input is the mask itself in every image, in the object's own frame.
    obj = load_object(synthetic_object)
    m = probe_inputs(obj, "mask")
    assert m.images.shape == obj.images.shape
    assert np.array_equal(m.images[..., 0][0] > 0, obj.mask) and set(np.unique(m.images)) <= {0.0, 1.0}


def test_benchmark_keeps_every_family_of_the_data(synthetic_object, tmp_path):
    """A family the generator's table does not know (another generator's, or none recorded) gets its own column
    after the table's families, in the per-family and probe tables: it is never dropped from them."""
    from orchestrate.benchmark import family_columns, main
    from unips.data import load_object
    from wildgen.light_families import LIGHT_FAMILIES

    ball = load_object(synthetic_object)
    write_synthetic_object(synthetic_object.parent / "ring.data", ball.images, ball.mask, ball.normals,
                           light_family="spot_ring")
    write_synthetic_object(synthetic_object.parent / "plain.data", ball.images, ball.mask, ball.normals,
                           light_family=None)
    torch.manual_seed(0)
    weights = save_checkpoint(tmp_path / "w.safetensors", create_model("glc-test"))
    out = tmp_path.with_name(tmp_path.name + "-bench")  # outside --data (tmp_path holds the objects)
    assert main(["--data", str(synthetic_object.parent), "--checkpoint", str(weights), "--counts", "1",
                 "--rerender-objects", "0", "--tta", "1", "--out", str(out)]) == 0
    syn = json.loads((out / "benchmark.json").read_text())["synthetic"]
    assert syn["families"] == ["directional", "spot_ring", "unknown"]
    for row in syn["family_table"].values():
        assert set(row) == {"directional", "spot_ring", "unknown", "all"}
    assert np.isfinite(syn["family_table"]["model"]["spot_ring"])
    assert set(syn["probe_table"]["model"]["families"]) == {"directional", "spot_ring", "unknown"}
    header = next(line for line in (out / "tables.md").read_text().splitlines() if line.startswith("| method "))
    assert [c.strip() for c in header.strip("|").split("|")] == ["method", "directional", "spot_ring", "unknown", "all"]
    assert family_columns(["zz", *reversed(LIGHT_FAMILIES), "aa"]) == [*LIGHT_FAMILIES, "aa", "zz"]


def test_learning_curve_card_trend_and_extrapolation(tmp_path) -> None:
    """bench/learning_curve.py --card on a lineage whose errors follow 20 - 1.5 log2(hours) exactly: the fit
    recovers a = 20, b = 1.5, and the hours at which the trend reaches the target (shifted by the family's
    test - validation difference) are 2^((a - need) / b); a stage marked 'not shipped' is left out."""
    import importlib.util
    import sys
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "learning_curve", Path(__file__).resolve().parents[1] / "bench" / "learning_curve.py"
    )
    lc = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = lc  # its options dataclass is read from its module's namespace
    spec.loader.exec_module(lc)
    err = lambda h: 20 - 1.5 * np.log2(h)  # noqa: E731
    lineage, cum = [], 0.0
    for i, h in enumerate([1.0, 1.0, 2.0, 4.0]):
        cum += h
        e = float(err(cum))
        lineage.append(
            {
                "stage": f"s{i}",
                "steps": 100,
                "hours": h,
                "best_step": 100,
                "curve": [{"step": 100, "all": e, "gain": 5.0}],
                "per_family_at_best": {"hdri": {"all": e, "gain": 5.0, "n": 20}},
            }
        )
    lineage.insert(
        2,
        {
            "stage": "side run (not shipped)",
            "steps": 100,
            "hours": 50.0,
            "curve": [{"step": 100, "all": 1.0, "gain": 0.0}],
            "per_family_at_best": {"hdri": {"all": 1.0, "gain": 0.0, "n": 20}},
        },
    )
    card = {
        "lineage": lineage,
        "test_set_deg": {"hdri": err(8.0) + 2.0},
        "validation_per_family_deg": {"hdri": err(8.0)},
    }
    assert [s["stage"] for s in lc.shipped_chain(card)] == ["s0", "s1", "s2", "s3"]
    a, b = lc.fit_log2([1, 2, 4, 8], [err(h) for h in (1, 2, 4, 8)])
    assert abs(a - 20) < 1e-9 and abs(b - 1.5) < 1e-9
    text = lc.card_table(card, target=12.0)
    row = next(line for line in text.splitlines() if line.startswith("| hdri "))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[1]) == 20.0 and float(cells[2]) == 1.5 and float(cells[5]) == 10.0  # need = 12 - 2
    assert int(cells[6]) == round(2 ** ((20 - 10) / 1.5))  # 101 hours
