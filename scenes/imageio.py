"""Image files of the dataset layout: 16-bit PNG, 8-bit mask, 16-bit normal TIFF, float EXR."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np


def to_uint16(x: np.ndarray) -> np.ndarray:
    """Linear [0, 1] floats to uint16, clipped and rounded."""
    return np.round(np.clip(x, 0.0, 1.0) * 65535.0).astype(np.uint16)


def write_png16(path: str | Path, rgb: np.ndarray) -> None:
    """(H, W, 3) float in [0, 1] or uint16 -> 16-bit RGB PNG (no gamma: linear values)."""
    import cv2

    data = rgb if rgb.dtype == np.uint16 else to_uint16(rgb)
    if not cv2.imwrite(str(path), np.ascontiguousarray(data[:, :, ::-1])):
        raise OSError(f"could not write {str(path)!r}")


def read_png16(path: str | Path) -> np.ndarray:
    """16-bit (or 8-bit) RGB PNG -> (H, W, 3) float32 in [0, 1]."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"cannot read image {str(path)!r}")
    scale = 65535.0 if img.dtype == np.uint16 else 255.0
    if img.ndim == 3:
        img = img[:, :, ::-1]
    return img.astype(np.float32) / scale


def write_mask(path: str | Path, mask: np.ndarray) -> None:
    import cv2

    if not cv2.imwrite(str(path), np.where(mask, 255, 0).astype(np.uint8)):
        raise OSError(f"could not write {str(path)!r}")


def encode_normals(n: np.ndarray) -> np.ndarray:
    """Unit normals (H, W, 3) (background exactly 0) -> uint16 (n + 1) / 2; background -> 32768."""
    return np.round(np.clip((n + 1.0) * 0.5, 0.0, 1.0) * 65535.0 + 0.5 * (n == 0)).astype(np.uint16)


def decode_normals(enc: np.ndarray) -> np.ndarray:
    """uint16 (n + 1) / 2 -> float normals; the 32768 background code maps back to 0."""
    n = enc.astype(np.float32) / 65535.0 * 2.0 - 1.0
    n[np.all(enc == 32768, axis=-1)] = 0.0
    return n


def write_normal_tif(path: str | Path, n: np.ndarray) -> None:
    """Camera-space normals -> 16-bit RGB TIFF (the UniPS `normal.tif`), written with OpenCV (BGR)."""
    import cv2

    if not cv2.imwrite(str(path), np.ascontiguousarray(encode_normals(n)[:, :, ::-1])):
        raise OSError(f"could not write {str(path)!r}")


def write_exr(path: str | Path, data: np.ndarray) -> None:
    """float32 (H, W), (H, W, 1) or (H, W, 3) -> EXR with channels Y or R, G, B."""
    import OpenEXR

    data = np.asarray(data, np.float32)
    if data.ndim == 3 and data.shape[2] == 1:
        data = data[:, :, 0]
    if data.ndim == 2:
        channels = {"Y": np.ascontiguousarray(data)}
    elif data.ndim == 3 and data.shape[2] == 3:
        channels = {c: np.ascontiguousarray(data[:, :, i]) for i, c in enumerate("RGB")}
    else:
        raise ValueError(f"write_exr: data shape {data.shape} is not (H, W), (H, W, 1) or (H, W, 3)")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, dict(channels)) as f:
        f.write(str(path))


def read_exr(path: str | Path) -> np.ndarray:
    """EXR -> float32 (H, W, C): RGB(A) when present, else its single channel."""
    import OpenEXR

    if not Path(path).is_file():
        raise FileNotFoundError(f"EXR file {str(path)!r} does not exist")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            ch = {k: np.asarray(v.pixels, np.float32) for k, v in f.channels().items()}
    except Exception as exc:
        raise ValueError(f"cannot read EXR {str(path)!r}: {exc}") from exc
    if all(c in ch for c in "RGB"):
        return np.stack([ch["R"], ch["G"], ch["B"]], -1)
    if len(ch) == 1:
        return next(iter(ch.values()))[:, :, None]
    names = sorted(ch)
    return np.stack([ch[k] for k in names], -1)


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write a text file through a temporary name and rename, so readers never see half a file."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)
