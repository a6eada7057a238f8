"""Archives the toolkit reads are untrusted (issue 50, item 1): a shard or a relay pack whose member names lead
outside the target is refused in one line and writes nothing there, even when its index was rewritten to match
(a checksum is not authentication)."""

from __future__ import annotations

import io
import json
import re
import tarfile
from pathlib import Path

import pytest

from scenes.files import sha256_file


@pytest.fixture(autouse=True)
def _own_import_path(monkeypatch):
    """A pack unpacked here puts its site first on sys.path and PYTHONPATH (as a session does): its stand-in
    mitsuba and drjit packages must not be what later tests of this process import."""
    import os
    import sys

    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.setenv("PYTHONPATH", os.environ.get("PYTHONPATH", ""))


def _export(folder: Path, out: Path) -> Path:
    """The one object folder, exported as shards into `out` (a dataset folder apart from it)."""
    import shutil

    from wildgen.export import export_dataset

    data = out.parent / "dataset"
    shutil.copytree(folder, data / folder.name)
    export_dataset(data, out)
    return out


def _rename_samples(shards: Path, new_key: str) -> None:
    """What whoever ships the shards can do: rename every member's key and rewrite index.json to match."""
    from scenes.folder.shard_format import INDEX_FILE

    index = json.loads((shards / INDEX_FILE).read_text())
    for entry in index["shards"]:
        path = shards / entry["name"]
        with tarfile.open(path) as src:
            members = [(m, src.extractfile(m).read()) for m in src.getmembers() if m.isfile()]
        buf = io.BytesIO()
        with tarfile.open(fileobj=buf, mode="w") as dst:
            for m, data in members:
                info = tarfile.TarInfo(new_key + m.name[m.name.index("."):])
                info.size = len(data)
                dst.addfile(info, io.BytesIO(data))
        path.write_bytes(buf.getvalue())
        entry.update(sha256=sha256_file(path), bytes=path.stat().st_size,
                     objects=[{**o, "name": new_key} for o in entry["objects"]])
    (shards / INDEX_FILE).write_text(json.dumps(index))


