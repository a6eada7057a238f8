"""The training assets that travel in orchestrate.gpu_session's pack, chosen by `ASSET_RULE` (recorded in the
pack's manifest.json): the recipe's training split only (`orchestrate.asset_split.split_plan`, never a held-out
mesh or HDR map), every training mesh, every training HDR map reduced to `HDR_WIDTH` px, then whole texture sets
in name order while the upload limit allows. `check_assets` refuses a folder the session could not use before
the pack's long compression starts; `pack_assets` writes the archive.
"""
from __future__ import annotations

import io
import lzma
import tarfile
from pathlib import Path

from orchestrate.archives import UNPACKED_LIMIT
from scenes.cli.errors import UsageError

ASSET_ARCHIVE = "assets.tar.xz"
HDR_WIDTH = 256
"""Width of the packed HDR maps (equirectangular, 256 x 128; area-averaged, so each light keeps its energy):
renders are 128 px, and a 1k map alone is 1.5 MiB, 28 of them more than the upload limit leaves."""
ASSET_RULE = (f"the training split of orchestrate.asset_split.split_plan (the last quarter of the meshes and the "
              f"last fifth of the HDR maps by name are held out and never packed); every training mesh folder; "
              f"every training HDR map area-resampled to {HDR_WIDTH} px wide; then whole texture sets in name order "
              f"while the upload limit (and the 1 GiB a pack unpacks to) allows")


def asset_choice(
    assets: Path,
) -> tuple[list[tuple[Path, str]], list[tuple[Path, str]], list[list[tuple[Path, str]]], list[str]]:
    """(meshes, HDR maps, texture sets, held-out names) of the training split: (file, name in the archive) pairs."""
    from orchestrate.asset_split import SPLIT_FOLDERS, split_plan

    plan = split_plan(assets, Path("/split"))
    train = Path("/split") / SPLIT_FOLDERS[0]
    meshes, hdris, held = [], [], []
    for link, src in sorted(plan.items()):
        if link.parent.name in SPLIT_FOLDERS:  # the shared texture folder: chosen below
            continue
        if train not in link.parents:
            held.append(f"{link.parent.name}/{src.name}")
        elif link.parent.name == "meshes":
            files = sorted(p for p in src.rglob("*") if p.is_file()) if src.is_dir() else [src]
            meshes += [(p, f"meshes/{p.relative_to(src.parent)}") for p in files]
        else:
            hdris.append((src, f"hdri/{src.stem}.hdr"))
    tex = assets / "textures"
    sets = []
    if tex.is_dir():
        for d in sorted(
            {
                p.parent
                for p in tex.rglob("*")
                if p.is_file() and p.suffix.lower() in (".jpg", ".jpeg", ".png", ".exr", ".tif", ".tiff")
            }
        ):
            sets.append([(p, f"textures/{p.relative_to(tex)}") for p in sorted(d.iterdir()) if p.is_file()])
    return meshes, hdris, sets, held


def _small_hdr(src: Path) -> bytes:
    import cv2

    from scenes.images import decode_image

    img = decode_image(src, cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH, f"--assets: {str(src)!r}")
    if img is None:
        raise UsageError(f"--assets: {str(src)!r} is not an HDR map OpenCV reads")
    img = cv2.resize(img, (HDR_WIDTH, HDR_WIDTH // 2), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".hdr", img)
    return buf.tobytes()


Chosen = tuple[list[tuple[str, bytes]], list[list[tuple[Path, str]]], list[str]]
"""What `check_assets` chose: (archive name, bytes) of the training meshes and reduced HDR maps, the texture
sets as (file, archive name) lists, the held-out names."""


def check_assets(assets: Path) -> Chosen:
    """The training split of `assets` read and checked (`Chosen`): UsageError naming --assets for a folder that
    is not one, holds too few assets to split, a link out of it, a mesh without faces or an unreadable map."""
    if not assets.is_dir():
        raise UsageError(f"--assets: {str(assets)!r} is not a folder (expected an asset folder with meshes/ and hdri/, "
                         "or 'none')")
    meshes, hdris, sets, held = asset_choice(assets)
    if not meshes and not hdris:
        raise UsageError(f"--assets: {str(assets)!r} has too few meshes and HDR maps to split into training and "
                         "held-out assets (expected meshes/ and hdri/ as in ../shared/assets)")
    from orchestrate.asset_split import check_packable

    if (total := sum(p.stat().st_size for p, _ in meshes)) > UNPACKED_LIMIT:  # before minutes of reading
        big = max((p for p, _ in meshes), key=lambda p: p.stat().st_size)
        raise UsageError(f"--assets: the training meshes of {str(assets)!r} are {total} bytes, over the "
                         f"{UNPACKED_LIMIT // 2**20} MiB a pack unpacks to (orchestrate.archives; the largest: "
                         f"{str(big)!r}, {big.stat().st_size} bytes); expected a smaller asset folder")
    check_packable(assets, [p for p, _ in meshes] + [p for p, _ in hdris] + [p for f in sets for p, _ in f])
    return [(a, p.read_bytes()) for p, a in meshes] + [(a, _small_hdr(p)) for p, a in hdris], sets, held


def pack_assets(assets: Path, dest: Path, budget: int, chosen: Chosen | None = None) -> dict:
    """Write dest/assets.tar.xz (`ASSET_RULE`, within `budget` bytes) of what `check_assets` chose (read now
    unless given) and return its manifest entry."""
    members, sets, held = chosen or check_assets(assets)
    names = [a for a, _ in members]
    used = sum(len(lzma.compress(b, preset=6)) for _, b in members)
    if used > budget:
        raise UsageError(f"--assets: the training meshes and maps of {str(assets)!r} need {used} bytes compressed, "
                         f"over the {budget} bytes the upload limit leaves (expected a smaller asset folder)")
    packed_sets, skipped, unpacked = [], [], sum(len(b) for _, b in members)
    for files in sets:
        data = [(a, p.read_bytes()) for p, a in files]
        size, raw = sum(len(lzma.compress(b, preset=6)) for _, b in data), sum(len(b) for _, b in data)
        name = str(Path(files[0][1]).parent)
        if used + size <= budget and unpacked + raw <= UNPACKED_LIMIT:
            members = members + data  # not the caller's list
            used, unpacked = used + size, unpacked + raw
            packed_sets.append(name)
        else:
            skipped.append(name)
    dest.mkdir(parents=True, exist_ok=True)
    from scenes.files import atomic_write

    def write(tmp: Path) -> None:
        with tarfile.open(tmp, "w:xz", preset=6) as tar:
            for arc, data in members:
                ti = tarfile.TarInfo(f"assets/{arc}")
                ti.size, ti.mode = len(data), 0o644
                tar.addfile(ti, io.BytesIO(data))

    atomic_write(dest / ASSET_ARCHIVE, write)
    size = (dest / ASSET_ARCHIVE).stat().st_size
    if size > budget:
        raise UsageError(f"--assets: {ASSET_ARCHIVE} is {size} bytes, over the {budget} bytes the upload limit leaves")
    return {"source": str(assets), "rule": ASSET_RULE, "bytes": size, "budget_bytes": budget,
            "meshes": sorted({a.split("/")[1] for a in names if a.startswith("meshes/")}),
            "hdri": [a for a in names if a.startswith("hdri/")],
            "texture_sets": packed_sets, "texture_sets_left_out": skipped, "held_out_never_packed": held}


