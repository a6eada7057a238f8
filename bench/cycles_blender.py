"""The Blender side of bench/bench_cycles.py: Blender itself (installed when missing), the script Blender runs to
import a wildgen object folder and render it with Cycles, the job it reads (the scene in Blender's frame), and
Cycles' multilayer EXRs read back.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

# Mitsuba world (y up, camera on +z) -> Blender world (z up, camera on -y): a proper rotation.
TO_BLENDER = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
# Mitsuba envmap local direction l -> the direction Blender's equirectangular lookup needs for the same texel:
# Mitsuba: l = (sin phi sin theta, cos theta, -cos phi sin theta), u = phi / 2 pi, row 0 = +y pole;
# Cycles: u = 0.5 - atan2(d.y, d.x) / 2 pi, top row = +z. So d = (l_z, l_x, l_y) (checked: env-only renders agree).
ENV_MI_TO_BL = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def ensure_blender() -> str:
    """Path of the `blender` binary; installs Debian's package when missing and running as root."""
    found = shutil.which("blender")
    if found:
        return found
    if os.geteuid() != 0 or not shutil.which("apt-get"):
        raise SystemExit("error: blender is not installed and this is not root with apt-get: "
                         "install it (Debian: apt-get install blender) and run again")
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    print("installing Debian's blender package (apt-get install --no-install-recommends blender) ...", flush=True)
    t0 = time.perf_counter()
    r = subprocess.run(
        ["apt-get", "install", "-y", "--no-install-recommends", "blender"], env=env, capture_output=True, text=True
    )
    if r.returncode != 0:
        subprocess.run(["apt-get", "update"], env=env, capture_output=True, text=True)
        r = subprocess.run(
            ["apt-get", "install", "-y", "--no-install-recommends", "blender"], env=env, capture_output=True, text=True
        )
    if r.returncode != 0 or not shutil.which("blender"):
        tail = (r.stderr or r.stdout).strip().splitlines()[-3:]
        raise SystemExit(f"error: apt-get install blender failed (exit {r.returncode}): {' | '.join(tail)}")
    print(f"installed in {time.perf_counter() - t0:.0f} s", flush=True)
    return shutil.which("blender")


def blender_version(blender: str) -> str:
    r = subprocess.run([blender, "-b", "--factory-startup", "--version"], capture_output=True, text=True, timeout=120)
    for line in r.stdout.splitlines():
        if line.startswith("Blender"):
            return line.strip()
    return "unknown"


# --------------------------------------------------------------------------- Blender side


