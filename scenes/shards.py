"""WebDataset shards of object folders: the one definition of the format, its writer and its reader.

A shard is a plain POSIX tar file (`SHARD_SUFFIX`) holding one *sample* per object folder, as WebDataset
(the `webdataset` package) reads it: every member is ``<key>.<suffix>``, where the key is the object's name
(`scenes.objfolder.object_name`, which therefore may not contain a dot) and the suffix names one file of the
folder. The files are stored exactly as they are on disk (PNG, TIFF, JSON bytes), so reading a sample back
means writing its files into a folder and handing it to the one reader of folders (`scenes.layouts`): there
is no second decoder. Suffixes:

- a top-level file keeps its name (``00017.L000.png``, ``00017.mask.png``, ``00017.normal.tif``,
  ``00017.scene.json``): the images, mask, ground-truth normals and scene.json with its lights;
- with `aux`, a file of the folder's aux directory becomes ``aux.<name>`` (``00017.aux.normal.exr``); the
  aux directory must be flat.

Members of a sample follow in sorted suffix order, samples in the order they are written; every member has
mtime 0, uid / gid 0, empty owner names and mode 0444, so the same folders give the same bytes.

Beside the shards, `INDEX_FILE` (index.json) holds `format` ("webdataset"), `format_version`, `objects`,
`shard_size`, `aux_files`, `pattern` (the brace pattern of all shards) and `shards`: per shard its `name`,
`bytes`, `sha256` and `objects` (`name`, source `folder`, `images`), in order; `complete` is false while an
export is running. Readers refuse a shard that the index does not list, whose checksum differs, or whose
index is incomplete.
"""
from __future__ import annotations

import hashlib
import io
import json
import re
from pathlib import Path
from typing import Any, BinaryIO, Iterator

from scenes.objfolder import AUX_DIR, OBJECT_SUFFIX, atomic_write_text, object_name, sha256_file

INDEX_FILE = "index.json"
"""The index beside the shards: per shard its objects and its sha256."""
FORMAT = "webdataset"
"""`format` of index.json."""
FORMAT_VERSION = 1
SHARD_SUFFIX = ".tar"
SHARD_DIGITS = 6
SHARD_NAME = re.compile(r"^\d{%d}\.tar$" % SHARD_DIGITS)
"""File names of shards (`shard_name`): 000000.tar, 000001.tar, ..."""
_AUX_PREFIX = AUX_DIR + "."


def shard_name(index: int) -> str:
    """File name of shard `index` (000000.tar ...)."""
    return f"{index:0{SHARD_DIGITS}d}{SHARD_SUFFIX}"


def shard_pattern(count: int) -> str:
    """The brace pattern naming `count` shards, as `unips.train --data DIR/PATTERN` takes it."""
    return f"{{{shard_name(0)[:-len(SHARD_SUFFIX)]}..{shard_name(count - 1)[:-len(SHARD_SUFFIX)]}}}{SHARD_SUFFIX}"


def sample_key(folder: Path, arg: str = "--data") -> str:
    """The WebDataset key of an object folder: its object name, which must be usable as a key (WebDataset
    splits a member name at the first dot of its file name)."""
    key = object_name(folder)
    if not key or "." in key or key.startswith("_"):
        raise ValueError(f"{arg}: object folder {str(folder)!r} is named {key!r}; a shard key must be a name without "
                         "dots that does not start with '_' (WebDataset splits member names at the first dot)")
    return key


def _member_suffix(name: str, where: Path, arg: str) -> str:
    if name.startswith("_"):  # WebDataset drops members whose suffix starts with "_" (its metadata)
        raise ValueError(f"{arg}: {str(where)!r}: file names starting with '_' cannot be stored in a shard")
    return name


def sample_files(folder: str | Path, aux: bool = False, arg: str = "--data") -> list[tuple[str, Path]]:
    """The (suffix, file) pairs of an object folder's sample, in member order: every top-level file (hidden
    ones, the temporaries of interrupted writes, excluded), and with `aux` every file of the aux directory."""
    folder = Path(folder)
    out = [(_member_suffix(p.name, p, arg), p) for p in sorted(folder.iterdir(), key=lambda p: p.name)
           if p.is_file() and not p.name.startswith(".")]
    aux_dir = folder / AUX_DIR
    if aux and aux_dir.is_dir():
        for p in sorted(aux_dir.iterdir(), key=lambda p: p.name):
            if p.name.startswith("."):
                continue
            if not p.is_file():
                raise ValueError(f"{arg}: {str(p)!r} is not a file; --aux stores a flat {AUX_DIR} folder only")
            out.append((_AUX_PREFIX + _member_suffix(p.name, p, arg), p))
    return sorted(out)


def suffix_path(suffix: str) -> Path:
    """The path inside the object folder of a member suffix (the inverse of `sample_files`' naming)."""
    if suffix.startswith(_AUX_PREFIX):
        return Path(AUX_DIR) / suffix[len(_AUX_PREFIX):]
    return Path(suffix)


class _HashingWriter(io.RawIOBase):
    """A write-only stream that forwards to `raw` and hashes and counts what passes."""

    def __init__(self, raw: BinaryIO):
        super().__init__()
        self.raw, self.sha, self.size = raw, hashlib.sha256(), 0

    def writable(self) -> bool:
        return True

    def write(self, data) -> int:
        self.sha.update(data)
        self.size += len(data)
        return self.raw.write(data)