@pytest.mark.parametrize("key", ["../../escaped", "/tmp/escaped-abs", "a\\b"])
def test_a_shard_whose_names_lead_outside_is_refused_and_writes_nothing(synthetic_object, tmp_path, capsys, key):
    from scenes.folder.shard_format import extract_sample, iter_samples
    from unips.train import main
    from unips.train_data import load_samples

    shards = _export(synthetic_object, tmp_path / "shards")
    _rename_samples(shards, key)
    with pytest.raises(ValueError, match="not a plain object name"):
        list(iter_samples(shards / "000000.tar"))
    with pytest.raises(ValueError, match="not a plain object name"):
        load_samples(shards, 32)
    before = sorted(p for p in tmp_path.rglob("*"))
    assert main(["--data", str(shards), "--out", str(tmp_path / "run"), "--model", "glc-test", "--steps", "1",
                 "--res", "32", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a plain object name" in err[0], err
    assert not list(tmp_path.parent.glob("escaped*")) and not Path("/tmp/escaped-abs.data").exists()
    assert [p for p in sorted(tmp_path.rglob("*")) if p not in before and "run" not in p.parts] == []
    # The writer of one sample refuses a member path that leaves its folder before writing anything.
    with pytest.raises(ValueError, match="outside its folder"):
        extract_sample({"scene.json": b"{}", "../../x.json": b"{}"}, tmp_path / "one.data")
    assert not (tmp_path / "one.data").exists()


@pytest.mark.parametrize("kind", [tarfile.SYMTYPE, tarfile.DIRTYPE])
def test_a_shard_member_that_is_not_a_plain_file_is_named(synthetic_object, tmp_path, kind):
    """WebDataset's reader passes over links and folders, so a sample would silently lack a file (and fail later
    under a misleading name): the shard is refused naming the member (sweep 8)."""
    from scenes.folder.shard_format import iter_samples

    shards = _export(synthetic_object, tmp_path / "shards")
    path = shards / "000000.tar"
    assert [key for key, _ in iter_samples(path)] == ["ball"]  # as exported: read
    with tarfile.open(path, "a") as tar:
        odd = tarfile.TarInfo("ball.extra.png")
        odd.type, odd.linkname = kind, "/etc/hostname" if kind == tarfile.SYMTYPE else ""
        tar.addfile(odd)
    with pytest.raises(ValueError, match=r"holds member 'ball.extra.png', a link, folder, sparse or special file"):
        list(iter_samples(path))


def test_a_shard_member_named_twice_is_refused_naming_it(synthetic_object, tmp_path):
    """Sweep 25: one member name twice in a shard (the second another content): refused as such, not as a sample
    the index does not list."""
    from scenes.folder.shard_format import iter_samples

    shards = _export(synthetic_object, tmp_path / "shards")
    path = shards / "000000.tar"
    with tarfile.open(path) as tar:
        first = next(m for m in tar if m.isreg())
    with tarfile.open(path, "a") as tar:
        again = tarfile.TarInfo(first.name)
        again.size = 3
        tar.addfile(again, io.BytesIO(b"bad"))
    with pytest.raises(ValueError, match=rf"holds member '{first.name}' twice"):
        list(iter_samples(path))


def test_a_shard_member_that_says_it_holds_more_than_the_shard_is_refused_before_it_is_read(synthetic_object,
                                                                                             tmp_path):
    """Sweep 25: a member whose header claims 8 or 16 GiB (a GNU sparse file, or a size field rewritten; the index's
    checksum rewritten to match): WebDataset reads a member whole into memory, and unips.train was killed for
    memory after 73 s. Refused from the header, naming the member, before any member is read."""
    from scenes.folder.shard_format import iter_samples

    shards = _export(synthetic_object, tmp_path / "shards")
    path = shards / "000000.tar"
    with tarfile.open(path, "a") as tar:
        big = tarfile.TarInfo("ball.extra.png")
        big.size = 4096
        tar.addfile(big, io.BytesIO(bytes(4096)))
    data = bytearray(path.read_bytes())
    at = data.rfind(b"ball.extra.png")  # its header: the size field (12 octal bytes) at offset 124
    data[at + 124:at + 136] = b"%011o\0" % (8 * 2**30 - 1)  # the most an octal size field says
    data[at + 148:at + 156] = b" " * 8
    data[at + 148:at + 155] = b"%06o\0" % sum(data[at:at + 512])
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"holds member 'ball.extra.png', which says it holds 8589934591 bytes, more "
                                         r"than the shard's"):
        list(iter_samples(path))


def _archive(path: Path, members: list[tuple[tarfile.TarInfo, bytes | None]]) -> Path:
    with tarfile.open(path, "w:xz") as tar:
        for info, data in members:
            tar.addfile(info, io.BytesIO(data) if data is not None else None)
    return path


def _file(name: str, data: bytes = b"x") -> tuple[tarfile.TarInfo, bytes]:
    info = tarfile.TarInfo(name)
    info.size = len(data)
    return info, data


def _site() -> list[tuple[tarfile.TarInfo, bytes]]:
    """The least site.tar.xz a session takes: the packed Mitsuba and Dr.Jit (here, empty packages)."""
    return [_file("mitsuba/__init__.py", b""), _file("drjit/__init__.py", b"")]


def _link(name: str, target: str) -> tuple[tarfile.TarInfo, None]:
    info = tarfile.TarInfo(name)
    info.type, info.linkname = tarfile.SYMTYPE, target
    return info, None


@pytest.mark.parametrize("member", ["dotdot", "absolute", "link_out"])
def test_a_relay_pack_member_outside_its_folder_is_refused(tmp_path, member):
    from orchestrate.relay import SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    bad = {"dotdot": _file("../../outside.txt"), "absolute": _file(str(tmp_path / "abs.txt")),
           "link_out": _link("pkg/evil", "/etc/passwd")}[member]
    _archive(carry / SITE_ARCHIVE, [_file("pkg/__init__.py", b""), bad])
    with pytest.raises(UsageError, match="outside|a link or special file"):
        unpack_carry(carry, work)
    assert not (tmp_path / "outside.txt").exists() and not (tmp_path.parent / "outside.txt").exists()
    assert not (tmp_path / "abs.txt").exists() and not (work / "site" / "pkg" / "evil").exists()


@pytest.mark.parametrize("linkname", ["pkg", "."])
def test_a_link_inside_a_relay_pack_is_refused_before_anything_is_written(tmp_path, linkname):
    """A link member that stays inside the target (lib -> pkg, here -> .) passes the data filter, but a later member
    written through it lands on another member's path (one file written twice, the first silently replaced, sweep
    24). --pack writes no links: every link member is refused, and nothing is unpacked."""
    from orchestrate.relay import SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, [_file("pkg/mod.py", b"good = 1\n"), _link("alias", linkname),
                                    _file("alias/mod.py" if linkname == "pkg" else "alias/pkg/mod.py", b"bad = 1\n")])
    with pytest.raises(UsageError, match="'alias', a link or special file"):
        unpack_carry(carry, work)
    assert not (work / "site" / "pkg" / "mod.py").exists()


