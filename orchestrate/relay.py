"""The relay of short GPU runs (issue 41): what orchestrate.gpu_session needs besides the session itself.

- `resolve_init`: `--init shipped|PATH`, the weights a session continues from, checked against the shipped
  architecture before any work (a session never restarts from fresh weights by accident, and never trains a
  model that could not replace the shipped one).
- `pack`: the wheels' site.tar.xz and, with `orchestrate.asset_pack`, the training assets' archive.
- `unpack_carry`: on the GPU machine, the pack's archives unpacked into --work (Mitsuba's site folder put on
  the path of this process and of its steps).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tarfile
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path

from orchestrate.archives import unpack_once
from orchestrate.asset_pack import ASSET_ARCHIVE, check_assets, pack_assets
from scenes.cli.errors import UsageError

REPO = Path(__file__).resolve().parents[1]
UPLOAD_LIMIT = 64 * 2**20
"""Bytes that may travel to the GPU machine: the working tree plus what is carried."""
KEEP_VARIANTS = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
"""The Mitsuba variants the packed Mitsuba keeps (render, check, and the check's fallback)."""
SITE_ARCHIVE = "site.tar.xz"
MANIFEST = "manifest.json"
PACKED = ("mitsuba==3.9.1", "drjit==1.5.0", "OpenEXR", "trimesh", "colour-science", "colour-demosaicing", "webdataset",
          "braceexpand", "tyro==1.0.17", "docstring-parser", "typeguard")
"""The wheels docs/model.md downloads for the pack: what the GPU image lacks, or lacks in this version (matplotlib
and its dependencies are in the image, `GPU_IMAGE`: packing them too made site.tar.xz 52 MiB, over the limit)."""
GPU_IMAGE = tuple(
    """absl-py accelerate certifi charset-normalizer click cloudpickle contourpy cycler filelock fonttools fsspec
h5py huggingface-hub idna imageio jinja2 joblib kiwisolver lazy-loader markupsafe matplotlib mpmath networkx numpy
opencv-python-headless packaging pandas pillow psutil pyparsing python-dateutil pyyaml regex requests safetensors
scikit-image scipy setuptools six sympy tifffile timm torch torchvision tqdm typing-extensions urllib3
zipp""".split()
)
"""Packages of the GPU machines' image ('cuda', /work/.library/device/KINDS.md, 2026-11-17) that this project may
import: the rehearsal's fresh environment holds these and the pack, nothing else."""
MARGIN = 2**20
"""Bytes of the upload limit kept free when the assets are chosen (the tree grows between pack and run)."""
SITE_MEASURED = int(41.5 * 2**20)
"""The real site.tar.xz of docs/model.md's wheels, as measured (what the assets test budgets for)."""


# ---------------------------------------------------------------- --init


def resolve_init(init: str | None, model: str | None) -> tuple[str | None, str]:
    """(weights path or None, model name) of a session's `--init` and `--model`. `shipped`: the registry's
    shipped weights (of --model, or of the one model that has them); PATH: a .safetensors/.pt weights file
    whose model name and configuration equal the shipped weights' of that model (when it has any); else UsageError."""
    from unips.models import DEFAULT_TRAIN_MODEL, list_models, list_pretrained, load_model
    from unips.models.registry import pretrained_entry

    if init is None:
        name = model or DEFAULT_TRAIN_MODEL
        if name not in list_models():
            raise UsageError(f"--model: got {name!r}, expected one of {', '.join(list_models())}")
        return None, name
    if init == "shipped":
        names = [model] if model else list_pretrained()
        if len(names) != 1 or names[0] not in list_pretrained():
            raise UsageError(
                f"--init: 'shipped', but {'--model ' + repr(model) + ' has' if model else 'the registry has'} "
                f"no single shipped weights file (shipped: {', '.join(list_pretrained()) or 'none'}; "
                "expected --model naming one of them)"
            )
        return str(pretrained_entry(names[0]).weights_path), names[0]
    path = Path(init)
    if not path.is_file():
        raise UsageError(f"--init: {init!r} is not a file (expected 'shipped' or a previous run's "
                         "final.safetensors / last.pt)")
    try:
        _, meta = load_model(path)
    except Exception as exc:  # any unreadable weights file is one line
        raise UsageError(f"--init: {init!r} is not a weights file this package reads ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else ''})") from None
    name = meta.get("model_name")
    if model and name != model:
        raise UsageError(f"--init: {init!r} holds a {name!r} model, but --model is {model!r} (expected the same "
                         "architecture: the relay continues one model, it never restarts)")
    check_architecture(path, name, meta.get("config"), "--init")
    return str(path), name


def check_architecture(path: Path, name: str | None, config: dict | None, flag: str) -> None:
    """UsageError when `name`/`config` differ from the shipped weights of that model (if it has them)."""
    from unips.models import list_pretrained, load_model
    from unips.models.registry import pretrained_entry

    if name not in list_pretrained():
        raise UsageError(f"{flag}: {str(path)!r} holds a {name!r} model, which has no shipped weights (expected the "
                         f"shipped architecture, one of: {', '.join(list_pretrained()) or 'none'}; the relay continues "
                         "the shipped model)")
    shipped = pretrained_entry(name).weights_path
    ref = json.loads(json.dumps(load_model(shipped)[1].get("config") or {}))
    config = json.loads(json.dumps(config or {}, default=str))  # tuples of a .pt as lists, like the sidecar's
    diff = sorted(k for k in set(ref) | set(config) if ref.get(k) != config.get(k))
    if diff:
        raise UsageError(f"{flag}: {str(path)!r} is a {name!r} whose configuration differs from the shipped "
                         f"weights' in {', '.join(diff[:4])} (expected the shipped architecture: an architecture "
                         "change is a new model, trained by orchestrate.train_recipe, not a relay run)")


def write_manifest(dest: Path, entries: dict) -> None:
    from scenes.files import write_json

    write_json(dest / MANIFEST, entries, indent=1)


# ---------------------------------------------------------------- packing (here)


def _keep_member(name: str) -> bool:
    """Whether a wheel member is needed at run time: Mitsuba without its other variants, and neither package's
    headers, type stubs, CMake / pkg-config files or byte code."""
    parts = name.split("/")
    if parts[-1].endswith((".pyi", ".pyc")) or "__pycache__" in parts:
        return False
    if parts[0] in ("mitsuba", "drjit") and len(parts) > 1 and parts[1] in ("include", "cmake", "pkgconfig",
                                                                              "mitsuba_stubs", "stubs"):
        return False
    if parts[0] == "mitsuba" and len(parts) == 2:
        stem = parts[1].split(".")[0]
        variant_like = stem.startswith(("scalar_", "llvm_", "cuda_")) and parts[1].endswith(".so")
        if variant_like and stem not in KEEP_VARIANTS:
            return False
    return True


def tree_bytes(root: Path = REPO) -> int:
    """Bytes of the working tree that travels (git's tracked and untracked, not ignored files)."""
    try:
        names = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=root,
                               capture_output=True, check=True).stdout.split(b"\0")
    except (OSError, subprocess.CalledProcessError):
        return 0
    return sum((root / n.decode()).stat().st_size for n in names if n and (root / n.decode()).is_file())


