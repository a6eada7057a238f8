"""Rendering one object: K path-traced images from one scene, plus one cheap ground-truth pass.

Every render goes through `render_film`. On the JIT variants (llvm_ad_rgb, cuda_ad_rgb) it does what
`mi.render` does (same sampler, seeding, camera rays and integrator, so the same samples) except the film
accumulation: `mi.render` adds the samples of a pixel into the film with atomic scatter-adds, and where the
samples of one pixel fall into the work blocks of two Dr.Jit threads their float sum depends on which thread
adds first. Here every sample's value is written to its own slot (no scatter, no atomics) and the samples of
each pixel are summed in sample order by one Dr.Jit lane (`pixel_sums`: float64, then divided by the sample
count and rounded to float32). The bytes therefore depend only on (scene, spp, seed), not on the thread count or
the machine's scheduling. The scalar variant keeps `mi.render`: its image tiles do not overlap under the box filter, so
each pixel is rendered by one thread (measured identical for 1, 2 and 3 Dr.Jit threads at 32x32).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from scenes.geometry import camera_rotation
from scenes.renderer.build import BuiltScene
from scenes.renderer.variant import require_variant
from scenes.textures import sample_texture

log = logging.getLogger(__name__)

MAX_SAMPLES_PER_PASS = 1 << 22
"""Samples of a 4-channel film traced in one kernel launch of `render_film` (films with C channels: 4 / C of it),
which bounds the per-sample output buffer to 64 MiB; more samples are split into passes of spp / p samples per
pixel, p the smallest divisor of spp that fits, and the passes are summed in order. Each pass traces the
integrator again and launches its own kernel: at 128 x 128 px and 256 spp one pass instead of four renders 6 %
faster (bench/bench_profile.py). Raised from 1 << 20 in issue 42, which changed the bytes of path-traced images
above 1M samples (e.g. 128 px at 256 spp, 256 px at 64 or 256 spp); the ground-truth pass (12 channels) splits
as before at 128-512 px."""


def render_film(scene, spp: int, seed: int, integrator=None) -> np.ndarray:
    """(H, W, C) float32 film of `scene`'s first sensor, laid out as `mi.render` returns it (RGB, alpha, then the
    integrator's AOVs; tests/test_determinism.py checks the layout against `mi.render` at 1 spp); the mean of
    `spp` samples per pixel drawn from the scene's sampler seeded with `seed` (what `mi.render` returns, up to
    the float rounding of the sum), independent of the Dr.Jit thread count (see the module docstring)."""
    mi = require_variant()
    import drjit as dr

    if not dr.is_jit_v(mi.Float):
        return np.array(mi.render(scene, integrator=integrator, spp=int(spp), seed=int(seed)), dtype=np.float32)
    integrator = integrator if integrator is not None else scene.integrator()
    sensor = scene.sensors()[0]
    film = sensor.film()
    if film.sample_border() or not film.rfilter().is_box_filter() or any(int(v) for v in film.crop_offset()):
        raise ValueError("render_film needs a box-filtered film without crop offset or border sampling")
    width, height = (int(v) for v in film.crop_size())
    # A nested integrator's own values (AOVs named `integrator.*`) are not in mi.render's output either.
    kept = [not name.startswith("integrator.") for name in integrator.aov_names()]
    limit = MAX_SAMPLES_PER_PASS * 4 // (4 + sum(kept))
    sampler = sensor.sampler()
    sampler.set_sample_count(int(spp))
    spp = int(sampler.sample_count())  # a stratified sampler may round the count
    per = next(p for p in range(spp, 0, -1) if spp % p == 0 and (width * height * p <= limit or p == 1))
    passes, n = spp // per, width * height * per
    sampler.set_samples_per_wavefront(per)
    seed_v = mi.UInt32(int(seed))
    dr.make_opaque(seed_v)  # a new seed must not bake a new literal into (and recompile) the kernel
    sampler.seed(seed_v, n)
    idx = dr.arange(mi.UInt32, n) // dr.opaque(mi.UInt32, per)  # sample -> pixel, as mi.render orders them
    row = idx // width
    pixel = mi.Vector2f(mi.Vector2i(idx - row * width, row))
    scale = mi.ScalarVector2f(1.0 / width, 1.0 / height)
    diff_scale = float(1.0 / np.sqrt(np.float32(spp), dtype=np.float32))
    total = None
    for _ in range(passes):
        film_pos = (pixel + sampler.next_2d()) * scale
        aperture = sampler.next_2d() if sensor.needs_aperture_sample() else mi.Point2f(0.5)
        time = mi.Float(sensor.shutter_open())
        if sensor.shutter_open_time() > 0:
            time += sampler.next_1d() * sensor.shutter_open_time()
        ray, weight = sensor.sample_ray_differential(time, mi.Float(0.0), film_pos, aperture)
        if ray.has_differentials:
            ray.scale_differential(diff_scale)
        spec, valid, aovs = integrator.sample(scene, sampler, ray, None, True)
        rgb = weight * spec
        aovs = [a for a, keep in zip(aovs, kept) if keep]
        channels = [rgb.x, rgb.y, rgb.z, dr.select(valid, mi.Float(1.0), mi.Float(0.0)), *aovs]
        if passes > 1:
            sampler.advance()
            sampler.schedule_state()
        dr.eval(*channels)
        part = pixel_sums(mi, channels, per, width * height).reshape(height, width, -1)
        total = part if total is None else total + part
    return (total / spp).astype(np.float32)


def pixel_sums(mi, channels: list, per: int, pixels: int) -> np.ndarray:
    """(pixels, C) float64: the sum of each pixel's `per` consecutive samples of every channel (each a Float of
    pixels * per evaluated values), added one after the other in sample order in float64.

    One Dr.Jit lane per pixel runs the loop, so the order of the additions (hence every bit of the result) does not
    depend on how the lanes are split over threads; it is the order NumPy's `sum(axis=..., dtype=float64)` over the
    sample axis used before (tests/test_determinism.py compares the two), without reading the per-sample buffer
    back. The loop is symbolic and `per` opaque: one compiled kernel serves every sample count."""
    import drjit as dr

    count = dr.opaque(mi.UInt32, per)
    first = dr.arange(mi.UInt32, pixels) * count
    zero = [dr.zeros(mi.Float64, pixels) for _ in channels]

    def body(s, sums):
        return s + 1, [acc + mi.Float64(dr.gather(mi.Float, c, first + s)) for acc, c in zip(sums, channels)]

    _, sums = dr.while_loop(state=(mi.UInt32(0), zero), cond=lambda s, sums: s < count, body=body,
                            labels=("s", "sums"))
    dr.eval(sums)
    return np.stack([np.asarray(v, dtype=np.float64) for v in sums], axis=-1)


@dataclass
class GroundTruth:
    """Per-pixel ground truth in the camera frame; background pixels are 0."""

    normal: np.ndarray  # (H, W, 3) float32, unit inside the mask, x right / y up / z toward the camera
    mask: np.ndarray  # (H, W) bool, pixel coverage >= 0.5
    coverage: np.ndarray  # (H, W) float32 in [0, 1], fraction of the pixel covered by the object
    depth: np.ndarray  # (H, W) float32, camera-z distance (along the viewing direction)
    base_color: np.ndarray  # (H, W, 3) float32
    roughness: np.ndarray  # (H, W) float32
    metallic: np.ndarray  # (H, W) float32
    uv: np.ndarray  # (H, W, 2) float32, mean texture coordinate


def render_image(built: BuiltScene, index: int, spp: int | None = None, seed: int | None = None) -> np.ndarray:
    """Linear RGB radiance (H, W, 3) float32 of image `index`, with its recorded seed unless overridden."""
    require_variant()

    built.apply_image(index)
    image = built.desc.images[index]
    out = render_film(
        built.scene,
        spp=int(spp if spp is not None else built.desc.render.spp),
        seed=int(seed if seed is not None else image.seed),
    )
    return np.ascontiguousarray(out[:, :, :3])


def render_images(built: BuiltScene, spp: int | None = None) -> list[np.ndarray]:
    """All K images of the object, from the same scene object, relit through mi.traverse."""
    return [render_image(built, i, spp=spp) for i in range(len(built.desc.images))]


def render_ground_truth(built: BuiltScene, spp: int | None = None) -> GroundTruth:
    """Normals, mask, depth and material maps from an `aov` pass (box filter, lights parked).

    The nested `depth` integrator makes alpha the pixel coverage (a one-bounce path tracer does not on scalar_rgb);
    AOVs of rays that miss are 0, so dividing by alpha gives the mean over the object's part of each pixel.
    """
    mi = require_variant()

    desc = built.desc
    built.park_lights()
    integrator = mi.load_dict(
        {
            "type": "aov",
            "aovs": "nn:sh_normal,pp:position,uv:uv",
            "integrator": {"type": "depth"},  # cheap; its alpha is the coverage on every variant
        }
    )
    out = render_film(built.object_scene, spp=int(spp or desc.render.gt_spp), seed=0,
                      integrator=integrator).astype(np.float64)  # the object alone: no floor in the truth
    if built.current_image is None and desc.images:
        built.apply_image(0)
    alpha = out[:, :, 3]
    normal_w, pos, uv = out[:, :, 4:7], out[:, :, 7:10], out[:, :, 10:12]
    hit = alpha > 1e-6
    safe = np.where(hit, alpha, 1.0)[..., None]
    pos, uv = pos / safe, uv / safe

    # Note: with a `normalmap` BSDF, Mitsuba's sh_normal AOV already is the perturbed shading normal.
    cam = desc.camera
    R = camera_rotation(cam.origin, cam.target, cam.up)
    n_cam = normal_w @ R.T
    norm = np.linalg.norm(n_cam, axis=-1, keepdims=True)
    n_cam = np.where(hit[..., None] & (norm > 1e-8), n_cam / np.maximum(norm, 1e-12), 0.0)
    fwd = -R[2]
    depth = np.where(hit, (pos - np.asarray(cam.origin)) @ fwd, 0.0)

    def lookup(name: str, channels: int) -> np.ndarray:
        arr = built.textures[name]
        vals = (
            arr[0, 0] * np.ones(uv.shape[:2] + (arr.shape[2],)) if arr.shape[:2] == (1, 1) else sample_texture(arr, uv)
        )
        vals = np.where(hit[..., None], vals, 0.0)
        return vals[..., :channels] if channels > 1 else vals[..., 0]

    return GroundTruth(
        normal=n_cam.astype(np.float32),
        mask=alpha >= 0.5,
        coverage=np.clip(alpha, 0, 1).astype(np.float32),
        depth=depth.astype(np.float32),
        base_color=lookup("base_color", 3).astype(np.float32),
        roughness=lookup("roughness", 1).astype(np.float32),
        metallic=lookup("metallic", 1).astype(np.float32),
        uv=np.where(hit[..., None], uv, 0.0).astype(np.float32),
    )


def instance_ids(built: BuiltScene, mask: np.ndarray) -> np.ndarray:
    """(H, W) uint16: which part of a cluster (`desc.parts`, id i + 1) the ray through each pixel centre hits first,
    0 for the background. Ray casting at pixel centres gives one exact id per pixel, where a film would average
    them; mask pixels whose centre ray misses (the object covers half the pixel, not its centre) take the id of the
    nearest pixel that has one, and pixels outside the mask are 0."""
    from scipy.ndimage import distance_transform_edt

    mi = require_variant()
    desc = built.desc
    cam = desc.camera
    h, w = cam.height, cam.width
    sensor = built.object_scene.sensors()[0]
    jj, ii = np.meshgrid(np.arange(w), np.arange(h))
    uv = mi.Point2f(((jj.ravel() + 0.5) / w).astype(np.float32), ((ii.ravel() + 0.5) / h).astype(np.float32))
    ray, _ = sensor.sample_ray(0.0, 0.5, uv, mi.Point2f(0.5, 0.5))
    si = built.object_scene.ray_intersect(ray)
    valid = np.array(si.is_valid(), bool).reshape(h, w)
    prim = np.array(si.prim_index, np.int64).reshape(h, w)
    ends = np.cumsum([p.faces for p in desc.parts])
    ids = np.where(valid, np.searchsorted(ends, prim, side="right") + 1, 0)
    ids = np.where(ids > len(ends), 0, ids)  # an emitter's triangles (never in view) are not a part
    hole = mask & (ids == 0)
    if hole.any() and (ids > 0).any():
        _, (ni, nj) = distance_transform_edt(ids == 0, return_indices=True)
        ids = np.where(hole, ids[ni, nj], ids)
    return np.where(mask, ids, 0).astype(np.uint16)
