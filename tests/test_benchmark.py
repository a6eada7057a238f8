"""orchestrate.benchmark: probe table with the photometric gain, DiLiGenT under the uncalibrated protocol."""

from __future__ import annotations

import json

import numpy as np
import torch

from unips.checkpoint import save_checkpoint
from unips.models import create_model

from test_unips_data import write_diligent


def test_benchmark_reports_probes_and_diligent_subsets(synthetic_object, tmp_path):
    from orchestrate.benchmark import main, probe_inputs
    from unips.data import load_object

    torch.manual_seed(0)
    weights = save_checkpoint(tmp_path / "w.safetensors", create_model("glc-test"))
    dil = tmp_path / "dil"
    write_diligent(dil / "sphPNG", k=8)
    out = tmp_path / "bench"
    rc = main(["--data", str(synthetic_object.parent), "--checkpoint", str(weights), "--counts", "1,6",
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

    # The mask-only probe input is the mask itself in every image, in the object's own frame.
    obj = load_object(synthetic_object)
    m = probe_inputs(obj, "mask")
    assert m.images.shape == obj.images.shape
    assert np.array_equal(m.images[..., 0][0] > 0, obj.mask) and set(np.unique(m.images)) <= {0.0, 1.0}
