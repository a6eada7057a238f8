"""GLC-UniPS encoder: convolutional stem, Swin backbone, pre-fusion communication, UPerNet fusion.

Per image, the encoder sees `[I * M, M]` (4 channels) at the canonical resolution s and returns a
global lighting context map of `context_dim` channels at s / 4. Images only interact in the
pre-fusion communication layers (one Transformer layer per backbone scale, applied at every
location across the K images).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .layers import TransformerLayer
from .net_config import GLCConfig

# timm builder used for the backbone; its architecture arguments are overridden from GLCConfig
# (with GLCConfig's defaults it is exactly Swin-S). Never built with pretrained weights.
TIMM_SWIN = "swin_small_patch4_window7_224"


class LayerNorm2d(nn.LayerNorm):
    """LayerNorm over channels at each location of an NCHW map (no statistics across images)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return super().forward(x.permute(0, 2, 3, 1)).permute(0, 3, 1, 2)


def conv_norm_act(cin: int, cout: int, kernel: int, stride: int = 1) -> nn.Sequential:
    """Convolution, channel LayerNorm, ReLU."""
    return nn.Sequential(
        nn.Conv2d(cin, cout, kernel, stride=stride, padding=kernel // 2, bias=False),
        LayerNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class ConvStem(nn.Module):
    """Five convolutions replacing Swin's patch embedding: `(N, 4, s, s) -> (N, s/4, s/4, E)` (NHWC)."""

    def __init__(self, in_chans: int, embed_dim: int, hidden: int) -> None:
        super().__init__()
        self.convs = nn.Sequential(
            conv_norm_act(in_chans, hidden, 3),
            conv_norm_act(hidden, hidden, 3, stride=2),
            conv_norm_act(hidden, embed_dim, 3),
            conv_norm_act(embed_dim, embed_dim, 3, stride=2),
            nn.Conv2d(embed_dim, embed_dim, 1),
        )
        self.norm = nn.LayerNorm(embed_dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.norm(self.convs(x).permute(0, 2, 3, 1))  # (N, s/4, s/4, E)


def build_backbone(cfg: GLCConfig) -> nn.Module:
    """timm Swin with `features_only` and our stem; returns NHWC maps at strides 4, 8, 16, 32."""
    import timm

    backbone = timm.create_model(
        TIMM_SWIN,
        pretrained=False,
        features_only=True,
        in_chans=4,
        img_size=cfg.canonical_resolution,
        embed_dim=cfg.swin_embed_dim,
        depths=cfg.swin_depths,
        num_heads=cfg.swin_heads,
        window_size=cfg.swin_window,
        drop_path_rate=cfg.swin_drop_path,
    )
    hidden = cfg.stem_channels or max(cfg.swin_embed_dim // 2, 4)
    # Same key, so the FeatureListNet keeps calling it first.
    backbone.patch_embed = ConvStem(4, cfg.swin_embed_dim, hidden)
    return backbone


class PreFusionCommunication(nn.Module):
    """One Transformer layer per scale across the K images at every location."""

    def __init__(self, cfg: GLCConfig) -> None:
        super().__init__()
        self.layers = nn.ModuleList(
            TransformerLayer(c, cfg.comm_heads, int(round(cfg.comm_ff_ratio * c)), cfg.dropout)
            for c in cfg.stage_channels
        )

    def forward(self, feats: list[torch.Tensor], batch: int) -> list[torch.Tensor]:
        """feats: NHWC maps `(B*K, h, w, C)`; returns NCHW maps `(B*K, C, h, w)`."""
        out = []
        for f, layer in zip(feats, self.layers):
            bk, h, w, c = f.shape
            k = bk // batch
            x = f.reshape(batch, k, h, w, c).permute(0, 2, 3, 1, 4).reshape(batch * h * w, k, c)
            x = layer(x)  # (B*h*w, K, C)
            x = x.reshape(batch, h, w, k, c).permute(0, 3, 4, 1, 2).reshape(bk, c, h, w)
            out.append(x)
        return out


class UPerNetFusion(nn.Module):
    """Pyramid pooling on the coarsest map + FPN; fuses the four scales at stride 4 to `context_dim`."""

    def __init__(self, in_channels: tuple[int, ...], channels: int, scales: tuple[int, ...]) -> None:
        super().__init__()
        top = in_channels[-1]
        self.scales = scales
        self.ppm = nn.ModuleList(
            nn.Sequential(nn.Conv2d(top, channels, 1), nn.ReLU(inplace=True)) for _ in scales
        )
        self.ppm_bottleneck = conv_norm_act(top + len(scales) * channels, channels, 3)
        self.lateral = nn.ModuleList(conv_norm_act(c, channels, 1) for c in in_channels[:-1])
        self.fpn = nn.ModuleList(conv_norm_act(channels, channels, 3) for _ in in_channels[:-1])
        self.fuse = conv_norm_act(len(in_channels) * channels, channels, 3)

    def forward(self, feats: list[torch.Tensor]) -> torch.Tensor:
        """feats: NCHW maps at strides 4..32; returns `(N, channels, h4, w4)`."""
        top = feats[-1]
        size = top.shape[-2:]
        pooled = [top] + [
            F.interpolate(branch(F.adaptive_avg_pool2d(top, s)), size=size, mode="bilinear",
                          align_corners=False)
            for s, branch in zip(self.scales, self.ppm)
        ]
        levels = [lat(f) for lat, f in zip(self.lateral, feats[:-1])] + [self.ppm_bottleneck(torch.cat(pooled, 1))]
        # Top-down pathway.
        for i in range(len(levels) - 1, 0, -1):
            levels[i - 1] = levels[i - 1] + F.interpolate(
                levels[i], size=levels[i - 1].shape[-2:], mode="bilinear", align_corners=False)
        outs = [conv(x) for conv, x in zip(self.fpn, levels[:-1])] + [levels[-1]]
        size0 = outs[0].shape[-2:]
        outs = [outs[0]] + [F.interpolate(x, size=size0, mode="bilinear", align_corners=False) for x in outs[1:]]
        return self.fuse(torch.cat(outs, 1))


class GLCEncoder(nn.Module):
    """`(B, K, 3, s, s)` images and `(B, 1, s, s)` mask at the canonical size -> `(B, K, C, s/4, s/4)`."""

    def __init__(self, cfg: GLCConfig) -> None:
        super().__init__()
        self.backbone = build_backbone(cfg)
        self.communication = PreFusionCommunication(cfg)
        self.fusion = UPerNetFusion(cfg.stage_channels, cfg.context_dim, cfg.ppm_scales)

    def forward(self, images: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        b, k, _, s, _ = images.shape
        m = mask[:, None].expand(b, k, 1, s, s)  # (B, K, 1, s, s)
        x = torch.cat([images * m, m], dim=2).reshape(b * k, 4, s, s)
        feats = self.backbone(x)  # 4 x (B*K, h, w, C) channels last
        feats = self.communication(feats, b)  # 4 x (B*K, C, h, w)
        ctx = self.fusion(feats)  # (B*K, Cctx, s/4, s/4)
        return ctx.reshape(b, k, *ctx.shape[1:])
