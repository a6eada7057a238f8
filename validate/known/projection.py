"""The camera model of a scene as plain numbers: projecting world points to continuous pixel
coordinates and generating the rays through given pixel positions.

It reproduces Mitsuba's sensors as `scenes.renderer.build.sensor_dict` builds them:
- orthographic: `look_at(origin, target, up) @ scale(s, s, 1)`; the film spans camera x in [-s, s] and
  camera y in [-s H/W, s H/W] (Mitsuba keeps square pixels);
- perspective: `fov` is the full horizontal angle (`fov_axis = x`), the same square-pixel rule.
Pixel (i, j) (row i from the top, column j from the left) covers [j, j+1] x [i, i+1] in continuous
coordinates (u, v): u grows to the right, v grows downward.

The same formulas are written once more in Dr.Jit inside `validate.known.normal_bsdf`; the tests check both
against Mitsuba's own ground-truth pass.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from scenes.description import CameraDesc
from scenes.geometry import camera_rotation


@dataclass
class CameraProjection:
    """Orthographic or perspective camera, in numbers a JSON string or a Dr.Jit kernel can carry."""

    kind: str
    """'orthographic' or 'perspective'."""
    origin: list[float]
    """Camera position (world)."""
    right: list[float]
    """World direction of image +x (camera frame x)."""
    up: list[float]
    """World direction of image +y (camera frame y)."""
    forward: list[float]
    """World viewing direction (camera frame -z)."""
    half_width: float
    """orthographic: half of the visible width (world units); perspective: tan(fov / 2)."""
    width: int
    """Image width in pixels."""
    height: int
    """Image height in pixels."""

    @classmethod
    def from_camera(cls, cam: CameraDesc) -> "CameraProjection":
        R = camera_rotation(cam.origin, cam.target, cam.up)  # rows: right, up, backward
        if cam.kind == "orthographic":
            half = float(cam.half_size)
        elif cam.kind == "perspective":
            half = math.tan(math.radians(cam.fov) / 2.0)
        else:
            raise ValueError(f"camera.kind: {cam.kind!r} is not supported, expected orthographic or perspective")
        return cls(
            kind=cam.kind,
            origin=[float(x) for x in cam.origin],
            right=R[0].tolist(),
            up=R[1].tolist(),
            forward=(-R[2]).tolist(),
            half_width=half,
            width=int(cam.width),
            height=int(cam.height),
        )

    @property
    def aspect(self) -> float:
        """Height over width: the film's half height is `aspect` times its half width."""
        return self.height / self.width

    @property
    def rotation(self) -> np.ndarray:
        """3x3 R with n_cam = R @ n_world (rows right, up, backward)."""
        return np.stack([self.right, self.up, -np.asarray(self.forward)])

    def to_dict(self) -> dict:
        return asdict(self)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World points (N, 3) -> continuous pixel coordinates u, v (N,) and depth z (N,) along `forward`."""
        d = np.asarray(points, np.float64) - np.asarray(self.origin)
        cx, cy, z = d @ np.asarray(self.right), d @ np.asarray(self.up), d @ np.asarray(self.forward)
        hw = self.half_width if self.kind == "orthographic" else self.half_width * np.maximum(z, 1e-12)
        u = (cx / hw + 1.0) * 0.5 * self.width
        v = (1.0 - cy / (hw * self.aspect)) * 0.5 * self.height
        return u, v, z

    def rays(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rays (origins (N, 3), unit directions (N, 3)) through continuous pixel positions u, v (N,)."""
        x = 2.0 * np.asarray(u, np.float64) / self.width - 1.0  # in [-1, 1] across the film
        y = (1.0 - 2.0 * np.asarray(v, np.float64) / self.height) * self.aspect
        right, up, fwd, o = (np.asarray(a, np.float64) for a in (self.right, self.up, self.forward, self.origin))
        if self.kind == "orthographic":
            origins = o + (x * self.half_width)[:, None] * right + (y * self.half_width)[:, None] * up
            dirs = np.broadcast_to(fwd, origins.shape).copy()
        else:
            dirs = fwd + (x * self.half_width)[:, None] * right + (y * self.half_width)[:, None] * up
            dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
            origins = np.broadcast_to(o, dirs.shape).copy()
        return origins, dirs

