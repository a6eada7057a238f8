"""Sweep 40, part m: the GENERATOR and RELAY side (wildgen.make / sensor / export / preview, orchestrate.gpu_session
--pack / --carry / --cpu-rehearsal, orchestrate.train_recipe, orchestrate.demo, orchestrate.docs), with cases that
cases37_*.py, cases38_*.py, cases39_*.py and tests/ do not hold.

- carried archives an attacker plants: a decompression bomb (a few hundred KB of xz unpacking to 2 GiB), a member
  whose mtime overflows time_t, a second tar stream hidden after the end-of-archive blocks, a Windows-style
  `..\\..\\` name, a zip saved as site.tar.xz, a folder member of mode 000 in a refused pack;
- --pack wheels that are not what their names say (text, a link to /etc/passwd, a dangling link, a member with an
  absolute name or a symlink member, a broken CRC, a version that is not PEP 440) and asset links out;
- --cpu-rehearsal flag combinations that contradict (cuda device or check variant), values out of range;
- wildgen.make: resumes of hand-edited manifests / scene.json (types wrong, file cut short, a manifest that is a link
  out), outputs that overlap shards, --overwrite through a linked object folder, asset headers declaring huge sizes;
- sensor / export / preview on edited or linked folders; recipe / demo fast failures; docs pages edited by hand.

Where a success must also be right, the command checks it and on a wrong result prints four `FAULT:` lines to stderr
and exits 3 (flagged `unclear`), or, for an expected refusal, prints one FAULT line and exits 0 (flagged `exit0`).
Every render is as small as wildgen.make allows (TINY: one 16-px object, 2 images, 1 spp).
"""
from __future__ import annotations

import textwrap

