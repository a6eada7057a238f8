"""Configuration of the SDM-UniPS family of networks (Ikehata, CVPR 2023): one dataclass, plain JSON-able values.

The defaults are the published network, whose weights load into it (`unips.models.official`); smaller
instances of the same code (`sdm-unips-tiny`) exist for tests.
"""

from __future__ import annotations

from dataclasses import dataclass

from .config_base import ModelConfig


@dataclass
class SDMConfig(ModelConfig):
    """Hyper-parameters of an SDM-UniPS network; `dataclasses.asdict` round-trips through JSON."""

    canonical_resolution: int = 256
    """Side of the square the encoder's backbone sees. The input side must be a multiple of it: the images are
    seen once resized to it and once as (side / canonical)^2 interleaved sub-images of that size (the
    scale-invariant encoder). A multiple of 32 (the backbone's total stride)."""
    convnext_dims: tuple[int, ...] = (96, 192, 384, 768)
    """Channels of the four ConvNeXt stages (ConvNeXt-T: 96, 192, 384, 768)."""
    convnext_depths: tuple[int, ...] = (3, 3, 9, 3)
    """ConvNeXt blocks per stage (ConvNeXt-T: 3, 3, 9, 3)."""
    comm_layers: tuple[int, ...] = (0, 1, 2, 4)
    """Per backbone scale, the depth of the attention across images before the fusion: 0 is none, n > 0 is
    n + 1 self-attention layers (the published network: none at the finest scale, 2, 3 and 5 layers below)."""
    heads: int = 8
    """Heads of every attention layer."""
    context_dim: int = 256
    """Channels of the global lighting contexts (the UPerNet output, at a quarter of the input side)."""
    ppm_scales: tuple[int, ...] = (1, 2, 3, 6)
    """Output sizes of the pyramid-pooling module of the UPerNet head."""
    upsample_dim: int = 256
    """Width of the per-pixel attention across images that refines the sampled contexts ("GLC upsample")."""
    upsample_layers: int = 1
    """Self-attention layers of that block beyond its first (which maps RGB + context to `upsample_dim`)."""
    aggregation_dim: int = 384
    """Width of the per-pixel aggregation across images (self-attention, then pooling by a learned seed)."""
    aggregation_layers: int = 2
    """Self-attention layers of the aggregation beyond its first."""
    pooling_ff: int = 512
    """Feed-forward width of the pooling block (fixed at 512 in the published network)."""
    regressor_layers: int = 1
    """Self-attention layers across pixels (the pixel-sampling transformer) beyond its first."""
    ff_dim: int = 1024
    """Feed-forward width of the decoder's attention layers (upsample, aggregation, pixel-sampling)."""
    dropout: float = 0.1
    """Dropout of the attention weights and feed-forward layers (training only)."""
    pixel_samples: int = 10000
    """Most pixels decoded together: the masked pixels are shuffled and split into near-equal chunks of at most
    this many, and the pixel-sampling transformer attends across the pixels of a chunk (so the result depends
    on the chunks: the published value is 10000)."""
    context_smoothing: bool = True
    """Blur the context maps with a Gaussian (sigma 1 px, kernel 10 x input side / canonical + 1) before they
    are sampled at the pixels, as the published network does at test time."""

    POSITIVE = ("heads", "pooling_ff", "ff_dim", "pixel_samples")
    NON_NEGATIVE = ("upsample_layers", "aggregation_layers", "regressor_layers")

    def check(self) -> None:
        for name in ("convnext_dims", "convnext_depths", "comm_layers"):
            if len(getattr(self, name)) != 4:
                raise self.bad(name, "4 values, one per backbone stage")
        if min(self.convnext_dims) < 1 or min(self.convnext_depths) < 1:
            raise self.bad("convnext_dims" if min(self.convnext_dims) < 1 else "convnext_depths", "positive values")
        if min(self.comm_layers) < 0:
            raise self.bad("comm_layers", "non-negative layer counts")
        for c, n in zip(self.convnext_dims, self.comm_layers):
            if n and c % self.heads:
                raise self.bad("heads", f"a divisor of the stage widths with attention {self.convnext_dims}")
        for name in ("context_dim", "upsample_dim", "aggregation_dim"):
            if getattr(self, name) < 1 or getattr(self, name) % self.heads:
                raise self.bad(name, f"a positive multiple of heads={self.heads}")
        if self.aggregation_dim % 2:
            raise self.bad("aggregation_dim", "an even width (the normal head halves it)")
