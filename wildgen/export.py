"""`python -m wildgen.export`: write a dataset of object folders as WebDataset tar shards.

Example: python -m wildgen.export --format webdataset --data DS --out SHARDS --shard-size 100

Training at scale reads a few large files rather than many small ones: each shard `SHARDS/000000.tar ...`
holds `--shard-size` objects, one WebDataset sample per object folder with its files stored as they are
(images, mask, normal map, scene.json with the lights; with --aux the aux/ files too) or, with `--encoding
decoded`, the arrays the one reader returns for it (faster to read in training), in the order of the
folders (sorted by name, as every reader lists them). `SHARDS/index.json` lists each shard's objects, byte
size and sha256. The format is `scenes.folder.shard_format`; `unips.train --data 'SHARDS/{000000..000009}.tar'`
reads it.

The export is deterministic (the same folders give the same bytes: fixed member order, mtime 0, uid / gid 0)
and atomic per shard (each is written under a temporary name and renamed); index.json is written first with
`complete: false` and rewritten complete at the end, so an interrupted export is never read as a finished one.
--out is locked while an export writes into it (a second run into it, of any command, is refused:
`scenes.cli.outputs.output_lock`), and index.json records
the dataset folder it was made from (`source`).
When --data has a manifest.json (wildgen.make, wildgen.sensor), every object it records is checked against its
checksums first. An existing export in --out (its index.json, shards, and the temporaries of a killed export) is
replaced only with --overwrite; an index.json that wildgen.export did not write, or shards without one, never.
"""
from __future__ import annotations

import os
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Literal

from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.options import REQUIRED, Command, check_fields, option
from scenes.cli.outputs import check_not_being_written, check_output_folder, claim_outputs, output_lock
from scenes.cli.progress import progress_bar
from scenes.files import is_within, links_out_of, not_a_file, read_json, temporary_target, temporary_writer, writer_gone
from scenes.folder.shard_format import (
    ENCODINGS,
    FORMAT,
    FORMAT_VERSION,
    INDEX_FILE,
    SHARD_NAME,
    check_encoding,
    sample_files,
    sample_key,
    shard_name,
    shard_pattern,
    write_index,
    write_shard,
)

FORMATS = ("webdataset",)
"""Export formats (one so far: WebDataset tar shards, `scenes.folder.shard_format`)."""
DEFAULT_SHARD_SIZE = 100


@dataclass
class ExportOptions:
    """The command line of wildgen.export."""

    data: str = REQUIRED
    """Dataset folder of object folders (wildgen.make, wildgen.sensor, or any layout the readers know)."""
    out: str = REQUIRED
    """Folder of the shards (000000.tar ...) and their index.json; apart from --data."""
    format: Literal[FORMATS] = "webdataset"
    """Output format: 'webdataset' (tar shards, one sample per object folder, read by unips.train --data)."""
    shard_size: int = option(DEFAULT_SHARD_SIZE, minimum=1)
    """Objects per shard (the last one holds the rest). Streaming training splits shards across processes and
    loader workers, so a dataset needs at least processes x workers shards."""
    encoding: Literal[ENCODINGS] = "files"
    """'files': each object's files as they are (PNG, TIFF, JSON; a sample unpacks into a folder the official loaders
    read). 'decoded': the arrays the one reader returns for the folder (integer image codes, mask, normals, the
    reader's metadata, scene.json), which training reads without decoding a PNG: several times faster to read
    (docs/model.md, bench/bench_shards.py), and bit-identical once read."""
    aux: bool = False
    """Also store each object's aux/ files (radiance and ground-truth EXRs, mesh, textures); training does not
    read them."""
    overwrite: bool = False
    """Replace the shards and index.json of an earlier export in --out (nothing else there is touched)."""
    quiet: bool = False
    """No progress bar."""

    def validate(self) -> "ExportOptions":
        check_fields(self)
        return self


COMMAND = Command(
    ExportOptions,
    prog="python -m wildgen.export",
    description="Write a dataset of object folders as WebDataset tar shards with an index of "
    "checksums (for training that streams its data).",
)


