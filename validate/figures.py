"""The re-render check's figure, drawn with matplotlib (`scenes.report.charts`).

Title: object, method (where the judged normal map came from), mode and metric. Rows: for a few images,
input | re-render | residual heat map; last row: mean residual over all images (judged normals), the
ground truth's (the same residual with the ground-truth normals, known-scene mode) or the angular error of
the judged map against the ground truth (fitted mode, when the folder has one), and the judged normal map.
Every panel is cropped to the object's bounding box and shows only the mask (white elsewhere).
Images are shown with one common exposure and the sRGB curve (`scenes.colors.linear_to_srgb`). Residual
heat maps use one fixed colour scale, `RESIDUAL_VMAX`, in every figure, so figures of two methods on one
object compare at a glance:
the relative residual |re-render - input| / (mean input over the mask), a pure number (0.1 = 10 % of the
mean brightness); values above the scale share its colour. Angular errors use 0 to `ANGLE_VMAX` degrees.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

CELL = 192  # smallest side of a panel in pixels (small images are enlarged with nearest neighbour)
LABEL_H = 22
"""Pixels above each panel for its label."""
BAR_W = 70
"""Pixels of the colour-bar column at the right."""
RESIDUAL_VMAX = 0.5
"""Top of the residual colour scale in every figure (a constant normal map scores about 0.25-0.45 on
DiLiGenT objects, the ground truth 0.03-0.35): fixed, never taken from the map being judged."""
ANGLE_VMAX = 45.0
"""Top of the angular-error colour scale (degrees)."""
MARGIN = 2
"""Pixels kept around the mask's bounding box."""


def mask_box(mask: np.ndarray, margin: int = MARGIN) -> tuple[slice, slice]:
    """Rows and columns of the mask's bounding box grown by `margin` (the whole image for an empty mask)."""
    if not mask.any():
        return slice(None), slice(None)
    ys, xs = np.nonzero(mask)
    h, w = mask.shape
    return (slice(max(0, ys.min() - margin), min(h, ys.max() + 1 + margin)),
            slice(max(0, xs.min() - margin), min(w, xs.max() + 1 + margin)))


def _explained_bgr(mask: np.ndarray, explained: np.ndarray) -> np.ndarray:
    """Explained pixels green, the rest of the mask grey, white outside."""
    out = np.full(mask.shape + (3,), 255, np.uint8)
    out[mask] = (150, 150, 150)
    out[mask & explained] = (60, 170, 60)
    return out


def explained_picture(mask: np.ndarray, explained: np.ndarray) -> np.ndarray:
    """explained.png of the fitted mode: (H, W, 3) BGR, explained mask pixels (P,) green, the others grey."""
    full = np.zeros(mask.shape, bool)
    full[mask] = explained
    return _explained_bgr(mask, full)


def _image(ax, rgb: np.ndarray, mask: np.ndarray) -> None:
    """An RGB panel in [0, 1], white outside the mask, one screen block per pixel."""
    out = np.clip(rgb, 0.0, 1.0).copy()
    out[~mask] = 1.0
    ax.imshow(out, interpolation="nearest", aspect="auto")


def _heat(ax, values: np.ndarray, vmax: float, mask: np.ndarray, cmap: str = "inferno"):
    """A heat-map panel on the fixed scale 0..vmax (values above share the top colour), white outside the mask."""
    import matplotlib

    colours = matplotlib.colormaps[cmap].with_extremes(bad="white")
    return ax.imshow(np.ma.masked_array(values, ~mask), cmap=colours, vmin=0.0, vmax=vmax,
                     interpolation="nearest", aspect="auto")


