"""Photometric-stereo networks behind a name registry (`create_model("glc-unips")`, ...)."""

from .config import GLCConfig
from .glc import GLCUniPS
from .registry import create_model, list_models, register_model
from . import zoo as _zoo  # registers the built-in configurations

__all__ = ["GLCConfig", "GLCUniPS", "create_model", "list_models", "register_model"]
