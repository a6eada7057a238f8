"""Normal-map files and angular error.

Normals are (H, W, 3) float arrays in the camera frame (x right, y up, z toward the camera), unit
length on the object and exactly zero on the background. On disk:

- 16-bit PNG / TIFF: RGB = round((n + 1) / 2 * 65535); the background (n = 0) is 32768 in every channel.
  Written with OpenCV in BGR order so that OpenCV (and any RGB-aware reader) reads RGB back.
- 8-bit PNG (DiLiGenT's ``Normal_gt.png``, visualisations): RGB = (n + 1) / 2 * 255.
- float EXR (channels R, G, B), ``.npy`` and MATLAB ``.mat`` hold n itself.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

#: Encoded value of n = 0 in a 16-bit normal map.
BACKGROUND_16 = 32768


def _check_normals(n: np.ndarray, what: str) -> np.ndarray:
    """Return n as float32 (H, W, 3) after checking its shape and that it is finite."""
    n = np.asarray(n)
    if n.ndim != 3 or n.shape[2] != 3:
        raise ValueError(f"{what}: expected a normal map of shape (H, W, 3), got shape {n.shape}")
    if not np.issubdtype(n.dtype, np.number):
        raise ValueError(f"{what}: expected a numeric array, got dtype {n.dtype}")
    n = n.astype(np.float32)
    if not np.all(np.isfinite(n)):
        raise ValueError(f"{what}: normal map contains NaN or infinite values")
    return n


def _background(n: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels whose normal is exactly zero."""
    return ~np.any(n != 0, axis=2)


def _imwrite(path: Path, image: np.ndarray) -> None:
    import cv2

    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), image):
        raise ValueError(f"path: cannot write image file {path} (unsupported extension or unwritable)")


def encode_normals_16(n: np.ndarray) -> np.ndarray:
    """(H, W, 3) normals -> (H, W, 3) uint16 RGB, (n + 1) / 2 * 65535, background 32768."""
    n = _check_normals(n, "n")
    enc = np.round((np.clip(n, -1.0, 1.0) + 1.0) * 0.5 * 65535.0).astype(np.uint16)
    enc[_background(n)] = BACKGROUND_16
    return enc


def write_normal_png(path: str | Path, n: np.ndarray) -> None:
    """Write a 16-bit RGB normal map (PNG or TIFF, chosen by the extension)."""
    enc = encode_normals_16(n)
    _imwrite(Path(path), np.ascontiguousarray(enc[..., ::-1]))  # OpenCV writes BGR


def write_normal_exr(path: str | Path, n: np.ndarray) -> None:
    """Write normals as a float32 OpenEXR file with channels R, G, B."""
    import OpenEXR

    n = _check_normals(n, "n")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    channels = {c: np.ascontiguousarray(n[..., i]) for i, c in enumerate("RGB")}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    # OpenEXR replaces the dict's values with Channel objects: hand it a copy.
    OpenEXR.File(header, dict(channels)).write(str(path))


def write_normal_visual(path: str | Path, n: np.ndarray) -> None:
    """Write an 8-bit RGB picture of the normals, (n + 1) / 2, background black."""
    n = _check_normals(n, "n")
    vis = np.round((np.clip(n, -1.0, 1.0) + 1.0) * 0.5 * 255.0).astype(np.uint8)
    vis[_background(n)] = 0
    _imwrite(Path(path), np.ascontiguousarray(vis[..., ::-1]))


def _read_exr(path: Path) -> np.ndarray:
    import OpenEXR

    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            ch = {name: np.asarray(c.pixels) for name, c in f.channels().items()}
    except Exception as exc:  # OpenEXR raises several types for corrupt files
        raise ValueError(f"path: cannot read EXR file {path}: {exc}") from exc
    missing = [c for c in "RGB" if c not in ch]
    if missing:
        raise ValueError(f"path: EXR file {path} lacks channels {missing} (has {sorted(ch)})")
    return np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float32)


