"""Reading what the re-render check needs: object folders (`<name>.data/`) and predicted normal maps.

Object folder (see ARCHITECTURE.md): `L000.png..` 16-bit linear images, `mask.png`, optional `normal.tif`,
`scene.json` (a `SceneDescription` plus extra top-level keys such as `camera_lights` and
`format_version`, which are ignored here).

Normal maps: camera frame (x right, y up, z toward the camera), full frame, as `unips.predict` writes
them: 16-bit PNG / TIFF with (n + 1) / 2 and background 32768 (decoded to 0), float EXR, or `.npy` (H, W, 3);
read with `unips.normal_io.read_normals`.
"""
from __future__ import annotations

import json
import logging
import re
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from scenes.description import SceneDescription
from scenes.imageio import read_png16

log = logging.getLogger(__name__)

NORMAL_NAMES = ("normal.png", "normal.exr", "normal.npy", "normal.tif", "normal.tiff")
"""File names looked for in a prediction folder, in this order."""
UNIT_TOLERANCE = 0.02
"""Largest accepted | |n| - 1 | inside the mask (16-bit PNG rounding is below 1e-4)."""
_IMAGE_RE = re.compile(r"^L(\d+)\.png$")


@dataclass
class ObjectData:
    """One object folder, loaded."""

    folder: Path
    """The `<name>.data` folder (relative paths in scene.json resolve against it)."""
    name: str
    """Folder name without '.data'."""
    desc: SceneDescription
    """The scene of the K images."""
    images: np.ndarray
    """(K, H, W, 3) float32 linear input images in [0, 1] (exposure applied, as stored)."""
    mask: np.ndarray
    """(H, W) bool object mask."""
    normal_gt: np.ndarray | None
    """(H, W, 3) float32 ground-truth camera-frame normals from normal.tif (0 outside the mask), or None."""


def object_name(folder: str | Path) -> str:
    name = Path(folder).name
    return name[: -len(".data")] if name.endswith(".data") else name


