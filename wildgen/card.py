"""The numbers of the dataset card (`python -m wildgen.preview --stats`): what to look at before training on a
dataset. Per object folder (`object_stats`): visible normals, lights (camera-frame directions, distances of near
lights, strengths), exposures, material, detail, light family, camera, sensor; over the dataset
(`dataset_stats`): the histograms with their bin edges, counts, min / median / max that stats.json holds
(`json_text`), and the folders that could not be read (`failed`, one line each), left out of everything else.
`wildgen.card_figure` draws them (stats.png)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

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
    """The field that sets a light type's strength (irradiance, intensity, radiance, scale): the class's
    `strength` (`scenes.lights.LIGHT_TYPES`)."""
    return kind.strength or None


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
    (`scenes.folder.layouts.read_folder`), lights, exposures, material and camera from the checked scene description
    (`scenes.folder.format.read_scene`), with what not every dataset records (`level`, `camera.focal_mm`). Raises one of
    READ_ERRORS when the folder cannot be read."""
    from collections import Counter

    from scenes.cli.errors import one_line
    from scenes.folder.format import NORMAL_FILE, SCENE_FILE, object_name, read_scene
    from scenes.folder.layouts import read_folder
    from scenes.geometry import camera_rotation
    from scenes.lights import LIGHT_TYPES, light_class

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
            kind = light_class(light)
            # The type's camera-frame report form about the object centre: the direction toward a distant
            # light, or the position of a near one relative to the centre.
            form = kind.report(light, rotation, centre, 1.0)
            field = _strength_field(kind)
            record = {"type": kind.type, "strength": float(getattr(light, field)) if field else None,
                      "direction": None, "distance": None}
            if "direction_to_light" in form:
                record["direction"] = np.asarray(form["direction_to_light"], np.float64)
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
    from scenes.cli.errors import one_line
    from scenes.folder.format import SCENE_FILE

    if isinstance(exc, KeyError):
        return f"{SCENE_FILE}: missing entry {exc.args[0]!r}"
    if isinstance(exc, (TypeError, AttributeError, IndexError)):
        return f"{SCENE_FILE}: unexpected content ({type(exc).__name__}: {one_line(exc)})"
    return one_line(exc)


def dataset_stats(dataset: str | Path, folders: list[Path]) -> dict:
    """The numbers of the dataset card (what stats.json holds) of the object `folders` of `dataset`. Every
    folder is read; one that cannot be read is recorded in `failed` (name: one line) and left out of the rest;
    ValueError when none can."""
    from scenes.files import shown_name
    from scenes.folder.format import object_name

    objects, failed = [], {}
    for folder in folders:
        try:
            objects.append(object_stats(folder))
        except READ_ERRORS as exc:
            failed[shown_name(object_name(folder))] = _why(exc)
    if not objects:
        name, why = next(iter(failed.items()))
        raise ValueError(f"DIR: none of the {len(folders)} object folder(s) in {str(dataset)!r} can be read "
                         f"(first: {name}: {why})")
    exposures = [e for o in objects for e in o["exposures"]]
    levels = [o["level"] for o in objects if o["level"] is not None]
    focal = [float(o["focal_mm"]) for o in objects if o["focal_mm"] is not None]
    return {
        "dataset": str(dataset),
        "objects": len(objects),
        "images": sum(len(o["per_image"]) for o in objects),
        "failed": failed,
        "normals": _normals_numbers(objects),
        "lights": _lights_numbers(objects),
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


def _normals_numbers(objects: list[dict]) -> dict:
    """stats.json `normals`: the visible normals of all objects."""
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
    return normals


def _lights_numbers(objects: list[dict]) -> dict:
    """stats.json `lights`: counts by type and per image, directions, distances of near lights, strengths."""
    from collections import Counter

    from scenes.lights import LIGHT_TYPES

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
    return {"total": len(lights),
            "per_image": {str(k): n for k, n in sorted(Counter(sum(im.values()) for im in images).items())},
            "per_type": per_type, "directions": directions, "distances": distances, "strength": strength}


def json_text(stats: dict) -> str:
    """stats.json: indented, but each list of numbers (bin edges, counts) on one line."""
    import re

    from scenes.files import json_text as plain_json_text

    text = plain_json_text(stats, indent=1)
    return re.sub(r"\[[^\[\]{}\"]*\]", lambda m: re.sub(r"\s+", " ", m.group(0)).replace("[ ", "[").replace(" ]", "]"),
                  text) + "\n"
