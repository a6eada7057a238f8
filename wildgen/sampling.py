"""PS-Wild-style sampling of one object: shape, pose (entropy rule), framing, material, per-image lights.

Object i draws only from `np.random.default_rng([seed, i])`, so the dataset does not depend on the
order in which objects are made or on which worker makes them. The lights of each image come from the
object's light family (`wildgen.light_families.LIGHT_FAMILIES`).

Entropy rule: the visible normals' distribution is a 16 x 16 histogram of (n_x, n_y) in the camera
frame over [-1, 1]^2, weighted by each camera-facing triangle's projected area (self-occlusion
ignored); its Shannon entropy in bits must reach `entropy_threshold` (default 4.0, as in the paper). A
plane seen face-on scores 0, a sphere about 7.5.
"""
from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from scenes.description import (
    CameraDesc,
    EnvironmentDesc,
    FloorDesc,
    ImageDesc,
    MaterialDesc,
    RenderDesc,
    SceneDescription,
    ShapeDesc,
    TextureDesc,
    fov_from_focal,
    multijitter_spp,
)
from scenes.folder.format import AUX_DIR, MESH_FILE
from scenes.lights import AreaLight, DirectionalLight, PointLight
from scenes.procedural import MeshData
from wildgen.assets import AssetLibrary
from wildgen.config import MATERIAL_CLASSES, GenConfig
from wildgen.light_families import IRRADIANCE, Placement, random_rotation, sample_lighting

log = logging.getLogger(__name__)

ENTROPY_BINS = 16
ORTHO_DISTANCE = 20.0  # orthographic camera distance: beyond every light we place
PERSPECTIVE_DISTANCE = 4.0
PERSPECTIVE_FOV = 30.0
MESH_RESOLUTION = 64


@dataclass
class SampledObject:
    """A sampled scene (file references still point at the asset library) and its geometry."""

    desc: SceneDescription
    mesh: MeshData
    shape_source: str  # procedural kind or the mesh file path


def visible_normal_entropy(mesh: MeshData, rotation: np.ndarray) -> float:
    """Entropy (bits) of the projected-area-weighted (n_x, n_y) histogram of camera-facing triangles."""
    p = mesh.positions.astype(np.float64) @ rotation.T
    f = mesh.faces
    cross = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    area2 = np.linalg.norm(cross, axis=1)
    n = cross / np.maximum(area2[:, None], 1e-18)
    facing = n[:, 2] > 0
    if not facing.any():
        return 0.0
    weights = area2[facing] * n[facing, 2]
    hist, _, _ = np.histogram2d(
        n[facing, 0], n[facing, 1], bins=ENTROPY_BINS, range=[[-1, 1], [-1, 1]], weights=weights
    )
    prob = hist.ravel() / max(hist.sum(), 1e-18)
    prob = prob[prob > 0]
    return float(-(prob * np.log2(prob)).sum())


def perspective_distance(fov: float) -> float:
    """Camera distance for a field of view (degrees): PERSPECTIVE_DISTANCE at PERSPECTIVE_FOV, and the same framing
    (distance times tan(fov / 2) held) at any other, so the object keeps its size whatever the focal length."""
    return PERSPECTIVE_DISTANCE * math.tan(math.radians(PERSPECTIVE_FOV / 2)) / math.tan(math.radians(fov / 2))


def fit_to_frame(mesh: MeshData, rotation: np.ndarray, camera: str, margin: float,
                 fov: float = PERSPECTIVE_FOV) -> tuple[np.ndarray, float]:
    """4x4 object-to-world transform that rotates, centres and scales the outline to the image edge.

    Returns (matrix, bounding radius in world units). The camera looks down -z at the origin; the
    orthographic view is [-1, 1]^2, the perspective camera sits at `perspective_distance(fov)`.
    """
    p = mesh.positions.astype(np.float64) @ rotation.T
    limit = 1.0 / (1.0 + margin)
    centre = 0.5 * (p[:, :2].min(0) + p[:, :2].max(0))
    p[:, :2] -= centre
    if camera == "orthographic":
        scale = limit / np.abs(p[:, :2]).max()
    else:
        # Bisection on the scale: perspective projection x / (D - z) must stay inside tan(fov / 2) * limit, and
        # the nearest point in front of the camera (0.5 at the default distance, a quarter of it for wide angles).
        dist = perspective_distance(fov)
        clear = min(0.5, 0.25 * dist)
        t = math.tan(math.radians(fov / 2)) * limit
        lo, hi = 1e-3, 2.0
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            q = p * mid
            inside = np.abs(q[:, :2]).max(1) / (dist - q[:, 2]) <= t
            lo, hi = (mid, hi) if inside.all() and (q[:, 2] < dist - clear).all() else (lo, mid)
        scale = lo
    m = np.eye(4)
    m[:3, :3] = scale * rotation
    m[:2, 3] = -scale * centre
    radius = float(scale * np.linalg.norm(mesh.positions, axis=1).max())
    return m, radius


