"""The only module that turns a `SceneDescription` into Mitsuba objects.

One Mitsuba scene is built per object. It holds a fixed set of light *slots* (per light type, the most
lights of that type any of its images uses; the environment map once if any image uses it); each image's
lighting is applied by writing the slots through `mi.traverse`, so changing the image never rebuilds the
scene or recompiles a kernel. The slot of each light class, and how one light is switched on or off in it,
is `scenes.renderer.light_slots` (dispatching on the class of `scenes.lights`).

Requires a Mitsuba variant to be set by the caller (see `scenes.renderer.variant`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scenes.description import FloorDesc, SceneDescription, TextureDesc
from scenes.envmaps import realize_environment
from scenes.geometry import mesh_data_for, transformed_mesh
from scenes.lights import LIGHT_TYPES
from scenes.procedural import MeshData
from scenes.renderer.light_slots import apply_lights, slot_dicts
from scenes.renderer.variant import require_variant
from scenes.textures import realize_texture

log = logging.getLogger(__name__)


def _bitmap_texture(arr: np.ndarray, **options: Any):
    """Raw (non-colour-managed) bilinear bitmap texture of `arr` (H, W, C).

    Instantiated here, not left as a dict: the bitmap plugin takes over its tensor, so a dict shared by two BSDFs
    (the re-render check wraps the material) would leave the second one an empty texture."""
    mi = require_variant()
    return mi.load_dict({"type": "bitmap", "data": mi.TensorXf(arr), "raw": True, "filter_type": "bilinear", **options})


def _texture_dict(tex: TextureDesc, base_dir: Path | None, owner: str) -> tuple[Any, np.ndarray]:
    arr = realize_texture(tex, base_dir, owner)
    if tex.kind == "constant":
        if arr.shape[2] == 1:
            return float(arr[0, 0, 0]), arr
        return {"type": "rgb", "value": arr[0, 0].tolist()}, arr
    return _bitmap_texture(arr, wrap_mode="repeat"), arr


def bsdf_dict(desc: SceneDescription, base_dir: Path | None) -> tuple[dict, dict[str, np.ndarray]]:
    """Mitsuba BSDF dict of the object's material, and the realised texture arrays (for ground truth)."""
    mat = desc.material
    base, base_arr = _texture_dict(mat.base_color, base_dir, "material.base_color")
    arrays = {"base_color": base_arr}
    d: dict[str, Any]
    if mat.kind == "lambertian":
        arrays["roughness"] = np.ones((1, 1, 1), np.float32)
        arrays["metallic"] = np.zeros((1, 1, 1), np.float32)
        d = {"type": "diffuse", "reflectance": base}
    else:
        rough, arrays["roughness"] = _texture_dict(mat.roughness, base_dir, "material.roughness")
        metal, arrays["metallic"] = _texture_dict(mat.metallic, base_dir, "material.metallic")
        d = {
            "type": "principled",
            "base_color": base,
            "roughness": rough,
            "metallic": metal,
            "specular": float(mat.specular),
        }
    if mat.normal_map or mat.detail is not None:
        if mat.normal_map:
            nm_arr = realize_texture(TextureDesc(kind="file", value=[0.5, 0.5, 1.0], file=mat.normal_map), base_dir,
                                     "material.normal_map", rgb=True)
        else:
            from scenes.detail import realize_detail

            nm_arr = realize_detail(mat.detail)
        arrays["normal_map"] = nm_arr
        # Textbook shading max(0, n'.l): no microfacet shadowing term on the perturbed normal.
        d = {
            "type": "normalmap",
            "normalmap": _bitmap_texture(nm_arr),
            "use_shadowing_function": False,
            "bsdf": d,
        }
    return d, arrays


@dataclass
class LightSlots:
    """How many Mitsuba emitters (slots) of each light type the scene holds: the most any one image uses."""

    counts: dict[str, int] = field(default_factory=dict)
    """Light type (a key of `scenes.lights.LIGHT_TYPES`) -> number of slots."""

    @classmethod
    def for_description(cls, desc: SceneDescription) -> "LightSlots":
        counts = dict.fromkeys(LIGHT_TYPES, 0)
        for image in desc.images:
            for t, light_cls in LIGHT_TYPES.items():
                counts[t] = max(counts[t], sum(type(l) is light_cls for l in image.lights))
        return cls(counts)


@dataclass
class BuiltScene:
    """A Mitsuba scene for one object plus what is needed to relight it per image."""

    desc: SceneDescription
    scene: Any
    params: Any
    slots: LightSlots
    textures: dict[str, np.ndarray] = field(default_factory=dict)
    """Realised material maps (H, W, C) in Mitsuba's texture orientation, for ground-truth maps."""
    environment: np.ndarray | None = None
    """The environment map array (H, W, 3), if any."""
    current_image: int | None = None
    off_slots: set[str] = field(default_factory=set)
    """Keys of the light slots switched off now (`build_scene` starts with all of them: fresh slots are off)."""
    object_scene: Any = None
    """The object alone (no floor, no lights) for the ground-truth pass and instance ids; `scene` when the
    description has no floor."""

    def apply_image(self, index: int) -> None:
        """Write the lights of image `index` into the slots (no rebuild, no recompilation)."""
        if not 0 <= index < len(self.desc.images):
            raise ValueError(f"image index: {index} out of range for {len(self.desc.images)} images")
        apply_lights(self.params, self.slots.counts, self.desc.images[index].lights, self.off_slots)
        self.current_image = index

    def park_lights(self) -> None:
        """Switch every light off and move area-light rectangles out of view (ground-truth pass)."""
        apply_lights(self.params, self.slots.counts, [], self.off_slots)
        self.current_image = None


