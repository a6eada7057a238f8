"""One object of a dataset: sample, render and write its `<name>.data` folder atomically (temporary name,
then rename), and its manifest entry (`make_object`, the unit of work every engine runs).

The folder holds no timestamps or host names (those go into the manifest), so the same seed gives
byte-identical folders whatever the Dr.Jit thread count (scenes.renderer.render.render_film; docs/generator.md,
"Crash safety, resume and determinism").
"""
from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from scenes.camera_sensor import SCENE_KEY as SENSOR_KEY
from scenes.camera_sensor import SENSORS, Sensor, rederive_image, scale_camera_lights, sensor_record, write_image
from scenes.description import SceneDescription, TextureDesc
from scenes.files import sha256_file
from scenes.folder.format import (
    AUX_DIR,
    FORMAT_VERSION,
    INSTANCES_FILE,
    MASK_FILE,
    MESH_FILE,
    NORMAL_BASE_FILE,
    NORMAL_FILE,
    OBJECT_SUFFIX,
    image_name,
    radiance_name,
    write_scene,
)
from scenes.geometry import lights_in_camera_frame, view_directions, write_mesh_ply
from scenes.images import write_exr, write_instances, write_mask, write_normal_map, write_png16
from scenes.renderer.build import build_scene
from scenes.renderer.render import instance_ids, render_ground_truth, render_images
from wildgen.assets import AssetLibrary
from wildgen.config import GenConfig
from wildgen.sampling import SampledObject, SkippedObject, sample_object

log = logging.getLogger(__name__)

TMP_PREFIX = ".tmp-"


@dataclass
class ObjectResult:
    """What was written for one object, for the manifest."""

    name: str
    folder: str
    light_family: str
    material_class: str
    shape: str
    files: dict[str, str] = field(default_factory=dict)  # relative path -> sha256
    timings: dict[str, float] = field(default_factory=dict)


def _localise(desc: SceneDescription, sampled: SampledObject, folder: Path) -> SceneDescription:
    """Copy/realise every input file into aux/ and point the description at it (self-contained folder)."""
    from scenes.textures import realize_texture

    aux = folder / AUX_DIR
    d = SceneDescription.from_dict(json.loads(json.dumps(desc.to_dict())))  # deep copy through plain data
    write_mesh_ply(aux / MESH_FILE, sampled.mesh)
    d.shape.kind, d.shape.file, d.shape.normalize = "mesh", f"{AUX_DIR}/{MESH_FILE}", False
    d.shape.params, d.shape.seed = {}, 0

    def local_texture(tex: TextureDesc, name: str) -> TextureDesc:
        if tex.kind == "constant":
            return tex
        if tex.kind == "file":
            src = Path(tex.file)
            dst = aux / f"{name}{src.suffix.lower()}"
            shutil.copyfile(src, dst)
            tex.file = f"{AUX_DIR}/{dst.name}"
            return tex
        arr = realize_texture(tex)
        write_exr(aux / f"{name}.exr", np.ascontiguousarray(arr[::-1]))  # files keep row 0 at the top
        channels = len(tex.value)
        return TextureDesc(
            kind="file", value=tex.value, file=f"{AUX_DIR}/{name}.exr", channel=0 if channels == 1 else None
        )

    d.material.base_color = local_texture(d.material.base_color, "texture_base_color")
    d.material.roughness = local_texture(d.material.roughness, "texture_roughness")
    d.material.metallic = local_texture(d.material.metallic, "texture_metallic")
    if d.material.detail is not None and not d.material.normal_map:
        from scenes.detail import realize_detail

        # the file keeps row 0 at the top (v = 1), as every normal-map file
        write_normal_map(aux / "texture_normal.png", realize_detail(d.material.detail)[::-1] * 2.0 - 1.0)
        d.material.normal_map = f"{AUX_DIR}/texture_normal.png"
    elif d.material.normal_map:
        src = Path(d.material.normal_map)
        dst = aux / f"texture_normal{src.suffix.lower()}"
        shutil.copyfile(src, dst)
        d.material.normal_map = f"{AUX_DIR}/{dst.name}"
    if d.environment is not None:
        env = d.environment
        if env.source == "file":
            src = Path(env.file)
            dst = aux / f"environment{src.suffix.lower()}"
            shutil.copyfile(src, dst)
            env.file = f"{AUX_DIR}/{dst.name}"
        else:
            from scenes.envmaps import realize_environment

            write_exr(aux / "environment.exr", realize_environment(env))
            env.source, env.file, env.seed = "file", f"{AUX_DIR}/environment.exr", 0
    return d