def draw_rerender_figure(
    inputs: np.ndarray,
    renders: np.ndarray,
    mask: np.ndarray,
    rows: list[int],
    mean_residual: np.ndarray,
    gt_mean_residual: np.ndarray | None,
    normals: np.ndarray,
    title: str = "",
    angular_error: np.ndarray | None = None,
    explained: np.ndarray | None = None,
):
    """The figure (module doc) as a matplotlib Figure; each panel is an Axes titled with its label.

    inputs, renders: (K, H, W, 3) linear images in [0, 1]; mask (H, W); rows: image indices to show;
    mean_residual, gt_mean_residual: (H, W) relative residual maps; normals: (H, W, 3) camera frame;
    angular_error: (H, W) degrees of the judged map against the ground truth, shown when there is no
    ground-truth residual; explained: (P,) bool over the mask pixels (fitted mode), the pixels the physics
    explains, shown as a panel; title: object, method, mode and metric (the caller's words).
    """
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    from scenes.colors import linear_to_srgb
    from scenes.report.charts import add_axes_px, new_figure

    explained_map = None
    if explained is not None:
        explained_map = np.zeros(mask.shape, bool)
        explained_map[mask] = explained
    box = mask_box(mask)
    inputs, renders, mask = inputs[(slice(None),) + box], renders[(slice(None),) + box], mask[box]
    mean_residual, normals = mean_residual[box], normals[box]
    gt_mean_residual = None if gt_mean_residual is None else gt_mean_residual[box]
    angular_error = None if angular_error is None else angular_error[box]
    k, h, w, _ = inputs.shape
    scale = max(1, int(np.ceil(CELL / max(h, w))))
    ph, pw = h * scale, w * scale
    # One exposure for all panels: the 99.5th percentile of the inputs inside the mask maps to 1.
    white = float(np.percentile(inputs[:, mask], 99.5)) if mask.any() else 1.0
    white = white if white > 0 else 1.0
    norm_by = float(np.abs(inputs[:, mask]).mean()) if mask.any() else 1.0
    vmax = RESIDUAL_VMAX
    cols = 3 if explained_map is None else 4
    top = LABEL_H + 4 if title else 0
    fig = new_figure(cols * pw + BAR_W, top + (len(rows) + 1) * (ph + LABEL_H))

    def panel(row: int, col: int, label: str):
        ax = add_axes_px(fig, col * pw, top + row * (ph + LABEL_H) + LABEL_H, pw, ph)
        ax.set_title(label, fontsize=8, loc="left", pad=3)
        return ax

    for line, i in enumerate(rows):
        _image(panel(line, 0, f"input {i:03d}"), linear_to_srgb(inputs[i] / white), mask)
        _image(panel(line, 1, f"re-render {i:03d}"), linear_to_srgb(renders[i] / white), mask)
        residual = np.abs(renders[i] - inputs[i]).mean(-1) / max(norm_by, 1e-12)
        _heat(panel(line, 2, f"rel. residual {i:03d}"), residual, vmax, mask)
    last = len(rows)
    _heat(panel(last, 0, "mean residual"), mean_residual, vmax, mask)
    if gt_mean_residual is not None:
        _heat(panel(last, 1, "mean residual, GT normals"), gt_mean_residual, vmax, mask)
    elif angular_error is not None:
        _heat(panel(last, 1, f"angle to GT (0-{ANGLE_VMAX:.0f} deg)"), angular_error, ANGLE_VMAX, mask, "jet")
    else:
        panel(last, 1, "(no ground truth)")
    _image(panel(last, 2, "judged normals"), (normals + 1) / 2, mask)
    if explained_map is not None:
        explained_rgb = _explained_bgr(mask, explained_map[box])[:, :, ::-1] / 255.0
        _image(panel(last, 3, "explained (judged pixels)"), explained_rgb, np.ones_like(mask))
    grid_h = (len(rows) + 1) * (ph + LABEL_H)
    cax = add_axes_px(fig, cols * pw + 6, top + LABEL_H, 14, max(grid_h - LABEL_H - 8, 32), frame=True)
    bar = fig.colorbar(ScalarMappable(Normalize(0.0, vmax), "inferno"), cax=cax)
    ticks = [vmax * t / 4 for t in range(5)]
    bar.set_ticks(ticks, labels=[f"{v:.3g}" for v in ticks[:-1]] + [f">={ticks[-1]:.3g}"])
    cax.tick_params(labelsize=7, length=3, pad=1)
    cax.set_title("rel. resid.", fontsize=7, loc="left", pad=8)
    if title:
        fig.suptitle(title, x=4 / fig.bbox.width, y=1.0 - 4 / fig.bbox.height, ha="left", va="top", fontsize=9)
    return fig


def rerender_figure(path: str | Path, *args, **kwargs) -> None:
    """Write `draw_rerender_figure(*args, **kwargs)` as PNG."""
    from scenes.report.charts import write_figure

    write_figure(path, draw_rerender_figure(*args, **kwargs))
