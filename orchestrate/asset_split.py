"""The asset split of the training recipe: which meshes and HDR maps train and which are held out.

`split_plan` is the rule (the last quarter of the meshes and the last fifth of the HDR maps, sorted by name,
held out; the textures shared); `orchestrate.train_recipe` writes it into its --work as folders of links,
`orchestrate.relay` packs only its training half for a GPU session, `bench/ab_data.py` reuses it.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

from scenes.cli.errors import UsageError

SPLIT_FOLDERS = ("train_assets", "heldout_assets")
"""The asset split in --work: folders of symbolic links to the --assets files, written by this recipe only."""


def split_plan(assets: Path, work: Path) -> dict[Path, Path]:
    """The asset split as {link in --work: the --assets file it points to}: the last quarter of the meshes and
    the last fifth of the HDR maps (sorted by name, rounded up) held out, the texture folder shared. The links point
    to absolute paths (a relative --assets would be read from the link's own folder, and break)."""
    assets = Path(assets).resolve()
    train, held = (work / d for d in SPLIT_FOLDERS)
    links: dict[Path, Path] = {}
    for d in (train, held):
        if (assets / "textures").is_dir():
            links[d / "textures"] = assets / "textures"
    meshes = (
        sorted(p for p in (assets / "meshes").iterdir() if p.is_dir() or p.suffix.lower() in (".obj", ".ply", ".stl"))
        if (assets / "meshes").is_dir()
        else []
    )
    hdris = (
        sorted(p for p in (assets / "hdri").iterdir() if p.suffix.lower() in (".hdr", ".exr"))
        if (assets / "hdri").is_dir()
        else []
    )
    for items, sub, share in ((meshes, "meshes", 4), (hdris, "hdri", 5)):
        cut = len(items) - math.ceil(len(items) / share)
        for i, p in enumerate(items):
            links[(train if i < cut else held) / sub / p.name] = p
    return links


def existing_split(work: Path) -> dict[Path, Path]:
    """The links of an earlier split in --work. Anything else found there (a file, a folder other than meshes/
    and hdri/) was not written by this recipe: UsageError, it is never deleted."""
    found: dict[Path, Path] = {}
    for name in SPLIT_FOLDERS:
        d = work / name
        if not os.path.lexists(d):
            continue
        if d.is_symlink() or not d.is_dir():
            raise UsageError(f"--work: {str(d)!r} is not a folder of this recipe's asset split; it is never replaced: "
                             "move it away or use another --work")
        entries = list(d.iterdir())
        for sub in ("meshes", "hdri"):
            if (d / sub).is_dir() and not (d / sub).is_symlink():
                entries += list((d / sub).iterdir())
        for e in entries:
            if e.is_symlink():
                found[e] = Path(os.readlink(e))
            elif not (e.parent == d and e.name in ("meshes", "hdri") and e.is_dir()):
                raise UsageError(
                    f"--work: {str(e)!r} was not written by orchestrate.train_recipe (its asset split holds "
                    "only links to --assets); it is never deleted: move it away or use another --work"
                )
    return found


def holds_assets(plan: dict[Path, Path], half: Path, assets: Path) -> bool:
    """Whether the half `half` of the split `plan` is an asset folder wildgen.make accepts: a mesh or an HDR map of
    its own, or a texture set (a folder in the shared textures/)."""
    textures = Path(assets) / "textures"
    return (any(link.parent.parent == half and link.parent.name in ("meshes", "hdri") for link in plan)
            or (textures.is_dir() and any(p.is_dir() for p in textures.iterdir())))


def _too_few(assets: Path, half: str) -> UsageError:
    return UsageError(f"--assets: {str(assets)!r} has too few meshes and HDR maps to split (the last quarter of the "
                      f"meshes and the last fifth of the maps are held out) and no texture sets: {half} would be "
                      "empty; expected at least 2 meshes or 2 HDR maps, or texture sets in textures/")


def check_split(assets: Path | None, work: Path, overwrite: bool) -> bool:
    """Whether the split must be (re)written: False when --work holds the same split already. A split of another
    asset folder is replaced only with --overwrite (`scenes.cli.outputs.claim_outputs`' rule); foreign files never."""
    found = existing_split(work)
    if assets is None:
        return False
    planned = split_plan(assets, work)
    for name in SPLIT_FOLDERS:  # each half must be an asset folder wildgen.make accepts
        if not holds_assets(planned, work / name, assets):
            raise _too_few(assets, name)
    if not found or found == planned:
        return not found
    if not overwrite:
        raise UsageError(f"--assets: {str(work / SPLIT_FOLDERS[0])!r} holds an earlier split of another asset folder "
                         f"(e.g. {str(next(iter(found.values())))!r}); pass --overwrite to split --assets again (the "
                         "datasets are rendered again too), or use another --work")
    return True


def split_assets(assets: Path, work: Path) -> tuple[Path, Path]:
    """Write the asset split (`split_plan`): symlink folders train_assets/ and heldout_assets/, after removing the
    links of an earlier split (`existing_split`; nothing else is ever removed)."""
    plan = split_plan(assets, work)
    if not holds_assets(plan, work / SPLIT_FOLDERS[0], assets):
        raise _too_few(assets, SPLIT_FOLDERS[0])
    for link in existing_split(work):
        link.unlink()
    for name in SPLIT_FOLDERS:
        for sub in ("meshes", "hdri"):
            (work / name / sub).mkdir(parents=True, exist_ok=True)
    for link, target in plan.items():
        os.symlink(target, link)
    return work / SPLIT_FOLDERS[0], work / SPLIT_FOLDERS[1]


def check_packable(assets: Path, files: list[Path]) -> None:
    """Refuse a file reached through a link that leads out of the asset folder (the pack leaves the machine, so it
    carries the folder's own files only: a link could pack any file this user may read), and a mesh the renderer
    cannot use (no faces, corrupt: wildgen.make's own up-front check would refuse it on the GPU machine, after the
    start-up that device time pays for)."""
    import os

    from scenes.cli.errors import UsageError
    from scenes.files import is_within
    from scenes.meshes import MESH_SUFFIXES, load_mesh

    out = next((p for p in files if not is_within(p, assets)), None)
    if out is not None:
        raise UsageError(f"--assets: {str(out)!r} leads outside {str(assets)!r} through a link (to "
                         f"{os.path.realpath(out)!r}); the pack carries the asset folder's own files only: copy the "
                         "file in, or remove the link")
    for p in files:
        if p.suffix.lower() in MESH_SUFFIXES:
            try:
                load_mesh(p)
            except (ValueError, OSError) as exc:
                raise UsageError(f"--assets: {exc}; fix or remove the file (it is in the training split)") from None
