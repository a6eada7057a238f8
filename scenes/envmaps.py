"""Environment maps as float32 (H, W, 3) equirectangular arrays: files and seeded procedural maps.

Mitsuba's `envmap` convention (its plugin source): texel row 0 is the +y pole, theta = pi i / (H - 1),
phi = 2 pi (j + 0.5) / W, local direction (sin phi sin theta, cos theta, -cos phi sin theta).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from scenes.description import EnvironmentDesc
from scenes.files import not_a_file


def directions(h: int, w: int) -> np.ndarray:
    """Unit direction of every texel, (H, W, 3), in the map's local frame."""
    theta = np.pi * np.arange(h) / (h - 1)
    phi = 2 * np.pi * (np.arange(w) + 0.5) / w
    t, p = np.meshgrid(theta, phi, indexing="ij")
    return np.stack([np.sin(p) * np.sin(t), np.cos(t), -np.cos(p) * np.sin(t)], -1)


def _blob(d: np.ndarray, centre: np.ndarray, width: float) -> np.ndarray:
    return np.exp((d @ centre - 1.0) / (width * width))


def indoor(seed: int, width: int) -> np.ndarray:
    """A room: dim wall/floor gradient, a few bright rectangular windows and small warm lamps."""
    rng = np.random.default_rng(seed)
    h = width // 2
    d = directions(h, width)
    up = d[..., 1:2]
    wall = rng.uniform(0.05, 0.2, 3) * rng.uniform(0.7, 1.0)
    env = np.where(up > 0, wall * (0.7 + 0.3 * up), wall * 0.5 * (1 + up)).astype(np.float64)
    for _ in range(rng.integers(1, 4)):  # windows: bright, sharp-edged rectangles in (phi, theta)
        phi0 = rng.uniform(0, 2 * np.pi)
        th0 = rng.uniform(0.25 * np.pi, 0.6 * np.pi)
        dphi = rng.uniform(0.15, 0.5)
        dth = rng.uniform(0.1, 0.35)
        theta = np.arccos(np.clip(d[..., 1], -1, 1))
        phi = np.mod(np.arctan2(d[..., 0], -d[..., 2]), 2 * np.pi)
        dp = np.abs(np.mod(phi - phi0 + np.pi, 2 * np.pi) - np.pi)
        inside = (dp < dphi) & (np.abs(theta - th0) < dth)
        env[inside] += rng.uniform(3, 12) * np.array([0.9, 0.95, 1.0]) * rng.uniform(0.9, 1.1, 3)
    for _ in range(rng.integers(0, 4)):  # lamps: small warm spots
        c = rng.normal(size=3)
        c[1] = abs(c[1]) + 0.3
        c /= np.linalg.norm(c)
        env += rng.uniform(20, 80) * _blob(d, c, rng.uniform(0.04, 0.08))[..., None] * np.array([1.0, 0.8, 0.55])
    return env.astype(np.float32)


def sky(seed: int, width: int) -> np.ndarray:
    """Outdoor sky: blue gradient, bright sun disc with halo, darker ground."""
    rng = np.random.default_rng(seed)
    h = width // 2
    d = directions(h, width)
    up = d[..., 1:2]
    zenith = np.array([0.25, 0.45, 1.0]) * rng.uniform(0.5, 1.5)
    horizon = np.array([0.9, 0.9, 1.0]) * rng.uniform(0.5, 1.5)
    env = np.where(
        up > 0, horizon + (zenith - horizon) * np.sqrt(np.clip(up, 0, 1)), 0.3 * horizon * np.array([0.8, 0.7, 0.6])
    )
    elev = rng.uniform(0.1, 1.3)
    az = rng.uniform(0, 2 * np.pi)
    sun = np.array([np.cos(elev) * np.sin(az), np.sin(elev), -np.cos(elev) * np.cos(az)])
    env = env + rng.uniform(300, 1500) * _blob(d, sun, 0.02)[..., None] * np.array([1.0, 0.95, 0.85])
    env = env + 2.0 * _blob(d, sun, 0.3)[..., None]
    return env.astype(np.float32)


MAX_RADIANCE = 1e9
"""The largest value of an environment map: a sun's pixel is about 1e5; sums of values beyond overflow float32."""


def load_environment(path: Path) -> np.ndarray:
    """Equirectangular .hdr/.exr file -> float32 (H, W, 3) RGB."""
    import cv2

    from scenes.images import decode_image, read_exr

    if why := not_a_file(path):
        raise FileNotFoundError(f"environment.file: {str(path)!r} {why}")
    suffix = path.suffix.lower()
    if suffix == ".exr":
        img = read_exr(path)
        img = img[:, :, :3] if img.ndim == 3 else img
    elif suffix == ".hdr":
        try:
            with open(path, "rb") as f:  # OpenCV decodes by content: a PNG named .hdr would be read as low-range
                magic = f.read(10)
        except OSError as exc:
            raise ValueError(f"environment.file: {str(path)!r} cannot be opened: {exc.strerror or exc}") from None
        if not magic.startswith(b"#?"):  # every Radiance file's first line: #?RADIANCE, #?RGBE or a program's name
            raise ValueError(f"environment.file: {str(path)!r} is not a Radiance HDR file (it begins with "
                             f"{magic[:6]!r}, not #?); expected an .hdr light probe")
        img = decode_image(path, cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH, f"environment.file: {str(path)!r}")
        if img is None:
            raise ValueError(f"environment.file: cannot decode {str(path)!r} as a Radiance HDR image")
        img = img[:, :, ::-1] if img.ndim == 3 else img
    else:
        raise ValueError(f"environment.file: {str(path)!r} has suffix {suffix!r}, expected .hdr or .exr")
    img = np.ascontiguousarray(img, dtype=np.float32)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"environment.file: {str(path)!r} holds {img.shape[2] if img.ndim == 3 else 1} channel(s); "
                         "expected an RGB map")
    if not np.all(np.isfinite(img)) or img.min() < 0:
        raise ValueError(f"environment.file: {str(path)!r} is not a finite non-negative RGB map")
    if not 0 < (peak := float(img.max())) <= MAX_RADIANCE:  # black lights nothing; beyond, float32 sums overflow
        raise ValueError(f"environment.file: {str(path)!r} " + ("is black (it lights nothing)" if peak <= 0 else
                         f"has values up to {peak:.3g}, above {MAX_RADIANCE:g}") + "; expected a light probe's "
                         "radiance (a sun a few 1e5 at most)")
    return img


def realize_environment(env: EnvironmentDesc, base_dir: Path | None = None) -> np.ndarray:
    """The environment map of `env` as float32 (H, W, 3)."""
    if env.source == "file":
        path = Path(env.file)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        return load_environment(path)
    if env.source == "indoor":
        return indoor(env.seed, env.width)
    return sky(env.seed, env.width)
