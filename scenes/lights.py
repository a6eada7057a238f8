"""The light types of a scene description: one plain class per type, each with only its own fields.

`LightDesc` is the base: the fields every type has (`color`, `temperature_k`) and what each type says about
itself (`type`, `summary`, `strength`, `environment_map`, `excludes`). Each type's class holds
- describe: its own fields and `validate(owner)`, which checks them (a ValueError naming `owner.field`);
- report: `report(R, target, exposure)`, its form in the camera frame (x right, y up, z toward the camera),
  with the image's exposure applied: report.json `lights` of the re-render check and scene.json
  `camera_lights` of the generator;
- JSON: `to_dict()` writes its `type` and its own fields only; `light_from_dict` reads that form and the old
  flat one (every type's fields in every light, see FLAT_FORM_DEFAULTS).

`LIGHT_TYPES` maps a type name to its class, in the order their Mitsuba slots are created. Everything that
dispatches on a light type goes through `light_type(name)` or `light_class(light)`, which refuse an unknown
type with a ValueError naming it and the known ones. The Mitsuba side of each type (its slot, the parameters
that switch it on and off) is `scenes.renderer.light_slots`; no Mitsuba here. Adding a type is one class here, its
entry in LIGHT_TYPES and in `scenes.renderer.light_slots.SLOT_BUILDERS`, and its tests.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any, ClassVar

import numpy as np

from scenes.checks import check_direction, check_json_types, check_matrix4, check_number, check_vector

IDENTITY4 = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]


def _identity4() -> list[list[float]]:
    return [row[:] for row in IDENTITY4]


def _exposed(strength: float, color: list[float], exposure: float) -> list[float]:
    return [float(strength) * float(c) * float(exposure) for c in color]


def camera_directional(direction: Any, irradiance: Any) -> dict:
    """The one JSON form of a directional light in the camera frame: `direction_to_light` (unit, toward the
    light) and `irradiance` (RGB, image units), as scene.json `camera_lights` stores it (the datasets on disk
    hold this key) and as report.json `lights` gives it, there after `"type": "directional"`."""
    return {"direction_to_light": np.asarray(direction, np.float64).tolist(),
            "irradiance": np.asarray(irradiance, np.float64).tolist()}


@dataclass(kw_only=True)
class LightDesc:
    """One light of one image (world frame): the base of the light types, never a light itself."""

    type: ClassVar[str] = ""
    """The type's name: its key in LIGHT_TYPES and its `type` in scene.json."""
    summary: ClassVar[str] = ""
    """One line: what the light is and which fields set it."""
    strength: ClassVar[str] = ""
    """The field that sets its strength (irradiance, intensity, radiance or scale), multiplied by `color`."""
    environment_map: ClassVar[bool] = False
    """Lit by the scene's environment map: at most one per image, one slot, needs `SceneDescription.environment`."""
    excludes: ClassVar[tuple[str, ...]] = ()
    """Light types that cannot share an image with this one (`ImageDesc.validate` refuses the pair)."""

    color: list[float] = field(default_factory=lambda: [1.0, 1.0, 1.0])
    """Linear RGB tint (e.g. from a colour temperature), multiplied with the strength."""
    temperature_k: float | None = None
    """Colour temperature the colour came from, if any (informational)."""

    def validate(self, owner: str) -> None:
        """Check the light (a registered type) and its colour; each type checks its own fields after this."""
        light_class(self, owner)
        check_vector(self.color, f"{owner}.color")
        if min(self.color) < 0:
            raise ValueError(f"{owner}.color: expected non-negative values, got {self.color!r}")
        if self.temperature_k is not None:  # informational, yet a record: a negative kelvin is no temperature
            check_number(self.temperature_k, f"{owner}.temperature_k", above=0)

    def report(self, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
        """The light in the camera frame: R world-to-camera rotation, the camera target, the image's exposure."""
        raise NotImplementedError

    def to_dict(self) -> dict:
        """The scene.json form: `type` and the type's own fields."""
        return {"type": self.type, **asdict(self)}


@dataclass(kw_only=True)
class DirectionalLight(LightDesc):
    type: ClassVar[str] = "directional"
    summary: ClassVar[str] = "a distant light: `direction` of travel, `irradiance` x `color` on a facing surface"
    strength: ClassVar[str] = "irradiance"

    direction: list[float] = field(default_factory=lambda: [0.0, 0.0, -1.0])
    """Direction of travel (from the light toward the scene)."""
    irradiance: float = 1.0
    """Irradiance on a surface facing the light."""

    def validate(self, owner: str) -> None:
        super().validate(owner)
        check_direction(self.direction, f"{owner}.direction")
        check_number(self.irradiance, f"{owner}.irradiance", minimum=0)

    def report(self, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
        d = -np.asarray(self.direction, np.float64)
        d = R @ (d / np.linalg.norm(d))
        return {"type": "directional", **camera_directional(d, _exposed(self.irradiance, self.color, exposure))}


@dataclass(kw_only=True)
class PointLight(LightDesc):
    type: ClassVar[str] = "point"
    summary: ClassVar[str] = "a point light at `position`, radiant `intensity` x `color` (W/sr)"
    strength: ClassVar[str] = "intensity"

    position: list[float] = field(default_factory=lambda: [0.0, 0.0, 3.0])
    """Position in world space."""
    intensity: float = 1.0
    """Radiant intensity."""

    def validate(self, owner: str) -> None:
        super().validate(owner)
        check_vector(self.position, f"{owner}.position")
        check_number(self.intensity, f"{owner}.intensity", minimum=0)

    def report(self, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
        return {"type": "point", "position": (R @ (np.asarray(self.position) - target)).tolist(),
                "intensity": _exposed(self.intensity, self.color, exposure)}


@dataclass(kw_only=True)
class AreaLight(LightDesc):
    type: ClassVar[str] = "area"
    summary: ClassVar[str] = "a rectangle at `position` facing `target`, `width` x `height`, `radiance` x `color`"
    strength: ClassVar[str] = "radiance"

    position: list[float] = field(default_factory=lambda: [0.0, 0.0, 3.0])
    """Centre of the rectangle in world space."""
    target: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    """Point the rectangle faces."""
    up: list[float] = field(default_factory=lambda: [0.0, 1.0, 0.0])
    """Up vector of the rectangle's frame."""
    width: float = 0.5
    """Side along the rectangle's local x."""
    height: float = 0.5
    """Side along the rectangle's local y."""
    radiance: float = 1.0
    """Emitted radiance."""

    def validate(self, owner: str) -> None:
        super().validate(owner)
        for name in ("position", "target", "up"):
            check_vector(getattr(self, name), f"{owner}.{name}")
        facing = np.subtract(self.target, self.position, dtype=np.float64)
        if not np.linalg.norm(facing) > 0:  # it faces no way: Mitsuba's look-at makes a frame of NaNs
            raise ValueError(f"{owner}.target: got {self.target!r}, the light's own position; expected a point it "
                             "faces")
        if np.linalg.norm(np.cross(facing, self.up)) <= 1e-9 * np.linalg.norm(facing) * np.linalg.norm(self.up):
            raise ValueError(f"{owner}.up: got {self.up!r}, along the way the light faces (or zero); expected a "
                             "direction across it")
        check_number(self.width, f"{owner}.width", above=0)
        check_number(self.height, f"{owner}.height", above=0)
        check_number(self.radiance, f"{owner}.radiance", minimum=0)

    def report(self, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
        nrm = R @ (np.asarray(self.target, np.float64) - np.asarray(self.position, np.float64))
        return {"type": "area", "position": (R @ (np.asarray(self.position) - target)).tolist(),
                "normal": (nrm / max(np.linalg.norm(nrm), 1e-12)).tolist(), "width": self.width,
                "height": self.height, "radiance": _exposed(self.radiance, self.color, exposure)}


@dataclass(kw_only=True)
class EnvironmentLight(LightDesc):
    type: ClassVar[str] = "environment"
    summary: ClassVar[str] = "the scene's environment map rotated by `to_world`, multiplied by `scale`"
    strength: ClassVar[str] = "scale"
    environment_map: ClassVar[bool] = True

    to_world: list[list[float]] = field(default_factory=_identity4)
    """Rotation of the map (4x4)."""
    scale: float = 1.0
    """Multiplier of the map."""

    def validate(self, owner: str) -> None:
        super().validate(owner)
        check_matrix4(self.to_world, f"{owner}.to_world")
        check_number(self.scale, f"{owner}.scale", minimum=0)

    def report(self, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
        return {"type": "environment", "scale": float(self.scale) * float(exposure),
                "to_camera": (R @ np.asarray(self.to_world, np.float64)[:3, :3]).tolist()}


@dataclass(kw_only=True)
class UniformLight(LightDesc):
    type: ClassVar[str] = "uniform"
    summary: ClassVar[str] = ("a uniform background, `radiance` x `color` from every direction: a sphere of radius "
                              "UNIFORM_RADIUS around the origin emitting inward, which would shadow distant lights")
    strength: ClassVar[str] = "radiance"
    excludes: ClassVar[tuple[str, ...]] = ("directional", "environment")

    radiance: float = 1.0
    """Radiance from every direction."""

    def validate(self, owner: str) -> None:
        super().validate(owner)
        check_number(self.radiance, f"{owner}.radiance", minimum=0)

    def report(self, R: np.ndarray, target: np.ndarray, exposure: float) -> dict:
        return {"type": "uniform", "radiance": _exposed(self.radiance, self.color, exposure)}


LIGHT_TYPES: dict[str, type[LightDesc]] = {t.type: t for t in (
    DirectionalLight, PointLight, AreaLight, EnvironmentLight, UniformLight)}
"""The light types, in the order their slots are created and written (the emitter order of a built scene)."""


def light_type(name: Any, owner: str = "light") -> type[LightDesc]:
    """The class of light type `name`; a ValueError naming `owner`.type, the value and the known types for
    anything else (never a fallback to another type)."""
    entry = LIGHT_TYPES.get(name) if isinstance(name, str) else None
    if entry is None:
        raise ValueError(f"{owner}.type: unknown light type {name!r}, expected one of {', '.join(LIGHT_TYPES)}")
    return entry


def light_class(light: Any, owner: str = "light") -> type[LightDesc]:
    """The registered class of `light`: its type must be in LIGHT_TYPES and the light an instance of exactly
    that class (a subclass the table does not name is refused like an unknown type)."""
    cls = light_type(getattr(light, "type", None), owner)
    if type(light) is not cls:
        raise ValueError(f"{owner}: a {cls.type!r} light must be a {cls.__name__}, got {type(light).__name__}")
    return cls


FLAT_FORM_DEFAULTS: dict[str, Any] = {
    "direction": [0.0, 0.0, -1.0], "irradiance": 1.0, "position": [0.0, 0.0, 3.0], "intensity": 1.0,
    "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "width": 0.5, "height": 0.5, "radiance": 1.0,
    "to_world": IDENTITY4, "scale": 1.0,
}
"""The old flat form of a light in scene.json (one record with every type's fields, written until the light
types became classes): the fields and defaults it carried. Reading it, a field of another type is dropped when
it holds this default (as every generated scene.json has it) and refused otherwise (it would be lost)."""


def light_from_dict(d: Any, owner: str = "light") -> LightDesc:
    """A light from its scene.json dict, keyed by `type` (missing: 'directional', the old default): its own
    fields, or the old flat form (FLAT_FORM_DEFAULTS). Unknown keys are refused by name."""
    if not isinstance(d, dict):
        raise ValueError(f"{owner}: expected an object, got {type(d).__name__}")
    cls = light_type(d.get("type", "directional"), owner)
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(d) - names - {"type"} - set(FLAT_FORM_DEFAULTS))
    if unknown:
        raise ValueError(
            f"{owner}: unknown field(s) {', '.join(unknown)}, expected some of {', '.join(sorted(names | {'type'}))}"
        )
    for key in sorted(set(d) - names - {"type"}):
        if d[key] != FLAT_FORM_DEFAULTS[key]:
            raise ValueError(f"{owner}.{key}: a {cls.type!r} light has no {key} (the old flat form may hold it "
                             f"only at its default {FLAT_FORM_DEFAULTS[key]!r}), got {d[key]!r}")
    light = cls(**{k: v for k, v in d.items() if k in names})
    check_json_types(light, owner, [k for k in d if k in names])
    return light


def camera_frame(lights: list, R: np.ndarray, target: Any, exposure: float) -> list[dict]:
    """The report form of one image's lights (see the module doc); R: world-to-camera rotation
    (`scenes.geometry.camera_rotation`), target: the point the camera looks at."""
    target = np.asarray(target, np.float64)
    return [light_class(l).report(l, R, target, exposure) for l in lights]
