"""What the fitted check and refinement can judge: the rule applied to a capture before any fitting.

Without a scene file, lights (per image) and albedo (per pixel) are fitted to the images around the normal
map. With too few images those free parameters explain a wrong map about as well as the right one: the
score cannot rank maps, and refinement moves a correct map away. Measured on a Lambertian sphere with
noise at DiLiGenT's level (`bench/bench_min_images.py`, quoted in docs/check.md, "What can be judged"):

- 1 image: every map is explained exactly (each normal by its own albedo); nothing is ranked;
- 2 images: 5-10 deg errors mostly score above the ground truth, but for one light pair in four by less
  than the image noise, and the ground truth itself scores up to 4.4 times the noise;
- 3 or 4 images: maps rank (by at least 2.7 noise levels), but refinement of the ground-truth map moves it
  by up to 5.3 deg (below 5 images none can be held out for early stopping);
- 5 images: refinement leaves the ground truth within 1.2 deg (0.0 in most draws), 6 or more: 0.0;
- lit pixels: with 8 images a sphere of 4 px (8 lit pixels per image) still ranks and refines (0.2 deg).

An image is *informative* when, at the fitting resolution, it is not constant inside the mask and has at
least `MIN_LIT_PIXELS` mask pixels that are lit (mean over channels above `LIT_LEVEL` times the image's
bright level) and saturated in no channel. `check_judgeable` refuses a capture with fewer informative
images than `MIN_IMAGES` asks for its use, with one line naming --data, the folder, what is wrong and the
minimum.
"""
from __future__ import annotations

import numpy as np

from validate.observations import Capture

MIN_IMAGES = {
    "photos": 3,  # fewer do not determine a normal (three unknowns per pixel): a capture is refused
    "advised": 6,  # below, a warning: unknown light needs more views than the three of calibrated stereo
    "check": 3,  # the fitted re-render check runs (informative images)
    "verdict": 5,  # a pixel needs this many unshadowed observations for the check to trust it (4 unknowns + 1)
    "refine": 5,  # refinement runs (informative images)
    "holdout": 5,  # refinement holds images out for early stopping from this many on
}
"""The one table of image counts: the fewest images each use needs (informative ones for "check" and "refine",
see the module doc; measured by `bench/bench_min_images.py`, docs/check.md "What can be judged")."""
MIN_LIT_PIXELS = 8
"""Fewest lit, unsaturated mask pixels (at the fitting resolution) that make an image informative: the
smallest count measured (a 4 px sphere), and about the unknowns of one image's light (direction 2, RGB
irradiance 3, RGB ambient 3)."""
LIT_LEVEL = 0.05
"""A pixel is lit when its mean over channels exceeds this fraction of its image's bright level (relative,
so the rule does not depend on the exposure; shadowed pixels lit only by ambient light stay below it)."""
BRIGHT_PERCENTILE = 99.0
"""Percentile of an image's positive mask values that is its bright level (a percentile, not the maximum,
so a few highlight or hot pixels do not move it)."""


def lit_pixels(images: np.ndarray, mask: np.ndarray, saturated: np.ndarray | None = None) -> np.ndarray:
    """(K,) number of mask pixels of each image that are lit and saturated in no channel (see the module
    doc). images (K, H, W, 3), mask (H, W) bool, saturated (K, H, W, 3) bool or None."""
    gray = images[:, mask].astype(np.float64).mean(-1)  # (K, P)
    out = np.zeros(len(images), np.int64)
    for i, g in enumerate(gray):
        positive = g[g > 0]
        if positive.size == 0:
            continue
        lit = g > LIT_LEVEL * np.percentile(positive, BRIGHT_PERCENTILE)
        if saturated is not None:
            lit &= ~saturated[i][mask].any(-1)
        out[i] = int(lit.sum())
    return out


