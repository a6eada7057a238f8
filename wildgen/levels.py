"""Complexity levels: `GenConfig` instances from simple scenes to complex ones (`wildgen.make --level N`).

PS-Verse (LINO-UniPS) groups its scenes by complexity and trains from simple to complex; `LEVELS` is this
toolkit's table of such groups, and `unips.train --curriculum` uses the level recorded in each scene.json.
Like a capture preset (`wildgen.presets`), a level is written as the configuration that makes its scenes and
sets the fields that differ from the defaults (flags given on the command line keep their values); it names
only entries of the existing tables. The docs' table is generated from it (`orchestrate.docs`, block
`generator:levels`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from wildgen.config import PROCEDURAL_KINDS, GenConfig
from wildgen.presets import changed_fields, fill_unless_given


@dataclass(frozen=True)
class Level:
    """One complexity level: what its scenes hold and the configuration that makes them."""

    about: str
    """What its scenes hold (for the docs)."""
    config: GenConfig
    """The configuration of its scenes (shapes, shape kinds, materials, light families cycled across objects,
    detail, cluster); the level sets the fields that differ from the defaults."""

    def overrides(self) -> dict[str, Any]:
        """The `GenConfig` field values this level sets."""
        return changed_fields(self.config)


LEVELS: dict[int, Level] = {
    1: Level("one convex shape (a superellipsoid), diffuse, one distant light per image",
             GenConfig(shapes="procedural", shape_kinds=["superquadric"], materials="diffuse", lights=["directional"],
                       detail=0.0)),
    2: Level("one smooth procedural shape (superellipsoid, blob, bumpy sphere), glossy plastic, a distant or a near "
             "point light",
             GenConfig(shapes="procedural", shape_kinds=["superquadric", "blob", "bumpy_sphere"], materials="specular",
                       lights=["directional", "point"], detail=0.0)),
    3: Level("one shape of any kind (meshes with concavities when --assets has them, tori), any material with "
             "spatially varying maps, near point and area lights or an environment map, detail on a third of the "
             "objects",
             GenConfig(shapes="any", shape_kinds=list(PROCEDURAL_KINDS), materials="any",
                       lights=["point", "near_area", "hdri"], detail=0.3)),
    4: Level("one or two touching objects, any material, mixed lights (environment map plus a near light) or "
             "PS-Verse combinations, detail on half of them",
             GenConfig(shapes="any", shape_kinds=list(PROCEDURAL_KINDS), materials="any",
                       lights=["mixed", "verse", "near_area"], detail=0.5, cluster="1-2")),
    5: Level("clusters of 2 to 4 objects with cast shadows and inter-reflections between them, any material, "
             "PS-Verse combinations, mixed and frontal-only lights, detail on most",
             GenConfig(shapes="any", shape_kinds=list(PROCEDURAL_KINDS), materials="any",
                       lights=["verse", "mixed", "near_area", "flash"], detail=0.7, cluster="2-4")),
}
"""The complexity levels, simplest first; their numbers are `wildgen.config.LEVEL_NUMBERS`, the values --level
accepts (tests/test_tables.py checks that the two agree and that each level names only existing entries)."""


def _flag_value(value: Any) -> str:
    return ",".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)


def check_level_and_preset(cfg: GenConfig, given: set[str]) -> None:
    """--level and --preset together: refused (ValueError, one line) where both set one field to different values
    that the user did not choose with its own flag (e.g. --level 5 --preset diligent: the level's light families
    or the preset's directional lights); elsewhere each sets its own fields."""
    if cfg.level is None or cfg.preset is None:
        return
    from wildgen.presets import preset_named

    level, preset = LEVELS[cfg.level].overrides(), preset_named(cfg.preset).overrides()
    given = set(given) | ({"width", "height"} if "res" in given else set())
    both = [k for k in level if k in preset and k not in given and level[k] != preset[k]]
    if both:
        flag = "--" + both[0].replace("_", "-")
        raise ValueError(f"--level: level {cfg.level} sets {flag} {_flag_value(level[both[0]])} and --preset "
                         f"{cfg.preset} sets {flag} {_flag_value(preset[both[0]])}; give {flag} to choose, or leave "
                         "out --level or --preset")


def apply_level(cfg: GenConfig, given: set[str]) -> set[str]:
    """Set the values of level `cfg.level` on the fields of `cfg` not in `given` (the flags the user gave keep
    their values). Returns the names of the fields it set; nothing happens when `cfg.level` is None."""
    if cfg.level is None:
        return set()
    if cfg.level not in LEVELS:
        raise ValueError(f"--level: unknown level {cfg.level!r}, expected one of {', '.join(map(str, LEVELS))}")
    return fill_unless_given(cfg, LEVELS[cfg.level].overrides(), given)
