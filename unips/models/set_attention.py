"""Attention blocks over sets as both published UniPS networks use them (after the Set Transformer of Lee et al.,
2019): UniPS (CVPR 2022) across images per encoder scale and per pixel, SDM-UniPS (CVPR 2023) likewise and across
pixels.

A set is `(N, K, D)`: N independent sets of K elements of D channels (pixels x images, or one set of pixels).
No positional encoding, so the blocks are permutation equivariant in K and the seed pooling is invariant.

The published network's attention block differs from a textbook Transformer layer in ways its weights
depend on, kept here exactly:
- the queries come from the LayerNorm-ed input, the keys and values from the raw input;
- no output projection: the block's output is the projected queries plus the attention (the residual is
  the queries, not the input), then a pre-norm feed-forward residual;
- the logits are scaled by 1/sqrt(width), not 1/sqrt(head width), except in SDM-UniPS's pixel-sampling
  transformer (`head_scale=True`, where its memory-efficient path scales by the head width);
- SDM-UniPS's projections have no biases, UniPS's have (`bias=True`); UniPS's attention across images in the
  encoder has no LayerNorm (`norm=False`).
Parameter names (`enc.i.mab.fc_q`, `dec.0.S`, ...) are those of the published checkpoints.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


class AttentionBlock(nn.Module):
    """Queries from `x (N, Q, Din)`, keys and values from `y (N, K, Din)` -> `(N, Q, Dout)`."""

    def __init__(self, dim_in: int, dim_out: int, heads: int, ff_dim: int, norm: bool = True,
                 head_scale: bool = False, dropout: float = 0.0, bias: bool = False) -> None:
        super().__init__()
        if dim_out % heads:
            raise ValueError(f"heads={heads}: expected a divisor of dim_out={dim_out}")
        self.heads = heads
        self.dropout = dropout
        self.scale = (dim_out // heads if head_scale else dim_out) ** -0.5
        self.fc_q = nn.Linear(dim_in, dim_out, bias=bias)
        self.fc_k = nn.Linear(dim_in, dim_out, bias=bias)
        self.fc_v = nn.Linear(dim_in, dim_out, bias=bias)
        self.ln0 = nn.LayerNorm(dim_in) if norm else nn.Identity()
        self.ln1 = nn.LayerNorm(dim_out) if norm else nn.Identity()
        self.fc_o1 = nn.Linear(dim_out, ff_dim, bias=bias)
        self.fc_o2 = nn.Linear(ff_dim, dim_out, bias=bias)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        q = self.fc_q(self.ln0(x))  # (N, Q, D)
        n, nq, d = q.shape
        h = self.heads
        k = self.fc_k(y).view(n, -1, h, d // h).transpose(1, 2)  # (N, h, K, D/h)
        v = self.fc_v(y).view(n, -1, h, d // h).transpose(1, 2)  # (N, h, K, D/h)
        a = F.scaled_dot_product_attention(q.view(n, nq, h, d // h).transpose(1, 2), k, v, scale=self.scale,
                                           dropout_p=self.dropout if self.training else 0.0)  # (N, h, Q, D/h)
        o = q + a.transpose(1, 2).reshape(n, nq, d)
        return o + self.drop(self.fc_o2(self.drop(F.gelu(self.fc_o1(self.ln1(o))))))


class SelfAttention(nn.Module):
    """Self-attention over the K elements: `(N, K, Din) -> (N, K, Dout)`."""

    def __init__(self, dim_in: int, dim_out: int, heads: int, ff_dim: int, head_scale: bool = False,
                 dropout: float = 0.0, bias: bool = False, norm: bool = True) -> None:
        super().__init__()
        self.mab = AttentionBlock(dim_in, dim_out, heads, ff_dim, norm=norm, head_scale=head_scale, dropout=dropout,
                                  bias=bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.mab(x, x)


class SeedPooling(nn.Module):
    """Pooling by attention from one learned seed: `(N, K, D) -> (N, 1, D)`; no LayerNorm."""

    def __init__(self, dim: int, heads: int, ff_dim: int, dropout: float = 0.0, bias: bool = False) -> None:
        super().__init__()
        self.S = nn.Parameter(torch.randn(1, 1, dim) * dim ** -0.5)
        self.mab = AttentionBlock(dim, dim, heads, ff_dim, norm=False, dropout=dropout, bias=bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.mab(self.S.expand(x.shape[0], -1, -1), x)


def self_attention_stack(dim_in: int, dim: int, extra_layers: int, heads: int, ff_dim: int,
                         head_scale: bool = False, dropout: float = 0.0, bias: bool = False) -> nn.Sequential:
    """A first layer `dim_in -> dim`, then `extra_layers` layers `dim -> dim`."""
    return nn.Sequential(*(SelfAttention(dim_in if i == 0 else dim, dim, heads, ff_dim, head_scale, dropout, bias)
                           for i in range(extra_layers + 1)))


class SetEncoder(nn.Module):
    """Stacked self-attention over the K elements: `(N, K, Din) -> (N, K, D)`."""

    def __init__(self, dim_in: int, dim: int, extra_layers: int, heads: int, ff_dim: int,
                 head_scale: bool = False, dropout: float = 0.0) -> None:
        super().__init__()
        self.enc = self_attention_stack(dim_in, dim, extra_layers, heads, ff_dim, head_scale, dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.enc(x)


class SetAggregation(nn.Module):
    """Self-attention over the K elements, then seed pooling: `(N, K, Din) -> (N, D)`."""

    def __init__(self, dim_in: int, dim: int, extra_layers: int, heads: int, ff_dim: int, pooling_ff: int,
                 dropout: float = 0.0, bias: bool = False) -> None:
        super().__init__()
        self.enc = self_attention_stack(dim_in, dim, extra_layers, heads, ff_dim, dropout=dropout, bias=bias)
        self.dec = nn.Sequential(SeedPooling(dim, heads, pooling_ff, dropout, bias))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.dec(self.enc(x))[:, 0]


class NormalHead(nn.Module):
    """`(n, A) -> (n, 3)` raw normals: A -> A/2 -> 3 with ReLU, the last layer of both published decoders."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.regression = nn.Sequential(nn.Linear(dim, dim // 2), nn.ReLU(), nn.Linear(dim // 2, 3))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.regression(x)