BLENDER_SCRIPT = r'''
import json, math, struct, sys, time
from array import array
import bpy
from mathutils import Matrix

# Debian's Blender runs the system Python, which may lack numpy: plain arrays only.
job = json.loads(open(sys.argv[sys.argv.index("--") + 1]).read())
folder = job["folder"]

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene

# ---- mesh from aux/mesh.ply (our binary PLY: x y z nx ny nz s t per vertex, uchar+3 int faces)
raw = open(folder + "/" + job["mesh_file"], "rb").read()
end = raw.index(b"end_header\n") + len(b"end_header\n")
header = raw[:end].decode("ascii").splitlines()
nv = int([l for l in header if l.startswith("element vertex")][0].split()[-1])
nf = int([l for l in header if l.startswith("element face")][0].split()[-1])
assert sys.byteorder == "little"
verts = array("f")
verts.frombytes(raw[end:end + nv * 32])
face_bytes = raw[end + nv * 32:end + nv * 32 + nf * 13]
faces = array("i")
for k in range(nf):
    faces.extend(struct.unpack_from("<3i", face_bytes, 13 * k + 1))
co = array("f", [verts[8 * i + j] for i in range(nv) for j in range(3)])
normals = [(verts[8 * i + 3], verts[8 * i + 4], verts[8 * i + 5]) for i in range(nv)]
mesh = bpy.data.meshes.new("object")
mesh.vertices.add(nv)
mesh.vertices.foreach_set("co", co)
mesh.loops.add(nf * 3)
mesh.loops.foreach_set("vertex_index", faces)
mesh.polygons.add(nf)
mesh.polygons.foreach_set("loop_start", array("i", range(0, 3 * nf, 3)))
mesh.polygons.foreach_set("loop_total", array("i", [3] * nf))
mesh.update()
mesh.validate()
uv = mesh.uv_layers.new(name="UVMap")
uv.data.foreach_set("uv", array("f", [verts[8 * v + j] for v in faces for j in (6, 7)]))
mesh.polygons.foreach_set("use_smooth", [True] * nf)
mesh.use_auto_smooth = True  # needed for custom normals in Blender 3.x
mesh.normals_split_custom_set_from_vertices(normals)
obj = bpy.data.objects.new("object", mesh)
obj.matrix_world = Matrix(job["object_matrix"])
scene.collection.objects.link(obj)

# ---- principled material from the texture EXRs
mat = bpy.data.materials.new("material")
mat.use_nodes = True
nt = mat.node_tree
bsdf = nt.nodes["Principled BSDF"]
bsdf.distribution = "GGX"
bsdf.subsurface_method = "BURLEY"
for name, value in (("Subsurface", 0.0), ("Specular Tint", 0.0), ("Anisotropic", 0.0), ("Sheen", 0.0),
                    ("Clearcoat", 0.0), ("Transmission", 0.0)):
    bsdf.inputs[name].default_value = value
bsdf.inputs["Specular"].default_value = job["material"]["specular"]

def texture(spec, socket, colour):
    if spec["kind"] == "constant":
        v = spec["value"]
        socket.default_value = (v[0], v[1], v[2], 1.0) if colour else v[0]
        return
    node = nt.nodes.new("ShaderNodeTexImage")
    node.image = bpy.data.images.load(folder + "/" + spec["file"])
    node.image.colorspace_settings.name = "sRGB" if spec.get("srgb") else ("Linear" if colour else "Non-Color")
    node.interpolation = "Linear"
    node.extension = "REPEAT"
    if colour:
        nt.links.new(node.outputs["Color"], socket)
    else:
        sep = nt.nodes.new("ShaderNodeSeparateColor")
        nt.links.new(node.outputs["Color"], sep.inputs["Color"])
        nt.links.new(sep.outputs[spec.get("channel") or 0], socket)

texture(job["material"]["base_color"], bsdf.inputs["Base Color"], True)
texture(job["material"]["roughness"], bsdf.inputs["Roughness"], False)
texture(job["material"]["metallic"], bsdf.inputs["Metallic"], False)
mesh.materials.append(mat)

# ---- area lights
area_objects = []
for k, l in enumerate(job["areas"]):
    data = bpy.data.lights.new(f"area{k}", type="AREA")
    data.shape = "RECTANGLE"
    data.size, data.size_y = l["width"], l["height"]
    data.energy = l["power"]
    data.color = l["color"]
    data.cycles.cast_shadow = True
    data.cycles.use_multiple_importance_sampling = True
    lo = bpy.data.objects.new(f"area{k}", data)
    lo.matrix_world = Matrix(l["matrix"])
    scene.collection.objects.link(lo)
    area_objects.append(lo)

# ---- world from aux/environment.exr, rotated like the Mitsuba envmap
world = bpy.data.worlds.new("world")
scene.world = world
world.use_nodes = True
wn = world.node_tree
bg = wn.nodes["Background"]
coord = wn.nodes.new("ShaderNodeTexCoord")
mapping = wn.nodes.new("ShaderNodeMapping")
mapping.vector_type = "VECTOR"
mapping.inputs["Rotation"].default_value = Matrix(job["env_rotation"]).to_euler("XYZ")
envtex = wn.nodes.new("ShaderNodeTexEnvironment")
envtex.image = bpy.data.images.load(folder + "/" + job["env_file"])
envtex.image.colorspace_settings.name = "Linear"
envtex.interpolation = "Linear"
envtex.projection = "EQUIRECTANGULAR"
wn.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
wn.links.new(mapping.outputs["Vector"], envtex.inputs["Vector"])
wn.links.new(envtex.outputs["Color"], bg.inputs["Color"])
world.cycles.sampling_method = "AUTOMATIC"

# ---- orthographic camera
cam = bpy.data.cameras.new("camera")
cam.type = "ORTHO"
cam.ortho_scale = job["ortho_scale"]
cam.clip_start, cam.clip_end = 0.01, 1000.0
co = bpy.data.objects.new("camera", cam)
co.matrix_world = Matrix(job["camera_matrix"])
scene.collection.objects.link(co)
scene.camera = co

# ---- Cycles settings
r = scene.render
r.engine = "CYCLES"
r.resolution_x, r.resolution_y, r.resolution_percentage = job["width"], job["height"], 100
r.threads_mode, r.threads = "FIXED", job["threads"]
r.use_persistent_data = True
r.image_settings.file_format = "OPEN_EXR_MULTILAYER"
r.image_settings.color_depth = "32"
r.image_settings.exr_codec = "ZIP"
r.film_transparent = False
c = scene.cycles
c.device = "CPU"
c.use_adaptive_sampling = False
c.use_denoising = False
c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = c.volume_bounces = job["bounces"]
c.transparent_max_bounces = job["bounces"]
c.caustics_reflective = c.caustics_refractive = True
c.blur_glossy = 0.0
c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
c.light_sampling_threshold = 0.0
c.filter_type = "BOX"
c.filter_width = 1.0
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"
scene.view_layers[0].use_pass_normal = True

times = []
for render in job["renders"]:
    for k, lo in enumerate(area_objects):
        lo.hide_render = not render["area"]
    bg.inputs["Strength"].default_value = job["env_scale"] if render["env"] else 0.0
    c.samples = render["spp"]
    c.seed = render["seed"]
    r.filepath = render["out"]
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    times.append(time.perf_counter() - t0)
json.dump({"times": times}, open(job["times_out"], "w"))
'''