def camera_lights(desc: SceneDescription) -> list[dict]:
    """Per image, the directional lights in the camera frame (toward the light, irradiance x exposure), for
    calibrated methods, and how many other lights the image has. Every light goes through its type's report
    form (`scenes.lights.LIGHT_TYPES`): an unknown type is a ValueError, never counted as another."""
    out = []
    for lights in lights_in_camera_frame(desc):
        dirs = [{k: v for k, v in l.items() if k != "type"} for l in lights if l["type"] == "directional"]
        out.append({"directional": dirs, "other": len(lights) - len(dirs)})
    return out


def exposure_for(radiance: np.ndarray, mask: np.ndarray, percentile: float, level: float) -> float:
    """Factor that maps the given percentile of the masked pixel values to `level`."""
    values = radiance[mask].ravel() if mask.any() else radiance.ravel()
    p = float(np.percentile(values, percentile)) if values.size else 0.0
    return float(level / p) if p > 1e-12 else 1.0


def ground_truth_problem(normal: np.ndarray, mask: np.ndarray, camera, max_backfacing: float) -> str | None:
    """Why a rendered ground truth is unusable, or None: an empty mask, non-finite normals inside it, or more
    than `max_backfacing` of them facing away from the camera (e.g. a mesh with coincident opposite faces
    gives noise normals, about half of them facing away)."""
    import math

    n = int(mask.sum())
    if n == 0:
        return "the object covers no pixel (empty mask)"
    inside = normal[mask].astype(np.float64)
    bad = int((~np.isfinite(inside).all(axis=1)).sum())
    if bad:
        return f"{bad} of {n} ground-truth normals inside the mask are NaN or infinite"
    # Camera frame, z toward the camera: a visible normal has n_z >= 0 under an orthographic camera, and
    # n_z >= -sin(half the diagonal field of view) under a perspective one.
    tol = 0.0
    if camera.kind == "perspective":
        half = math.atan(math.tan(math.radians(camera.fov) / 2) * math.hypot(1.0, camera.height / camera.width))
        tol = math.sin(half)
    away = float(np.mean(inside[:, 2] < -tol - 1e-3))
    if away > max_backfacing:
        return (f"{away:.0%} of the ground-truth normals inside the mask face away from the camera (at most "
                f"{max_backfacing:.0%} accepted; a mesh with coincident opposite faces or inverted normals?)")
    return None


def base_normals(desc: SceneDescription, base_dir: Path) -> np.ndarray:
    """Camera-frame normals of the object's geometry without its normal map (the detail-free ground truth)."""
    plain = dataclasses.replace(desc, material=dataclasses.replace(desc.material, normal_map=None, detail=None))
    return render_ground_truth(build_scene(plain, base_dir=base_dir)).normal


def publish_folder(tmp: Path, final: Path) -> dict[str, str]:
    """Checksum a fully written temporary object folder and rename it to its final name (replacing an earlier
    one of this dataset): readers never see half a folder. Returns {relative path: sha256}.

    A folder already there is replaced only when it holds exactly the files this object writes, by name (an earlier
    render of the same object, finished after the manifest's last write); one holding anything else, or less (a
    user's folder with an L000.png of their own), is somebody's and is kept: the object fails (ValueError, not
    retried) and the run goes on."""
    files = {str(p.relative_to(tmp)): sha256_file(p) for p in sorted(tmp.rglob("*")) if p.is_file()}
    if os.path.lexists(final):
        there = [] if final.is_symlink() or not final.is_dir() else sorted(final.rglob("*"))
        foreign = final if final.is_symlink() or not final.is_dir() else next(
            (p for p in there if p.is_symlink() or (not p.is_dir() and str(p.relative_to(final)) not in files)), None)
        why = None if foreign is None else f"{str(foreign)!r} is not a file this object writes"
        if why is None and {str(p.relative_to(final)) for p in there if not p.is_dir()} != set(files):
            why = "it lacks files an earlier render of this object would hold"  # a user's folder under its name
        if why is not None:
            shutil.rmtree(tmp, ignore_errors=True)
            raise ValueError(f"{str(final)!r} is there already and is not this dataset's ({why}): it is kept; move it "
                             "away, then run again to render this object")
        shutil.rmtree(final)
    os.replace(tmp, final)
    return files


