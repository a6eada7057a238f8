"""`python -m wildgen.sensor`: re-apply another camera sensor to an existing dataset, without rendering.

Example: python -m wildgen.sensor --data DS --sensor phone --out DS_phone

For every object folder of --data, each image is made again from its float radiance (`aux/radiance_XXX.exr`)
and its recorded exposure by the sensor preset (`scenes.camera_sensor.SENSORS`; the model is in `scenes.camera_sensor`);
every other file (mask, normal map, aux/) is copied unchanged, and scene.json records the sensor and each
image's noise seed (`scenes.camera_sensor.sensor_record`), so any image can be re-derived. Each object is written
under a temporary name and renamed when complete; --out gets a manifest.json with the sha256 checksum of every
file (the source's manifest with the new checksums and a `sensor` entry), `complete: false` until the last object
is written (every reader refuses a dataset of a run stopped half-way). Every source object is checked (scene.json,
radiance files, checksums) before the first is written; one that fails (or whose radiance the sensor cannot take)
is recorded as failed in --out's manifest with its reason, the rest goes on, and the command exits 1.
The same --data, --sensor and --seed give byte-identical files; --seed 0 gives the images that
`wildgen.make --sensor NAME` writes.
"""
from __future__ import annotations

import copy
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Literal

import numpy as np

from scenes.camera_sensor import (
    SCENE_KEY,
    SENSORS,
    Sensor,
    read_sensor_record,
    rederive_image,
    scale_camera_lights,
    sensor_named,
    sensor_record,
    write_image,
)
from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.needs import Needs
from scenes.cli.options import REQUIRED, Command, check_fields, option
from scenes.cli.outputs import check_apart, check_not_being_written, check_output_folder, check_replaceable
from scenes.cli.progress import progress_bar
from scenes.files import is_within, read_json, write_json
from scenes.folder.format import (
    AUX_DIR,
    MANIFEST_VERSION,
    SCENE_FILE,
    check_dataset_complete,
    image_files,
    image_name,
    list_object_folders,
    object_name,
    radiance_name,
    read_scene,
    write_scene,
)
from scenes.images import read_exr
from wildgen.dataset import (
    MANIFEST,
    check_manifest_names,
    clean_leftovers,
    dataset_lock,
    unlisted_file,
    verify_object,
)
from wildgen.writer import TMP_PREFIX, publish_folder


@dataclass
class SensorOptions:
    """The command line of wildgen.sensor."""

    data: str = REQUIRED
    """Dataset folder made by wildgen.make (object folders holding their radiance, aux/radiance_XXX.exr)."""
    sensor: Literal[tuple(SENSORS)] = REQUIRED
    """Sensor preset whose files replace the images (a key of scenes.camera_sensor.SENSORS)."""
    out: str = REQUIRED
    """New dataset folder; an existing one that is not empty is refused unless --overwrite."""
    seed: int = option(0, minimum=0)
    """Noise seed: image i draws its noise from (seed, its sampler seed); 0 gives the images of wildgen.make
    --sensor."""
    overwrite: bool = False
    """Replace the dataset in --out (its manifest.json and object folders; other files are left alone)."""
    quiet: bool = False
    """No progress bar."""

    def validate(self) -> "SensorOptions":
        check_fields(self)
        return self


COMMAND = Command(
    SensorOptions,
    needs=(Needs("seed", lambda c, _: c.sensor != "ideal", "with a sensor that adds noise (not --sensor ideal)"),),
    prog="python -m wildgen.sensor",
    description="Re-apply a camera sensor (noise, black level, response, bit depth, vignetting, "
    "Bayer filter, white balance) to the radiance of an existing dataset, without "
    "rendering.",
)


MAX_EXPOSED = 1e6
"""Radiance times exposure above this (a million times the sensor's full scale) is no render's: refused by name."""

