"""The re-render check's figure, drawn with OpenCV (no plotting library needed).

Rows: for a few images, input | re-render | residual heat map; last row: mean residual over all images
(predicted normals), the same with the ground-truth normals (when known), and the predicted normal map.
Images are shown with one common exposure and the sRGB curve; heat maps share one colour scale, drawn as a
colour bar on the right: the relative residual |re-render - input| / (mean input over the mask), a pure number
(0.1 = 10 % of the mean brightness), from 0 to the 99th percentile shown (values above share its colour).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

CELL = 192  # smallest side of a panel in pixels (small images are enlarged with nearest neighbour)
LABEL_H = 22


def _srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _to_bgr8(rgb: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)[:, :, ::-1])


def _heat(values: np.ndarray, vmax: float, mask: np.ndarray | None) -> np.ndarray:
    import cv2

    v = np.clip(values / max(vmax, 1e-12), 0, 1)
    bgr = cv2.applyColorMap((v * 255).astype(np.uint8), cv2.COLORMAP_INFERNO)
    if mask is not None:
        bgr[~mask] = (bgr[~mask] * 0.35).astype(np.uint8)  # dim the background
    return bgr


def _panel(bgr: np.ndarray, label: str, size: tuple[int, int]) -> np.ndarray:
    import cv2

    h, w = size
    img = cv2.resize(bgr, (w, h), interpolation=cv2.INTER_NEAREST)
    canvas = np.full((h + LABEL_H, w, 3), 255, np.uint8)
    canvas[LABEL_H:] = img
    cv2.putText(canvas, label, (4, LABEL_H - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    return canvas


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
) -> None:
    """Write the figure as PNG.

    inputs, renders: (K, H, W, 3) linear images in [0, 1]; mask (H, W); rows: image indices to show;
    mean_residual, gt_mean_residual: (H, W) relative residual maps; normals: (H, W, 3) camera frame.
    """
    import cv2

    k, h, w, _ = inputs.shape
    scale = max(1, int(np.ceil(CELL / max(h, w))))
    size = (h * scale, w * scale)
    # One exposure for all panels: the 99.5th percentile of the inputs inside the mask maps to 1.
    white = float(np.percentile(inputs[:, mask], 99.5)) if mask.any() else 1.0
    white = white if white > 0 else 1.0
    norm_by = float(np.abs(inputs[:, mask]).mean()) if mask.any() else 1.0
    res = [np.abs(renders[i] - inputs[i]).mean(-1) / max(norm_by, 1e-12) for i in rows]
    vmax = float(np.percentile(np.concatenate([r[mask] for r in res] + [mean_residual[mask]]), 99)) if mask.any() else 1.0
    vmax = vmax if vmax > 0 else 1.0
    lines = []
    for i, r in zip(rows, res):
        lines.append(
            [
                _panel(_to_bgr8(_srgb(inputs[i] / white)), f"input L{i:03d}", size),
                _panel(_to_bgr8(_srgb(renders[i] / white)), f"re-render {i:03d}", size),
                _panel(_heat(r, vmax, mask), f"rel. residual {i:03d}", size),
            ]
        )
    nrm = np.where(mask[..., None], (normals + 1) / 2, 1.0)
    last = [
        _panel(_heat(mean_residual, vmax, mask), "mean residual", size),
        _panel(_heat(gt_mean_residual, vmax, mask), "mean residual, GT normals", size)
        if gt_mean_residual is not None
        else _panel(np.full(size + (3,), 255, np.uint8), "(no ground truth)", size),
        _panel(_to_bgr8(nrm), "predicted normals", size),
    ]
    lines.append(last)
    grid = np.concatenate([np.concatenate(line, axis=1) for line in lines], axis=0)
    from scenes.colorbar import colorbar

    bar = colorbar(grid.shape[0] - LABEL_H, vmax, cv2.COLORMAP_INFERNO, "rel. resid.", ticks=4)
    bar = np.concatenate([np.full((LABEL_H, bar.shape[1], 3), 255, np.uint8), bar], axis=0)[: max(grid.shape[0], 64)]
    if bar.shape[0] < grid.shape[0]:
        bar = np.concatenate([bar, np.full((grid.shape[0] - bar.shape[0],) + bar.shape[1:], 255, np.uint8)], axis=0)
    grid = np.concatenate([grid, bar], axis=1)
    if title:
        bar = np.full((LABEL_H + 4, grid.shape[1], 3), 255, np.uint8)
        cv2.putText(bar, title, (4, LABEL_H - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        grid = np.concatenate([bar, grid], axis=0)
    if not cv2.imwrite(str(path), grid):
        raise OSError(f"could not write figure {str(path)!r}")
