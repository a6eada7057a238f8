"""`python -m wildgen.preview DIR`: contact sheets (images, normal map, mask) per object and an overview;
with `--stats`, the dataset card instead.

Writes DIR/preview/<object>.png and DIR/preview/overview.png. Images are linear; they are shown with a
display gamma of 2.2 so that dark regions stay visible.

The dataset card (`--stats`) is what to look at before training on a dataset: DIR/preview/stats.png plots the
distributions of the visible normals, the light directions, distances and strengths, the exposures, the
materials, light families, camera and sensor of all objects; DIR/preview/stats.json holds the numbers behind
every panel (counts, histograms with their bin edges, min / median / max) and the objects that could not be
read (`failed`, one line each), which are left out of everything else.
"""
from __future__ import annotations

from typing import Annotated

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from scenes.cli import check_output_folder, make_output_folder
from scenes.config import Command, Positional, arg

TILE = 128


def _to_display(rgb: np.ndarray) -> np.ndarray:
    """Linear float RGB -> 8-bit BGR for OpenCV, gamma 2.2."""
    return np.round(np.clip(rgb, 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)[:, :, ::-1]


def _tile(img: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.resize(img, (TILE, TILE), interpolation=cv2.INTER_NEAREST if img.shape[0] < TILE else cv2.INTER_AREA)


def _label(img: np.ndarray, text: str) -> np.ndarray:
    import cv2

    out = img.copy()
    cv2.putText(out, text, (3, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def object_sheet(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """Contact sheet of one object folder, and a 2-tile summary (first image, normal map) for the overview."""
    import cv2

    from scenes.objfolder import MASK_FILE, NORMAL_FILE, image_files, normal_visual, read_image, read_mask, read_normals

    images = image_files(folder)
    if not images:
        raise FileNotFoundError(f"DIR: object folder {str(folder)!r} has no L*.png images")
    try:
        tiles = [_label(_tile(_to_display(read_image(p))), p.stem) for p in images]
        n = read_normals(folder / NORMAL_FILE)
        mask = read_mask(folder / MASK_FILE).astype(np.uint8) * 255
    except (OSError, ValueError) as exc:
        raise ValueError(f"DIR: object folder {str(folder)!r}: {exc}") from exc
    tiles.append(_label(_tile(np.ascontiguousarray(normal_visual(n)[:, :, ::-1])), "normal"))
    tiles.append(_label(_tile(cv2.cvtColor(mask, cv2.COLOR_GRAY2BGR)), "mask"))
    cols = 6
    while len(tiles) % cols:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.concatenate(tiles[i : i + cols], 1) for i in range(0, len(tiles), cols)]
    return np.concatenate(rows, 0), np.concatenate([tiles[0], tiles[len(images)]], 1)


def _object_folders(dataset: Path) -> list[Path]:
    """The object folders of DIR (or DIR itself when it is one); the one-line error when there are none."""
    folders = sorted(p for p in dataset.glob("*.data") if p.is_dir()) if dataset.is_dir() else []
    if dataset.name.endswith(".data") and dataset.is_dir():
        folders = [dataset]
    if not folders:
        raise FileNotFoundError(f"DIR: no <object>.data folders in {str(dataset)!r}")
    return folders


def _output_folder(dataset: Path, out: str | Path | None) -> Path:
    """--out, or DIR/preview (beside a single object folder: its parent's preview/), checked writable."""
    out_dir = Path(out) if out else (dataset if not dataset.name.endswith(".data") else dataset.parent) / "preview"
    check_output_folder(out_dir)
    return out_dir


def preview(dataset: str | Path, out: str | Path | None = None, overwrite: bool = False) -> list[Path]:
    """Write contact sheets and the overview; returns the written paths. Every object is read and every sheet
    drawn before anything is written; existing sheets are replaced only with `overwrite`
    (`scenes.cli.claim_outputs`)."""
    from scenes.cli import claim_outputs
    from scenes.objfolder import write_picture

    dataset = Path(dataset)
    folders = _object_folders(dataset)
    out_dir = _output_folder(dataset, out)
    targets = [out_dir / f"{folder.name[:-5]}.png" for folder in folders] + [out_dir / "overview.png"]
    claim_outputs(targets, overwrite, owner="wildgen.preview")
    print(f"drawing contact sheets of {len(folders)} object(s) into {out_dir}", flush=True)
    sheets, summaries = [], []
    for folder in folders:
        sheet, summary = object_sheet(folder)
        sheets.append(sheet)
        summaries.append(_label(summary, folder.name[:-5]))
    cols = 4
    while len(summaries) % cols:
        summaries.append(np.zeros_like(summaries[0]))
    overview = np.concatenate([np.concatenate(summaries[i : i + cols], 1) for i in range(0, len(summaries), cols)], 0)
    make_output_folder(out_dir)
    for path, image in zip(targets, [*sheets, overview]):
        write_picture(path, image)
    return targets


# ---------------------------------------------------------------------------------- the dataset card

STATS_PICTURE = "stats.png"
STATS_SUMMARY = "stats.json"
NXY_EDGES = np.round(np.linspace(-1.0, 1.0, 41), 6)
"""Bins of the (n_x, n_y) histogram of visible normals: 40 x 40 over [-1, 1]^2."""
ANGLE_EDGES = np.linspace(0.0, 180.0, 91)
"""Bins (2 degrees) of the angle between a visible normal and the view axis (camera z)."""
AZIMUTH_EDGES = np.linspace(-180.0, 180.0, 25)
ELEVATION_EDGES = np.linspace(-90.0, 90.0, 19)
"""Bins (15 x 10 degrees) of the directions toward the lights, camera frame: azimuth in the image plane
(0 = right, 90 = up), elevation above the image plane (90 = along the view axis, from the camera's side;
below 0 = from behind the object)."""
DATA_BINS = 20
"""Bins of the histograms whose range is the data's (light distances, log10 of exposures and strengths)."""
FRAME = "camera frame: x right, y up, z toward the camera"
READ_ERRORS = (ValueError, OSError, KeyError, TypeError, AttributeError, IndexError)
"""What reading one object folder may raise (a scene.json of unexpected shape included): the folder is
recorded in `failed` and the card goes on."""


def _strength_field(kind) -> str | None:
    """The `LightDesc` field that sets a light type's strength (irradiance, intensity, radiance, scale): the
    type's one field checked non-negative in `scenes.lights.LIGHT_TYPES`."""
    names = [name for name, check in kind.fields if check == "non_negative"]
    return names[0] if len(names) == 1 else None


def _summary(values) -> dict:
    """count, min, median, max of numbers (count 0 alone when there are none)."""
    v = np.asarray(list(values), np.float64)
    if v.size == 0:
        return {"count": 0}
    return {"count": int(v.size), "min": float(v.min()), "median": float(np.median(v)), "max": float(v.max())}


def _histogram(values, edges=None, log: bool = False) -> dict:
    """Counts of `values` with the bin edges: `edges`, else DATA_BINS bins from their min to their max. With
    `log` the bins are of log10(value) (`log10_edges`); values <= 0, which have none, are counted as `zero`."""
    v = np.asarray(list(values), np.float64)
    out: dict = {}
    if log:
        out["zero"] = int(np.sum(v <= 0))
        v = np.log10(v[v > 0])
    if edges is None:
        lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 1.0)
        if hi - lo < 1e-9:
            lo, hi = lo - 0.5, hi + 0.5
        edges = np.linspace(lo, hi, DATA_BINS + 1)
    out["log10_edges" if log else "edges"] = [float(e) for e in edges]
    out["counts"] = np.histogram(v, np.asarray(edges))[0].tolist()
    return out


def _median_of_bins(edges: np.ndarray, counts: np.ndarray) -> float | None:
    """The median of binned values, interpolated linearly inside its bin."""
    total = counts.sum()
    if total == 0:
        return None
    cum = np.cumsum(counts)
    i = int(np.searchsorted(cum, total / 2.0))
    before = cum[i - 1] if i else 0
    return float(edges[i] + (edges[i + 1] - edges[i]) * (total / 2.0 - before) / counts[i])


def _counts(values) -> dict[str, int]:
    """How often each value occurs, by its text, sorted."""
    from collections import Counter

    return dict(sorted(Counter(str(v) for v in values).items()))


def _object_radius(shape, folder: Path) -> float | None:
    """Bounding radius of the object in scene units, None when unknown: the object-space radius (1 for the
    analytic sphere and normalised shapes; a mesh used as stored, as the generator writes it, is read)
    stretched by `shape.to_world`."""
    m = np.asarray(shape.to_world, np.float64)[:3, :3]
    if shape.kind == "sphere" or shape.normalize:
        return float(np.linalg.svd(m, compute_uv=False)[0])
    if shape.kind != "mesh" or not shape.file:
        return None
    from scenes.meshes import load_mesh

    path = Path(shape.file)
    try:
        mesh = load_mesh(path if path.is_absolute() else folder / path, normalize=False)
    except (OSError, ValueError):
        return None
    return float(np.linalg.norm(mesh.positions.astype(np.float64) @ m.T, axis=1).max())


def object_stats(folder: Path) -> dict:
    """What the dataset card needs of one object folder: mask, normals and sensor through the one reader
    (`scenes.layouts.read_folder`), lights, exposures, material and camera from the checked scene description
    (`scenes.objfolder.read_scene`), with what not every dataset records (`level`, `camera.focal_mm`). Raises one of
    READ_ERRORS when the folder cannot be read."""
    from collections import Counter

    from scenes.cli import one_line
    from scenes.geometry import camera_rotation
    from scenes.layouts import read_folder
    from scenes.lights import LIGHT_TYPES, light_type
    from scenes.objfolder import NORMAL_FILE, SCENE_FILE, object_name, read_scene

    data = read_folder(folder, images=False, layout="ours", arg="DIR")
    if data.normals is None:
        raise FileNotFoundError(f"{NORMAL_FILE}: missing")
    try:
        desc, extras = read_scene(folder)
    except ValueError as exc:
        raise ValueError(one_line(exc) if SCENE_FILE in str(exc) else f"{SCENE_FILE}: {one_line(exc)}") from None
    inside = data.normals[data.mask].astype(np.float64)
    known = np.any(inside != 0, axis=1)  # the reader leaves 0 where a mask pixel has no normal
    n = inside[known]
    angles = np.degrees(np.arccos(np.clip(n[:, 2], -1.0, 1.0)))
    camera = desc.camera
    rotation = camera_rotation(camera.origin, camera.target, camera.up)
    centre = np.asarray(desc.shape.to_world, np.float64)[:3, 3]
    lights, per_image = [], []
    for image in desc.images:
        for light in image.lights:
            kind = light_type(light.type)
            # The type's camera-frame report form about the object centre: the direction toward a distant
            # light, or the position of a near one relative to the centre.
            form = kind.report(light, rotation, centre, 1.0)
            field = _strength_field(kind)
            record = {"type": kind.name, "strength": float(getattr(light, field)) if field else None,
                      "direction": None, "distance": None}
            if "direction" in form:
                record["direction"] = np.asarray(form["direction"], np.float64)
            elif "position" in form:
                p = np.asarray(form["position"], np.float64)
                record["distance"] = float(np.linalg.norm(p))
                record["direction"] = p / record["distance"] if record["distance"] > 0 else None
            lights.append(record)
        present = Counter(light.type for light in image.lights)
        per_image.append({t: present[t] for t in LIGHT_TYPES})
    near = any(r["distance"] is not None for r in lights)
    focal = getattr(camera, "focal_mm", None)
    return {
        "name": object_name(folder),
        "mask_pixels": int(data.mask.sum()), "without_normal": int(np.sum(~known)),
        "nxy": np.histogram2d(n[:, 0], n[:, 1], [NXY_EDGES, NXY_EDGES])[0].astype(np.int64),
        "angles": np.histogram(angles, ANGLE_EDGES)[0].astype(np.int64),
        "angle_sum": float(angles.sum()),
        "angle_range": (float(angles.min()), float(angles.max())) if angles.size else None,
        "lights": lights, "per_image": per_image,
        "exposures": [float(image.exposure) for image in desc.images],
        "radius": _object_radius(desc.shape, folder) if near else None,
        "material_class": desc.material.material_class,
        # surface detail: the procedural kind, a normal-map file (a texture set's), or none
        "detail": (desc.material.detail.kind if desc.material.detail is not None
                   else "normal-map file" if desc.material.normal_map else "none"),
        "light_family": desc.light_family,
        "parts": max(1, len(desc.parts)),  # objects in the scene (a cluster's parts)
        "level": getattr(desc, "level", extras.get("level")),  # a description field, or an extra key of the file
        "camera_kind": camera.kind,
        "fov": float(camera.fov) if camera.kind == "perspective" else None,
        "focal_mm": float(focal) if focal is not None else None,
        "resolution": f"{data.shape[1]}x{data.shape[0]}",
        "sensor": data.sensor.name if data.sensor is not None else "ideal",
    }


def _why(exc: BaseException) -> str:
    """One line saying why an object folder could not be read."""
    from scenes.cli import one_line
    from scenes.objfolder import SCENE_FILE

    if isinstance(exc, KeyError):
        return f"{SCENE_FILE}: missing entry {exc.args[0]!r}"
    if isinstance(exc, (TypeError, AttributeError, IndexError)):
        return f"{SCENE_FILE}: unexpected content ({type(exc).__name__}: {one_line(exc)})"
    return one_line(exc)


def dataset_stats(dataset: str | Path, folders: list[Path] | None = None) -> dict:
    """The numbers of the dataset card (what stats.json holds). Every object folder is read; one that cannot
    be read is recorded in `failed` (name: one line) and left out of the rest; ValueError when none can."""
    from collections import Counter

    from scenes.lights import LIGHT_TYPES
    from scenes.objfolder import object_name

    dataset = Path(dataset)
    folders = _object_folders(dataset) if folders is None else folders
    objects, failed = [], {}
    for folder in folders:
        try:
            objects.append(object_stats(folder))
        except READ_ERRORS as exc:
            failed[object_name(folder)] = _why(exc)
    if not objects:
        name, why = next(iter(failed.items()))
        raise ValueError(f"DIR: none of the {len(folders)} object folder(s) in {str(dataset)!r} can be read "
                         f"(first: {name}: {why})")

    nxy = sum(o["nxy"] for o in objects)
    angles = sum(o["angles"] for o in objects)
    ranges = [o["angle_range"] for o in objects if o["angle_range"] is not None]
    pixels = int(nxy.sum())
    normals = {
        "frame": FRAME, "mask_pixels": sum(o["mask_pixels"] for o in objects),
        "without_normal": sum(o["without_normal"] for o in objects), "pixels": pixels,
        "nx_ny_histogram": {"nx_edges": NXY_EDGES.tolist(), "ny_edges": NXY_EDGES.tolist(), "counts": nxy.tolist()},
        "angle_to_view_axis_deg": {
            "edges": ANGLE_EDGES.tolist(), "counts": angles.tolist(),
            "min": min(r[0] for r in ranges) if ranges else None,
            "median": _median_of_bins(ANGLE_EDGES, angles),
            "mean": sum(o["angle_sum"] for o in objects) / pixels if pixels else None,
            "max": max(r[1] for r in ranges) if ranges else None},
    }

    lights = [l for o in objects for l in o["lights"]]
    images = [im for o in objects for im in o["per_image"]]
    per_type = {}
    for t in LIGHT_TYPES:
        k = [im[t] for im in images]
        per_type[t] = {"lights": int(sum(k)), "images_with": int(sum(1 for c in k if c)),
                       "per_image": {str(c): n for c, n in sorted(Counter(k).items())}}
    directed = [l["direction"] for l in lights if l["direction"] is not None]
    d = np.asarray(directed, np.float64).reshape(-1, 3)
    azimuth = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    elevation = np.degrees(np.arcsin(np.clip(d[:, 2], -1.0, 1.0)))
    directions = {
        "frame": FRAME, "lights": len(directed), "without_direction": len(lights) - len(directed),
        "azimuth_edges": AZIMUTH_EDGES.tolist(), "elevation_edges": ELEVATION_EDGES.tolist(),
        "counts": np.histogram2d(azimuth, elevation, [AZIMUTH_EDGES, ELEVATION_EDGES])[0].astype(int).tolist(),
        "azimuth_deg": _summary(azimuth), "elevation_deg": _summary(elevation),
    }
    near = [(l, o["radius"]) for o in objects for l in o["lights"] if l["distance"] is not None]
    in_radii = bool(near) and all(r is not None and r > 0 for _, r in near)
    distance = [l["distance"] / r for l, r in near] if in_radii else [l["distance"] for l, _ in near]
    distances = {
        "types": sorted({l["type"] for l, _ in near}), "from": "object centre (translation of shape.to_world)",
        "unit": "object radii" if in_radii else "scene units", **_summary(distance), **_histogram(distance),
        "scene_units": _summary(l["distance"] for l, _ in near),
        "objects_without_radius": sum(1 for o in objects if o["radius"] is None and
                                      any(l["distance"] is not None for l in o["lights"])),
    }
    strength = {}
    for t, kind in LIGHT_TYPES.items():
        values = [l["strength"] for l in lights if l["type"] == t and l["strength"] is not None]
        if values:
            strength[t] = {"field": _strength_field(kind), **_summary(values), **_histogram(values, log=True)}
    exposures = [e for o in objects for e in o["exposures"]]

    levels = [o["level"] for o in objects if o["level"] is not None]
    focal = [float(o["focal_mm"]) for o in objects if o["focal_mm"] is not None]
    return {
        "dataset": str(dataset),
        "objects": len(objects),
        "images": len(images),
        "failed": failed,
        "normals": normals,
        "lights": {"total": len(lights),
                   "per_image": {str(k): n for k, n in sorted(Counter(sum(im.values()) for im in images).items())},
                   "per_type": per_type, "directions": directions, "distances": distances, "strength": strength},
        "exposure": {**_summary(exposures), **_histogram(exposures, log=True)},
        "materials": _counts(o["material_class"] for o in objects),
        "detail": _counts(o["detail"] for o in objects),
        "light_families": _counts(o["light_family"] for o in objects),
        "levels": ({"counts": _counts(levels), "not_recorded": len(objects) - len(levels)} if levels
                   else "not recorded"),
        "camera": {
            "kinds": _counts(o["camera_kind"] for o in objects),
            "fov_deg": _summary(o["fov"] for o in objects if o["fov"] is not None),
            "focal_mm": ({**_summary(focal), "not_recorded": len(objects) - len(focal)} if focal
                         else "not recorded"),
            "resolutions": _counts(o["resolution"] for o in objects),
            "images_per_object": _summary(len(o["exposures"]) for o in objects),
        },
        "sensors": _counts(o["sensor"] for o in objects),
        "objects_per_scene": _counts(o["parts"] for o in objects),
    }


# Drawing (OpenCV: matplotlib is not a dependency). A panel is a white canvas with a title, a grey subtitle
# and a plot area that maps data coordinates to pixels.
PANEL_W, PANEL_H = 540, 400
_BLACK, _GREY, _LIGHT, _BLUE = (0, 0, 0), (110, 110, 110), (215, 215, 215), (180, 119, 31)


def _put(img: np.ndarray, text: str, x: float, y: float, scale: float = 0.42, colour=_BLACK, align: str = "left",
         thickness: int = 1) -> None:
    import cv2

    width = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)[0][0]
    x = x - width / 2 if align == "center" else x - width if align == "right" else x
    cv2.putText(img, text, (int(round(x)), int(round(y))), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thickness,
                cv2.LINE_AA)


def _ticks(lo: float, hi: float, count: int = 5, integer: bool = False) -> list[float]:
    """Round tick values (steps of 1, 2, 2.5 or 5 x 10^k; whole numbers with `integer`) between lo and hi."""
    import math

    if hi <= lo:
        return [lo]
    raw = (hi - lo) / count
    magnitude = 10.0 ** math.floor(math.log10(raw))
    factors = (1, 2, 5, 10) if integer else (1, 2, 2.5, 5, 10)
    step = next(m * magnitude for m in factors if m * magnitude >= raw * 0.999)
    step = max(step, 1.0) if integer else step
    first = math.ceil(lo / step - 1e-9) * step
    return [first + k * step for k in range(int((hi - first) / step + 1e-9) + 1)]


def _log_ticks(lo: float, hi: float) -> list[float]:
    """Tick positions on a log10 axis from lo to hi (log10 values) at round values: 1-2-5 steps within a
    decade, whole decades (with 2 and 5 between when there are few) otherwise."""
    import math

    if hi - lo < 1.0:
        values = [v for v in _ticks(10.0 ** lo, 10.0 ** hi, 4) if v > 0]
    else:
        decades = range(math.floor(lo), math.ceil(hi) + 1)
        values = [m * 10.0 ** k for k in decades for m in ((1, 2, 5) if hi - lo < 2.5 else (1,))]
    return [math.log10(v) for v in values if lo - 1e-9 <= math.log10(v) <= hi + 1e-9]


def _fmt(v: float) -> str:
    return f"{v:.4g}" if abs(v) >= 1e-9 else "0"


class _Panel:
    def __init__(self, title: str, subtitle: str = "", right_margin: int = 20, square: bool = False):
        self.img = np.full((PANEL_H, PANEL_W, 3), 255, np.uint8)
        _put(self.img, title, 12, 24, 0.55, thickness=1)
        if subtitle:
            _put(self.img, subtitle, 12, 44, 0.4, _GREY)
        self.left, self.top, self.bottom = 72, 62, PANEL_H - 52
        self.right = self.left + self.bottom - self.top if square else PANEL_W - right_margin
        self.xlim, self.ylim = (0.0, 1.0), (0.0, 1.0)

    def x(self, v: float) -> int:
        lo, hi = self.xlim
        return int(round(self.left + (v - lo) / (hi - lo) * (self.right - self.left)))

    def y(self, v: float) -> int:
        lo, hi = self.ylim
        return int(round(self.bottom - (v - lo) / (hi - lo) * (self.bottom - self.top)))

    def axes(self, xlim, ylim, xlabel: str, ylabel: str, xticks=None, yticks=None, xfmt=_fmt, yfmt=_fmt,
             counts: bool = False) -> None:
        """Frame, ticks and axis labels (ylabel written upward along the y axis); `counts`: the y axis counts
        things (whole-number ticks)."""
        import cv2

        self.xlim, self.ylim = (float(xlim[0]), float(xlim[1])), (float(ylim[0]), float(ylim[1]))
        cv2.rectangle(self.img, (self.left, self.top), (self.right, self.bottom), _BLACK, 1)
        for v in _ticks(*self.xlim) if xticks is None else xticks:
            cv2.line(self.img, (self.x(v), self.bottom), (self.x(v), self.bottom + 4), _BLACK, 1)
            _put(self.img, xfmt(v), self.x(v), self.bottom + 18, 0.38, align="center")
        for v in _ticks(*self.ylim, integer=counts) if yticks is None else yticks:
            cv2.line(self.img, (self.left - 4, self.y(v)), (self.left, self.y(v)), _BLACK, 1)
            _put(self.img, yfmt(v), self.left - 7, self.y(v) + 4, 0.38, align="right")
        _put(self.img, xlabel, (self.left + self.right) / 2, PANEL_H - 12, 0.42, align="center")
        label = np.full((18, self.bottom - self.top, 3), 255, np.uint8)
        _put(label, ylabel, label.shape[1] / 2, 13, 0.42, align="center")
        self.img[self.top:self.bottom, 4:22] = np.rot90(label)

    def bars(self, edges, counts, colour=_BLUE) -> None:
        import cv2

        for e0, e1, c in zip(edges[:-1], edges[1:], counts):
            if c > 0:
                x0, x1 = self.x(e0), self.x(e1)
                cv2.rectangle(self.img, (x0, self.y(c)), (max(x0, x1 - (1 if x1 - x0 > 3 else 0)), self.y(0)),
                              colour, -1)

    def heat(self, counts: np.ndarray, unit: str) -> None:
        """counts[i, j]: x bin i, y bin j over the plot area (call before `axes`); empty bins white; a colour
        bar at the right."""
        import cv2

        from scenes.colorbar import BAR_WIDTH, colorbar

        grid = np.asarray(counts, np.float64).T[::-1]  # rows from the top (largest y) down
        vmax = max(float(grid.max()), 1.0)
        picture = cv2.applyColorMap(np.round(grid / vmax * 255).astype(np.uint8), cv2.COLORMAP_VIRIDIS)
        picture[grid == 0] = 255
        self.img[self.top:self.bottom, self.left:self.right] = cv2.resize(
            picture, (self.right - self.left, self.bottom - self.top), interpolation=cv2.INTER_NEAREST)
        bar = colorbar(self.bottom - self.top + 30, vmax, cv2.COLORMAP_VIRIDIS, unit, fmt="{:.3g}", clipped=False)
        x0 = min(self.right + 12, PANEL_W - BAR_WIDTH)
        self.img[self.top - 22:self.bottom + 8, x0:x0 + BAR_WIDTH] = bar

    def note(self, text: str, line: int = 0) -> None:
        """A grey line inside the plot area, top right."""
        _put(self.img, text, self.right - 6, self.top + 16 + 16 * line, 0.38, _GREY, align="right")


def _category_panel(title: str, subtitle: str, groups: list[tuple[str, list[tuple[str, float, str]]]],
                    note_width: int = 150) -> np.ndarray:
    """Horizontal bars: per group a header and rows (label, value, note written after the bar, in `note_width`
    pixels)."""
    import cv2

    img = _Panel(title, subtitle).img
    rows = sum(1 + len(items) for _, items in groups)
    step = min(22, (PANEL_H - 70) // max(rows, 1))
    y, label_w, bar_x1 = 66, 150, PANEL_W - note_width
    for header, items in groups:
        _put(img, header, 12, y + 4, 0.42, _GREY)
        y += step
        top = max([v for _, v, _ in items] + [1e-12])
        for label, value, note in items:
            _put(img, label, 24, y + 4, 0.42)
            x1 = label_w + int(round((bar_x1 - label_w) * value / top))
            if value > 0:
                cv2.rectangle(img, (label_w, y - 7), (max(label_w + 1, x1), y + 5), _BLUE, -1)
            _put(img, note, x1 + 6, y + 4, 0.38)
            y += step
    return img


def _normals_panel(stats: dict) -> np.ndarray:
    import cv2

    n = stats["normals"]
    p = _Panel("Visible normals (n_x, n_y)", f"{n['pixels']} mask pixels of {stats['objects']} objects; "
               "camera frame, +y up", square=True)
    p.xlim = p.ylim = (-1.0, 1.0)
    p.heat(np.asarray(n["nx_ny_histogram"]["counts"]), "pixels")
    cv2.circle(p.img, (p.x(0), p.y(0)), p.x(1) - p.x(0), _GREY, 1, cv2.LINE_AA)
    p.axes((-1, 1), (-1, 1), "n_x (right)", "n_y (up)", xticks=[-1, -0.5, 0, 0.5, 1], yticks=[-1, -0.5, 0, 0.5, 1])
    return p.img


def _angle_panel(stats: dict) -> np.ndarray:
    a = stats["normals"]["angle_to_view_axis_deg"]
    counts, edges = np.asarray(a["counts"]), np.asarray(a["edges"])
    beyond = int(counts[edges[:-1] >= 90].sum())
    p = _Panel("Angle between normal and view axis", "0 = facing the camera, 90 = seen edge-on")
    top = 90.0 if beyond == 0 else 180.0
    p.axes((0, top), (0, max(counts.max(), 1) * 1.1), "angle to the view axis (degrees)", "pixels",
           xticks=list(range(0, int(top) + 1, 15 if top == 90 else 30)), counts=True)
    p.bars(edges, counts)
    if a["median"] is not None:
        p.note(f"min {a['min']:.1f}, median {a['median']:.1f}, max {a['max']:.1f} deg")
    if beyond:
        p.note(f"{beyond} pixels beyond 90 deg", 1)
    return p.img


def _directions_panel(stats: dict) -> np.ndarray:
    d = stats["lights"]["directions"]
    p = _Panel("Directions toward the lights", f"{d['lights']} lights, camera frame; environment / uniform "
               f"lights have none ({d['without_direction']})", right_margin=120)
    p.xlim, p.ylim = (-180.0, 180.0), (-90.0, 90.0)
    p.heat(np.asarray(d["counts"]), "lights")
    p.axes((-180, 180), (-90, 90), "azimuth (degrees; 0 = right, 90 = up)", "elevation (90 = from the camera)",
           xticks=[-180, -90, 0, 90, 180], yticks=[-90, -45, 0, 45, 90])
    return p.img


def _lights_per_image_panel(stats: dict) -> np.ndarray:
    per_type, images = stats["lights"]["per_type"], stats["images"]
    items = []
    for t, e in per_type.items():
        present = [int(k) for k in e["per_image"] if int(k) > 0]
        if present:
            span = f"{min(present)}-{max(present)}" if min(present) < max(present) else f"{min(present)}"
            note = f"{e['lights']} in {e['images_with']}/{images} images, {span} per image"
        else:
            note = "none"
        items.append((t, float(e["lights"]), note))
    totals = [(f"{k} light{'s' if k != '1' else ''}", float(n), f"{n} image{'s' if n != 1 else ''}")
              for k, n in stats["lights"]["per_image"].items()]
    return _category_panel("Lights by type and per image", f"{stats['lights']['total']} lights in {images} images",
                           [("light type: lights in all images", items), ("lights in one image", totals)],
                           note_width=260)


def _distance_panel(stats: dict) -> np.ndarray:
    d = stats["lights"]["distances"]
    p = _Panel("Distance of near lights from the object centre",
               f"{d['count']} {' / '.join(d['types']) or 'point / area'} lights")
    if d["count"] == 0:
        _put(p.img, "no point or area lights in this dataset", PANEL_W / 2, PANEL_H / 2, 0.5, _GREY, "center")
        return p.img
    edges, counts = np.asarray(d["edges"]), np.asarray(d["counts"])
    p.axes((edges[0], edges[-1]), (0, max(counts.max(), 1) * 1.1), f"distance ({d['unit']})", "lights", counts=True)
    p.bars(edges, counts)
    p.note(f"min {d['min']:.3g}, median {d['median']:.3g}, max {d['max']:.3g}")
    return p.img


def _strength_panel(stats: dict) -> np.ndarray:
    """Per light type the range (min to max) and median of its strength on a log axis."""
    import cv2

    s = stats["lights"]["strength"]
    p = _Panel("Light strengths by type", "min - max, dot at the median; each type in its own unit")
    if not s:
        return p.img
    lows = [np.log10(e["min"]) for e in s.values() if e["min"] > 0]
    highs = [np.log10(e["max"]) for e in s.values() if e["max"] > 0]
    lo, hi = (min(lows), max(highs)) if lows else (-1.0, 1.0)
    lo, hi = (lo - 0.5, hi + 0.5) if hi - lo < 1 else (lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo))
    p.left = 170
    p.axes((lo, hi), (0, len(s) + 1), "strength (log scale)", "", xticks=_log_ticks(lo, hi), yticks=[],
           xfmt=lambda v: _fmt(10 ** v))
    for k, (t, e) in enumerate(s.items()):
        y = p.y(len(s) - k)
        _put(p.img, f"{t} ({e['field']})", p.left - 8, y + 4, 0.4, align="right")
        if e["max"] <= 0:
            _put(p.img, "all zero", p.left + 6, y + 4, 0.38, _GREY)
            continue
        x0, x1 = p.x(np.log10(e["min"])) if e["min"] > 0 else p.left, p.x(np.log10(e["max"]))
        cv2.line(p.img, (x0, y), (x1, y), _BLUE, 3)
        if e["median"] > 0:
            cv2.circle(p.img, (p.x(np.log10(e["median"])), y), 5, _BLACK, -1, cv2.LINE_AA)
        _put(p.img, f"n={e['count']}", min(x1 + 8, p.right - 40), y - 8, 0.36, _GREY)
    return p.img


def _exposure_panel(stats: dict) -> np.ndarray:
    e = stats["exposure"]
    p = _Panel("Exposure per image", "factor applied to the radiance before the image is written")
    edges, counts = np.asarray(e["log10_edges"]), np.asarray(e["counts"])
    p.axes((edges[0], edges[-1]), (0, max(counts.max(), 1) * 1.1), "exposure (log scale)", "images",
           xticks=_log_ticks(edges[0], edges[-1]), xfmt=lambda v: _fmt(10 ** v), counts=True)
    p.bars(edges, counts)
    p.note(f"min {e['min']:.3g}, median {e['median']:.3g}, max {e['max']:.3g}")
    return p.img


def _materials_panel(stats: dict) -> np.ndarray:
    n = stats["objects"]
    groups = [(title, [(k, float(v), f"{v} ({100.0 * v / n:.0f}%)") for k, v in stats[key].items()])
              for title, key in (("material class", "materials"), ("surface detail", "detail"),
                                 ("light family", "light_families"))]
    return _category_panel("Materials, detail and light families", f"{n} objects", groups)


def _capture_panel(stats: dict) -> np.ndarray:
    cam = stats["camera"]

    def listed(counts: dict) -> str:
        return ", ".join(f"{k}: {v}" for k, v in counts.items())

    def spread(s: dict, unit: str) -> str:
        if s["min"] == s["max"]:
            return f"{s['min']:.3g} {unit}".strip()
        return f"{s['min']:.3g} - {s['max']:.3g} {unit} (median {s['median']:.3g})"

    levels = stats["levels"]
    lines = [("camera", listed(cam["kinds"])),
             ("field of view", spread(cam["fov_deg"], "deg") if cam["fov_deg"]["count"] else "orthographic only"),
             ("focal length", cam["focal_mm"] if isinstance(cam["focal_mm"], str) else
              spread(cam["focal_mm"], "mm") + " (35 mm equiv.)"),
             ("resolution", listed(cam["resolutions"])),
             ("images per object", spread(cam["images_per_object"], "")),
             ("sensor", listed(stats["sensors"])),
             ("objects per scene", listed(stats["objects_per_scene"])),
             ("level", levels if isinstance(levels, str) else listed(levels["counts"])),
             ("objects read", str(stats["objects"])),
             ("could not be read", f"{len(stats['failed'])}" + (" (see stats.json 'failed')" if stats["failed"] else ""))]
    img = _Panel("Camera, sensor, levels", "").img
    y = 66
    for label, value in lines:
        _put(img, label, 12, y, 0.42, _GREY)
        text = str(value)
        while text:  # wrap long lists
            cut = text if len(text) <= 44 else text[:text.rfind(", ", 0, 44) + 1 or 44]
            _put(img, cut.strip(), 170, y, 0.42)
            text = text[len(cut):].strip()
            y += 22
    return img


def draw_stats(stats: dict) -> np.ndarray:
    """The dataset card: a header and 3 x 3 panels, 8-bit BGR."""
    panels = [_normals_panel(stats), _angle_panel(stats), _directions_panel(stats),
              _lights_per_image_panel(stats), _distance_panel(stats), _strength_panel(stats),
              _exposure_panel(stats), _materials_panel(stats), _capture_panel(stats)]
    rows = [np.concatenate(panels[i:i + 3], 1) for i in range(0, len(panels), 3)]
    for row in rows:  # thin separators between panels
        row[:, PANEL_W::PANEL_W] = _LIGHT
        row[0] = _LIGHT
    header = np.full((56, 3 * PANEL_W, 3), 255, np.uint8)
    failed = f", {len(stats['failed'])} could not be read" if stats["failed"] else ""
    _put(header, f"Dataset card: {stats['dataset']}", 12, 26, 0.65, thickness=2)
    _put(header, f"{stats['objects']} objects{failed}, {stats['images']} images", 12, 48, 0.45, _GREY)
    return np.concatenate([header, *rows], 0)


def _json_text(stats: dict) -> str:
    """stats.json: indented, but each list of numbers (bin edges, counts) on one line."""
    import json
    import re

    text = json.dumps(stats, indent=1, allow_nan=False)
    return re.sub(r"\[[^\[\]{}\"]*\]", lambda m: re.sub(r"\s+", " ", m.group(0)).replace("[ ", "[").replace(" ]", "]"),
                  text) + "\n"


def write_stats(dataset: str | Path, out: str | Path | None = None, overwrite: bool = False) -> list[Path]:
    """Write the dataset card (stats.png) and its numbers (stats.json); returns their paths. Outputs are
    checked before any folder is read; existing ones are replaced only with `overwrite`."""
    from scenes.cli import claim_outputs
    from scenes.objfolder import atomic_write_text, write_picture

    dataset = Path(dataset)
    folders = _object_folders(dataset)
    out_dir = _output_folder(dataset, out)
    targets = [out_dir / STATS_PICTURE, out_dir / STATS_SUMMARY]
    claim_outputs(targets, overwrite, owner="wildgen.preview --stats")
    print(f"reading {len(folders)} object(s) for the dataset card", flush=True)
    stats = dataset_stats(dataset, folders)
    picture = draw_stats(stats)
    make_output_folder(out_dir)
    write_picture(targets[0], picture)
    atomic_write_text(targets[1], _json_text(stats))
    return targets


@dataclass
class PreviewOptions:
    """The command line of wildgen.preview."""

    dataset: Annotated[str, Positional, arg(metavar="DIR")] = ""
    """Dataset directory (or one <object>.data folder)."""
    out: Annotated[str | None, arg(help_behavior_hint="(default: DIR/preview)")] = None
    """Output folder: one <object>.png per object and overview.png (with --stats: stats.png and stats.json)."""
    stats: bool = False
    """Instead of the contact sheets, write the dataset card: stats.png plots the distributions to check before
    training (visible normals, light directions, distances and strengths, exposures, materials, light
    families, camera, sensor) and stats.json holds the numbers behind it, with the object folders that could
    not be read under `failed`."""
    overwrite: bool = False
    """Replace the contact sheets (or the dataset card) of an earlier run in the output folder (other files are
    never touched)."""


COMMAND = Command(PreviewOptions, prog="python -m wildgen.preview", description="Contact sheet PNG per object and one overview PNG of a dataset; with --stats, "
                                     "the dataset card (stats.png, stats.json) instead.")


def main(argv: list[str] | None = None) -> int:
    from scenes.cli import UsageError, report_error

    try:
        args = COMMAND.parse(argv)
        if args.stats:
            written = write_stats(args.dataset, args.out, args.overwrite)  # outputs checked before any read
        else:
            written = preview(args.dataset, args.out, args.overwrite)  # outputs checked before any sheet is drawn
    except (UsageError, ValueError, OSError) as exc:
        return report_error(exc)
    if args.stats:
        print(f"wrote the dataset card {written[0]} and its numbers {written[1]}")
    else:
        print(f"wrote {len(written) - 1} contact sheets and {written[-1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