def _sensor_versions() -> dict[str, str]:
    """Versions of the packages that determine the sensor's bytes (noise streams, demosaicing)."""
    from importlib import metadata

    out = {}
    # OpenCV under either build name: the project installs the contrib build, the GPU image has the plain one
    for pkg in ("numpy", "colour-demosaicing", "colour-science", "opencv-contrib-python-headless",
                "opencv-python-headless"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def check_source_object(src: Path) -> tuple:
    """What `apply_to_object` reads of object folder `src`, checked (its scene.json, sensor record and every
    radiance file present): (description, scene.json extras, old sensor record, radiance paths)."""
    from scenes.files import check_text_name, links_out_of

    check_text_name(src, "--data")  # the converted folder and its files take this name
    for folder, dirs, files in os.walk(src):  # the dataset is untrusted: nothing of the machine is copied in
        out = next((Path(folder, n) for n in dirs + files if links_out_of(Path(folder, n), src)), None)
        if out is not None:
            raise ValueError(f"--data: {str(out)!r} is a link to {os.readlink(out)!r}, outside its object folder; "
                             "the sensor copies the object folder's own files only (copy the file in, or remove the "
                             "link)")
    desc, extras = read_scene(src)
    old = read_sensor_record(extras, len(desc.images), where=f"--data: {str(src / SCENE_FILE)!r}")
    radiance = [src / AUX_DIR / radiance_name(i) for i in range(len(desc.images))]
    missing = [p.name for p in radiance if not p.is_file()]  # a link to a device is named as such below
    odd = next((p for p in radiance if os.path.lexists(p) and not p.is_file()), None)
    if odd is not None:
        from scenes.files import not_a_file

        raise FileNotFoundError(f"--data: {str(odd)!r} {not_a_file(odd)} (the radiance a sensor is applied to)")
    if missing:
        raise FileNotFoundError(f"--data: object folder {str(src)!r} has no {AUX_DIR}/{missing[0]} (the radiance a "
                                f"sensor is applied to; {len(missing)} of {len(radiance)} missing)")
    return desc, extras, old, radiance


def apply_to_object(src: Path, out_dir: Path, sensor: Sensor, seed: int = 0) -> tuple[str, dict[str, str]]:
    """Write `out_dir/<src name>` from object folder `src` with `sensor` (atomically: a temporary name, then a
    rename). Returns (folder name, {relative path: sha256})."""
    desc, extras, old, radiance = check_source_object(src)
    top_images = {p.name for p in image_files(src)}

    def skip(folder: str, names: list[str]) -> list[str]:  # the files this tool writes anew
        return [n for n in names if Path(folder) == src and (n in top_images or n == SCENE_FILE)]

    final = out_dir / src.name
    tmp = out_dir / f"{TMP_PREFIX}{src.name}.{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        shutil.copytree(src, tmp, ignore=skip)
        record = sensor_record(sensor, [im.seed for im in desc.images], seed)
        for i, (image, path) in enumerate(zip(desc.images, radiance)):
            rad = read_exr(path)  # (H, W, 3) float32, before exposure
            if rad.ndim != 3 or rad.shape[2] != 3:
                raise ValueError(f"--data: {str(path)!r} has shape {rad.shape}, expected an RGB image")
            want = (desc.camera.height, desc.camera.width)
            if rad.shape[:2] != want:
                raise ValueError(f"--data: {str(path)!r} is {rad.shape[1]} x {rad.shape[0]} px, expected the "
                                 f"object's {want[1]} x {want[0]} (its scene.json camera)")
            if not np.isfinite(rad).all() or float(rad.min()) < 0:
                raise ValueError(f"--data: {str(path)!r} holds NaN, infinite or negative values; expected the "
                                 "radiance a render wrote (finite, 0 or more)")
            if float(rad.max()) * image.exposure > MAX_EXPOSED:  # the sensor's photon counts would overflow
                raise ValueError(f"--data: {str(path)!r} holds radiance up to {float(rad.max()):.3g} (times exposure "
                                 f"{image.exposure:.3g}); expected exposed values below {MAX_EXPOSED:g} (1 is the "
                                 "sensor's full scale)")
            write_image(tmp / image_name(i), rederive_image(rad, image.exposure, sensor, record["noise_seeds"][i]))
        extras = dict(extras)
        extras[SCENE_KEY] = record
        factor = sensor.exposure / old.sensor.exposure
        if factor != 1.0 and isinstance(extras.get("camera_lights"), list):  # irradiance includes the exposure
            extras["camera_lights"] = scale_camera_lights(extras["camera_lights"], factor)
        write_scene(tmp, desc, extras)
        files = publish_folder(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return final.name, files


def _read_source_manifest(data: Path) -> dict | None:
    path = data / MANIFEST
    if not path.is_file():
        return None
    try:
        manifest = read_json(path)
        if not isinstance(manifest, dict) or not isinstance(manifest.get("objects"), list):
            raise ValueError("no 'objects' list")
    except (OSError, ValueError) as exc:
        raise ValueError(f"--data: {str(path)!r} is not a readable manifest ({exc})") from None
    check_manifest_names(manifest, path, "--data", folder_re=None)  # any dataset's folder names, but plain ones
    return manifest


def _prepare_out(data: Path, out: Path, overwrite: bool, names: list[str]) -> None:
    """Refuse --out when it is --data, inside it or around it, an existing dataset without --overwrite, or holds a
    link or a file under the name of an object folder it will write (never replaced)."""
    check_apart(out, {"--data": data})  # not it, nor inside it, by any name (a link, a second mount)
    if is_within(data, out):
        raise UsageError(f"--out: {str(out)!r} must be a folder apart from --data {str(data)!r} (not it, inside it "
                         "or around it)")
    check_output_folder(out)
    check_not_being_written(out, "--out")  # another run's folder is said as such, before what it holds
    if out.is_dir() and any(out.iterdir()):
        check_replaceable(out, "--out", "wildgen.sensor")
        if not overwrite:
            raise UsageError(f"--out: {str(out)!r} already exists and is not empty; pass --overwrite to replace the "
                             "dataset there, or choose another folder")
        if not (out / MANIFEST).is_file():
            raise UsageError(f"--out: {str(out)!r} is not empty and holds no {MANIFEST}: --overwrite only replaces a "
                             "dataset, choose another folder")
        if not _is_sensor_manifest(out / MANIFEST):
            raise UsageError(f"--out: {str(out / MANIFEST)!r} was not written by wildgen.sensor (no sensor record in "
                             "it); it is never replaced, even with --overwrite: move it away or choose another folder")
        odd = next((out / n for n in names if (out / n).is_symlink() or (out / n).exists() and not (out / n).is_dir()),
                   None)
        if odd is not None:
            raise UsageError(f"--out: {str(odd)!r} is {'a link' if odd.is_symlink() else 'a file'} where an object "
                             "folder is written; it is never replaced: move it away or choose another folder")
        foreign = unlisted_file(out)
        if foreign is not None:
            raise UsageError(f"--out: {str(foreign)!r} was not written by wildgen.sensor (the manifest does not list "
                             "it); it is never removed, even with --overwrite: move it away or choose another folder")


def _is_sensor_manifest(path: Path) -> bool:
    """Whether `path` is a manifest this command wrote (its objects and its sensor record)."""
    try:
        d = read_json(path)
    except (OSError, ValueError):
        return False
    return isinstance(d, dict) and isinstance(d.get("objects"), list) and isinstance(d.get("sensor"), dict)


def _remove_dataset(out: Path) -> None:
    """--overwrite: the manifest, the object folders it lists and temporary folders of an interrupted run (a
    folder the manifest does not list is the user's, even with a scene.json in it)."""
    try:
        listed = {e.get("folder") for e in read_json(out / MANIFEST).get("objects", [])
                  if isinstance(e, dict)}
    except (OSError, ValueError, AttributeError):
        listed = set()
    (out / MANIFEST).unlink(missing_ok=True)
    clean_leftovers(out)
    for p in out.iterdir():
        if p.is_dir() and not p.is_symlink() and p.name in listed:  # (temporaries: clean_leftovers' rule)
            shutil.rmtree(p)


def apply_to_dataset(data: str | Path, out: str | Path, sensor: Sensor, seed: int = 0, overwrite: bool = False,
                     progress: Callable[[int, int, str], None] | None = None) -> dict:
    """Write dataset `out` from dataset `data` with `sensor` (see the module docstring); returns its manifest."""
    data, out = Path(data), Path(out)
    if not data.is_dir():
        raise FileNotFoundError(f"--data: {str(data)!r} is not a folder")
    sensor = sensor.validate()
    check_dataset_complete(data)
    source = _read_source_manifest(data)
    if source is not None:
        entries = [e for e in source["objects"] if isinstance(e, dict)]
    else:
        entries = [{"index": i, "name": object_name(f), "folder": f.name, "status": "done"}
                   for i, f in enumerate(list_object_folders(data))]
    done = [e for e in entries if e.get("status") == "done"]
    if not done:  # an empty dataset out of folders on disk would pass for a conversion
        found = (f"its manifest.json lists no finished object ({len(entries)} listed, none done)" if source is not None
                 else "it holds no object folder")
        raise ValueError(f"--data: {str(data)!r}: {found}; expected a dataset wildgen.make wrote")
    bad = _check_sources(data, done, source is not None)  # every input before the first object is written
    if len(bad) == len(done) and done:  # nothing to write: the first reason is the error
        raise ValueError(next(iter(bad.values())))
    _prepare_out(data, out, overwrite, [str(e["folder"]) for e in done if e.get("name") not in bad])

    manifest = copy.deepcopy(source) if source is not None else {"format_version": MANIFEST_VERSION}
    manifest["objects"] = []
    if isinstance(manifest.get("config"), dict):
        manifest["config"]["sensor"] = sensor.name  # what wildgen.make records as --sensor
    manifest["sensor"] = {"name": sensor.name, "model": sensor.to_dict(), "seed": int(seed),
                          "source": str(data.resolve()), "versions": _sensor_versions()}

    def write_manifest(objects: list[dict], complete: bool) -> None:
        manifest["objects"], manifest["complete"] = objects, complete  # readers refuse an incomplete dataset
        write_json(out / MANIFEST, manifest, indent=1, sort_keys=True)

    with dataset_lock(out):
        if overwrite:
            _remove_dataset(out)
        write_manifest([], False)  # from the start: an interrupted run can be replaced with --overwrite
        written = []
        for entry in entries:
            if entry.get("status") == "done":
                if progress is not None:
                    progress(sum(e.get("status") in ("done", "failed") for e in written), len(done),
                             entry.get("folder", "?"))
                entry = _convert(data, out, entry, sensor, seed, bad.get(entry.get("name")))
            written.append(entry)
        write_manifest(written, True)
    return manifest


def _check_sources(data: Path, done: list[dict], listed: bool) -> dict[str, str]:
    """The source objects that cannot be converted, {name: reason}: a file that differs from the source's
    manifest (`listed`), an unreadable scene.json or sensor record, a missing radiance file. One bad object is
    recorded and the rest goes on."""
    bad = {}
    for e in done:
        where = f"--data: object {e.get('name', '?')!r} of {str(data)!r}"
        problem = verify_object(data, e) if listed else None
        if problem is not None:
            bad[e.get("name")] = f"{where}: {problem} (the source differs from its manifest)"
            continue
        try:
            check_source_object(data / e["folder"])
        except (OSError, ValueError) as exc:
            bad[e.get("name")] = str(exc)
    return bad


def _convert(data: Path, out: Path, entry: dict, sensor: Sensor, seed: int, problem: str | None) -> dict:
    """The --out manifest entry of one source object: converted (its new folder and checksums) or failed, with
    the reason (`problem` found before, or a radiance file the sensor cannot take)."""
    if problem is None:
        try:
            folder, files = apply_to_object(data / entry["folder"], out, sensor, seed)
        except ValueError as exc:
            problem = str(exc)
    if problem is not None:
        from wildgen.writer import failed_entry

        return failed_entry(entry.get("index"), problem, attempts=1, name=entry.get("name"))
    entry = {**entry, "folder": folder, "files": files}
    entry.pop("timings", None)  # the render's timings and Ray node are not this run's
    entry.pop("node", None)
    return entry


def main(argv: list[str] | None = None) -> int:
    try:
        opts = COMMAND.parse(argv).validate()
        check_not_being_written(opts.data, "--data")
        sensor = sensor_named(opts.sensor)
        t0 = time.perf_counter()
        if opts.quiet:
            manifest = apply_to_dataset(opts.data, opts.out, sensor, opts.seed, opts.overwrite)
        else:
            with progress_bar("object") as progress:
                manifest = apply_to_dataset(opts.data, opts.out, sensor, opts.seed, opts.overwrite, progress)
    except INPUT_ERRORS as exc:
        return report_error(exc)
    except OSError as exc:  # a full disk or an unwritable file: one line, exit 1
        return report_error(exc, 1)
    n = sum(e.get("status") == "done" for e in manifest["objects"])
    print(f"wrote {n} object folders with sensor {sensor.name!r} (seed {opts.seed}) to {opts.out} in "
          f"{time.perf_counter() - t0:.1f} s")
    failed = [e for e in manifest["objects"] if e.get("status") == "failed"]
    if failed:
        print(f"error: {len(failed)} of {n + len(failed)} object(s) could not be converted (first, "
              f"{failed[0].get('name')}: {failed[0].get('error')}); they are recorded as failed in "
              f"{str(Path(opts.out) / MANIFEST)!r}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    sys.exit(run_supervised("wildgen.sensor", main))
