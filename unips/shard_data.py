"""Training data from WebDataset shards (`wildgen.export`; the format is `scenes.folder.shard_format`).

A `--data` value names shards when it ends in ``.tar`` (one shard, or a brace pattern such as
``SHARDS/{000000..000099}.tar``) or is a folder holding `index.json`. Every shard must be listed, complete and
with a matching sha256, in the index.json of its folder; a corrupt shard is refused by name before any of its
samples is used.

A sample of the `files` encoding is decoded by writing its files (stored as they were in the object folder)
into a temporary folder and reading that with the model's loader (`unips.data.load_object`, a view of
`scenes.folder.layouts.read_folder`): the same files through the same reader give the same arrays, so a shard object is
byte-identical to its folder. A sample of the `decoded` encoding holds what that reader returned at export
(`scenes.folder.shard_format.decode_folder`), bit for bit, and is read without decoding a PNG. Two ways to read shards:

- cached (`iter_objects`, what `unips.train` does by default): the shards are read in the order given and
  every object kept in memory, like folders, so training draws exactly the batches it draws from the folders
  the shards were exported from;
- streamed (`ShardStream`, `unips.train --shuffle-buffer N`): for data larger than memory. Each epoch the
  shard list is permuted by (seed, epoch), split across DDP ranks (`webdataset.split_by_node`) and loader
  workers (`webdataset.split_by_worker`), and each (rank, worker) shuffles its samples through a buffer of N
  objects seeded by (seed, epoch, rank, worker): every object is seen exactly once per epoch across all ranks
  and workers, and the stream is a function of the seed and the number of ranks and workers.
"""
from __future__ import annotations

import dataclasses
import errno
import itertools
import os
import random
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import torch

from scenes.files import not_a_file
from scenes.folder.shard_format import (
    DECODED,
    ENCODINGS,
    INDEX_FILE,
    SHARD_SUFFIX,
    decode_folder,
    extract_sample,
    is_decoded,
    listed_samples,
    read_index,
    sample_folder_name,
)
from unips.data import PSObject, load_object, object_from_folder


def is_shard_source(root: str | Path) -> bool:
    """True when a --data entry names shards (a ``.tar`` path or pattern, or a folder with index.json)."""
    text = str(root)
    # an index that is not a regular file is still the index, refused by its reader
    return text.endswith(SHARD_SUFFIX) or (Path(text).is_dir() and os.path.lexists(Path(text) / INDEX_FILE))


def source_label(root: str | Path) -> str:
    """Short name of a --data entry, used to pool several (DIRNAME/OBJECT): the shards' folder name."""
    path = Path(str(root))
    return path.parent.name if str(root).endswith(SHARD_SUFFIX) else path.name


@dataclass(frozen=True)
class Shard:
    """One shard to read and its index entry."""

    path: Path
    entry: dict[str, Any]
    encoding: str = "files"
    """What its index.json says its samples hold (`scenes.folder.shard_format.ENCODINGS`); each sample read is
    checked against it (`decode_object`)."""

    @property
    def objects(self) -> list[dict[str, Any]]:
        return self.entry["objects"]


MAX_SHARDS = 1_000_000
"""The most shards a --data pattern may name (a million shards of one object each: far beyond a training set)."""


def pattern_count(text: str) -> int:
    """How many names the brace pattern `text` expands to ({000..099}: 100, {a,b}: 2, their product), counted
    without expanding it."""
    import re

    count = 1
    for group in re.findall(r"\{([^{}]*)\}", text):
        if m := re.fullmatch(r"\s*(-?\d+)\.\.(-?\d+)(?:\.\.(-?\d+))?\s*", group):
            step = abs(int(m[3])) if m[3] and int(m[3]) else 1
            count *= abs(int(m[2]) - int(m[1])) // step + 1
        else:
            count *= group.count(",") + 1
    return count