def _linear_colour(rng: np.random.Generator) -> list[float]:
    """A random surface colour (HSV in display space, converted to linear)."""
    import colorsys

    h, s, v = rng.uniform(0, 1), rng.uniform(0, 0.9), rng.uniform(0.25, 0.95)
    return [float(c) ** 2.2 for c in colorsys.hsv_to_rgb(h, s, v)]


def _scalar_map(rng: np.random.Generator, lo: float, hi: float, res: int) -> TextureDesc:
    a, b = sorted(rng.uniform(lo, hi, 2))
    if rng.random() < 0.5:
        return TextureDesc(kind="constant", value=[float(a)])
    kind = str(rng.choice(["noise", "cells", "stripes"]))
    return TextureDesc(
        kind=kind,
        value=[float(a)],
        value2=[float(b)],
        scale=float(rng.uniform(2, 8)),
        seed=int(rng.integers(2**31)),
        resolution=res,
    )


def sample_material(rng: np.random.Generator, cls: str, lib: AssetLibrary, tex_res: int) -> MaterialDesc:
    """Principled material of class diffuse / specular / metallic with spatially varying maps."""
    rough_range = {"diffuse": (0.5, 1.0), "specular": (0.05, 0.4), "metallic": (0.05, 0.5)}[cls]
    spec = {"diffuse": rng.uniform(0.0, 0.3), "specular": rng.uniform(0.5, 1.0), "metallic": 0.5}[cls]
    use_set = bool(lib.textures) and rng.random() < 0.5
    set_index = int(rng.integers(len(lib.textures))) if lib.textures else 0
    if use_set:
        ts = lib.textures[set_index]
        base = TextureDesc(kind="file", value=[0.5, 0.5, 0.5], file=str(ts.base_color), srgb=True)
    else:
        kind = str(rng.choice(["noise", "cells", "stripes", "constant"], p=[0.35, 0.25, 0.2, 0.2]))
        base = TextureDesc(
            kind=kind,
            value=_linear_colour(rng),
            value2=_linear_colour(rng),
            scale=float(rng.uniform(2, 8)),
            seed=int(rng.integers(2**31)),
            resolution=tex_res,
        )
    roughness = _scalar_map(rng, *rough_range, tex_res)
    metallic = _scalar_map(rng, 0.7, 1.0, tex_res) if cls == "metallic" else TextureDesc(kind="constant", value=[0.0])
    normal_map = None
    if use_set:
        ts = lib.textures[set_index]
        if ts.roughness is not None and rng.random() < 0.7:
            roughness = TextureDesc(kind="file", value=[0.5], file=str(ts.roughness), channel=ts.roughness_channel)
        if cls == "metallic" and ts.metallic is not None:
            metallic = TextureDesc(kind="file", value=[1.0], file=str(ts.metallic), channel=ts.metallic_channel)
        if ts.normal is not None and rng.random() < 0.5:
            normal_map = str(ts.normal)
    return MaterialDesc(
        kind="principled",
        material_class=cls,
        base_color=base,
        roughness=roughness,
        metallic=metallic,
        specular=float(spec),
        normal_map=normal_map,
    )


FLOOR_TILT = (20.0, 70.0)
"""Angle (deg) between the floor's normal and the world's up, toward the camera: a table seen from above (small) to
a backdrop behind the object (large)."""
FLOOR_SIZE = (2.5, 8.0)
"""Side of the floor's square over the object's bounding radius."""
FLOOR_ROLL = 15.0
"""The floor turns up to this much (deg) about the viewing axis: a table not quite level in the picture."""


