"""The light families of the generator: how the lights of each image of an object are drawn.

`LIGHT_FAMILIES` is the one list of families: `wildgen.make --lights` and the configuration check, the
training recipe, the benchmark tables, the bench scripts and the tests all read it. A family is a sampler of
one image's lights plus a one-line description; adding a family is one entry here (and its tests). A sampler
gets the object's rng, its `Placement`, the image's index and the object's image count: random families draw
from the rng only; fixed patterns (`grid96`, `light_stage`, `display`) draw nothing: an image's light is set by
its index (and the image count) alone.

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
from scenes.description import CameraDesc
from scenes.lights import AreaLight, DirectionalLight, EnvironmentLight, LightDesc, PointLight, UniformLight

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
    sample: Callable[[np.random.Generator, Placement, int, int], list[LightDesc]]
    """The lights of one image: (rng, placement, image index, images of the object) -> lights; draws only from
    the generator (the dataset's byte reproducibility)."""


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
    return DirectionalLight(direction=(-l).tolist(), irradiance=IRRADIANCE, color=color, temperature_k=kelvin)


def _point(rng: np.random.Generator, p: Placement, strength: float = 1.0) -> LightDesc:
    l = _hemisphere(rng, 0.1)
    r = p.radius * rng.uniform(2.5, 5.0)
    color, kelvin = _temperature_color(rng)
    return PointLight(position=(p.centre + r * l).tolist(), intensity=float(strength * IRRADIANCE * r * r),
                      color=color, temperature_k=kelvin)


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
    return AreaLight(
        position=pos.tolist(), target=p.centre.tolist(), up=up, width=float(w), height=float(h),
        radiance=float(strength * IRRADIANCE * r * r / (w * h)), color=color, temperature_k=kelvin,
    )


def _environment(rng: np.random.Generator, p: Placement, relative: float) -> LightDesc:
    m = np.eye(4)
    m[:3, :3] = random_rotation(rng)
    return EnvironmentLight(to_world=m.tolist(), scale=float(p.env_scale * relative))


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


def _uniform(rng: np.random.Generator, relative: float) -> LightDesc:
    """A uniform background: the same radiance from every direction, `relative` x IRRADIANCE on a facing surface
    (E = pi L), white or a colour temperature (light type `uniform`, `scenes.lights`)."""
    color, kelvin = _temperature_color(rng)
    return UniformLight(radiance=float(relative * IRRADIANCE / math.pi), color=color, temperature_k=kelvin)


def _verse_family(rng: np.random.Generator, p: Placement, index: int, count: int) -> list[LightDesc]:
    """PS-Verse's per-image recipe: a background (the environment map or a uniform one), 0-3 point lights and
    0-1 near rectangle, each at 30-100 % of the nominal strength."""
    if rng.random() < 0.5:
        lights = [_environment(rng, p, rng.uniform(0.2, 1.0))]
    else:
        lights = [_uniform(rng, rng.uniform(0.2, 1.0))]
    lights += [_point(rng, p, rng.uniform(0.3, 1.0)) for _ in range(int(rng.integers(0, 4)))]
    if rng.random() < 0.5:
        lights.append(_near_area(rng, p, rng.uniform(0.3, 1.0)))
    return lights


def _flash_family(rng: np.random.Generator, p: Placement, index: int, count: int) -> list[LightDesc]:
    """A phone flash: a white point light at the camera's position (the world-frame `camera.origin`), giving
    IRRADIANCE at the object's centre, plus the dim room (the environment map at 5-20 %, rotated per image).
    Camera and flash do not move, so without the room all images of an object would be the same."""
    origin = np.asarray(p.camera.origin, np.float64)
    d = float(np.linalg.norm(origin - p.centre))
    flash = PointLight(position=origin.tolist(), intensity=float(IRRADIANCE * d * d))
    return [flash, _environment(rng, p, rng.uniform(0.05, 0.2))]


FRONTAL_CONE_DEG = 20.0
"""`frontal`: the largest angle between its light and the viewing direction (+z), seen from the object's centre."""


def _frontal_family(rng: np.random.Generator, p: Placement, index: int, count: int) -> list[LightDesc]:
    """A hard case: one point light within FRONTAL_CONE_DEG of the viewing direction, 5-10 object radii from the
    centre (a lamp next to the lens), plus a uniform ambient of 0-100 % of its irradiance (weak shading contrast)."""
    l = _hemisphere(rng, math.cos(math.radians(FRONTAL_CONE_DEG)))
    r = p.radius * rng.uniform(5.0, 10.0)
    color, kelvin = _temperature_color(rng)
    lamp = PointLight(position=(p.centre + r * l).tolist(), intensity=float(IRRADIANCE * r * r),
                      color=color, temperature_k=kelvin)
    return [lamp, _uniform(rng, rng.uniform(0.0, 1.0))]


GRID_COLUMNS, GRID_ROWS = 12, 8
GRID_HALF_SPAN = (0.8, 0.5)
"""`grid96`: a planar 12 x 8 grid of distant lights, like DiLiGenT's LED array: light k points from the object
toward (u, v, 1) normalised, u = x / z over 12 even steps of [-0.8, 0.8], v = y / z over 8 steps of [-0.5, 0.5]
(zenith angles up to 43 degrees); k runs up the columns, left to right."""
GRID_STRIDE = 53
"""`grid96`: image i is lit by grid light (53 i mod 96): 53 is prime to 96, so 96 images use every light once, and
among the strides that do it spreads the first K images most evenly over the grid (K = 6-32), so that
`--images 10` gets lights across the grid rather than one column."""


def grid96_direction(k: int) -> np.ndarray:
    """Unit direction toward light k (mod 96) of the `grid96` pattern (world = camera frame)."""
    col, row = divmod(k % (GRID_COLUMNS * GRID_ROWS), GRID_ROWS)
    u = GRID_HALF_SPAN[0] * (2 * col / (GRID_COLUMNS - 1) - 1)
    v = GRID_HALF_SPAN[1] * (2 * row / (GRID_ROWS - 1) - 1)
    l = np.array([u, v, 1.0])
    return l / np.linalg.norm(l)


def _grid96_family(rng: np.random.Generator, p: Placement, index: int, count: int) -> list[LightDesc]:
    l = grid96_direction(GRID_STRIDE * index)
    return [DirectionalLight(direction=(-l).tolist(), irradiance=IRRADIANCE)]


LIGHT_STAGE_MIN_Z = -0.5
"""`light_stage`: the lowest z of its directions: the sphere around the object except the cap of 60 degrees
right behind it (lights the object hides from the camera)."""
GOLDEN_ANGLE = math.pi * (3 - math.sqrt(5))


def light_stage_direction(k: int, count: int) -> np.ndarray:
    """Unit direction toward light k of a `light_stage` of `count` lights: a Fibonacci lattice (even area per
    light) on the sphere zone z >= LIGHT_STAGE_MIN_Z, k = 0 nearest the viewing direction, spiralling outward."""
    k %= count
    z = 1.0 - (1.0 - LIGHT_STAGE_MIN_Z) * (k + 0.5) / count
    s = math.sqrt(max(0.0, 1.0 - z * z))
    phi = k * GOLDEN_ANGLE
    return np.array([s * math.cos(phi), s * math.sin(phi), z])


def _light_stage_family(rng: np.random.Generator, p: Placement, index: int, count: int) -> list[LightDesc]:
    return [DirectionalLight(direction=(-light_stage_direction(index, count)).tolist(), irradiance=IRRADIANCE)]


SCREEN_DISTANCE = 8.0
"""`display`: distance (object radii) from the object's centre to the screen plane, toward the camera."""
SCREEN_SIZE = (10.0, 6.25)
"""`display`: the screen's width and height (object radii; 16:10, a monitor about 50 cm wide seen from 40 cm by
an object of 5 cm radius)."""
SCREEN_GRID = (4, 3)
"""`display`: the screen's patches, columns x rows; one is lit per image."""


def display_patches(p: Placement) -> list[tuple[np.ndarray, float, float]]:
    """(centre, width, height) of the `display` patches that are never in front of the object in view, row by row
    from the bottom, left to right; a perspective camera nearer than the screen sees none of them, an
    orthographic one sees through the middle columns."""
    cols, rows = SCREEN_GRID
    w, h = p.radius * SCREEN_SIZE[0] / cols, p.radius * SCREEN_SIZE[1] / rows
    patches = []
    for row in range(rows):
        for col in range(cols):
            offset = np.array([(col + 0.5) * w - p.radius * SCREEN_SIZE[0] / 2,
                               (row + 0.5) * h - p.radius * SCREEN_SIZE[1] / 2, p.radius * SCREEN_DISTANCE])
            centre = p.centre + offset
            if not _occludes_view(centre, 0.5 * math.hypot(w, h), p.camera):
                patches.append((centre, w, h))
    if not patches:  # pragma: no cover - the outer columns lie outside any framed object's view
        raise RuntimeError("no display patch lies outside the view")
    return patches


def _display_family(rng: np.random.Generator, p: Placement, index: int, count: int) -> list[LightDesc]:
    """Patch index (mod the patches) of the screen lit white, the rest of the screen dark; its radiance gives
    IRRADIANCE at the centre of a surface facing it (E = L A cos / r^2, cos the screen's emission angle)."""
    patches = display_patches(p)
    centre, w, h = patches[index % len(patches)]
    r = float(np.linalg.norm(centre - p.centre))
    cos = p.radius * SCREEN_DISTANCE / r
    return [AreaLight(position=centre.tolist(), target=(centre - np.array([0.0, 0.0, 1.0])).tolist(),
                      up=[0.0, 1.0, 0.0], width=float(w), height=float(h),
                      radiance=float(IRRADIANCE * r * r / (w * h * cos)))]


LIGHT_FAMILIES: dict[str, LightFamily] = {
    "directional": LightFamily("one distant light from the camera-facing hemisphere, white or a colour temperature",
                               lambda rng, p, i, n: [_directional(rng)]),
    "point": LightFamily("one point light 2.5-5 object radii from the centre", lambda rng, p, i, n: [_point(rng, p)]),
    "near_area": LightFamily("one or two rectangle lights 1.5-4 object radii from the centre (hand-held lamps), "
                             "half of the images in a dim room (the environment map at 5-20%)",
                             lambda rng, p, i, n: _near_area_family(rng, p)),
    "hdri": LightFamily("the object's environment map alone, randomly rotated",
                        lambda rng, p, i, n: [_environment(rng, p, 1.0)]),
    "mixed": LightFamily("a near rectangle or a distant light with the environment map, or 2-3 near rectangles",
                         lambda rng, p, i, n: _mixed_family(rng, p)),
    "verse": LightFamily("as PS-Verse (LINO-UniPS): per image the environment map or a uniform background (half "
                         "each, 20-100%), plus 0-3 point lights and 0-1 near rectangle", _verse_family),
    "flash": LightFamily("a phone flash: a white point light at the camera, plus a dim room (the environment map "
                         "at 5-20%, rotated per image); a hard case: frontal light only", _flash_family),
    "frontal": LightFamily("hard case: one point light within 20 degrees of the viewing direction, 5-10 object radii "
                           "away, plus a uniform ambient of 0-100% of its irradiance (weak shading contrast)",
                           _frontal_family),
    "grid96": LightFamily("fixed pattern: 96 distant lights on a 12 x 8 grid like DiLiGenT's LED array (zenith up to "
                          "43 degrees), white; image i lit by light 53 i mod 96 (the first images spread over the "
                          "grid, 96 images use each light once)", _grid96_family),
    "light_stage": LightFamily("fixed pattern, one light at a time: image i of K lit by distant light i of K spread "
                               "evenly over the sphere but the 60-degree cap behind the object (a light stage)",
                               _light_stage_family),
    "display": LightFamily("fixed pattern: a screen 8 object radii in front of the object, 4 x 3 patches; image i "
                           "lit by patch i (mod the patches outside the view), white", _display_family),
}
"""The light families by name, in the order of --help and the benchmark columns."""
PS_WILD_FAMILIES = ("directional", "point", "near_area", "hdri", "mixed")
"""The families of the PS-Wild recipe (UniPS 2022), which the shipped model was trained and measured on: the
training recipe's default cycle, so that adding a family to the table does not change its data."""
ENVIRONMENT_FAMILIES = ("near_area", "hdri", "mixed", "verse", "flash")
"""The families whose images may be lit by the object's environment map (the others never draw it: a flag that
shapes the map, --env-width, does nothing without one of these)."""


def light_family(name: str) -> LightFamily:
    """The table entry of family `name`; a ValueError naming --lights and the known families otherwise."""
    if name not in LIGHT_FAMILIES:
        raise ValueError(f"--lights: unknown family {name!r}, expected one of {', '.join(LIGHT_FAMILIES)}")
    return LIGHT_FAMILIES[name]


def sample_lighting(
    rng: np.random.Generator, family: str, n_images: int, placement: Placement
) -> list[list[LightDesc]]:
    """The lights of each of `n_images` images for one light family."""
    sample = light_family(family).sample
    return [sample(rng, placement, i, n_images) for i in range(n_images)]
