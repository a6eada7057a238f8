"""The light types of a scene description: one table says, for each `LightDesc.type`, how it is described,
built into Mitsuba and reported.

`LIGHT_TYPES` maps a type name to its `LightType`:
- describe: the `LightDesc` fields that define it and how `LightDesc.validate` checks each one;
- build: its light *slot* in the Mitsuba scene (`scenes.mitsuba_build`): the emitter created once, switched
  off, and the parameters that show one light in it or switch it off again;
- report: its form in the camera frame (x right, y up, z toward the camera), with the image's exposure
  applied: report.json `lights` of the re-render check and scene.json `camera_lights` of the generator.

Everything that dispatches on a light type goes through `light_type(name)`, which refuses an unknown name
with a ValueError naming it and the known ones. Adding a type is one entry here (plus its tests, and the
`LightDesc` fields it needs if it has parameters no type has yet).

No Mitsuba import here: the build functions receive the `mitsuba` module from the builder.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from scenes.variant import require_variant

PARK_POSITION = [0.0, 1.0e5, 0.0]  # where unused area lights wait: far above, invisibly small
PARK_SCALE = 1.0e-6
SCALAR_PARK = ([0.0, 1.0e3, 0.0], 1.0e-3)
"""scalar_rgb computes a rectangle's area from its float32 corners: at 1e5 corners 2e-6 apart coincide (zero
area, "no probability mass"), so there unused area lights wait nearer and larger (corners 2e-3 apart at 1e3).
The JIT variants keep the original place: it changes no byte of their renders."""

FIELD_CHECKS = ("vector", "direction", "matrix", "positive", "non_negative")
"""How `LightDesc.validate` checks a field (`scenes.description`): a finite 3-vector, a non-zero one, a 4x4
matrix, a positive number, a non-negative number."""


def park_transform(mi: Any):
    """The to_world of an unused area light (see PARK_POSITION, SCALAR_PARK)."""
    T = mi.ScalarTransform4f
    pos, scale = SCALAR_PARK if mi.variant().startswith("scalar") else (PARK_POSITION, PARK_SCALE)
    return T().translate(pos) @ T().scale([scale, scale, scale])


def area_light_transform(light: Any):
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


def _exposed(strength: float, color: list[float], exposure: float) -> list[float]:
    return [float(strength) * float(c) * float(exposure) for c in color]


# --- directional -------------------------------------------------------------------------------------------
def _directional_on(mi: Any, l: Any) -> dict[str, Any]:
    T = mi.ScalarTransform4f
    d = np.asarray(l.direction, np.float64)
    d /= np.linalg.norm(d)
    up = [0.0, 1.0, 0.0] if abs(d[1]) < 0.99 else [1.0, 0.0, 0.0]
    return {"to_world": mi.AffineTransform4f(T().look_at(origin=[0, 0, 0], target=d.tolist(), up=up)),
            "irradiance.value": mi.Color3f(_rgb(l.irradiance, l.color))}


def camera_directional(direction: Any, irradiance: Any) -> dict:
    """The one JSON form of a directional light in the camera frame: `direction_to_light` (unit, toward the
    light) and `irradiance` (RGB, image units), as scene.json `camera_lights` stores it (the datasets on disk
    hold this key) and as report.json `lights` gives it, there after `"type": "directional"`."""
    return {"direction_to_light": np.asarray(direction, np.float64).tolist(),
            "irradiance": np.asarray(irradiance, np.float64).tolist()}


def _directional_report(l: Any, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
    d = -np.asarray(l.direction, np.float64)
    d = R @ (d / np.linalg.norm(d))
    return {"type": "directional", **camera_directional(d, _exposed(l.irradiance, l.color, exposure))}


# --- point -------------------------------------------------------------------------------------------------
def _point_on(mi: Any, l: Any) -> dict[str, Any]:
    return {"position": mi.Point3f(l.position), "intensity.value": mi.Color3f(_rgb(l.intensity, l.color))}


def _point_report(l: Any, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
    return {"type": "point", "position": (R @ (np.asarray(l.position) - target)).tolist(),
            "intensity": _exposed(l.intensity, l.color, exposure)}


# --- area --------------------------------------------------------------------------------------------------
def _area_slot(mi: Any, environment: np.ndarray | None) -> dict:
    # The rectangle is a real surface: an unused one is black and parked out of the way (it would cast a shadow).
    return {"type": "rectangle", "to_world": park_transform(mi),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 0.0}}}


def _area_on(mi: Any, l: Any) -> dict[str, Any]:
    return {"to_world": mi.AffineTransform4f(area_light_transform(l)),
            "emitter.radiance.value": mi.Color3f(_rgb(l.radiance, l.color))}


def _area_off(mi: Any) -> dict[str, Any]:
    return {"to_world": mi.AffineTransform4f(park_transform(mi)), "emitter.radiance.value": mi.Color3f(0.0)}


def _area_report(l: Any, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
    nrm = R @ (np.asarray(l.target, np.float64) - np.asarray(l.position, np.float64))
    return {"type": "area", "position": (R @ (np.asarray(l.position) - target)).tolist(),
            "normal": (nrm / max(np.linalg.norm(nrm), 1e-12)).tolist(), "width": l.width, "height": l.height,
            "radiance": _exposed(l.radiance, l.color, exposure)}


# --- environment -------------------------------------------------------------------------------------------
def _environment_slot(mi: Any, environment: np.ndarray | None) -> dict:
    return {"type": "envmap", "bitmap": mi.Bitmap(environment), "scale": 0.0}


def _environment_on(mi: Any, l: Any) -> dict[str, Any]:
    return {"to_world": mi.AffineTransform4f(mi.ScalarTransform4f(np.asarray(l.to_world, np.float64))),
            "scale": mi.Float(float(l.scale))}


def _environment_report(l: Any, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
    return {"type": "environment", "scale": float(l.scale) * float(exposure),
            "to_camera": (R @ np.asarray(l.to_world, np.float64)[:3, :3]).tolist()}


# --- uniform -----------------------------------------------------------------------------------------------
UNIFORM_RADIUS = 500.0
"""A uniform light is a sphere of this radius around the world origin, emitting inward: the camera and every
other light of its image must lie inside it (the generator's camera is 20 units away at most)."""


def _uniform_slot(mi: Any, environment: np.ndarray | None) -> dict:
    # Not Mitsuba's `constant` emitter: a scene holds one environment emitter at most, and an object's images may
    # use the environment map too. Inside a sphere of constant radiance L every direction brings L, as from a
    # constant environment (irradiance pi L on any unoccluded surface). Unused, it is black and parked.
    return {"type": "sphere", "flip_normals": True, "to_world": park_transform(mi),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 0.0}}}


