"""WebDataset shards of object folders: the one definition of the format, its writer and its reader.

A shard is a plain POSIX tar file (`SHARD_SUFFIX`) holding one *sample* per object folder, as WebDataset
(the `webdataset` package) reads it: every member is ``<key>.<suffix>``, where the key is the object's name
(`scenes.folder.format.object_name`, which therefore may not contain a dot) and the suffix names one file of the
folder. The files are stored exactly as they are on disk (PNG, TIFF, JSON bytes), so reading a sample back
means writing its files into a folder and handing it to the one reader of folders (`scenes.folder.layouts`): there
is no second decoder. Suffixes:
- a top-level file keeps its name (``00017.L000.png``, ``00017.mask.png``, ``00017.normal.tif``,
  ``00017.scene.json``): the images, mask, ground-truth normals and scene.json with its lights;
- with `aux`, a file of the folder's aux directory becomes ``aux.<name>`` (``00017.aux.normal.exr``); the
  aux directory must be flat.

That is the `files` encoding, the default. The `decoded` encoding (`ENCODINGS`) stores instead what the one
reader returned for the folder, so that reading it back decodes no PNG and repeats no check (`encode_decoded`):
- ``<key>.decoded.json``: the reader's metadata (layout, image names, lights, sensor, which files it read);
- ``<key>.decoded.images.npy``: the images as their integer file codes (uint16 or uint8, converted on reading by
  `scenes.images.codes_to_linear`, the conversion of `read_image`) or as float32 when they came from EXRs;
- ``<key>.decoded.mask.npy``, and ``decoded.normals.npy`` / ``decoded.saturated.npy`` when the reader gave them;
- ``<key>.scene.json``, the folder's scene file as it was (the scene stays re-renderable from the shard).

A decoded sample gives the reader's arrays bit for bit (the exporter checks each conversion), for training speed;
a `files` shard is the archival form, whose samples unpack into folders the official loaders read.

Members follow in sorted suffix order, samples as written; mtime 0, uid/gid 0, no owner names, mode 0444: the same
folders give the same bytes.

Beside the shards, `INDEX_FILE` (index.json) holds `format` ("webdataset"), `format_version`, `encoding` (absent in
exports written before it: `files`), `objects`, `shard_size`, `aux_files`, `pattern` (the brace pattern of all
shards), `source` (the dataset folder, absolute; absent in older exports) and `shards`: per shard its `name`,
`bytes`, `sha256` and `objects` (`name`, source `folder`, `images`), in order; `complete` is false while an export is
running. Readers refuse a shard that the index does not list, whose checksum differs, or whose index is incomplete.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import re
from pathlib import Path
from typing import Any, BinaryIO, Iterator

from scenes.files import json_text, not_a_file, parse_json, read_json, sha256_file, write_json
from scenes.folder.format import AUX_DIR, OBJECT_SUFFIX, object_name

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
ENCODINGS = ("files", "decoded")
"""How a sample stores its object: 'files' (the folder's files as they are) or 'decoded' (the one reader's arrays,
read back without decoding; see the module docstring)."""
DECODED = "decoded"
"""Prefix of the members of a decoded sample (``<key>.decoded.json``, ``<key>.decoded.images.npy`` ...)."""
DECODED_META = DECODED + ".json"
_DECODED_ARRAYS = ("images", "mask", "normals", "saturated")


def shard_name(index: int) -> str:
    """File name of shard `index` (000000.tar ...)."""
    return f"{index:0{SHARD_DIGITS}d}{SHARD_SUFFIX}"


def shard_pattern(count: int) -> str:
    """The brace pattern naming `count` shards, as `unips.train --data DIR/PATTERN` takes it."""
    return f"{{{shard_name(0)[:-len(SHARD_SUFFIX)]}..{shard_name(count - 1)[:-len(SHARD_SUFFIX)]}}}{SHARD_SUFFIX}"


class ShardKeyError(ValueError):
    """A sample key that is not a plain object name (`is_plain_key`): a damaged or hostile shard."""


MAX_KEY_BYTES = 200
"""The longest sample key: its object folder's name (<key>.data, and a temporary beside it) fits a file name."""
KEY_RULE = (f"printable characters, at most {MAX_KEY_BYTES} bytes, with no '/', '.' or '\\' and no leading '_' "
            "(WebDataset splits member names at the first dot)")
