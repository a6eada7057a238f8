"""The shipped model's recipe; it lives in `orchestrate.train_recipe` (this script keeps the old command).

    python bench/train_recipe.py --work /tmp/recipe [--ablation] [--ship]
    # same as: python -m orchestrate.train_recipe --work /tmp/recipe [--ablation] [--ship]
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, when run as a script

from orchestrate.train_recipe import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
