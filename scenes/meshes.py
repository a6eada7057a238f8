"""Mesh files (OBJ/PLY/STL) to `MeshData`, normalised to the unit sphere, vertex normals kept."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from scenes.checks import check_read_whole
from scenes.files import not_a_file
from scenes.procedural import MeshData, smooth_normals

log = logging.getLogger(__name__)

MESH_SUFFIXES = (".obj", ".ply", ".stl")


def load_mesh(path: str | Path, normalize: bool = True) -> MeshData:
    """Read a triangle mesh with trimesh (process=False keeps UV seams and file normals).

    Our own PLY files (`write_mesh_ply`) are read exactly; with normalize=False they are used as stored.

    Raises FileNotFoundError for a missing file and ValueError for an unknown suffix, an unreadable
    file, an empty mesh or non-finite vertices.
    """
    import trimesh

    path = Path(path)
    if why := not_a_file(path):
        raise FileNotFoundError(f"shape.file: mesh file {str(path)!r} {why}")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(
            f"shape.file: {str(path)!r} has suffix {path.suffix!r}, expected one of {', '.join(MESH_SUFFIXES)}"
        )
    check_read_whole(path, f"shape.file: mesh file {str(path)!r}")
    if path.suffix.lower() == ".obj":  # a text format: refuse binary garbage here, not deep inside trimesh
        try:
            text = path.read_bytes().decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(
                f"shape.file: {str(path)!r} is not a text OBJ file (byte {exc.start} is not UTF-8 text)"
            ) from None
        zero = next((n for n, line in enumerate(text.splitlines(), 1) if line.startswith("f ")
                     and any(v.split("/")[0] in ("0", "+0", "-0") for v in line.split()[1:])), None)
        if zero is not None:  # trimesh would read index 0 as -1, the last vertex: a silently wrong mesh
            raise ValueError(f"shape.file: {str(path)!r} line {zero}: a face index 0; OBJ counts vertices from 1")
    own = _read_own_ply(path)
    if own is not None:
        if normalize:
            return normalize_mesh(*own, name=path)
        pos, faces, nrm, uv = own
        return MeshData(pos.astype(np.float32), faces.astype(np.int32), nrm.astype(np.float32), uv.astype(np.float32))
    relative = _absolute_obj_indices(text) if path.suffix.lower() == ".obj" else None
    try:
        if relative is not None:  # trimesh resolves a negative index against the end of the file, not the line
            import io

            loaded = trimesh.load(io.BytesIO(relative.encode()), file_type="obj", process=False, force="mesh")
        else:
            loaded = trimesh.load(str(path), process=False, force="mesh")
    except ImportError as exc:  # an optional decoder trimesh wants for this file: the file is the problem
        raise ValueError(
            f"shape.file: cannot read mesh {str(path)!r}: not a mesh trimesh can decode ({exc.name or exc})"
        ) from exc
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise ValueError(f"shape.file: cannot read mesh {str(path)!r}: {type(exc).__name__}: {exc}") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.vertices) == 0 or len(loaded.faces) == 0:
        raise ValueError(f"shape.file: mesh {str(path)!r} has no triangles")
    positions = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.int64)
    if not np.all(np.isfinite(positions)):
        raise ValueError(f"shape.file: mesh {str(path)!r} has non-finite vertex positions")
    if faces.min() < 0 or faces.max() >= len(positions):
        raise ValueError(f"shape.file: mesh {str(path)!r} has face indices outside its {len(positions)} vertices")

    normals = None
    # trimesh computes normals when the file has none; only keep normals the file provides.
    if _file_has_normals(path):
        normals = np.asarray(loaded.vertex_normals, dtype=np.float64)
    if normals is None or normals.shape != positions.shape or not np.all(np.isfinite(normals)):
        normals = smooth_normals(positions, faces).astype(np.float64)

    uvs = None
    visual = getattr(loaded, "visual", None)
    if visual is not None and getattr(visual, "uv", None) is not None and len(visual.uv) == len(positions):
        uvs = np.asarray(visual.uv, dtype=np.float64)[:, :2]
        if not np.all(np.isfinite(uvs)):  # a texture lookup at NaN renders NaN
            raise ValueError(f"shape.file: mesh {str(path)!r} has non-finite texture coordinates (vt)")
    return normalize_mesh(positions, faces, normals, uvs, name=path)


def _absolute_obj_indices(text: str) -> str | None:
    """The OBJ `text` with its faces' relative indices (-1: the last vertex, texture coordinate or normal defined
    before the face, as streaming exporters write) made absolute; None when it has none (or they cannot be read:
    trimesh says what is wrong)."""
    import re

    if not re.search(r"^f .*(?:^|\s|/)-\d", text, re.MULTILINE):
        return None
    counts = {"v": 0, "vt": 0, "vn": 0}
    lines = []
    try:
        for line in text.splitlines():
            words = line.split()
            if words and words[0] in counts:
                counts[words[0]] += 1
            elif words and words[0] == "f":
                line = "f " + " ".join("/".join(
                    str(counts[key] + 1 + int(i)) if i.startswith("-") else i
                    for key, i in zip(("v", "vt", "vn"), word.split("/"))) for word in words[1:])
            lines.append(line)
    except ValueError:
        return None
    return "\n".join(lines) + "\n"


def normalize_mesh(
    positions: np.ndarray, faces: np.ndarray, normals: np.ndarray, uvs: np.ndarray | None, name: Path | None = None
) -> MeshData:
    """Centre on the bounding-box centre and scale into the unit sphere; spherical UVs if none. `name`: the file,
    for the error."""
    centre = 0.5 * (positions.min(0) + positions.max(0))
    p = positions - centre
    radius = float(np.linalg.norm(p, axis=1).max())
    if radius <= 0:
        raise ValueError(f"shape.file: mesh{'' if name is None else f' {str(name)!r}'} is degenerate (all vertices "
                         "coincide)")
    p = p / radius
    n = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    if uvs is None:
        d = p / np.maximum(np.linalg.norm(p, axis=1, keepdims=True), 1e-12)
        uvs = np.stack(
            [0.5 + np.arctan2(d[:, 2], d[:, 0]) / (2 * np.pi), np.arccos(np.clip(d[:, 1], -1, 1)) / np.pi], 1
        )
    return MeshData(
        p.astype(np.float32), faces.astype(np.int32), n.astype(np.float32), np.mod(uvs, 1.0).astype(np.float32)
    )


def _file_has_normals(path: Path) -> bool:
    suffix = path.suffix.lower()
    head = path.read_bytes()
    if suffix == ".obj":
        return b"\nvn " in head or head.startswith(b"vn ")
    if suffix == ".ply":
        end = head.find(b"end_header")
        return b"property float nx" in head[: max(end, 0)]
    return False


_OWN_PLY_PROPS = [b"x", b"y", b"z", b"nx", b"ny", b"nz", b"s", b"t"]


def _read_own_ply(path: Path):
    """Exact reader for the binary PLY layout `scenes.geometry.write_mesh_ply` writes; else None."""
    if path.suffix.lower() != ".ply":
        return None
    raw = path.read_bytes()
    end = raw.find(b"end_header\n")
    if end < 0 or not raw.startswith(b"ply\nformat binary_little_endian 1.0\n"):
        return None
    lines = raw[:end].split(b"\n")
    try:
        n = int(next(l for l in lines if l.startswith(b"element vertex")).split()[2])
        f = int(next(l for l in lines if l.startswith(b"element face")).split()[2])
    except (StopIteration, ValueError, IndexError):
        return None
    props = [l.split()[2] for l in lines if l.startswith(b"property float")]
    if props != _OWN_PLY_PROPS or b"property list uchar int vertex_indices" not in lines:
        return None
    body = raw[end + len(b"end_header\n") :]
    vbytes, fbytes = n * 32, f * 13
    if len(body) != vbytes + fbytes:
        raise ValueError(f"shape.file: PLY {str(path)!r} is truncated ({len(body)} bytes, expected {vbytes + fbytes})")
    verts = np.frombuffer(body[:vbytes], "<f4").reshape(n, 8).astype(np.float64)
    faces = np.frombuffer(body[vbytes:], dtype=[("n", "u1"), ("idx", "<i4", (3,))])
    if n == 0 or f == 0 or np.any(faces["n"] != 3):
        raise ValueError(f"shape.file: PLY {str(path)!r} has no triangles or non-triangle faces")
    idx = faces["idx"].astype(np.int64)
    if idx.min() < 0 or idx.max() >= n or not np.all(np.isfinite(verts)):
        raise ValueError(f"shape.file: PLY {str(path)!r} has bad indices or non-finite vertices")
    return verts[:, :3], idx, verts[:, 3:6], verts[:, 6:8]