def resolve_shards(root: str | Path, arg: str = "--data") -> list[Shard]:
    """The shards a --data entry names, in order, each checked against the index.json of its folder (listed,
    export complete); a missing shard is a FileNotFoundError naming it."""
    from webdataset.shardlists import expand_urls

    text = str(root)
    indexes: dict[Path, dict[str, dict[str, Any]]] = {}
    encodings: dict[Path, str] = {}

    def entries(folder: Path) -> dict[str, dict[str, Any]]:
        if folder not in indexes:
            index = read_index(folder, arg)
            indexes[folder] = {e["name"]: e for e in index["shards"]}
            encodings[folder] = index.get("encoding", "files")  # absent in the first version: files
            if encodings[folder] not in ENCODINGS:
                raise ValueError(f"{arg}: {str(folder / INDEX_FILE)!r} has encoding {encodings[folder]!r}; expected "
                                 f"one of {', '.join(ENCODINGS)}")
        return indexes[folder]

    if text.endswith(SHARD_SUFFIX):
        if (count := pattern_count(text)) > MAX_SHARDS:  # expanded whole into memory: bounded before
            raise ValueError(f"{arg}: {text[:120]!r} names {count:.3g} shards; expected at most {MAX_SHARDS} (the "
                             "pattern wildgen.export's index.json records names as many as were written)")
        paths = [Path(p) for p in expand_urls(text)]
    else:
        folder = Path(text)
        paths = [folder / name for name in entries(folder)]
    if not paths:
        where = "" if text.endswith(SHARD_SUFFIX) else " (its index.json lists none)"
        raise ValueError(f"{arg}: {text!r} names no shard{where}")
    shards = []
    for p in paths:
        if why := not_a_file(p):
            raise FileNotFoundError(f"{arg}: shard {str(p)!r} {why}")
        known = entries(p.parent)
        if p.name not in known:
            raise ValueError(
                f"{arg}: shard {str(p)!r} is not listed in {str(p.parent / INDEX_FILE)!r} (expected one of "
                f"{', '.join(list(known)[:3])}{', ...' if len(known) > 3 else ''})"
            )
        shards.append(Shard(p, known[p.name], encodings[p.parent]))
    if len({s.path.resolve() for s in shards}) != len(shards):
        raise ValueError(f"{arg}: {text!r} names a shard twice")
    return shards


def count_images(root: str | Path, arg: str = "--data") -> tuple[int, int]:
    """(objects, images) of the shards of a --data entry, from their index (no shard is read)."""
    objects = [o for s in resolve_shards(root, arg) for o in s.objects]
    return len(objects), sum(int(o.get("images", 0)) for o in objects)


SHM = "/dev/shm"
"""Memory-backed file system where decoding writes its temporary folders when it has room: creating and
removing a folder of small files there costs a sixth of what it costs on a journaling disk file system."""


def scratch_dir(size: int) -> str | None:
    """Where to extract a sample of `size` bytes: $TMPDIR when set, else `SHM` when it is a writable folder with
    room for twice the sample, else the system's temporary folder (None)."""
    if os.environ.get("TMPDIR") or not os.access(SHM, os.W_OK | os.X_OK):
        return None
    try:
        st = os.statvfs(SHM)
    except OSError:
        return None
    return SHM if st.f_bavail * st.f_frsize > 2 * size + (16 << 20) else None


def decode_object(key: str, files: dict[str, bytes], shard: Path, arg: str = "--data",
                  encoding: str | None = None) -> PSObject:
    """The `PSObject` of one sample (`path` names the shard and the object). A `files` sample: its files written
    into a temporary folder (`scratch_dir`) and read by `load_object`, exactly as the object folder they came
    from. A `decoded` sample: the reader's arrays as the exporter stored them
    (`scenes.folder.shard_format.decode_folder`). `encoding`: what the shard's index says its samples hold; a sample
    of the other kind is refused (the index and the shard disagree)."""
    if encoding is not None and is_decoded(files) != (encoding == DECODED):
        held = DECODED if is_decoded(files) else "files"
        raise ValueError(f"{arg}: object {key!r} of shard {str(shard)!r} holds a {held!r} sample, where "
                         f"{str(shard.parent / INDEX_FILE)!r} says the encoding is {encoding!r} (the shard and its "
                         "index disagree: export it again)")
    if is_decoded(files):
        try:
            return object_from_folder(decode_folder(files, shard / sample_folder_name(key)))
        except ValueError as exc:
            raise ValueError(f"{arg}: object {key!r} of shard {str(shard)!r}: {exc}") from None
    size = sum(len(v) for v in files.values())
    try:
        with tempfile.TemporaryDirectory(prefix="unips-shard-", dir=scratch_dir(size)) as tmp:
            try:
                folder = extract_sample(files, Path(tmp) / sample_folder_name(key))
            except ValueError as exc:  # a member naming no file inside the sample's folder
                raise ValueError(f"{arg}: shard {str(shard)!r}: {exc}") from None
            try:
                obj = load_object(folder, arg=arg)
            except (ValueError, FileNotFoundError) as exc:
                where = f"{shard}[{key}]"
                said = str(exc).replace(str(folder), where).removeprefix(f"{arg}: ")  # the flag is said once
                raise ValueError(f"{arg}: object {key!r} of shard {str(shard)!r}: {said}") from None
    except OSError as exc:  # a full scratch folder: errno 28 names no file, this names the folder and the fix
        if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
            raise
        where = scratch_dir(size) or tempfile.gettempdir()
        raise OSError(f"{arg}: no space left in the scratch folder {where!r} (TMPDIR, else the system's temporary "
                      f"folder) to unpack object {key!r} of shard {str(shard)!r} ({size} bytes); expected TMPDIR to "
                      "name a folder with room") from None
    return dataclasses.replace(obj, path=shard / folder.name)


