"""Scene description as plain data.

Everything needed to render one object under K lightings lives in these dataclasses. They hold only
numbers, strings and lists, round-trip through JSON exactly (`to_json` / `from_json`), and are checked
by `validate()`; `scenes.renderer.build` is the only module that turns them into Mitsuba objects.

Frames: the world frame is right-handed; the default camera sits on +z looking at the origin with +y up,
so that the world frame equals the camera frame (x right, y up, z toward the camera).
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from scenes.checks import (
    check_choice,
    check_direction,
    check_finite,
    check_int,
    check_json_types,
    check_matrix4,
    check_number,
    check_seed,
    check_vector,
)
from scenes.files import json_text
from scenes.lights import IDENTITY4, LIGHT_TYPES, LightDesc, light_from_dict

MAX_TEXELS = 8192
"""The widest texture or detail map a scene may ask for (the generator makes at most 8192: 2 x its 4096 texture);
twice that for a camera side or a procedural environment map's width (the generator's images are at most 8192)."""
MAX_RINGS = 2048
"""The finest tessellation of a procedural shape (2048 rings x 4096 segments: 8 M vertices; the generator uses 64)."""
MAX_BOUNCES = 2**31 - 3
"""The most bounces Mitsuba takes: its max_depth (bounces + 2) is a signed 32-bit integer."""

SHAPE_KINDS = ("mesh", "sphere", "blob", "superquadric", "bumpy_sphere", "torus", "plane")
TEXTURE_KINDS = ("constant", "noise", "cells", "stripes", "file")
MATERIAL_KINDS = ("principled", "lambertian")
ENVIRONMENT_SOURCES = ("file", "indoor", "sky")
CAMERA_KINDS = ("orthographic", "perspective")
FRAME_WIDTH_MM = 36.0
"""Width of the 35 mm film frame that 35 mm-equivalent focal lengths refer to (horizontal field of view)."""


def fov_from_focal(focal_mm: float) -> float:
    """Full horizontal field of view (degrees) of a 35 mm-equivalent focal length (mm)."""
    return math.degrees(2.0 * math.atan(FRAME_WIDTH_MM / (2.0 * float(focal_mm))))
SAMPLERS = ("multijitter", "independent", "stratified")

def multijitter_spp(spp: int) -> int:
    """The sample count Mitsuba's multijitter sampler really uses: floor(sqrt(n)) x ceil(n / floor(sqrt(n)))."""
    rx = max(1, int(math.isqrt(spp)))
    return rx * (-(-spp // rx))


def _identity4() -> list[list[float]]:
    return [row[:] for row in IDENTITY4]


@dataclass
class ShapeDesc:
    """The object: a mesh file or a seeded procedural surface, placed by `to_world`."""

    kind: str = "sphere"
    """One of SHAPE_KINDS. 'sphere' is Mitsuba's analytic sphere (exact normals, used by tests)."""
    file: str | None = None
    """Mesh file (OBJ/PLY/STL) for kind 'mesh'; relative paths resolve against the scene's base folder."""
    seed: int = 0
    """Seed of the procedural generator (ignored for 'mesh' and 'sphere')."""
    params: dict[str, float] = field(default_factory=dict)
    """Procedural parameters (see scenes.procedural); missing ones take seeded random values."""
    resolution: int = 96
    """Tessellation of procedural shapes: rings of the (u, v) grid (segments are 2x)."""
    normalize: bool = True
    """Centre the mesh and scale it into the unit sphere before `to_world`."""
    to_world: list[list[float]] = field(default_factory=_identity4)
    """4x4 object-to-world matrix (row-major) applied after normalisation."""

    def validate(self) -> None:
        check_choice(self.kind, "shape.kind", SHAPE_KINDS)
        if self.kind == "mesh" and not self.file:
            raise ValueError("shape.file: kind 'mesh' needs a mesh file path, got None")
        check_int(self.resolution, "shape.resolution", 4, MAX_RINGS)
        check_seed(self.seed, "shape.seed")
        from scenes.procedural import check_params

        check_params(self.kind, self.params)
        check_matrix4(self.to_world, "shape.to_world")


@dataclass
class TextureDesc:
    """A scalar or RGB texture: constant, seeded procedural pattern, or image file."""

    kind: str = "constant"
    """One of TEXTURE_KINDS."""
    value: list[float] = field(default_factory=lambda: [0.5, 0.5, 0.5])
    """Constant value, or the first colour of a pattern (1 entry for scalar maps, 3 for colour)."""
    value2: list[float] | None = None
    """Second colour of a pattern (same length as `value`)."""
    scale: float = 4.0
    """Pattern frequency in cycles per unit of texture coordinate."""
    seed: int = 0
    """Seed of the pattern."""
    resolution: int = 256
    """Side of the texture image realised from a pattern, in texels."""
    file: str | None = None
    """Image file for kind 'file' (EXR/PNG/JPG); relative paths resolve against the base folder."""
    channel: int | None = None
    """For kind 'file' and scalar maps: which channel of the image to use (e.g. 1 = G of an ARM map)."""
    srgb: bool = False
    """For kind 'file': decode sRGB to linear (colour photographs); False for data maps."""

    def validate(self, owner: str, unit: bool = False) -> None:
        """`unit`: its values are reflectances or BSDF weights, from 0 to 1 (an object's material)."""
        check_choice(self.kind, f"{owner}.kind", TEXTURE_KINDS)
        if not isinstance(self.value, list) or len(self.value) not in (1, 3):
            raise ValueError(f"{owner}.value: expected a list of 1 or 3 numbers, got {self.value!r}")
        check_finite(self.value, f"{owner}.value")
        if self.value2 is not None:
            if len(self.value2) != len(self.value):
                raise ValueError(f"{owner}.value2: expected {len(self.value)} numbers, got {self.value2!r}")
            check_finite(self.value2, f"{owner}.value2")
        for key in ("value", "value2") if unit else ():
            for v in getattr(self, key) or []:
                check_number(v, f"{owner}.{key}", minimum=0, maximum=1)
        check_number(self.scale, f"{owner}.scale", above=0)
        check_int(self.resolution, f"{owner}.resolution", 1, MAX_TEXELS)
        check_seed(self.seed, f"{owner}.seed")
        if self.channel is not None:
            check_int(self.channel, f"{owner}.channel", 0, 3)  # R, G, B or A of the file
        if self.kind == "file" and not self.file:
            raise ValueError(f"{owner}.file: kind 'file' needs an image path, got None")


@dataclass
class DetailDesc:
    """Procedural surface detail (`scenes.detail`): a tangent-space normal map made from a periodic height field."""

    kind: str = "bumps"
    """Pattern, a key of `scenes.detail.DETAIL_KINDS`: bumps, scratches, fabric, stone."""
    strength_deg: float = 15.0
    """Tilt of the detail normals from the base normal, degrees (its 95th percentile over the map)."""
    scale: float = 6.0
    """Repetitions of the pattern across the UV square (larger: finer detail)."""
    seed: int = 0
    """Seed of the pattern."""
    resolution: int = 512
    """Side of the normal-map texture in texels."""

    def validate(self) -> None:
        from scenes.detail import DETAIL_KINDS

        check_choice(self.kind, "material.detail.kind", tuple(DETAIL_KINDS))
        if not (isinstance(self.strength_deg, (int, float)) and 0 <= self.strength_deg < 90):
            raise ValueError(f"material.detail.strength_deg: expected degrees in [0, 90), got {self.strength_deg!r}")
        check_number(self.scale, "material.detail.scale", above=0)
        check_int(self.resolution, "material.detail.resolution", 4, MAX_TEXELS)
        check_seed(self.seed, "material.detail.seed")


@dataclass
class MaterialDesc:
    """Principled BSDF with spatially varying maps, or a plain Lambertian (tests)."""

    kind: str = "principled"
    """'principled' or 'lambertian' (Mitsuba `diffuse`: base_color is the albedo)."""
    material_class: str = "diffuse"
    """The class it was sampled from: diffuse / specular / metallic (informational)."""
    base_color: TextureDesc = field(default_factory=TextureDesc)
    """Base colour (albedo), linear RGB."""
    roughness: TextureDesc = field(default_factory=lambda: TextureDesc(value=[0.5]))
    """Principled roughness in [0, 1]."""
    metallic: TextureDesc = field(default_factory=lambda: TextureDesc(value=[0.0]))
    """Principled metallic in [0, 1]."""
    specular: float = 0.5
    """Principled specular (dielectric reflectance control)."""
    normal_map: str | None = None
    """Optional tangent-space normal map file (OpenGL convention, (n+1)/2); when given it is what is rendered."""
    detail: DetailDesc | None = None
    """Procedural surface detail: rendered as a normal map when `normal_map` is not given (the generator writes
    it to aux/ and sets `normal_map`, keeping this as the record of how it was made)."""

    def validate(self) -> None:
        check_choice(self.kind, "material.kind", MATERIAL_KINDS)
        if self.detail is not None:
            self.detail.validate()
        self.base_color.validate("material.base_color", unit=True)
        self.roughness.validate("material.roughness", unit=True)
        self.metallic.validate("material.metallic", unit=True)
        check_number(self.specular, "material.specular", minimum=0)


@dataclass
class EnvironmentDesc:
    """The object's environment map (shared by its images; each image rotates and scales it)."""

    source: str = "indoor"
    """'file' (.hdr/.exr), 'indoor' (procedural windows and lamps) or 'sky' (procedural sky and sun)."""
    file: str | None = None
    """Map file for source 'file'; relative paths resolve against the base folder."""
    seed: int = 0
    """Seed of a procedural map."""
    width: int = 256
    """Width of a procedural map (height is width / 2)."""

    def validate(self) -> None:
        check_choice(self.source, "environment.source", ENVIRONMENT_SOURCES)
        if self.source == "file" and not self.file:
            raise ValueError("environment.file: source 'file' needs a .hdr/.exr path, got None")
        check_int(self.width, "environment.width", 8, MAX_TEXELS * 2)  # (height: width / 2)
        check_seed(self.seed, "environment.seed")


@dataclass
class FloorDesc:
    """A flat surface the object stands on (a table, a cushion; tilted toward the camera, a backdrop): a square seen
    wherever the object does not hide it, lit by the images' lights and casting nothing on them from below. Never
    part of the object's mask or ground truth (`wildgen.make --floor`)."""

    point: list[float] = field(default_factory=lambda: [0.0, -1.0, 0.0])
    """A point of the plane (world units), where the object touches it."""
    normal: list[float] = field(default_factory=lambda: [0.0, 1.0, 0.0])
    """The plane's unit normal, on the object's side."""
    size: float = 20.0
    """Side of the square, centred on `point` (large enough to reach past the frame)."""
    base_color: TextureDesc = field(default_factory=lambda: TextureDesc(value=[0.5, 0.5, 0.5]))
    """Its diffuse colour (linear), repeated over the square."""
    roughness: TextureDesc = field(default_factory=lambda: TextureDesc(value=[0.8]))
    """Its roughness (a non-metal, principled BSDF)."""

    def validate(self) -> None:
        check_vector(self.point, "floor.point")
        check_direction(self.normal, "floor.normal")
        check_number(self.size, "floor.size", minimum=1e-6)
        self.base_color.validate("floor.base_color")
        self.roughness.validate("floor.roughness")


@dataclass
class CameraDesc:
    """Sensor: orthographic (the model's assumption) or perspective, looking at `target`."""

    kind: str = "orthographic"
    """'orthographic' or 'perspective'."""
    origin: list[float] = field(default_factory=lambda: [0.0, 0.0, 4.0])
    """Camera position."""
    target: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    """Point looked at."""
    up: list[float] = field(default_factory=lambda: [0.0, 1.0, 0.0])
    """Up vector."""
    half_size: float = 1.0
    """orthographic: the visible square is [-half_size, half_size]^2 around the target."""
    fov: float = 30.0
    """perspective: full horizontal field of view in degrees."""
    width: int = 64
    """Image width in pixels."""
    height: int = 64
    """Image height in pixels."""
    focal_mm: float | None = None
    """perspective: the 35 mm-equivalent focal length (mm) the field of view came from, when the generator drew
    one (`fov = 2 atan(FRAME_WIDTH_MM / (2 focal_mm))`, a 36 mm-wide frame); None otherwise."""

    def validate(self) -> None:
        check_choice(self.kind, "camera.kind", CAMERA_KINDS)
        check_vector(self.origin, "camera.origin")
        check_vector(self.target, "camera.target")
        check_vector(self.up, "camera.up")
        forward = [t - o for t, o in zip(self.target, self.origin)]
        side = [forward[1] * self.up[2] - forward[2] * self.up[1], forward[2] * self.up[0] - forward[0] * self.up[2],
                forward[0] * self.up[1] - forward[1] * self.up[0]]
        if sum(f * f for f in forward) == 0 or sum(c * c for c in side) == 0:  # no viewing direction, or no roll
            raise ValueError(f"camera: origin {self.origin!r}, target {self.target!r} and up {self.up!r} define no "
                             "view (expected a target apart from the origin and an up vector not along the view)")
        check_number(self.half_size, "camera.half_size", above=0)
        check_number(self.fov, "camera.fov", above=0)
        if self.fov >= 180:
            raise ValueError(f"camera.fov: expected less than 180 degrees, got {self.fov!r}")
        if self.focal_mm is not None:
            check_number(self.focal_mm, "camera.focal_mm", above=0)
            if self.kind != "perspective":
                raise ValueError(f"camera.focal_mm: a focal length needs a perspective camera, got kind {self.kind!r}")
            if abs(fov_from_focal(self.focal_mm) - self.fov) > 1e-6:
                raise ValueError(f"camera.fov: {self.fov!r} does not match focal_mm {self.focal_mm!r} "
                                 f"(expected {fov_from_focal(self.focal_mm)!r})")
        for name in ("width", "height"):
            check_int(getattr(self, name), f"camera.{name}", 1, MAX_TEXELS * 2)


@dataclass
class RenderDesc:
    """Path tracer settings shared by the images of one object."""

    spp: int = 64
    """Samples per pixel."""
    bounces: int = 10
    """Indirect bounces as Blender counts them; Mitsuba's max_depth = bounces + 2 (see `max_depth`)."""
    sampler: str = "multijitter"
    """Mitsuba sampler; the stratified 'multijitter' needs 3-7x fewer samples than 'independent'."""
    gt_spp: int = 16
    """Samples per pixel of the ground-truth pass (normals, mask, depth, material maps)."""

    @property
    def max_depth(self) -> int:
        """Mitsuba counts the camera segment and the final segment to the light: 10 bounces = 12."""
        return self.bounces + 2

    def validate(self) -> None:
        for name in ("spp", "gt_spp"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise ValueError(f"render.{name}: expected a positive integer, got {v!r}")
        bounces = self.bounces
        if isinstance(bounces, bool) or not isinstance(bounces, int) or not 0 <= bounces <= MAX_BOUNCES:
            raise ValueError(f"render.bounces: expected an integer from 0 to {MAX_BOUNCES} (Mitsuba's max_depth, "
                             f"bounces + 2, is a signed 32-bit integer), got {self.bounces!r}")
        check_choice(self.sampler, "render.sampler", SAMPLERS)


@dataclass
class ImageDesc:
    """The lighting of one image and how it is rendered and exposed."""

    lights: list[LightDesc] = field(default_factory=list)
    """Lights present in this image (world frame)."""
    seed: int = 0
    """Sampler seed of this image (re-rendering with it reproduces the same noise)."""
    exposure: float = 1.0
    """Factor applied to the linear radiance before quantisation."""

    def validate(self, index: int) -> None:
        if not self.lights:
            raise ValueError(f"images[{index}].lights: expected at least one light, got none")
        n_env = 0
        for j, light in enumerate(self.lights):
            if not isinstance(light, LightDesc):
                raise ValueError(f"images[{index}].lights[{j}]: expected a LightDesc, got {type(light).__name__}")
            light.validate(f"images[{index}].lights[{j}]")
            n_env += light.environment_map
        if n_env > 1:
            raise ValueError(f"images[{index}].lights: at most one environment light per image, got {n_env}")
        present = {light.type for light in self.lights}
        for name in sorted(present):
            clash = sorted(present & set(LIGHT_TYPES[name].excludes))
            if clash:
                raise ValueError(f"images[{index}].lights: a {name!r} light cannot share an image with "
                                 f"{' or '.join(map(repr, clash))} lights ({name}: {LIGHT_TYPES[name].summary})")
        check_number(self.exposure, f"images[{index}].exposure", above=0)
        check_seed(self.seed, f"images[{index}].seed")


@dataclass
class PartDesc:
    """One object of a cluster: its triangles in the scene's mesh, and what it was made from."""

    source: str = ""
    """The procedural kind or mesh file the part came from (informational)."""
    first_face: int = 0
    """Index of its first triangle in the scene's mesh."""
    faces: int = 0
    """Number of its triangles (they follow `first_face` contiguously)."""


@dataclass
class SceneDescription:
    """One object (or a cluster of objects sharing one mesh and one material), its material, the camera, and
    the lighting of each of its K images."""

    shape: ShapeDesc = field(default_factory=ShapeDesc)
    material: MaterialDesc = field(default_factory=MaterialDesc)
    camera: CameraDesc = field(default_factory=CameraDesc)
    render: RenderDesc = field(default_factory=RenderDesc)
    images: list[ImageDesc] = field(default_factory=list)
    environment: EnvironmentDesc | None = None
    """Environment map used by the images' 'environment' lights (required if any image has one)."""
    light_family: str = "custom"
    """Lighting family the images were sampled from: a key of `wildgen.light_families.LIGHT_FAMILIES` for generated
    objects, free text otherwise."""
    name: str = "object"
    """Object name (folder name without '.data')."""
    level: int | None = None
    """Complexity level the scene was drawn at (`wildgen.make --level`, `wildgen.levels.LEVELS`); None otherwise."""
    parts: list[PartDesc] = field(default_factory=list)
    """The objects of a cluster (`wildgen.make --cluster`), in the order of their triangles in the shape's mesh;
    empty for a single object. Part i has instance id i + 1 in aux/instances.png (0: background)."""
    floor: FloorDesc | None = None
    """The surface the object stands on, seen around it (`wildgen.make --floor`); None: a black background. Left out
    of scene.json when None (older scenes read the same)."""

    def validate(self) -> "SceneDescription":
        """Check every field; raise ValueError naming the first bad one. Returns self."""
        self.shape.validate()
        end = 0
        for i, part in enumerate(self.parts):
            if part.first_face != end or not isinstance(part.faces, int) or part.faces <= 0:
                raise ValueError(f"parts[{i}]: expected triangles {end}.. following the previous part, got first_face "
                                 f"{part.first_face!r} and {part.faces!r} faces")
            end += part.faces
        if self.parts and self.shape.kind != "mesh":
            raise ValueError(f"parts: a cluster needs a mesh shape, got kind {self.shape.kind!r}")
        self.material.validate()
        self.camera.validate()
        self.render.validate()
        if not self.images:
            raise ValueError("images: expected at least one image, got an empty list")
        for i, image in enumerate(self.images):
            image.validate(i)
        uses_env = any(l.environment_map for im in self.images for l in im.lights)
        if uses_env and self.environment is None:
            raise ValueError("environment: images use an 'environment' light but no environment map is given")
        if self.environment is not None:
            self.environment.validate()
        if self.floor is not None:
            self.floor.validate()
        return self

    # --- JSON -------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The JSON form; each light keyed by its `type` with its own fields (`scenes.lights.LightDesc.to_dict`)."""
        d = asdict(self)
        if self.floor is None:
            del d["floor"]
        for image, image_dict in zip(self.images, d["images"]):
            image_dict["lights"] = [light.to_dict() for light in image.lights]
        return d

    def to_json(self, indent: int | None = 1) -> str:
        return json_text(self.to_dict(), indent=indent, sort_keys=True, strict=True)

    @classmethod
    def from_dict(cls, d: dict) -> "SceneDescription":
        return _from_dict(cls, d, "scene")

    @classmethod
    def from_json(cls, text: str) -> "SceneDescription":
        return cls.from_dict(json.loads(text))


_NESTED = {
    "shape": ShapeDesc,
    "material": MaterialDesc,
    "detail": DetailDesc,
    "camera": CameraDesc,
    "render": RenderDesc,
    "environment": EnvironmentDesc,
    "floor": FloorDesc,
    "base_color": TextureDesc,
    "roughness": TextureDesc,
    "metallic": TextureDesc,
}


def _from_dict(cls: type, d: Any, owner: str) -> Any:
    """Build dataclass `cls` from a JSON dict, rejecting unknown keys by name."""
    if not isinstance(d, dict):
        raise ValueError(f"{owner}: expected an object, got {type(d).__name__}")
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(d) - names)
    if unknown:
        raise ValueError(f"{owner}: unknown field(s) {', '.join(unknown)}, expected some of {', '.join(sorted(names))}")
    kwargs: dict[str, Any] = {}
    for key, value in d.items():
        if key == "images" and cls is SceneDescription:
            kwargs[key] = [_from_dict(ImageDesc, v, f"images[{i}]") for i, v in enumerate(value)]
        elif key == "parts" and cls is SceneDescription:
            kwargs[key] = [_from_dict(PartDesc, v, f"parts[{i}]") for i, v in enumerate(value)]
        elif key == "lights" and cls is ImageDesc:
            kwargs[key] = [light_from_dict(v, f"{owner}.lights[{i}]") for i, v in enumerate(value)]
        elif key in _NESTED and value is not None:
            kwargs[key] = _from_dict(_NESTED[key], value, f"{owner}.{key}" if owner != "scene" else key)
        else:
            kwargs[key] = value
    obj = cls(**kwargs)
    check_json_types(obj, "" if owner == "scene" else owner, d)
    return obj
