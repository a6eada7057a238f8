"""Image and normal comparisons of the re-render check (plain NumPy)."""
from __future__ import annotations

import numpy as np


def expose(radiance: np.ndarray, exposure: float) -> np.ndarray:
    """What the dataset stores: clip(radiance * exposure, 0, 1), rounded to 16 bit, as float32."""
    return (np.round(np.clip(radiance * exposure, 0.0, 1.0) * 65535.0) / 65535.0).astype(np.float32)


def rel_l1(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    """mean |image - reference| / mean |reference| over the mask pixels (all channels); images (H, W, C)."""
    diff = np.abs(image[mask].astype(np.float64) - reference[mask])
    denom = float(np.abs(reference[mask]).mean())
    return float(diff.mean() / denom) if denom > 0 else float("inf") if diff.mean() > 0 else 0.0


def psnr(image: np.ndarray, reference: np.ndarray, mask: np.ndarray, peak: float = 1.0) -> float:
    """PSNR in dB over the mask pixels, peak value 1 (the images are in [0, 1]); inf when identical."""
    mse = float(np.mean((image[mask].astype(np.float64) - reference[mask]) ** 2))
    return float(10.0 * np.log10(peak * peak / mse)) if mse > 0 else float("inf")


def relative_residual_map(images: np.ndarray, references: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W) per-pixel residual averaged over the K images (K, H, W, C), divided by the mean |reference|
    over the mask and images: its mean over the mask is the rel_l1 of all images pooled."""
    res = np.abs(images.astype(np.float64) - references).mean(axis=(0, 3))
    denom = float(np.abs(references[:, mask]).mean())
    return (res / denom if denom > 0 else res).astype(np.float32)


def finite_or_none(x: float | None) -> float | None:
    """JSON has no inf/NaN: map them to None."""
    return float(x) if x is not None and np.isfinite(x) else None


def mean_or_none(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.mean(vals)) if vals and len(vals) == len(values) else None
