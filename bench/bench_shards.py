"""Reading many small objects: object folders against WebDataset shards (samples per second, side by side).

    python bench/bench_shards.py [--objects 200] [--images 8] [--res 64] [--shard-size 100] [--out shards.json]

Writes `--objects` synthetic object folders (a Lambertian ellipsoid with a random albedo under random
directional lights plus sensor-like noise, 16-bit PNGs of `--res` px, written through `scenes.folder.format`; no
rendering) into a temporary folder, exports them twice with `wildgen.export` (`--shard-size` objects per shard):
`--encoding files` (the folder's files as they are) and `--encoding decoded` (the one reader's arrays), and reads
the three sources back three ways, each timed cold and warm:

- files: every file of every object read into memory (folders: list the folder, read each file; shards:
  verify the checksum, then webdataset's tar reader), the part that storage decides;
- objects: decoded by the model's loader (folders: `unips.data.load_object`; shards: `unips.shard_data.iter_objects`,
  which writes each `files` sample to a temporary folder and reads it with the same loader, and maps a `decoded`
  sample's arrays);
- samples: the training samples (`unips.train_data.load_samples` of the folder and of the shard pattern,
  cropped and resized to --res).

`cold`: before the pass, every file of both sources is written back (`os.sync`) and evicted from the page
cache with posix_fadvise(POSIX_FADV_DONTNEED), so it is read from the disk (on a virtual machine the host may
still cache it); `warm`: the fastest of `--repeats` further passes, from the page cache. The ratios are shard
objects/s over folder objects/s. Measured on a shared machine: rerun it before trusting one number.
"""
from __future__ import annotations

import dataclasses
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import MIN_RES, claim_result, parse, run_main, write_result  # noqa: E402
from scenes.cli.options import Command, arg, option  # noqa: E402


def write_objects(root: Path, count: int, images: int, res: int, seed: int = 0) -> None:
    """`count` object folders 00000.data ... of synthetic Lambertian ellipsoids (noisy, so PNGs do not shrink to
    nothing)."""
    from scenes.folder.format import write_object_folder

    rng = np.random.default_rng(seed)
    i, j = np.mgrid[0:res, 0:res] + 0.5
    for index in range(count):
        ri, rj = rng.uniform(0.25, 0.45, 2) * res
        x, y = (j - res / 2) / rj, -(i - res / 2) / ri
        q = 1 - x * x - y * y
        mask = q > 0.02
        n = np.stack([x, y, np.sqrt(np.clip(q, 0, None))], -1)
        n = np.where(mask[..., None], n / np.linalg.norm(n, axis=-1, keepdims=True), 0.0)
        lights = rng.normal(size=(images, 3))
        lights[:, 2] = np.abs(lights[:, 2]) + 0.5
        lights /= np.linalg.norm(lights, axis=1, keepdims=True)
        albedo = rng.uniform(0.3, 0.9, 3)
        shade = np.clip(np.einsum("hwc,kc->khw", n, lights), 0, None)[..., None] * albedo * mask[..., None]
        imgs = np.clip(shade + rng.normal(0, 0.004, shade.shape), 0, 1)
        scene = {"light_family": "directional",
                 "camera_lights": [{"directional": [{"direction_to_light": d.tolist(), "irradiance": [1, 1, 1]}],
                                    "other": 0} for d in lights]}
        write_object_folder(root / f"{index:05d}.data", imgs, mask, n, scene=scene)


def evict(paths: list[Path]) -> None:
    """Drop the files' pages from the page cache (after writing back dirty ones), so the next read is cold."""
    os.sync()
    for p in paths:
        fd = os.open(p, os.O_RDONLY)
        try:
            os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
        finally:
            os.close(fd)


def read_folder_files(data: Path) -> int:
    n = 0
    for folder in sorted(p for p in data.iterdir() if p.is_dir()):
        for p in sorted(folder.iterdir()):  # the synthetic folders have no subfolder
            p.read_bytes()
        n += 1
    return n


def read_shard_files(pattern: str) -> int:
    from scenes.folder.shard_format import iter_samples, verify_shard
    from unips.shard_data import resolve_shards

    n = 0
    for shard in resolve_shards(pattern):
        verify_shard(shard.path, shard.entry)
        n += sum(1 for _ in iter_samples(shard.path))
    return n


def decode_folders(data: Path) -> int:
    from unips.data import find_objects, load_object

    return sum(1 for p in find_objects(data) if load_object(p) is not None)


def decode_shards(pattern: str) -> int:
    from unips.shard_data import iter_objects

    return sum(1 for _ in iter_objects(pattern))


