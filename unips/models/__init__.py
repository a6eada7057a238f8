"""Photometric-stereo networks behind a name registry: `create_model("glc-tiny", pretrained=True)`, ...

`registry.py` maps names to factories, to shipped weights and to the layout of published checkpoints, each entry with
its data contract (`contract.py`), `zoo.py` registers the configurations and names the default model of each purpose,
`builder.py` builds a model (fresh, shipped weights, a model file, or the authors' published files read by
`official.py`) and reads / writes model files; `config_base.py` is what the three configurations share. Our reading of
UniPS (glc-tiny, glc-small, glc-base, glc-test): `config.py`, `glc.py` (`encoder.py`, `decoder.py`, `layers.py`). The
published UniPS (glc-unips): `unips22_config.py`, `unips22.py` (`swin.py`); the published SDM-UniPS (sdm-unips):
`sdm_config.py`, `sdm.py` (`sdm_encoder.py`, `convnext.py`); what both published networks share: `uper.py`,
`set_attention.py`.
"""

from .builder import convert_official, create_model, load_model, load_official, save_checkpoint
from .contract import InputContract
from .glc import GLCUniPS
from .net_config import GLCConfig
from .official import OfficialWeights
from .registry import (
                       Pretrained,
                       input_contract,
                       list_models,
                       list_pretrained,
                       official_entry,
                       pretrained_entry,
                       pretrained_weights,
                       register_model,
)
from .sdm import SDMUniPS
from .sdm_config import SDMConfig
from .unips22 import UniPS22
from .unips22_config import UniPS22Config
from .zoo import DEFAULT_MODEL, DEFAULT_TRAIN_MODEL  # importing zoo registers the built-in configurations

__all__ = ["DEFAULT_MODEL", "DEFAULT_TRAIN_MODEL", "GLCConfig", "GLCUniPS", "InputContract", "OfficialWeights",
           "Pretrained", "SDMConfig", "SDMUniPS", "UniPS22", "UniPS22Config", "convert_official", "create_model",
           "input_contract", "list_models", "list_pretrained", "load_model", "load_official", "official_entry",
           "pretrained_entry", "pretrained_weights", "register_model", "save_checkpoint"]
