"""Photometric-stereo networks behind a name registry: `create_model("glc-tiny", pretrained=True)`, ...

`registry.py` maps names to factories and to shipped weights, `zoo.py` registers the configurations,
`builder.py` builds a model (fresh, shipped weights, or a model file) and reads / writes model files.
"""

from .builder import create_model, load_model, save_checkpoint
from .config import GLCConfig
from .glc import GLCUniPS
from .registry import Pretrained, list_models, list_pretrained, pretrained_entry, pretrained_weights, register_model
from .zoo import DEFAULT_MODEL  # importing zoo registers the built-in configurations

__all__ = ["DEFAULT_MODEL", "GLCConfig", "GLCUniPS", "Pretrained", "create_model", "list_models", "list_pretrained",
           "load_model", "pretrained_entry", "pretrained_weights", "register_model", "save_checkpoint"]
