"""The lights an object folder records, per layout: DiLiGenT's light files, our scene.json's camera-frame lights,
none for the official UniPS layout (`Lights`); the table of layouts (`scenes.folder.layouts`) names one of these
readers per layout."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scenes.files import not_a_file, read_text_file
from scenes.folder.format import DILIGENT_INTENSITIES, DILIGENT_LIGHTS, SCENE_FILE, read_scene_dict


@dataclass
class Lights:
    """What a folder says about its lighting (all None / unknown for a layout without calibration)."""

    family: str | None = None
    """Light family of the capture ("directional", "point", ...; scene.json's `light_family`), None if unknown."""
    directions: np.ndarray | None = None
    """(N, 3) float64 unit vectors toward the light, camera frame, one per image file; directional captures only."""
    intensities: np.ndarray | None = None
    """(N, 3) float64 RGB intensity of each light as the images record it (ours: irradiance times exposure;
    DiLiGenT: `light_intensities.txt`, which calibrated methods divide the raw images by)."""
    level: int | None = None
    """Complexity level of a generated scene (scene.json `level`, `wildgen.make --level`), read from the same file
    as the family; None if unknown."""


def read_text_matrix(path: Path, rows: int, what: str) -> np.ndarray:
    """(rows, 3) float64 matrix from a text file of numbers separated by whitespace or commas (DiLiGenT's light
    files; a spreadsheet's UTF-8 BOM and CRLF line ends are read too), checked: one line, naming `what` and the row,
    for a missing file, non-numbers, a wrong shape or non-finite values."""
    if why := not_a_file(path):
        raise FileNotFoundError(f"{what} file {path} {why}")
    try:
        text = read_text_file(path).removeprefix("\ufeff")  # a BOM: what Windows programs write first
    except UnicodeDecodeError as exc:
        raise ValueError(f"{what} file {path}: {exc}") from None
    lines = [(i, line) for i, line in enumerate(text.splitlines(), 1) if line.strip()]
    values = []
    for i, line in lines:
        try:
            values.append([float(v) for v in line.replace(",", " ").split()])
        except ValueError:
            raise ValueError(f"{what} file {path}: line {i} is {line.strip()[:60]!r}; expected 3 numbers separated "
                             "by spaces or commas") from None
        if len(values[-1]) != 3:
            raise ValueError(f"{what} file {path}: line {i} holds {len(values[-1])} numbers, expected 3")
        if not np.all(np.isfinite(values[-1])):
            raise ValueError(f"{what} file {path}: line {i} holds NaN or infinite values ({line.strip()[:60]!r})")
    if len(values) != rows:
        raise ValueError(f"{what} file {path}: has {len(values)} rows, expected {rows} (one per image)")
    return np.array(values, dtype=np.float64).reshape(rows, 3)


def _unit_directions(d: np.ndarray, where: str) -> np.ndarray:
    """Rows of `d` normalised; a row without a direction (zero, or so small or large that its length does not
    come out finite and positive) is refused, naming it."""
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        norms = np.linalg.norm(d, axis=1)
        unit = d / norms[:, None]
    bad = ~(np.isfinite(norms) & (norms >= 1e-9) & np.isfinite(unit).all(axis=1))
    if bad.any():
        row = int(np.argmax(bad))
        values = " ".join(f"{v:.6g}" for v in d[row])
        what = f"a zero vector ({values})" if norms[row] < 1e-9 else f"{values}, whose length is {norms[row]:.6g}"
        raise ValueError(f"{where}: row {row + 1} is {what}; expected a direction toward the light, of a finite "
                         "length from 1e-9 to about 1e154")
    return unit


INTENSITY_RANGE = (float(np.finfo(np.float32).tiny), 1e30)
"""Light intensities a calibrated method may divide the images by, in single precision: below the smallest normal
float32 (about 1.2e-38) the quotient overflows, above 1e30 it vanishes."""


def check_intensities(raw: np.ndarray, where: str, zero: bool = False) -> None:
    """Refuse (N, 3) intensities outside `INTENSITY_RANGE` (0 also, unless `zero`: a light switched off), naming
    `where` and the row."""
    lo, hi = INTENSITY_RANGE
    bad = ~(((raw >= lo) & (raw <= hi)) | ((raw == 0) if zero else False))
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        at = f": row {row + 1} holds" if len(raw) > 1 else " is"
        raise ValueError(f"{where}{at} {' '.join(f'{v:.6g}' for v in raw[row])}; expected "
                         f"intensities {'0 or ' if zero else ''}from {lo:.3g} to {hi:g} (the images are divided by "
                         "them in single precision)")


BEHIND_Z = 0.05
"""A calibrated light direction with z below -BEHIND_Z (behind the object, away from the camera) is refused."""


def read_diligent_lights(folder: str | Path, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """A DiLiGenT folder's calibration: (unit directions toward the light (rows, 3), raw RGB intensities
    (rows, 3), ones when ``light_intensities.txt`` is absent), both float64 and checked."""
    folder = Path(folder)
    path = folder / DILIGENT_LIGHTS
    directions = _unit_directions(read_text_matrix(path, rows, "light_directions"), f"light_directions file {path}")
    behind = np.flatnonzero(directions[:, 2] < -BEHIND_Z)
    if len(behind):  # a light behind the object lights none of what the camera sees: a flipped axis, most likely
        raise ValueError(f"light_directions file {path}: row {behind[0] + 1} points away from the camera (z = "
                         f"{directions[behind[0], 2]:.2f}; {len(behind)} of {rows} rows); expected directions toward "
                         "the light in the camera frame, x right, y up, z toward the camera")
    int_path = folder / DILIGENT_INTENSITIES
    present = os.path.lexists(int_path)  # a dangling link or a folder is named, never read as no file (ones)
    raw = read_text_matrix(int_path, rows, "light_intensities") if present else np.ones((rows, 3))
    check_intensities(raw, f"light_intensities file {int_path}")
    return directions, raw


def _vector3(value: Any, where: str, name: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {name} is not a list of 3 numbers ({exc})") from exc
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{where}: {name} must be 3 finite numbers, got {value!r}")
    return v


def camera_lights(scene: dict[str, Any], num_images: int, path: Path) -> tuple[np.ndarray | None, np.ndarray | None]:
    """scene.json's `camera_lights`, checked entry by entry: (unit directions, irradiances), both (N, 3)
    float64, when every image has exactly one directional light and nothing else; (None, None) when the key is
    absent or any image has other lights. A malformed entry, a zero direction or a count other than one
    entry per image file is refused."""
    cam = scene.get("camera_lights")
    if cam is None:
        return None, None
    if not isinstance(cam, list) or len(cam) != num_images:
        got = f"{len(cam)} entries" if isinstance(cam, list) else f"a {type(cam).__name__}"
        raise ValueError(f"scene file {path}: camera_lights has {got}, expected a list of {num_images} (one per image "
                         f"file of the folder; an image added to it, or one removed, does not belong to this scene)")
    dirs, irr, single = [], [], True
    for i, entry in enumerate(cam):
        where = f"scene file {path}: camera_lights[{i}]"
        if not isinstance(entry, dict) or not isinstance(entry.get("directional", []), list):
            raise ValueError(f"{where} is malformed (expected {{'directional': [...], 'other': N}}, got {entry!r:.80})")
        other = entry.get("other", 0)
        if not isinstance(other, int) or isinstance(other, bool) or other < 0:
            raise ValueError(f"{where}: 'other' must be a count >= 0, got {other!r}")
        for j, light in enumerate(entry.get("directional", [])):
            if not isinstance(light, dict):
                raise ValueError(f"{where}.directional[{j}] is malformed (expected a dict, got {light!r:.80})")
            d = _vector3(light.get("direction_to_light"), f"{where}.directional[{j}]", "direction_to_light")
            e = _vector3(light.get("irradiance"), f"{where}.directional[{j}]", "irradiance")
            d = d / max(float(np.abs(d).max()), 1e-300)  # scaled first: the length of [1e308]*3 overflows
            if not np.isfinite(d).all() or np.linalg.norm(d) < 1e-9:
                raise ValueError(f"{where}.directional[{j}]: direction_to_light is a zero vector")
            if (e < 0).any():  # a light adds energy: a negative one would pass every later check unseen
                raise ValueError(f"{where}.directional[{j}]: irradiance {e.tolist()} has a negative value; expected "
                                 "values >= 0")
            check_intensities(e[None], f"{where}.directional[{j}]: irradiance", zero=True)
            dirs.append(d / np.linalg.norm(d))
            irr.append(e)
        single = single and len(entry.get("directional", [])) == 1 and other == 0
    if not single:
        return None, None
    return np.asarray(dirs), np.asarray(irr)


LEVEL_RANGE = (1, 5)
"""The complexity levels a scene.json may record (`wildgen.levels.LEVELS`, which this layer cannot import; a test
holds the two equal): a curriculum orders the objects by them."""


def ours_lights(folder: Path, num_images: int, scene: dict | None) -> Lights:
    path = folder / SCENE_FILE
    scene = read_scene_dict(path) if scene is None else scene
    family = scene.get("light_family")
    if family is not None and not isinstance(family, str):
        raise ValueError(f"scene file {path}: light_family must be a string, got {family!r}")
    directions, intensities = camera_lights(scene, num_images, path)
    level = scene.get("level")
    if level is not None and (isinstance(level, bool) or not isinstance(level, int)
                              or not LEVEL_RANGE[0] <= level <= LEVEL_RANGE[1]):
        raise ValueError(f"scene file {path}: level must be a whole number from {LEVEL_RANGE[0]} to {LEVEL_RANGE[1]} "
                         f"(wildgen.make --level), got {level!r}")
    return Lights(family=family, directions=directions, intensities=intensities, level=level)


def diligent_lights(folder: Path, num_images: int, scene: dict | None) -> Lights:
    directions, raw = read_diligent_lights(folder, num_images)
    return Lights(family="directional", directions=directions, intensities=raw)


def no_lights(folder: Path, num_images: int, scene: dict | None) -> Lights:
    return Lights()
