"""What the tests of the published networks share (tests/test_glc_unips.py, tests/test_sdm_unips.py): the authors'
code from ../shared/reference imported as a package of its own, seeded weights, the angle between normal maps."""

from __future__ import annotations

import importlib
import sys
import types
from pathlib import Path

import pytest
import torch


def reference_module(root: Path, alias: str, module: str):
    """Module `module` (e.g. "model.model") of the authors' package at `root` (a folder named `modules`, which
    would clash with other packages of that name), imported as package `alias`; skips when `root` is absent."""
    if not root.is_dir():
        pytest.skip(f"{root} is not present (the reference code lives in ../shared/reference)")
    if alias not in sys.modules:
        package = types.ModuleType(alias)
        package.__path__ = [str(root)]  # a namespace package: its relative imports resolve inside it
        sys.modules[alias] = package
    return importlib.import_module(f"{alias}.{module}")


def randomise(net: torch.nn.Module, seed: int) -> None:
    """Seeded values in every tensor, scaled so activations stay of order one; unlike the published
    initialisation, layer scales, norms and seeds are far from 0 or 1 or uninitialised memory, so every path counts."""
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for name, p in net.named_parameters():
            noise = torch.randn(p.shape, generator=g)
            if p.ndim >= 2:
                p.copy_(noise * p[0].numel() ** -0.5)
            elif name.endswith("weight") or name.endswith("gamma"):
                p.copy_(1.0 + 0.1 * noise)
            else:
                p.copy_(0.1 * noise)


def angle_deg(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Angles between `(B, 3, H, W)` normal maps; atan2 in float64 (acos of a float32 dot product near 1 is
    off by hundredths of a degree)."""
    a, b = a.double(), b.double()
    return torch.rad2deg(torch.atan2(torch.linalg.cross(a, b, dim=1).norm(dim=1), (a * b).sum(dim=1)))


def load_error(path: Path, name: str) -> str:
    """The message with which `create_model(name, checkpoint_path=path)` refuses a published checkpoint, checked to
    be one line."""
    from unips.models import create_model

    with pytest.raises((ValueError, FileNotFoundError)) as err:
        create_model(name, checkpoint_path=path)
    text = str(err.value)
    assert "\n" not in text
    return text
