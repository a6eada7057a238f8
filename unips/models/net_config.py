"""Configuration of the GLC-UniPS family of networks (one dataclass, plain JSON-able values)."""

from __future__ import annotations

from dataclasses import dataclass

from .config_base import ModelConfig

# Decoder pixel-token kinds and their channel counts (see GLCConfig.pixel_token).
PIXEL_TOKENS = {"rgb": 3, "normalized": 6}


@dataclass
class GLCConfig(ModelConfig):
    """Hyper-parameters of a GLC-UniPS network; `dataclasses.asdict` round-trips through JSON."""

    canonical_resolution: int = 256
    """Side of the square the encoder sees; images and mask are resized to it. Multiple of 32 (patch 4 in the
    stem, then three 2x patch mergings)."""
    swin_embed_dim: int = 96
    """Swin backbone (built by timm, never with pretrained weights): channels of the first stage."""
    swin_depths: tuple[int, ...] = (2, 2, 18, 2)
    """Swin blocks per stage (Swin-S: 2, 2, 18, 2)."""
    swin_heads: tuple[int, ...] = (3, 6, 12, 24)
    """Attention heads per stage (Swin-S: 3, 6, 12, 24)."""
    swin_window: int = 7
    """Swin window side; timm shrinks it on stages whose feature map is smaller."""
    swin_drop_path: float = 0.1
    """Stochastic-depth rate of the backbone (timm's default for Swin)."""
    stem_channels: int = 0
    """Hidden channels of the convolutional stem (five convolutions to 1/4 resolution); 0 means half the
    embedding dimension."""
    comm_heads: int = 8
    """Heads of the pre-fusion communication layer (one Transformer layer per scale, across images)."""
    comm_ff_ratio: float = 2.0
    """Feed-forward width of the communication layer as a multiple of the scale's channels."""
    context_dim: int = 256
    """Channels of the global lighting contexts (UPerNet output, at canonical / 4)."""
    ppm_scales: tuple[int, ...] = (1, 2, 3, 6)
    """Output sizes of the pyramid-pooling module of the UPerNet head."""
    decoder_dim: int = 384
    """Width of the per-pixel decoder (tokens: one per image, RGB + context projected to this)."""
    decoder_layers: int = 3
    """Self-attention layers across images in the decoder."""
    decoder_heads: int = 8
    """Heads of the decoder's self-attention layers and of the PMA pooling."""
    decoder_ff: int = 1024
    """Feed-forward width of the decoder's Transformer layers (and of the PMA block)."""
    predictor_hidden: int = 192
    """Hidden width of the normal predictor MLP (decoder_dim -> predictor_hidden -> 3)."""
    dropout: float = 0.1
    """Dropout in the communication and decoder Transformer layers (paper: 0.1)."""
    uniform_context: bool = False
    """Ablation "trivial context": contexts averaged over the masked area, the same at every pixel."""
    pixel_chunk: int = 10000
    """Pixels decoded at once in `forward`; bounds decoder memory independently of the resolution."""
    pixel_token: str = "rgb"
    """What the decoder sees of a pixel's own observations, per image: "rgb" (the paper: the raw value), or
    "normalized": log(1 + RGB) and RGB divided by the pixel's mean intensity over the K images, so that
    comparing one pixel's observations across images is a first-layer feature."""
    mask_before_resize: bool = False
    """Multiply the images by the mask before resizing them to the canonical resolution, so that background
    pixels never bleed into the object's border (old checkpoints: False)."""

    POSITIVE = ("swin_embed_dim", "swin_window", "comm_heads", "context_dim", "decoder_dim", "decoder_heads",
                "decoder_ff", "predictor_hidden", "pixel_chunk")
    NON_NEGATIVE = ("decoder_layers",)
    PROBABILITIES = ("dropout", "swin_drop_path")

    def check(self) -> None:
        if len(self.swin_depths) != 4 or min(self.swin_depths) < 1:
            raise self.bad("swin_depths", "4 positive stage depths")
        if len(self.swin_heads) != 4 or min(self.swin_heads) < 1:
            raise self.bad("swin_heads", "4 positive head counts")
        for i, h in enumerate(self.swin_heads):
            if (self.swin_embed_dim * 2 ** i) % h:
                raise self.bad("swin_heads", f"head counts dividing the stage widths {self.stage_channels}")
        for c in self.stage_channels:
            if c % self.comm_heads:
                raise self.bad("comm_heads", f"a divisor of every stage width {self.stage_channels}")
        if self.decoder_dim % self.decoder_heads:
            raise self.bad("decoder_heads", f"a divisor of decoder_dim={self.decoder_dim}")
        if self.pixel_token not in PIXEL_TOKENS:
            raise self.bad("pixel_token", f"one of {', '.join(PIXEL_TOKENS)}")
        if self.stem_channels < 0:
            raise self.bad("stem_channels", "0 (automatic) or a positive integer")

    @property
    def stage_channels(self) -> tuple[int, int, int, int]:
        """Channels of the four backbone stages."""
        e = self.swin_embed_dim
        return (e, 2 * e, 4 * e, 8 * e)

    @property
    def pixel_token_channels(self) -> int:
        """Channels of a pixel's own observation per image in the decoder's tokens."""
        return PIXEL_TOKENS[self.pixel_token]