def _source_folders(data: Path) -> list[Path]:
    """The object folders of --data in reader order, checked against the dataset's manifest when it has one."""
    from scenes.folder.format import entry_folder, manifest_problem
    from scenes.folder.layouts import find_object_folders
    from wildgen.dataset import MANIFEST, check_manifest_names, verify_object

    if not data.is_dir():
        raise FileNotFoundError(f"--data: {str(data)!r} is not a folder (expected a dataset of object folders)")
    folders = find_object_folders(data, "--data")
    for folder in folders:  # the dataset is untrusted: a linked folder would pack any folder of the machine
        if links_out_of(folder, data):
            raise ValueError(f"--data: object folder {str(folder)!r} is a link to {os.readlink(folder)!r}, outside "
                             "the dataset; a shard holds the dataset's own folders only (copy it in, or remove the "
                             "link)")
    if os.path.lexists(data / MANIFEST) and (why := not_a_file(data / MANIFEST)):  # never taken for none
        raise ValueError(f"--data: {str(data / MANIFEST)!r} {why} (the dataset's manifest, whose statuses say which "
                         "objects are whole); restore it, or move it away to export the folders without it")
    if (data / MANIFEST).is_file():
        try:
            manifest = read_json(data / MANIFEST)
            if not isinstance(manifest, dict) or not isinstance(manifest.get("objects"), list):
                raise ValueError("no 'objects' list")
            if (problem := manifest_problem(manifest)) is not None:
                raise ValueError(problem)
            entries = [e for e in manifest["objects"] if isinstance(e, dict) and e.get("status") == "done"]
            odd = next((e.get("status") for e in manifest["objects"] if isinstance(e, dict)
                        and e.get("status") not in ("done", "skipped", "failed")), None)
            if odd is not None:
                raise ValueError(f"an object with status {odd!r}, expected done, skipped or failed (a run that did "
                                 "not finish: run wildgen.make again to complete it)")
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"--data: {str(data / MANIFEST)!r} is not a readable manifest ({exc})") from None
        check_manifest_names(manifest, data / MANIFEST, "--data", folder_re=None)
        for e in entries:
            problem = verify_object(data, e)
            if problem is not None:
                raise ValueError(f"--data: object {e.get('name', '?')!r} of {str(data)!r}: {problem} (the dataset "
                                 "differs from its manifest)")
        listed = {entry_folder(e) for e in entries}
        extra = next((f for f in folders if f.parent == data and f.name not in listed), None)
        if extra is not None:  # no checksum to verify it by: not the dataset the manifest describes
            raise ValueError(f"--data: object folder {extra.name!r} of {str(data)!r} is not listed as done in its "
                             f"{MANIFEST} (the dataset differs from its manifest: move the folder away, or render it "
                             "with wildgen.make)")
    empty = next((p for f in folders for p in sorted(f.rglob("*")) if p.is_file() and not p.stat().st_size), None)
    if empty is not None:  # no file of an object folder is empty (a copy cut short): it would fail only when trained
        raise ValueError(f"--data: {str(empty)!r} is empty (0 bytes); expected the object's files whole (copy them "
                         "again, or render the object again)")
    keys = [sample_key(f) for f in folders]
    seen: dict[str, Path] = {}
    for key, folder in zip(keys, folders):
        if key in seen:
            raise ValueError(f"--data: {str(seen[key])!r} and {str(folder)!r} have the same object name {key!r}")
        seen[key] = folder
    return folders


def _earlier_export(index_path: Path) -> dict[str, Any] | None:
    """The index.json of an earlier wildgen.export (a JSON object of format 'webdataset' with a list of shards),
    or None when the file is something else: a user's own index.json is never taken for an export."""
    try:
        index = read_json(index_path)
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    ok = isinstance(index, dict) and index.get("format") == FORMAT and isinstance(index.get("shards"), list)
    return index if ok else None


