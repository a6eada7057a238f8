"""Texture arrays: seeded procedural patterns (noise, cells, stripes) and image files.

All arrays are float32 (H, W, C) in Mitsuba's texture orientation: row 0 is v = 0. Patterns are periodic
in u and v (integer frequencies, wrapped cell distances) so that UV seams do not show.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from scenes.colors import srgb_to_linear
from scenes.description import TextureDesc
from scenes.files import not_a_file


def _pattern(kind: str, res: int, scale: float, seed: int) -> np.ndarray:
    """Scalar field in [0, 1] of shape (res, res)."""
    rng = np.random.default_rng(seed)
    v, u = np.meshgrid((np.arange(res) + 0.5) / res, (np.arange(res) + 0.5) / res, indexing="ij")
    base = max(1, int(round(scale)))
    if kind == "noise":
        field = np.zeros_like(u)
        amp = 1.0
        for octave in range(4):
            f = base * 2**octave
            for _ in range(3):
                kx, ky = rng.integers(-f, f + 1, 2)
                if kx == 0 and ky == 0:
                    kx = f
                field += amp * np.sin(2 * np.pi * (kx * u + ky * v) + rng.uniform(0, 2 * np.pi))
            amp *= 0.5
        field = (field - field.min()) / max(np.ptp(field), 1e-8)
        return field
    if kind == "cells":
        n = max(2, base * base)
        pts = rng.uniform(0, 1, (n, 2))
        values = rng.uniform(0, 1, n)
        best = np.full(u.shape, np.inf)
        out = np.zeros_like(u)
        for (px, py), val in zip(pts, values):
            dx = np.abs(u - px)
            dy = np.abs(v - py)
            d = np.minimum(dx, 1 - dx) ** 2 + np.minimum(dy, 1 - dy) ** 2
            closer = d < best
            best[closer] = d[closer]
            out[closer] = val
        return out
    if kind == "stripes":
        kx, ky = rng.integers(0, base + 1, 2)
        if kx == 0 and ky == 0:
            kx = base
        s = np.sin(2 * np.pi * (kx * u + ky * v) + rng.uniform(0, 2 * np.pi))
        return 0.5 + 0.5 * np.tanh(4 * s)
    raise ValueError(f"texture.kind: unknown pattern {kind!r}, expected noise, cells or stripes")


def read_image_file(path: Path) -> np.ndarray:
    """Float32 (H, W, C) from EXR/HDR/PNG/JPG, in file orientation (row 0 at the top), RGB order."""
    import cv2

    from scenes.images import decode_image

    if why := not_a_file(path):
        raise FileNotFoundError(f"texture file {str(path)!r} {why}")
    if path.suffix.lower() == ".exr":
        from scenes.images import read_exr

        return read_exr(path)
    img = decode_image(path, cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR,
                       f"texture file {str(path)!r}")
    if img is None:
        raise ValueError(f"texture file {str(path)!r} cannot be decoded as an image")
    if img.ndim == 2:
        img = img[:, :, None]
    if img.shape[2] >= 3:
        img = img[:, :, [2, 1, 0] + list(range(3, img.shape[2]))]
    if img.dtype == np.uint8:
        img = img.astype(np.float32) / 255.0
    elif img.dtype == np.uint16:
        img = img.astype(np.float32) / 65535.0
    else:
        img = img.astype(np.float32)
    return img


def outside_unit_range(img: np.ndarray, path: Path) -> str | None:
    """What is wrong with the values of map `img` (of file `path`) where they leave [0, 1] (a map of reflectance,
    roughness or metal, or an encoded normal; never radiance), else None."""
    if img.size and not (float(img.min()) >= 0 and float(img.max()) <= 1 + 1e-6):
        return (f"{str(path)!r} holds values from {float(img.min()):.4g} to {float(img.max()):.4g}; expected 0 to 1 "
                "(a map of reflectance, roughness, metal or an encoded normal)")
    return None


def realize_texture(tex: TextureDesc, base_dir: Path | None = None, owner: str = "texture",
                    rgb: bool = False) -> np.ndarray:
    """The texture as an array (H, W, C), C = len(tex.value); constants give a 1x1 array. `owner`: the scene field
    it is (material.roughness), named in its errors. A file's values must lie in [0, 1] (reflectances and encoded
    normals, never radiance); with `rgb` it must hold three channels (a normal map: a grey file is a height map)."""
    channels = len(tex.value)
    if tex.kind == "constant":
        return np.asarray(tex.value, np.float32).reshape(1, 1, channels)
    if tex.kind == "file":
        path = Path(tex.file)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        try:
            img = read_image_file(path)
        except (FileNotFoundError, ValueError) as exc:  # the file is named; the field that named it, here
            raise type(exc)(f"{owner}.file: {exc}") from None
        if tex.srgb:
            img = srgb_to_linear(img[:, :, :3])
        if rgb and img.shape[2] < 3:
            raise ValueError(f"{owner}.file: {str(path)!r} has {img.shape[2]} channel(s), expected 3 (a tangent-space "
                             "normal map, (n + 1) / 2)")
        if channels == 1:
            ch = tex.channel if tex.channel is not None else 0
            if ch >= img.shape[2]:
                raise ValueError(f"{owner}.channel: {ch} out of range for {str(path)!r} with {img.shape[2]} channels")
            img = img[:, :, ch : ch + 1]
        else:
            img = img[:, :, :3] if img.shape[2] >= 3 else np.repeat(img[:, :, :1], 3, 2)
        if why := outside_unit_range(img, path):
            raise ValueError(f"{owner}.file: {why}")
        # Image files have row 0 at the top (v = 1); Mitsuba's row 0 is v = 0.
        return np.ascontiguousarray(img[::-1]).astype(np.float32)
    t = _pattern(tex.kind, tex.resolution, tex.scale, tex.seed)[:, :, None]
    a = np.asarray(tex.value, np.float32)
    b = np.asarray(tex.value2 if tex.value2 is not None else tex.value, np.float32)
    return (a * (1 - t) + b * t).astype(np.float32)


def sample_texture(arr: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of texture `arr` (H, W, C) at uv (..., 2) with wrap-around, Mitsuba's orientation."""
    h, w, _ = arr.shape
    x = np.mod(uv[..., 0], 1.0) * w - 0.5
    y = np.mod(uv[..., 1], 1.0) * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    x0m, x1m = np.mod(x0, w), np.mod(x0 + 1, w)
    y0m, y1m = np.mod(y0, h), np.mod(y0 + 1, h)
    return (
        arr[y0m, x0m] * (1 - fx) * (1 - fy)
        + arr[y0m, x1m] * fx * (1 - fy)
        + arr[y1m, x0m] * (1 - fx) * fy
        + arr[y1m, x1m] * fx * fy
    ).astype(np.float32)