@pytest.mark.parametrize("content", [b"", b"not an archive at all", None])
def test_a_damaged_relay_pack_is_one_line(tmp_path, capsys, content):
    """An empty, foreign or truncated site.tar.xz: one line naming --carry and the file, exit 2, no traceback."""
    from orchestrate.gpu_session import main
    from orchestrate.relay import SITE_ARCHIVE

    carry = tmp_path / "carry"
    carry.mkdir()
    if content is None:  # a real archive cut in half
        whole = _archive(tmp_path / "whole.tar.xz", [_file(f"pkg/m{i}.py", bytes(range(256)) * 64) for i in range(8)])
        content = whole.read_bytes()[: whole.stat().st_size // 2]
    (carry / SITE_ARCHIVE).write_bytes(content)
    code = main(["--carry", str(carry), "--work", str(tmp_path / "work"), "--out", str(tmp_path / "out"),
                 "--cpu-rehearsal"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("error: --carry:") and SITE_ARCHIVE in err[0], err


@pytest.mark.parametrize("members", ["none", "folders-only"])
def test_a_relay_pack_holding_no_file_is_refused(tmp_path, members):
    """Sweep 26: a site.tar.xz holding no member was unpacked (nothing) and the CPU rehearsal ran on this machine's
    own Mitsuba, exit 0; on the GPU machine, which has none, it would fail late. An archive with no file is
    refused in one line (as its docstring said), and nothing is left behind."""
    from orchestrate.relay import SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry = tmp_path / "carry"
    carry.mkdir()
    folder = tarfile.TarInfo("pkg")
    folder.type = tarfile.DIRTYPE
    _archive(carry / SITE_ARCHIVE, {"none": [], "folders-only": [(folder, None)]}[members])
    with pytest.raises(UsageError, match=f"^--carry: .*{SITE_ARCHIVE}' holds no file"):
        unpack_carry(carry, tmp_path / "work")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["carry"]


def test_help_unpacks_nothing_where_the_packages_are_installed(tmp_path):
    """boot_site (run before gpu_session's imports) leaves the pack alone where tyro is installed: the arguments
    are checked first, and --help touches no file."""
    from orchestrate.relay import SITE_ARCHIVE, boot_site

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, _site())
    boot_site(["--carry", str(carry), "--work", str(work), "--help"])
    assert not work.exists()


@pytest.mark.parametrize("member", ["site/sitecustomize.py", "victim.txt", "data/manifest.json", "assets"])
def test_the_assets_archive_writes_only_under_work_assets(tmp_path, member):
    """A carried assets.tar.xz unpacks into work/assets and nowhere else in --work: not onto the steps' path
    (code that would run), not over the user's files or a step's dataset; work/assets itself a file is refused too
    (sweep 33: it was unpacked, then refused, the site unpacked for it left behind)."""
    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    work.mkdir()
    (work / "victim.txt").write_text("mine\n")
    _archive(carry / SITE_ARCHIVE, _site())
    _archive(carry / ASSET_ARCHIVE, [_file("assets/meshes/a.ply", b"ply"), _file(member, b"import os\n")])
    with pytest.raises(UsageError, match=f"{member}.*outside its assets/ folder"):
        unpack_carry(carry, work)
    assert (work / "victim.txt").read_text() == "mine\n"
    assert sorted(p.name for p in work.iterdir()) == ["victim.txt"]  # the site unpacked for it is gone too


def _wheel(path: Path, names: list[str]) -> Path:
    import zipfile

    with zipfile.ZipFile(path, "w") as z:
        for n in names:
            z.writestr(n, b"x")
    return path


def test_a_pack_refuses_wheel_members_outside_and_never_replaces_the_users_files(tmp_path, capsys):
    from orchestrate.gpu_session import main

    wheels, pack = tmp_path / "wh", tmp_path / "pk"
    wheels.mkdir()
    _wheel(wheels / "drjit-1.5.0-cp312-cp312-manylinux_2_17_x86_64.whl", ["drjit/__init__.py"])
    bad = _wheel(wheels / "mitsuba-3.9.1-cp312-cp312-manylinux_2_17_x86_64.whl", ["mitsuba/__init__.py",
                                                                                  "../../evil.py"])
    assert main(["--pack", str(pack), "--wheels", str(wheels), "--assets", "none"]) == 2
    err = capsys.readouterr().err
    assert "--wheels" in err and "../../evil.py" in err and not (pack / "site.tar.xz").exists()
    bad.unlink()
    _wheel(wheels / "mitsuba-3.9.1-cp312-cp312-manylinux_2_17_x86_64.whl", ["mitsuba/__init__.py"])
    pack.mkdir(exist_ok=True)
    (pack / "site.tar.xz").write_bytes(b"the user's own")
    assert main(["--pack", str(pack), "--wheels", str(wheels), "--assets", "none"]) == 2
    assert "--overwrite" in capsys.readouterr().err and (pack / "site.tar.xz").read_bytes() == b"the user's own"
    (pack / "manifest.json").write_text('{"mine": 1}\n')
    assert main(["--pack", str(pack), "--wheels", str(wheels), "--assets", "none", "--overwrite"]) == 2
    assert "was not written by" in capsys.readouterr().err and (pack / "site.tar.xz").read_bytes() == b"the user's own"
    assert main(["--pack", str(pack), "--wheels", str(wheels), "--init", "shipped"]) == 2
    assert "--init: a session's flag, not used with --pack" in capsys.readouterr().err


@pytest.mark.parametrize("kind", ["symlink", "hardlink"])
def test_a_link_in_the_assets_archive_is_refused_before_a_write_through_it(tmp_path, kind):
    """A link member under assets/ (to the session's site folder, or to a file of --work), then a file written
    under the link's name: the write would land outside work/assets. Links are refused in the assets archive."""
    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    work.mkdir()
    (work / "victim.txt").write_text("mine\n")
    link = tarfile.TarInfo("assets/v")
    link.type, link.linkname = ((tarfile.SYMTYPE, "../victim.txt") if kind == "symlink" else
                                (tarfile.LNKTYPE, "victim.txt"))
    _archive(carry / SITE_ARCHIVE, _site())
    _archive(carry / ASSET_ARCHIVE, [(link, None), _file("assets/v", b"overwritten\n")])
    with pytest.raises(UsageError, match="assets/v.*a link or special file"):
        unpack_carry(carry, work)
    assert (work / "victim.txt").read_text() == "mine\n"


@pytest.mark.parametrize("where", ["site", "assets"])
def test_a_work_folder_that_is_a_link_into_a_users_folder_is_never_unpacked_into(tmp_path, where):
    """--work/site (or --work/assets) a link to a user's folder: the archive's members would replace the user's
    files of the same name through it (sweep 8). Refused naming the link; the user's file stays."""
    import os

    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work, mine = tmp_path / "carry", tmp_path / "work", tmp_path / "mine"
    for folder in (carry, work, mine):
        folder.mkdir()
    (mine / "keep.txt").write_text("mine\n")
    os.symlink(mine, work / where)
    _archive(carry / SITE_ARCHIVE, [*_site(), _file("keep.txt", b"replaced\n")])
    _archive(carry / ASSET_ARCHIVE, [_file("assets/keep.txt", b"replaced\n")])
    with pytest.raises(UsageError, match=f"{where}'.* is a link"):
        unpack_carry(carry, work)
    assert (mine / "keep.txt").read_text() == "mine\n"


def test_a_carried_archive_or_wheel_that_is_a_device_is_named_not_read(tmp_path, capsys):
    import os

    from orchestrate.gpu_session import main
    from orchestrate.relay import SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry = tmp_path / "carry"
    carry.mkdir()
    os.symlink("/dev/zero", carry / SITE_ARCHIVE)
    with pytest.raises(UsageError, match="not a regular file"):
        unpack_carry(carry, tmp_path / "work")
    wheels = tmp_path / "wh"
    wheels.mkdir()
    _wheel(wheels / "drjit-1.5.0-cp312-cp312-manylinux_2_17_x86_64.whl", ["drjit/__init__.py"])
    os.symlink("/dev/zero", wheels / "mitsuba-3.9.1-cp312-cp312-manylinux_2_17_x86_64.whl")
    assert main(["--pack", str(tmp_path / "pk"), "--wheels", str(wheels), "--assets", "none"]) == 2
    assert "not a regular file" in capsys.readouterr().err


@pytest.mark.parametrize("names, said", [
    (["mitsuba-3.9.1-cp312-cp312-win_amd64.whl"], "does not install on the GPU machine"),
    (["mitsuba-3.9.1-cp311-cp311-manylinux_2_17_x86_64.whl"], "does not install on the GPU machine"),
    (["mitsuba-3.9.1-cp312-cp312-manylinux_2_17_aarch64.whl"], "does not install on the GPU machine"),
    (["mitsuba-3.9.1-cp312-cp312-manylinux_2_17_x86_64.whl", "mitsuba-3.9.0-cp312-cp312-manylinux_2_17_x86_64.whl"],
     "two wheels of mitsuba"),
    (["mitsuba-3.9.0-cp312-cp312-manylinux_2_17_x86_64.whl"], "this toolkit runs mitsuba 3.9.1"),
    ([], "has no drjit wheel"),
    (["tyro-1.0.17-py3-none-any.whl", "not-a-wheel.whl"], "is not a wheel's file name"),
])
def test_a_pack_takes_only_wheels_that_install_on_the_gpu_machine(tmp_path, capsys, names, said):
    """The wheels' names (PEP 427) say where they install: a Windows, Python 3.11 or ARM wheel, two versions of one
    package, a mitsuba or drjit the toolkit does not run, or no drjit at all are refused before anything is packed."""
    from orchestrate.gpu_session import main

    wheels = tmp_path / "wh"
    wheels.mkdir()
    always = [] if said == "has no drjit wheel" else ["drjit-1.5.0-cp312-cp312-manylinux_2_17_x86_64.whl"]
    if not any(n.startswith("mitsuba-") for n in names):
        names = [*names, "mitsuba-3.9.1-cp312-cp312-manylinux_2_17_x86_64.whl"]
    for name in [*always, *names]:
        _wheel(wheels / name, [name.split("-")[0] + "/__init__.py"])
    assert main(["--pack", str(tmp_path / "pk"), "--wheels", str(wheels), "--assets", "none"]) == 2
    err = capsys.readouterr().err
    assert said in err and err.startswith("error: --wheels") and not (tmp_path / "pk" / "site.tar.xz").exists(), err


def test_wheels_that_install_on_the_gpu_machine_pass_the_name_check(tmp_path):
    """Real wheel names pip downloads for CPython 3.12 on Linux x86-64 (manylinux2014 pairs, the stable ABI of an
    older CPython, pure Python for Python 2 and 3) pass; the tags come from `packaging.tags`, as pip's own."""
    from orchestrate.relay import check_wheel_names

    names = ["mitsuba-3.9.1-cp312-cp312-manylinux_2_17_x86_64.manylinux2014_x86_64.whl",
             "drjit-1.5.0-cp312-cp312-manylinux_2_17_x86_64.manylinux2014_x86_64.whl",
             "OpenEXR-3.3.2-cp312-cp312-manylinux_2_17_x86_64.manylinux2014_x86_64.whl",
             "cryptography-44.0.0-cp39-abi3-manylinux_2_28_x86_64.whl",
             "braceexpand-0.1.7-py2.py3-none-any.whl", "typeguard-4.4.1-py3-none-any.whl"]
    check_wheel_names(tmp_path, [tmp_path / n for n in names])
    names[0] = "mitsuba-3.9.1.0-cp312-cp312-manylinux_2_17_x86_64.whl"  # PEP 440: the same version
    check_wheel_names(tmp_path, [tmp_path / n for n in names])


def test_an_assets_member_whose_name_is_not_text_is_refused_naming_it(tmp_path):
    """A member named with a Latin-1 byte (tar keeps it as a lone surrogate) is refused before anything is unpacked,
    naming the archive and the rule (sweep 21: the message named neither)."""
    import os

    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, _site())
    _archive(carry / ASSET_ARCHIVE, [_file("assets/meshes/a.ply", b"ply"),
                                     _file(os.fsdecode(b"assets/meshes/caf\xe9.ply"), b"ply")])
    with pytest.raises(UsageError, match=r"assets.tar.xz.*not UTF-8 text \(byte 0xE9\).*rename it"):
        unpack_carry(carry, work)
    assert not (work / "assets" / "meshes" / "a.ply").exists()


@pytest.mark.parametrize("second", ["file", "folder"])
def test_an_assets_member_named_twice_is_refused_before_anything_is_unpacked(tmp_path, second):
    """Sweep 23: assets.tar.xz naming assets/meshes/m0.ply twice (a file, then a file or a folder of that name): the
    later member would replace the earlier, and the session rendered with what was left (a mesh reader's
    IndexError); refused naming the archive and the member, nothing unpacked. An assets archive without an asset
    folder is refused too (it rendered procedural shapes without a word)."""
    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, _site())
    again = _file("assets/meshes/m0.ply", b"ply2") if second == "file" else (tarfile.TarInfo("assets/meshes/m0.ply"),
                                                                             None)
    if second == "folder":
        again[0].type = tarfile.DIRTYPE
    _archive(carry / ASSET_ARCHIVE, [_file("assets/meshes/m0.ply", b"ply"), again])
    with pytest.raises(UsageError, match=r"assets.tar.xz.*'assets/meshes/m0.ply' twice"):
        unpack_carry(carry, work)
    assert not (work / "assets").exists()
    _archive(carry / ASSET_ARCHIVE, [_file("assets", b"not a folder")])
    with pytest.raises(UsageError, match=r"assets.tar.xz.*'assets' outside its assets/ folder"):
        unpack_carry(carry, tmp_path / "work2")
    assert not (tmp_path / "work2").exists()
    # sweep 39: an asset folder of nothing to draw was named as --work's assets folder, not as --carry's archive
    _archive(carry / ASSET_ARCHIVE, [_file("assets/README.md", b"# nothing")])
    with pytest.raises(UsageError, match=r"--carry: '.*carry/assets.tar.xz' holds no asset folder"):
        unpack_carry(carry, tmp_path / "work3")
    assert not (tmp_path / "work3").exists()


