"""The Mitsuba side of the light types (`scenes.lights`): per light class its *slot*, the emitter created once
switched off, and the parameters that show one light in it or switch it off again.

`SLOT_BUILDERS` maps each class of `scenes.lights.LIGHT_TYPES` to its `SlotBuilder`; `scenes.renderer.build`
creates the slots (`slot_dicts`) and writes one image's lights into them (`apply_lights`) through it. A scene
holds, per type, as many slots as the busiest image uses (`LightSlots` in `scenes.renderer.build`); slots an
image does not use get zero strength and zero sampling weight, and unused rectangles and spheres are also
parked out of the way (they are real surfaces that would cast shadows).

The functions receive the `mitsuba` module from the builder (a variant must be set, `scenes.renderer.variant`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from scenes.lights import (
    LIGHT_TYPES,
    AreaLight,
    DirectionalLight,
    EnvironmentLight,
    LightDesc,
    PointLight,
    UniformLight,
    light_class,
)
from scenes.renderer.variant import require_variant

PARK_POSITION = [0.0, 1.0e5, 0.0]  # where unused area lights wait: far above, invisibly small
PARK_SCALE = 1.0e-6
SCALAR_PARK = ([0.0, 1.0e3, 0.0], 1.0e-3)
"""scalar_rgb computes a rectangle's area from its float32 corners: at 1e5 corners 2e-6 apart coincide (zero
area, "no probability mass"), so there unused area lights wait nearer and larger (corners 2e-3 apart at 1e3).
The JIT variants keep the original place: it changes no byte of their renders."""

UNIFORM_RADIUS = 500.0
"""A uniform light is a sphere of this radius around the world origin, emitting inward: the camera and every
other light of its image must lie inside it (the generator's camera is 20 units away at most)."""


def park_transform(mi: Any):
    """The to_world of an unused area light (see PARK_POSITION, SCALAR_PARK)."""
    T = mi.ScalarTransform4f
    pos, scale = SCALAR_PARK if mi.variant().startswith("scalar") else (PARK_POSITION, PARK_SCALE)
    return T().translate(pos) @ T().scale([scale, scale, scale])


def area_light_transform(light: AreaLight):
    """Rectangle ([-1,1]^2, emitting along +z) at `position` facing `target`, sized width x height."""
    mi = require_variant()
    T = mi.ScalarTransform4f
    pos = np.asarray(light.position, np.float64)
    fwd = np.asarray(light.target, np.float64) - pos
    up = np.asarray(light.up, np.float64)
    if np.linalg.norm(np.cross(fwd, up)) < 1e-9 * max(np.linalg.norm(fwd), 1e-12):
        up = np.array([1.0, 0.0, 0.0]) if abs(fwd[0]) < 0.9 * np.linalg.norm(fwd) else np.array([0.0, 0.0, 1.0])
    return T().look_at(origin=pos.tolist(), target=light.target, up=up.tolist()) @ T().scale(
        [light.width / 2, light.height / 2, 1.0]
    )


def _rgb(strength: float, color: list[float]) -> list[float]:
    return [float(strength) * float(c) for c in color]


# --- directional -------------------------------------------------------------------------------------------
def _directional_slot(mi: Any, environment: np.ndarray | None) -> dict:
    return {"type": "directional", "direction": [0, 0, -1], "irradiance": {"type": "rgb", "value": 0.0}}


def _directional_on(mi: Any, l: DirectionalLight) -> dict[str, Any]:
    T = mi.ScalarTransform4f
    d = np.asarray(l.direction, np.float64)
    d /= np.linalg.norm(d)
    up = [0.0, 1.0, 0.0] if abs(d[1]) < 0.99 else [1.0, 0.0, 0.0]
    return {"to_world": mi.AffineTransform4f(T().look_at(origin=[0, 0, 0], target=d.tolist(), up=up)),
            "irradiance.value": mi.Color3f(_rgb(l.irradiance, l.color))}


def _directional_off(mi: Any) -> dict[str, Any]:
    return {"irradiance.value": mi.Color3f(0.0)}


# --- point -------------------------------------------------------------------------------------------------
def _point_slot(mi: Any, environment: np.ndarray | None) -> dict:
    return {"type": "point", "position": [0, 0, 3], "intensity": {"type": "rgb", "value": 0.0}}


def _point_on(mi: Any, l: PointLight) -> dict[str, Any]:
    return {"position": mi.Point3f(l.position), "intensity.value": mi.Color3f(_rgb(l.intensity, l.color))}


def _point_off(mi: Any) -> dict[str, Any]:
    return {"intensity.value": mi.Color3f(0.0)}


# --- area --------------------------------------------------------------------------------------------------
def _area_slot(mi: Any, environment: np.ndarray | None) -> dict:
    # The rectangle is a real surface: an unused one is black and parked out of the way (it would cast a shadow).
    return {"type": "rectangle", "to_world": park_transform(mi),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 0.0}}}


def _area_on(mi: Any, l: AreaLight) -> dict[str, Any]:
    return {"to_world": mi.AffineTransform4f(area_light_transform(l)),
            "emitter.radiance.value": mi.Color3f(_rgb(l.radiance, l.color))}


