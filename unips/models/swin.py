"""The Swin Transformer backbone (Liu et al., 2021) as the published UniPS (CVPR 2022) uses it: the detection /
segmentation variant (feature maps padded to whole windows, a LayerNorm-ed map out of each stage) with a
convolutional stem in place of the patch embedding.

Why not timm's Swin (which `encoder.py` uses for our own GLC models): the published weights need this variant's
exact behaviour and names. Its windows never shrink on small maps (a 8 x 8 map is padded to 14 x 14 for windows of
7, and shifted windows stay on), its attention mask is computed on the padded map, its patch merging comes at the
end of a stage, and its relative-position index is a saved buffer. Parameter names follow the published
checkpoint (`patch_embed.convs.i.conv.0`, `layers.i.blocks.j.attn.qkv`, `layers.i.downsample.reduction`,
`norm{i}`), so its state dict loads without renaming.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

MASKED = -100.0
"""Logit added between tokens of a shifted window that come from different regions (the published value)."""


class StemConv(nn.Module):
    """A bias-free convolution, ReLU unless `relu` is False: `(N, Cin, H, W) -> (N, Cout, H / stride, W / stride)`."""

    def __init__(self, cin: int, cout: int, kernel: int, stride: int, relu: bool = True) -> None:
        super().__init__()
        layers: list[nn.Module] = [nn.Conv2d(cin, cout, kernel, stride=stride, padding=kernel // 2, bias=False)]
        self.conv = nn.Sequential(*layers, *([nn.ReLU()] if relu else []))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.conv(x)


class ConvStem(nn.Module):
    """Five convolutions to a quarter of the side (two of stride 2), no normalisation: `(N, Cin, s, s) ->
    (N, E, s/4, s/4)`."""

    def __init__(self, in_chans: int, embed_dim: int) -> None:
        super().__init__()
        half = embed_dim // 2
        self.convs = nn.Sequential(StemConv(in_chans, half, 3, 2), StemConv(half, half, 3, 1),
                                   StemConv(half, embed_dim, 3, 2), StemConv(embed_dim, embed_dim, 3, 1),
                                   StemConv(embed_dim, embed_dim, 1, 1, relu=False))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.convs(x)


def relative_position_index(window: int) -> torch.Tensor:
    """`(w*w, w*w)` index into the `(2w - 1)^2` table of relative offsets between two tokens of a window."""
    yx = torch.stack(torch.meshgrid(torch.arange(window), torch.arange(window), indexing="ij")).flatten(1)
    offset = yx[:, :, None] - yx[:, None, :] + (window - 1)  # (2, w*w, w*w), each in [0, 2w - 2]
    return offset[0] * (2 * window - 1) + offset[1]


def to_windows(x: torch.Tensor, window: int) -> torch.Tensor:
    """`(B, H, W, C) -> (B, nW, w*w, C)`, windows in row-major order (H, W multiples of w)."""
    b, h, w, c = x.shape
    x = x.reshape(b, h // window, window, w // window, window, c).permute(0, 1, 3, 2, 4, 5)
    return x.reshape(b, -1, window * window, c)


def from_windows(x: torch.Tensor, window: int, h: int, w: int) -> torch.Tensor:
    """Inverse of `to_windows`: `(B, nW, w*w, C) -> (B, H, W, C)`."""
    b, _, _, c = x.shape
    x = x.reshape(b, h // window, w // window, window, window, c).permute(0, 1, 3, 2, 4, 5)
    return x.reshape(b, h, w, c)


def shifted_window_mask(h: int, w: int, window: int, shift: int) -> torch.Tensor:
    """`(nW, w*w, w*w)` logits to add in shifted windows of a padded `h x w` map: 0 between tokens of one region
    of the rolled map, `MASKED` between regions (three bands per axis: up to -w, -w to -shift, -shift on)."""
    region = torch.zeros(1, h, w, 1)
    bands = (slice(0, -window), slice(-window, -shift), slice(-shift, None))
    for i, rows in enumerate(bands):
        for j, cols in enumerate(bands):
            region[:, rows, cols] = 3 * i + j
    ids = to_windows(region, window)[0, :, :, 0]  # (nW, w*w)
    same = ids[:, None, :] == ids[:, :, None]
    return torch.where(same, 0.0, MASKED)


class WindowAttention(nn.Module):
    """Multi-head self-attention inside each window, with a learned bias per relative offset and head."""

    def __init__(self, dim: int, heads: int, window: int) -> None:
        super().__init__()
        self.heads = heads
        self.relative_position_bias_table = nn.Parameter(torch.zeros((2 * window - 1) ** 2, heads))
        nn.init.trunc_normal_(self.relative_position_bias_table, std=0.02)
        self.register_buffer("relative_position_index", relative_position_index(window))  # saved in the checkpoint
        self.qkv = nn.Linear(dim, 3 * dim)
        self.proj = nn.Linear(dim, dim)

    def forward(self, x: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
        """x `(B, nW, n, C)` (n = w*w tokens per window); mask `(nW, n, n)` or None -> `(B, nW, n, C)`."""
        b, nw, n, c = x.shape
        h = self.heads
        q, k, v = self.qkv(x).reshape(b, nw, n, 3, h, c // h).permute(3, 0, 1, 4, 2, 5)  # 3 x (B, nW, h, n, C/h)
        bias = self.relative_position_bias_table[self.relative_position_index.reshape(-1)]
        bias = bias.reshape(n, n, h).permute(2, 0, 1)  # (h, n, n)
        logits = bias if mask is None else bias + mask[:, None]  # (h, n, n) or (nW, h, n, n)
        o = F.scaled_dot_product_attention(q, k, v, attn_mask=logits.to(q.dtype))  # (B, nW, h, n, C/h)
        return self.proj(o.transpose(2, 3).reshape(b, nw, n, c))


class Mlp(nn.Module):
    """`C -> hidden -> C` with GELU."""

    def __init__(self, dim: int, hidden: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(dim, hidden)
        self.act = nn.GELU()
        self.fc2 = nn.Linear(hidden, dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc2(self.act(self.fc1(x)))


class DropPath(nn.Module):
    """Stochastic depth: in training, a sample's residual branch is dropped with probability `rate`."""

    def __init__(self, rate: float) -> None:
        super().__init__()
        self.rate = rate

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.rate == 0.0:
            return x
        keep = torch.rand((x.shape[0],) + (1,) * (x.ndim - 1), device=x.device) >= self.rate
        return x * keep.to(x.dtype) / (1.0 - self.rate)