def _constant(images: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(K,) bool: images whose every mask value is one number (all channels)."""
    inside = images[:, mask].reshape(len(images), -1)
    if inside.shape[1] == 0:
        return np.ones(len(images), bool)
    return inside.max(1) == inside.min(1)


def _names(cap: Capture, idx: np.ndarray, counts: np.ndarray | None = None, limit: int = 4) -> str:
    idx = list(idx)
    shown = [cap.image_names[i] + (f" {int(counts[i])}" if counts is not None else "") for i in idx[:limit]]
    return ", ".join(shown) + (f" and {len(idx) - limit} more" if len(idx) > limit else "")


def check_judgeable(cap: Capture, use: str, arg: str = "--data", mask_arg: str | None = None) -> None:
    """Raise ValueError (one line naming `arg`, the folder and the minimum) when the fitted check (`use`
    "check") or refinement ("refine") cannot judge a normal map on `cap`, a capture at the fitting resolution:
    fewer images than `MIN_IMAGES[use]`, non-finite values, every image black, constant, or saturated
    wherever it is lit, or fewer informative images (see the module doc) than `MIN_IMAGES[use]`. A mask too small
    is named by `mask_arg` (default `arg`)."""
    if use not in ("check", "refine"):
        raise ValueError(f"use: unknown use {use!r}, expected check or refine")
    k, least = len(cap.images), MIN_IMAGES[use]
    what = "the fitted check" if use == "check" else "refinement"
    need = (f"{what} needs at least {least} images with at least {MIN_LIT_PIXELS} lit, unsaturated mask pixels "
            "each (docs/check.md, 'What can be judged')")
    where = f"{arg}: {cap.folder}"
    if k < least:
        raise ValueError(f"{where} has {k} image(s); {need}: with fewer, the fitted lights and albedo explain a "
                         "wrong normal map about as well as the right one")
    scale = (f" at the fitting resolution (1/{cap.downsample}: raise --max-pixels, or lower --downsample where it is "
             "given)") if cap.downsample > 1 else ""
    if int(cap.mask.sum()) < MIN_LIT_PIXELS:
        raise ValueError(f"{mask_arg or arg}: the mask of {cap.folder} has {int(cap.mask.sum())} pixels{scale}; "
                         f"{need}")
    inside = cap.images[:, cap.mask]  # (K, P, 3)
    finite = np.isfinite(inside).all(axis=(1, 2))
    if not finite.all():
        raise ValueError(
            f"{where}: image {_names(cap, np.flatnonzero(~finite))} has NaN or infinite values inside the mask"
        )
    # Black or constant inside the mask while the images are not: a mask that is given (or found) on the wrong
    # part of the frame (a lamp, a flat floor), said as the mask's fault.
    blame = (f"{mask_arg}: the mask of {cap.folder}" if mask_arg and cap.images.std(axis=0).max() > 0 else where)
    if not (inside > 0).any():
        raise ValueError(f"{blame}: every image is black inside the mask; {need}")
    constant = _constant(cap.images, cap.mask)
    if constant.all():
        raise ValueError(f"{blame}: every image is constant inside the mask (one value per image"
                         + ("; a lamp or a flat lit surface, not the object?" if blame != where else "") + f"); {need}")
    counts = lit_pixels(cap.images, cap.mask, cap.saturated)
    counts[constant] = 0
    good = counts >= MIN_LIT_PIXELS
    if good.sum() >= least:
        return
    if (counts == 0).all() and cap.saturated is not None and (lit_pixels(cap.images, cap.mask) > 0).any():
        raise ValueError(f"{where}: every lit mask pixel is saturated (at the file's largest code) in every image; "
                         f"{need}: expose so that the object stays below white")
    raise ValueError(
        f"{where}: only {int(good.sum())} of {k} images have at least {MIN_LIT_PIXELS} lit, unsaturated "
        f"mask pixels{scale} (lit pixels of the others: {_names(cap, np.flatnonzero(~good), counts)}); {need}"
    )
