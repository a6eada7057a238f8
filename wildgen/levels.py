"""Complexity levels: named sets of `GenConfig` values from simple scenes to complex ones (`wildgen.make --level N`).

PS-Verse (LINO-UniPS) groups its scenes by complexity and trains from simple to complex; `LEVELS` is this
toolkit's table of such groups, and `unips.train --curriculum` uses the level recorded in each scene.json.
Like a capture preset (`wildgen.presets`), a level fills the dataset's configuration (flags given on the
command line keep their values) and names only entries of the existing tables. The docs' table is generated
from it (`orchestrate.docs`, block `generator:levels`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from wildgen.config import PROCEDURAL_KINDS
from wildgen.light_families import LIGHT_FAMILIES
from wildgen.presets import fill_unless_given


@dataclass(frozen=True)
class ComplexityLevel:
    """One complexity level: what its scenes hold and the `GenConfig` values that make them."""

    level: int
    """The value of --level (1 simplest)."""
    about: str
    """What its scenes hold (for the docs)."""
    shapes: str
    """`GenConfig.shapes`: procedural, mesh or any."""
    shape_kinds: tuple[str, ...]
    """Procedural shape kinds drawn (`GenConfig.shape_kinds`)."""
    materials: str
    """`GenConfig.materials`."""
    lights: tuple[str, ...]
    """Light families, cycled across objects."""
    detail: float
    """Fraction of objects with surface detail (`GenConfig.detail`)."""
    cluster: str | None
    """Objects per scene (`GenConfig.cluster`), None for one."""

    def overrides(self) -> dict[str, Any]:
        """The `GenConfig` field values this level sets."""
        return {"shapes": self.shapes, "shape_kinds": list(self.shape_kinds), "materials": self.materials,
                "lights": list(self.lights), "detail": self.detail, "cluster": self.cluster}


LEVELS: dict[int, ComplexityLevel] = {lv.level: lv for lv in (
    ComplexityLevel(1, "one convex shape (a superellipsoid), diffuse, one distant light per image",
                    "procedural", ("superquadric",), "diffuse", ("directional",), 0.0, None),
    ComplexityLevel(2, "one smooth procedural shape (superellipsoid, blob, bumpy sphere), glossy plastic, a distant or "
                    "a near point light", "procedural", ("superquadric", "blob", "bumpy_sphere"), "specular",
                    ("directional", "point"), 0.0, None),
    ComplexityLevel(3, "one shape of any kind (meshes with concavities when --assets has them, tori), any material "
                    "with spatially varying maps, near point and area lights or an environment map, detail on a "
                    "third of the objects", "any", PROCEDURAL_KINDS, "any", ("point", "near_area", "hdri"), 0.3, None),
    ComplexityLevel(4, "one or two touching objects, any material, mixed lights (environment map plus a near light) "
                    "or PS-Verse combinations, detail on half of them", "any", PROCEDURAL_KINDS, "any",
                    ("mixed", "verse", "near_area"), 0.5, "1-2"),
    ComplexityLevel(5, "clusters of 2 to 4 objects with cast shadows and inter-reflections between them, any material, "
                    "PS-Verse combinations, mixed and frontal-only lights, detail on most", "any", PROCEDURAL_KINDS, "any",
                    ("verse", "mixed", "near_area", "flash"), 0.7, "2-4"),
)}
"""The complexity levels, simplest first."""

for _lv in LEVELS.values():  # a level names only entries of the existing tables
    assert all(f in LIGHT_FAMILIES for f in _lv.lights) and set(_lv.shape_kinds) <= set(PROCEDURAL_KINDS), _lv.level


def apply_level(cfg: Any, given: set[str]) -> set[str]:
    """Set the values of level `cfg.level` (a `GenConfig`) on the fields not in `given` (the flags the user gave
    keep their values). Returns the names of the fields it set; nothing happens when `cfg.level` is None."""
    if cfg.level is None:
        return set()
    if cfg.level not in LEVELS:
        raise ValueError(f"--level: unknown level {cfg.level!r}, expected one of {', '.join(map(str, LEVELS))}")
    return fill_unless_given(cfg, LEVELS[cfg.level].overrides(), given)