DEVICE_PYTHON, DEVICE_GLIBC = (3, 12), (2, 39)
"""The GPU machine's Python and the newest glibc a wheel may ask for there (Linux on x86-64; sessions saw Python
3.12.3, Ubuntu 24.04's, whose glibc is 2.39: /work/.library/device/KINDS.md): a wheel must install there
(`check_wheel_names`)."""


def device_tags() -> frozenset:
    """The wheel tags pip accepts on the GPU machine (`packaging.tags`: CPython 3.12 and its stable ABI, pure
    Python; manylinux up to `DEVICE_GLIBC` and plain linux on x86-64)."""
    from packaging.tags import compatible_tags, cpython_tags

    platforms = ["linux_x86_64", "manylinux1_x86_64", "manylinux2010_x86_64", "manylinux2014_x86_64",
                 *(f"manylinux_2_{minor}_x86_64" for minor in range(5, DEVICE_GLIBC[1] + 1))]
    return frozenset([*cpython_tags(DEVICE_PYTHON, platforms=platforms),
                      *compatible_tags(DEVICE_PYTHON, "cp312", platforms=platforms)])


def check_wheel_names(wheels: Path, found: list[Path]) -> None:
    """The wheels' file names (PEP 427): each installable on the GPU machine (CPython 3.12 or pure Python, Linux on
    x86-64 or any platform), one version of each package, and mitsuba and drjit at the versions this toolkit runs
    (`PACKED`); UsageError naming the wheel otherwise."""
    from packaging.utils import InvalidWheelFilename, parse_wheel_filename
    from packaging.version import Version

    seen: dict[str, Path] = {}
    versions: dict[str, str] = {}
    for wheel in found:
        try:
            name, version, _, tags = parse_wheel_filename(wheel.name)
        except InvalidWheelFilename as exc:
            raise UsageError(f"--wheels: {wheel.name!r} is not a wheel's file name ({exc})") from None
        if not tags & device_tags():
            raise UsageError(f"--wheels: {wheel.name!r} does not install on the GPU machine (CPython 3.12 on Linux "
                             f"x86-64; its tags: {', '.join(sorted(map(str, tags)))[:160]})")
        if name in seen:
            raise UsageError(f"--wheels: {wheel.name!r} and {seen[name].name!r} are two wheels of {name}; keep the "
                             "one for the GPU machine")
        seen[name] = wheel
        versions[name] = str(version)
    for pin in PACKED[:2]:  # then the versions (two of one package said as such first)
        name, pinned = pin.split("==")
        if name in versions and Version(versions[name]) != Version(pinned):  # PEP 440: 3.9.1.0 is 3.9.1
            raise UsageError(f"--wheels: {seen[name].name!r} is {name} {versions[name]}; this toolkit runs {name} "
                             f"{pinned}")
    if missing := [p.split("==")[0] for p in PACKED[:2] if p.split("==")[0] not in seen]:
        raise UsageError(f"--wheels: {str(wheels)!r} has no {' or '.join(missing)} wheel (expected "
                         f"{', '.join(p.replace('==', '-') + '-cp312-...whl' for p in PACKED[:2])})")


