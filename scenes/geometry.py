"""Plain NumPy geometry of a scene description: camera frame, object mesh in world space, PLY files.

No Mitsuba here: `wildgen` (camera-frame lights, mesh files), `validate.known.projection` and `scenes.renderer.render`
use these without building anything; `scenes.renderer.build` turns their results into Mitsuba objects.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from scenes.description import SceneDescription
from scenes.procedural import MeshData, generate


def camera_rotation(origin, target, up) -> np.ndarray:
    """3x3 matrix R with n_cam = R @ n_world for the camera frame x right, y up, z toward the camera."""
    origin, target, up = (np.asarray(v, np.float64) for v in (origin, target, up))
    fwd = target - origin
    fwd /= np.linalg.norm(fwd)
    left = np.cross(up, fwd)
    n = np.linalg.norm(left)
    if n < 1e-9:
        raise ValueError(f"camera.up: {up.tolist()} is parallel to the viewing direction")
    left /= n
    upv = np.cross(fwd, left)
    return np.stack([-left, upv, -fwd])


def view_directions(camera) -> np.ndarray:
    """(H, W, 3) float32 unit direction from the surface seen at each pixel centre toward the camera, in the camera
    frame (x right, y up, z toward the camera; row 0 at the top). Orthographic: (0, 0, 1) everywhere.
    Perspective (pinhole, `camera.fov` across the width): the reverse of the ray through the pixel centre."""
    h, w = camera.height, camera.width
    if camera.kind == "orthographic":
        return np.broadcast_to(np.float32([0, 0, 1]), (h, w, 3)).copy()
    t = np.tan(np.radians(camera.fov) / 2.0)
    x = (2.0 * (np.arange(w) + 0.5) / w - 1.0) * t
    y = (1.0 - 2.0 * (np.arange(h) + 0.5) / h) * t * h / w
    # the ray through a pixel centre is (x, y, -1); toward the camera is its reverse
    d = np.stack(np.broadcast_arrays(-x[None, :], -y[:, None], np.ones((h, w))), -1)
    return (d / np.linalg.norm(d, axis=-1, keepdims=True)).astype(np.float32)


def mesh_data_for(desc: SceneDescription, base_dir: Path | None) -> MeshData | None:
    """Geometry of a mesh or procedural shape in object space (None for the analytic sphere)."""
    from scenes.meshes import load_mesh

    shape = desc.shape
    if shape.kind == "sphere":
        return None
    if shape.kind == "mesh":
        path = Path(shape.file)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        return load_mesh(path, normalize=shape.normalize)
    data = generate(shape.kind, shape.seed, shape.resolution, shape.params)
    if shape.normalize:
        from scenes.meshes import normalize_mesh

        data = normalize_mesh(data.positions.astype(np.float64), data.faces, data.normals, data.uvs)
    return data


def transformed_mesh(data: MeshData, to_world: list[list[float]]) -> MeshData:
    """Apply a 4x4 transform to positions (affine) and normals (inverse transpose)."""
    m = np.asarray(to_world, np.float64)
    pos = data.positions.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    nrm = data.normals.astype(np.float64) @ np.linalg.inv(m[:3, :3])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    return MeshData(pos.astype(np.float32), data.faces, nrm.astype(np.float32), data.uvs)


def write_mesh_ply(path: str | Path, data: MeshData) -> None:
    """Binary little-endian PLY with positions, normals and UVs (read back by `scenes.meshes`)."""
    n, f = len(data.positions), len(data.faces)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\n"
        f"element face {f}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode("ascii")
    verts = np.concatenate([data.positions, data.normals, data.uvs], 1).astype("<f4")
    faces = np.zeros(f, dtype=[("n", "u1"), ("idx", "<i4", (3,))])
    faces["n"] = 3
    faces["idx"] = data.faces
    Path(path).write_bytes(header + verts.tobytes() + faces.tobytes())


def lights_in_camera_frame(desc: SceneDescription, exposures: list[float] | None = None) -> list[list[dict]]:
    """Per image of a scene description, its lights in the camera frame in the report form of their types
    (`scenes.lights.camera_frame`), scaled by the image's exposure (or by `exposures`, the ones actually applied):
    the one conversion that the generator's scene.json `camera_lights` and the check's report.json `lights` share.
    An unknown light type is a ValueError, never reported as another type."""
    from scenes.lights import camera_frame

    cam = desc.camera
    R = camera_rotation(cam.origin, cam.target, cam.up)
    exposures = [image.exposure for image in desc.images] if exposures is None else exposures
    return [camera_frame(image.lights, R, cam.target, exp) for image, exp in zip(desc.images, exposures)]