"""`is_plain_key` in words, for the messages that refuse a key."""


def is_plain_key(key: str) -> bool:
    """The one rule of a sample key, written (`sample_key`) and read (`iter_samples`): an object name without dots
    (WebDataset splits a member name at the first dot), path separators or control characters, not starting with
    '_' (WebDataset's own metadata): a key read from a shard can never name a folder outside the target."""
    return (bool(key) and not key.startswith("_") and not any(c in key for c in "./\\")
            and key.isprintable() and len(key.encode()) <= MAX_KEY_BYTES)


def sample_key(folder: Path, arg: str = "--data") -> str:
    """The WebDataset key of an object folder: its object name, which must be usable as a key (`is_plain_key`)."""
    key = object_name(folder)
    if not is_plain_key(key):
        raise ValueError(f"{arg}: object folder {str(folder)!r} is named {key[:80]!r}; a shard key must be a name of "
                         f"{KEY_RULE}")
    return key


def _inside(p: Path, folder: Path, arg: str) -> Path:
    """`p` when it is a file of `folder`'s own: a link that leads out of it is refused (the dataset is untrusted:
    a link would pack any file of the machine into the shard)."""
    from scenes.files import links_out_of

    if links_out_of(p, folder):
        raise ValueError(f"{arg}: {str(p)!r} is a link to {os.readlink(p)!r}, outside its object folder; a sample "
                         "holds the object folder's own files only (copy the file in, or remove the link)")
    return p


def _member_suffix(name: str, where: Path, arg: str) -> str:
    if name.startswith("_"):  # WebDataset drops members whose suffix starts with "_" (its metadata)
        raise ValueError(f"{arg}: {str(where)!r}: file names starting with '_' cannot be stored in a shard")
    if name.startswith(DECODED + "."):  # would read back as a decoded sample
        raise ValueError(f"{arg}: {str(where)!r}: file names starting with '{DECODED}.' are reserved for decoded "
                         "samples and cannot be stored in a shard")
    return name


def sample_files(folder: str | Path, aux: bool = False, arg: str = "--data") -> list[tuple[str, Path]]:
    """The (suffix, file) pairs of an object folder's sample, in member order: every top-level file (hidden
    ones, the temporaries of interrupted writes, excluded), and with `aux` every file of the aux directory."""
    folder = Path(folder)
    out = [(_member_suffix(p.name, p, arg), _inside(p, folder, arg))
           for p in sorted(folder.iterdir(), key=lambda p: p.name) if p.is_file() and not p.name.startswith(".")]
    aux_dir = folder / AUX_DIR
    if aux and aux_dir.is_dir():
        for p in sorted(aux_dir.iterdir(), key=lambda p: p.name):
            if p.name.startswith("."):
                continue
            if not p.is_file():
                raise ValueError(f"{arg}: {str(p)!r} is not a file; --aux stores a flat {AUX_DIR} folder only")
            out.append((_AUX_PREFIX + _member_suffix(p.name, p, arg), _inside(p, folder, arg)))
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


def _npy(array) -> bytes:
    import numpy as np

    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(array), allow_pickle=False)
    return buf.getvalue()


def _as_codes(images, where: Path, arg: str):
    """The integer file codes that `codes_to_linear` turns back into exactly `images` (float32), or the float32
    images themselves when no integer type does (EXR files)."""
    import numpy as np

    from scenes.images import CODE_SCALES, codes_to_linear

    if images.dtype != np.float32:
        raise ValueError(f"{arg}: {str(where)!r}: the reader gave {images.dtype} images; expected float32")
    for dtype, scale in sorted(CODE_SCALES.items(), key=lambda kv: kv[1]):
        codes = np.rint(images * scale)
        if codes.min(initial=0) < 0 or codes.max(initial=0) > scale:
            continue
        codes = codes.astype(dtype)
        if np.array_equal(codes_to_linear(codes).view(np.uint32), images.view(np.uint32)):  # bits: -0.0 is not 0.0
            return codes
    return images


