"""SDM-UniPS network (Ikehata, "Scalable, Detailed and Mask-Free Universal Photometric Stereo", CVPR 2023).

Interface (as `GLCUniPS`'s):
- `model(images, mask) -> normals`: images `(B, K, 3, H, H)` float32 with H a multiple of the canonical side
  (the published preprocessing: square crop, side a multiple of 512, each image divided by the maximum over
  the masked pixels of its channel mean); mask `(B, 1, H, H)` in {0, 1}; returns `(B, 3, H, H)` unit normals in
  the camera frame (x right, y up, z toward the camera), zero outside the mask.
- `model.encode(images, mask) -> contexts (B, K, C, H/4, H/4)` (smoothed as the decoder samples them).

The decoder works on chunks of masked pixels: per pixel, attention across its K images refines the sampled
contexts, a second one aggregates the images into one feature, and the pixel-sampling transformer attends
across the pixels of the chunk before the normal head. The chunks are a random split of the masked pixels
(as published), drawn from `rng` (seeded by default, so a prediction is repeatable).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from .sdm_config import SDMConfig
from .sdm_encoder import ScaleInvariantEncoder
from .set_attention import NormalHead, SetAggregation, SetEncoder

RGB = 3


def gaussian_blur(x: torch.Tensor, kernel: int, sigma: float = 1.0) -> torch.Tensor:
    """Per-channel Gaussian blur of `(N, C, h, w)` with a `kernel` x `kernel` window (normalised to sum 1)
    and zero padding, as two separable passes."""
    t = torch.arange(kernel, dtype=x.dtype, device=x.device) - (kernel - 1) / 2
    g = torch.exp(-0.5 * (t / sigma) ** 2)
    g = g / g.sum()
    c = x.shape[1]
    x = F.conv2d(x, g.view(1, 1, kernel, 1).expand(c, 1, kernel, 1), padding=(kernel // 2, 0), groups=c)
    return F.conv2d(x, g.view(1, 1, 1, kernel).expand(c, 1, 1, kernel), padding=(0, kernel // 2), groups=c)


class ContextUpsample(nn.Module):
    """Per pixel, attention across its K images over [RGB, sampled context]: `(n, K, 3 + C) -> (n, K, D)`."""

    def __init__(self, cfg: SDMConfig) -> None:
        super().__init__()
        self.comm = SetEncoder(RGB + cfg.context_dim, cfg.upsample_dim, cfg.upsample_layers, cfg.heads,
                               cfg.ff_dim, dropout=cfg.dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.comm(x)


class ContextAggregation(nn.Module):
    """Per pixel, the K images pooled into one feature: `(n, K, 3 + D) -> (n, A)`."""

    def __init__(self, cfg: SDMConfig) -> None:
        super().__init__()
        self.aggregation = SetAggregation(RGB + cfg.upsample_dim, cfg.aggregation_dim, cfg.aggregation_layers,
                                          cfg.heads, cfg.ff_dim, cfg.pooling_ff, dropout=cfg.dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.aggregation(x)


class PixelRegressor(nn.Module):
    """The pixel-sampling transformer: attention across the n pixels of a chunk, then the normal head."""

    def __init__(self, cfg: SDMConfig) -> None:
        super().__init__()
        d = cfg.aggregation_dim
        # The published code runs this block through its memory-efficient attention, which scales the logits
        # by the head width (the other blocks by the full width).
        self.comm = SetEncoder(d, d, cfg.regressor_layers, cfg.heads, cfg.ff_dim, head_scale=True,
                               dropout=cfg.dropout)
        self.prediction_normal = NormalHead(d)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.prediction_normal(self.comm(x[None])[0])  # one set of n pixels


def _check_inputs(images: torch.Tensor, mask: torch.Tensor, canonical: int) -> None:
    if not isinstance(images, torch.Tensor) or images.ndim != 5 or images.shape[2] != RGB:
        shape = tuple(images.shape) if isinstance(images, torch.Tensor) else type(images).__name__
        raise ValueError(f"images: got {shape}, expected a tensor (B, K, 3, H, H) with K >= 1")
    b, k, _, h, w = images.shape
    if k < 1 or h != w or h < canonical or h % canonical:
        raise ValueError(f"images: got shape {tuple(images.shape)}, expected K >= 1 and square images whose side "
                         f"is a multiple of the canonical resolution {canonical}")
    if not isinstance(mask, torch.Tensor) or tuple(mask.shape) != (b, 1, h, w):
        shape = tuple(mask.shape) if isinstance(mask, torch.Tensor) else type(mask).__name__
        raise ValueError(f"mask: got {shape}, expected a tensor {(b, 1, h, w)} matching images")


def pixel_chunks(ids: torch.Tensor, size: int, rng: Any) -> tuple[torch.Tensor, ...]:
    """The masked pixel indices `ids`, shuffled by `rng.permutation` and split into near-equal chunks of at
    most `size` (the first ones one longer), as the published decoder draws them."""
    ids = ids[torch.from_numpy(np.asarray(rng.permutation(len(ids)))).to(ids.device)]
    return torch.tensor_split(ids, len(ids) // size + 1) if len(ids) > size else (ids,)


class SDMUniPS(nn.Module):
    """Scalable, detailed and mask-free universal photometric stereo network; parameter names as published."""

    def __init__(self, config: SDMConfig) -> None:
        super().__init__()
        self.config = config
        self.model_name: str | None = None  # set by the registry
        self.image_encoder = ScaleInvariantEncoder(config)
        self.glc_upsample = ContextUpsample(config)
        self.glc_aggregation = ContextAggregation(config)
        self.regressor = PixelRegressor(config)

    def encode(self, images: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Lighting contexts `(B, K, C, H/4, H/4)`, blurred when `context_smoothing` is set."""
        _check_inputs(images, mask, self.config.canonical_resolution)
        b, k, _, h, w = images.shape
        m = mask.to(images.dtype)[:, None].expand(b, k, 1, h, w)
        x = torch.cat([images * m, m], dim=2).reshape(b * k, RGB + 1, h, w)  # the masked images and the mask
        ctx = self.image_encoder(x, k)  # (B*K, C, H/4, W/4)
        if self.config.context_smoothing:
            ctx = gaussian_blur(ctx, 10 * (h // self.config.canonical_resolution) + 1)
        return ctx.reshape(b, k, *ctx.shape[1:])

    def decode_pixels(self, contexts: torch.Tensor, images: torch.Tensor, ids: torch.Tensor) -> torch.Tensor:
        """Unit normals `(n, 3)` of one object at flat pixel indices `ids (n,)` (row * W + column), decoded
        together: contexts `(K, C, h, w)`, images `(K, 3, H, W)`."""
        k, _, h, w = images.shape
        rows, cols = ids // w, ids % w
        # Sampling points of the published decoder: 2 * index / size - 1, not the pixel centres.
        coords = torch.stack([2 * cols.to(images.dtype) / w - 1, 2 * rows.to(images.dtype) / h - 1], dim=-1)
        ctx = F.grid_sample(contexts, coords.expand(k, 1, -1, 2), mode="bilinear", align_corners=False)
        ctx = ctx[:, :, 0].permute(2, 0, 1)  # (n, K, C)
        rgb = images[:, :, rows, cols].permute(2, 0, 1)  # (n, K, 3): the raw (unmasked) observations
        up = self.glc_upsample(torch.cat([rgb, ctx], dim=2))  # (n, K, D)
        feat = self.glc_aggregation(torch.cat([rgb, up], dim=2))  # (n, A)
        return F.normalize(self.regressor(feat), dim=1)

    def forward(self, images: torch.Tensor, mask: torch.Tensor, rng: Any = None) -> torch.Tensor:
        """Unit normals `(B, 3, H, W)` over the mask (zero outside). rng: anything with `.permutation(n)` that
        shuffles the pixels before they are split into chunks (default: a generator seeded with 0)."""
        contexts = self.encode(images, mask)  # (B, K, C, h, w)
        rng = np.random.default_rng(0) if rng is None else rng
        b, _, _, h, w = images.shape
        out = images.new_zeros(b, RGB, h * w)
        for i in range(b):
            ids = torch.nonzero(mask[i, 0].reshape(-1) > 0)[:, 0]
            for chunk in pixel_chunks(ids, self.config.pixel_samples, rng):
                out[i][:, chunk] = self.decode_pixels(contexts[i], images[i], chunk).T
        return out.reshape(b, RGB, h, w)

    def num_parameters(self) -> int:
        """Number of trainable parameters."""
        return sum(p.numel() for p in self.parameters() if p.requires_grad)