def claim_session_outputs(out: Path, overwrite: bool) -> None:
    """A session's own files in --out (its run/ is unips.train's to claim): an earlier session's are replaced only
    with `overwrite`; a user's never (a JSON file without a session's keys; the curve without an earlier session's
    variant_check.json, the first file a session writes)."""
    from scenes.cli.outputs import claim_outputs

    owner = "orchestrate.gpu_session"
    claim_outputs([out / "variant_check.json", out / "model_card.json", out / "summary.json"], overwrite, "--out",
                  owner, signed={out / "variant_check.json": ("variant", "check_variant"),
                                 out / "model_card.json": ("model", "recipe"),
                                 out / "summary.json": ("variant", "check_variant", "options")})
    claim_outputs([out / "learning_curve.png"], overwrite, "--out", owner, marker=out / "variant_check.json")


def pack(dest: Path, wheels: Path, limit: int = UPLOAD_LIMIT, tree: int | None = None,
         assets: Path | None = None, overwrite: bool = False) -> int:
    """Write dest/site.tar.xz: every wheel in `wheels` unpacked as pip would (`_keep_member` filters Mitsuba to
    KEEP_VARIANTS), compressed; with `assets`, dest/assets.tar.xz (`pack_assets`, in what the limit leaves);
    dest/manifest.json records both. Returns the bytes that travel (the archives plus the working tree `tree`);
    UsageError with the measured size when they exceed `limit`. An earlier pack's files are replaced only with
    `overwrite` (and a manifest.json that is not a pack's never)."""
    from scenes.cli.outputs import check_apart, claim_outputs

    check_apart(dest, {"--wheels": wheels, "--assets": assets}, "--pack")  # else read as input by the next pack
    claim_outputs([dest / SITE_ARCHIVE, dest / MANIFEST, dest / ASSET_ARCHIVE], overwrite, "--pack",
                  "orchestrate.gpu_session --pack", signed={dest / MANIFEST: ("site", "tree_bytes")})
    found = sorted(wheels.glob("*.whl")) if wheels.is_dir() else []
    if not found:
        raise UsageError(f"--wheels: {str(wheels)!r} holds no .whl files (expected the Python 3.12 x86-64 wheels of "
                         "mitsuba, drjit and the packages the GPU machine lacks; see docs/model.md)")
    check_wheel_names(wheels, found)
    from scenes.files import atomic_write, not_a_file

    owner: dict[str, Path] = {}  # each packed file -> its wheel: the files of all wheels unpack side by side
    sizes: dict[str, int] = {}  # each packed file -> the bytes it unpacks to
    for wheel in found:  # every wheel readable before anything is written or the long compression starts
        if why := not_a_file(wheel):
            raise UsageError(f"--wheels: {str(wheel)!r} {why}")
        try:
            with zipfile.ZipFile(wheel) as z:
                bad = z.testzip()
                # a member packed as named would leave --carry's folder on unpacking
                odd = next((n for n in z.namelist() if n.startswith("/") or ".." in n.split("/")), None)
                infos = [i for i in z.infolist() if not i.is_dir() and _keep_member(i.filename)]
                kept = [i.filename for i in infos]
                sizes.update({i.filename: i.file_size for i in infos})
        except (zipfile.BadZipFile, OSError, zlib.error, EOFError, RuntimeError, NotImplementedError) as exc:
            # RuntimeError: an encrypted member; NotImplementedError: a compression zipfile cannot read (PPMd)
            raise UsageError(f"--wheels: {str(wheel)!r} is not a readable wheel ({exc}); expected the .whl files "
                             "pip downloads (see docs/model.md): download it again") from None
        if bad is not None:
            raise UsageError(f"--wheels: {str(wheel)!r} is damaged (member {bad!r} fails its CRC); download it again")
        if odd is not None:
            raise UsageError(f"--wheels: {str(wheel)!r} holds member {odd[:120]!r}, whose name leads outside the "
                             "folder it is unpacked into (expected names relative to it); not a wheel pip writes")
        for name in kept:
            if name in owner:  # the unpacker refuses a name twice: the pack would be useless on the GPU machine
                raise UsageError(f"--wheels: {wheel.name!r} and {owner[name].name!r} both hold {name[:120]!r} "
                                 "(expected wheels that install side by side); refused")
            owner[name] = wheel
    _check_unpacked_size(sizes, owner)
    folders = {n.rsplit("/", i)[0] for n in owner for i in range(1, n.count("/") + 1)}
    if clash := sorted(folders & owner.keys()):  # a file where another wheel's member needs a folder
        raise UsageError(f"--wheels: {owner[clash[0]].name!r} holds the file {clash[0][:120]!r}, which another "
                         "member needs as a folder (expected wheels that install side by side); refused")
    chosen = check_assets(assets) if assets is not None else None  # a bad asset named before the long compression
    dest.mkdir(parents=True, exist_ok=True)
    archive = dest / SITE_ARCHIVE

    def write(tmp: Path) -> None:
        with tarfile.open(tmp, "w:xz", preset=6) as tar:
            for wheel in found:
                with zipfile.ZipFile(wheel) as z:
                    for info in z.infolist():
                        if info.is_dir() or not _keep_member(info.filename):
                            continue
                        ti = tarfile.TarInfo(info.filename)
                        ti.size, ti.mode = info.file_size, 0o755 if info.filename.endswith(".so") else 0o644
                        with z.open(info) as f:
                            tar.addfile(ti, f)

    atomic_write(archive, write)  # a full disk leaves no half archive, and says which file it was
    try:
        total, mib = _finish_pack(dest, archive, found, limit, tree, assets, chosen)
    except UsageError:  # a pack over the limit is no pack: nothing of it stays to be carried by mistake
        for name in (SITE_ARCHIVE, ASSET_ARCHIVE, MANIFEST):
            (dest / name).unlink(missing_ok=True)
        raise
    print(f"packed {archive}: {mib}, within {limit / 2**20:.0f} MiB")
    return total