def blender_job(folder: Path, scene: dict, lights: dict[str, list[dict]], renders: list[dict], threads: int,
                area_factor: float, out: Path) -> dict:
    """Everything the Blender script needs, converted to Blender's frame (z up)."""
    from scenes.geometry import camera_rotation

    M = TO_BLENDER
    M4 = np.eye(4)
    M4[:3, :3] = M
    cam = scene["camera"]
    R = camera_rotation(cam["origin"], cam["target"], cam["up"])  # rows: right, up, toward camera (Mitsuba world)
    cam_m = np.eye(4)
    cam_m[:3, 0], cam_m[:3, 1], cam_m[:3, 2] = M @ R[0], M @ R[1], M @ R[2]
    cam_m[:3, 3] = M @ np.asarray(cam["origin"], float)

    areas = []
    for l in lights["area"]:
        pos = np.asarray(l["position"], float)
        fwd = np.asarray(l["target"], float) - pos
        fwd /= np.linalg.norm(fwd)
        up = np.asarray(l["up"], float)
        x = np.cross(up, fwd)
        x /= np.linalg.norm(x)
        y = np.cross(fwd, x)  # Mitsuba look_at frame: x, y, z = fwd
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2] = M @ x, M @ -y, M @ -fwd  # Blender lights shine along their local -z
        m[:3, 3] = M @ pos
        areas.append({"width": l["width"], "height": l["height"], "color": l["color"], "matrix": m.tolist(),
                      "power": area_factor * l["width"] * l["height"] * l["radiance"]})
    env = lights["env"][0]
    Rm = np.asarray(env["to_world"], float)[:3, :3]
    env_rot = ENV_MI_TO_BL @ Rm.T @ M.T  # Blender world direction -> Blender lookup direction of the same texel
    mat = scene["material"]
    if mat.get("normal_map"):
        raise SystemExit("error: normal maps are not exported (the bench uses procedural assets only)")
    textures = {}
    for key in ("base_color", "roughness", "metallic"):
        spec = dict(mat[key])
        if spec["kind"] == "file" and spec["file"].endswith(".exr"):
            spec["file"] = rgb_copy(folder, spec["file"])  # Blender reads single-channel 'Y' EXRs unreliably
        textures[key] = spec
    return {
        "folder": str(folder),
        "mesh_file": scene["shape"]["file"],
        "object_matrix": (M4 @ np.asarray(scene["shape"]["to_world"], float)).tolist(),
        "material": {**textures, "specular": mat["specular"]},
        "areas": areas,
        "env_file": scene["environment"]["file"],
        "env_rotation": env_rot.tolist(),
        "env_scale": env["scale"],
        "ortho_scale": 2.0 * cam["half_size"],
        "camera_matrix": cam_m.tolist(),
        "width": cam["width"],
        "height": cam["height"],
        "threads": threads,
        "bounces": scene["render"]["bounces"],
        "renders": renders,
        "times_out": str(out / "cycles_times.json"),
    }


def rgb_copy(folder: Path, rel: str) -> str:
    """An RGB copy of a texture EXR next to it (same values in every channel for scalar maps)."""
    from scenes.images import read_exr, write_exr

    arr = read_exr(folder / rel)
    if arr.shape[2] == 3:
        return rel
    dst = Path(rel).with_name(Path(rel).stem + "_rgb.exr")
    write_exr(folder / dst, np.repeat(arr[:, :, :1], 3, axis=2))
    return str(dst)


def read_multilayer(path: Path) -> dict[str, np.ndarray]:
    """Blender multilayer EXR -> {'combined': (H, W, 3), 'normal': (H, W, 3)}."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = {k: np.asarray(v.pixels, np.float32) for k, v in f.channels().items()}

    def get(layer: str, names: str) -> np.ndarray:
        keys = [next(k for k in ch if k.endswith(f"{layer}.{n}")) for n in names]
        return np.stack([ch[k] for k in keys], -1)

    return {"combined": get("Combined", "RGB"), "normal": get("Normal", "XYZ")}