def write_shard(path: str | Path, folders: list[tuple[str, Path]], aux: bool = False,
                arg: str = "--data") -> dict[str, Any]:
    """Write one shard holding the samples of `folders` ((key, object folder) pairs, in that order) with
    webdataset's TarWriter, atomically (a temporary name, then a rename). Returns its index entry (name,
    bytes, sha256, objects)."""
    import webdataset as wds

    from scenes.layouts import detect_layout, layout_named
    from scenes.objfolder import atomic_write

    path = Path(path)
    objects = []
    result: dict[str, Any] = {}

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            stream = _HashingWriter(f)
            # Fixed metadata: the same folders give the same bytes (mtime 0, uid / gid 0, no owner names).
            writer = wds.TarWriter(stream, user="", group="", mode=0o444, mtime=0, encoder=False)
            for key, folder in folders:
                sample: dict[str, Any] = {"__key__": key}
                for suffix, p in sample_files(folder, aux, arg):
                    sample[suffix] = p.read_bytes()
                writer.write(sample)
                layout = detect_layout(folder)
                images = len(layout_named(layout).images(folder)) if layout else 0
                objects.append({"name": key, "folder": folder.name, "images": images})
            writer.close()
            result.update(bytes=stream.size, sha256=stream.sha.hexdigest())

    atomic_write(path, write)
    return {"name": path.name, **result, "objects": objects}


def write_index(folder: str | Path, index: dict[str, Any]) -> None:
    """Write `folder/index.json` atomically (sorted keys: the same export gives the same bytes)."""
    atomic_write_text(Path(folder) / INDEX_FILE, json.dumps(index, indent=1, sort_keys=True) + "\n")


def read_index(folder: str | Path, arg: str = "--data") -> dict[str, Any]:
    """index.json of a shard folder, checked: the format, complete, and each shard with a name, sha256 and
    objects. FileNotFoundError / ValueError naming `arg`."""
    path = Path(folder) / INDEX_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{arg}: {str(path)!r} does not exist (shards need the index that wildgen.export "
                                "writes beside them, with their checksums)")
    try:
        index = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{arg}: {str(path)!r} cannot be read as JSON ({exc})") from None
    if not isinstance(index, dict) or index.get("format") != FORMAT or not isinstance(index.get("shards"), list):
        raise ValueError(f"{arg}: {str(path)!r} is not a shard index of wildgen.export (expected format "
                         f"{FORMAT!r} and a list of shards)")
    if not index.get("complete"):
        raise ValueError(f"{arg}: {str(path)!r} belongs to an export that did not finish; run wildgen.export again")
    for entry in index["shards"]:
        if not (isinstance(entry, dict) and isinstance(entry.get("name"), str) and isinstance(entry.get("sha256"), str)
                and isinstance(entry.get("objects"), list)):
            raise ValueError(f"{arg}: {str(path)!r} has a malformed shard entry {entry!r:.80}")
    return index


def verify_shard(path: str | Path, entry: dict[str, Any], arg: str = "--data") -> None:
    """Refuse a shard whose size or sha256 differs from its index entry (ValueError naming the shard)."""
    path = Path(path)
    size = path.stat().st_size
    if "bytes" in entry and size != entry["bytes"]:
        raise ValueError(f"{arg}: shard {str(path)!r} is corrupt: {size} bytes, {INDEX_FILE} records {entry['bytes']}")
    digest = sha256_file(path)
    if digest != entry["sha256"]:
        raise ValueError(f"{arg}: shard {str(path)!r} is corrupt: its sha256 {digest[:16]}... differs from "
                         f"{INDEX_FILE}'s {entry['sha256'][:16]}...")


def iter_samples(path: str | Path, arg: str = "--data") -> Iterator[tuple[str, dict[str, bytes]]]:
    """(key, {suffix: bytes}) of every sample of one shard, in order (webdataset's tar reader and grouping, with
    suffixes kept as written). Call `verify_shard` first; a malformed tar is a ValueError naming the shard."""
    import tarfile

    from webdataset.tariterators import group_by_keys, tar_file_expander

    path = Path(path)
    try:
        with open(path, "rb") as f:
            members = tar_file_expander([{"url": str(path), "stream": f}])
            for sample in group_by_keys(members, lcase=False):
                key = sample["__key__"]
                yield key, {k: v for k, v in sample.items() if not k.startswith("__")}
    except (tarfile.TarError, ValueError, OSError) as exc:
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise ValueError(f"{arg}: shard {str(path)!r} cannot be read ({first:.200})") from None


def extract_sample(files: dict[str, bytes], folder: str | Path) -> Path:
    """Write the files of one sample into `folder` (created; must not exist), as the object folder held them."""
    folder = Path(folder)
    folder.mkdir(parents=True)
    for suffix, data in files.items():
        target = folder / suffix_path(suffix)
        if target.parent != folder:
            target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    return folder


def sample_folder_name(key: str) -> str:
    """The folder name a sample is extracted to (its object name is the key)."""
    return key + OBJECT_SUFFIX

