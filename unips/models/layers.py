"""Set layers used across images: pre-norm Transformer layer and pooling by multi-head attention.

Inputs are sets of per-image tokens `(N, K, D)`: N independent sets (pixels), K elements (images),
D channels. No positional encoding over K, so every layer is permutation equivariant in K and the
PMA pooling is invariant.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


class MultiHeadAttention(nn.Module):
    """Multi-head attention from queries `(N, Q, D)` to keys/values `(N, K, D)`."""

    def __init__(self, dim: int, heads: int, dropout: float = 0.0) -> None:
        super().__init__()
        if dim % heads:
            raise ValueError(f"heads={heads}: expected a divisor of dim={dim}")
        self.heads = heads
        self.dropout = dropout
        self.q = nn.Linear(dim, dim)
        self.kv = nn.Linear(dim, 2 * dim)
        self.out = nn.Linear(dim, dim)

    def forward(self, queries: torch.Tensor, keys: torch.Tensor) -> torch.Tensor:
        n, nq, d = queries.shape
        nk = keys.shape[1]
        h = self.heads
        q = self.q(queries).view(n, nq, h, d // h).transpose(1, 2)  # (N, h, Q, D/h)
        k, v = self.kv(keys).view(n, nk, 2, h, d // h).permute(2, 0, 3, 1, 4)  # 2 x (N, h, K, D/h)
        p = self.dropout if self.training else 0.0
        o = F.scaled_dot_product_attention(q, k, v, dropout_p=p)  # (N, h, Q, D/h)
        return self.out(o.transpose(1, 2).reshape(n, nq, d))


class FeedForward(nn.Module):
    """Two-layer MLP with GELU and dropout."""

    def __init__(self, dim: int, hidden: int, dropout: float = 0.0) -> None:
        super().__init__()
        self.fc1 = nn.Linear(dim, hidden)
        self.fc2 = nn.Linear(hidden, dim)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.drop(self.fc2(self.drop(F.gelu(self.fc1(x)))))


class TransformerLayer(nn.Module):
    """Pre-layer-norm Transformer layer over the K elements of each set: `(N, K, D) -> (N, K, D)`."""

    def __init__(self, dim: int, heads: int, ff_dim: int, dropout: float = 0.0) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(dim)
        self.attn = MultiHeadAttention(dim, heads, dropout)
        self.norm2 = nn.LayerNorm(dim)
        self.ff = FeedForward(dim, ff_dim, dropout)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.norm1(x)
        x = x + self.drop(self.attn(y, y))
        return x + self.ff(self.norm2(x))


class PoolingByAttention(nn.Module):
    """PMA with one learned seed: `(N, K, D) -> (N, D)`, invariant to the order of the K elements."""

    def __init__(self, dim: int, heads: int, ff_dim: int, dropout: float = 0.0) -> None:
        super().__init__()
        self.seed = nn.Parameter(torch.randn(1, 1, dim) * 0.02)
        self.norm_q = nn.LayerNorm(dim)
        self.norm_kv = nn.LayerNorm(dim)
        self.attn = MultiHeadAttention(dim, heads, dropout)
        self.norm2 = nn.LayerNorm(dim)
        self.ff = FeedForward(dim, ff_dim, dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        s = self.seed.expand(x.shape[0], 1, -1)  # (N, 1, D)
        s = s + self.attn(self.norm_q(s), self.norm_kv(x))
        s = s + self.ff(self.norm2(s))
        return s[:, 0]