@pytest.mark.parametrize("suffix", [".", "aux..", ""])
def test_a_shard_member_naming_no_file_inside_its_sample_folder_is_refused(tmp_path, suffix):
    """Sweep 24's drafts: a member '00000..' has the suffix '.', the sample's folder itself: unips.train ended in
    'Is a directory' naming its scratch folder, after creating the sample folder. Refused before anything is
    written, naming the member."""
    from scenes.folder.shard_format import extract_sample

    with pytest.raises(ValueError, match="names no file inside its folder"):
        extract_sample({"L000.png": b"x", suffix: b"y"}, tmp_path / "00000.data")
    assert not (tmp_path / "00000.data").exists()


@pytest.mark.parametrize("where", ["site", "assets"])
def test_a_users_files_in_the_work_folder_are_never_replaced_by_a_pack(tmp_path, where):
    """Sweep 24: --work/assets (or --work/site) already holding a user's files of the pack's names: the pack was
    unpacked over them, member by member. Refused naming the folder and --overwrite, the user's file unchanged;
    the same pack unpacked again (a resumed session) passes without a write; --overwrite replaces the folder."""
    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, [*_site(), _file("pkg/__init__.py", b"packed = 1\n")])
    _archive(carry / ASSET_ARCHIVE, [_file("assets/meshes/m0.ply", b"packed ply")])
    mine = work / where / ("pkg/__init__.py" if where == "site" else "meshes/m0.ply")
    mine.parent.mkdir(parents=True)
    mine.write_bytes(b"the user's own\n")
    with pytest.raises(UsageError, match=rf"--work: '{work / where}' already holds files.*--overwrite"):
        unpack_carry(carry, work)
    assert mine.read_bytes() == b"the user's own\n"
    assert unpack_carry(carry, work, replace=True) == work / "assets"
    assert mine.read_bytes() in (b"packed = 1\n", b"packed ply")
    stamp = mine.stat().st_mtime_ns
    assert unpack_carry(carry, work) == work / "assets" and mine.stat().st_mtime_ns == stamp  # resumed: untouched