def _check_unpacked_size(sizes: dict[str, int], owner: dict[str, Path]) -> None:
    """UsageError when the wheels' kept members (name -> bytes, name -> wheel) unpack to more than the GPU machine's
    unpacking accepts (`orchestrate.archives.UNPACKED_LIMIT`): said when packing, not after the upload."""
    from orchestrate.archives import UNPACKED_LIMIT

    if (size := sum(sizes.values())) > UNPACKED_LIMIT:
        big = max(sizes, key=sizes.__getitem__)
        raise UsageError(f"--wheels: the wheels' kept members unpack to {size} bytes, over the "
                         f"{UNPACKED_LIMIT // 2**20} MiB an archive may unpack to (orchestrate.archives; the "
                         f"largest: {big!r} in {owner[big].name!r})")


def _finish_pack(dest: Path, archive: Path, found: list[Path], limit: int, tree: int | None,
                 assets: Path | None, chosen: tuple | None = None) -> tuple[int, str]:
    """The assets archive and the manifest beside a written site archive; UsageError when the whole is over
    `limit` (the manifest is written only for a pack within it)."""
    tree = tree_bytes() if tree is None else tree
    site = archive.stat().st_size
    manifest = {"site": {"archive": SITE_ARCHIVE, "bytes": site, "wheels": [w.name for w in found]}, "tree_bytes": tree,
                "upload_limit_bytes": limit}
    (dest / ASSET_ARCHIVE).unlink(missing_ok=True)  # an earlier pack's (claimed above) never outlives its manifest
    if assets is not None:
        manifest["assets"] = pack_assets(assets, dest, limit - site - tree - MARGIN, chosen)
    asset_bytes = manifest.get("assets", {}).get("bytes", 0)
    total = site + asset_bytes + tree
    manifest["total_bytes"] = total
    mib = (f"{total} bytes = {total / 2**20:.1f} MiB ({site / 2**20:.1f} MiB {archive}, {asset_bytes / 2**20:.1f} MiB "
           f"{ASSET_ARCHIVE}, {tree / 2**20:.1f} MiB working tree)")
    if total > limit:
        raise UsageError(
            f"--pack: what would travel is {mib}, over the {limit} bytes ({limit / 2**20:.0f} MiB) upload limit: "
            "leave out wheels the GPU machine has, or render the data here and carry shards instead; nothing was kept"
        )
    write_manifest(dest, manifest)
    return total, mib