def write_object(sampled: SampledObject, out_dir: Path, percentile: float, level: float,
                 max_backfacing: float = 0.1, sensor: Sensor | None = None) -> ObjectResult:
    """Render `sampled` and write `out_dir/<name>.data`, atomically. Returns the manifest entry.

    sensor: what turns each image's radiance into its PNG (`scenes.camera_sensor`); None or `ideal` writes the linear
    16-bit rendering and records nothing (the folder is byte-identical to one written before sensors existed);
    any other sensor is recorded in scene.json with each image's noise seed, so every PNG can be re-derived.

    Raises SkippedObject (nothing written) when the ground truth fails `ground_truth_problem`."""
    name = sampled.desc.name
    final = out_dir / f"{name}{OBJECT_SUFFIX}"
    tmp = out_dir / f"{TMP_PREFIX}{name}{OBJECT_SUFFIX}.{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    (tmp / AUX_DIR).mkdir(parents=True)
    timings: dict[str, float] = {}
    try:
        t0 = time.perf_counter()
        desc = _localise(sampled.desc, sampled, tmp)
        built = build_scene(desc, base_dir=tmp)
        timings["build_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        gt = render_ground_truth(built)
        timings["ground_truth_s"] = time.perf_counter() - t0
        problem = ground_truth_problem(gt.normal, gt.mask, desc.camera, max_backfacing)
        if problem is not None:
            raise SkippedObject(f"object {name}: ground truth rejected: {problem}")
        instances = instance_ids(built, gt.mask) if desc.parts else None
        t0 = time.perf_counter()
        radiance = render_images(built)
        timings["render_s"] = time.perf_counter() - t0
        del built

        t0 = time.perf_counter()
        real_sensor = sensor is not None and sensor != SENSORS["ideal"]
        for i, img in enumerate(radiance):
            desc.images[i].exposure = exposure_for(img, gt.mask, percentile, level)
        record = sensor_record(sensor, [im.seed for im in desc.images]) if real_sensor else None
        for i, img in enumerate(radiance):
            if record is None:
                write_png16(tmp / image_name(i), img * desc.images[i].exposure)
            else:
                write_image(tmp / image_name(i),
                            rederive_image(img, desc.images[i].exposure, sensor, record["noise_seeds"][i]))
            write_exr(tmp / AUX_DIR / radiance_name(i), img)
        write_mask(tmp / MASK_FILE, gt.mask)
        normal = np.where(gt.mask[..., None], gt.normal, 0.0)
        write_normal_map(tmp / NORMAL_FILE, normal)
        if desc.parts:
            write_instances(tmp / AUX_DIR / INSTANCES_FILE, instances)
        if desc.material.normal_map:
            t1 = time.perf_counter()
            write_normal_map(tmp / NORMAL_BASE_FILE, np.where(gt.mask[..., None], base_normals(desc, tmp), 0.0))
            timings["ground_truth_base_s"] = time.perf_counter() - t1
        write_exr(tmp / AUX_DIR / "normal.exr", gt.normal)
        write_exr(tmp / AUX_DIR / "depth.exr", gt.depth)
        write_exr(tmp / AUX_DIR / "coverage.exr", gt.coverage)
        write_exr(tmp / AUX_DIR / "base_color.exr", gt.base_color)
        write_exr(tmp / AUX_DIR / "roughness.exr", gt.roughness)
        write_exr(tmp / AUX_DIR / "metallic.exr", gt.metallic)
        write_exr(tmp / AUX_DIR / "view.exr", view_directions(desc.camera))
        extras = {"camera_lights": camera_lights(desc), "format_version": FORMAT_VERSION}
        if record is not None:
            extras[SENSOR_KEY] = record
            extras["camera_lights"] = scale_camera_lights(extras["camera_lights"], sensor.exposure)
        write_scene(tmp, desc, extras)
        timings["write_s"] = time.perf_counter() - t0
        files = publish_folder(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return ObjectResult(
        name=name,
        folder=final.name,
        light_family=desc.light_family,
        material_class=desc.material.material_class,
        shape=sampled.shape_source if not sampled.shape_source.startswith("/") else Path(sampled.shape_source).name,
        files=files,
        timings=timings,
    )


def index_name(index: int) -> str:
    """Name of object `index` (its folder is `<name>.data`)."""
    return f"{index:05d}"


def make_object(cfg: GenConfig, index: int, out_dir: Path, lib: AssetLibrary | None = None) -> dict:
    """Sample, render and write object `index`; a pure function of (cfg, index). Returns its manifest entry."""
    lib = lib if lib is not None else AssetLibrary.scan(cfg.assets)
    name = index_name(index)
    t0 = time.perf_counter()
    try:
        sampled = sample_object(cfg, index, lib, name=name)
        result = write_object(sampled, Path(out_dir), cfg.exposure_percentile, cfg.exposure_level, cfg.max_backfacing,
                              sensor=SENSORS[cfg.sensor])
    except SkippedObject as exc:  # the entropy rule or the ground-truth check: deterministic, recorded with its reason
        log.info("%s", exc)
        return {"index": index, "name": name, "status": "skipped", "reason": str(exc)}
    entry = {"index": index, "status": "done", **asdict(result)}
    entry["timings"]["total_s"] = time.perf_counter() - t0
    return entry


def failed_entry(index: int, error: str, attempts: int, name: str | None = None) -> dict:
    """Manifest entry of an object that failed `attempts` times (last error kept); `name` where the object has one
    already (a source dataset's), else its index's."""
    if name is None and isinstance(index, int):
        name = index_name(index)
    return {"index": index, "name": name, "status": "failed", "error": error, "attempts": attempts}
