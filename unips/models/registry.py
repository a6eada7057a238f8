"""Model registry: each name maps to a factory (fresh weights from config overrides) and, optionally, to
its shipped weights and model card (a pretrained entry, as timm's registry keeps per-model weight sources), and,
for the published networks, to the authors' checkpoint files (an official entry, `unips.models.official`). Each
entry carries its data contract (`unips.models.contract.InputContract`, as timm's pretrained_cfg carries its input
size and normalisation); a model with neither entry gets ours (`UNIPS_INPUTS`): `input_contract(name)`.

`unips.models.create_model` (in `builder.py`) is the one entry point that builds a model: fresh, from
the shipped weights (`pretrained=True`) or from a weights file (`checkpoint_path=`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from torch import nn

from scenes.files import read_figures

from .contract import UNIPS_INPUTS, InputContract
from .official import OfficialWeights

ModelFactory = Callable[..., nn.Module]

WEIGHTS_DIR = Path(__file__).resolve().parents[1] / "weights"
"""The folder of shipped weights inside the package (`unips/weights/`)."""


@dataclass(frozen=True)
class Pretrained:
    """Where the shipped weights of a registered model live: file names inside `unips/weights/`.

    `orchestrate.train_recipe --ship` writes exactly these files; `create_model(name, pretrained=True)`
    reads them. An entry may name files that are not shipped (yet): loading them is then an error,
    never a fallback to fresh weights.
    """

    weights: str
    """The `.safetensors` file; its `.json` sidecar (model name and config) lies next to it."""
    card: str
    """The model card (JSON): data recipe, training, validation and test figures, lineage, weaknesses."""
    inputs: InputContract = UNIPS_INPUTS
    """What the weights expect of their inputs, with the resolution they were trained at (`train_resolution`, the
    same as the `.json` sidecar's `extra.train_args.res`, which is kept for provenance and never read)."""

    @property
    def weights_path(self) -> Path:
        return WEIGHTS_DIR / self.weights

    @property
    def card_path(self) -> Path:
        return WEIGHTS_DIR / self.card


_REGISTRY: dict[str, ModelFactory] = {}
_PRETRAINED: dict[str, Pretrained] = {}
_OFFICIAL: dict[str, OfficialWeights] = {}


def register_model(name: str, pretrained: Pretrained | None = None,
                   official: OfficialWeights | None = None) -> Callable[[ModelFactory], ModelFactory]:
    """Decorator registering `factory(**overrides) -> nn.Module` under `name`, with the place of its shipped
    weights and the layout of the authors' published checkpoint when it has them (each with its data contract;
    both must then agree on it)."""
    if pretrained is not None and official is not None and pretrained.inputs != official.inputs:
        raise ValueError(f"model {name!r}: its pretrained and official entries have different input contracts")

    def deco(factory: ModelFactory) -> ModelFactory:
        if name in _REGISTRY:
            raise ValueError(f"model name {name!r} is already registered")
        _REGISTRY[name] = factory
        if pretrained is not None:
            _PRETRAINED[name] = pretrained
        if official is not None:
            _OFFICIAL[name] = official
        return factory
    return deco


def list_models() -> list[str]:
    """Registered model names, sorted."""
    return sorted(_REGISTRY)


def list_pretrained() -> list[str]:
    """Names whose shipped weights file is present in the package, sorted."""
    return sorted(n for n, p in _PRETRAINED.items() if p.weights_path.is_file())


def _check_name(name: str) -> None:
    if name not in _REGISTRY:
        raise ValueError(f"model name {name!r} is not registered; known models: {', '.join(list_models())}")


def pretrained_entry(name: str) -> Pretrained:
    """The pretrained entry of `name`; ValueError when the name is unknown or has no entry."""
    _check_name(name)
    if name not in _PRETRAINED:
        with_entry = ", ".join(sorted(_PRETRAINED)) or "none"
        raise ValueError(f"pretrained: model {name!r} has no shipped-weights entry in the registry "
                         f"(models with one: {with_entry})")
    return _PRETRAINED[name]


def input_contract(name: str) -> InputContract:
    """The data contract of model `name`: its pretrained entry's, else its official entry's, else ours
    (`UNIPS_INPUTS`); ValueError when the name is unknown."""
    _check_name(name)
    entry = _PRETRAINED.get(name) or _OFFICIAL.get(name)
    return entry.inputs if entry is not None else UNIPS_INPUTS


def official_entry(name: str) -> OfficialWeights:
    """The published-checkpoint entry of `name`; ValueError when the name is unknown or has none."""
    _check_name(name)
    if name not in _OFFICIAL:
        with_entry = ", ".join(sorted(_OFFICIAL)) or "none"
        raise ValueError(f"--checkpoint: model {name!r} has no published checkpoint format to read (models with "
                         f"one: {with_entry}); pass a .safetensors or .pt model file")
    return _OFFICIAL[name]


def pretrained_weights(name: str) -> Path:
    """Path of the shipped weights of `name`; FileNotFoundError (one line, what to do instead) when the entry's
    file is not in the package."""
    path = pretrained_entry(name).weights_path
    if not path.is_file():
        raise FileNotFoundError(f"no shipped weights for {name!r} yet (unips/weights/{path.name} is missing); "
                                "pass --checkpoint PATH to a .safetensors or .pt model file")
    return path


def build_model(name: str, **overrides: Any) -> nn.Module:
    """The registry's factory call: model `name` with fresh weights and config fields replaced by `overrides`.

    Unknown names and unknown override keys raise ValueError. The returned module carries `model_name`
    (this name) and `config` (its full configuration dataclass). Use `create_model`, which also loads weights.
    """
    _check_name(name)
    model = _REGISTRY[name](**overrides)
    model.model_name = name
    return model


def read_model_card(path: Path) -> dict[str, Any]:
    """A model card (the JSON object beside shipped weights: figures, lineage), {} when there is none. A damaged
    one (truncated, not JSON, not an object) is a ValueError naming the file, never a bare JSON error."""
    if not path.is_file():
        return {}
    try:
        card = read_figures(path)
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise ValueError(f"model card {str(path)!r} is not readable JSON ({exc}; truncated?); expected the card as "
                         "written (restore it, e.g. git checkout)") from None
    if not isinstance(card, dict):
        raise ValueError(f"model card {str(path)!r} holds a JSON {type(card).__name__}, expected an object")
    return card
