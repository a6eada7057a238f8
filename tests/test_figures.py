"""The re-render figure: cropped to the mask, nothing shown outside it, one fixed residual scale for every
map of an object, and a title naming object, method and metric; checked on the matplotlib Figure (panel
titles, the data each panel shows against values computed here, colour limits) and on the written PNG."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from scenes.folder.format import PREDICTION_INFO, prediction_label
from validate.figures import ANGLE_VMAX, CELL, LABEL_H, RESIDUAL_VMAX, draw_rerender_figure, mask_box, rerender_figure


def _scene(h=40, w=60):
    mask = np.zeros((h, w), bool)
    mask[10:20, 30:50] = True  # 10 x 20 box, far from the image centre
    inputs = np.zeros((3, h, w, 3), np.float32)
    inputs[:, mask] = np.linspace(0.05, 0.5, int(mask.sum()))[:, None]  # a ramp: mostly darker than white
    inputs[:, ~mask] = 0.9  # a bright background that must not show
    normals = np.zeros((h, w, 3), np.float32)
    normals[mask] = (0, 0, 1)
    return inputs, mask, normals


def _srgb(x):
    """IEC 61966-2-1 encoding, written out here as the answer to compare with."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def _figure(tmp_path, name, residual_value, inputs, mask, normals, render_gain=1.0, **kw):
    """(the Figure, its panels by title, the written PNG as OpenCV reads it)."""
    renders = inputs * render_gain
    mean_res = np.full(mask.shape, residual_value, np.float32)
    args = (inputs, renders, mask, [0], mean_res, None, normals)
    fig = draw_rerender_figure(*args, **kw)
    path = tmp_path / f"{name}.png"
    rerender_figure(path, *args, **kw)
    img = cv2.imread(str(path))
    assert img is not None and img.shape[:2] == (round(fig.bbox.height), round(fig.bbox.width))
    panels = {ax.get_title(loc="left"): ax for ax in fig.axes}
    return fig, panels, img


def _data(ax) -> np.ma.MaskedArray:
    (image,) = ax.get_images()
    return image.get_array()


