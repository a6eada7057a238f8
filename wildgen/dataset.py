"""Making a dataset: plan (resume), run the objects on an engine, keep manifest.json consistent.

Every object is a pure function of (config, index) (`make_object`), so a dataset can be made in any
order, by any number of workers, interrupted and resumed, and the object folders come out
byte-identical (with one Dr.Jit thread per worker; for more threads see docs/generator.md, "Crash safety,
resume and determinism"). Only the parent process writes `manifest.json`, atomically, after each object
(throttled when the manifest gets large, see `ManifestWriter`).

Resuming: when `DIR/manifest.json` exists with the same configuration (the object count may grow),
objects whose folder matches the manifest's checksums are kept, objects rejected by the entropy rule
stay rejected (that is deterministic), and missing, corrupt or failed objects are rendered again.
Temporary folders of interrupted objects are removed.
"""
from __future__ import annotations

import logging
import os
import platform
import re
import shutil
import socket
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

from scenes.files import not_a_file, read_json, write_json
from scenes.folder.format import MANIFEST_VERSION, OBJECT_FOLDER, entry_folder, manifest_problem
from wildgen.config import GenConfig
from wildgen.parallel import Engine, InProcessEngine
from wildgen.writer import TMP_PREFIX, index_name, sha256_file

log = logging.getLogger(__name__)

MANIFEST = "manifest.json"
LOCK = ".wildgen.lock"
TMP_FOLDER = re.compile(r"^" + re.escape(TMP_PREFIX) + r"\d{5,}\.data\.\d+$")  # `writer.write_object`'s temporary names
# Config fields that may differ between runs into the same folder: the object count only extends it.
NOT_IDENTITY = ("objects", "variant")


class DatasetError(ValueError):
    """The output folder cannot be used as asked (other config, busy, unreadable manifest)."""