def sample_floor(cfg: GenConfig, index: int, positions: np.ndarray, radius: float) -> FloorDesc | None:
    """The floor of object `index` (a fraction `cfg.floor` of objects), touching the object's world-space vertices
    `positions` (N, 3) from below, a square of `FLOOR_SIZE` times the object's bounding `radius` (a cushion under
    it to a table past the frame), drawn from the stream (seed, index, 2) so that the object's other draws do not
    change. Procedural textures only: the scene stays re-renderable from its folder."""
    rng = np.random.default_rng([cfg.seed, index, 2])
    if cfg.floor is None or rng.random() >= cfg.floor:
        return None
    tilt, roll = math.radians(rng.uniform(*FLOOR_TILT)), math.radians(rng.uniform(-FLOOR_ROLL, FLOOR_ROLL))
    normal = np.array([-math.sin(roll) * math.cos(tilt), math.cos(roll) * math.cos(tilt), math.sin(tilt)])
    contact = positions[int(np.argmin(positions @ normal))]
    base = TextureDesc(kind=str(rng.choice(["noise", "cells", "stripes", "constant"])), value=_linear_colour(rng),
                       value2=_linear_colour(rng), scale=float(rng.uniform(20, 60)), seed=int(rng.integers(2**31)),
                       resolution=cfg.texture_resolution)
    return FloorDesc(point=[float(c) for c in contact], normal=[float(c) for c in normal],
                     size=float(radius * rng.uniform(*FLOOR_SIZE)),
                     base_color=base, roughness=TextureDesc(value=[float(rng.uniform(0.3, 1.0))]))


def above_floor(lights: list, floor: FloorDesc | None) -> list:
    """`lights` with each directional, point or area light that lies below the floor mirrored above it (nobody puts
    the lamp under the table: it would light nothing); the others as they are."""
    if floor is None:
        return lights
    n, o = np.asarray(floor.normal, float), np.asarray(floor.point, float)
    n = n / np.linalg.norm(n)

    def mirror_point(p: list[float]) -> list[float]:
        q = np.asarray(p, float)
        side = float((q - o) @ n)
        return [float(c) for c in (q - 2 * side * n if side < 0 else q)]

    out = []
    for light in lights:
        if isinstance(light, DirectionalLight) and float(np.asarray(light.direction) @ n) > 0:  # travels up: from below
            d = np.asarray(light.direction, float)
            light = dataclasses.replace(light, direction=[float(c) for c in d - 2 * float(d @ n) * n])
        elif isinstance(light, (PointLight, AreaLight)) and float((np.asarray(light.position) - o) @ n) < 0:
            moved = {"position": mirror_point(light.position)}
            if isinstance(light, AreaLight):
                moved["target"] = mirror_point(light.target)
            light = dataclasses.replace(light, **moved)
        out.append(light)
    return out


DETAIL_SCALE = (3.0, 12.0)
"""Range of the pattern's repetitions across the UV square."""


def with_detail(material: MaterialDesc, cfg: GenConfig, index: int) -> MaterialDesc:
    """The material with (a fraction `cfg.detail` of objects) or without surface detail, drawn from the stream
    (seed, index, 1) so that the object's other draws do not change."""
    from scenes.description import DetailDesc
    from scenes.detail import DETAIL_KINDS

    rng = np.random.default_rng([cfg.seed, index, 1])
    if rng.random() >= cfg.detail:
        return dataclasses.replace(material, normal_map=None, detail=None)
    if material.normal_map is not None:  # the texture set's own normal map is the detail
        return material
    detail = DetailDesc(kind=str(rng.choice(list(DETAIL_KINDS))),
                        strength_deg=float(rng.uniform(*cfg.detail_strength_range())),
                        scale=float(rng.uniform(*DETAIL_SCALE)), seed=int(rng.integers(2**31)),
                        resolution=max(64, 2 * cfg.texture_resolution))
    return dataclasses.replace(material, detail=detail)


def _environment_desc(rng: np.random.Generator, lib: AssetLibrary, width: int) -> EnvironmentDesc:
    if lib.hdris:
        return EnvironmentDesc(source="file", file=str(lib.hdris[int(rng.integers(len(lib.hdris)))]))
    return EnvironmentDesc(source=str(rng.choice(["indoor", "sky"])), seed=int(rng.integers(2**31)), width=width)


def _environment_scale(env: EnvironmentDesc) -> float:
    """Scale so the map's mean radiance gives about IRRADIANCE on a surface facing it (E = pi L)."""
    from scenes.envmaps import realize_environment

    mean = float(realize_environment(env).mean())
    return IRRADIANCE / (math.pi * max(mean, 1e-6))