class SwinBlock(nn.Module):
    """(Shifted-)window attention and MLP, each pre-LayerNorm with a residual: `(B, H, W, C)` kept."""

    def __init__(self, dim: int, heads: int, window: int, shift: int, drop_path: float, mlp_ratio: float = 4.0):
        super().__init__()
        self.window, self.shift = window, shift
        self.norm1 = nn.LayerNorm(dim)
        self.attn = WindowAttention(dim, heads, window)
        self.drop_path = DropPath(drop_path)
        self.norm2 = nn.LayerNorm(dim)
        self.mlp = Mlp(dim, int(dim * mlp_ratio))

    def forward(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        b, h, w, c = x.shape
        win, s = self.window, self.shift
        y = self.norm1(x)
        y = F.pad(y, (0, 0, 0, -w % win, 0, -h % win))  # zeros after the norm, up to whole windows
        hp, wp = y.shape[1:3]
        if s:
            y = torch.roll(y, shifts=(-s, -s), dims=(1, 2))
        y = from_windows(self.attn(to_windows(y, win), mask if s else None), win, hp, wp)
        if s:
            y = torch.roll(y, shifts=(s, s), dims=(1, 2))
        x = x + self.drop_path(y[:, :h, :w])
        return x + self.drop_path(self.mlp(self.norm2(x)))


class PatchMerging(nn.Module):
    """2 x 2 neighbours concatenated (odd sides padded), LayerNorm, linear: `(B, H, W, C) -> (B, H/2, W/2, 2C)`."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.norm = nn.LayerNorm(4 * dim)
        self.reduction = nn.Linear(4 * dim, 2 * dim, bias=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = F.pad(x, (0, 0, 0, x.shape[2] % 2, 0, x.shape[1] % 2))
        # The published order of the four neighbours: (0, 0), (1, 0), (0, 1), (1, 1) as (row, column) offsets.
        x = torch.cat([x[:, 0::2, 0::2], x[:, 1::2, 0::2], x[:, 0::2, 1::2], x[:, 1::2, 1::2]], dim=-1)
        return self.reduction(self.norm(x))


class SwinStage(nn.Module):
    """Blocks alternating plain and shifted windows, then (except in the last stage) patch merging."""

    def __init__(self, dim: int, depth: int, heads: int, window: int, drop_path: list[float], merge: bool) -> None:
        super().__init__()
        self.window = window
        self.blocks = nn.ModuleList(SwinBlock(dim, heads, window, 0 if i % 2 == 0 else window // 2, drop_path[i])
                                    for i in range(depth))
        self.downsample = PatchMerging(dim) if merge else None

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """`(B, H, W, C)` -> (the stage's output `(B, H, W, C)`, the next stage's input)."""
        win = self.window
        h, w = x.shape[1:3]
        mask = shifted_window_mask(h + -h % win, w + -w % win, win, win // 2).to(x.device)
        for block in self.blocks:
            x = block(x, mask)
        return x, (self.downsample(x) if self.downsample is not None else x)


class SwinBackbone(nn.Module):
    """`(N, Cin, s, s) -> 4 maps (N, E * 2^i, s / 2^(i+2), s / 2^(i+2))`, each LayerNorm-ed over channels."""

    def __init__(self, in_chans: int, embed_dim: int, depths: tuple[int, ...], heads: tuple[int, ...],
                 window: int, drop_path: float) -> None:
        super().__init__()
        self.patch_embed = ConvStem(in_chans, embed_dim)
        rates = torch.linspace(0, drop_path, sum(depths)).tolist()  # stochastic depth grows along the blocks
        starts = [sum(depths[:i]) for i in range(len(depths))]
        self.layers = nn.ModuleList(
            SwinStage(embed_dim * 2 ** i, d, h, window, rates[s:s + d], merge=i < len(depths) - 1)
            for i, (d, h, s) in enumerate(zip(depths, heads, starts)))
        self.dims = tuple(embed_dim * 2 ** i for i in range(len(depths)))
        for i, d in enumerate(self.dims):  # norm0 .. norm3: one per output map
            self.add_module(f"norm{i}", nn.LayerNorm(d))

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        x = self.patch_embed(x).permute(0, 2, 3, 1)  # (N, s/4, s/4, E): channels last inside the stages
        outs = []
        for i, stage in enumerate(self.layers):
            out, x = stage(x)
            outs.append(getattr(self, f"norm{i}")(out).permute(0, 3, 1, 2))  # (N, C_i, h_i, w_i)
        return outs
