"""The published UniPS network (Ikehata, "Universal Photometric Stereo Network using Global Lighting Contexts",
CVPR 2022), whose authors' weights load into it (`glc-unips`).

Interface (as `GLCUniPS`'s):
- `model(images, mask) -> normals`: images `(B, K, 3, H, W)` float32 at the working side (the published
  preprocessing, `unips.glc_preprocess`: square crop, 512 x 512, each image divided by its masked mean intensity,
  multiplied by the mask); mask `(B, 1, H, W)` in {0, 1}; returns `(B, 3, H, W)` unit normals in the camera frame
  (x right, y up, z toward the camera), zero outside the mask.
- `model.encode(images, mask) -> contexts (B, K, C, s/4, s/4)` at the canonical side s.
- `model.decode_pixels(contexts, images, mask, coords) -> (B, N, 3)` at grid_sample coordinates (training).

Encoder, per image `[I * M, M]` at the canonical side: Swin-S with a convolutional stem (`swin.py`), at each of its
four scales one self-attention layer across the K images at every location, UPerNet fusion (`uper.py`) into the
global lighting contexts. Decoder, per pixel at the working side: its K observations, each the raw RGB with the
context bilinearly sampled there, go through self-attention across the images, are pooled by a learned seed and
regressed to a normal (`set_attention.py`). Pixels are decoded independently.

Module and parameter names follow the published checkpoint files: `encoder.*` is the authors' `*_enc.pytmodel`
(`backbone.0`, `attn.i.0`, `fusion.0`), `aggregation.*` their `*_agg.pytmodel`, `prediction.*` their
`*_pred.pytmodel`.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .glc import check_inputs
from .set_attention import NormalHead, SelfAttention, SetAggregation
from .swin import SwinBackbone
from .unips22_config import UniPS22Config
from .uper import UPerHead

RGB = 3


class ContextEncoder(nn.Module):
    """`(B*K, 4, s, s)` (K images per object) -> global lighting contexts `(B*K, C, s/4, s/4)`."""

    def __init__(self, cfg: UniPS22Config) -> None:
        super().__init__()
        dims = cfg.stage_channels
        self.backbone = nn.Sequential(SwinBackbone(RGB + 1, cfg.swin_embed_dim, cfg.swin_depths, cfg.swin_heads,
                                                   cfg.swin_window, cfg.swin_drop_path))
        # One self-attention layer across the images per scale: biases, no LayerNorm, feed-forward twice the width.
        self.attn = nn.ModuleList(nn.Sequential(SelfAttention(c, c, cfg.heads, 2 * c, dropout=cfg.dropout, bias=True,
                                                              norm=False)) for c in dims)
        self.fusion = nn.Sequential(UPerHead(dims, cfg.context_dim, cfg.ppm_scales))

    def forward(self, x: torch.Tensor, num_images: int) -> torch.Tensor:
        fused = []
        for f, attn in zip(self.backbone(x), self.attn):
            bk, c, h, w = f.shape
            tokens = f.reshape(-1, num_images, c, h, w).permute(0, 3, 4, 1, 2).reshape(-1, num_images, c)
            tokens = attn(tokens)  # (B*h*w, K, C): attention across the images at every location
            fused.append(tokens.reshape(-1, h, w, num_images, c).permute(0, 3, 4, 1, 2).reshape(bk, c, h, w))
        return self.fusion(fused)


def published_coords(rows: torch.Tensor, cols: torch.Tensor, h: int, w: int) -> torch.Tensor:
    """`(N, 2)` grid_sample coordinates (x, y) where the published decoders sample the contexts of pixel (row,
    column): 2 * index / size - 1, a half pixel up and left of the pixel centres."""
    return torch.stack([2 * cols.to(torch.float32) / w - 1, 2 * rows.to(torch.float32) / h - 1], dim=-1)


class UniPS22(nn.Module):
    """Universal photometric stereo network with global lighting contexts, as published; parameter names as in the
    authors' checkpoint files."""

    def __init__(self, config: UniPS22Config) -> None:
        super().__init__()
        self.config = config
        self.model_name: str | None = None  # set by the registry
        self.encoder = ContextEncoder(config)
        self.aggregation = SetAggregation(RGB + config.context_dim, config.aggregation_dim, config.aggregation_layers,
                                          config.heads, config.aggregation_ff, config.pooling_ff,
                                          dropout=config.dropout, bias=True)
        self.prediction = NormalHead(config.aggregation_dim)

    def encode(self, images: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Global lighting contexts `(B, K, C, s/4, s/4)` from images and mask at any side."""
        check_inputs(images, mask)
        b, k, _, h, w = images.shape
        s = self.config.canonical_resolution
        mask = mask.to(images.dtype)
        if (h, w) != (s, s):  # as published: bilinear without antialiasing, the mask nearest
            images = F.interpolate(images.reshape(b * k, RGB, h, w), size=(s, s), mode="bilinear",
                                   align_corners=False).reshape(b, k, RGB, s, s)
            mask = F.interpolate(mask, size=(s, s), mode="nearest")
        m = mask[:, None].expand(b, k, 1, s, s)
        x = torch.cat([images * m, m], dim=2).reshape(b * k, RGB + 1, s, s)  # the masked images and the mask
        ctx = self.encoder(x, k)  # (B*K, C, s/4, s/4)
        return ctx.reshape(b, k, *ctx.shape[1:])

    def _decode_tokens(self, rgb: torch.Tensor, ctx: torch.Tensor) -> torch.Tensor:
        """rgb `(n, K, 3)`, sampled contexts `(n, K, C)` -> unit normals `(n, 3)`."""
        feat = self.aggregation(torch.cat([rgb, ctx], dim=2))  # (n, A)
        return F.normalize(self.prediction(feat), dim=1)

    @staticmethod
    def _sample(maps: torch.Tensor, coords: torch.Tensor) -> torch.Tensor:
        """maps `(K, C, h, w)` bilinearly at coords `(n, 2)` (zero padding, as published) -> `(n, K, C)`."""
        k = maps.shape[0]
        out = F.grid_sample(maps, coords.to(maps.dtype).expand(k, 1, -1, 2), mode="bilinear", align_corners=False)
        return out[:, :, 0].permute(2, 0, 1)

    def decode_pixels(self, contexts: torch.Tensor, images: torch.Tensor, mask: torch.Tensor,
                      coords: torch.Tensor) -> torch.Tensor:
        """Normals `(B, N, 3)` at `coords (B, N, 2)` (grid_sample convention) of the masked input images (the
        training interface of `GLCUniPS.decode_pixels`)."""
        check_inputs(images, mask)
        b, k = images.shape[:2]
        if coords.ndim != 3 or coords.shape[0] != b or coords.shape[2] != 2:
            raise ValueError(f"coords: got {tuple(coords.shape)}, expected (B={b}, N, 2)")
        masked = images * mask[:, None].to(images.dtype)
        return torch.stack([self._decode_tokens(self._sample(masked[i], coords[i]),
                                                self._sample(contexts[i], coords[i])) for i in range(b)])

    def forward(self, images: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Unit normals `(B, 3, H, W)` over the mask (zero outside), decoded in chunks of `pixel_chunk` pixels."""
        contexts = self.encode(images, mask)  # (B, K, C, h, w)
        b, _, _, h, w = images.shape
        out = images.new_zeros(b, RGB, h * w)
        for i in range(b):
            ids = torch.nonzero(mask[i, 0].reshape(-1) > 0)[:, 0]
            for chunk in torch.split(ids, self.config.pixel_chunk):
                rows, cols = chunk // w, chunk % w
                rgb = images[i][:, :, rows, cols].permute(2, 0, 1)  # (n, K, 3): the observations themselves
                ctx = self._sample(contexts[i], published_coords(rows, cols, h, w))  # (n, K, C)
                out[i][:, chunk] = self._decode_tokens(rgb, ctx).T
        return out.reshape(b, RGB, h, w)

    def num_parameters(self) -> int:
        """Number of trainable parameters."""
        return sum(p.numel() for p in self.parameters() if p.requires_grad)
