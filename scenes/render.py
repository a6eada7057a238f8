"""Rendering one object: K path-traced images from one scene, plus one cheap ground-truth pass."""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from scenes.geometry import camera_rotation
from scenes.mitsuba_build import BuiltScene
from scenes.textures import sample_texture
from scenes.variant import require_variant

log = logging.getLogger(__name__)


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
    mi = require_variant()

    built.apply_image(index)
    image = built.desc.images[index]
    out = mi.render(
        built.scene,
        spp=int(spp if spp is not None else built.desc.render.spp),
        seed=int(seed if seed is not None else image.seed),
    )
    return np.array(out, dtype=np.float32)[:, :, :3]


def render_images(built: BuiltScene, spp: int | None = None) -> list[np.ndarray]:
    """All K images of the object, from the same scene object, relit through mi.traverse."""
    return [render_image(built, i, spp=spp) for i in range(len(built.desc.images))]


def render_ground_truth(built: BuiltScene, spp: int | None = None) -> GroundTruth:
    """Normals, mask, depth and material maps from an `aov` pass (box filter, lights parked).

    The nested `depth` integrator makes alpha the pixel coverage (a one-bounce path tracer does not on scalar_rgb); AOVs of rays
    that miss are 0, so dividing by alpha gives the mean over the object's part of each pixel.
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
    out = np.array(mi.render(built.scene, integrator=integrator, spp=int(spp or desc.render.gt_spp), seed=0), np.float64)
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
        vals = arr[0, 0] * np.ones(uv.shape[:2] + (arr.shape[2],)) if arr.shape[:2] == (1, 1) else sample_texture(arr, uv)
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
