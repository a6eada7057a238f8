"""Photometric-stereo networks behind a name registry: `create_model("glc-tiny", pretrained=True)`, ...

`registry.py` maps names to factories, to shipped weights and to the layout of published checkpoints, `zoo.py`
registers the configurations, `builder.py` builds a model (fresh, shipped weights, a model file, or the authors'
published files read by `official.py`) and reads / writes model files. Our reading of UniPS (glc-tiny, glc-small,
glc-base, glc-test): `config.py`, `glc.py` (`encoder.py`, `decoder.py`, `layers.py`). The published UniPS (glc-unips):
`unips22_config.py`, `unips22.py` (`swin.py`); the published SDM-UniPS (sdm-unips): `sdm_config.py`, `sdm.py`
(`sdm_encoder.py`, `convnext.py`); what both published networks share: `uper.py`, `set_attention.py`.
"""

from .builder import convert_official, create_model, load_model, load_official, save_checkpoint
from .config import GLCConfig
from .glc import GLCUniPS
from .official import OfficialWeights
from .registry import (
                       Pretrained,
                       list_models,
                       list_pretrained,
                       model_inputs,
                       official_entry,
                       pretrained_entry,
                       pretrained_weights,
                       register_model,
)
from .sdm import SDMUniPS
from .sdm_config import SDMConfig
from .unips22 import UniPS22
from .unips22_config import UniPS22Config
from .zoo import DEFAULT_MODEL  # importing zoo registers the built-in configurations

__all__ = ["DEFAULT_MODEL", "GLCConfig", "GLCUniPS", "OfficialWeights", "Pretrained", "SDMConfig", "SDMUniPS",
           "UniPS22", "UniPS22Config", "convert_official", "create_model", "list_models", "list_pretrained",
           "load_model", "load_official", "model_inputs", "official_entry", "pretrained_entry", "pretrained_weights",
           "register_model", "save_checkpoint"]
