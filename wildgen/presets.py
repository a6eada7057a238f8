"""Capture presets: `GenConfig` instances that make a dataset look like one kind of real rig.

`PRESETS` is the one list (the way nerfstudio writes its method configs): each entry is the configuration of
its rig, written as a `GenConfig`, and `wildgen.make --preset NAME` takes from it every field it sets, that is
every field whose value differs from `GenConfig()`'s default (flags given on the command line keep their
values over the preset's). The docs' table of presets is generated from it (`orchestrate.docs`, block
`generator:presets`) and the tests check each entry against the configuration it produces. A preset holds
only names of the existing tables: a light family of `wildgen.light_families.LIGHT_FAMILIES` (a fixed light
pattern is such a family) and a sensor of `scenes.camera_sensor.SENSORS`.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from wildgen.config import GenConfig


def changed_fields(config: GenConfig) -> dict[str, Any]:
    """The fields of `config` whose values differ from `GenConfig()`'s defaults: what a preset or a level sets."""
    default = GenConfig()
    return {f.name: getattr(config, f.name) for f in fields(GenConfig)
            if getattr(config, f.name) != getattr(default, f.name)}


@dataclass(frozen=True)
class Preset:
    """One capture preset: what it imitates and the configuration that does it."""

    about: str
    """What rig it imitates and how (for the docs)."""
    config: GenConfig
    """The rig's configuration; the preset sets the fields that differ from the defaults."""

    def overrides(self) -> dict[str, Any]:
        """The `GenConfig` field values this preset sets."""
        return changed_fields(self.config)


PRESETS: dict[str, Preset] = {
    "diligent": Preset(
        "The DiLiGenT benchmark's rig: a camera with a long lens (orthographic here) and 96 LEDs on a planar grid in "
        "front of the object, one lit per image (the same angular span as DiLiGenT's), a machine-vision camera "
        "writing 16-bit PNG files (12 significant bits).",
        GenConfig(lights=["grid96"], images=96, width=612, height=512, camera="orthographic",
                  sensor="machine-vision")),
    "phone-flash": Preset(
        "A phone photographing an object with its flash on, in a dim room: perspective camera, a point light at "
        "the camera plus the room's ambient light, the phone's 8-bit sRGB files with demosaicing, noise and "
        "vignetting. Frontal light only: a hard case.",
        GenConfig(lights=["flash"], images=10, width=256, height=256, camera="perspective", sensor="phone")),
    "light-stage": Preset(
        "A light stage: many distant lights around the object, one at a time (image i of K lit by light i of K, "
        "spread evenly over the sphere but the cap behind the object), a machine-vision camera.",
        GenConfig(lights=["light_stage"], images=64, width=256, height=256, camera="orthographic",
                  sensor="machine-vision")),
    "display": Preset(
        "A computer screen as the light source, filmed by a webcam between the screen and the object: perspective "
        "camera, a 4 x 3 grid of screen patches 8 object radii in front of the object, one lit white per image, "
        "the webcam's 8-bit files.",
        GenConfig(lights=["display"], images=12, width=256, height=256, camera="perspective", sensor="webcam")),
}
"""The capture presets by name, in the order of --help and the docs' table. --preset lists the names from
`wildgen.config.PRESET_NAMES` (GenConfig cannot import its own instances); tests/test_tables.py checks that the
two agree and that each preset names only existing light families and sensors."""


def preset_named(name: str) -> Preset:
    """The entry of preset `name`; a ValueError naming --preset and the known presets otherwise."""
    if name not in PRESETS:
        raise ValueError(f"--preset: unknown preset {name!r}, expected one of {', '.join(PRESETS)}")
    return PRESETS[name]


def apply_preset(cfg: GenConfig, given: set[str]) -> set[str]:
    """Set the values of preset `cfg.preset` on the fields of `cfg` not in `given` (the flags the user gave:
    they keep their values; `res` stands for width and height). Returns the names of the fields it set.
    Nothing happens when `cfg.preset` is None."""
    if cfg.preset is None:
        return set()
    return fill_unless_given(cfg, preset_named(cfg.preset).overrides(), given)


def fill_unless_given(cfg: GenConfig, values: dict[str, Any], given: set[str]) -> set[str]:
    """Set `values` (GenConfig field -> value) on `cfg`, except the fields in `given` (the flags the user gave keep
    their values; `res` stands for width and height); lists are copied. Returns the names of the fields set.
    The one rule of `--preset` and `--level` (`wildgen.levels.apply_level`)."""
    given = set(given) | ({"width", "height"} if "res" in given else set())
    chosen = {k: v for k, v in values.items() if k not in given}
    for name, value in chosen.items():
        setattr(cfg, name, list(value) if isinstance(value, list) else value)
    return set(chosen)
