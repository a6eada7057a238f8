"""SDM-UniPS encoder: ConvNeXt per image, attention across images per scale, UPerNet fusion, and the
scale-invariant spatial-light encoding that runs it all at the canonical resolution.

Per image the encoder sees `[I * M, M]` (4 channels) at side H, a multiple m of the canonical side s, and returns
lighting contexts at H / 4: the backbone and fusion see the image (a) resized to s and (b) as its m^2 interleaved
sub-images `x[..., i::m, j::m]` (each of side s, together every pixel); the contexts of (b) are put back in their
interleaved places at H / 4, those of (a) upsampled to H / 4, and the two added.

Module and parameter names follow the published checkpoint (`backbone.backbone.0`, `fusion.fusion`,
`fusion.comm.i`), so its state dict loads without renaming.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .convnext import ConvNeXt
from .sdm_config import SDMConfig
from .set_attention import SetEncoder
from .uper import UPerHead


def split_interleaved(x: torch.Tensor, size: int) -> torch.Tensor:
    """`(N, C, m*size, m*size) -> (m*m*N, C, size, size)`: sub-image k = i*m + j is `x[:, :, i::m, j::m]`,
    sub-image-major (all N images of sub-image 0 first)."""
    n, c, h, _ = x.shape
    m = h // size
    x = x.reshape(n, c, size, m, size, m)  # x[n, c, a, i, b, j] = pixel (a*m + i, b*m + j)
    return x.permute(3, 5, 0, 1, 2, 4).reshape(m * m * n, c, size, size)


def merge_interleaved(x: torch.Tensor, m: int) -> torch.Tensor:
    """Inverse of `split_interleaved`: `(m*m*N, C, s, s) -> (N, C, m*s, m*s)`."""
    _, c, s, _ = x.shape
    n = x.shape[0] // (m * m)
    x = x.reshape(m, m, n, c, s, s).permute(2, 3, 4, 0, 5, 1)  # (N, C, a, i, b, j)
    return x.reshape(n, c, m * s, m * s)


class FeatureExtractor(nn.Module):
    """The ConvNeXt, one level down (`backbone.0`) as in the published checkpoint."""

    def __init__(self, cfg: SDMConfig, in_chans: int) -> None:
        super().__init__()
        self.backbone = nn.Sequential(ConvNeXt(in_chans, cfg.convnext_dims, cfg.convnext_depths))

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        return self.backbone(x)


class FeatureFusion(nn.Module):
    """Attention across the K images of an object at each scale that has it, then UPerNet fusion."""

    def __init__(self, cfg: SDMConfig) -> None:
        super().__init__()
        self.fusion = UPerHead(cfg.convnext_dims, cfg.context_dim, cfg.ppm_scales)
        # One block per scale with attention, numbered consecutively (comm.0 is the first such scale).
        self.comm = nn.ModuleList(SetEncoder(c, c, n, cfg.heads, c, dropout=cfg.dropout)
                                  for c, n in zip(cfg.convnext_dims, cfg.comm_layers) if n > 0)
        self.has_comm = tuple(n > 0 for n in cfg.comm_layers)

    def forward(self, feats: list[torch.Tensor], num_images: int) -> torch.Tensor:
        """feats[i] `(G*K, C_i, h_i, w_i)`, G groups of K images each -> `(G*K, out, h_0, w_0)`."""
        comm = iter(self.comm)
        fused = []
        for f, has in zip(feats, self.has_comm):
            if has:
                gk, c, h, w = f.shape
                tokens = f.reshape(-1, num_images, c, h, w).permute(0, 3, 4, 1, 2).reshape(-1, num_images, c)
                tokens = next(comm)(tokens)  # (G*h*w, K, C): attention across the images at every location
                f = tokens.reshape(-1, h, w, num_images, c).permute(0, 3, 4, 1, 2).reshape(gk, c, h, w)
            fused.append(f)
        return self.fusion(fused)


class ScaleInvariantEncoder(nn.Module):
    """`(B*K, 4, H, H)` (K images per object, H a multiple of the canonical side) -> contexts `(B*K, C, H/4, H/4)`."""

    def __init__(self, cfg: SDMConfig, in_chans: int = 4) -> None:
        super().__init__()
        self.canonical = cfg.canonical_resolution
        self.backbone = FeatureExtractor(cfg, in_chans)
        self.fusion = FeatureFusion(cfg)

    def forward(self, x: torch.Tensor, num_images: int) -> torch.Tensor:
        n, _, h, _ = x.shape
        s = self.canonical
        m = h // s
        resized = F.interpolate(x, size=(s, s), mode="bilinear", align_corners=True)  # (N, 4, s, s)
        # One pass over the resized images and the m^2 interleaved sub-images: groups of K images stay
        # contiguous, so the attention across images never mixes objects or sub-images.
        both = torch.cat([resized, split_interleaved(x, s)], dim=0)  # ((1 + m^2) * N, 4, s, s)
        ctx = self.fusion(self.backbone(both), num_images)  # ((1 + m^2) * N, C, s/4, s/4)
        coarse = F.interpolate(ctx[:n], size=(h // 4, h // 4), mode="bilinear", align_corners=True)
        return coarse + merge_interleaved(ctx[n:], m)  # (N, C, H/4, H/4)