def test_a_refused_pack_leaves_no_folder_behind(tmp_path):
    """Sweep 25: a site.tar.xz refused for a member leading outside (pkg/../../evil.py) left empty --work and
    --work/site folders behind, and a refused assets.tar.xz the site unpacked before it: a refused run leaves
    nothing."""
    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry = tmp_path / "carry"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, [_file("pkg/__init__.py", b""), _file("pkg/../../evil.py", b"x = 1\n")])
    with pytest.raises(UsageError, match="outside"):
        unpack_carry(carry, tmp_path / "work")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["carry"]
    (tmp_path / "work").mkdir()  # a good site, then an assets archive refused: the site unpacked for it goes too
    _archive(carry / SITE_ARCHIVE, _site())
    _archive(carry / ASSET_ARCHIVE, [_file("assets/a.ply", b"ply"), _file("assets/../evil.py", b"x = 1\n")])
    with pytest.raises(UsageError, match="outside"):
        unpack_carry(carry, tmp_path / "work")
    assert list((tmp_path / "work").iterdir()) == []


def test_an_index_holding_a_number_that_is_not_finite_is_refused_naming_the_flag(synthetic_object, tmp_path):
    """Sweep 25: index.json's shard_size edited to 1e400 (inf): the shards were read and trained on, exit 0. The
    one JSON rule refuses it, and the index's reader names --data, the file and the key."""
    from scenes.folder.shard_format import read_index

    shards = _export(synthetic_object, tmp_path / "shards")
    index = shards / "index.json"
    index.write_text(re.sub(r'"shard_size": \d+', '"shard_size": 1e400', index.read_text()))
    with pytest.raises(ValueError, match=rf"^--data: '{index}': holds shard_size = inf, not a finite number"):
        read_index(shards, "--data")