def read_scene_json(path: str | Path) -> SceneDescription:
    """scene.json -> SceneDescription, ignoring top-level keys that are not description fields."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"scene.json: {str(path)!r} does not exist (is this an object folder?)")
    try:
        d = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"scene.json: {str(path)!r} is not valid JSON: {exc}") from exc
    if not isinstance(d, dict):
        raise ValueError(f"scene.json: {str(path)!r} holds a {type(d).__name__}, expected an object")
    known = {f.name for f in fields(SceneDescription)}
    extra = sorted(set(d) - known)
    if extra:
        log.debug("scene.json: ignoring extra keys %s", extra)
    desc = SceneDescription.from_dict({k: v for k, v in d.items() if k in known})
    return desc.validate()


def _image_files(folder: Path) -> list[Path]:
    found = {}
    for p in folder.iterdir():
        m = _IMAGE_RE.match(p.name)
        if m:
            found[int(m.group(1))] = p
    indices = sorted(found)
    if indices != list(range(len(indices))):
        missing = sorted(set(range(max(indices, default=-1) + 1)) - set(indices))
        raise ValueError(f"images: {str(folder)!r} has L*.png files with gaps (missing indices {missing[:10]})")
    return [found[i] for i in indices]


def load_object(folder: str | Path) -> ObjectData:
    """Load an object folder; raise FileNotFoundError / ValueError naming what is missing or inconsistent."""
    import cv2

    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"--data: {str(folder)!r} is not a folder")
    desc = read_scene_json(folder / "scene.json")
    files = _image_files(folder)
    if len(files) != len(desc.images):
        raise ValueError(
            f"images: {str(folder)!r} has {len(files)} L*.png files but scene.json describes {len(desc.images)} images"
        )
    h, w = desc.camera.height, desc.camera.width
    images = np.empty((len(files), h, w, 3), np.float32)
    for i, f in enumerate(files):
        img = read_png16(f)
        if img.ndim != 3 or img.shape[:2] != (h, w):
            raise ValueError(f"images: {str(f)!r} has shape {img.shape}, expected ({h}, {w}, 3) from scene.json")
        images[i] = img[:, :, :3]
    mask_path = folder / "mask.png"
    if not mask_path.is_file():
        raise FileNotFoundError(f"mask: {str(mask_path)!r} does not exist")
    m = cv2.imread(str(mask_path), cv2.IMREAD_UNCHANGED)
    if m is None:
        raise ValueError(f"mask: cannot read {str(mask_path)!r}")
    if m.ndim == 3:
        m = m[:, :, 0]
    if m.shape != (h, w):
        raise ValueError(f"mask: {str(mask_path)!r} has shape {m.shape}, expected ({h}, {w})")
    mask = m > (m.max() / 2 if m.max() > 0 else 0)
    if not mask.any():
        raise ValueError(f"mask: {str(mask_path)!r} is empty")
    normal_gt = None
    tif = folder / "normal.tif"
    if tif.is_file():
        normal_gt = read_normal_map(tif)
        if normal_gt.shape != (h, w, 3):
            raise ValueError(f"normal.tif: {str(tif)!r} has shape {normal_gt.shape}, expected ({h}, {w}, 3)")
        normal_gt = np.where(mask[..., None], _renormalise(normal_gt), 0.0).astype(np.float32)
    return ObjectData(folder=folder, name=object_name(folder), desc=desc, images=images, mask=mask, normal_gt=normal_gt)


def read_normal_map(path: str | Path) -> np.ndarray:
    """Normal-map file -> (H, W, 3) float32 camera-frame normals, background 0 (not checked against a
    mask here). Reading is `unips.normal_io.read_normals` (the project's one reader: OpenCV for 16-bit
    PNG/TIFF in BGR order, EXR, .npy, .mat); it rejects non-finite values anywhere in the map."""
    from unips.normal_io import read_normals

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"--normals: {str(path)!r} does not exist")
    return read_normals(path)


def _renormalise(n: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(norm > 0.5, n / np.maximum(norm, 1e-12), 0.0)


def check_normals(
    n: np.ndarray, mask: np.ndarray, source: str = "--normals", allow_missing: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Check a normal map against an object mask.

    Returns (normals renormalised where valid and 0 elsewhere, valid (H, W) bool). Valid is the mask,
    minus the exactly-zero normals inside it when `allow_missing` (a predictor's "no estimate", e.g.
    pixels dark in every image). Raises ValueError for a wrong shape, or NaN / infinite / non-unit
    normals inside the mask.
    """
    n = np.asarray(n)
    if n.ndim != 3 or n.shape[2] != 3 or n.shape[:2] != mask.shape:
        raise ValueError(f"{source}: normal map has shape {n.shape}, expected {mask.shape + (3,)} (the size of the input images)")
    valid = mask.copy()
    if allow_missing:
        valid &= np.any(n != 0, axis=-1)
    inside = n[valid].astype(np.float64)
    bad = ~np.isfinite(inside).all(axis=1)
    if bad.any():
        raise ValueError(f"{source}: {int(bad.sum())} normal(s) inside the mask are NaN or infinite")
    norm = np.linalg.norm(inside, axis=1)
    off = np.abs(norm - 1.0) > UNIT_TOLERANCE
    if off.any():
        zero = int(np.sum(norm[off] == 0))
        hint = f"; {zero} of them are exactly 0 (no estimate): --allow-missing keeps the surface's own normal there" if zero else ""
        raise ValueError(
            f"{source}: {int(off.sum())} normal(s) inside the mask are not unit length "
            f"(|n| from {norm.min():.3f} to {norm.max():.3f}, tolerance {UNIT_TOLERANCE}){hint}"
        )
    out = np.zeros(mask.shape + (3,), np.float32)
    out[valid] = (inside / norm[:, None]).astype(np.float32)
    return out, valid


def find_prediction(pred: str | Path, name: str | None = None) -> Path:
    """The normal-map file for an object: `pred` itself if a file, else `pred[/name]/normal.{png,exr,npy,tif}`."""
    pred = Path(pred)
    if pred.is_file():
        return pred
    folders = [pred / name, pred] if name else [pred]
    for folder in folders:
        for fname in NORMAL_NAMES:
            if (folder / fname).is_file():
                return folder / fname
    where = " or ".join(str(f) for f in folders)
    raise FileNotFoundError(f"--normals: no {'/'.join(NORMAL_NAMES)} in {where}")


def list_objects(dataset: str | Path) -> list[Path]:
    """Object folders (`*.data` with a scene.json) of a dataset folder, sorted by name."""
    dataset = Path(dataset)
    folders = sorted(p for p in dataset.iterdir() if p.is_dir() and p.name.endswith(".data") and not p.name.startswith("."))
    if not folders:
        raise FileNotFoundError(f"--data: {str(dataset)!r} has no scene.json and no *.data object folders")
    for f in folders:
        if not (f / "scene.json").is_file():
            raise FileNotFoundError(f"--data: object folder {str(f)!r} has no scene.json")
    return folders