def _read_mat(path: Path) -> np.ndarray:
    import scipy.io

    try:
        data = scipy.io.loadmat(str(path))
    except Exception as exc:
        raise ValueError(f"path: cannot read MAT file {path}: {exc}") from exc
    arrays = {k: v for k, v in data.items() if not k.startswith("__")}
    for key in ("Normal_gt", "normal", "normals", "Normal_est", "N"):
        if key in arrays:
            return np.asarray(arrays[key], dtype=np.float32)
    if len(arrays) == 1:
        return np.asarray(next(iter(arrays.values())), dtype=np.float32)
    raise ValueError(f"path: MAT file {path} has no 'Normal_gt' key and several arrays {sorted(arrays)}")


def decode_normal_image(img: np.ndarray, what: str) -> np.ndarray:
    """Decode an RGB integer normal image (uint8 or uint16) to float normals.

    Pixels whose decoded vector is shorter than 0.5 (the encoded zero vector, 32768 or 128) become 0.
    Float images are taken as n itself.
    """
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"{what}: expected a 3-channel normal image, got shape {img.shape}")
    if img.dtype == np.uint16:
        n = img.astype(np.float32) / 65535.0 * 2.0 - 1.0
    elif img.dtype == np.uint8:
        n = img.astype(np.float32) / 255.0 * 2.0 - 1.0
    elif np.issubdtype(img.dtype, np.floating):
        n = img.astype(np.float32)
    else:
        raise ValueError(f"{what}: unsupported normal image dtype {img.dtype} (expected uint8, uint16 or float)")
    if np.issubdtype(img.dtype, np.integer):
        n[np.linalg.norm(n, axis=2) < 0.5] = 0.0
    return n


def read_normals(path: str | Path) -> np.ndarray:
    """Read a normal map written by this module or a dataset: .png/.tif/.tiff, .exr, .npy, .mat.

    Returns (H, W, 3) float32; background pixels are 0. Raises FileNotFoundError for a missing file,
    ValueError for unreadable files, wrong shapes or non-finite values.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"path: normal map {path} does not exist")
    suffix = path.suffix.lower()
    if suffix in (".png", ".tif", ".tiff"):
        import cv2

        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise ValueError(f"path: cannot read image file {path} (corrupt or unsupported)")
        if img.ndim != 3 or img.shape[2] not in (3, 4):
            raise ValueError(f"path: normal image {path} must be RGB, got shape {img.shape}")
        n = decode_normal_image(np.ascontiguousarray(img[..., 2::-1]), f"path {path}")
    elif suffix == ".exr":
        n = _read_exr(path)
    elif suffix == ".npy":
        try:
            n = np.load(path, allow_pickle=False)
        except Exception as exc:
            raise ValueError(f"path: cannot read NPY file {path}: {exc}") from exc
    elif suffix == ".mat":
        n = _read_mat(path)
    else:
        raise ValueError(f"path: unsupported normal-map extension {suffix!r} for {path} "
                         "(expected .png, .tif, .tiff, .exr, .npy or .mat)")
    return _check_normals(n, f"normal map {path}")


def _unit(n: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    return n / np.maximum(norm, 1e-12)


def angular_error_deg(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W) angular error in degrees inside mask, 0 outside.

    Both maps are normalised first; a zero predicted normal inside the mask counts as 90 degrees.
    """
    pred = _check_normals(pred, "pred")
    gt = _check_normals(gt, "gt")
    mask = np.asarray(mask)
    if pred.shape != gt.shape:
        raise ValueError(f"pred: shape {pred.shape} differs from gt shape {gt.shape}")
    if mask.shape != pred.shape[:2]:
        raise ValueError(f"mask: shape {mask.shape} differs from the normal maps' {pred.shape[:2]}")
    mask = mask.astype(bool)
    dot = np.clip(np.sum(_unit(pred.astype(np.float64)) * _unit(gt.astype(np.float64)), axis=-1), -1.0, 1.0)
    err = np.degrees(np.arccos(dot))
    err[~mask] = 0.0
    return err.astype(np.float32)


def mean_angular_error(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> float:
    """Mean angular error in degrees over the mask (which must not be empty)."""
    mask = np.asarray(mask).astype(bool)
    if not mask.any():
        raise ValueError("mask: is empty, cannot average the angular error")
    err = angular_error_deg(pred, gt, mask)
    return float(np.mean(err[mask], dtype=np.float64))