def sensor_dict(desc: SceneDescription, spp: int) -> dict:
    mi = require_variant()
    T = mi.ScalarTransform4f
    cam = desc.camera
    look = T().look_at(origin=cam.origin, target=cam.target, up=cam.up)
    film = {
        "type": "hdrfilm",
        "width": cam.width,
        "height": cam.height,
        "rfilter": {"type": "box"},
        "pixel_format": "rgba",
        "sample_border": False,
    }
    sampler = {"type": desc.render.sampler, "sample_count": spp}
    if cam.kind == "orthographic":
        return {
            "type": "orthographic",
            "to_world": look @ T().scale([cam.half_size, cam.half_size, 1.0]),
            "film": film,
            "sampler": sampler,
        }
    return {"type": "perspective", "to_world": look, "fov": cam.fov, "fov_axis": "x", "film": film, "sampler": sampler}


def build_scene(desc: SceneDescription, base_dir: str | Path | None = None, bsdf_wrapper=None) -> BuiltScene:
    """Build the Mitsuba scene of `desc`. Relative file paths resolve against `base_dir`.

    `bsdf_wrapper(bsdf_dict) -> dict`, if given, wraps the object's BSDF (the re-render check uses it).
    """
    mi = require_variant()
    T = mi.ScalarTransform4f
    desc.validate()
    base = Path(base_dir) if base_dir is not None else None
    bsdf, arrays = bsdf_dict(desc, base)
    if bsdf_wrapper is not None:
        bsdf = bsdf_wrapper(bsdf)
    scene: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": desc.render.max_depth},
        "sensor": sensor_dict(desc, desc.render.spp),
    }
    data = mesh_data_for(desc, base)
    if desc.parts and data is not None and sum(p.faces for p in desc.parts) != len(data.faces):
        raise ValueError(f"parts: {sum(p.faces for p in desc.parts)} triangles in all, the mesh "
                         f"{desc.shape.file!r} has {len(data.faces)}; expected the parts to share out its triangles")

    def the_object() -> Any:
        if data is None:
            return {"type": "sphere", "to_world": T(np.asarray(desc.shape.to_world, np.float64)), "bsdf": bsdf}
        return make_mesh("object", transformed_mesh(data, desc.shape.to_world), bsdf)

    scene["object"] = the_object()
    object_scene = None
    if desc.floor is not None:
        # The ground truth sees the object alone: a second scene without the floor (and without lights).
        object_scene = mi.load_dict({**scene, "object": the_object()}, optimize=False)
        scene["floor"] = floor_dict(desc.floor, base)
    slots = LightSlots.for_description(desc)
    uses_env = any(slots.counts[t] for t, light_cls in LIGHT_TYPES.items() if light_cls.environment_map)
    env_arr = realize_environment(desc.environment, base) if uses_env else None
    slot_entries = slot_dicts(slots.counts, env_arr)
    scene.update(slot_entries)  # the table's order is the emitter order
    # optimize=False: Mitsuba's shape merging orders area lights by memory address, which would make the emitter
    # order (hence the noise pattern) depend on what the process allocated before.
    loaded = mi.load_dict(scene, optimize=False)
    built = BuiltScene(
        desc=desc,
        scene=loaded,
        params=mi.traverse(loaded),
        slots=slots,
        textures=arrays,
        environment=env_arr,
        off_slots=set(slot_entries),
    )
    built.object_scene = object_scene if object_scene is not None else loaded
    built.apply_image(0)
    return built


def floor_dict(floor: FloorDesc, base_dir: Path | None) -> dict:
    """The floor's Mitsuba shape: a square of side `floor.size` centred on `floor.point`, facing `floor.normal`,
    with a non-metal principled BSDF."""
    mi = require_variant()
    n = np.asarray(floor.normal, np.float64)
    n /= np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = u * floor.size / 2, v * floor.size / 2, n  # the rectangle's +z is its normal
    m[:3, 3] = floor.point
    base, _ = _texture_dict(floor.base_color, base_dir, "floor.base_color")
    rough, _ = _texture_dict(floor.roughness, base_dir, "floor.roughness")
    return {"type": "rectangle", "to_world": mi.ScalarTransform4f(m),
            "bsdf": {"type": "principled", "base_color": base, "roughness": rough, "metallic": 0.0}}


def make_mesh(name: str, data: MeshData, bsdf: dict | Any):
    """In-memory Mitsuba mesh from arrays, with vertex normals and texture coordinates."""
    mi = require_variant()
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf) if isinstance(bsdf, dict) else bsdf
    mesh = mi.Mesh(name, len(data.positions), len(data.faces), props, True, True)
    p = mi.traverse(mesh)
    # Flat buffers of the parameter's own type (Float / UInt on JIT variants, ArrayXf / ArrayXu on scalar ones):
    # row-major (N, 3) arrays are already the interleaved x y z x y z layout Mitsuba stores.
    for key, arr, dtype in (("vertex_positions", data.positions, np.float32), ("faces", data.faces, np.uint32),
                            ("vertex_normals", data.normals, np.float32), ("vertex_texcoords", data.uvs, np.float32)):
        p[key] = type(p[key])(np.ascontiguousarray(arr, dtype=dtype).ravel())
    p.update()
    return mesh