def encode_decoded(folder: Path, arg: str = "--data") -> dict[str, bytes]:
    """The members (suffix -> bytes) of the decoded sample of an object folder: what `read_folder` returns for it
    (see the module docstring)."""
    from scenes.folder.format import SCENE_FILE
    from scenes.folder.layouts import read_folder

    fd = read_folder(folder, arg=arg)
    meta = {"name": fd.name, "layout": fd.layout, "image_names": fd.image_names, "num_files": fd.num_files,
            "shape": list(fd.shape), "has_scene": fd.has_scene,
            "mask_file": None if fd.mask_file is None else fd.mask_file.name,
            "normals_file": None if fd.normals_file is None else fd.normals_file.name,
            "sensor": None if fd.sensor is None else fd.sensor.to_dict(),
            "lights": {"family": fd.lights.family, "level": fd.lights.level,
                       "directions": None if fd.lights.directions is None else fd.lights.directions.tolist(),
                       "intensities": None if fd.lights.intensities is None else fd.lights.intensities.tolist()}}
    arrays = {"images": _as_codes(fd.images, folder, arg)}
    arrays.update((name, getattr(fd, name)) for name in _DECODED_ARRAYS[1:] if getattr(fd, name) is not None)
    # dtype and shape again in the metadata: the reader maps each array without parsing its .npy header.
    meta["arrays"] = {name: {"dtype": a.dtype.str, "shape": list(a.shape)} for name, a in arrays.items()}
    members = {DECODED_META: json_text(meta, indent=None, sort_keys=True, newline=True).encode()}
    members.update((f"{DECODED}.{name}.npy", _npy(a)) for name, a in arrays.items())
    if (folder / SCENE_FILE).is_file():
        members[SCENE_FILE] = (folder / SCENE_FILE).read_bytes()
    return members


class _MemberError(ValueError):
    """A decoded member that is missing, damaged or not what decoded.json describes (already names it)."""


def decode_folder(files: dict[str, bytes], folder: Path):
    """The `scenes.folder.layouts.FolderData` of a decoded sample's members, as `read_folder` returned it for the object
    folder; `folder` (where the sample came from, e.g. SHARD/KEY.data) stands for its path. A ValueError naming the
    member that is missing, unreadable or not of the type and shape the reader returns."""
    import numpy as np

    from scenes.camera_sensor import Sensor
    from scenes.folder.layouts import FolderData, Lights, check_read_normals
    from scenes.images import CODE_SCALES, codes_to_linear

    def array(name: str, required: bool, dtypes: tuple, shape: tuple):
        suffix = f"{DECODED}.{name}.npy"
        spec = meta["arrays"].get(name)
        if suffix not in files or spec is None:
            if required or (suffix in files) != (spec is not None):
                raise _MemberError(f"{folder}: decoded sample has no {suffix} member, or {DECODED_META} does not "
                                   "describe it")
            return None
        dtype, got = np.dtype(spec["dtype"]), tuple(spec["shape"])
        if dtype not in dtypes or got != shape:
            raise _MemberError(f"{folder}: member {suffix} is {dtype} {got}, expected one of "
                               f"{', '.join(str(d) for d in dtypes)} {shape}")
        try:  # numpy's own reader: its header's byte order and Fortran order are the array's, no pickles
            got = np.lib.format.read_array(io.BytesIO(files[suffix]), allow_pickle=False)
        except (ValueError, EOFError, OSError) as exc:
            raise _MemberError(f"{folder}: member {suffix} is not the .npy array of {spec} that {DECODED_META} "
                               f"describes ({exc})") from None
        if got.dtype.newbyteorder("=") != dtype or got.shape != shape:
            raise _MemberError(f"{folder}: member {suffix} is {got.dtype} {got.shape}, not the .npy array of {spec} "
                               f"that {DECODED_META} describes")
        return np.ascontiguousarray(got, dtype)

    try:
        meta = parse_json(f"member {DECODED_META}", files[DECODED_META].decode("utf-8"))
        h, w = (int(v) for v in meta["shape"])
        k = len(meta["image_names"])
        if min(h, w, k) < 1:
            raise ValueError(f"shape {h}x{w} with {k} images")
        codes = array("images", True, (*CODE_SCALES, np.dtype(np.float32)), (k, h, w, 3))
        images = codes if codes.dtype.kind == "f" else codes_to_linear(codes)
        if codes.dtype.kind == "f" and not np.isfinite(images).all():  # (integer codes are finite by construction)
            raise _MemberError(f"{folder}: member {DECODED}.images.npy holds NaN or infinite values")
        mask = array("mask", True, (np.dtype(bool),), (h, w))
        if not mask.any():
            raise _MemberError(f"{folder}: member {DECODED}.mask.npy is empty (no object pixel)")
        flag, f32 = (np.dtype(bool),), (np.dtype(np.float32),)
        d = meta["lights"]
        vectors = [None if d[key] is None else np.asarray(d[key], np.float64) for key in ("directions", "intensities")]
        if any(v is not None and (v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all()) for v in vectors):
            raise ValueError("lights: expected (N, 3) finite directions and intensities")
        normals = array("normals", False, f32, (h, w, 3))  # as the reader leaves them: unit in the mask, else zero
        try:
            check_read_normals(normals, mask, f"{folder}: member {DECODED}.normals.npy")
        except ValueError as exc:
            raise _MemberError(str(exc)) from None

        def file(name):
            return None if name is None else folder / str(name)

        return FolderData(name=str(meta["name"]), path=folder, layout=str(meta["layout"]),
                          image_paths=[folder / str(n) for n in meta["image_names"]], num_files=int(meta["num_files"]),
                          shape=(h, w), images=images, saturated=array("saturated", False, flag, (k, h, w, 3)),
                          mask=mask, mask_file=file(meta["mask_file"]),
                          normals=normals, normals_file=file(meta["normals_file"]),
                          lights=Lights(d["family"], *vectors, d["level"]), has_scene=bool(meta["has_scene"]),
                          sensor=None if meta["sensor"] is None else Sensor.from_dict(meta["sensor"]))
    except _MemberError:
        raise
    except (KeyError, TypeError, AttributeError, ValueError, UnicodeDecodeError, RecursionError) as exc:
        first = (str(exc).splitlines() or [""])[0]
        raise ValueError(f"{folder}: member {DECODED_META} is malformed ({type(exc).__name__}: {first:.160})") from None


