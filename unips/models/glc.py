"""GLC-UniPS network: encoder at the canonical resolution, decoder per pixel at the input resolution.

Interface (used by prediction and training):
- `model(images, mask) -> normals`: images `(B, K, 3, H, W)` float32, preprocessed (square crop,
  each image divided by its masked mean); mask `(B, 1, H, W)` in {0, 1}; returns `(B, 3, H, W)` unit
  normals in the camera frame (x right, y up, z toward the camera), zero outside the mask.
- `model.encode(images, mask) -> contexts (B, K, C, s/4, s/4)`.
- `model.decode_pixels(contexts, images, mask, coords) -> (B, N, 3)` for `coords (B, N, 2)` in
  [-1, 1], (x, y) ordered and pixel-centre aligned as `grid_sample(align_corners=False)` expects.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .decoder import PixelDecoder
from .encoder import GLCEncoder
from .net_config import GLCConfig


def pixel_centre_coords(ys: torch.Tensor, xs: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """Integer pixel indices -> `(N, 2)` grid_sample coordinates (x, y) of the pixel centres."""
    x = (2.0 * xs.to(torch.float32) + 1.0) / width - 1.0
    y = (2.0 * ys.to(torch.float32) + 1.0) / height - 1.0
    return torch.stack([x, y], dim=-1)


def check_inputs(images: torch.Tensor, mask: torch.Tensor) -> None:
    if not isinstance(images, torch.Tensor) or images.ndim != 5 or images.shape[2] != 3:
        shape = tuple(images.shape) if isinstance(images, torch.Tensor) else type(images).__name__
        raise ValueError(f"images: got {shape}, expected a tensor (B, K, 3, H, W) with K >= 1")
    b, k, _, h, w = images.shape
    if k < 1 or h < 1 or w < 1:
        raise ValueError(f"images: got shape {tuple(images.shape)}, expected K, H, W >= 1")
    if not isinstance(mask, torch.Tensor) or tuple(mask.shape) != (b, 1, h, w):
        shape = tuple(mask.shape) if isinstance(mask, torch.Tensor) else type(mask).__name__
        raise ValueError(f"mask: got {shape}, expected a tensor {(b, 1, h, w)} matching images")


class GLCUniPS(nn.Module):
    """Universal photometric stereo network with global lighting contexts (Ikehata, CVPR 2022)."""

    def __init__(self, config: GLCConfig) -> None:
        super().__init__()
        self.config = config
        self.model_name: str | None = None  # set by the registry
        self.encoder = GLCEncoder(config)
        self.decoder = PixelDecoder(config)

    # -- encoder ----------------------------------------------------------------------------
    def encode(self, images: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Global lighting contexts `(B, K, C, s/4, s/4)` from images and mask at any resolution."""
        check_inputs(images, mask)
        b, k, _, h, w = images.shape
        s = self.config.canonical_resolution
        mask = mask.to(images.dtype)
        if self.config.mask_before_resize:
            images = images * mask[:, None]
        if (h, w) != (s, s):
            # Antialiased bilinear resize, so downscaling large inputs does not alias.
            imgs = F.interpolate(images.reshape(b * k, 3, h, w), size=(s, s), mode="bilinear",
                                 align_corners=False, antialias=True).reshape(b, k, 3, s, s)
            m = F.interpolate(mask, size=(s, s), mode="bilinear", align_corners=False, antialias=True)
        else:
            imgs, m = images, mask
        ctx = self.encoder(imgs, m)  # (B, K, C, s/4, s/4)
        if self.config.uniform_context:
            ctx = self._uniform(ctx, m)
        return ctx

    @staticmethod
    def _uniform(ctx: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Replace every context map by its average over the (resized) mask."""
        b, k, c, h, w = ctx.shape
        wgt = F.adaptive_avg_pool2d(mask, (h, w)).reshape(b, 1, 1, h, w)  # (B, 1, 1, h, w)
        mean = (ctx * wgt).sum(dim=(-2, -1), keepdim=True) / wgt.sum(dim=(-2, -1), keepdim=True).clamp_min(1e-6)
        return mean.expand(b, k, c, h, w)

    # -- decoder ----------------------------------------------------------------------------
    def pixel_features(self, rgb: torch.Tensor) -> torch.Tensor:
        """A pixel's observations `(B, K, 3, N)` -> decoder features `(B, K, P, N)`.

        "normalized": log(1 + RGB), and RGB divided by the pixel's mean intensity over its K
        images, which is invariant to the pixel's albedo and to a global exposure, so the decoder
        compares one pixel across lights from its first layer on.
        """
        if self.config.pixel_token == "rgb":
            return rgb
        rgb = rgb.clamp_min(0.0)
        mean = rgb.mean(dim=(1, 2), keepdim=True)  # (B, 1, 1, N)
        relative = rgb / (mean + 1e-3)
        return torch.cat([torch.log1p(rgb), relative], dim=2)  # (B, K, 6, N)

    def _decode_tokens(self, rgb: torch.Tensor, ctx: torch.Tensor) -> torch.Tensor:
        """rgb `(B, K, 3, N)`, ctx `(B, K, C, N)` -> normals `(B, N, 3)`."""
        b, k, _, n = rgb.shape
        feats = self.pixel_features(rgb)  # (B, K, P, N)
        tokens = torch.cat([feats, ctx], dim=2).permute(0, 3, 1, 2).reshape(b * n, k, -1)  # (B*N, K, P+C)
        return self.decoder(tokens).reshape(b, n, 3)

    @staticmethod
    def _sample_contexts(contexts: torch.Tensor, coords: torch.Tensor) -> torch.Tensor:
        """contexts `(B, K, C, h, w)`, coords `(B, N, 2)` -> `(B, K, C, N)` (bilinear)."""
        b, k, c, h, w = contexts.shape
        s = F.grid_sample(contexts.reshape(b, k * c, h, w), coords[:, None], mode="bilinear",
                          padding_mode="border", align_corners=False)  # (B, K*C, 1, N)
        return s.reshape(b, k, c, -1)

    def decode_pixels(self, contexts: torch.Tensor, images: torch.Tensor, mask: torch.Tensor,
                      coords: torch.Tensor) -> torch.Tensor:
        """Normals `(B, N, 3)` at `coords (B, N, 2)` (grid_sample convention) of the input images."""
        check_inputs(images, mask)
        b, k, _, h, w = images.shape
        if coords.ndim != 3 or coords.shape[0] != b or coords.shape[2] != 2:
            raise ValueError(f"coords: got {tuple(coords.shape)}, expected (B={b}, N, 2)")
        if contexts.ndim != 5 or contexts.shape[:2] != (b, k):
            raise ValueError(f"contexts: got {tuple(contexts.shape)}, expected (B={b}, K={k}, C, h, w)")
        masked = (images * mask[:, None].to(images.dtype)).reshape(b, k * 3, h, w)
        rgb = F.grid_sample(masked, coords[:, None], mode="bilinear", padding_mode="zeros",
                            align_corners=False).reshape(b, k, 3, -1)  # (B, K, 3, N)
        return self._decode_tokens(rgb, self._sample_contexts(contexts, coords))

    # -- full prediction ----------------------------------------------------------------------
    def forward(self, images: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Unit normals `(B, 3, H, W)` over the mask (zero outside), decoded in pixel chunks."""
        contexts = self.encode(images, mask)  # (B, K, C, h, w)
        b, k, _, h, w = images.shape
        chunk = self.config.pixel_chunk
        out = images.new_zeros(b, 3, h, w)
        for i in range(b):
            ys, xs = torch.nonzero(mask[i, 0] > 0.5, as_tuple=True)
            for start in range(0, ys.numel(), chunk):
                y, x = ys[start:start + chunk], xs[start:start + chunk]
                # Masked pixels at their centres: read the RGB values directly, contexts bilinearly.
                rgb = images[i][:, :, y, x][None]  # (1, K, 3, n)
                coords = pixel_centre_coords(y, x, h, w)[None]  # (1, n, 2)
                ctx = self._sample_contexts(contexts[i:i + 1], coords)  # (1, K, C, n)
                out[i][:, y, x] = self._decode_tokens(rgb, ctx)[0].T  # (3, n)
        return out

    def num_parameters(self) -> int:
        """Number of trainable parameters."""
        return sum(p.numel() for p in self.parameters() if p.requires_grad)
