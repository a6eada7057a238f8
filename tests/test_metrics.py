"""The relative L1 residual of the check (`validate.residuals`): one rule, hand-worked numbers."""
from __future__ import annotations

import json
import math

import numpy as np

from validate.residuals import finite_or_none, rel_l1, rel_l1_observations, relative_l1


def test_rel_l1_rule_and_its_degenerate_case():
    """Known-scene form (mean over the mask) and fitted form (sum over the chosen observations, saturated ones
    censored) against hand-worked values; a zero or empty reference is NaN in both (never inf, never 0), and
    report.json writes it as null."""
    image = np.array([[[1.0], [4.0]]])  # (H=1, W=2, C=1)
    ref = np.array([[[2.0], [4.0]]])
    both, second = np.array([[True, True]]), np.array([[False, True]])
    assert rel_l1(image, ref, both) == (1.0 / 2) / (6.0 / 2)  # mean |diff| 0.5 over mean |ref| 3: 1/6
    assert rel_l1(image, ref, second) == 0.0  # a perfect render of a lit pixel
    assert math.isnan(rel_l1(image, np.zeros_like(ref), both))  # black reference, render not black (was inf)
    assert math.isnan(rel_l1(np.zeros_like(ref), np.zeros_like(ref), both))  # both black (was 0.0)
    assert math.isnan(rel_l1(image, ref, np.zeros((1, 2), bool)))  # no pixel

    render = np.array([[[0.5], [1.5]]], np.float32)  # (K=1, P=2, C=1)
    observed = np.ones((1, 2, 1), np.float32)
    assert rel_l1_observations(render, observed) == 0.5  # (0.5 + 0.5) / 2
    sat_second = np.array([[[False], [True]]])
    assert rel_l1_observations(render, observed, saturated=sat_second) == 0.25  # 1.5 above a clipped 1: free
    assert rel_l1_observations(render, observed, saturated=~sat_second) == 0.5  # 0.5 below a clipped 1 still costs
    assert rel_l1_observations(render, observed, where=np.array([[True, False]])) == 0.5  # 0.5 / 1
    assert rel_l1_observations(render, observed, where=np.array([[False, True]]), saturated=sat_second) == 0.0
    assert math.isnan(rel_l1_observations(render, observed, where=np.zeros((1, 2), bool)))
    assert math.isnan(rel_l1_observations(render, np.zeros_like(observed)))

    assert relative_l1(1.0, 4.0) == 0.25 and math.isnan(relative_l1(1.0, 0.0)) and math.isnan(relative_l1(0.0, 0.0))
    assert json.dumps({"rel_l1": finite_or_none(relative_l1(1.0, 0.0))}, allow_nan=False) == '{"rel_l1": null}'
