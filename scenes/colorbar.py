"""A labelled colour bar for heat-map figures (OpenCV only): the one legend of `unips.evaluate`'s error maps
and `validate`'s residual panels, so that every colour-coded map says what its colours mean and in which unit."""
from __future__ import annotations

import numpy as np

BAR_WIDTH = 96
"""Width in pixels of the colour-bar panel (gradient, ticks and labels)."""


def colorbar(height: int, vmax: float, colormap: int, unit: str, ticks: int = 4, fmt: str = "{:.3g}",
             clipped: bool = True) -> np.ndarray:
    """(height, BAR_WIDTH, 3) BGR uint8 panel: the colour scale from 0 (bottom) to `vmax` (top) of `colormap`
    (an OpenCV COLORMAP_*), `ticks` + 1 labelled values and `unit` written above; `clipped` marks the top
    label with '>=' (values above vmax share its colour)."""
    import cv2

    height = max(int(height), 64)
    panel = np.full((height, BAR_WIDTH, 3), 255, np.uint8)
    top, bottom = 22, height - 8
    levels = np.linspace(255, 0, bottom - top).round().astype(np.uint8)[:, None]
    strip = cv2.applyColorMap(np.repeat(levels, 14, axis=1), colormap)
    panel[top:bottom, 4:18] = strip
    font, scale = cv2.FONT_HERSHEY_SIMPLEX, 0.36
    cv2.putText(panel, unit, (2, 13), font, scale, (0, 0, 0), 1, cv2.LINE_AA)
    for t in range(ticks + 1):
        value = vmax * t / ticks
        y = int(round(bottom - 1 - (bottom - 1 - top) * t / ticks))
        cv2.line(panel, (18, y), (22, y), (0, 0, 0), 1)
        label = ((">=" if clipped and t == ticks else "") + fmt.format(value))
        cv2.putText(panel, label, (24, min(max(y + 4, top + 4), bottom)), font, scale, (0, 0, 0), 1, cv2.LINE_AA)
    return panel
