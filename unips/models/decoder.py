"""GLC-UniPS per-pixel decoder: attention across images, PMA pooling, normal predictor.

Input per pixel: one token per image, the pixel's observation in that image (raw RGB, or RGB
normalised across the images, see `GLCConfig.pixel_token`) concatenated with the bilinearly sampled
global lighting context (P + C channels). Output: a unit normal.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .layers import PoolingByAttention, TransformerLayer
from .net_config import GLCConfig


class PixelDecoder(nn.Module):
    """`(N, K, P + C)` tokens -> `(N, 3)` unit normals; invariant to the order of the K tokens."""

    def __init__(self, cfg: GLCConfig) -> None:
        super().__init__()
        d = cfg.decoder_dim
        self.embed = nn.Linear(cfg.pixel_token_channels + cfg.context_dim, d)
        self.layers = nn.ModuleList(
            TransformerLayer(d, cfg.decoder_heads, cfg.decoder_ff, cfg.dropout) for _ in range(cfg.decoder_layers)
        )
        self.pool = PoolingByAttention(d, cfg.decoder_heads, cfg.decoder_ff, cfg.dropout)
        self.norm = nn.LayerNorm(d)
        self.predictor = nn.Sequential(
            nn.Linear(d, cfg.predictor_hidden), nn.ReLU(inplace=True), nn.Linear(cfg.predictor_hidden, 3)
        )

    def forward(self, tokens: torch.Tensor) -> torch.Tensor:
        x = self.embed(tokens)  # (N, K, D)
        for layer in self.layers:
            x = layer(x)
        x = self.norm(self.pool(x))  # (N, D)
        n = self.predictor(x)  # (N, 3)
        return F.normalize(n, dim=-1, eps=1e-8)