@dataclass
class Options:
    """The command line of bench/bench_shards.py."""

    objects: int = option(200, minimum=1)
    """Objects written and read."""
    images: int = option(8, minimum=1)
    """Images per object."""
    res: int = option(64, minimum=MIN_RES)
    """Image side in pixels (at least 8: an object needs pixels)."""
    shard_size: int = option(100, minimum=1)
    """Objects per shard."""
    repeats: int = option(3, minimum=1)
    """warm passes of each reader (the fastest is kept)"""
    out: Annotated[Path | None, arg(metavar="FILE")] = None
    """also write the results as JSON here"""


COMMAND = Command(Options, prog="python bench/bench_shards.py", description=__doc__.split("\n\n")[0])
RESULT_KEYS = ("settings", "sizes", "rows")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    claim_result(args.out, RESULT_KEYS, COMMAND)

    import importlib

    import torch

    importlib.import_module("webdataset")  # imported now, not inside the first timed pass
    from scenes.folder.shard_format import ENCODINGS
    from unips.train_data import load_samples
    from wildgen.export import export_dataset

    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory(prefix="bench-shards-") as tmp:
        data = Path(tmp) / "data"
        t0 = time.perf_counter()
        write_objects(data, args.objects, args.images, args.res)
        folder_files = [p for p in data.rglob("*") if p.is_file()]
        patterns, shard_files, sizes = {}, [], {"folder_files": len(folder_files),
                                                "folder_bytes": sum(p.stat().st_size for p in folder_files)}
        for encoding in ENCODINGS:
            out = Path(tmp) / f"shards-{encoding}"
            index = export_dataset(data, out, shard_size=args.shard_size, encoding=encoding)
            patterns[encoding] = str(out / index["pattern"])
            files = sorted(out.glob("*.tar")) + [out / "index.json"]
            shard_files += files
            sizes[f"shards_{encoding}"] = len(files) - 1
            sizes[f"shard_bytes_{encoding}"] = sum(p.stat().st_size for p in files)
        print(f"{args.objects} objects x {args.images} images at {args.res} px: {sizes['folder_files']} files "
              f"({sizes['folder_bytes'] / 2**20:.1f} MiB) vs {sizes['shards_files']} shards of files "
              f"({sizes['shard_bytes_files'] / 2**20:.1f} MiB) and of decoded arrays "
              f"({sizes['shard_bytes_decoded'] / 2**20:.1f} MiB); written in {time.perf_counter() - t0:.1f} s")
        sources = ("folders",) + ENCODINGS
        readers = {
            "files": {"folders": lambda: read_folder_files(data),
                      **{e: partial(read_shard_files, patterns[e]) for e in ENCODINGS}},
            "objects": {"folders": lambda: decode_folders(data),
                        **{e: partial(decode_shards, patterns[e]) for e in ENCODINGS}},
            "samples": {"folders": lambda: len(load_samples(data, args.res)),
                        **{e: partial(lambda p: len(load_samples(p, args.res)), patterns[e]) for e in ENCODINGS}},
        }
        rows = []
        for what, fns in readers.items():
            for cache in ("cold", "warm"):
                rates: dict[str, float] = {}
                for _ in range(1 if cache == "cold" else args.repeats):  # warm: the best of --repeats passes
                    for source in sources:
                        if cache == "cold":
                            evict(folder_files + shard_files)
                        t = time.perf_counter()
                        n = fns[source]()
                        seconds = time.perf_counter() - t
                        assert n == args.objects, (what, source, n)
                        rates[source] = max(rates.get(source, 0.0), n / seconds)
                rows.append({"read": what, "cache": cache, **{f"{s}_per_s": round(rates[s], 1) for s in sources},
                             **{f"ratio_{e}": round(rates[e] / rates["folders"], 2) for e in ENCODINGS}})
    from scenes.report.tables import markdown_table

    print()
    print(
        markdown_table(
            [
                "read",
                "cache",
                "folders (objects/s)",
                "shards, files (objects/s)",
                "shards, decoded (objects/s)",
                "files / folders",
                "decoded / folders",
            ],
            [
                [
                    r["read"],
                    r["cache"],
                    f"{r['folders_per_s']:.0f}",
                    f"{r['files_per_s']:.0f}",
                    f"{r['decoded_per_s']:.0f}",
                    f"{r['ratio_files']:.2f}x",
                    f"{r['ratio_decoded']:.2f}x",
                ]
                for r in rows
            ],
        )
    )
    if args.out:
        settings = dataclasses.asdict(args) | {"out": str(args.out)}
        write_result(args.out, {"settings": settings, "sizes": sizes, "rows": rows}, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