def is_decoded(files: dict[str, bytes]) -> bool:
    """True for the members of a decoded sample."""
    return DECODED_META in files


def check_encoding(encoding: str, aux: bool) -> None:
    """Refuse an unknown encoding, and aux files in a decoded export (ValueError naming the flag)."""
    if encoding not in ENCODINGS:
        raise ValueError(f"--encoding: got {encoding!r}, expected one of {', '.join(ENCODINGS)}")
    if encoding == DECODED and aux:
        raise ValueError("--aux: a decoded export stores what training reads; aux files need --encoding files")


def write_shard(path: str | Path, folders: list[tuple[str, Path]], aux: bool = False,
                arg: str = "--data", encoding: str = "files") -> dict[str, Any]:
    """Write one shard holding the samples of `folders` ((key, object folder) pairs, in that order) with
    webdataset's TarWriter, atomically (a temporary name, then a rename), in `encoding` (`ENCODINGS`). Returns its
    index entry (name, bytes, sha256, objects)."""
    import webdataset as wds

    from scenes.files import atomic_write
    from scenes.folder.layouts import detect_layout, layout_named

    check_encoding(encoding, aux)
    path = Path(path)
    objects = []
    result: dict[str, Any] = {}

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            stream = _HashingWriter(f)
            # Fixed metadata: the same folders give the same bytes (mtime 0, uid / gid 0, no owner names).
            writer = wds.TarWriter(stream, user="", group="", mode=0o444, mtime=0, encoder=False)
            try:
                _write_samples(writer)
            except BaseException:
                try:  # closed while its file is open: never again at garbage collection, into a closed file
                    writer.close()
                except Exception:  # a full disk fails the close too; the first error is the one reported
                    pass
                raise
            writer.close()
            result.update(bytes=stream.size, sha256=stream.sha.hexdigest())

    def _write_samples(writer) -> None:
        for key, folder in folders:
            sample: dict[str, Any] = {"__key__": key}
            if encoding == DECODED:
                sample.update(encode_decoded(folder, arg))
            else:
                for suffix, p in sample_files(folder, aux, arg):
                    sample[suffix] = p.read_bytes()
            writer.write(sample)
            layout = detect_layout(folder)
            images = len(layout_named(layout).images(folder)) if layout else 0
            objects.append({"name": key, "folder": folder.name, "images": images})

    atomic_write(path, write)
    return {"name": path.name, **result, "objects": objects}