def _shape_candidates(rng: np.random.Generator, cfg: GenConfig, lib: AssetLibrary) -> tuple[ShapeDesc, str]:
    use_mesh = bool(lib.meshes) and (cfg.shapes == "mesh" or (cfg.shapes == "any" and rng.random() < 0.5))
    if cfg.shapes == "mesh" and not lib.meshes:
        raise ValueError("--shapes: 'mesh' needs an --assets folder with meshes/")
    if use_mesh:
        path = lib.meshes[int(rng.integers(len(lib.meshes)))]
        return ShapeDesc(kind="mesh", file=str(path)), str(path)
    kind = str(rng.choice(cfg.shape_kinds))
    return ShapeDesc(kind=kind, seed=int(rng.integers(2**31)), resolution=MESH_RESOLUTION), kind


def _shape_mesh(shape: ShapeDesc) -> MeshData:
    """The object-space mesh of a drawn shape (normalised as the shape says)."""
    from scenes.geometry import mesh_data_for

    return mesh_data_for(SceneDescription(shape=shape, images=[ImageDesc(lights=[DirectionalLight()])]), None)


CLUSTER_PART_SCALE = (0.5, 1.0)
"""Size of each object of a cluster, relative to the unit sphere its shape is normalised into."""
CLUSTER_PRESS = (0.0, 0.1)
"""How far a new object is pushed into the ones it touches, past first contact, as a fraction of its radius: 0
touches, more overlaps (the surfaces intersect a little, as soft objects pressed together)."""
CLUSTER_CONTACT = 0.01
"""Vertices closer than this (scene units of the normalised shapes) count as touching."""
CONTACT_PROBES = 3000
"""Vertices of the sliding object tested for contact (every k-th one; all of them when fewer)."""