# ---------------------------------------------------------------- on the GPU machine


def _flag(argv: list[str], name: str, default: str | None) -> str | None:
    for i, a in enumerate(argv):
        if a == name and i + 1 < len(argv):
            return argv[i + 1]
        if a.startswith(name + "="):
            return a.split("=", 1)[1]
    return default


def boot_site(argv: list[str]) -> None:
    """Before gpu_session imports its command-line machinery: where tyro is missing (a bare GPU machine: it travels
    in the pack), unpack the pack's site.tar.xz into --work/site and put it on the path, since the arguments cannot
    be parsed without it. Where tyro is installed nothing is unpacked here: `unpack_carry` does it after the
    arguments are checked (and `--help` touches no file). Bad values and archives: the command's own checks."""
    import importlib.util

    if importlib.util.find_spec("tyro") is not None:
        return
    carry, work = _flag(argv, "--carry", None), _flag(argv, "--work", "/tmp/gpu_session")
    if carry and _flag(argv, "--pack", None) is None and (Path(carry) / SITE_ARCHIVE).is_file():
        try:
            _site(Path(carry), Path(work), "--overwrite" in argv)
        except UsageError:
            pass  # reported by unpack_carry, once the command's error handling is in place


def _site(carry: Path, work: Path, replace: bool = False) -> Path:
    site = work / "site"
    if str(site) not in sys.path:
        made = [p for p in (site, *site.parents) if not os.path.lexists(p)]
        site.mkdir(parents=True, exist_ok=True)
        try:
            unpack_once(carry / SITE_ARCHIVE, site, replace=replace)
        except UsageError:  # a refused pack leaves nothing behind: the folders made for it go (what it wrote too)
            if made:
                shutil.rmtree(made[-1], ignore_errors=True)
            raise
        sys.path.insert(0, str(site))
        os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH")) if p)
    return site


