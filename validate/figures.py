"""The re-render check's figure, drawn with OpenCV (no plotting library needed).

Title: object, method (where the judged normal map came from), mode and metric. Rows: for a few images,
input | re-render | residual heat map; last row: mean residual over all images (judged normals), the
ground truth's (the same residual with the ground-truth normals, known-scene mode) or the angular error of
the judged map against the ground truth (fitted mode, when the folder has one), and the judged normal map.
Every panel is cropped to the object's bounding box and shows only the mask (white elsewhere).
Images are shown with one common exposure and the sRGB curve. Residual heat maps use one fixed colour
scale, `RESIDUAL_VMAX`, in every figure, so figures of two methods on one object compare at a glance:
the relative residual |re-render - input| / (mean input over the mask), a pure number (0.1 = 10 % of the
mean brightness); values above the scale share its colour. Angular errors use 0 to `ANGLE_VMAX` degrees.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

CELL = 192  # smallest side of a panel in pixels (small images are enlarged with nearest neighbour)
LABEL_H = 22
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


def _masked(bgr: np.ndarray, mask: np.ndarray) -> np.ndarray:
    out = bgr.copy()
    out[~mask] = 255
    return out


def _srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _to_bgr8(rgb: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)[:, :, ::-1])


def _heat(values: np.ndarray, vmax: float, mask: np.ndarray, colormap: int | None = None) -> np.ndarray:
    import cv2

    v = np.clip(values / max(vmax, 1e-12), 0, 1)
    bgr = cv2.applyColorMap((v * 255).astype(np.uint8), cv2.COLORMAP_INFERNO if colormap is None else colormap)
    return _masked(bgr, mask)


def _panel(bgr: np.ndarray, label: str, size: tuple[int, int]) -> np.ndarray:
    import cv2

    h, w = size
    img = cv2.resize(bgr, (w, h), interpolation=cv2.INTER_NEAREST)
    canvas = np.full((h + LABEL_H, w, 3), 255, np.uint8)
    canvas[LABEL_H:] = img
    cv2.putText(canvas, label, (4, LABEL_H - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    return canvas


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


def rerender_figure(
    path: str | Path,
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
) -> None:
    """Write the figure as PNG.

    inputs, renders: (K, H, W, 3) linear images in [0, 1]; mask (H, W); rows: image indices to show;
    mean_residual, gt_mean_residual: (H, W) relative residual maps; normals: (H, W, 3) camera frame;
    angular_error: (H, W) degrees of the judged map against the ground truth, shown when there is no
    ground-truth residual; explained: (P,) bool over the mask pixels (fitted mode), the pixels the physics
    explains, shown as a panel; title: object, method, mode and metric (the caller's words).
    """
    import cv2

    from scenes.colorbar import colorbar

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
    size = (h * scale, w * scale)
    # One exposure for all panels: the 99.5th percentile of the inputs inside the mask maps to 1.
    white = float(np.percentile(inputs[:, mask], 99.5)) if mask.any() else 1.0
    white = white if white > 0 else 1.0
    norm_by = float(np.abs(inputs[:, mask]).mean()) if mask.any() else 1.0
    res = [np.abs(renders[i] - inputs[i]).mean(-1) / max(norm_by, 1e-12) for i in rows]
    vmax = RESIDUAL_VMAX
    lines = []
    for i, r in zip(rows, res):
        lines.append(
            [
                _panel(_masked(_to_bgr8(_srgb(inputs[i] / white)), mask), f"input {i:03d}", size),
                _panel(_masked(_to_bgr8(_srgb(renders[i] / white)), mask), f"re-render {i:03d}", size),
                _panel(_heat(r, vmax, mask), f"rel. residual {i:03d}", size),
            ]
        )
    if gt_mean_residual is not None:
        middle = _panel(_heat(gt_mean_residual, vmax, mask), "mean residual, GT normals", size)
    elif angular_error is not None:
        middle = _panel(_heat(angular_error, ANGLE_VMAX, mask, cv2.COLORMAP_JET),
                        f"angle to GT (0-{ANGLE_VMAX:.0f} deg)", size)
    else:
        middle = _panel(np.full(size + (3,), 255, np.uint8), "(no ground truth)", size)
    last = [
        _panel(_heat(mean_residual, vmax, mask), "mean residual", size),
        middle,
        _panel(_masked(_to_bgr8((normals + 1) / 2), mask), "judged normals", size),
    ]
    if explained_map is not None:
        last.append(_panel(_explained_bgr(mask, explained_map[box]), "explained (judged pixels)", size))
        lines = [line + [_panel(np.full(size + (3,), 255, np.uint8), "", size)] for line in lines]
    lines.append(last)
    grid = np.concatenate([np.concatenate(line, axis=1) for line in lines], axis=0)
    bar = colorbar(grid.shape[0] - LABEL_H, vmax, cv2.COLORMAP_INFERNO, "rel. resid.", ticks=4)
    bar = np.concatenate([np.full((LABEL_H, bar.shape[1], 3), 255, np.uint8), bar], axis=0)[: max(grid.shape[0], 64)]
    if bar.shape[0] < grid.shape[0]:
        bar = np.concatenate([bar, np.full((grid.shape[0] - bar.shape[0],) + bar.shape[1:], 255, np.uint8)], axis=0)
    grid = np.concatenate([grid, bar[: grid.shape[0]]], axis=1)
    if title:
        bar = np.full((LABEL_H + 4, grid.shape[1], 3), 255, np.uint8)
        cv2.putText(bar, title, (4, LABEL_H - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        grid = np.concatenate([bar, grid], axis=0)
    from scenes.objfolder import write_picture

    write_picture(path, grid)
