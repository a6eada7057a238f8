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

        xy = (
            colour.temperature.CCT_to_xy_Kang2002(kelvin)
            if kelvin >= 1667
            else colour.temperature.CCT_to_xy_Krystek1985(kelvin)
        )
        xyz = colour.xy_to_XYZ(xy)
        rgb = colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)
    rgb = np.clip(np.asarray(rgb, np.float64), 0, None)
    rgb = rgb / rgb.max()
    return float(rgb[0]), float(rgb[1]), float(rgb[2])


# --------------------------------------------------------------------------- the sRGB transfer function

def _colour():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # colour-science warns about optional packages at import
        import colour

    return colour


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Linear values -> sRGB-encoded values in [0, 1] (IEC 61966-2-1, colour-science's `cctf_encoding`),
    clipped to [0, 1] first: how every picture for people shows linear light (figures, contact sheets)."""
    return np.asarray(_colour().cctf_encoding(np.clip(linear, 0.0, 1.0), function="sRGB"), np.float64)


def srgb_to_linear(encoded: np.ndarray) -> np.ndarray:
    """sRGB-encoded values -> linear float32 (IEC 61966-2-1 decoding, the inverse of `linear_to_srgb`): how a
    texture file marked sRGB becomes reflectance. This is colour-science's `cctf_decoding(x, "sRGB")` written
    out in float32 arithmetic, because rendered data depend on it bit for bit: colour-science computes in
    float64, and its result rounded to float32 differs from this one in the last bits for 187 of the 256 8-bit
    codes (both are within 6 float32 steps of the exact curve on every 8- and 16-bit code; tests/test_figures.py)."""
    x = encoded
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)