def unpack_carry(carry: Path, work: Path, replace: bool = False, then: Callable[[Path | None], object] | None = None):
    """Unpack carry/site.tar.xz into work/site (put first on sys.path and on the steps' PYTHONPATH) and
    carry/assets.tar.xz into work/ (work/assets); returns the asset folder, or None when none was packed (with
    `then`: what then(asset folder) returns, the checks that need the carried packages). Either folder holding files
    this pack did not put there is refused, or with `replace` (--overwrite) emptied first
    (`orchestrate.archives.unpack_once`). A refusal, also by `then`, leaves nothing unpacked behind."""
    from scenes.files import not_a_file

    if not carry.is_dir() or not os.path.lexists(carry / SITE_ARCHIVE):
        raise UsageError(f"--carry: {str(carry)!r} holds no {SITE_ARCHIVE} (expected the folder written here by "
                         "`python -m orchestrate.gpu_session --pack .carry`)")
    for archive in (carry / SITE_ARCHIVE, carry / ASSET_ARCHIVE):
        if os.path.lexists(archive) and (why := not_a_file(archive)):
            raise UsageError(f"--carry: {str(archive)!r} {why}")
    if bad := next((work / n for n in ("site", "assets") if os.path.lexists(work / n) and not (work / n).is_dir()), 0):
        raise UsageError(f"--work: {str(bad)!r} is not a folder, where the session unpacks --carry's pack; expected "
                         "a --work without it (move it away)")
    marks = (work / f".{n}.unpacked" for n in ("site", "assets"))  # a record of ours, rewritten: a plain file only
    if bad := next((m for m in marks if os.path.lexists(m) and (m.is_symlink() or not m.is_file())), 0):
        raise UsageError(f"--work: {str(bad)!r} is not a plain file (a folder or a link), where the session records "
                         "which pack it unpacked; expected a --work without it (move it away)")
    fresh = [n for n in ("site", ".site.unpacked", "assets", ".assets.unpacked") if not os.path.lexists(work / n)]
    made = [p for p in (work, *work.parents) if not os.path.lexists(p)]
    _site(carry, work, replace)
    try:
        packed = None
        if (carry / ASSET_ARCHIVE).is_file():
            unpack_once(carry / ASSET_ARCHIVE, work, under="assets", replace=replace)
            from wildgen.assets import AssetLibrary

            try:  # packed, yet nothing to draw there: the archive is at fault, not the folder it was unpacked into
                AssetLibrary.scan(work / "assets")
            except (ValueError, OSError):
                raise UsageError(f"--carry: {str(carry / ASSET_ARCHIVE)!r} holds no asset folder (expected assets/ "
                                 "with the packed meshes, maps and textures); pack again with --pack, or remove it to "
                                 "render without") from None
            packed = work / "assets"
        return then(packed) if then is not None else packed
    except UsageError:  # a refused pack or flag leaves nothing behind: what was unpacked a moment ago goes too
        for p in (work / name for name in fresh):
            shutil.rmtree(p, ignore_errors=True) if p.is_dir() and not p.is_symlink() else p.unlink(missing_ok=True)
        if made:  # the folders made for it, empty again
            shutil.rmtree(made[-1], ignore_errors=True)
        raise