def test_a_flag_refused_after_the_pack_is_unpacked_leaves_nothing_unpacked(tmp_path, capsys):
    """Sweep 36 (c36-order-02/04/05): the variant and the flags only the steps' own checks refuse (a missing --assets
    folder, --res) are checked once the pack is unpacked (those checks need the carried packages); the refusal left
    --work/site and --work/assets behind. Now it takes back what was unpacked a moment ago."""
    import mitsuba  # noqa: F401  (the real one first: the pack's stand-in never becomes this process's mitsuba)

    from orchestrate.gpu_session import main
    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, _site())
    _archive(carry / ASSET_ARCHIVE, [_file("assets/meshes/m0.ply", b"ply")])
    code = main(["--carry", str(carry), "--work", str(work), "--out", str(tmp_path / "out"), "--cpu-rehearsal",
                 "--assets", str(tmp_path / "no-such-assets"), "--objects", "1", "--res", "16", "--spp", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--assets" in err[0] and "no-such-assets" in err[0], err
    assert not (work / "site").exists() and not (work / "assets").exists(), sorted(work.rglob("*"))


def test_assets_none_is_kept_when_the_pack_carries_assets(tmp_path):
    """Sweep 36 (c36-gs-04): `--assets none` with a --carry whose pack holds assets rendered with the packed assets
    all the same; 'none' said is none (the render's arguments carry no --assets), and without the flag the packed
    ones are used."""
    from orchestrate import gpu_session

    packed = tmp_path / "work" / "assets"
    paths = (tmp_path / "work" / "data", tmp_path / "work" / "shards", tmp_path / "out" / "run")
    common = ["--out", str(tmp_path / "out"), "--work", str(tmp_path / "work"), "--cpu-rehearsal", "--objects", "1",
              "--res", "16", "--spp", "1", "--variant", "scalar_rgb", "--check-variant", "none"]
    for argv, given, expected in (([*common, "--assets", "none"], packed, None), (common, None, None)):
        opts = gpu_session.COMMAND.parse(argv)
        init, opts.model = gpu_session.resolve_init(opts.init, opts.model)  # as the session does first
        assert gpu_session._checked(opts, given, paths, "cpu", init)[0] is expected  # nothing said, none packed


@pytest.mark.parametrize("mtime", [10**20, -(10**19)])
def test_a_member_time_beyond_the_platforms_is_one_line_and_nothing_stays(tmp_path, mtime):
    """Sweep 40: a forged PAX mtime of 1e20 s (or -1e19) ended in OverflowError from tarfile's extraction, a
    traceback, and --work/site stayed behind."""
    from orchestrate.relay import SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    stamped = _file("pkg/__init__.py", b"")
    stamped[0].mtime = mtime
    with tarfile.open(carry / SITE_ARCHIVE, "w:xz", format=tarfile.PAX_FORMAT) as tar:
        for info, data in [*_site(), stamped]:
            tar.addfile(info, io.BytesIO(data))
    with pytest.raises(UsageError, match=r"--carry: '.*site.tar.xz' cannot be unpacked"):
        unpack_carry(carry, work)
    assert not work.exists()


def test_an_archive_that_would_unpack_beyond_the_limit_is_refused_before_a_byte_is_written(tmp_path, monkeypatch):
    """Sweep 40: a decompression bomb (a few hundred KiB of xz declaring a 2 GiB member) was unpacked whole into
    --work/site. The sizes the members declare are summed before anything is written (the limit made small here;
    the sweep case unpacks the real 2 GiB)."""
    from orchestrate import archives
    from orchestrate.relay import SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    monkeypatch.setattr(archives, "UNPACKED_LIMIT", 1000)
    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, [*_site(), _file("pkg/zeros.bin", b"\0" * 1001)])
    with pytest.raises(UsageError, match=r"--carry: '.*site.tar.xz' would unpack to 1001 bytes .* over the 0 MiB"):
        unpack_carry(carry, work)
    assert not work.exists()
    _archive(carry / SITE_ARCHIVE, [*_site(), _file("pkg/zeros.bin", b"\0" * 1000)])
    unpack_carry(carry, work)
    assert (work / "site" / "pkg" / "zeros.bin").stat().st_size == 1000


@pytest.mark.parametrize("name", [".site.unpacked", ".assets.unpacked"])
@pytest.mark.parametrize("kind", ["folder", "link"])
def test_an_unpack_record_that_is_not_a_plain_file_is_refused_before_anything_is_unpacked(tmp_path, name, kind):
    """Sweep 41: --work/.site.unpacked planted as a folder holding a user's file: '[Errno 21] Is a directory', no
    flag named, and --work/site left unpacked. As a link to a user's file it would be written through."""
    from orchestrate.relay import ASSET_ARCHIVE, SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, _site())
    _archive(carry / ASSET_ARCHIVE, [_file("assets/meshes/m0.ply", b"ply")])
    (tmp_path / "mine.txt").write_text("mine\n")
    if kind == "folder":
        (work / name).mkdir(parents=True)
        (work / name / "mine.txt").write_text("mine\n")
    else:
        work.mkdir()
        (work / name).symlink_to(tmp_path / "mine.txt")
    with pytest.raises(UsageError, match=rf"--work: '.*{name}' is not a plain file"):
        unpack_carry(carry, work)
    assert sorted(p.name for p in work.iterdir()) == [name] and (tmp_path / "mine.txt").read_text() == "mine\n"


def test_a_member_name_holding_a_newline_is_refused_before_anything_is_unpacked(tmp_path):
    """Sweep 41: 'pkg/a\\nb.py' in site.tar.xz was unpacked (a name no wheel holds, which splits in any list of
    names); refused naming the archive and the member."""
    from orchestrate.relay import SITE_ARCHIVE, unpack_carry
    from scenes.cli.errors import UsageError

    carry, work = tmp_path / "carry", tmp_path / "work"
    carry.mkdir()
    _archive(carry / SITE_ARCHIVE, [*_site(), _file("pkg/a\nb.py", b"")])
    with pytest.raises(UsageError, match=r"site.tar.xz' holds member 'pkg/a\\nb.py', whose name holds a control"):
        unpack_carry(carry, work)
    assert not work.exists()