def versions() -> dict[str, str]:
    """Versions of the packages that determine the pixels."""
    from importlib import metadata

    out = {"python": platform.python_version()}
    # OpenCV under either build name: the project installs the contrib build, the GPU image has the plain one
    for pkg in ("mitsuba", "drjit", "numpy", "unips-toolkit", "opencv-contrib-python-headless",
                "opencv-python-headless", "OpenEXR"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def write_manifest(
    out_dir: Path, cfg: GenConfig, variant: str, entries: dict[int, dict], extra: dict | None = None
) -> None:
    """Write DIR/manifest.json atomically: resolved config, seed, versions, variant, objects."""
    manifest = {
        "format_version": MANIFEST_VERSION,
        "config": cfg.to_dict(),
        "seed": cfg.seed,
        "variant": variant,
        "versions": versions(),
        "host": platform.node(),
        "updated": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "objects": [entries[i] for i in sorted(entries)],
    }
    if extra:
        manifest.update(extra)
    write_json(Path(out_dir) / MANIFEST, manifest, indent=1, sort_keys=True)


def load_manifest(out_dir: str | Path) -> dict | None:
    """The manifest of `out_dir`, or None when there is none. An unreadable one is a DatasetError."""
    path = Path(out_dir) / MANIFEST
    if not os.path.lexists(path):
        return None
    if why := not_a_file(path):  # a folder or a dangling link under the name is no manifest, nor the lack of one
        raise DatasetError(f"--out: {str(path)!r} {why} (where the dataset's manifest belongs); move it away, or use "
                           "another --out")
    try:
        manifest = read_json(path)
        if not isinstance(manifest.get("config"), dict) or not isinstance(manifest.get("objects"), list):
            raise ValueError("no 'config' or 'objects'")
        if (problem := manifest_problem(manifest)) is not None:
            raise ValueError(problem)
    except (ValueError, OSError) as exc:
        raise DatasetError(
            f"--out: {str(path)!r} is not a readable manifest ({exc}); pass --overwrite to start afresh"
        ) from exc
    check_manifest_names(manifest, path, "--out", "; pass --overwrite to start afresh")
    return manifest


def check_manifest_names(manifest: dict, path: Path, flag: str, hint: str = "",
                         folder_re: re.Pattern | None = OBJECT_FOLDER) -> None:
    """Names read from a manifest never lead out of its dataset (a resume or an --overwrite removes them, a reader
    reads them): each object's folder a plain name (matching `folder_re` when given), each of its files a relative
    path inside it. DatasetError naming `flag` otherwise."""
    for i, entry in enumerate(manifest["objects"]):
        if not isinstance(entry, dict):  # a bare name or number: no record to check its folder against
            raise DatasetError(f"{flag}: {str(path)!r} lists {entry!r:.80} as object {i}; expected a JSON object (an "
                               f"object's record: index, name, folder, files, status){hint}")
        folder, files = entry.get("folder"), entry.get("files") or {}
        plain = isinstance(folder, str) and Path(folder).name == folder and folder not in ("", ".", "..") \
            and "\0" not in folder and len(os.fsencode(folder)) <= 255  # what the file system can name
        if folder is not None and not (plain and (folder_re is None or folder_re.match(folder))):
            bad = folder
        elif not isinstance(files, dict):
            bad = files
        else:
            bad = next((f for f in files if not _inside(f)), None)
        if bad is not None:
            raise DatasetError(f"{flag}: {str(path)!r} names {bad!r} for object {entry.get('index', '?')}, not a "
                               f"file or folder inside its dataset{hint}")
    folders = [e.get("folder") for e in manifest["objects"] if isinstance(e, dict) and e.get("folder") is not None]
    twice = next((f for i, f in enumerate(folders) if f in folders[:i]), None)
    if twice is not None:
        raise DatasetError(f"{flag}: {str(path)!r} names the folder {twice!r} for two objects{hint}")


def _inside(rel: object) -> bool:
    """A relative path of a manifest's file list that stays inside its object folder."""
    p = Path(rel) if isinstance(rel, str) else None
    return p is not None and not p.is_absolute() and ".." not in p.parts and rel not in ("", ".")


def config_differences(manifest: dict, cfg: GenConfig) -> list[str]:
    """Fields (other than the object count and the requested variant) where `cfg` differs from the manifest's;
    DatasetError for a key this toolkit does not know (no flag of a run could match it)."""
    # A key an older manifest lacks was added later with its default value.
    old, new = {**GenConfig().to_dict(), **manifest["config"]}, cfg.to_dict()
    if unknown := sorted(set(old) - set(new)):
        raise DatasetError(f"--out: its {MANIFEST} records config key {unknown[0]!r}, which this toolkit does not know "
                           "(a newer toolkit, or an edit, wrote it): use the toolkit that made the dataset, another "
                           "folder, or --overwrite")
    keys = sorted((set(old) | set(new)) - set(NOT_IDENTITY))
    return [k for k in keys if old.get(k) != new.get(k)]


class ManifestWriter:
    """Holds the entries and writes the manifest after each object, atomically.

    With tens of thousands of objects each write takes a while (the manifest keeps every file's
    checksum), so a write is skipped while less than `budget` x (last write's duration) has passed
    since the last one: writing stays under about 1 / budget of the run time. An object finished but
    not yet recorded is rendered again on resume (same bytes), so the manifest is never ahead of the disk.
    """

    def __init__(self, out_dir: Path, cfg: GenConfig, variant: str, entries: dict[int, dict], extra: dict | None = None,
                 budget: float = 10.0):
        self.out_dir, self.cfg, self.variant, self.entries, self.extra = out_dir, cfg, variant, entries, extra
        self.budget = budget
        self.complete = False  # until the run's end: a stopped run's folders are never read as a dataset
        self._last_end = 0.0
        self._last_cost = 0.0

    def update(self, entry: dict) -> None:
        self.entries[entry["index"]] = entry
        if time.perf_counter() - self._last_end >= self.budget * self._last_cost:
            self.flush()

    def flush(self) -> None:
        t0 = time.perf_counter()
        extra = {**(self.extra or {}), "complete": self.complete}
        write_manifest(self.out_dir, self.cfg, self.variant, self.entries, extra)
        self._last_end = time.perf_counter()
        self._last_cost = self._last_end - t0


def verify_object(out_dir: Path, entry: dict) -> str | None:
    """None when the folder of a 'done' entry holds exactly its files with their checksums, else the problem."""
    folder = Path(out_dir) / entry_folder(entry)
    if not folder.is_dir():
        return f"its folder {folder.name!r} is missing"
    if folder.is_symlink():  # e.g. to another object's folder: one object's files under two names
        return f"its folder {folder.name!r} is a link (to {os.readlink(folder)!r}), not the folder the run wrote"
    files = entry.get("files") or {}
    found = list(folder.rglob("*"))
    link = next((p for p in found if p.is_symlink()), None)
    if link is not None:  # never written by a run: the link may lead to any file of the machine
        return f"{str(link.relative_to(folder))!r} is a link (to {os.readlink(link)!r}), not a file the run wrote"
    on_disk = {str(p.relative_to(folder)) for p in found if p.is_file()}
    if on_disk != set(files):
        first = sorted(on_disk ^ set(files))[0]
        return (f"files differ from the manifest ({len(on_disk ^ set(files))} added or missing, the first "
                f"{first!r}, {'not listed' if first in on_disk else 'missing or not a regular file'})")
    for rel, digest in files.items():
        if sha256_file(folder / rel) != digest:
            return f"checksum mismatch in {rel}"
    return None


def clean_leftovers(out_dir: Path, before: set[str] | None = None) -> list[Path]:
    """Remove temporary folders of interrupted objects (a name this tool writes, of a writer that no longer runs:
    `scenes.files.writer_gone`); returns what was removed. With `before` (the names there when this run started),
    also every such folder that appeared since: this run's, whatever became of its writer (a worker on a Ray node
    that was lost may linger a while)."""
    from scenes.files import temporary_folder_writer, writer_gone

    removed = []
    for p in sorted(Path(out_dir).glob(f"{TMP_PREFIX}*")):
        ours = before is not None and p.name not in before
        if not TMP_FOLDER.match(p.name) or not (ours or writer_gone(temporary_folder_writer(p.name))):
            continue
        shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
        removed.append(p)
    return removed


@dataclass
class Plan:
    """What a run into an existing (or new) folder will do."""

    todo: list[int] = field(default_factory=list)
    """Indices to render, ascending."""
    kept: dict[int, dict] = field(default_factory=dict)
    """Entries carried over from the manifest: verified 'done' objects and entropy-rule rejections."""
    complete: int = 0
    """Objects already complete (checksums verified)."""
    rejected: int = 0
    """Objects the entropy rule rejected in an earlier run (deterministic, not tried again)."""
    redo: dict[int, str] = field(default_factory=dict)
    """Index -> why an object recorded in the manifest is rendered again (corrupt, missing, failed)."""
    leftovers: int = 0
    """Temporary folders of interrupted objects removed."""
    resumed: bool = False
    """True when an existing manifest was continued."""


def plan_run(cfg: GenConfig, out_dir: Path, variant: str, overwrite: bool = False) -> Plan:
    """Decide which objects to render; removes leftovers and corrupt folders. Call under `dataset_lock`.

    Raises DatasetError when the folder holds a dataset of another configuration or variant, or, without
    a manifest, anything under a name this run would write (`00000.data`...): files this tool did not
    write are never replaced. `overwrite` deletes the existing object folders and manifest first.
    """
    out_dir = Path(out_dir)
    plan = Plan()
    manifest = None if overwrite else load_manifest(out_dir)
    if overwrite:  # before anything there is removed
        _refuse_a_sensor_output(out_dir / MANIFEST)
    if manifest is None:
        # Object folders without a manifest are not this tool's: never replaced, even with --overwrite
        # (scenes.cli.outputs.claim_outputs, the rule of every command); with a manifest, --overwrite replaces them.
        from scenes.cli.errors import UsageError
        from scenes.cli.outputs import claim_outputs

        names = [out_dir / f"{index_name(i)}.data" for i in range(cfg.objects)]
        try:
            claim_outputs([p for p in names if os.path.lexists(p)], overwrite, owner="wildgen.make",
                          marker=out_dir / MANIFEST, folders=True)
        except UsageError as exc:
            raise DatasetError(str(exc)) from None
    plan.leftovers = len(clean_leftovers(out_dir))
    if overwrite:
        _remove_dataset(out_dir)
    if manifest is not None:
        diff = config_differences(manifest, cfg)
        if diff:
            shown = ", ".join(f"{k}: {manifest['config'].get(k)!r} -> {cfg.to_dict().get(k)!r}" for k in diff[:3])
            raise DatasetError(
                f"--out: {str(out_dir)!r} holds a dataset made with another configuration ({shown}); "
                "use another folder, the same flags (or --resume), or --overwrite"
            )
        if manifest.get("variant") != variant:
            raise DatasetError(
                f"--variant: {str(out_dir)!r} was rendered with {manifest.get('variant')!r}, this run uses {variant!r} "
                "(pixels would differ); pass --variant " f"{manifest.get('variant')} or --overwrite"
            )
        old_objects = int(manifest["config"].get("objects", 0))
        if cfg.objects < old_objects:
            raise DatasetError(
                f"--objects: {str(out_dir)!r} already has {old_objects} objects, {cfg.objects} is fewer; "
                "pass at least that many or --overwrite"
            )
        now, old_versions = versions(), manifest.get("versions", {})
        if changed := [k for k in ("mitsuba", "drjit", "numpy") if old_versions.get(k) != now.get(k)]:
            log.warning("manifest was written with other versions of %s: resumed objects may differ in bytes",
                        ", ".join(changed))
        check_no_foreign_file(out_dir, "--out")  # a done object found changed is rendered anew: never take theirs
        plan.resumed = True
    old = {int(e["index"]): e for e in (manifest or {}).get("objects", []) if isinstance(e, dict) and "index" in e}
    for index in range(cfg.objects):
        entry = old.get(index)
        status = entry.get("status") if entry else None
        if entry and status not in ("done", "skipped", "failed"):  # a status make never writes: an edited manifest
            raise DatasetError(f"--out: {str(out_dir / MANIFEST)!r} records object {index_name(index)} as "
                               f"{str(status)[:40]!r}, not done, skipped or failed; restore it, or use --overwrite")
        target = out_dir / (entry or {}).get("folder", f"{index_name(index)}.data")
        if target.is_symlink() or target.exists() and not target.is_dir():  # the user's, never replaced
            raise DatasetError(f"--out: {str(target)!r} is {'a link' if target.is_symlink() else 'a file'} where "
                               "object folders are written; it is never replaced: move it away")
        if status == "done":
            problem = verify_object(out_dir, entry)
            if problem is None:
                plan.kept[index] = entry
                plan.complete += 1
                continue
            plan.redo[index] = problem
            log.warning("object %s: %s; rendering it again", index_name(index), problem)
            shutil.rmtree(out_dir / entry.get("folder", f"{index_name(index)}.data"), ignore_errors=True)
        elif status == "skipped":
            plan.kept[index] = entry
            plan.rejected += 1
            continue
        elif status == "failed":
            plan.redo[index] = f"failed before: {entry.get('error', '?')}"
        plan.todo.append(index)
    return plan


def _remove_dataset(out_dir: Path) -> None:
    """--overwrite: delete the manifest and the object folders it lists; a file the manifest does not list inside
    one of them (a user's own) stops the run before anything is deleted. An object folder it does not list is left
    to `writer.publish_folder`'s rule (replaced only by a render that rewrites every file in it)."""
    manifest = out_dir / MANIFEST
    if manifest.is_symlink():  # a link make never writes: what it points to is somebody's
        raise DatasetError(f"--overwrite: {str(manifest)!r} is a link (to {os.readlink(manifest)!r}), not a manifest "
                           "wildgen.make wrote: it is never replaced; remove the link or use another --out")
    check_no_foreign_file(out_dir, "--overwrite")
    listed = set(_listed(out_dir))
    if manifest.exists():
        manifest.unlink()
    for p in out_dir.iterdir():
        if p.is_dir() and not p.is_symlink() and OBJECT_FOLDER.match(p.name) and p.name in listed:
            shutil.rmtree(p)


def _refuse_a_sensor_output(path: Path) -> None:
    """DatasetError when `path` is a manifest wildgen.sensor wrote (a top-level sensor record; make --sensor records
    the sensor in its config only): make --overwrite replaces only a dataset it rendered."""
    try:
        record = read_json(path) if path.is_file() and not path.is_symlink() else None
    except (OSError, ValueError):
        return
    if isinstance(record, dict) and isinstance(record.get("sensor"), dict):
        raise DatasetError(f"--overwrite: {str(path)!r} was written by wildgen.sensor (its sensor record): "
                           "wildgen.make replaces only a dataset it rendered; move it away or use another --out")


def check_no_foreign_file(out_dir: Path, flag: str) -> None:
    """Stop before anything is removed when an object folder the manifest lists holds a file it does not list."""
    if (foreign := unlisted_file(out_dir)) is not None:
        raise DatasetError(f"{flag}: {str(foreign)!r} is not a file of the dataset (manifest.json does not "
                           "list it): it is never deleted; move it out of the object folder, then run again")


def _listed(out: Path) -> dict[str, dict]:
    """The object folders `out`'s manifest.json lists, by name, with their entries ({} without a readable one)."""
    try:
        entries = read_json(out / MANIFEST).get("objects", [])
    except (OSError, ValueError, AttributeError):
        return {}
    return {str(e["folder"]): e for e in (entries if isinstance(entries, list) else [])  # plain names only: a name
            if isinstance(e, dict) and isinstance(e.get("folder"), str)  # read from a file never leads out of `out`
            and e["folder"] not in ("", ".", "..") and Path(e["folder"]).name == e["folder"]}


def unlisted_file(out: Path) -> Path | None:
    """The first file inside an object folder of the dataset in `out` that its manifest.json does not list (a
    user's, which removing the folder would take with it; the toolkit's own temporaries aside), or None."""
    from scenes.files import temporary_target

    for name, e in _listed(out).items():
        folder, files = out / name, e.get("files")
        if not isinstance(files, dict) or not folder.is_dir() or folder.is_symlink():
            continue
        for p in sorted(folder.rglob("*")):
            rel = p.relative_to(folder)
            if (p.is_file() or p.is_symlink()) and rel.as_posix() not in files and \
                    (rel.parent / (temporary_target(p.name) or "")).as_posix() not in files:  # a listed file's temp
                return p
    return None


@contextmanager
def dataset_lock(out_dir: Path) -> Iterator[None]:
    """Hold an exclusive lock on `out_dir` (two runs writing one folder would delete each other's work).

    Two advisory `flock`s: LOCK, whose text names the holder (pid and host) for a second wildgen.make, and the
    folder's own (`scenes.files.folder_lock`), the one every command that writes a folder takes
    (`scenes.cli.outputs.output_lock`): no other run writes into the folder meanwhile. Released by the kernel
    if the process dies, so a killed run never blocks the next one. Not reliable on every network filesystem;
    one driver per output folder is the rule.
    """
    import fcntl

    from scenes.cli.errors import UsageError
    from scenes.cli.outputs import busy_message, check_no_holder_above
    from scenes.files import FolderBusy, folder_lock
    from scenes.folder.format import check_not_in_object_folder

    try:
        check_no_holder_above(out_dir)  # inside a folder another run writes: the two runs' files would mix
        check_not_in_object_folder(out_dir)
    except UsageError as exc:
        raise DatasetError(str(exc)) from None
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / LOCK
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    held = None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "another process"
            raise DatasetError(
                f"--out: {str(out_dir)!r} is being written by {holder}; wait for it or use another folder"
            ) from None
        try:
            held = folder_lock(out_dir)
        except FolderBusy:
            os.unlink(path)
            raise DatasetError(busy_message(out_dir)) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode(), 0)
        try:
            yield
        finally:
            os.unlink(path)
    finally:
        if held is not None:
            os.close(held)
        os.close(fd)