def check_target(data: str | Path, out: str | Path, overwrite: bool, flag: str = "--out",
                 data_flag: str = "--data") -> list[Path]:
    """Everything about the shard folder `out` that can be known before any work, writing nothing: apart from
    --data, writable, and holding nothing this command would replace without leave. An earlier export (an
    index.json that wildgen.export wrote, its shards and the temporaries a killed export left) is replaced only
    with `overwrite`; an index.json that is not an export's, or shards without an index, never. Returns the
    earlier export's files (removed before writing). One line naming `flag` otherwise."""
    data, out = Path(data), Path(out)
    check_output_folder(out, flag)  # first: a loop of links is refused before anything resolves it
    if is_within(out, data) or is_within(data, out):  # either way, a second mount of it too
        raise UsageError(f"{flag}: {str(out)!r} must be a folder apart from {data_flag} {str(data)!r} (not it, inside "
                         "it or around it)")
    index = out / INDEX_FILE
    if index.is_file() and not index.is_symlink() and _earlier_export(index) is None:
        raise UsageError(f"{flag}: {str(index)!r} is not a shard index of wildgen.export; it is never replaced, even "
                         f"with --overwrite: move it away or use another {flag}")
    names = sorted(p.name for p in out.iterdir()) if out.is_dir() else []
    earlier = _earlier_export(index) if index.is_file() and not index.is_symlink() else None
    mine = _planned_shards(earlier) if earlier is not None else None
    old = [out / n for n in names if SHARD_NAME.match(n) and (mine is None or n in mine)]
    claim_outputs([index, *old], overwrite, flag=flag, owner="wildgen.export", marker=index)
    targets = [(n, temporary_target(n)) for n in names]
    leftovers = [out / n for n, t in targets if t is not None and (t == INDEX_FILE or SHARD_NAME.match(t))
                 and writer_gone(temporary_writer(n))]  # a live pid's 'temporary' is somebody's file
    return [*old, *(leftovers if os.path.lexists(index) else [])]


def _planned_shards(index: dict[str, Any]) -> set[str]:
    """The shard names an earlier export wrote or was about to write: those its index lists and those of its
    pattern ({000000..000009}.tar; a killed export's shards are renamed before they are listed). A shard-like
    file outside them is not the export's and is left alone."""
    planned = {str(s.get("name")) for s in index.get("shards", []) if isinstance(s, dict)}
    m = re.fullmatch(r"\{(\d+)\.\.(\d+)\}(\.\w+)", str(index.get("pattern", "")))
    if m and int(m[2]) - int(m[1]) < 10**6:
        planned |= {shard_name(i) for i in range(int(m[1]), int(m[2]) + 1)}
    return planned


def replaces_export(out: str | Path, data: str | Path) -> bool:
    """True when `out` holds an export of the dataset folder `data` (its index records it as its source)."""
    out, data = Path(out), Path(data)
    index = _earlier_export(out / INDEX_FILE) if (out / INDEX_FILE).is_file() else None
    return index is not None and index.get("source") == str(data.resolve())


def export_dataset(data: str | Path, out: str | Path, shard_size: int = DEFAULT_SHARD_SIZE, aux: bool = False,
                   overwrite: bool = False, progress: Callable[[int, int, str], None] | None = None,
                   flag: str = "--out", encoding: str = "files", held: bool = False) -> dict[str, Any]:
    """Write the object folders of `data` as shards into `out` (see the module docstring); returns the index.
    `flag`: the option that named `out`, in errors. `held`: the caller holds `out` already (`output_lock`, as
    wildgen.make --shards does from its start)."""
    data, out = Path(data), Path(out)
    if isinstance(shard_size, bool) or not isinstance(shard_size, int) or shard_size < 1:
        raise ValueError(f"--shard-size: got {shard_size!r}, expected an integer >= 1")
    check_encoding(encoding, aux)  # before --out is claimed
    folders = _source_folders(data)
    if encoding != "decoded":  # every file name storable and every folder readable, before anything is replaced
        from scenes.folder.layouts import read_folder

        for folder in folders:
            sample_files(folder, aux)
            read_folder(folder, images=False, arg="--data")  # (a missing mask.png would fail only when trained)
    if not held:  # another export writing there now: say so, not that its files are an earlier run's
        check_not_being_written(out, flag)
    check_target(data, out, overwrite, flag)
    if held:
        return _export_locked(data, out, folders, shard_size, aux, overwrite, progress, flag, encoding)
    with output_lock(out, flag, inputs={"--data": data}):  # one writer per folder, whatever the command
        return _export_locked(data, out, folders, shard_size, aux, overwrite, progress, flag, encoding)