def _uniform_on(mi: Any, l: Any) -> dict[str, Any]:
    T = mi.ScalarTransform4f
    return {"to_world": mi.AffineTransform4f(T().scale([UNIFORM_RADIUS] * 3)),
            "emitter.radiance.value": mi.Color3f(_rgb(l.radiance, l.color))}


def _uniform_report(l: Any, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
    return {"type": "uniform", "radiance": _exposed(l.radiance, l.color, exposure)}


@dataclass(frozen=True)
class LightType:
    """One light type of `LightDesc.type`: how it is described, built and reported."""

    name: str
    """The `LightDesc.type` value."""
    summary: str
    """One line: what the light is and which fields set it."""
    fields: tuple[tuple[str, str], ...]
    """describe: the `LightDesc` fields of this type, each with its check (one of FIELD_CHECKS), in check order."""
    slot: Callable[[Any, np.ndarray | None], dict]
    """build: the Mitsuba dict of one slot, switched off (`mitsuba` module, the scene's environment map or None)."""
    on: Callable[[Any, Any], dict[str, Any]]
    """build: the slot parameters (relative to its key) that show light `l` in it."""
    off: Callable[[Any], dict[str, Any]]
    """build: the parameters of an unused slot (zero strength; area rectangles parked)."""
    report: Callable[[Any, np.ndarray, np.ndarray, float], dict]
    """report: the light in the camera frame: (light, R world-to-camera rotation, camera target, exposure)."""
    weight: str = "sampling_weight"
    """build: the parameter of the slot's sampling weight."""
    environment_map: bool = False
    """Lit by the scene's environment map: at most one per image, one slot, needs `SceneDescription.environment`."""
    excludes: tuple[str, ...] = ()
    """Light types that cannot share an image with this one (`ImageDesc.validate` refuses the pair)."""

    @property
    def prefix(self) -> str:
        """Scene key of the slots: `prefix_k`, or `prefix` alone for the environment map's single slot."""
        return f"light_{self.name}"

    def key(self, k: int) -> str:
        return self.prefix if self.environment_map else f"{self.prefix}_{k}"


LIGHT_TYPES: dict[str, LightType] = {t.name: t for t in (
    LightType("directional", "a distant light: `direction` of travel, `irradiance` x `color` on a facing surface",
              (("direction", "direction"), ("irradiance", "non_negative")),
              lambda mi, env: {"type": "directional", "direction": [0, 0, -1], "irradiance": {"type": "rgb", "value": 0.0}},
              _directional_on, lambda mi: {"irradiance.value": mi.Color3f(0.0)}, _directional_report),
    LightType("point", "a point light at `position`, radiant `intensity` x `color` (W/sr)",
              (("position", "vector"), ("intensity", "non_negative")),
              lambda mi, env: {"type": "point", "position": [0, 0, 3], "intensity": {"type": "rgb", "value": 0.0}},
              _point_on, lambda mi: {"intensity.value": mi.Color3f(0.0)}, _point_report),
    LightType("area", "a rectangle at `position` facing `target`, `width` x `height`, `radiance` x `color`",
              (("position", "vector"), ("target", "vector"), ("up", "vector"), ("width", "positive"),
               ("height", "positive"), ("radiance", "non_negative")),
              _area_slot, _area_on, _area_off, _area_report, weight="emitter.sampling_weight"),
    LightType("environment", "the scene's environment map rotated by `to_world`, multiplied by `scale`",
              (("to_world", "matrix"), ("scale", "non_negative")),
              _environment_slot, _environment_on, lambda mi: {"scale": mi.Float(0.0)}, _environment_report,
              environment_map=True),
    LightType("uniform", "a uniform background, `radiance` x `color` from every direction: a sphere of radius "
              "UNIFORM_RADIUS around the origin emitting inward, which would shadow distant lights",
              (("radiance", "non_negative"),),
              _uniform_slot, _uniform_on, _area_off, _uniform_report, weight="emitter.sampling_weight",
              excludes=("directional", "environment")),
)}
"""The light types, in the order their slots are created and written (the emitter order of a built scene)."""

assert all(check in FIELD_CHECKS for t in LIGHT_TYPES.values() for _, check in t.fields)
assert all(other in LIGHT_TYPES for t in LIGHT_TYPES.values() for other in t.excludes)


def light_type(name: Any, owner: str = "light") -> LightType:
    """The table entry of light type `name`; a ValueError naming `owner`.type, the value and the known types
    for anything else (never a fallback to another type)."""
    entry = LIGHT_TYPES.get(name) if isinstance(name, str) else None
    if entry is None:
        raise ValueError(f"{owner}.type: unknown light type {name!r}, expected one of {', '.join(LIGHT_TYPES)}")
    return entry


def camera_frame(lights: list, R: np.ndarray, target: Any, exposure: float) -> list[dict]:
    """The report form of one image's lights (see the module doc); R: world-to-camera rotation
    (`scenes.geometry.camera_rotation`), target: the point the camera looks at."""
    target = np.asarray(target, np.float64)
    return [light_type(l.type).report(l, R, target, exposure) for l in lights]
