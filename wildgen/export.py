"""`python -m wildgen.export`: write a dataset of object folders as WebDataset tar shards.

Example: python -m wildgen.export --format webdataset --data DS --out SHARDS --shard-size 100

Training at scale reads a few large files rather than many small ones: each shard `SHARDS/000000.tar ...`
holds `--shard-size` objects, one WebDataset sample per object folder with its files stored as they are
(images, mask, normal map, scene.json with the lights; with --aux the aux/ files too) or, with `--encoding
decoded`, the arrays the one reader returns for it (faster to read in training), in the order of the
folders (sorted by name, as every reader lists them). `SHARDS/index.json` lists each shard's objects, byte
size and sha256. The format is `scenes.folder.shards`; `unips.train --data 'SHARDS/{000000..000009}.tar'` reads it.

The export is deterministic (the same folders give the same bytes: fixed member order, mtime 0, uid / gid 0)
and atomic per shard (each is written under a temporary name and renamed); index.json is written first with
`complete: false` and rewritten complete at the end, so an interrupted export is never read as a finished one.
When --data has a manifest.json (wildgen.make, wildgen.sensor), every object it records is checked against its
checksums first. An existing export in --out is replaced only with --overwrite.
"""
from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Literal

from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.outputs import check_output_folder, claim_outputs
from scenes.cli.progress import progress_bar
from scenes.cli.options import Command, REQUIRED, check_fields, option
from scenes.folder.shards import (ENCODINGS, FORMAT, FORMAT_VERSION, INDEX_FILE, SHARD_NAME, check_encoding,
    sample_key, shard_name, shard_pattern, write_index, write_shard)

FORMATS = ("webdataset",)
"""Export formats (one so far: WebDataset tar shards, `scenes.folder.shards`)."""
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


COMMAND = Command(ExportOptions, prog="python -m wildgen.export", description="Write a dataset of object folders as WebDataset tar shards with an index of "
                                     "checksums (for training that streams its data).")


def _source_folders(data: Path) -> list[Path]:
    """The object folders of --data in reader order, checked against the dataset's manifest when it has one."""
    from scenes.folder.layouts import find_object_folders
    from wildgen.dataset import MANIFEST, verify_object

    if not data.is_dir():
        raise FileNotFoundError(f"--data: {str(data)!r} is not a folder (expected a dataset of object folders)")
    folders = find_object_folders(data, "--data")
    if (data / MANIFEST).is_file():
        try:
            manifest = json.loads((data / MANIFEST).read_text())
            entries = [e for e in manifest["objects"] if isinstance(e, dict) and e.get("status") == "done"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"--data: {str(data / MANIFEST)!r} is not a readable manifest ({exc})") from None
        for e in entries:
            problem = verify_object(data, e)
            if problem is not None:
                raise ValueError(f"--data: object {e.get('name', '?')!r} of {str(data)!r}: {problem} (the dataset "
                                 "differs from its manifest)")
    keys = [sample_key(f) for f in folders]
    seen: dict[str, Path] = {}
    for key, folder in zip(keys, folders):
        if key in seen:
            raise ValueError(f"--data: {str(seen[key])!r} and {str(folder)!r} have the same object name {key!r}")
        seen[key] = folder
    return folders


def _claim_out(data: Path, out: Path, overwrite: bool, flag: str = "--out") -> list[Path]:
    """--out apart from --data; the index and shards of an earlier export replaced only with --overwrite, and
    never shards that no index.json claims. Returns the earlier shards (removed before writing)."""
    d, o = data.resolve(), out.resolve()
    if o == d or d in o.parents or o in d.parents:
        raise UsageError(f"{flag}: {str(out)!r} must be a folder apart from --data {str(data)!r} (not it, inside it "
                         "or around it)")
    check_output_folder(out, flag)
    old = sorted(p for p in out.iterdir() if SHARD_NAME.match(p.name)) if out.is_dir() else []
    claim_outputs([out / INDEX_FILE, *old], overwrite, flag=flag, owner="wildgen.export", marker=out / INDEX_FILE)
    return old


def export_dataset(data: str | Path, out: str | Path, shard_size: int = DEFAULT_SHARD_SIZE, aux: bool = False,
                   overwrite: bool = False, progress: Callable[[int, int, str], None] | None = None,
                   flag: str = "--out", encoding: str = "files") -> dict[str, Any]:
    """Write the object folders of `data` as shards into `out` (see the module docstring); returns the index.
    `flag`: the option that named `out`, in errors."""
    data, out = Path(data), Path(out)
    if isinstance(shard_size, bool) or not isinstance(shard_size, int) or shard_size < 1:
        raise ValueError(f"--shard-size: got {shard_size!r}, expected an integer >= 1")
    check_encoding(encoding, aux)  # before --out is claimed
    folders = _source_folders(data)
    old = _claim_out(data, out, overwrite, flag)
    out.mkdir(parents=True, exist_ok=True)
    groups = [folders[i:i + shard_size] for i in range(0, len(folders), shard_size)]
    index: dict[str, Any] = {"format": FORMAT, "format_version": FORMAT_VERSION, "complete": False,
                             "encoding": encoding, "objects": len(folders), "shard_size": shard_size,
                             "aux_files": bool(aux), "pattern": shard_pattern(len(groups)), "shards": []}
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


def export_after_make(data: str | Path, out: str | Path, encoding: str = "files") -> int:
    """`wildgen.make --shards OUT [--shard-encoding E]`: export the finished dataset (default shard size; an earlier
    export in OUT is replaced, since it was made from this dataset). Returns the exit status; errors are one line."""
    try:
        index = export_dataset(data, out, overwrite=True, flag="--shards", encoding=encoding)
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


if __name__ == "__main__":
    sys.exit(main())