def write_index(folder: str | Path, index: dict[str, Any]) -> None:
    """Write `folder/index.json` atomically (sorted keys: the same export gives the same bytes)."""
    write_json(Path(folder) / INDEX_FILE, index, indent=1, sort_keys=True, newline=True)


def read_index(folder: str | Path, arg: str = "--data") -> dict[str, Any]:
    """index.json of a shard folder, checked: the format, complete, and each shard with a name, sha256 and
    objects. FileNotFoundError / ValueError naming `arg`."""
    path = Path(folder) / INDEX_FILE
    if why := not_a_file(path):
        raise FileNotFoundError(f"{arg}: {str(path)!r} {why} (shards need the index that wildgen.export writes "
                                "beside them, with their checksums)")
    try:
        index = read_json(path)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{arg}: {str(path)!r} cannot be read as JSON ({exc})") from None
    except ValueError as exc:  # the one JSON rules' refusals (a NaN, a key twice, too deep), naming the file
        raise ValueError(f"{arg}: {exc}") from None
    if not isinstance(index, dict) or index.get("format") != FORMAT or not isinstance(index.get("shards"), list):
        raise ValueError(f"{arg}: {str(path)!r} is not a shard index of wildgen.export (expected format "
                         f"{FORMAT!r} and a list of shards)")
    version = index.get("format_version", FORMAT_VERSION)
    if not _count(version) or not 1 <= version <= FORMAT_VERSION:
        raise ValueError(f"{arg}: {str(path)!r} has format_version {version!r}; this toolkit reads versions 1 to "
                         f"{FORMAT_VERSION} (a newer wildgen.export wrote it?)")
    if index.get("complete") is not True:  # ('yes' is no answer: only the export's own true says it finished)
        raise ValueError(f"{arg}: {str(path)!r} belongs to an export that did not finish (complete is "
                         f"{index.get('complete')!r:.20}); run wildgen.export again")
    for entry in index["shards"]:
        if not (isinstance(entry, dict) and isinstance(entry.get("name"), str) and isinstance(entry.get("sha256"), str)
                and isinstance(entry.get("objects"), list) and ("bytes" not in entry or _count(entry["bytes"]))):
            raise ValueError(f"{arg}: {str(path)!r} has a malformed shard entry {entry!r:.80}")
        if not SHARD_NAME.match(entry["name"]):  # a name read from a file never leads out of its folder
            raise ValueError(f"{arg}: {str(path)!r} lists the shard {entry['name']!r}; expected names of shards beside "
                             "it (000000.tar ...)")
    names = [e["name"] for e in index["shards"]]
    twice = next((n for i, n in enumerate(names) if n in names[:i]), None)
    if twice is not None:
        raise ValueError(f"{arg}: {str(path)!r} lists the shard {twice!r} twice")
    _check_counts(index, path, arg)
    return index


def _count(value: Any) -> bool:  # a whole number, at least 0
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _check_counts(index: dict[str, Any], path: Path, arg: str) -> None:
    """The index's numbers agree with what it lists: its object count with its shards' objects, each object's
    image count a count (the shards' samples are checked against them as they are read)."""
    listed = sum(len(e["objects"]) for e in index["shards"])
    if "objects" in index and (not _count(index["objects"]) or index["objects"] != listed):
        raise ValueError(f"{arg}: {str(path)!r} says objects {index['objects']!r}, but its shards list {listed}; the "
                         "index was edited (expected the index wildgen.export wrote)")
    odd = next((o for e in index["shards"] for o in e["objects"]
                if not isinstance(o, dict) or "images" in o and not (_count(o["images"]) and o["images"] > 0)), None)
    if odd is not None:
        raise ValueError(f"{arg}: {str(path)!r} lists the object {odd!r:.80}; expected an object with its name and "
                         "image count")