def test_figure_is_cropped_to_the_mask_and_blank_outside(tmp_path):
    inputs, mask, normals = _scene()
    rows, cols = mask_box(mask)
    assert (rows.start, rows.stop, cols.start, cols.stop) == (8, 22, 28, 52)
    fig, panels, img = _figure(tmp_path, "a", 0.1, inputs, mask, normals)
    assert fig.get_suptitle() == ""
    assert {"input 000", "re-render 000", "rel. residual 000", "mean residual", "(no ground truth)",
            "judged normals", "rel. resid."} == set(panels)
    crop = mask[rows, cols]
    shown = _data(panels["input 000"])
    assert shown.shape == (14, 24, 3)
    assert np.all(shown[~crop] == 1.0)  # white outside the mask, not the bright grey background
    white = np.percentile(inputs[:, mask], 99.5)
    assert np.allclose(shown[crop], _srgb(inputs[0][rows, cols][crop] / white), atol=1e-6)
    scale = int(np.ceil(CELL / 24))  # crop is 14 x 24 pixels
    panel_h, panel_w = 14 * scale, 24 * scale
    assert img.shape[0] == 2 * (panel_h + LABEL_H)  # one image row + the summary row, no title
    # the written input panel: the corner pixel (outside the mask) is white, the centre is not
    assert tuple(img[LABEL_H + 1, 1]) == (255, 255, 255)
    assert tuple(img[LABEL_H + panel_h // 2, panel_w // 2]) != (255, 255, 255)


def test_residual_colour_scale_is_fixed_across_maps(tmp_path):
    inputs, mask, normals = _scene()
    crop = mask[mask_box(mask)]
    # Two maps of one object with different residual ranges: the same value has the same colour in both.
    low = _figure(tmp_path, "low", 0.1, inputs, mask, normals)
    high = _figure(tmp_path, "high", 0.1, inputs, mask, normals, render_gain=1.8)  # large per-image residuals
    for _, panels, _ in (low, high):
        for title in ("rel. residual 000", "mean residual"):
            assert panels[title].get_images()[0].get_clim() == (0.0, RESIDUAL_VMAX)
        bar = panels["rel. resid."]
        assert bar.get_ylim() == (0.0, RESIDUAL_VMAX)
        assert bar.get_yticklabels()[-1].get_text() == f">={RESIDUAL_VMAX:g}"
    residual = _data(high[1]["rel. residual 000"])
    assert np.all(residual.mask == ~crop)
    assert np.allclose(residual[crop], 0.8 * inputs[0][mask].mean(-1) / inputs[:, mask].mean(), rtol=1e-5)
    scale = int(np.ceil(CELL / 24))
    y = 2 * LABEL_H + 14 * scale + (14 * scale) // 2  # summary row, mean-residual panel centre
    x = (24 * scale) // 2
    assert np.array_equal(low[2][y, x], high[2][y, x])
    over = _figure(tmp_path, "over", 10 * RESIDUAL_VMAX, inputs, mask, normals)[2]
    at_top = _figure(tmp_path, "top", RESIDUAL_VMAX, inputs, mask, normals)[2]
    assert np.array_equal(over[y, x], at_top[y, x])  # clipped at the fixed top
    assert not np.array_equal(over[y, x], low[2][y, x])


def test_angular_error_panel_when_only_the_ground_truth_is_known(tmp_path):
    inputs, mask, normals = _scene()
    err = np.where(mask, 30.0, 0.0).astype(np.float32)
    _, with_panels, with_err = _figure(tmp_path, "err", 0.1, inputs, mask, normals, angular_error=err)
    _, without_panels, without = _figure(tmp_path, "none", 0.1, inputs, mask, normals)
    angle = with_panels[f"angle to GT (0-{ANGLE_VMAX:.0f} deg)"].get_images()[0]
    assert angle.get_clim() == (0.0, ANGLE_VMAX) and np.all(angle.get_array()[mask[mask_box(mask)]] == 30.0)
    assert without_panels["(no ground truth)"].get_images() == []
    scale = int(np.ceil(CELL / 24))
    y = 2 * LABEL_H + 14 * scale + (14 * scale) // 2
    x = 24 * scale + (24 * scale) // 2
    assert tuple(without[y, x]) == (255, 255, 255)  # "(no ground truth)": a blank panel
    assert tuple(with_err[y, x]) != (255, 255, 255)


def test_title_and_explained_panel(tmp_path):
    inputs, mask, normals = _scene()
    explained = np.arange(int(mask.sum())) % 2 == 0
    fig, panels, img = _figure(tmp_path, "t", 0.1, inputs, mask, normals, title="ball, model glc-tiny",
                               explained=explained)
    assert fig.get_suptitle() == "ball, model glc-tiny"
    scale = int(np.ceil(CELL / 24))
    assert img.shape[0] == 2 * (14 * scale + LABEL_H) + LABEL_H + 4  # a title line above the panels
    shown = _data(panels["explained (judged pixels)"])
    inside = shown[mask[mask_box(mask)]]
    green, grey = np.array([60, 170, 60]) / 255.0, np.full(3, 150 / 255.0)
    assert np.allclose(inside[explained], green) and np.allclose(inside[~explained], grey)


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


def _srgb_decode(v):
    """IEC 61966-2-1 decoding, written out here in float64."""
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def test_srgb_curves_match_the_standard():
    from scenes.colors import linear_to_srgb, srgb_to_linear

    codes8 = np.arange(256, dtype=np.float32) / 255.0
    codes16 = np.arange(65536, dtype=np.float32) / 65535.0
    for codes in (codes8, codes16):
        decoded = srgb_to_linear(codes)
        assert decoded.dtype == np.float32
        # the texture decoding (float32 arithmetic): within 6 float32 steps of the standard on every code
        want = _srgb_decode(codes.astype(np.float64))
        assert np.all(np.abs(decoded - want) <= 6 * np.spacing(want.astype(np.float32)))
    assert srgb_to_linear(np.float32([0.5]))[0] == pytest.approx(0.21404114, abs=1e-7)  # a textbook value
    linear = np.linspace(0.0, 1.0, 1001)
    assert np.allclose(linear_to_srgb(linear), _srgb(linear), atol=1e-12)
    assert np.allclose(_srgb_decode(linear_to_srgb(linear)), linear, atol=1e-12)
    assert np.array_equal(linear_to_srgb(np.array([-1.0, 2.0])), linear_to_srgb(np.array([0.0, 1.0])))  # clipped


def test_colorbar_shows_the_map_colours_and_its_scale():
    from scenes.report.charts import BAR_WIDTH, colorbar, colorbar_figure, opencv_colormap

    lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_JET)[:, 0]
    cmap = opencv_colormap(cv2.COLORMAP_JET)
    assert np.array_equal(np.round(cmap(np.arange(256))[:, :3] * 255)[:, ::-1], lut)
    fig = colorbar_figure(200, 90.0, cv2.COLORMAP_JET, "angle (deg)", ticks=3, fmt="{:.0f}")
    (cax,) = fig.axes
    assert cax.get_ylim() == (0.0, 90.0)
    assert [t.get_text() for t in cax.get_yticklabels()] == ["0", "30", "60", ">=90"]
    assert [t.get_text() for t in fig.texts] == ["angle (deg)"]
    bar = colorbar(200, 90.0, cv2.COLORMAP_JET, "angle (deg)", ticks=3, fmt="{:.0f}", clipped=False)
    assert bar.shape == (200, BAR_WIDTH, 3) and bar.dtype == np.uint8
    for end in (lut[0], lut[255]):  # both ends of the scale drawn in the map's exact colours
        assert (bar == end).all(-1).any()
    assert colorbar(10, 1.0, cv2.COLORMAP_JET, "x").shape[0] == 64  # never shorter than its labels


def test_a_name_the_font_lacks_is_drawn_without_a_warning():
    """A capture folder named in CJK: its title is drawn (boxes for the missing glyphs) and nothing is printed."""
    import warnings

    from scenes.report.charts import new_figure, to_bgr

    fig = new_figure(200, 80)
    fig.suptitle("pho tos \u00e9\u4e2d")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert to_bgr(fig).shape == (80, 200, 3)
