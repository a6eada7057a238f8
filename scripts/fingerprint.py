"""Fingerprint of the toolkit's outputs for fixed seeds: one SHA-256 per output file, to show that a change of
the code's structure changed no byte of what the commands write.

    python scripts/fingerprint.py --work W --out fingerprint.json [--assets ../shared/assets]
    python scripts/fingerprint.py --work W --out F --hash-only   # hash only
    python scripts/fingerprint.py --compare A.json B.json

It runs the real commands, as a user would: a dataset of every light family, a level-5 dataset (clusters,
surface detail, perspective), a dataset through a sensor preset, shards of both encodings, a prediction of
the shipped model and the known-scene re-render report. Files that hold wall-clock times, host names or
pictures drawn for people (contact sheets, figures) are listed by name but not hashed; JSON reports are
hashed with their timing fields removed, so that what they measure is compared and when is not.
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import json
import subprocess
import sys
from pathlib import Path

# JSON keys whose values are wall-clock measurements or the run's environment, not results.
VOLATILE_KEYS = {"seconds", "elapsed_s", "time_s", "timings", "wall_s", "started", "finished", "host", "hostname",
                 "pid", "created", "duration_s", "render_seconds", "peak_rss_mb", "node", "worker", "date",
                 "python", "platform", "argv", "command", "updated",
                 "rerender_over_original"}
FIGURE_SUFFIXES = (".png",)
FIGURE_DIRS = ("preview", "figures")
FIGURE_NAMES = ("figure.png", "error.png", "overview.png", "stats.png")


def _volatile(key: str) -> bool:
    return key in VOLATILE_KEYS or key.endswith("_s")  # a duration in seconds


def _strip(value, work: str):
    if isinstance(value, dict):
        return {k: _strip(v, work) for k, v in value.items() if not _volatile(k)}
    if isinstance(value, list):
        return [_strip(v, work) for v in value]
    if isinstance(value, str):
        return value.replace(work, "<work>")
    return value


def _csv_digest(path: Path) -> str:
    rows = list(csv.reader(path.read_text().splitlines()))
    keep = [i for i, name in enumerate(rows[0] if rows else []) if not _volatile(name)]
    text = "\n".join(",".join(row[i] for i in keep if i < len(row)) for row in rows)
    return "csv:" + hashlib.sha256(text.encode()).hexdigest()


def file_digest(path: Path, work: Path) -> str:
    if path.suffix == ".json" and path.name != "scene.json":
        try:
            data = json.loads(path.read_text())
        except ValueError:
            return hashlib.sha256(path.read_bytes()).hexdigest()
        return "json:" + hashlib.sha256(json.dumps(_strip(data, str(work)), sort_keys=True).encode()).hexdigest()
    if path.suffix == ".csv":
        return _csv_digest(path)
    if path.suffix in (".jsonl", ".log", ".txt") and path.name != "filenames.txt":
        return "not hashed (log)"
    if path.name in FIGURE_NAMES or any(part in FIGURE_DIRS for part in path.parts):
        return "not hashed (figure)"
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run(cmd: list[str], cwd: Path) -> None:
    print("+", " ".join(cmd), flush=True)
    subprocess.run([sys.executable, "-m", *cmd], cwd=cwd, check=True)


def produce(work: Path, assets: Path | None) -> None:
    work.mkdir(parents=True, exist_ok=True)
    families = ("directional,point,near_area,hdri,mixed,verse,flash,frontal,grid96,light_stage,display")
    common = ["--images", "4", "--res", "32", "--spp", "8", "--gt-spp", "4", "--quiet", "--overwrite"]
    asset_args = ["--assets", str(assets)] if assets else []
    run(["wildgen.make", "--lights", families, "--objects", "11", "--seed", "5", "--out", "families",
         *asset_args, *common], work)
    run(["wildgen.make", "--level", "5", "--objects", "3", "--seed", "6", "--camera", "perspective",
         "--focal", "15-300", "--out", "level5", *asset_args, *common], work)
    run(["wildgen.make", "--preset", "phone-flash", "--objects", "2", "--seed", "7", "--out", "phone",
         *common], work)
    run(["wildgen.export", "--format", "webdataset", "--data", "families", "--out", "shards_files",
         "--overwrite"], work)
    run(["wildgen.export", "--format", "webdataset", "--encoding", "decoded", "--data", "families",
         "--out", "shards_decoded", "--overwrite"], work)
    run(["unips.predict", "--method", "model", "--input", "families", "--out", "pred", "--overwrite"], work)
    run(["validate.rerender", "--data", "families", "--normals", "pred", "--out", "rerender",
         "--overwrite"], work)


def fingerprint(work: Path) -> dict[str, str]:
    return {str(p.relative_to(work)): file_digest(p, work) for p in sorted(work.rglob("*")) if p.is_file()}


def compare(a: dict[str, str], b: dict[str, str]) -> int:
    bad = 0
    for name in sorted(set(a) | set(b)):
        if a.get(name) != b.get(name):
            bad += 1
            print(f"differs: {name}: {a.get(name, 'missing')} != {b.get(name, 'missing')}")
    same = sum(1 for n in a if a.get(n) == b.get(n) and not a[n].startswith("not hashed"))
    print(f"{same} files identical, {bad} differ, "
          f"{sum(1 for v in a.values() if v.startswith('not hashed'))} listed without hash")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--work", type=Path)
    p.add_argument("--out", type=Path)
    p.add_argument("--assets", type=Path)
    p.add_argument("--compare", nargs=2, type=Path)
    p.add_argument("--hash-only", action="store_true", help="hash an existing --work folder without running")
    args = p.parse_args(argv)
    if args.compare:
        return compare(*(json.loads(f.read_text()) for f in args.compare))
    if not args.work or not args.out:
        p.error("--work and --out are required without --compare")
    if not args.hash_only:
        produce(args.work.resolve(), args.assets.resolve() if args.assets else None)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this tree's scenes.files
    from scenes.files import write_json

    write_json(args.out, fingerprint(args.work.resolve()), indent=1, sort_keys=True, newline=True)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