TINY = "--objects 1 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet"
MK = "$PY -m wildgen.make"
MKO = MK + ' --out "$C/out" ' + TINY
MKA = MK + ' --out "$C/out" --assets "$C/assets" ' + TINY
RES = f'{MK} --out "$C/out" --resume --workers 0 --quiet'
"""Resume the dataset in $C/out (a copy of $F/data) with its manifest's configuration."""
PV = "$PY -m wildgen.preview"
SEN = "$PY -m wildgen.sensor --quiet"
EX = "$PY -m wildgen.export --quiet"
GS = "$PY -m orchestrate.gpu_session"
SESS = (GS + ' --out "$C/o" --work "$C/w" --carry "$C/c" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1'
        " --check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
SESS_PLAIN = (GS + ' --out "$C/o" --work "$C/w" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1 '
              "--check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
PACK = GS + ' --pack "$C/p" --wheels "$C/whl" --assets none'
RC = "$PY -m orchestrate.train_recipe"
RCW = RC + ' --work "$C/w" --assets none --train-objects 1 --steps 1 --threads 1'
DEMO = "$PY -m orchestrate.demo"
DEMO_TINY = "--objects 1 --images 4 --res 16 --spp 1"
DS = 'cp -r "$F/data" d\n'
OUTDS = 'cp -r "$F/data" out\n'
OUT = ["$C/out", "$C/out/*", "$C/out/*/*", "$C/out/*/*/*"]
SESS_CHANGE = ["$C/o", "$C/o/*", "$C/o/*/*", "$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*", "$C/w/*/*/*/*"]
PACK_CHANGE = ["$C/p", "$C/p/*"]
SPHERE = '"$F/assets/meshes/sphere/sphere.obj"'
WHEELS = r"""mkdir -p whl
$PY - <<'EOF'
import zipfile
for name in ("mitsuba-3.9.1", "drjit-1.5.0"):
    with zipfile.ZipFile(f"whl/{name}-cp312-cp312-manylinux_2_28_x86_64.whl", "w") as z:
        z.writestr(name.split("-")[0] + "/__init__.py", "")
EOF
"""
"""Setup: whl/, two tiny wheels that pass the pack's name and version checks."""
MITSUBA_WHL = "whl/mitsuba-3.9.1-cp312-cp312-manylinux_2_28_x86_64.whl"
REPO_COPY = r"""mkdir repo
(cd "$REPO" && git ls-files -z --cached --others --exclude-standard | tar --null -T - --ignore-failed-read -cf - 2>/dev/null) | tar -xf - -C repo
"""
"""Setup: repo/, a copy of the working tree (orchestrate.docs writes into the tree it runs from)."""
DOCS = 'cd "$C/repo" && PYTHONPATH="$C/repo" $PY -m orchestrate.docs'


def py(code: str) -> str:
    """A bash heredoc running `code` with the toolkit's python in $C."""
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


def manifest(folder: str, code: str) -> str:
    """Setup: edit FOLDER/manifest.json by hand: `code` runs with the dict `m` loaded, then it is written back."""
    return py("import json\n"
              f"p = '{folder}/manifest.json'\n"
              "m = json.load(open(p))\n"
              + textwrap.dedent(code).strip() + "\n"
              "json.dump(m, open(p, 'w'), indent=1)\n")


def rechecksum(folder: str, obj: str, name: str) -> str:
    """Setup: record the current SHA-256 of FOLDER/OBJ.data/NAME in FOLDER/manifest.json."""
    return manifest(folder, f"""
        import hashlib
        e = next(e for e in m['objects'] if str(e.get('name', '')).startswith('{obj}'))
        e['files']['{name}'] = hashlib.sha256(open('{folder}/{obj}.data/{name}', 'rb').read()).hexdigest()
        """)


def mktar(path: str, body: str, mode: str = "w:xz") -> str:
    """Setup: the tar `path` (relative to $C) written by `body` (Python, with `tar` open and `add(tar, name,
    data=b'', **attrs)`)."""
    return (f'mkdir -p "$(dirname {path})"\n$PY - <<\'EOF\'\nimport io, os, tarfile\n'
            "def add(tar, name, data=b'', **kw):\n"
            "    ti = tarfile.TarInfo(name); ti.mode = 0o644; ti.size = len(data)\n"
            "    for k, v in kw.items(): setattr(ti, k, v)\n"
            "    tar.addfile(ti, io.BytesIO(data))\n"
            f"with tarfile.open({path!r}, {mode!r}, format=tarfile.PAX_FORMAT) as tar:\n"
            + textwrap.indent(body.strip("\n"), "    ") + "\nEOF\n")


GOOD_SITE = mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')")
BAD_ASSETS = mktar("c/assets.tar.xz", "add(tar, 'assets/README.md', b'# nothing to draw')")
"""Setup: c/assets.tar.xz that the session refuses (nothing to draw) after it has unpacked the site: the site's
members are written, then everything unpacked is removed again."""


def left(path: str, what: str) -> str:
    """Command tail: a refusal that left `path` behind exits 0 with a FAULT line (flagged exit0)."""
    return (f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r')


def nosite() -> str:
    return left("$C/w/site", "--work/site left behind by a refused pack")


def fault(what: str) -> str:
    """Bash: four FAULT lines on stderr and exit 3 (a wrong result: flagged `unclear`)."""
    return "{ for i in 1 2 3 4; do echo " + repr("FAULT: " + what) + " >&2; done; exit 3; }"


def if_ok(check: str, what: str) -> str:
    """Command tail: when the command succeeded, `check` (bash) must hold, else FAULT (unclear)."""
    return f"; r=$?; if [ $r = 0 ]; then {check} || {fault(what)}; fi; exit $r"


COMPLETE = ("$PY -c \"import json,sys; m=json.load(open('out/manifest.json')); "
            "sys.exit(0 if m.get('complete') else 'FAULT: out/manifest.json not complete')\"")

CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


# ============================================================================ --carry archives planted by an attacker
case("m40-relay-site-xz-bomb", "archive", SESS + left("$C/w/site/pkg/zeros.bin", "the 2 GiB member was unpacked"),
     names=["site.tar.xz"], timeout=120,
     setup="mkdir -p c\n" + py("""
        import io, lzma, tarfile
        n = 2 << 30
        def hdr(name, size):
            ti = tarfile.TarInfo(name); ti.size = size; ti.mode = 0o644
            return ti.tobuf(tarfile.PAX_FORMAT)
        chunk = lzma.compress(b"\\0" * (64 << 20), preset=0)
        with open("c/site.tar.xz", "wb") as f:
            f.write(lzma.compress(hdr("pkg/__init__.py", 0) + hdr("pkg/zeros.bin", n)))
            for _ in range(n // (64 << 20)):
                f.write(chunk)
            f.write(lzma.compress(b"\\0" * 1024))
        """), may_change=SESS_CHANGE,
     why="A site.tar.xz of a few hundred KB whose one member unpacks to 2 GiB of zeros (concatenated xz streams) is "
         "a decompression bomb: refused naming site.tar.xz from the sizes its headers declare, before 2 GiB are "
         "written into --work.")
case("m40-relay-site-member-mtime-beyond-time-t", "archive", SESS + nosite(), names=["--carry"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'', mtime=10**20)") + BAD_ASSETS,
     may_change=SESS_CHANGE,
     why="A PAX mtime of 1e20 s does not fit time_t: setting it must not end in an OverflowError traceback "
         "(ignored, or the pack refused in one line); the session then refuses the empty assets naming --carry "
         "and leaves no --work/site.")
case("m40-relay-site-member-mtime-negative-huge", "archive", SESS + nosite(), names=["--carry"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'', mtime=-10**19)") + BAD_ASSETS,
     may_change=SESS_CHANGE,
     why="A PAX mtime of -1e19 s: no traceback while unpacking; the refusal of the empty assets names --carry.")
case("m40-relay-site-second-tar-stream-hidden", "archive", SESS + nosite(), names=["--carry"], timeout=90,
     setup="mkdir -p c\n" + py("""
        import io, lzma, tarfile
        def tar_bytes(name, data):
            b = io.BytesIO()
            with tarfile.open(fileobj=b, mode="w", format=tarfile.PAX_FORMAT) as t:
                ti = tarfile.TarInfo(name); ti.size = len(data); t.addfile(ti, io.BytesIO(data))
            return b.getvalue()
        raw = tar_bytes("pkg/__init__.py", b"") + tar_bytes("../../evil_m40_hidden.py", b"import os")
        open("c/site.tar.xz", "wb").write(lzma.compress(raw))
        """) + BAD_ASSETS, may_change=SESS_CHANGE,
     why="A second tar stream after the first's end-of-archive blocks (what `tar -i` would unpack) holding "
         "../../evil_m40_hidden.py: never written anywhere; the refusal names --carry.")
case("m40-relay-site-backslash-dotdot-name", "archive", SESS + nosite(), names=["--carry"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                 "add(tar, 'pkg\\\\..\\\\..\\\\evil_m40_bs.py', b'x')") + BAD_ASSETS,
     may_change=SESS_CHANGE,
     why="A Windows-style name pkg\\..\\..\\evil_m40_bs.py is one POSIX file name: written inside --work/site at "
         "most (or refused), never above it; the session refuses the empty assets naming --carry.")
case("m40-relay-site-folder-mode-000-then-refused", "archive", SESS + nosite(), names=["--carry"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                 "ti = tarfile.TarInfo('locked'); ti.type = tarfile.DIRTYPE; ti.mode = 0o000; tar.addfile(ti)\n"
                 "add(tar, 'locked/x.py', b'', mode=0o000)") + BAD_ASSETS,
     may_change=SESS_CHANGE,
     why="A folder member of mode 000 (and a file of mode 000 in it): once the assets are refused, everything "
         "unpacked is removed again; no unreadable --work/site is left behind.")
case("m40-relay-site-a-zip-named-xz", "archive", SESS + nosite(), names=["site.tar.xz"], timeout=90,
     setup="mkdir c\n" + py("""
        import zipfile
        with zipfile.ZipFile("c/site.tar.xz", "w") as z:
            z.writestr("pkg/__init__.py", "")
        """), may_change=SESS_CHANGE,
     why="A zip saved as site.tar.xz is refused in one line naming the file; nothing unpacked.")
case("m40-relay-site-gzip-named-xz-then-refused", "archive", SESS + nosite(), names=["--carry"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')", mode="w:gz") + BAD_ASSETS,
     may_change=SESS_CHANGE,
     why="A gzip tar saved under the .xz name is read (or refused naming it); either way the empty assets are "
         "refused naming --carry and nothing stays unpacked.")
case("m40-relay-assets-member-mtime-beyond-time-t", "archive", SESS + nosite(), names=["--carry"], timeout=90,
     setup=GOOD_SITE + mktar("c/assets.tar.xz", "add(tar, 'assets/README.md', b'x', mtime=10**20)"),
     may_change=SESS_CHANGE,
     why="An assets member with a PAX mtime of 1e20 s: no OverflowError traceback; the assets (a README) are "
         "refused naming --carry, nothing left unpacked.")

# ============================================================================ --cpu-rehearsal combinations and values
case("m40-gs-rehearsal-with-device-cuda", "order", SESS_PLAIN + " --device cuda" + left("$C/w/data", "rendered"),
     names=["--device"], may_change=SESS_CHANGE, timeout=90,
     why="--cpu-rehearsal asks for the CPU, --device cuda for the GPU: refused naming --device before rendering.")
case("m40-gs-rehearsal-check-variant-cuda", "order",
     SESS_PLAIN.replace("--check-variant none", "--check-variant cuda_ad_rgb") + left("$C/w/data", "rendered"),
     names=["--check-variant"], may_change=SESS_CHANGE, timeout=90,
     why="A CPU rehearsal cannot check with cuda_ad_rgb: refused naming --check-variant before the first render.")
case("m40-gs-device-cpu-without-rehearsal", "order",
     SESS_PLAIN.replace(" --cpu-rehearsal", "") + " --device cpu", expect="either", may_change=SESS_CHANGE,
     timeout=120,
     why="--device cpu without --cpu-rehearsal on a machine with no GPU: refused in one line (or run as a "
         "rehearsal); never a traceback.")
case("m40-gs-minutes-nan", "input", SESS_PLAIN.replace("--minutes 1", "--minutes nan") + left("$C/w/data", "rendered"),
     names=["--minutes"], may_change=SESS_CHANGE, timeout=90,
     why="A NaN budget compares false with every limit: refused naming --minutes.")
case("m40-gs-reserve-s-negative", "input", SESS_PLAIN.replace("--reserve-s 30", "--reserve-s -5")
     + left("$C/w/data", "rendered"), names=["--reserve-s"], may_change=SESS_CHANGE, timeout=90,
     why="A negative reserve keeps nothing for the files that follow: refused naming --reserve-s.")
case("m40-gs-reserve-s-nan", "input", SESS_PLAIN.replace("--reserve-s 30", "--reserve-s nan")
     + left("$C/w/data", "rendered"), names=["--reserve-s"], may_change=SESS_CHANGE, timeout=90,
     why="A NaN reserve is refused naming --reserve-s (every budget check would pass).")
case("m40-gs-steps-0", "input", SESS_PLAIN.replace("--steps 1", "--steps 0") + left("$C/w/data", "rendered"),
     names=["--steps"], may_change=SESS_CHANGE, timeout=90,
     why="A schedule of 0 steps trains nothing: refused naming --steps before rendering.")
case("m40-gs-batch-0", "input", SESS_PLAIN.replace("--batch 1", "--batch 0") + left("$C/w/data", "rendered"),
     names=["--batch"], may_change=SESS_CHANGE, timeout=90,
     why="Batches of 0 objects are refused naming --batch before rendering.")
case("m40-gs-log-every-0", "input", SESS_PLAIN + " --log-every 0" + left("$C/w/data", "rendered"),
     names=["--log-every"], may_change=SESS_CHANGE, timeout=90,
     why="A learning-curve record every 0 steps is refused naming --log-every before rendering.")
case("m40-gs-out-not-given", "input", SESS_PLAIN.replace(' --out "$C/o"', "") + left("$C/w/data", "rendered"),
     names=["--out"], may_change=SESS_CHANGE, timeout=90,
     why="A session without --out has nothing to bring back: refused naming --out before rendering.")
case("m40-gs-work-inside-out", "writer",
     SESS_PLAIN.replace('--work "$C/w"', '--work "$C/o/w"') + left("$C/o/w/data", "rendered into --out"),
     names=["--work"], may_change=SESS_CHANGE, timeout=90,
     why="--work inside --out would bring the whole dataset and shards back (far above 8 files): refused naming "
         "--work.")
case("m40-gs-init-a-test-model-run", "weights", SESS_PLAIN + ' --init "$F/run/final.safetensors"'
     + left("$C/w/data", "rendered before the weights were refused"), names=["--init"], may_change=SESS_CHANGE,
     timeout=90,
     why="--init of a glc-test run (not the shipped architecture) is refused naming --init before rendering.")
case("m40-gs-init-fifo", "weights", SESS_PLAIN + ' --init "$C/final.safetensors"' + left("$C/w/data", "rendered"),
     names=["--init"], setup="mkfifo final.safetensors", may_change=SESS_CHANGE, timeout=60,
     why="--init a FIFO: named as not a file, no hang waiting for a writer.")

# ============================================================================ --pack with odd wheels and assets
case("m40-pack-wheel-is-text", "input", PACK + left("$C/p/site.tar.xz", "packed"), names=["numpy-2.0.0"],
     setup=WHEELS + "echo 'pip download failed' > whl/numpy-2.0.0-cp312-cp312-manylinux_2_28_x86_64.whl",
     may_change=PACK_CHANGE, timeout=60,
     why="A text file under a wheel's name (a failed download) is refused naming it, not packed.")
case("m40-pack-wheel-link-to-passwd", "archive", PACK + left("$C/p/site.tar.xz", "packed"), names=["numpy-2.0.0"],
     setup=WHEELS + "ln -s /etc/passwd whl/numpy-2.0.0-cp312-cp312-manylinux_2_28_x86_64.whl",
     may_change=PACK_CHANGE, timeout=60,
     why="A wheel that is a link to /etc/passwd is refused naming it; nothing of it travels.")
case("m40-pack-wheel-dangling-link", "input", PACK + left("$C/p/site.tar.xz", "packed"), names=["numpy-2.0.0"],
     setup=WHEELS + "ln -s nowhere.whl whl/numpy-2.0.0-cp312-cp312-manylinux_2_28_x86_64.whl",
     may_change=PACK_CHANGE, timeout=60,
     why="A dangling link among the wheels is refused naming it (no traceback from opening it).")
case("m40-pack-wheel-member-absolute", "archive", PACK + left("$C/p/site.tar.xz", "packed"), names=["mitsuba"],
     setup=WHEELS + py(f"""
        import zipfile
        with zipfile.ZipFile("{MITSUBA_WHL}", "w") as z:
            z.writestr("mitsuba/__init__.py", "")
            z.writestr("/tmp/evil_m40_abs.py", "x")
        """), may_change=PACK_CHANGE, timeout=60,
     why="A wheel member with an absolute name is refused naming the wheel; no /tmp/evil_m40_abs.py appears.")
case("m40-pack-wheel-member-symlink", "archive",
     PACK + if_ok("! tar -tvJf p/site.tar.xz | grep -q '^l'", "a symlink member packed into site.tar.xz"),
     expect="either",
     setup=WHEELS + py(f"""
        import zipfile
        with zipfile.ZipFile("{MITSUBA_WHL}", "w") as z:
            z.writestr("mitsuba/__init__.py", "")
            zi = zipfile.ZipInfo("mitsuba/escape_m40"); zi.create_system = 3; zi.external_attr = 0o120777 << 16
            z.writestr(zi, "/etc")
        """), may_change=PACK_CHANGE, timeout=60,
     why="A wheel member that is a symlink (to /etc): refused naming the wheel, or packed as the plain file pip "
         "would install; never carried as a link (the session refuses links in the pack).")
case("m40-pack-wheel-crc-broken", "input", PACK + left("$C/p/site.tar.xz", "packed"), names=["mitsuba"],
     setup=WHEELS + py(f"""
        import zipfile
        with zipfile.ZipFile("{MITSUBA_WHL}", "w") as z:
            z.writestr("mitsuba/__init__.py", "x = 1111111\\n")
        b = open("{MITSUBA_WHL}", "rb").read().replace(b"x = 1111111", b"x = 2222222", 1)
        open("{MITSUBA_WHL}", "wb").write(b)
        """), may_change=PACK_CHANGE, timeout=60,
     why="A wheel whose member fails its CRC (a damaged download) is refused naming the wheel, not packed.")
case("m40-pack-wheel-version-not-pep440", "input", PACK + left("$C/p/site.tar.xz", "packed"), names=["--wheels"],
     setup=WHEELS + "cd whl; mv drjit-1.5.0-cp312-cp312-manylinux_2_28_x86_64.whl "
                    "drjit-latest-cp312-cp312-manylinux_2_28_x86_64.whl",
     may_change=PACK_CHANGE, timeout=60,
     why="A wheel named drjit-latest-... has no version: refused naming --wheels (and the file).")
case("m40-pack-wheels-a-file", "input", GS + ' --pack "$C/p" --wheels "$C/whl" --assets none', names=["--wheels"],
     setup="echo x > whl", timeout=60, why="--wheels a plain file is refused naming --wheels.")
case("m40-pack-dest-a-file", "input", GS + ' --pack "$C/p" --wheels "$C/whl" --assets none', names=["--pack"],
     setup=WHEELS + "echo mine > p", timeout=60,
     why="--pack a user's plain file is refused naming --pack; the file is kept.")
case("m40-pack-dest-holds-users-notes", "writer", PACK, expect="either",
     setup=WHEELS + "mkdir p; echo 'my notes' > p/notes.txt",
     may_change=["$C/p/site.tar.xz", "$C/p/assets.tar.xz", "$C/p/manifest.json", "$C/p/.*"], timeout=60,
     why="Packing into a folder holding a user's notes.txt: packed beside it or refused; notes.txt is never "
         "removed or changed.")
case("m40-pack-assets-mesh-link-to-passwd", "archive",
     GS + ' --pack "$C/p" --wheels "$C/whl" --assets "$C/a"' + left("$C/p/assets.tar.xz", "packed"),
     names=["aaa_stolen.obj"], setup=WHEELS + "mkdir -p a/meshes a/hdri; cp " + SPHERE + " a/meshes/\n"
     "cp \"$F/assets/hdri/apartment.hdr\" a/hdri/\nln -s /etc/passwd a/meshes/aaa_stolen.obj",
     may_change=PACK_CHANGE, timeout=60,
     why="An asset mesh that is a link to /etc/passwd is refused naming it; its content never travels in "
         "assets.tar.xz.")

# ============================================================================ wildgen.make
case("m40-make-resume-scene-json-cut-short", "writer",
     RES + if_ok("$PY -c \"import json; json.load(open('out/00001.data/scene.json'))\"",
                 "exit 0 with out/00001.data/scene.json still cut short"),
     expect="either", names=[], setup=OUTDS + "truncate -s 200 out/00001.data/scene.json", may_change=OUT,
     timeout=90,
     why="scene.json of a done object cut short (checksum in the manifest disagrees): the resume re-renders the "
         "object or refuses naming scene.json; never exit 0 with the dataset still broken.")
case("m40-make-resume-manifest-images-a-string", "input", RES, names=["manifest.json"],
     setup=OUTDS + manifest("out", "m['config']['images'] = '4'"), may_change=["$C/out/manifest.json"], timeout=60,
     why="config.images written as the string '4' is refused naming manifest.json (and images), nothing rendered.")
case("m40-make-resume-manifest-seed-fractional", "input", RES, names=["manifest.json"],
     setup=OUTDS + manifest("out", "m['config']['seed'] = 1.5"), may_change=["$C/out/manifest.json"], timeout=60,
     why="config.seed 1.5 is not a seed: refused naming manifest.json (and seed); not truncated to 1.")
case("m40-make-resume-manifest-duplicate-keys", "input", RES, expect="either",
     setup=OUTDS + py("""
        t = open("out/manifest.json").read()
        t = t.replace('"complete": true,', '"complete": false, "complete": true,', 1)
        open("out/manifest.json", "w").write(t)
        """), may_change=["$C/out/manifest.json"], timeout=60,
     why="A manifest naming `complete` twice (false, then true): resumed as complete or refused naming "
         "manifest.json; no object deleted, no traceback.")
case("m40-make-resume-other-images", "writer", RES + " --images 2", names=["--images"], setup=OUTDS, timeout=60,
     why="--images 2 resuming a 4-image dataset would mix two configurations: refused naming --images and "
         "--overwrite, nothing changed.")
case("m40-make-resume-other-seed", "writer", RES + " --seed 2", names=["--seed"], setup=OUTDS, timeout=60,
     why="--seed 2 resuming a dataset of seed 1: refused naming --seed, nothing changed.")
case("m40-make-resume-fewer-objects", "writer", RES + " --objects 1", expect="either", setup=OUTDS,
     may_change=["$C/out/manifest.json"], timeout=60,
     why="--objects 1 resuming 3 done objects: refused naming --objects, or nothing to do; objects 00001 and "
         "00002 are never deleted.")
case("m40-make-resume-manifest-a-link-out", "writer", RES + " --objects 4", expect="either",
     setup=OUTDS + "mv out/manifest.json victim.json; cp victim.json victim.orig; "
                   "ln -s ../victim.json out/manifest.json",
     may_change=OUT, timeout=110,
     why="out/manifest.json a link to a file outside --out: refused naming it, or the manifest written in "
         "--out; victim.json is never written through the link.")
case("m40-make-out-is-a-shards-folder", "writer", MKO, expect="either", setup='cp -r "$F/shards" out',
     may_change=["$C/out/manifest.json", "$C/out/0*.data", "$C/out/0*.data/*", "$C/out/0*.data/*/*", "$C/out/.*"],
     timeout=60,
     why="--out a WebDataset shards folder (000000.tar, index.json): refused naming --out (a folder readers "
         "would take for shards), or rendered beside them; 000000.tar and index.json untouched.")
case("m40-make-shards-inside-out", "writer", MKO + ' --shards "$C/out/sh"' + left("$C/out/manifest.json",
     "rendered before refusing --shards"), names=["--shards"], timeout=60,
     why="Shards inside the dataset they are made from would be read back as an object folder's sibling: "
         "refused naming --shards before the render.")
case("m40-make-shards-folder-of-users-tars", "writer", MKO + ' --shards "$C/sh"' + left("$C/out/manifest.json",
     "rendered before refusing --shards"), names=["--shards"],
     setup="mkdir sh; cp \"$F/shards/000000.tar\" sh/; echo 'my notes' > sh/notes.txt", timeout=60,
     why="--shards a folder holding a 000000.tar without an index (not an export of this dataset): refused "
         "naming --shards before rendering, the user's tar kept.")
case("m40-make-assets-ply-binary-count-4e9", "input", MKA + " --shapes mesh", names=["huge.ply"], timeout=90,
     setup="mkdir -p assets/meshes; printf 'ply\\nformat binary_little_endian 1.0\\nelement vertex 4000000000\\n"
           "property float x\\nproperty float y\\nproperty float z\\nelement face 1\\n"
           "property list uchar int vertex_indices\\nend_header\\n' > assets/meshes/huge.ply; "
           "head -c 64 /dev/zero >> assets/meshes/huge.ply",
     why="A binary PLY declaring 4e9 vertices in 64 bytes is refused naming huge.ply, not a 48 GB allocation.")
case("m40-make-assets-hdr-declares-200000-px", "input", MKA + " --lights hdri", names=["vast.hdr"], timeout=90,
     setup="mkdir -p assets/hdri; printf '#?RADIANCE\\nFORMAT=32-bit_rle_rgbe\\n\\n-Y 200000 +X 200000\\n' "
           "> assets/hdri/vast.hdr; head -c 4096 /dev/zero >> assets/hdri/vast.hdr",
     why="A Radiance header declaring 200000x200000 px over 4 KB of data is refused naming vast.hdr before a "
         "480 GB allocation.")
case("m40-make-assets-texture-png-bomb-header", "input", MKA + " --materials diffuse", names=["wood_col.png"],
     timeout=90, setup="mkdir -p assets/textures/wood\n" + py("""
        import struct, zlib
        def chunk(t, d):
            return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
        png = (b"\\x89PNG\\r\\n\\x1a\\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 100000, 100000, 8, 2, 0, 0, 0))
               + chunk(b"IDAT", zlib.compress(b"\\0" * 1000)) + chunk(b"IEND", b""))
        open("assets/textures/wood/wood_col.png", "wb").write(png)
        """),
     why="A base-colour PNG whose header declares 100000x100000 px (a decompression bomb) is refused naming "
         "wood_col.png, not read into 30 GB.")
case("m40-make-ray-address-list", "input", MK + ' --out "$C/out" --objects 1 --images 2 --res 16 --spp 1 '
     '--gt-spp 1 --quiet --ray "127.0.0.1:6379,127.0.0.2:6379"', names=["--ray"], timeout=60,
     why="Two addresses in one --ray is no address: refused naming --ray, no minute-long connection attempts.")
case("m40-make-overwrite-through-linked-object-folder", "writer", MKO + " --overwrite", expect="either",
     setup=OUTDS + "mkdir mine; echo precious > mine/photo.jpg; cp -r out/00001.data/. mine/; "
                   "rm -rf out/00001.data; ln -s ../mine out/00001.data",
     may_change=OUT, timeout=90,
     why="--overwrite with out/00001.data a link to a user's folder: the link may go, but the user's folder and "
         "photo.jpg behind it are never deleted.")
case("m40-make-out-unicode-and-spaces", "exit0",
     MK + ' --out "$C/dätä set/ø ut" ' + TINY + " && test -f \"$C/dätä set/ø ut/00000.data/mask.png\"",
     expect="ok", may_change=["$C/dätä set", "$C/dätä set/*", "$C/dätä set/*/*", "$C/dätä set/*/*/*"], timeout=90,
     why="A full path with spaces and non-ASCII letters is a valid --out: the object is rendered there.")
case("m40-make-assets-equals-out", "writer", MK + ' --out "$C/assets" --assets "$C/assets" ' + TINY,
     names=["--out"], setup="mkdir -p assets/meshes; cp " + SPHERE + " assets/meshes/", timeout=60,
     why="--out equal to --assets would render object folders into the asset library: refused naming --out.")

# ============================================================================ wildgen.sensor
case("m40-sensor-out-a-link-to-data", "writer", SEN + ' --data "$C/d" --sensor phone --out "$C/o"',
     names=["--out"], setup=DS + "ln -s d o", timeout=60,
     why="--out a link to --data would replace the dataset's own images: refused naming --out, d/ unchanged.")
case("m40-sensor-radiance-missing", "input", SEN + ' --data "$C/d" --sensor phone --out "$C/o"',
     names=["radiance_002.exr"], setup=DS + "rm d/00001.data/aux/radiance_002.exr",
     may_change=["$C/o", "$C/o/*", "$C/o/*/*", "$C/o/*/*/*"], timeout=60,
     why="An object missing one radiance EXR is refused naming it (or recorded failed, exit non-zero); never "
         "exit 0 with an image short.")
case("m40-sensor-scene-json-fewer-images", "input", SEN + ' --data "$C/d" --sensor phone --out "$C/o"'
     + if_ok("[ $(ls o/00000.data/L*.png | wc -l) = $($PY -c \"import json; print(len(json.load("
             "open('o/00000.data/scene.json'))['images']))\") ]", "o/00000.data: images and scene.json disagree"),
     expect="either", setup=DS + py("""
        import json
        p = "d/00000.data/scene.json"; s = json.load(open(p)); s["images"] = s["images"][:2]
        json.dump(s, open(p, "w"), indent=1)
        """) + rechecksum("d", "00000", "scene.json"),
     may_change=["$C/o", "$C/o/*", "$C/o/*/*", "$C/o/*/*/*"], timeout=60,
     why="scene.json listing 2 images beside 4 radiance files (checksum updated): refused naming scene.json, "
         "or an object of 2 images whose files agree with its scene.json; never an index error.")

# ============================================================================ wildgen.export
case("m40-export-out-a-link-into-data", "writer", EX + ' --data "$C/d" --out "$C/o"', names=["--out"],
     setup=DS + "ln -s d/00000.data o", timeout=60,
     why="--out a link into an object folder of --data is refused naming --out; the object folder unchanged.")
case("m40-export-decoded-image-cut-short", "input", EX + ' --data "$C/d" --out "$C/o" --encoding decoded',
     names=["L001.png"], setup=DS + "truncate -s 100 d/00002.data/L001.png\n" + rechecksum("d", "00002", "L001.png"),
     may_change=["$C/o", "$C/o/*"], timeout=60,
     why="A PNG cut short (its checksum updated too) cannot be decoded: refused naming L001.png, no index.json "
         "claiming a complete export.")
case("m40-export-overwrite-index-names-a-file-above", "writer", EX + ' --data "$C/d" --out "$C/o" --overwrite',
     expect="either", setup=DS + "cp -r \"$F/shards\" o; echo 'mine' > notes.txt\n" + py("""
        import json
        p = "o/index.json"; m = json.load(open(p)); m["source"] = __import__("os").path.abspath("d")
        m["shards"].append(dict(m["shards"][0], name="../notes.txt"))
        json.dump(m, open(p, "w"), indent=1)
        """), may_change=["$C/o", "$C/o/*"], timeout=60,
     why="An earlier index.json edited to list ../notes.txt as a shard: --overwrite replaces only shards inside "
         "--out (or refuses naming index.json); notes.txt is never deleted.")

# ============================================================================ wildgen.preview
case("m40-preview-object-folder-link-loop", "input", PV + ' "$C/d" --out "$C/pv"', expect="either",
     setup=DS + "ln -s . d/00003.data", may_change=["$C/pv", "$C/pv/*"], timeout=60,
     why="An object folder that is a link to the dataset itself: named and skipped, or refused; no hang, no "
         "recursion.")
case("m40-preview-stats-scene-json-duplicate-key", "input", PV + ' "$C/d" --out "$C/pv" --stats', expect="either",
     setup=DS + py("""
        t = open("d/00001.data/scene.json").read()
        t = t.replace('"format_version": 1,', '"format_version": 1, "format_version": "x",', 1)
        open("d/00001.data/scene.json", "w").write(t)
        """), may_change=["$C/pv", "$C/pv/*"], timeout=60,
     why="scene.json naming format_version twice (1, then 'x'): the object is listed as failed or the card "
         "drawn; no traceback.")

# ============================================================================ orchestrate.train_recipe
case("m40-recipe-model-unknown", "input", RCW + " --model glc-nope", names=["--model"], timeout=60,
     why="An unknown model name is refused naming --model before any dataset is rendered.")
case("m40-recipe-threads-0", "input", RCW.replace("--threads 1", "--threads 0"), names=["--threads"], timeout=60,
     why="0 torch threads is refused naming --threads.")
case("m40-recipe-train-objects-negative", "input", RCW.replace("--train-objects 1", "--train-objects -3"),
     names=["--train-objects"], timeout=60,
     why="A negative training-set size is refused naming --train-objects.")
case("m40-recipe-train-seed-duplicated", "input", RCW + " --train-seed 7,7", expect="either", timeout=60,
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*", "$C/w/*/*/*/*"],
     why="The same training seed twice would render one dataset twice: refused naming --train-seed, or taken "
         "once; no traceback.")

# ============================================================================ orchestrate.demo
case("m40-demo-out-holds-users-files", "writer", DEMO + ' --out "$C/o" ' + DEMO_TINY, expect="either",
     setup="mkdir o; echo 'mine' > o/notes.txt; mkdir o/data; echo 'x' > o/data/keep.txt", timeout=120,
     may_change=["$C/o/data/0*", "$C/o/data/0*/*", "$C/o/data/0*/*/*", "$C/o/data/manifest.json", "$C/o/data/.*", "$C/o/data/preview", "$C/o/data/preview/*",
                 "$C/o/pred", "$C/o/pred/*", "$C/o/pred/*/*", "$C/o/pred/*/*/*", "$C/o/rerender", "$C/o/rerender/*",
                 "$C/o/rerender/*/*", "$C/o/rerender/*/*/*", "$C/o/summary.md", "$C/o/.*"],
     why="--out holding a user's files (a data/ folder among them) without --overwrite: refused naming --out, or "
         "the demo written beside them; notes.txt and data/keep.txt never changed.")
case("m40-demo-out-a-link-to-users-folder-overwrite", "writer", DEMO + ' --out "$C/o" --overwrite ' + DEMO_TINY,
     expect="either", setup="mkdir mine; echo 'precious' > mine/photo.jpg; ln -s mine o",
     may_change=["$C/mine/data", "$C/mine/data/*", "$C/mine/data/*/*", "$C/mine/pred", "$C/mine/pred/*",
                 "$C/mine/pred/*/*", "$C/mine/rerender", "$C/mine/rerender/*", "$C/mine/rerender/*/*",
                 "$C/mine/summary.md", "$C/mine/*.json"], timeout=120,
     why="--out a link to a user's folder with --overwrite: refused, or written beside; photo.jpg survives.")
case("m40-demo-checkpoint-a-directory-of-shards", "weights", DEMO + ' --out "$C/o" ' + DEMO_TINY
     + ' --checkpoint "$F/shards/000000.tar"', names=["--checkpoint"], timeout=60,
     why="--checkpoint a WebDataset tar is not weights: refused naming --checkpoint before rendering.")

# ============================================================================ orchestrate.docs (on a copy)
case("m40-docs-page-utf16", "input", DOCS + " --check", names=["model.md"], timeout=110,
     setup=REPO_COPY + "iconv -f utf-8 -t utf-16 repo/docs/model.md > m16 && mv m16 repo/docs/model.md",
     why="A page re-saved as UTF-16 is refused naming model.md (not reported stale and then rewritten as "
         "garbage).")
case("m40-docs-block-duplicated", "input", DOCS, expect="either", timeout=110,
     setup=REPO_COPY + py("""
        import re
        p = "repo/docs/capture.md"; t = open(p).read()
        m = re.search(r"<!-- BEGIN generated:capture:diligent -->.*?<!-- END generated:capture:diligent -->\\n", t,
                      re.S)
        open(p, "w").write(t + "\\n" + m.group(0))
        """), may_change=["$C/repo/*", "$C/repo/*/*", "$C/repo/*/*/*"],
     why="One generated block twice in a page: refused naming capture.md and the block, or both regenerated; "
         "no traceback.")
case("m40-docs-blocks-nested", "input", DOCS, expect="either", timeout=110,
     setup=REPO_COPY + py("""
        p = "repo/docs/capture.md"; t = open(p).read()
        t = t.replace("<!-- END generated:capture:diligent -->",
                      "<!-- BEGIN generated:capture:doubtful-mask -->\\n<!-- END generated:capture:doubtful-mask -->"
                      "\\n<!-- END generated:capture:diligent -->", 1)
        open(p, "w").write(t)
        """), may_change=["$C/repo/*", "$C/repo/*/*", "$C/repo/*/*/*"],
     why="A BEGIN pasted inside another block: the block is regenerated (its content is generated) or the page "
         "refused naming capture.md; the later block of that name is kept, no traceback.")
case("m40-docs-page-read-only-stale", "writer", DOCS, expect="either", timeout=110,
     setup=REPO_COPY + "sed -i 's/^<!-- END generated:capture:diligent -->/stale line\\n&/' repo/docs/capture.md; "
                       "chmod 444 repo/docs/capture.md",
     may_change=["$C/repo/*", "$C/repo/*/*", "$C/repo/*/*/*"],
     why="A stale page that is read-only: rewritten (the folder is writable) or refused naming capture.md in one "
         "line; no traceback.")
