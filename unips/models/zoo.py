"""The registered configurations, their entries' data contracts, and the default model name of each purpose
(`DEFAULT_MODEL` to predict, `DEFAULT_TRAIN_MODEL` to train).

- The published networks, whose authors' checkpoint files load (`official=`) and whose inputs get the authors'
  preprocessing (the official entry's `inputs`): UniPS, CVPR 2022 (`glc-unips`, `unips22.py`) and SDM-UniPS, CVPR 2023
  (`sdm-unips`, `sdm.py`), each with a tiny instance of the same code for tests.
- Our own reading of the UniPS paper (`glc.py`, `GLCConfig`: timm's Swin, pre-norm Transformer layers, our
  preprocessing), not weight-compatible with the published one: the CPU-trained `glc-tiny` (shipped) and
  `glc-small`, `glc-base` at the paper's size, `glc-test` for tests.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from .config_base import config_with_overrides
from .contract import GLC_UNIPS_INPUTS, SDM_UNIPS_INPUTS, UNIPS_INPUTS
from .glc import GLCUniPS
from .net_config import GLCConfig
from .official import OfficialWeights
from .registry import Pretrained, register_model
from .sdm import SDMUniPS
from .sdm_config import SDMConfig
from .unips22 import UniPS22
from .unips22_config import UniPS22Config

# Our reading of the paper's "base + pre-fusion" network at its size: Swin-S, canonical 256, contexts 64x64x256
# (about 69 M); never trained here, and not the published network (that is glc-unips).
GLC_BASE = GLCConfig()

# Same structure, small enough to train on a 2-core CPU in about an hour.
GLC_TINY = GLCConfig(
    canonical_resolution=64,
    swin_embed_dim=24,
    swin_depths=(1, 1, 2, 1),
    swin_heads=(1, 2, 4, 8),
    swin_window=4,
    swin_drop_path=0.0,
    comm_heads=4,
    context_dim=32,
    decoder_dim=32,
    decoder_layers=2,
    decoder_heads=2,
    decoder_ff=64,
    predictor_hidden=32,
    dropout=0.0,
)

# The CPU model that reads the light (issue 12): per-pixel tokens normalised across the images, a
# decoder with real capacity (width 64, 3 layers), 24x24 lighting contexts from a canonical
# resolution of 96 that stays below the 128 px working resolution, masking before resizing; the
# backbone is glc-tiny's.
GLC_SMALL = dataclasses.replace(
    GLC_TINY,
    canonical_resolution=96,
    swin_window=3,
    context_dim=48,
    decoder_dim=64,
    decoder_layers=3,
    decoder_heads=4,
    decoder_ff=128,
    predictor_hidden=64,
    pixel_token="normalized",
    mask_before_resize=True,
)

# Unit tests: a forward pass at 32x32 in milliseconds.
GLC_TEST = GLCConfig(
    canonical_resolution=32,
    swin_embed_dim=8,
    swin_depths=(1, 1, 1, 1),
    swin_heads=(1, 2, 2, 4),
    swin_window=4,
    swin_drop_path=0.0,
    comm_heads=2,
    context_dim=16,
    ppm_scales=(1, 2),
    decoder_dim=16,
    decoder_layers=1,
    decoder_heads=2,
    decoder_ff=32,
    predictor_hidden=8,
    dropout=0.0,
    pixel_chunk=4096,
)


@register_model("glc-base")
def glc_base(**overrides: Any) -> GLCUniPS:
    """Our reading of GLC-UniPS at the paper's size (Swin-S backbone, pre-fusion communication); untrained."""
    return GLCUniPS(config_with_overrides(GLC_BASE, overrides))


DEFAULT_MODEL = "glc-tiny"
"""The model to predict with, the shipped one: what `unips.predict`, `orchestrate.benchmark`, `orchestrate.demo`
and `orchestrate.capture` run without `--checkpoint` (its weights: `create_model(DEFAULT_MODEL, pretrained=True)`)."""
DEFAULT_TRAIN_MODEL = "glc-small"
"""The model to train by default: `unips.train --model`, `orchestrate.train_recipe --model` and
`orchestrate.gpu_session` without `--init`."""

# The shipped glc-tiny was trained on 128 px renders (its sidecar records the same, extra.train_args.res, checked by
# tests/test_shipped_model.py); glc-small is sized for them too (orchestrate.train_recipe renders its data at 128).
TRAINED_AT_128 = dataclasses.replace(UNIPS_INPUTS, train_resolution=128)


@register_model("glc-tiny", pretrained=Pretrained(weights="glc-tiny.safetensors", card="model_card.json",
                                                  inputs=TRAINED_AT_128))
def glc_tiny(**overrides: Any) -> GLCUniPS:
    """Narrow GLC-UniPS for CPU training (canonical 64)."""
    return GLCUniPS(config_with_overrides(GLC_TINY, overrides))