def verify_shard(path: str | Path, entry: dict[str, Any], arg: str = "--data") -> None:
    """Refuse a shard whose size or sha256 differs from its index entry (ValueError naming the shard)."""
    size = os.stat(path).st_size
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

    try:
        size, seen = os.stat(path).st_size, set()  # WebDataset reads a member whole into memory: bounded first
        with tarfile.open(path) as tar:  # WebDataset passes over links, devices and folders: here they are refused
            odd = next((m for m in tar if not m.isreg() or m.issparse() or m.offset_data + m.size > size
                        or m.name in seen or seen.add(m.name)), None)
        if odd is not None:
            what = ", a link, folder, sparse or special file" if not odd.isreg() or odd.issparse() else \
                " twice (one file of an object, given two contents)" if odd.name in seen else \
                f", which says it holds {odd.size} bytes, more than the shard's {size}"
            raise ShardKeyError(f"{arg}: shard {str(path)!r} holds member {odd.name[:80]!r}{what} (expected the plain "
                                "files wildgen.export writes); nothing of it is unpacked")
        with open(path, "rb") as f:
            members = tar_file_expander([{"url": str(path), "stream": f}])
            for sample in group_by_keys(members, lcase=False):
                key = sample["__key__"]
                if not is_plain_key(key):  # the shard is untrusted: its names never become paths as they are
                    raise ShardKeyError(f"{arg}: shard {str(path)!r} holds sample {key[:80]!r}, not a plain object "
                                        f"name (expected what wildgen.export writes: {KEY_RULE}); nothing of it is "
                                        "unpacked")
                yield key, {k: v for k, v in sample.items() if not k.startswith("__")}
    except ShardKeyError:
        raise
    except (tarfile.TarError, ValueError, OSError) as exc:
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise ValueError(f"{arg}: shard {str(path)!r} cannot be read ({first:.200})") from None


def listed_samples(path: str | Path, entry: dict[str, Any], arg="--data") -> Iterator[tuple[str, dict[str, bytes]]]:
    """`iter_samples` of a shard checked against its index entry: the checksum first (`verify_shard`), then each
    sample's key against the objects the entry lists, in order, and their number (ValueError naming the shard and
    the object): samples that were damaged, dropped or renamed and an index rewritten to match are refused."""
    verify_shard(path, entry, arg)
    listed = [str(o.get("name")) if isinstance(o, dict) else repr(o) for o in entry["objects"]]
    n = 0
    for n, (key, files) in enumerate(iter_samples(path, arg), 1):
        if n > len(listed) or key != listed[n - 1]:
            want = f"object {listed[n - 1]!r}" if n <= len(listed) else f"no sample after its {len(listed)} objects"
            raise ValueError(f"{arg}: shard {str(path)!r} holds sample {key!r} at position {n}, where {INDEX_FILE} "
                             f"lists {want} (the shard and its index disagree)")
        yield key, files
    if n < len(listed):
        raise ValueError(f"{arg}: shard {str(path)!r} holds {n} samples, {INDEX_FILE} lists {len(listed)} objects "
                         f"(first missing: {listed[n]!r})")


def extract_sample(files: dict[str, bytes], folder: str | Path) -> Path:
    """Write the files of one sample into `folder` (created; must not exist), as the object folder held them; a
    member whose path would leave the folder is refused before anything is written."""
    folder = Path(folder)
    inside = folder.resolve()
    for suffix in files:  # a file strictly inside: not the folder itself ('00000..' names '.'), not above it
        name, real = suffix.removeprefix(_AUX_PREFIX), (folder / suffix_path(suffix)).resolve()  # a flat file name
        if name in ("", ".", "..") or "/" in name or "\\" in name or real == inside or not real.is_relative_to(inside):
            raise ValueError(f"member {suffix[:80]!r} of sample {folder.name!r} names no file inside its folder (it "
                             "would be written outside its folder, or as a folder); nothing of it is unpacked")
    folder.mkdir(parents=True)
    for suffix, data in files.items():
        target = folder / suffix_path(suffix)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    return folder


def sample_folder_name(key: str) -> str:
    """The folder name a sample is extracted to (its object name is the key)."""
    return key + OBJECT_SUFFIX

