"""Configuration of the published UniPS network (Ikehata, "Universal Photometric Stereo Network using Global
Lighting Contexts", CVPR 2022): one dataclass, plain JSON-able values.

The defaults are the published network, whose weights load into it (`unips.models.official`); smaller instances of
the same code (`glc-unips-tiny`) exist for tests. Our own reading of the paper, trained here on the CPU (glc-tiny,
glc-small), is another network: `config.py` (`GLCConfig`).
"""

from __future__ import annotations

from dataclasses import dataclass

from .config_base import ModelConfig


@dataclass
class UniPS22Config(ModelConfig):
    """Hyper-parameters of a published-UniPS network; `dataclasses.asdict` round-trips through JSON."""

    canonical_resolution: int = 256
    """Side of the square the encoder sees: the images (bilinear) and the mask (nearest) are resized to it from the
    working side (the published test run: 256, from 512). A multiple of 32 (stem stride 4, three patch mergings)."""
    swin_embed_dim: int = 96
    """Channels of the first Swin stage (Swin-S: 96; the stem's hidden convolutions have half)."""
    swin_depths: tuple[int, ...] = (2, 2, 18, 2)
    """Swin blocks per stage (Swin-S: 2, 2, 18, 2)."""
    swin_heads: tuple[int, ...] = (3, 6, 12, 24)
    """Attention heads per Swin stage (Swin-S: 3, 6, 12, 24)."""
    swin_window: int = 7
    """Window side; maps are padded to whole windows, never shrunk (as published)."""
    swin_drop_path: float = 0.2
    """Stochastic-depth rate of the last Swin block, linear from 0 over the blocks (training only)."""
    heads: int = 8
    """Heads of the attention across images, in the encoder (per scale) and in the pixel decoder."""
    context_dim: int = 256
    """Channels of the global lighting contexts (the UPerNet output, at a quarter of the canonical side)."""
    ppm_scales: tuple[int, ...] = (1, 2, 3, 6)
    """Output sizes of the pyramid-pooling module of the UPerNet head."""
    aggregation_dim: int = 384
    """Width of the pixel decoder: per pixel, attention across its K observations (RGB + sampled context), then
    pooling by a learned seed into one feature."""
    aggregation_layers: int = 3
    """Self-attention layers of the pixel decoder beyond its first (the published --num_agg_enc, default 3)."""
    aggregation_ff: int = 1024
    """Feed-forward width of the pixel decoder's self-attention layers."""
    pooling_ff: int = 512
    """Feed-forward width of the seed pooling (fixed at 512 in the published network)."""
    dropout: float = 0.1
    """Dropout of the attention weights and feed-forward layers across images (training only)."""
    pixel_chunk: int = 10000
    """Most pixels decoded at once; bounds the decoder's memory. Pixels are decoded independently, so the result
    does not depend on it (the published test run splits the pixels into chunks of about 10000)."""

    POSITIVE = ("swin_window", "heads", "context_dim", "aggregation_ff", "pooling_ff", "pixel_chunk")
    NON_NEGATIVE = ("aggregation_layers",)
    PROBABILITIES = ("dropout", "swin_drop_path")

    def check(self) -> None:
        for name in ("swin_depths", "swin_heads"):
            if len(getattr(self, name)) != 4 or min(getattr(self, name)) < 1:
                raise self.bad(name, "4 positive values, one per Swin stage")
        if self.swin_embed_dim < 2 or self.swin_embed_dim % 2:
            raise self.bad("swin_embed_dim", "an even positive width (the stem halves it)")
        for c, h in zip(self.stage_channels, self.swin_heads):
            if c % h:
                raise self.bad("swin_heads", f"head counts dividing the stage widths {self.stage_channels}")
            if c % self.heads:
                raise self.bad("heads", f"a divisor of every stage width {self.stage_channels}")
        if self.aggregation_dim % self.heads or self.aggregation_dim % 2:
            raise self.bad("aggregation_dim", f"an even multiple of heads={self.heads} (the normal head halves it)")

    @property
    def stage_channels(self) -> tuple[int, ...]:
        """Channels of the four Swin stages."""
        return tuple(self.swin_embed_dim * 2 ** i for i in range(4))