def make_dataset(
    cfg: GenConfig,
    out_dir: str | Path,
    variant: str,
    progress: Callable[[dict], None] | None = None,
    *,
    engine: Engine | None = None,
    overwrite: bool = False,
    on_plan: Callable[[Plan], None] | None = None,
    extra: dict | None = None,
) -> dict[int, dict]:
    """Render every object of `cfg` that `out_dir` does not hold yet; returns all entries by index.

    `engine` runs the objects (default: this process, one after the other, see `wildgen.parallel`);
    `progress` is called with each new entry (done, skipped or failed), `on_plan` once before
    rendering. On KeyboardInterrupt the finished objects are kept, the manifest is written, the
    temporary folders are removed, and the interrupt is re-raised.
    """
    out_dir = Path(out_dir)
    engine = engine if engine is not None else InProcessEngine()
    with dataset_lock(out_dir):
        plan = plan_run(cfg, out_dir, variant, overwrite=overwrite)
        if plan.todo and hasattr(engine, "prepare"):  # a cluster that cannot be joined: refused before any write
            engine.prepare()
        if on_plan is not None:
            on_plan(plan)
        writer = ManifestWriter(out_dir, cfg, variant, dict(plan.kept), extra=extra)
        writer.flush()

        def record(entry: dict) -> None:
            writer.update(entry)
            if progress is not None:
                progress(entry)

        # a folder there before the run is never this run's to drop (`writer.publish_folder` decides whether
        # it may be replaced): only folders this run wrote and did not record are
        there = {i for i in plan.todo if os.path.lexists(out_dir / f"{index_name(i)}.data")}
        temporaries = {p.name for p in out_dir.glob(f"{TMP_PREFIX}*")}  # somebody's, if any: kept
        try:
            if plan.todo:
                engine.run(cfg, out_dir, variant, plan.todo, record)
            writer.complete = True  # every object rendered, rejected or recorded as failed
        finally:
            # Also on KeyboardInterrupt / errors: the engine has stopped its workers by now.
            clean_leftovers(out_dir, temporaries)
            drop_unrecorded(out_dir, [i for i in plan.todo if i not in there], writer.entries)
            writer.flush()
        return writer.entries


def drop_unrecorded(out_dir: Path, indices: list[int], entries: dict[int, dict]) -> list[Path]:
    """Remove folders of `indices` that the manifest does not record as done.

    A worker can finish an object just as the run is interrupted, before the parent hears of it;
    such a folder is complete but unknown to the manifest. Removing it keeps folders and manifest in
    step (a resumed run would render it again anyway, with the same bytes).
    """
    removed = []
    for index in indices:
        if entries.get(index, {}).get("status") != "done":
            folder = Path(out_dir) / f"{index_name(index)}.data"
            if folder.exists():
                shutil.rmtree(folder, ignore_errors=True)
                removed.append(folder)
    return removed