@register_model("glc-small", pretrained=Pretrained(weights="glc-small.safetensors", card="glc-small.card.json",
                                                   inputs=TRAINED_AT_128))
def glc_small(**overrides: Any) -> GLCUniPS:
    """CPU-trainable GLC-UniPS with photometric pixel tokens and a wider decoder (canonical 96)."""
    return GLCUniPS(config_with_overrides(GLC_SMALL, overrides))


@register_model("glc-test")
def glc_test(**overrides: Any) -> GLCUniPS:
    """Minimal GLC-UniPS for unit tests (canonical 32)."""
    return GLCUniPS(config_with_overrides(GLC_TEST, overrides))


# SDM-UniPS as published (ConvNeXt-T, canonical 256, about 63 M): the authors' checkpoint loads into it.
SDM_UNIPS = SDMConfig()

SDM_OFFICIAL = OfficialWeights(
    files=(("normal/*.pytmodel", ""),),
    source="the authors' SDM-UniPS-CVPR2023 repository (github.com/satoshi-ikehata/SDM-UniPS-CVPR2023), README "
           "section 'Download Pretrained Models': checkpoint.zip, whose normal/nml.pytmodel is read",
    licence="MIT with a non-commercial clause (the SDM-UniPS licence)",
    inputs=SDM_UNIPS_INPUTS,
)

# Same code, small dims: a forward pass at 64 x 64 in a fraction of a second (tests).
SDM_TINY = SDMConfig(
    canonical_resolution=32,
    convnext_dims=(8, 16, 32, 64),
    convnext_depths=(1, 1, 1, 1),
    comm_layers=(0, 1, 1, 1),
    heads=2,
    context_dim=16,
    ppm_scales=(1, 2),
    upsample_dim=16,
    aggregation_dim=16,
    aggregation_layers=1,
    pooling_ff=16,
    ff_dim=32,
    dropout=0.0,
    pixel_samples=2048,
)


@register_model("sdm-unips", official=SDM_OFFICIAL)
def sdm_unips(**overrides: Any) -> SDMUniPS:
    """SDM-UniPS as published (Ikehata, CVPR 2023); `checkpoint_path=` the authors' checkpoint folder."""
    return SDMUniPS(config_with_overrides(SDM_UNIPS, overrides))


@register_model("sdm-unips-tiny", official=SDM_OFFICIAL)
def sdm_unips_tiny(**overrides: Any) -> SDMUniPS:
    """Minimal SDM-UniPS for unit tests (canonical 32); reads files in the published layout of its own size."""
    return SDMUniPS(config_with_overrides(SDM_TINY, overrides))


# UniPS as published (Swin-S with its stem, canonical 256, about 70 M): the authors' checkpoint loads into it.
GLC_UNIPS = UniPS22Config()

GLC_OFFICIAL = OfficialWeights(
    files=(("*_enc.pytmodel", "encoder."), ("*_agg.pytmodel", "aggregation."), ("*_pred.pytmodel", "prediction.")),
    source="the authors' Universal-PS-CVPR2022 repository (github.com/satoshi-ikehata/Universal-PS-CVPR2022), README "
           "section 'Download pretrained model': the checkpoint folder, whose *_enc, *_agg and *_pred.pytmodel are "
           "read",
    licence="GPL-3.0 (the Universal-PS-CVPR2022 licence)",
    inputs=GLC_UNIPS_INPUTS,
)

# Same code, small widths: a forward pass at 64 x 64 in a fraction of a second (tests).
GLC_UNIPS_TINY = UniPS22Config(
    canonical_resolution=32,
    swin_embed_dim=8,
    swin_depths=(1, 2, 1, 1),
    swin_heads=(1, 2, 2, 4),
    swin_window=4,
    swin_drop_path=0.0,
    heads=2,
    context_dim=16,
    ppm_scales=(1, 2),
    aggregation_dim=32,
    aggregation_layers=1,
    aggregation_ff=64,
    pooling_ff=32,
    dropout=0.0,
    pixel_chunk=2048,
)


@register_model("glc-unips", official=GLC_OFFICIAL)
def glc_unips(**overrides: Any) -> UniPS22:
    """UniPS as published (Ikehata, CVPR 2022); `checkpoint_path=` the authors' checkpoint folder."""
    return UniPS22(config_with_overrides(GLC_UNIPS, overrides))


@register_model("glc-unips-tiny", official=GLC_OFFICIAL)
def glc_unips_tiny(**overrides: Any) -> UniPS22:
    """Minimal published-UniPS network for unit tests (canonical 32); reads files in the published layout of its own
    size."""
    return UniPS22(config_with_overrides(GLC_UNIPS_TINY, overrides))
