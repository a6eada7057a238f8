"""Light colours from colour temperatures (colour-science), as linear sRGB with max channel 1."""
from __future__ import annotations

import functools
import warnings

import numpy as np


@functools.lru_cache(maxsize=256)
def temperature_to_rgb(kelvin: float) -> tuple[float, float, float]:
    """Linear sRGB colour of a blackbody (Planckian locus) at `kelvin`, normalised to max 1."""
    if not np.isfinite(kelvin) or not 1000 <= kelvin <= 40000:
        raise ValueError(f"temperature_k: expected 1000..40000 K, got {kelvin!r}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # colour-science warns about optional matplotlib at import
        import colour

        xy = colour.temperature.CCT_to_xy_Kang2002(kelvin) if kelvin >= 1667 else colour.temperature.CCT_to_xy_Krystek1985(kelvin)
        xyz = colour.xy_to_XYZ(xy)
        rgb = colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)
    rgb = np.clip(np.asarray(rgb, np.float64), 0, None)
    rgb = rgb / rgb.max()
    return float(rgb[0]), float(rgb[1]), float(rgb[2])
