"""UPerNet fusion (Xiao et al., "Unified Perceptual Parsing for Scene Understanding", 2018) as both published
UniPS networks use it (UniPS, CVPR 2022, after its Swin-S; SDM-UniPS, CVPR 2023, after its ConvNeXt-T): pyramid
pooling on the coarsest map, a top-down feature pyramid, every level upsampled to the finest and fused.

Parameter names follow the published checkpoints (`psp_modules.i.1`, `bottleneck.0`, `lateral_convs.i.0`,
`fpn_convs.i.0`, `fpn_bottleneck.0`); no normalisation layers (the published heads have none).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


def conv_relu(cin: int, cout: int, kernel: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, kernel, padding=kernel // 2), nn.ReLU())


class PyramidPooling(nn.ModuleList):
    """Average-pool to each scale, 1x1 convolution, ReLU, bilinear back to the input size (PSPNet)."""

    def __init__(self, scales: tuple[int, ...], cin: int, cout: int) -> None:
        super().__init__(nn.Sequential(nn.AdaptiveAvgPool2d(s), nn.Conv2d(cin, cout, 1), nn.ReLU()) for s in scales)

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        return [F.interpolate(p(x), size=x.shape[2:], mode="bilinear", align_corners=False) for p in self]


class UPerHead(nn.Module):
    """UPerNet fusion (Xiao et al., 2018): 4 maps of `dims` channels at strides 4..32 -> `(N, out, s/4, s/4)`."""

    def __init__(self, dims: tuple[int, ...], out: int, ppm_scales: tuple[int, ...]) -> None:
        super().__init__()
        self.psp_modules = PyramidPooling(ppm_scales, dims[-1], out)
        self.bottleneck = conv_relu(dims[-1] + len(ppm_scales) * out, out, 3)
        self.lateral_convs = nn.ModuleList(conv_relu(d, out, 1) for d in dims[:-1])
        self.fpn_convs = nn.ModuleList(conv_relu(out, out, 3) for _ in dims[:-1])
        self.fpn_bottleneck = conv_relu(len(dims) * out, out, 3)

    def forward(self, feats: list[torch.Tensor]) -> torch.Tensor:
        top = feats[-1]
        laterals = [conv(f) for conv, f in zip(self.lateral_convs, feats)]
        laterals.append(self.bottleneck(torch.cat([top, *self.psp_modules(top)], dim=1)))
        for i in range(len(laterals) - 1, 0, -1):  # top-down: each level gets the upsampled coarser one
            laterals[i - 1] = laterals[i - 1] + F.interpolate(laterals[i], size=laterals[i - 1].shape[2:],
                                                              mode="bilinear", align_corners=False)
        outs = [conv(lat) for conv, lat in zip(self.fpn_convs, laterals)] + [laterals[-1]]
        size = outs[0].shape[2:]
        outs = [outs[0]] + [F.interpolate(o, size=size, mode="bilinear", align_corners=False) for o in outs[1:]]
        return self.fpn_bottleneck(torch.cat(outs, dim=1))
