"""Image and normal comparisons of the re-render check (plain NumPy)."""
from __future__ import annotations

from typing import Any

import numpy as np

from scenes.files import to_plain


def expose(radiance: np.ndarray, exposure: float) -> np.ndarray:
    """What the dataset stores: clip(radiance * exposure, 0, 1), rounded to 16 bit, as float32."""
    with np.errstate(over="ignore"):  # radiance beyond float32 saturates the sensor like any other
        return (np.round(np.clip(radiance * exposure, 0.0, 1.0) * 65535.0) / 65535.0).astype(np.float32)


def relative_l1(error: Any, reference: Any) -> float:
    """The one rule of every relative L1 residual of the check: `error / reference`, the summed (or mean)
    |render - observed| over the summed (or mean) |observed| of the same observations, divided in the
    caller's precision. Degenerate case: when `reference` is not positive (no observation, or all of them
    0) the residual is undefined and the answer is NaN (never inf, never 0); report.json writes it as null."""
    return float(error / reference) if reference > 0 else float("nan")


def rel_l1(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    """Known-scene check, one image: mean |image - reference| / mean |reference| over the mask pixels (all
    channels), in float64; images (H, W, C). NaN when degenerate (`relative_l1`)."""
    if not mask.any():
        return float("nan")
    diff = np.abs(image[mask].astype(np.float64) - reference[mask])
    return relative_l1(diff.mean(), float(np.abs(reference[mask]).mean()))


def rel_l1_observations(render: np.ndarray, observed: np.ndarray, where: np.ndarray | None = None,
                        saturated: np.ndarray | None = None) -> float:
    """Fitted check: sum |render - observed| / sum |observed| over (K, P, 3) arrays, in their precision,
    over the observations `where` selects (a boolean index of their leading axes; all by default). Where
    `saturated` (bool, the shape of `observed`) the observation is a lower bound and only a render below it
    counts. NaN when degenerate (`relative_l1`)."""
    err = np.abs(render - observed)
    if saturated is not None:
        err = np.where(saturated, np.maximum(observed - render, 0), err)
    if where is not None:
        err, observed = err[where], observed[where]
    return relative_l1(err.sum(), float(np.abs(observed).sum()))


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
    """JSON has no inf/NaN: map them to None (`scenes.files.to_plain` of one number)."""
    return None if x is None else to_plain(float(x))


def mean_or_none(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.mean(vals)) if vals and len(vals) == len(values) else None
