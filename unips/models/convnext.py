"""ConvNeXt backbone (Liu et al., "A ConvNet for the 2020s") as SDM-UniPS uses it: four stages, a normalised
feature map out of each, any number of input channels.

Parameter names follow the published SDM-UniPS checkpoint (`downsample_layers.i`, `stages.i.j`, `norm{i}`), so
its state dict loads without renaming; timm's ConvNeXt names them differently (`stem`, `stages.i.blocks.j`).
"""

from __future__ import annotations

import torch
from torch import nn


class ChannelsFirstLayerNorm(nn.LayerNorm):
    """LayerNorm over the channels of each location of an `(N, C, H, W)` map."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return super().forward(x.permute(0, 2, 3, 1)).permute(0, 3, 1, 2)


class ConvNeXtBlock(nn.Module):
    """Depth-wise 7x7 convolution, LayerNorm, MLP (x4) with GELU, layer scale, residual: `(N, C, H, W)` kept."""

    def __init__(self, dim: int, layer_scale: float = 1e-6) -> None:
        super().__init__()
        self.dwconv = nn.Conv2d(dim, dim, kernel_size=7, padding=3, groups=dim)
        self.norm = nn.LayerNorm(dim, eps=1e-6)
        self.pwconv1 = nn.Linear(dim, 4 * dim)
        self.act = nn.GELU()
        self.pwconv2 = nn.Linear(4 * dim, dim)
        self.gamma = nn.Parameter(torch.full((dim,), layer_scale))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.dwconv(x).permute(0, 2, 3, 1)  # (N, H, W, C): the MLP acts on channels last
        y = self.gamma * self.pwconv2(self.act(self.pwconv1(self.norm(y))))
        return x + y.permute(0, 3, 1, 2)


class ConvNeXt(nn.Module):
    """`(N, in_chans, s, s) -> 4 maps (N, dims[i], s / 2^(i+2), s / 2^(i+2))`, each LayerNorm-ed over channels."""

    def __init__(self, in_chans: int, dims: tuple[int, ...], depths: tuple[int, ...]) -> None:
        super().__init__()
        # Stem: 4x4 patches; then a 2x2 strided convolution before each later stage.
        self.downsample_layers = nn.ModuleList([nn.Sequential(
            nn.Conv2d(in_chans, dims[0], kernel_size=4, stride=4), ChannelsFirstLayerNorm(dims[0], eps=1e-6))])
        for i in range(3):
            self.downsample_layers.append(nn.Sequential(
                ChannelsFirstLayerNorm(dims[i], eps=1e-6), nn.Conv2d(dims[i], dims[i + 1], kernel_size=2, stride=2)))
        self.stages = nn.ModuleList(nn.Sequential(*(ConvNeXtBlock(d) for _ in range(n))) for d, n in zip(dims, depths))
        for i, d in enumerate(dims):  # norm0 .. norm3: one per output map
            self.add_module(f"norm{i}", ChannelsFirstLayerNorm(d, eps=1e-6))

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        outs = []
        for i, (down, stage) in enumerate(zip(self.downsample_layers, self.stages)):
            x = stage(down(x))
            outs.append(getattr(self, f"norm{i}")(x))
        return outs