def _contact_distance(placed: np.ndarray, part: np.ndarray, direction: np.ndarray, far: float) -> float:
    """The distance t along `direction` at which `part` (vertices about its centre) placed at t * direction first
    touches the `placed` vertices, coming from t = far (separated) inward: bisection on the nearest-vertex gap."""
    from scipy.spatial import cKDTree

    tree = cKDTree(placed)
    part = part[:: max(1, len(part) // CONTACT_PROBES)]  # a strided subset: the bisection's cost, not its answer
    apart = lambda t: tree.query(part + t * direction, k=1)[0].min() >= CLUSTER_CONTACT  # noqa: E731
    lo, hi = 0.0, far
    while not apart(hi):  # far enough to be apart from every placed object
        lo, hi = hi, 2 * hi
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if apart(mid) else (mid, hi)
    return hi


def _sample_cluster(rng: np.random.Generator, cfg: GenConfig, lib: AssetLibrary,
                    count: int) -> tuple[MeshData, list, str]:
    """`count` shapes, each normalised, scaled and rotated, placed each against a random earlier one (slid in from
    beside it, mostly in the image plane, some in front or behind, until the surfaces touch, then pressed a
    little into it), merged into one mesh centred on its bounding box.
    Returns (mesh, parts (`PartDesc`), source)."""
    from scenes.description import PartDesc

    pos, fac, nrm, uvs, parts, centres, radii = [], [], [], [], [], [], []
    faces_so_far = vertices_so_far = 0
    for i in range(count):
        shape, source = _shape_candidates(rng, cfg, lib)
        data = _shape_mesh(shape)
        scale = float(rng.uniform(*CLUSTER_PART_SCALE))
        rot = random_rotation(rng)
        p = data.positions.astype(np.float64) @ rot.T * scale
        radius = float(np.linalg.norm(p, axis=1).max())
        if i == 0:
            centre = np.zeros(3)
        else:  # slide in from beside an earlier object (mostly in the image plane) until it touches, then press
            j = int(rng.integers(i))
            phi = rng.uniform(0, 2 * np.pi)
            d = np.array([np.cos(phi), np.sin(phi), rng.uniform(-0.5, 0.5)])
            d /= np.linalg.norm(d)
            t = _contact_distance(np.concatenate(pos) - centres[j], p, d, radius + radii[j] + CLUSTER_CONTACT)
            centre = centres[j] + d * max(t - rng.uniform(*CLUSTER_PRESS) * radius, 0.0)
        centres.append(centre)
        radii.append(radius)
        pos.append(p + centre)
        nrm.append(data.normals.astype(np.float64) @ rot.T)
        fac.append(data.faces.astype(np.int64) + vertices_so_far)
        uvs.append(data.uvs)
        parts.append(PartDesc(source=source, first_face=faces_so_far, faces=len(data.faces)))
        faces_so_far += len(data.faces)
        vertices_so_far += len(p)
    allp = np.concatenate(pos)
    allp -= 0.5 * (allp.min(0) + allp.max(0))
    mesh = MeshData(allp.astype(np.float32), np.concatenate(fac).astype(np.int32),
                    np.concatenate(nrm).astype(np.float32), np.concatenate(uvs).astype(np.float32))
    return mesh, parts, f"cluster of {count}: " + ", ".join(Path(p.source).name for p in parts)


class SkippedObject(Exception):
    """No pose of any tried shape reached the entropy threshold."""


def sample_object(cfg: GenConfig, index: int, lib: AssetLibrary, name: str | None = None) -> SampledObject:
    """Sample object `index` of the dataset. Raises SkippedObject when the entropy rule rejects it."""
    rng = np.random.default_rng([cfg.seed, index])
    family = cfg.lights[index % len(cfg.lights)]
    tried = []
    parts: list = []
    for _ in range(cfg.shape_tries):
        if cfg.cluster is not None:
            lo, hi = cfg.cluster_range()
            mesh, parts, source = _sample_cluster(rng, cfg, lib, int(rng.integers(lo, hi + 1)))
            # one mesh for the cluster: the writer stores it in the object folder (aux/mesh.ply)
            shape = ShapeDesc(kind="mesh", file=f"{AUX_DIR}/{MESH_FILE}", normalize=False)
        else:
            shape, source = _shape_candidates(rng, cfg, lib)
            mesh = _shape_mesh(shape)
        best = -1.0
        for _ in range(cfg.pose_tries):
            rotation = random_rotation(rng)
            entropy = visible_normal_entropy(mesh, rotation)
            best = max(best, entropy)
            if entropy >= cfg.entropy_threshold:
                break
        else:
            tried.append(f"{source!r} (best entropy {best:.2f})")  # (quoted: a file name may hold a line break)
            continue
        break
    else:
        raise SkippedObject(f"object {index}: no pose reached entropy {cfg.entropy_threshold} bits: {'; '.join(tried)}")

    focal_mm = None
    if cfg.focal is not None:  # drawn only when asked, so datasets without --focal keep their random streams
        lo, hi = cfg.focal_range()
        focal_mm = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    fov = fov_from_focal(focal_mm) if focal_mm is not None else PERSPECTIVE_FOV
    to_world, radius = fit_to_frame(mesh, rotation, cfg.camera, cfg.margin, fov)
    shape.to_world = to_world.tolist()
    centre = to_world[:3, 3].copy()
    cls = cfg.materials if cfg.materials != "any" else str(rng.choice(MATERIAL_CLASSES))
    material = sample_material(rng, cls, lib, cfg.texture_resolution)
    if cfg.detail is not None:
        material = with_detail(material, cfg, index)
    env = _environment_desc(rng, lib, cfg.env_width)
    env_scale = _environment_scale(env)
    if cfg.camera == "orthographic":
        camera = CameraDesc(
            kind="orthographic", origin=[0.0, 0.0, ORTHO_DISTANCE], half_size=1.0, width=cfg.width, height=cfg.height
        )
    else:
        camera = CameraDesc(kind="perspective", origin=[0.0, 0.0, perspective_distance(fov)], fov=fov, width=cfg.width,
                            height=cfg.height, focal_mm=focal_mm)
    lights = sample_lighting(rng, family, cfg.images, Placement(centre, radius, camera, env_scale))
    seeds = rng.integers(0, 2**31 - 1, cfg.images)
    floor = sample_floor(cfg, index, mesh.positions @ to_world[:3, :3].T + to_world[:3, 3], radius)
    uses_env = any(l.environment_map for ls in lights for l in ls)
    desc = SceneDescription(
        shape=shape,
        material=material,
        camera=camera,
        render=RenderDesc(spp=multijitter_spp(cfg.spp), bounces=cfg.bounces, gt_spp=cfg.gt_spp),
        images=[ImageDesc(lights=above_floor(ls, floor), seed=int(s)) for ls, s in zip(lights, seeds)],
        environment=env if uses_env else None,
        light_family=family,
        name=name or f"{index:05d}",
        level=cfg.level,
        parts=parts,
        floor=floor,
    )
    return SampledObject(desc=desc.validate(), mesh=mesh, shape_source=source)
