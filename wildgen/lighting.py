"""The light families of the generator: how the lights of each image of an object are drawn.

`LIGHT_FAMILIES` is the one list of families: `wildgen.make --lights` and the configuration check, the
training recipe, the benchmark tables, the bench scripts and the tests all read it. A family is a sampler of
one image's lights plus a one-line description; adding a family is one entry here (and its tests).

Frame: the world frame is the camera frame (x right, y up, z toward the camera; `wildgen.sampling` puts the
camera on the +z axis looking at the origin). Strengths are set so that the main light of an image gives
about `IRRADIANCE` at the object's centre, whatever its distance.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from scenes.colors import temperature_to_rgb
from scenes.description import CameraDesc, LightDesc

IRRADIANCE = 1.0  # nominal irradiance at the object centre from each image's main light


@dataclass(frozen=True)
class Placement:
    """What the lights of one image are drawn around: the framed object, its camera and its environment map."""

    centre: np.ndarray
    """Object centre (world frame)."""
    radius: float
    """Object bounding radius (world units)."""
    camera: CameraDesc
    """The camera of the images: emitters are kept out of its view."""
    env_scale: float
    """Scale of the environment map that gives about `IRRADIANCE` on a surface facing it."""


@dataclass(frozen=True)
class LightFamily:
    """One light family: a one-line description and the sampler of one image's lights."""

    description: str
    """What the lights of an image are (for --help and the docs)."""
    sample: Callable[[np.random.Generator, Placement], list[LightDesc]]
    """The lights of one image; draws only from the generator (the dataset's byte reproducibility)."""


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """Uniform random rotation matrix (3x3) from a random unit quaternion (also the object poses' sampler)."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _temperature_color(rng: np.random.Generator) -> tuple[list[float], float | None]:
    """White half of the time, else a blackbody colour between 2700 K and 9000 K."""
    kelvin = float(rng.uniform(2700, 9000))
    if rng.random() < 0.5:
        return [1.0, 1.0, 1.0], None
    return list(temperature_to_rgb(kelvin)), kelvin


def _hemisphere(rng: np.random.Generator, min_z: float) -> np.ndarray:
    """Uniform direction on the camera-facing hemisphere with z >= min_z (toward the camera is +z)."""
    z = rng.uniform(min_z, 1.0)
    phi = rng.uniform(0, 2 * np.pi)
    s = math.sqrt(max(0.0, 1 - z * z))
    return np.array([s * math.cos(phi), s * math.sin(phi), z])


def _occludes_view(position: np.ndarray, half_diag: float, camera: CameraDesc) -> bool:
    """True if an emitter at `position` (size half_diag) could appear in front of the object in the image
    (camera on the +z axis looking at the origin)."""
    if camera.kind == "orthographic":
        return position[2] > -half_diag and np.hypot(position[0], position[1]) - half_diag < 1.05 * camera.half_size
    depth = camera.origin[2] - position[2]
    if depth <= 0:
        return False  # behind the camera
    t = math.tan(math.radians(camera.fov / 2))
    return np.hypot(position[0], position[1]) / depth - half_diag / depth < 1.05 * t * math.sqrt(2)


def _directional(rng: np.random.Generator) -> LightDesc:
    l = _hemisphere(rng, 0.1)
    color, kelvin = _temperature_color(rng)
    return LightDesc(type="directional", direction=(-l).tolist(), irradiance=IRRADIANCE, color=color, temperature_k=kelvin)


def _point(rng: np.random.Generator, p: Placement) -> LightDesc:
    l = _hemisphere(rng, 0.1)
    r = p.radius * rng.uniform(2.5, 5.0)
    color, kelvin = _temperature_color(rng)
    return LightDesc(type="point", position=(p.centre + r * l).tolist(), intensity=IRRADIANCE * r * r, color=color, temperature_k=kelvin)


def _near_area(rng: np.random.Generator, p: Placement, strength: float = 1.0) -> LightDesc:
    """A rectangle 1.5-4 object radii from the centre, facing it, never in front of the object in view."""
    for _ in range(200):
        l = _hemisphere(rng, 0.0)
        r = p.radius * rng.uniform(1.5, 4.0)
        w, h = p.radius * rng.uniform(0.3, 1.0, 2)
        pos = p.centre + r * l
        if not _occludes_view(pos, 0.5 * math.hypot(w, h), p.camera):
            break
    else:  # pragma: no cover - the loop finds a grazing position in practice
        raise RuntimeError("could not place a near area light outside the view")
    color, kelvin = _temperature_color(rng)
    up = [0.0, 1.0, 0.0] if abs(l[1]) < 0.9 else [1.0, 0.0, 0.0]
    return LightDesc(
        type="area", position=pos.tolist(), target=p.centre.tolist(), up=up, width=float(w), height=float(h),
        radiance=float(strength * IRRADIANCE * r * r / (w * h)), color=color, temperature_k=kelvin,
    )


def _environment(rng: np.random.Generator, p: Placement, relative: float) -> LightDesc:
    m = np.eye(4)
    m[:3, :3] = random_rotation(rng)
    return LightDesc(type="environment", to_world=m.tolist(), scale=float(p.env_scale * relative))


def _near_area_family(rng: np.random.Generator, p: Placement) -> list[LightDesc]:
    lights = [_near_area(rng, p) for _ in range(1 if rng.random() < 0.7 else 2)]
    if rng.random() < 0.5:  # a dim room around the hand-held light
        lights.append(_environment(rng, p, rng.uniform(0.05, 0.2)))
    return lights


def _mixed_family(rng: np.random.Generator, p: Placement) -> list[LightDesc]:
    combo = int(rng.integers(0, 3))
    if combo == 0:
        return [_near_area(rng, p), _environment(rng, p, rng.uniform(0.2, 1.0))]
    if combo == 1:
        return [_directional(rng), _environment(rng, p, rng.uniform(0.2, 1.0))]
    return [_near_area(rng, p, rng.uniform(0.5, 1.0)) for _ in range(int(rng.integers(2, 4)))]


LIGHT_FAMILIES: dict[str, LightFamily] = {
    "directional": LightFamily("one distant light from the camera-facing hemisphere, white or a colour temperature",
                               lambda rng, p: [_directional(rng)]),
    "point": LightFamily("one point light 2.5-5 object radii from the centre", lambda rng, p: [_point(rng, p)]),
    "near_area": LightFamily("one or two rectangle lights 1.5-4 object radii from the centre (hand-held lamps), "
                             "half of the images in a dim room (the environment map at 5-20%)", _near_area_family),
    "hdri": LightFamily("the object's environment map alone, randomly rotated",
                        lambda rng, p: [_environment(rng, p, 1.0)]),
    "mixed": LightFamily("a near rectangle or a distant light with the environment map, or 2-3 near rectangles",
                         _mixed_family),
}
"""The light families by name, in the order of --help, the recipe's cycle and the benchmark columns."""


def light_family(name: str) -> LightFamily:
    """The table entry of family `name`; a ValueError naming --lights and the known families otherwise."""
    if name not in LIGHT_FAMILIES:
        raise ValueError(f"--lights: unknown family {name!r}, expected one of {', '.join(LIGHT_FAMILIES)}")
    return LIGHT_FAMILIES[name]


def sample_lighting(rng: np.random.Generator, family: str, n_images: int, placement: Placement) -> list[list[LightDesc]]:
    """The lights of each of `n_images` images for one light family."""
    sample = light_family(family).sample
    return [sample(rng, placement) for _ in range(n_images)]
