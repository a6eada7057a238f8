"""A picture of an integrated surface shaded under one light, rendered by Mitsuba: how a user sees the shape that
the normal map makes (the capture page shows it beside the map)."""
from __future__ import annotations

import numpy as np

from scenes.renderer.variant import require_variant

LIGHT_FROM = (-0.45, 0.55, 0.70)
"""Direction toward the light in the camera frame (from the upper left, in front): the usual shading of a relief."""
AMBIENT = 0.12
"""Uniform environment radiance, so that what the light does not reach stays readable."""


def shaded_surface(points: np.ndarray, faces: np.ndarray, shape: tuple[int, int], focal_px: float | None,
                   spp: int = 32) -> np.ndarray:
    """(H, W) float32 radiance of the mesh (points (P, 3) in the camera frame x right, y up, z toward the camera, the
    camera at the origin looking down -z; faces (F, 3)) under `LIGHT_FROM` and `AMBIENT`, with a grey diffuse
    material and the faces' own normals. `focal_px`: a pinhole of that focal length centred on the image; None: an
    orthographic camera whose pixels are one unit wide (the integrator's orthographic frame)."""
    mi = require_variant()
    h, w = shape
    props = mi.Properties()
    props["bsdf"] = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.7, 0.7]}})
    mesh = mi.Mesh("surface", len(points), len(faces), props, False, False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = type(params["vertex_positions"])(np.ascontiguousarray(points, np.float32).ravel())
    params["faces"] = type(params["faces"])(np.ascontiguousarray(faces, np.uint32).ravel())
    params.update()
    far = float(np.abs(points[:, 2]).max()) * 2.0 + 1.0
    look = mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0])
    if focal_px is None:
        sensor = {"type": "orthographic", "to_world": look @ mi.ScalarTransform4f().scale([w / 2, w / 2, 1]),
                  "near_clip": 1e-3, "far_clip": far}
    else:
        sensor = {"type": "perspective", "fov": float(np.degrees(2 * np.arctan(w / 2 / focal_px))), "fov_axis": "x",
                  "to_world": look, "near_clip": 1e-3 * far, "far_clip": far}
    sensor["film"] = {"type": "hdrfilm", "width": w, "height": h, "pixel_format": "rgb", "rfilter": {"type": "box"}}
    sensor["sampler"] = {"type": "independent", "sample_count": spp}
    light = np.asarray(LIGHT_FROM, float) / np.linalg.norm(LIGHT_FROM)
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "direct"}, "sensor": sensor, "surface": mesh,
                          "sun": {"type": "directional", "direction": (-light).tolist(),
                                  "irradiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
                          "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [AMBIENT] * 3}}})
    img = np.array(mi.render(scene, seed=0), dtype=np.float32)
    return img.mean(axis=-1)
