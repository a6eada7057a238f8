"""Capture presets: named sets of `GenConfig` values that make a dataset look like one kind of real rig.

`PRESETS` is the one list: `wildgen.make --preset NAME` fills the dataset's configuration from an entry (flags
given on the command line keep their values over the preset's), the docs' table of presets is generated from
it (`orchestrate.docs`, block `generator:presets`) and the tests check each entry against the configuration it
produces. A preset holds only names of the existing tables: a light family of `wildgen.light_families.LIGHT_FAMILIES`
(a fixed light pattern is such a family) and a sensor of `scenes.sensor.SENSORS`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from scenes.sensor import SENSORS
from wildgen.light_families import LIGHT_FAMILIES


@dataclass(frozen=True)
class CapturePreset:
    """One capture preset: the `GenConfig` values it sets, and what it imitates."""

    name: str
    """The value of --preset."""
    about: str
    """What rig it imitates and how (for the docs)."""
    lights: str
    """Light family (a key of `wildgen.light_families.LIGHT_FAMILIES`); a fixed light pattern is a family whose image i
    gets light i of the pattern."""
    images: int
    """Images per object."""
    width: int
    """Image width in pixels."""
    height: int
    """Image height in pixels."""
    camera: str
    """'orthographic' or 'perspective' (`GenConfig.camera`)."""
    sensor: str
    """Camera sensor preset (a key of `scenes.sensor.SENSORS`)."""

    def overrides(self) -> dict[str, Any]:
        """The `GenConfig` field values this preset sets."""
        return {"lights": [self.lights], "images": self.images, "width": self.width, "height": self.height,
                "camera": self.camera, "sensor": self.sensor}


PRESETS: dict[str, CapturePreset] = {p.name: p for p in (
    CapturePreset(
        "diligent",
        "The DiLiGenT benchmark's rig: a camera with a long lens (orthographic here) and 96 LEDs on a planar grid in "
        "front of the object, one lit per image (the same angular span as DiLiGenT's), a machine-vision camera "
        "writing 16-bit PNG files (12 significant bits).",
        lights="grid96", images=96, width=612, height=512, camera="orthographic", sensor="machine-vision"),
    CapturePreset(
        "phone-flash",
        "A phone photographing an object with its flash on, in a dim room: perspective camera, a point light at "
        "the camera plus the room's ambient light, the phone's 8-bit sRGB files with demosaicing, noise and "
        "vignetting. Frontal light only: a hard case.",
        lights="flash", images=10, width=256, height=256, camera="perspective", sensor="phone"),
    CapturePreset(
        "light-stage",
        "A light stage: many distant lights around the object, one at a time (image i of K lit by light i of K, "
        "spread evenly over the sphere but the cap behind the object), a machine-vision camera.",
        lights="light_stage", images=64, width=256, height=256, camera="orthographic", sensor="machine-vision"),
    CapturePreset(
        "display",
        "A computer screen as the light source, filmed by a webcam between the screen and the object: perspective "
        "camera, a 4 x 3 grid of screen patches 8 object radii in front of the object, one lit white per image, "
        "the webcam's 8-bit files.",
        lights="display", images=12, width=256, height=256, camera="perspective", sensor="webcam"),
)}
"""The capture presets by name, in the order of --help and the docs' table."""

for _p in PRESETS.values():  # a preset names only entries of the existing tables
    assert _p.lights in LIGHT_FAMILIES and _p.sensor in SENSORS, _p.name


def preset_named(name: str) -> CapturePreset:
    """The entry of preset `name`; a ValueError naming --preset and the known presets otherwise."""
    if name not in PRESETS:
        raise ValueError(f"--preset: unknown preset {name!r}, expected one of {', '.join(PRESETS)}")
    return PRESETS[name]


def apply_preset(cfg: Any, given: set[str]) -> set[str]:
    """Set the values of preset `cfg.preset` (a `GenConfig`) on the fields not in `given` (the flags the user
    gave: they keep their values; `res` stands for width and height). Returns the names of the fields it set.
    Nothing happens when `cfg.preset` is None."""
    if cfg.preset is None:
        return set()
    return fill_unless_given(cfg, preset_named(cfg.preset).overrides(), given)


def fill_unless_given(cfg: Any, values: dict[str, Any], given: set[str]) -> set[str]:
    """Set `values` (GenConfig field -> value) on `cfg`, except the fields in `given` (the flags the user gave keep
    their values; `res` stands for width and height); lists are copied. Returns the names of the fields set.
    The one rule of `--preset` and `--level` (`wildgen.levels.apply_level`)."""
    given = set(given) | ({"width", "height"} if "res" in given else set())
    chosen = {k: v for k, v in values.items() if k not in given}
    for name, value in chosen.items():
        setattr(cfg, name, list(value) if isinstance(value, list) else value)
    return set(chosen)
