"""The published UniPS preprocessing (the test-time data loader of its `main.py`), for the models whose registry
entry's contract asks for it (`unips.models.contract`: preprocess "glc-unips"); `unips.inference.run_model`
dispatches here.

- Crop: the box of SDM-UniPS's loader (`unips.sdm_preprocess.sdm_crop`, the same rule) with a margin of
  `GLC_MARGIN` px: the mask's bounding box grown by 4 px, its shorter side grown by half the difference on each side
  (clipped to the image); when the grown box would touch the image border, the whole image instead (then not
  square: it is stretched by the resize, as published).
- Resize: the crop to `GLC_SIDE` x `GLC_SIDE` (512, the published loader and decoder side) by nearest neighbour,
  images and mask alike; the network resizes the images bilinearly (the mask by nearest neighbour) to its canonical
  side (256) for the encoder and decodes every masked pixel at 512.
- Normalisation: each image divided by its mean over the masked pixels of the channel mean (no epsilon), then
  multiplied by the mask.
- Images: at most `GLC_MAX_IMAGES` (64), a seeded random subset when there are more (the published loader draws
  one at random on every run; the network does not depend on their order).
- Back (ours: the published code writes only a 512 px picture): the network's map resized bicubically to the crop,
  kept where its length is within 0.5 of 1, normalised, put into the full frame, zero outside the object's mask,
  as for SDM-UniPS (`sdm_output`).

Nearest-neighbour resizing picks pixels without arithmetic, so for 8/16-bit files the images equal the published
loader's exactly.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from unips.data import PSObject
from unips.models.contract import GLC_UNIPS_INPUTS
from unips.sdm_preprocess import SDMCrop, image_subset, sdm_crop

GLC_MARGIN = GLC_UNIPS_INPUTS.margin
"""Pixels around the mask's bounding box (fixed in the published loader; the registry entry's contract)."""
GLC_SIDE = GLC_UNIPS_INPUTS.side
"""Working side: the published test run's loader and decoder size (the contract's `side`)."""
GLC_MAX_IMAGES = GLC_UNIPS_INPUTS.max_images
"""Most images the network sees (the published test configuration's test_maxNumberOfImages; the contract's)."""


def glc_crop(mask: np.ndarray, side: int = GLC_SIDE, margin: int = GLC_MARGIN) -> SDMCrop:
    """The published crop of `mask (H, W)` and its working side."""
    return dataclasses.replace(sdm_crop(mask, margin=margin), side=side)


def glc_inputs(obj: PSObject, crop: SDMCrop, max_images: int = GLC_MAX_IMAGES,
               seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """images `(K, S, S, 3)` float32 (normalised, zero outside the mask) and mask `(S, S)` float32 in {0, 1}."""
    import cv2

    chosen = image_subset(obj.num_images, max_images, seed)
    s = crop.side
    mask = cv2.resize(obj.mask[crop.r0:crop.r1, crop.c0:crop.c1].astype(np.float32), (s, s),
                      interpolation=cv2.INTER_NEAREST)  # (S, S) in {0, 1}
    inside = mask == 1
    if not inside.any():
        raise ValueError(f"mask: {obj.name}'s object vanishes at the working side {s} px")
    images = np.stack([cv2.resize(obj.images[i, crop.r0:crop.r1, crop.c0:crop.c1], (s, s),
                                  interpolation=cv2.INTER_NEAREST) for i in chosen])  # (K, S, S, 3)
    mean = images[:, inside].mean(axis=2).mean(axis=1)  # (K,): the masked mean of the channel mean
    return (images / mean[:, None, None, None] * mask[None, :, :, None]).astype(np.float32), mask
