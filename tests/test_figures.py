"""The re-render figure: cropped to the mask, nothing shown outside it, one fixed residual scale for every
map of an object, and a title naming object, method and metric."""
from __future__ import annotations

import json

import cv2
import numpy as np

from scenes.objfolder import PREDICTION_INFO, prediction_label
from validate.figures import CELL, LABEL_H, RESIDUAL_VMAX, mask_box, rerender_figure


def _scene(h=40, w=60):
    mask = np.zeros((h, w), bool)
    mask[10:20, 30:50] = True  # 10 x 20 box, far from the image centre
    inputs = np.zeros((3, h, w, 3), np.float32)
    inputs[:, mask] = np.linspace(0.05, 0.5, int(mask.sum()))[:, None]  # a ramp: mostly darker than white
    inputs[:, ~mask] = 0.9  # a bright background that must not show
    normals = np.zeros((h, w, 3), np.float32)
    normals[mask] = (0, 0, 1)
    return inputs, mask, normals


def _figure(tmp_path, name, residual_value, inputs, mask, normals, render_gain=1.0, **kw):
    renders = inputs * render_gain
    mean_res = np.full(mask.shape, residual_value, np.float32)
    path = tmp_path / f"{name}.png"
    rerender_figure(path, inputs, renders, mask, [0], mean_res, None, normals, **kw)
    img = cv2.imread(str(path))
    assert img is not None
    return img


def test_figure_is_cropped_to_the_mask_and_blank_outside(tmp_path):
    inputs, mask, normals = _scene()
    rows, cols = mask_box(mask)
    assert (rows.start, rows.stop, cols.start, cols.stop) == (8, 22, 28, 52)
    img = _figure(tmp_path, "a", 0.1, inputs, mask, normals)
    scale = int(np.ceil(CELL / 24))  # crop is 14 x 24 pixels
    panel_h, panel_w = 14 * scale, 24 * scale
    assert img.shape[0] == 2 * (panel_h + LABEL_H)  # one image row + the summary row, no title
    # input panel: the corner pixel (outside the mask) is white, not the bright grey background
    corner = img[LABEL_H + 1, 1]
    assert tuple(corner) == (255, 255, 255)
    centre = img[LABEL_H + panel_h // 2, panel_w // 2]
    assert tuple(centre) != (255, 255, 255)


def test_residual_colour_scale_is_fixed_across_maps(tmp_path):
    inputs, mask, normals = _scene()
    # Two maps of one object with different residual ranges: the same value has the same colour in both.
    low = _figure(tmp_path, "low", 0.1, inputs, mask, normals)
    high = _figure(tmp_path, "high", 0.1, inputs, mask, normals, render_gain=1.8)  # large per-image residuals
    scale = int(np.ceil(CELL / 24))
    y = 2 * LABEL_H + 14 * scale + (14 * scale) // 2  # summary row, mean-residual panel centre
    x = (24 * scale) // 2
    assert np.array_equal(low[y, x], high[y, x])
    over = _figure(tmp_path, "over", 10 * RESIDUAL_VMAX, inputs, mask, normals)
    at_top = _figure(tmp_path, "top", RESIDUAL_VMAX, inputs, mask, normals)
    assert np.array_equal(over[y, x], at_top[y, x])  # clipped at the fixed top
    assert not np.array_equal(over[y, x], low[y, x])


def test_angular_error_panel_when_only_the_ground_truth_is_known(tmp_path):
    inputs, mask, normals = _scene()
    err = np.where(mask, 30.0, 0.0).astype(np.float32)
    with_err = _figure(tmp_path, "err", 0.1, inputs, mask, normals, angular_error=err)
    without = _figure(tmp_path, "none", 0.1, inputs, mask, normals)
    scale = int(np.ceil(CELL / 24))
    y = 2 * LABEL_H + 14 * scale + (14 * scale) // 2
    x = 24 * scale + (24 * scale) // 2
    assert tuple(without[y, x]) == (255, 255, 255)  # "(no ground truth)": a blank panel
    assert tuple(with_err[y, x]) != (255, 255, 255)


def test_prediction_label_names_the_method(tmp_path):
    folder = tmp_path / "pred" / "ball"
    folder.mkdir(parents=True)
    (folder / "normal.exr").write_bytes(b"")
    assert prediction_label(folder / "normal.exr") == "ball/normal.exr"
    (folder / PREDICTION_INFO).write_text(json.dumps({"method": "model", "model_name": "glc-tiny"}))
    assert prediction_label(folder / "normal.exr") == "model glc-tiny"
    (folder / PREDICTION_INFO).write_text(json.dumps({"method": "least-squares", "model_name": None}))
    assert prediction_label(folder / "normal.exr") == "least-squares"
    (folder / PREDICTION_INFO).write_text("{broken")
    assert prediction_label(folder / "normal.exr") == "ball/normal.exr"