def _export_locked(data: Path, out: Path, folders: list[Path], shard_size: int, aux: bool, overwrite: bool,
                   progress: Callable[[int, int, str], None] | None, flag: str, encoding: str) -> dict[str, Any]:
    """`export_dataset` under the lock of --out (checked again under it: what another export left is seen)."""
    old = check_target(data, out, overwrite, flag)
    groups = [folders[i:i + shard_size] for i in range(0, len(folders), shard_size)]
    theirs = [p for p in (out / shard_name(i) for i in range(len(groups))) if os.path.lexists(p) and p not in old]
    if theirs:  # beyond what the earlier export planned: somebody's file under a shard's name
        raise UsageError(f"{flag}: {str(theirs[0])!r} is not a shard of the earlier wildgen.export (its index.json "
                         "does not plan it); it is never replaced, even with --overwrite: move it away or use "
                         f"another {flag}")
    index: dict[str, Any] = {"format": FORMAT, "format_version": FORMAT_VERSION, "complete": False,
                             "encoding": encoding, "objects": len(folders), "shard_size": shard_size,
                             "aux_files": bool(aux), "pattern": shard_pattern(len(groups)), "shards": [],
                             "source": str(data.resolve())}
    write_index(out, index)  # first: from now on --out is this command's (an interrupted export is replaced)
    for p in old:
        p.unlink(missing_ok=True)
    for i, group in enumerate(groups):
        if progress is not None:
            progress(i, len(groups), shard_name(i))
        index["shards"].append(write_shard(out / shard_name(i), [(sample_key(f), f) for f in group], aux,
                                           encoding=encoding))
    index["complete"] = True
    write_index(out, index)
    return index


def export_after_make(data: str | Path, out: str | Path, encoding: str = "files", overwrite: bool = False) -> int:
    """`wildgen.make --shards OUT [--shard-encoding E]`: export the finished dataset (default shard size) into OUT,
    which the make holds from its start. An earlier export in OUT is replaced when it was made from this dataset
    (or with --overwrite: `overwrite`); the target was checked before the render (`check_target`). Returns the exit
    status; errors are one line."""
    try:
        replace = overwrite or replaces_export(out, data)
        index = export_dataset(data, out, overwrite=replace, flag="--shards", encoding=encoding, held=True)
    except INPUT_ERRORS as exc:
        return report_error(exc)
    except OSError as exc:
        return report_error(exc, 1)
    print(f"shards in {out}: {index['objects']} objects in {len(index['shards'])} shard(s) {index['pattern']} and "
          f"{INDEX_FILE}")
    return 0


def main(argv: list[str] | None = None) -> int:
    try:
        opts = COMMAND.parse(argv).validate()
        check_not_being_written(opts.data, "--data")
        t0 = time.perf_counter()
        if opts.quiet:
            index = export_dataset(opts.data, opts.out, opts.shard_size, opts.aux, opts.overwrite,
                                   encoding=opts.encoding)
        else:
            with progress_bar("shard") as progress:
                index = export_dataset(opts.data, opts.out, opts.shard_size, opts.aux, opts.overwrite, progress,
                                       encoding=opts.encoding)
    except INPUT_ERRORS as exc:
        return report_error(exc)
    except OSError as exc:  # a full disk or an unwritable file: one line, exit 1
        return report_error(exc, 1)
    size = sum(s["bytes"] for s in index["shards"])
    print(f"wrote {index['objects']} objects in {len(index['shards'])} shards ({size / 2**20:.1f} MiB) to "
          f"{os.path.join(opts.out, index['pattern'])} with {INDEX_FILE}, in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    sys.exit(run_supervised("wildgen.export", main))
