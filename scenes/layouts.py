"""Which photometric-stereo folder layout a folder is, and its files in loader order.

The one home of layout detection for both readers: `unips.data` (what the model sees) and
`validate.capture` (what the fitted re-render check sees). Layouts:

- ``"ours"``: ``L000.png ...`` + ``scene.json`` (`scenes.objfolder` owns the rest of the folder);
- ``"diligent"``: ``light_directions.txt`` + ``001.png ...`` (order from ``filenames.txt`` when present);
- ``"unips"``: official UniPS / SDM-UniPS ``L*`` images without a scene file.

Detected in that order. Everything here reads names and text files only, never images.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

LAYOUTS = ("ours", "unips", "diligent")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
"""Suffixes of ``L*`` images that the official loaders read (their ``L*[!.txt]`` pattern, minus text files)."""
ALL_IMAGE_SUFFIXES = IMAGE_SUFFIXES + (".exr",)
"""Those plus float EXR, which `validate.capture` also reads; what layout detection looks for."""


def natural_key(name: str) -> list[Any]:
    """Sort key so that L2 comes before L10; zero-padded names sort as usual."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


def l_images(folder: str | Path, suffixes: tuple[str, ...] = IMAGE_SUFFIXES) -> list[Path]:
    """Files ``L*`` with one of `suffixes`, in natural order."""
    folder = Path(folder)
    return sorted((p for p in folder.iterdir() if p.is_file() and p.name.startswith("L") and p.suffix.lower() in suffixes),
                  key=lambda p: natural_key(p.name))


def digit_images(folder: str | Path) -> list[Path]:
    """DiLiGenT-style ``001.png ...`` (all-digit stems), in natural order."""
    folder = Path(folder)
    return sorted((p for p in folder.iterdir() if p.is_file() and p.suffix.lower() == ".png" and p.stem.isdigit()),
                  key=lambda p: natural_key(p.name))


def diligent_images(folder: str | Path) -> list[Path]:
    """A DiLiGenT folder's images: in ``filenames.txt`` order when the file exists, else `digit_images`."""
    folder = Path(folder)
    listing = folder / "filenames.txt"
    if listing.is_file():
        return [folder / line.strip() for line in listing.read_text().splitlines() if line.strip()]
    return digit_images(folder)


def detect_layout(path: str | Path) -> str | None:
    """Layout name of an object folder (one of LAYOUTS), or None when the folder is not one."""
    folder = Path(path)
    if not folder.is_dir():
        return None
    has_l = bool(l_images(folder, ALL_IMAGE_SUFFIXES))
    if has_l and (folder / "scene.json").is_file():
        return "ours"
    if (folder / "light_directions.txt").is_file() and ((folder / "filenames.txt").is_file() or digit_images(folder)):
        return "diligent"
    return "unips" if has_l else None


def read_text_matrix(path: Path, rows: int, what: str) -> np.ndarray:
    """(rows, 3) float64 matrix from a whitespace / comma separated text file (DiLiGenT's light files),
    checked: one line, naming `what`, for a missing file, non-numbers, a wrong shape or non-finite values."""
    if not path.is_file():
        raise FileNotFoundError(f"{what} file {path} does not exist")
    try:
        text = path.read_text().replace(",", " ")
        values = np.array([[float(v) for v in line.split()] for line in text.splitlines() if line.strip()], dtype=np.float64)
    except ValueError as exc:
        raise ValueError(f"{what} file {path}: cannot parse numbers ({exc})") from exc
    if values.ndim != 2 or values.shape[1] != 3:
        raise ValueError(f"{what} file {path}: expected 3 numbers per row, got shape {values.shape}")
    if values.shape[0] != rows:
        raise ValueError(f"{what} file {path}: has {values.shape[0]} rows, expected {rows} (one per image)")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{what} file {path}: contains NaN or infinite values")
    return values


def read_diligent_lights(folder: str | Path, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """A DiLiGenT folder's calibration: (unit directions toward the light (rows, 3), raw RGB intensities
    (rows, 3), ones when ``light_intensities.txt`` is absent), both float64 and checked."""
    folder = Path(folder)
    directions = read_text_matrix(folder / "light_directions.txt", rows, "light_directions")
    norms = np.linalg.norm(directions, axis=1)
    if np.any(norms < 1e-9):
        raise ValueError(f"light_directions file {folder / 'light_directions.txt'}: row {int(np.argmin(norms)) + 1} is a zero vector")
    int_path = folder / "light_intensities.txt"
    raw = read_text_matrix(int_path, rows, "light_intensities") if int_path.is_file() else np.ones((rows, 3))
    if np.any(raw <= 0):
        raise ValueError(f"light_intensities file {int_path}: intensities must be > 0")
    return directions / norms[:, None], raw