def _area_off(mi: Any) -> dict[str, Any]:
    return {"to_world": mi.AffineTransform4f(park_transform(mi)), "emitter.radiance.value": mi.Color3f(0.0)}


# --- environment -------------------------------------------------------------------------------------------
def _environment_slot(mi: Any, environment: np.ndarray | None) -> dict:
    return {"type": "envmap", "bitmap": mi.Bitmap(environment), "scale": 0.0}


def _environment_on(mi: Any, l: EnvironmentLight) -> dict[str, Any]:
    return {"to_world": mi.AffineTransform4f(mi.ScalarTransform4f(np.asarray(l.to_world, np.float64))),
            "scale": mi.Float(float(l.scale))}


def _environment_off(mi: Any) -> dict[str, Any]:
    return {"scale": mi.Float(0.0)}


# --- uniform -----------------------------------------------------------------------------------------------
def _uniform_slot(mi: Any, environment: np.ndarray | None) -> dict:
    # Not Mitsuba's `constant` emitter: a scene holds one environment emitter at most, and an object's images may
    # use the environment map too. Inside a sphere of constant radiance L every direction brings L, as from a
    # constant environment (irradiance pi L on any unoccluded surface). Unused, it is black and parked.
    return {"type": "sphere", "flip_normals": True, "to_world": park_transform(mi),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 0.0}}}


def _uniform_on(mi: Any, l: UniformLight) -> dict[str, Any]:
    T = mi.ScalarTransform4f
    return {"to_world": mi.AffineTransform4f(T().scale([UNIFORM_RADIUS] * 3)),
            "emitter.radiance.value": mi.Color3f(_rgb(l.radiance, l.color))}


@dataclass(frozen=True)
class SlotBuilder:
    """The Mitsuba slot of one light class."""

    slot: Callable[[Any, np.ndarray | None], dict]
    """The Mitsuba dict of one slot, switched off (`mitsuba` module, the scene's environment map or None)."""
    on: Callable[[Any, Any], dict[str, Any]]
    """The slot parameters (relative to its key) that show light `l` in it."""
    off: Callable[[Any], dict[str, Any]]
    """The parameters of an unused slot (zero strength; rectangles and spheres parked)."""
    weight: str = "sampling_weight"
    """The parameter of the slot's sampling weight."""


SLOT_BUILDERS: dict[type[LightDesc], SlotBuilder] = {
    DirectionalLight: SlotBuilder(_directional_slot, _directional_on, _directional_off),
    PointLight: SlotBuilder(_point_slot, _point_on, _point_off),
    AreaLight: SlotBuilder(_area_slot, _area_on, _area_off, weight="emitter.sampling_weight"),
    EnvironmentLight: SlotBuilder(_environment_slot, _environment_on, _environment_off),
    UniformLight: SlotBuilder(_uniform_slot, _uniform_on, _area_off, weight="emitter.sampling_weight"),
}


def slot_key(cls: type[LightDesc], k: int) -> str:
    """Scene key of slot k of a light class: `light_<type>_<k>`, or `light_<type>` alone for the environment
    map's single slot."""
    return f"light_{cls.type}" if cls.environment_map else f"light_{cls.type}_{k}"


def slot_dicts(counts: dict[str, int], environment: np.ndarray | None) -> dict[str, dict]:
    """The switched-off slots of a scene, `counts[type]` of each type, in LIGHT_TYPES order (the emitter order)."""
    mi = require_variant()
    return {slot_key(cls, k): SLOT_BUILDERS[cls].slot(mi, environment)
            for cls in LIGHT_TYPES.values() for k in range(counts[cls.type])}


def apply_lights(params: Any, counts: dict[str, int], lights: list[LightDesc], off: set[str] | None = None) -> None:
    """Write one image's lights into the slots (`mi.traverse` parameters); unused slots are switched off. An
    unknown light type is refused, never left dark.

    off: the keys of the slots that are switched off now (updated here); a slot that stays off is not written
    again. Its values are the same, but writing a parked rectangle's transform makes Mitsuba rebuild the scene's
    ray-tracing acceleration structure once more (about 10 ms for a 16k-triangle object, per image)."""
    mi = require_variant()
    # Unused slots get no samples, unless no light is on at all (Mitsuba needs some sampling mass).
    off_weight = 0.0 if lights else 1.0
    for l in lights:
        light_class(l)
    for cls, builder in SLOT_BUILDERS.items():
        shown = [l for l in lights if type(l) is cls]
        count = counts.get(cls.type, 0)
        for k in range(min(count, 1) if cls.environment_map else count):
            key = slot_key(cls, k)
            stays_off = k >= len(shown) and off is not None and key in off
            values = {} if stays_off else builder.on(mi, shown[k]) if k < len(shown) else builder.off(mi)
            for name, value in values.items():
                params[f"{key}.{name}"] = _opaque(value)
            params[f"{key}.{builder.weight}"] = 1.0 if k < len(shown) else off_weight
            if off is not None:
                (off.add if k >= len(shown) else off.discard)(key)
    params.update()


def _opaque(value):
    """Make a JIT value opaque, so a new light setting does not bake new literals into (and recompile) the kernel."""
    import drjit as dr

    dr.make_opaque(value)
    return value