def check_images(obj: PSObject, shard: Shard, arg: str = "--data") -> PSObject:
    """Refuse an object whose image count differs from the one its shard's index entry lists."""
    listed = next((o.get("images") for o in shard.entry["objects"]
                   if isinstance(o, dict) and o.get("name") == obj.name), None)
    if listed is not None and listed != obj.images.shape[0]:
        raise ValueError(f"{arg}: object {obj.name!r} of shard {str(shard.path)!r} holds {obj.images.shape[0]} images, "
                         f"where {INDEX_FILE} lists {listed} (the shard and its index disagree)")
    return obj


def iter_objects(root: str | Path, arg: str = "--data") -> Iterator[PSObject]:
    """Every object of the shards of a --data entry, in order (each shard's checksum verified first)."""
    seen: set[str] = set()
    for shard in resolve_shards(root, arg):
        for key, files in listed_samples(shard.path, shard.entry, arg):
            if key in seen:
                raise ValueError(f"{arg}: object {key!r} appears twice (again in shard {str(shard.path)!r})")
            seen.add(key)
            yield check_images(decode_object(key, files, shard.path, arg, shard.encoding), shard, arg)


# ------------------------------------------------------------------------------------------- streaming


def _seed(*parts: int) -> int:
    return int(np.random.default_rng([int(p) for p in parts]).integers(2**63))


def worker_skip(consumed: int, worker: int, workers: int) -> int:
    """How many samples loader worker `worker` of `workers` (0: the loading runs in-process) has produced when
    the training process has taken `consumed`: a DataLoader takes them from its workers in turn."""
    if workers <= 1:
        return consumed
    return len(range(worker, consumed, workers))


class ShardStream(torch.utils.data.IterableDataset):
    """The samples of a list of shards as an endless (or `epochs`-long) stream, split and shuffled as the module
    docstring says; `prepare` turns each decoded `PSObject` into what the stream yields (e.g. a training
    `Sample`). `skip`: samples the training process has already consumed (a resumed run), passed over without
    decoding."""

    def __init__(self, shards: list[Shard], prepare: Callable[[PSObject], Any], seed: int = 0, buffer: int = 100,
                 epochs: int | None = None, skip: int = 0, arg: str = "--data"):
        super().__init__()
        self.shards, self.prepare, self.seed, self.buffer = list(shards), prepare, int(seed), int(buffer)
        self.epochs, self.skip, self.arg = epochs, int(skip), arg

    def _raw(self, rank: int, worker: int) -> Iterator[tuple[str, dict[str, bytes], Shard]]:
        import webdataset as wds

        epochs = itertools.count() if self.epochs is None else range(self.epochs)
        for epoch in epochs:
            order = np.random.default_rng([self.seed, 7_001, epoch]).permutation(len(self.shards))
            mine = list(wds.split_by_worker(wds.split_by_node([self.shards[i] for i in order])))
            if not mine:
                return
            samples = ((key, files, shard) for shard in mine
                       for key, files in _verified_samples(shard, self.arg))
            rng = random.Random(_seed(self.seed, 7_002, epoch, rank, worker))
            yield from wds.shuffle(bufsize=self.buffer, initial=self.buffer, rng=rng)(samples)

    def __iter__(self) -> Iterator[Any]:
        from webdataset.utils import pytorch_worker_info

        rank, _, worker, workers = pytorch_worker_info()
        raw = self._raw(rank, worker)
        for _ in range(worker_skip(self.skip, worker, workers)):
            if next(raw, None) is None:
                return
        for key, files, shard in raw:
            obj = decode_object(key, files, shard.path, self.arg, shard.encoding)
            yield self.prepare(check_images(obj, shard, self.arg))


def _verified_samples(shard: Shard, arg: str) -> Iterator[tuple[str, dict[str, bytes]]]:
    yield from listed_samples(shard.path, shard.entry, arg)


def check_split(shards: list[Shard], world: int, workers: int, arg: str = "--data") -> None:
    """Streaming gives every (rank, loader worker) its own shards: refuse fewer shards than that."""
    need = world * max(workers, 1)
    if len(shards) < need:
        raise ValueError(f"{arg}: {len(shards)} shard(s) cannot feed {world} process(es) x {max(workers, 1)} loader "
                         f"worker(s); expected at least {need} (export with a smaller --shard-size, or lower "
                         "--loader-workers)")


def stream_samples(roots: list[str | Path], prepare: Callable[[PSObject], Any], *, seed: int, buffer: int,
                   workers: int, world: int = 1, skip: int = 0, arg: str = "--data") -> Iterator[Any]:
    """An endless iterator over the streamed samples of this process, from the shards of the --data entries
    `roots` (`ShardStream` in a DataLoader with `workers` worker processes; 0 decodes in this process)."""
    shards = [s for r in roots for s in resolve_shards(r, arg)]
    check_split(shards, world, workers, arg)
    stream = ShardStream(shards, prepare, seed=seed, buffer=buffer, skip=skip, arg=arg)
    if workers == 0:
        return iter(stream)
    return iter(torch.utils.data.DataLoader(stream, batch_size=None, num_workers=workers))
