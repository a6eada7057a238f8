"""Model registry: names -> factories building `nn.Module`s from keyword overrides."""

from __future__ import annotations

from typing import Any, Callable

from torch import nn

ModelFactory = Callable[..., nn.Module]

_REGISTRY: dict[str, ModelFactory] = {}


def register_model(name: str) -> Callable[[ModelFactory], ModelFactory]:
    """Decorator registering `factory(**overrides) -> nn.Module` under `name`."""
    def deco(factory: ModelFactory) -> ModelFactory:
        if name in _REGISTRY:
            raise ValueError(f"model name {name!r} is already registered")
        _REGISTRY[name] = factory
        return factory
    return deco


def list_models() -> list[str]:
    """Registered model names, sorted."""
    return sorted(_REGISTRY)


def create_model(name: str, **overrides: Any) -> nn.Module:
    """Build the model registered as `name`, with config fields replaced by `overrides`.

    Unknown names and unknown override keys raise ValueError. The returned module carries
    `model_name` (this name) and `config` (its full configuration dataclass).
    """
    if name not in _REGISTRY:
        raise ValueError(f"model name {name!r} is not registered; known models: {', '.join(list_models())}")
    model = _REGISTRY[name](**overrides)
    model.model_name = name
    return model
