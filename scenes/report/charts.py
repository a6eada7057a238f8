"""Charts and figures for people, drawn with matplotlib (Agg, without pyplot or a display): a figure sized in
pixels, axes placed in pixels, the figure as an 8-bit BGR picture (written by `scenes.images.write_picture`,
atomically, like every picture), an OpenCV colour map as a matplotlib one, and the labelled colour bar of the
heat maps that stay image pixels (`unips.evaluate`'s error maps): every colour-coded map says what its colours
mean and in which unit."""
from __future__ import annotations

from pathlib import Path

import numpy as np

DPI = 100
"""Figures are sized in pixels: inches = pixels / DPI."""
BAR_WIDTH = 96
"""Width in pixels of the colour-bar picture (gradient, ticks and labels)."""


def new_figure(width_px: int, height_px: int, layout: str | None = None):
    """A white matplotlib Figure of `width_px` x `height_px` pixels, with an Agg canvas (no pyplot state);
    `layout`: matplotlib's layout engine ("constrained" for grids of charts, None for axes placed in pixels)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_px / DPI, height_px / DPI), dpi=DPI, facecolor="white", layout=layout)
    FigureCanvasAgg(fig)
    return fig


def add_axes_px(fig, left: float, top: float, width: float, height: float, frame: bool = False):
    """Axes at a rectangle given in pixels from the figure's top-left corner; without `frame` an image panel
    (no ticks, no frame)."""
    w, h = fig.get_size_inches() * fig.dpi
    ax = fig.add_axes((left / w, 1.0 - (top + height) / h, width / w, height / h))
    if not frame:
        ax.set_axis_off()
    return ax


def to_bgr(fig) -> np.ndarray:
    """The figure drawn (Agg) as an (H, W, 3) uint8 BGR picture. A character of a name the font lacks (a CJK
    folder name) is drawn as a box, without matplotlib's warning on the terminal."""
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Glyph .* missing from")
        fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    return np.ascontiguousarray(rgba[:, :, 2::-1])


def write_figure(path: str | Path, fig) -> None:
    """Write the figure as a picture (PNG from the extension), atomically."""
    from scenes.images import write_picture

    write_picture(path, to_bgr(fig))


def opencv_colormap(colormap: int):
    """An OpenCV COLORMAP_* as a 256-entry matplotlib colour map, so that a bar shows exactly the colours of
    the map it labels."""
    import cv2
    from matplotlib.colors import ListedColormap

    bgr = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], colormap)[:, 0]
    return ListedColormap(bgr[:, ::-1] / 255.0)


def colorbar_figure(height: int, vmax: float, colormap: int, unit: str, ticks: int = 4, fmt: str = "{:.3g}",
                    clipped: bool = True):
    """The colour-bar Figure (BAR_WIDTH x max(height, 64) pixels): the scale of `colormap` (an OpenCV
    COLORMAP_*) from 0 (bottom) to `vmax` (top), `ticks` + 1 labelled values, `unit` written above; `clipped`
    marks the top label with '>=' (values above vmax share its colour)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    height = max(int(height), 64)
    fig = new_figure(BAR_WIDTH, height)
    cax = add_axes_px(fig, 4, 22, 14, height - 30, frame=True)
    bar = fig.colorbar(ScalarMappable(Normalize(0.0, vmax), opencv_colormap(colormap)), cax=cax)
    values = [vmax * t / ticks for t in range(ticks + 1)]
    bar.set_ticks(values, labels=[(">=" if clipped and t == ticks else "") + fmt.format(v)
                                  for t, v in enumerate(values)])
    cax.tick_params(labelsize=7, length=3, pad=1)
    fig.text(2 / BAR_WIDTH, 1.0 - 13 / height, unit, fontsize=7)
    return fig


def colorbar(height: int, vmax: float, colormap: int, unit: str, ticks: int = 4, fmt: str = "{:.3g}",
             clipped: bool = True) -> np.ndarray:
    """`colorbar_figure` as a (max(height, 64), BAR_WIDTH, 3) BGR uint8 picture, to set beside a heat map."""
    return to_bgr(colorbar_figure(height, vmax, colormap, unit, ticks, fmt, clipped))
