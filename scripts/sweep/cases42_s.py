"""Sweep 42, part s: the GENERATOR and RELAY side (wildgen.make / sensor / export / preview, orchestrate.gpu_session
--pack and --carry, the relay's site.tar.xz / assets.tar.xz, orchestrate.docs, orchestrate.demo, asset packs and
scene.json re-rendering), from angles the earlier sweeps used little:

- the process environment: HOME unset, TMPDIR missing, OMP_NUM_THREADS=abc, a C/ASCII locale, COLUMNS odd,
  DRJIT_LIBLLVM_PATH wrong, CUDA_VISIBLE_DEVICES garbage, RAY_ADDRESS garbage without --ray;
- stdout / stderr closed or piped into `head -1` (SIGPIPE); `ulimit -f` / `ulimit -n` small;
- file names of 256 bytes, NFC/NFD twins, mtimes in the future or at 0, sparse huge files;
- meshes: binary PLY with wrong counts / NaN / indices out of range / big-endian, 10^6 faces, zero extent, CRLF;
- HDR maps: wrong FORMAT, truncated RLE, a PNG renamed, near-float-max pixels, zero size, endless header;
- scene.json hand-edited for validate.rerender (types, NaN, missing keys, a special file as the mesh);
- tar archives with block devices, hard links to themselves, duplicate names (file then link), ustar prefix
  escapes, GNU sparse members, hard links outside in the assets archive;
- a second run after SIGKILL at several points (only the parent killed, mid-unpack, mid-pack, docs);
- outputs overlapping inputs through `..` and trailing slashes.

Cases whose command adds its own check print a line starting with `FAULT:` and exit 0/3 so the harness flags it.
"""
from __future__ import annotations

import textwrap

TINY = "--objects 1 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet"
MK = "$PY -m wildgen.make"
MKO = MK + ' --out "$C/out" ' + TINY
"""wildgen.make of one tiny object into $C/out."""
MKA = MKO + ' --assets "$C/assets"'
"""The same with the asset library in $C/assets."""
MKV = MK + ' --out "$C/out" --objects 1 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0'
"""Tiny make that prints its progress lines (not --quiet)."""
SEN = "$PY -m wildgen.sensor --quiet"
EX = "$PY -m wildgen.export --quiet"
PV = "$PY -m wildgen.preview"
GS = "$PY -m orchestrate.gpu_session"
SESS = (GS + ' --out "$C/o" --work "$C/w" --carry "$C/c" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1'
        " --check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
PROBE = SESS + ' --assets "$C/no-such-assets"'
"""A session whose --assets is checked only once the pack is unpacked: an accepted pack ends in a refusal naming
--assets (and nothing of it stays), a refused pack in one naming the archive."""
PACK = GS + ' --pack "$C/p" --wheels "$C/whl"'
DEMO = "$PY -m orchestrate.demo"
DEMO_TINY = "--objects 1 --images 4 --res 16 --spp 1"
DS = 'cp -r "$F/data" d\n'
OUTDS = 'cp -r "$F/data" out\n'
OBJ8 = 'cp -r "$F/data8/00000.data" d\n'
RRD = ('$PY -m validate.rerender --data d --normals "$F/pred8/00000/normal.png" --out r --spp 1 --no-floors '
       '--threshold 0.5')
R = ["$C/r", "$C/r/*", "$C/r/*/*"]
OUT = ["$C/out", "$C/out/*", "$C/out/*/*", "$C/out/*/*/*"]
SESS_CHANGE = ["$C/o", "$C/o/*", "$C/o/*/*", "$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*", "$C/w/*/*/*/*"]
PACK_CHANGE = ["$C/p", "$C/p/*", "$C/p/*/*"]
SPHERE = '"$F/assets/meshes/sphere/sphere.obj"'
HDR = '"$F/assets/hdri/apartment.hdr"'
WHEELS = r"""mkdir -p whl
$PY - <<'EOF'
import zipfile
for name in ("mitsuba-3.9.1", "drjit-1.5.0"):
    with zipfile.ZipFile(f"whl/{name}-cp312-cp312-manylinux_2_28_x86_64.whl", "w") as z:
        z.writestr(name.split("-")[0] + "/__init__.py", "")
EOF
"""
REPO_COPY = r"""mkdir repo
(cd "$REPO" && git ls-files -z --cached --others --exclude-standard | tar --null -T - --ignore-failed-read -cf - 2>/dev/null) | tar -xf - -C repo
"""
DOCS = 'cd "$C/repo" && PYTHONPATH="$C/repo" $PY -m orchestrate.docs'
REPO_CHANGE = ["$C/repo", "$C/repo/*", "$C/repo/*/*", "$C/repo/*/*/*", "$C/repo/*/*/*/*"]
ASCII = "LC_ALL=C LANG=C PYTHONUTF8=0 PYTHONCOERCECLOCALE=0 "
"""A plain ASCII locale (no PEP 538 coercion, no UTF-8 mode)."""


def py(code: str) -> str:
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


def mktar(path: str, body: str, mode: str = "w:xz", fmt: str = "tarfile.PAX_FORMAT") -> str:
    """Setup: the tar `path` written by `body` (Python, with `tar` open, `add(tar, name, data=b'', **attrs)`)."""
    return (f'mkdir -p "$(dirname {path})"\n$PY - <<\'EOF\'\nimport io, os, tarfile\n'
            "def add(tar, name, data=b'', pax=None, **kw):\n"
            "    ti = tarfile.TarInfo(name); ti.mode = 0o644; ti.size = len(data)\n"
            "    for k, v in kw.items(): setattr(ti, k, v)\n"
            "    if pax: ti.pax_headers = pax\n"
            "    tar.addfile(ti, io.BytesIO(data) if ti.isreg() else None)\n"
            f"with tarfile.open({path!r}, {mode!r}, format={fmt}) as tar:\n"
            + textwrap.indent(body.strip("\n"), "    ") + "\nEOF\n")


GOOD_SITE = mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')")
SPHERE_MEMBER = "add(tar, 'assets/meshes/m.obj', open(os.environ['F'] + '/assets/meshes/sphere/sphere.obj', 'rb').read())"


def left(path: str, what: str) -> str:
    return (f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r')


def nosite() -> str:
    return left("$C/w/site", "--work/site left behind after a refusal")


def killed(cmd: str, after_s: float, group: bool = True) -> str:
    """Command head: `cmd` started, killed with SIGKILL after `after_s` s (its process group, or only its
    python process when group is False)."""
    if group:
        return (f"set -m; ( {cmd} ) >/dev/null 2>&1 & p=$!; sleep {after_s}; kill -KILL -$p 2>/dev/null; "
                "wait $p 2>/dev/null; set +m; ")
    return (f"{cmd} >/dev/null 2>&1 & p=$!; sleep {after_s}; kill -KILL $p 2>/dev/null; wait $p 2>/dev/null; ")


def complete(folder: str = "out", n: int | None = None) -> str:
    cond = "m.get('complete')" + (f" and sum(e.get('status') == 'done' for e in m['objects']) == {n}" if n else "")
    return (f"$PY -c \"import json,sys; m=json.load(open('{folder}/manifest.json')); "
            f"sys.exit(0 if {cond} else 'FAULT: {folder}/manifest.json not complete')\"")


def if_ok_complete(folder: str = "out") -> str:
    """Command tail: an exit 0 must leave a complete dataset in `folder`."""
    return ("; r=$?; if [ $r = 0 ]; then " + complete(folder) + " || exit 0; fi; exit $r")


def mesh(name: str, code: str) -> str:
    """Setup: assets/meshes/NAME written by `code` (Python; `p` is the path, numpy as np, struct)."""
    return "mkdir -p assets/meshes\n" + py(f"import numpy as np, struct\np = 'assets/meshes/{name}'\n"
                                           + textwrap.dedent(code).strip())


def hdr(name: str, code: str) -> str:
    """Setup: assets/hdri/NAME written by `code` (Python; `p` is the path)."""
    return "mkdir -p assets/hdri\n" + py(f"import numpy as np\np = 'assets/hdri/{name}'\n"
                                         + textwrap.dedent(code).strip())


def scene(code: str) -> str:
    """Setup: d/ (an object folder of data8) whose scene.json `s` is edited by `code` and written back."""
    return OBJ8 + py("import json\ns = json.load(open('d/scene.json'))\n" + textwrap.dedent(code).strip()
                     + "\njson.dump(s, open('d/scene.json', 'w'), indent=1)\n")


PLY_HEAD = ("def ply(p, verts, faces, fmt='binary_little_endian', nv=None, nf=None, dt='<'):\n"
            "    h = f'ply\\nformat {fmt} 1.0\\nelement vertex {len(verts) if nv is None else nv}\\n'\n"
            "    h += 'property float x\\nproperty float y\\nproperty float z\\n'\n"
            "    h += f'element face {len(faces) if nf is None else nf}\\nproperty list uchar int vertex_indices\\n'\n"
            "    h += 'end_header\\n'\n"
            "    b = h.encode()\n"
            "    for v in verts: b += struct.pack(dt + 'fff', *v)\n"
            "    for f in faces: b += struct.pack(dt + 'B', len(f)) + struct.pack(dt + 'i' * len(f), *f)\n"
            "    open(p, 'wb').write(b)\n"
            "import os, trimesh\n"
            "_m = trimesh.load(os.environ['F'] + '/assets/meshes/sphere/sphere.obj', process=False, force='mesh')\n"
            "V = [tuple(map(float, v)) for v in _m.vertices]\n"
            "FS = [tuple(map(int, f)) for f in _m.faces]\n")
"""Python for mesh(): `ply(p, verts, faces, ...)` writes a binary PLY; V, FS the fixtures' sphere (a mesh that
renders, so a refusal is about the damage, not the entropy rule)."""

CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


# ============================================================================ the process environment
case("s42-make-home-unset", "env", "env -u HOME " + MKO + " && " + complete(), expect="ok", may_change=OUT,
     timeout=90, why="No HOME (a cron job, a container): nothing the render needs lives there; the run completes.")
case("s42-make-tmpdir-missing", "env", "TMPDIR=\"$C/no/such/tmp\" " + MKO + " && " + complete(), expect="ok",
     may_change=OUT, timeout=90,
     why="A TMPDIR that does not exist: Python falls back to /tmp (or the run names TMPDIR); never a traceback.")
case("s42-make-omp-threads-abc", "env", "OMP_NUM_THREADS=abc MKL_NUM_THREADS=abc " + MKO + " && " + complete(),
     expect="ok", may_change=OUT, timeout=90,
     why="OMP_NUM_THREADS=abc is ignored by the libraries (a warning at most): the render completes.")
case("s42-make-ascii-locale-unicode-out", "env", ASCII + MK + ' --out "$C/dätä ø" ' + TINY
     + " && test -f \"$C/dätä ø/manifest.json\"", expect="either",
     may_change=["$C/dätä ø", "$C/dätä ø/*", "$C/dätä ø/*/*", "$C/dätä ø/*/*/*"], timeout=90,
     why="Under an ASCII locale a non-ASCII --out: rendered there, or refused in one line naming --out and the "
         "locale; never a UnicodeEncodeError traceback.")
case("s42-make-ascii-locale-unicode-mesh", "env", ASCII + MKA + " --shapes mesh" + if_ok_complete(), expect="either",
     setup="mkdir -p assets/meshes; cp " + SPHERE + " assets/meshes/kugel-ä.obj", may_change=OUT, timeout=100,
     why="A mesh named with a non-ASCII letter under an ASCII locale: read and recorded, or refused in one line "
         "naming it and the locale; never a UnicodeEncodeError traceback.")
case("s42-make-cuda-visible-devices-garbage", "env", "CUDA_VISIBLE_DEVICES=banana " + MKO + " && " + complete(),
     expect="ok", may_change=OUT, timeout=90,
     why="A garbage CUDA_VISIBLE_DEVICES means no GPU: the default variant falls back to the CPU and completes.")
case("s42-make-ray-address-env-without-ray", "env", "RAY_ADDRESS=garbage:notaport " + MKO + " && " + complete(),
     expect="ok", may_change=OUT, timeout=90,
     why="RAY_ADDRESS set to garbage while --ray is not given: Ray is not used, the local render completes.")
case("s42-sensor-home-unset-omp-abc", "env", "env -u HOME OMP_NUM_THREADS=abc " + SEN
     + ' --data d --sensor phone --out s && test -f s/manifest.json', expect="ok", setup=DS,
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"], timeout=90,
     why="sensor needs neither HOME nor a valid OMP_NUM_THREADS: the new dataset is written.")
case("s42-docs-ascii-locale-check", "env",
     DOCS + " --check >/dev/null 2>&1; a=$?; " + ASCII + "PYTHONPATH=\"$C/repo\" $PY -m orchestrate.docs --check; b=$?; "
     "echo \"utf8 $a ascii $b\"; [ $a = $b ] || { echo 'FAULT: docs --check depends on the locale'; exit 0; }; "
     "[ $b -le 1 ] || exit 3", expect="ok", setup=REPO_COPY, may_change=REPO_CHANGE, timeout=120,
     why="docs --check reads and compares UTF-8 pages: under an ASCII locale it gives the same verdict, not a "
         "UnicodeDecodeError (files must be opened as UTF-8 explicitly).")
# ============================================================================ stdout / stderr closed, SIGPIPE
case("s42-make-stdout-closed", "stream", MKV + " >&- && " + complete(), expect="ok", may_change=OUT, timeout=90,
     why="stdout closed (a daemon): progress has nowhere to go but the dataset is rendered, complete, exit 0.")
case("s42-make-stderr-closed", "stream", MKV + " 2>&- && " + complete(), expect="ok", may_change=OUT, timeout=90,
     why="stderr closed: no OSError on the first warning or progress line; the dataset completes.")
case("s42-make-stdout-into-head-1", "stream",
     "( " + MKV + "; echo $? > rc ) | head -1; sleep 1; r=$(cat rc); echo \"rc=$r\"; "
     "if [ \"$r\" = 0 ]; then " + complete() + "; else exit $r; fi", expect="either", may_change=OUT, timeout=90,
     why="`make | head -1`: after the reader goes the run finishes (or stops quietly); no BrokenPipeError "
         "traceback, and an exit 0 leaves a complete manifest.")
case("s42-export-stdout-into-head-1", "stream",
     "( $PY -m wildgen.export --data d --out s --shard-size 1; echo $? > rc ) | head -1; sleep 1; r=$(cat rc); "
     "echo rc=$r; exit $r", expect="either", setup=DS, may_change=["$C/s", "$C/s/*"], timeout=90,
     why="export piped into head -1: finished or stopped quietly; never a BrokenPipeError traceback.")
case("s42-docs-check-into-head-1", "stream",
     "( " + DOCS + " --check; echo $? > \"$C/rc\" ) | head -1; sleep 1; r=$(cat \"$C/rc\"); echo rc=$r; "
     "[ $r -le 1 ] || exit $r", expect="either", setup=REPO_COPY, may_change=REPO_CHANGE, timeout=90,
     why="docs --check | head -1: a verdict or a quiet stop, never a BrokenPipeError traceback.")
case("s42-make-help-into-head-1", "stream", "set -o pipefail; " + MK + " --help | head -1", expect="either",
     timeout=40, why="`--help | head -1` (a user peeking at usage): no 'Exception ignored ... BrokenPipeError'.")

# ============================================================================ resource limits
case("s42-make-ulimit-fsize-tiny", "limit", "( ulimit -f 2; " + MKO + " )" + if_ok_complete(), names=["out"],
     may_change=OUT, timeout=90,
     why="With files limited to 2 KiB a write fails (EFBIG): refused in one line naming the file, never an exit 0 "
         "with truncated PNGs / EXRs recorded as done.")
case("s42-make-ulimit-fsize-then-rerun", "limit",
     "( ulimit -f 2; " + MKO + " ) >/dev/null 2>&1; " + MKO + " && " + complete() + " && " + py("""
        import cv2, glob, sys
        for f in glob.glob('out/*.data/*.png'):
            if cv2.imread(f, cv2.IMREAD_UNCHANGED) is None:
                sys.exit('FAULT: ' + f + ' unreadable after the rerun')
        """), expect="ok", may_change=OUT, timeout=120,
     why="After a run cut by a full-disk-like EFBIG, the same command completes with readable images: nothing "
         "half-written counted as done.")
case("s42-make-ulimit-nofile-small", "limit", "( ulimit -n 24; " + MKO + " )" + if_ok_complete(),
     expect="either", may_change=OUT, timeout=90,
     why="24 file descriptors: rendered, or refused in one line (too many open files); no traceback, no hang.")
case("s42-export-ulimit-fsize-tiny", "limit",
     "( ulimit -f 8; " + EX + " --data d --out s ); r=$?; if grep -q '\"complete\": true' s/index.json 2>/dev/null; "
     "then echo 'FAULT: index.json complete though a shard failed to be written'; exit 0; fi; exit $r", names=["s"], setup=DS, may_change=["$C/s", "$C/s/*"], timeout=90,
     why="A shard cut at 8 KiB (EFBIG) is refused in one line; no index.json claiming the export complete.")
case("s42-relay-ulimit-fsize-member", "limit", "( ulimit -f 64; " + PROBE + " )" + nosite(),
     names=["site"], setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                                 "add(tar, 'pkg/blob.bin', os.urandom(300000))"),
     may_change=SESS_CHANGE, timeout=90,
     why="A site member that cannot be written whole (EFBIG at 64 KiB) is refused in one line and nothing of the "
         "half-unpacked site stays for the next run to trust.")
case("s42-pack-ulimit-fsize-tiny", "limit", "( ulimit -f 64; " + PACK + " --assets none )"
     + left("$C/p/manifest.json", "a manifest written beside a cut site.tar.xz"), names=["site.tar.xz"],
     setup=WHEELS.replace('z.writestr(name.split("-")[0] + "/__init__.py", "")',
                          'z.writestr(name.split("-")[0] + "/__init__.py", ""); '
                          'z.writestr(name.split("-")[0] + "/blob.bin", __import__("os").urandom(400000))'),
     may_change=PACK_CHANGE, timeout=90,
     why="A pack whose site.tar.xz (about 800 KB) cannot be written past 64 KiB is refused in one line naming "
         "it; no manifest vouches for a cut archive.")

# ============================================================================ names: length, NFC/NFD, mtimes, sparse
case("s42-make-out-component-256-bytes", "input", MK + ' --out "$C/$(printf "a%.0s" $(seq 256))" ' + TINY,
     names=["--out"], timeout=60,
     why="A path component of 256 bytes cannot exist: refused naming --out (File name too long), not a traceback.")
case("s42-make-assets-mesh-name-255-bytes", "input", MKA + " --shapes mesh && " + complete(), expect="ok",
     setup='mkdir -p assets/meshes; cp ' + SPHERE + ' "assets/meshes/$(printf "m%.0s" $(seq 251)).obj"',
     may_change=OUT, timeout=100,
     why="A mesh whose name is exactly 255 bytes is a valid file: drawn and rendered (derived names must not add "
         "to it past the limit).")
case("s42-make-assets-nfc-nfd-twin-meshes", "input", MKA + " --shapes mesh --objects 2 && " + complete("out", 2),
     expect="ok", setup='mkdir -p assets/meshes; cp ' + SPHERE + ' "assets/meshes/$(printf "caf\\xc3\\xa9").obj"; '
     'cp "$F/assets/meshes/torus/torus.obj" "assets/meshes/$(printf "cafe\\xcc\\x81").obj"',
     may_change=OUT, timeout=120,
     why="Two meshes whose names differ only in Unicode normalisation (NFC vs NFD) are two files: both usable, "
         "no KeyError from a normalised lookup.")
case("s42-export-object-folders-nfc-nfd-twins", "input", EX + " --data d --out s", expect="either",
     setup="mkdir d; cp -r \"$F/data/00000.data\" \"d/$(printf 'caf\\xc3\\xa9').data\"; "
           "cp -r \"$F/data/00001.data\" \"d/$(printf 'cafe\\xcc\\x81').data\"",
     may_change=["$C/s", "$C/s/*"], timeout=90,
     why="Two object folders named as NFC/NFD twins: exported as two samples or refused naming them; never one "
         "silently replacing the other.")
case("s42-make-resume-mtimes-in-future", "input",
     "find out -exec touch -d '2199-01-01' {} +; " + MK + ' --out "$C/out" --resume --workers 0 --quiet && '
     + complete(), expect="ok", setup=OUTDS, may_change=OUT, timeout=120,
     why="A dataset whose files carry mtimes in 2199 (a clock gone wrong): resumed as complete, no negative age.")
case("s42-pack-assets-mtimes-year-5138", "input", PACK + ' --assets "$C/assets" && test -f p/assets.tar.xz',
     expect="either", setup=WHEELS + "mkdir -p assets/meshes assets/hdri\n"
     "for i in 1 2 3 4; do cp " + SPHERE + " assets/meshes/m$i.obj; cp " + HDR + " assets/hdri/h$i.hdr; done\n"
     "find assets -exec touch -d @99999999999 {} +", may_change=PACK_CHANGE,
     timeout=90, why="Asset files dated in the year 5138: packed (PAX times) or refused in one line naming the "
                     "file; not a struct.error traceback.")
case("s42-make-assets-obj-sparse-8gib", "input", MKA + " --shapes mesh", names=["huge.obj"],
     setup='mkdir -p assets/meshes; cp ' + SPHERE + ' assets/meshes/huge.obj; truncate -s 8G assets/meshes/huge.obj',
     timeout=60,
     why="An 8 GiB OBJ (a sphere followed by NULs, sparse) is refused by size naming huge.obj before it is read "
         "into memory; no hang.")
case("s42-make-assets-hdr-sparse-tail-4gib", "input", MKA + " --lights hdri" + if_ok_complete(), expect="either",
     setup='mkdir -p assets/hdri; cp ' + HDR + ' assets/hdri/tail.hdr; truncate -s +4G assets/hdri/tail.hdr',
     may_change=OUT, timeout=100,
     why="A valid HDR followed by 4 GiB of NULs: read as its header says or refused naming tail.hdr; never read "
         "whole into memory (no OOM, no hang).")
case("s42-pack-assets-sparse-mesh-2gib", "input", PACK + ' --assets "$C/assets"', names=["a_big.obj"],
     setup=WHEELS + "mkdir -p assets/meshes assets/hdri\n"
     "for i in 1 2 3 4; do cp " + SPHERE + " assets/meshes/m$i.obj; cp " + HDR + " assets/hdri/h$i.hdr; done\n"
     "cp " + SPHERE + " assets/meshes/a_big.obj; truncate -s 2G assets/meshes/a_big.obj", may_change=PACK_CHANGE,
     timeout=100,
     why="A 2 GiB sparse mesh cannot travel (upload limit 64 MiB): refused naming it before minutes of xz.")

# ============================================================================ meshes
case("s42-make-ply-binary-vertex-count-short", "input", MKA + " --shapes mesh", names=["short.ply"],
     setup=mesh("short.ply", PLY_HEAD + "ply(p, V, FS, nv=len(V) + 40)"), timeout=90,
     why="A binary PLY whose header says 40 vertices more than stored: refused naming short.ply (faces read as "
         "vertices would be garbage).")
case("s42-make-ply-binary-face-count-beyond", "input", MKA + " --shapes mesh", names=["faces.ply"],
     setup=mesh("faces.ply", PLY_HEAD + "ply(p, V, FS, nf=len(FS) + 50)"), timeout=90,
     why="A binary PLY claiming 50 faces more than stored is refused naming the file, not read past its end.")
case("s42-make-ply-binary-index-out-of-range", "input", MKA + " --shapes mesh", names=["idx.ply"],
     setup=mesh("idx.ply", PLY_HEAD + "ply(p, V, FS[:-1] + [(1, 2, 10**7)])"), timeout=90,
     why="A binary PLY face naming vertex 10^7 is refused naming idx.ply, not an IndexError or a silent drop.")
case("s42-make-ply-binary-negative-index", "input", MKA + " --shapes mesh", names=["neg.ply"],
     setup=mesh("neg.ply", PLY_HEAD + "ply(p, V, FS[:-1] + [(1, 2, -5)])"), timeout=90,
     why="A negative index in a binary PLY (numpy would wrap it to another vertex) is refused naming neg.ply.")
case("s42-make-ply-binary-nan-vertex", "input", MKA + " --shapes mesh", names=["nan.ply"],
     setup=mesh("nan.ply", PLY_HEAD + "ply(p, [(float('nan'), 0.0, 1.0)] + V[1:], FS)"), timeout=90,
     why="A NaN vertex in a binary PLY is named up front like one in an OBJ, not normalised into a NaN mesh.")
case("s42-make-ply-binary-big-endian", "input", MKA + " --shapes mesh && " + complete(), expect="ok",
     setup=mesh("be.ply", PLY_HEAD + "ply(p, V, FS, fmt='binary_big_endian', dt='>')"), may_change=OUT, timeout=100,
     why="A valid big-endian binary PLY (old scanners) is read correctly and rendered.")
case("s42-make-obj-tiny-scale", "input", MKA + " --shapes mesh" + if_ok_complete(), expect="either",
     setup="mkdir -p assets/meshes; " + py("""
        import re
        out = []
        for line in open('""" + "/tmp/sw40/fx/assets/meshes/sphere/sphere.obj" + """'):
            if line.startswith('v '):
                x, y, z = map(float, line.split()[1:4]); line = f'v {x*1e-30} {y*1e-30} {z*1e-30}\\n'
            out.append(line)
        open('assets/meshes/tiny.obj', 'w').writelines(out)
        """), may_change=OUT, timeout=100,
     why="A sphere 1e-30 units across (a unit mix-up): normalised and rendered, or refused naming tiny.obj; "
         "never NaN normals from float32 underflow with exit 0.")
case("s42-make-obj-crlf-lines", "input", MKA + " --shapes mesh && " + complete(), expect="ok",
     setup="mkdir -p assets/meshes; sed 's/$/\\r/' " + SPHERE + " > assets/meshes/win.obj", may_change=OUT,
     timeout=100, why="An OBJ saved on Windows (CRLF) is the same mesh: rendered.")
case("s42-make-obj-million-faces", "input", MKA + " --shapes mesh && " + complete(), expect="ok",
     setup=mesh("dense.obj", """
        n = 708  # 2 * 707 * 707 = 999698 faces on a height field sphere cap
        u, v = np.meshgrid(np.linspace(0, np.pi, n), np.linspace(0, 2 * np.pi, n), indexing='ij')
        P = np.stack([np.sin(u) * np.cos(v), np.sin(u) * np.sin(v), np.cos(u)], -1).reshape(-1, 3)
        i = np.arange(n * n).reshape(n, n)
        a, b, c, d = i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()
        F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]) + 1
        with open(p, 'w') as f:
            f.write(''.join('v %.6f %.6f %.6f\\n' % tuple(x) for x in P))
            f.write(''.join('f %d %d %d\\n' % tuple(x) for x in F))
        """), may_change=OUT, timeout=120,
     why="A 10^6-face scan is an ordinary mesh: rendered at 16 px within the timeout (no quadratic step).")
case("s42-make-obj-texcoord-index-beyond", "input", MKA + " --shapes mesh" + if_ok_complete(), expect="either",
     setup="mkdir -p assets/meshes; { cat " + SPHERE + "; printf 'vt 0 0\\nf 1/99999 2/99999 3/99999\\n'; } "
           "> assets/meshes/vt.obj",
     may_change=OUT, timeout=100,
     why="Texture indices beyond the vt list: the texture coordinates dropped, or refused naming vt.obj; no "
         "IndexError.")

# ============================================================================ HDR maps
case("s42-make-hdr-format-garbage", "input", MKA + " --lights hdri", names=["bad.hdr"],
     setup="mkdir -p assets/hdri; sed '0,/FORMAT=32-bit_rle_rgbe/s//FORMAT=jpeg/' " + HDR + " > assets/hdri/bad.hdr",
     timeout=90, why="An HDR whose FORMAT line is unknown is refused naming bad.hdr before rendering.")
case("s42-make-hdr-truncated-mid-rle", "input", MKA + " --lights hdri", names=["cut.hdr"],
     setup="mkdir -p assets/hdri; head -c 300000 " + HDR + " > assets/hdri/cut.hdr", timeout=90,
     why="An HDR cut after a fifth of its scanlines is refused naming cut.hdr, not used with black rows.")
case("s42-make-hdr-a-png-renamed", "input", MKA + " --lights hdri", names=["photo.hdr"],
     setup="mkdir -p assets/hdri; cp \"$F/mask.png\" assets/hdri/photo.hdr", timeout=90,
     why="A PNG saved as .hdr is refused naming photo.hdr (not a Radiance file), not decoded by content as LDR.")
case("s42-make-hdr-size-zero", "input", MKA + " --lights hdri", names=["zero.hdr"],
     setup="mkdir -p assets/hdri; printf '#?RADIANCE\\nFORMAT=32-bit_rle_rgbe\\n\\n-Y 0 +X 0\\n' > assets/hdri/zero.hdr",
     timeout=90, why="An HDR of 0x0 pixels is refused naming zero.hdr (no ZeroDivisionError in resampling).")
case("s42-make-hdr-endless-header", "input", MKA + " --lights hdri", names=["long.hdr"],
     setup="mkdir -p assets/hdri; { printf '#?RADIANCE\\n'; head -c 50000000 /dev/zero | tr '\\0' 'x'; } "
           "> assets/hdri/long.hdr", timeout=90,
     why="A 50 MB header line without end is refused naming long.hdr; no hang reading it line by line.")
case("s42-make-hdr-near-float-max", "input", MKA + " --lights hdri" + if_ok_complete() + " && " + py("""
        import glob, sys, numpy as np
        from scenes.exr import read_exr
        for f in glob.glob('out/*.data/aux/radiance_*.exr'):
            if not np.isfinite(read_exr(f)).all():
                sys.exit('FAULT: ' + f + ' holds inf/NaN')
        """), expect="either",
     setup=hdr("max.hdr", """
        w, h = 32, 16
        px = bytes([255, 255, 255, 254]) * (w * h)
        open(p, 'wb').write(f'#?RADIANCE\\nFORMAT=32-bit_rle_rgbe\\n\\n-Y {h} +X {w}\\n'.encode() + px)
        """), may_change=OUT, timeout=100,
     why="Texels near 1.7e38 (exponent byte 254): refused naming max.hdr, or rendered with finite radiance; "
         "never inf/NaN images with exit 0.")
# ============================================================================ scene.json re-rendering (validate.rerender)
case("s42-rr-scene-shape-file-dev-zero", "archive", RRD, names=["scene.json"],
     setup=scene("s['shape']['file'] = '/dev/zero'"), may_change=R, timeout=90,
     why="scene.json naming /dev/zero as the mesh is refused naming scene.json; never read endlessly.")
case("s42-rr-scene-shape-file-link-out", "archive", RRD, names=["mesh"],
     setup=OBJ8 + "rm d/aux/mesh.ply; ln -s /etc/passwd d/aux/mesh.ply", may_change=R, timeout=90,
     why="aux/mesh.ply replaced by a link to /etc/passwd: refused naming the mesh, nothing of passwd echoed.")
case("s42-rr-scene-camera-width-a-string", "input", RRD, names=["scene.json"],
     setup=scene("s['camera']['width'] = str(s['camera']['width'])"), may_change=R, timeout=90,
     why="camera.width written as a string by hand is refused naming scene.json, not a TypeError.")
case("s42-rr-scene-camera-fov-nan", "input", RRD, names=["scene.json"],
     setup=scene("s['camera']['fov'] = float('nan'); s['camera']['kind'] = 'perspective'"), may_change=R,
     timeout=90, why="A NaN field of view is refused naming scene.json, not rendered into NaN images.")
case("s42-rr-scene-images-empty", "input", RRD, names=["scene.json"], setup=scene("s['images'] = []"),
     may_change=R, timeout=90,
     why="scene.json listing no images while L*.png exist disagrees with the folder: refused naming scene.json.")
case("s42-rr-scene-light-color-negative", "input", RRD, names=["scene.json"],
     setup=scene("s['images'][0]['lights'][0]['color'] = [-1.0, -1.0, -1.0]"), may_change=R, timeout=90,
     why="A light of negative colour cannot exist: refused naming scene.json, not a report over negative radiance.")
case("s42-rr-scene-camera-size-disagrees", "input", RRD, names=["scene.json"],
     setup=scene("s['camera']['width'] = 64; s['camera']['height'] = 64"), may_change=R, timeout=90,
     why="scene.json saying 64 px over 32-px images is refused naming scene.json (or the size), not resampled.")
case("s42-rr-mesh-ply-nan-vertex", "input", RRD, names=["mesh.ply"],
     setup=OBJ8 + py("""
        import trimesh, numpy as np
        m = trimesh.load('d/aux/mesh.ply', process=False)
        v = np.array(m.vertices); v[0] = np.nan
        trimesh.Trimesh(v, m.faces, process=False).export('d/aux/mesh.ply')
        """), may_change=R, timeout=90,
     why="aux/mesh.ply edited to hold a NaN vertex is refused naming mesh.ply, not rendered into a NaN depth map.")

# ============================================================================ relay archives
case("s42-relay-site-block-device", "archive", PROBE + nosite(), names=["site.tar.xz"],
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                 "add(tar, 'pkg/sda', type=tarfile.BLKTYPE, devmajor=8, devminor=0)"),
     may_change=SESS_CHANGE, timeout=90,
     why="A block-device member (/dev/sda's numbers) is refused naming site.tar.xz; no node is created.")
case("s42-relay-site-hardlink-to-itself", "archive", PROBE + nosite(), names=["site.tar.xz"],
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                 "add(tar, 'pkg/self.py', type=tarfile.LNKTYPE, linkname='pkg/self.py')"),
     may_change=SESS_CHANGE, timeout=90,
     why="A hard link naming itself is refused in one line naming site.tar.xz; no hang, no KeyError.")
case("s42-relay-site-file-then-link-same-name", "archive", PROBE + nosite(), names=["site.tar.xz"],
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                 "add(tar, 'pkg/evil_s42.py', b'x = 1')\n"
                 "add(tar, 'pkg/evil_s42.py', type=tarfile.SYMTYPE, linkname='/etc/passwd')"),
     may_change=SESS_CHANGE, timeout=90,
     why="A file then a link out under the same name: refused naming site.tar.xz before anything is written.")
case("s42-relay-site-dir-then-file-same-name", "archive", PROBE + nosite(), expect="either",
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                 "add(tar, 'pkg/sub', type=tarfile.DIRTYPE, mode=0o755)\n"
                 "add(tar, 'pkg/sub', b'now a file')"),
     may_change=SESS_CHANGE, timeout=90,
     why="A folder member then a file of the same name: refused naming site.tar.xz or the pack accepted and the "
         "--assets refusal follows; no IsADirectoryError traceback, nothing left.")
case("s42-relay-site-ustar-prefix-escape", "archive", PROBE + nosite(), names=["site.tar.xz"],
     setup="mkdir -p c\n" + py("""
        import io, lzma, tarfile
        def blk(name, prefix, data):
            ti = tarfile.TarInfo('x'); ti.size = len(data); ti.mode = 0o644
            h = bytearray(ti.tobuf(tarfile.USTAR_FORMAT)[:512])
            h[0:100] = name.encode().ljust(100, b'\\0'); h[345:500] = prefix.encode().ljust(155, b'\\0')
            h[148:156] = b' ' * 8
            h[148:156] = ('%06o\\0 ' % sum(h)).encode()
            return bytes(h) + data + b'\\0' * (-len(data) % 512)
        raw = blk('__init__.py', 'pkg', b'') + blk('escape_s42.py', '../../..', b'x') + b'\\0' * 1024
        open('c/site.tar.xz', 'wb').write(lzma.compress(raw))
        """), may_change=SESS_CHANGE, timeout=90,
     why="A ustar member whose prefix field is ../../.. leads out of --work/site: refused naming site.tar.xz, "
         "escape_s42.py written nowhere.")
case("s42-relay-site-gnu-sparse-3gib", "archive", PROBE + nosite(), names=["site.tar.xz"],
     setup="mkdir -p c t/pkg; : > t/pkg/__init__.py; truncate -s 3G t/pkg/hole.bin; "
           "tar --sparse --format=gnu -C t -cJf c/site.tar.xz pkg",
     may_change=SESS_CHANGE, timeout=120,
     why="A GNU sparse member of 3 GiB apparent size is a bomb like a 3 GiB xz stream: refused naming "
         "site.tar.xz before it is written.")
case("s42-relay-assets-hardlink-outside", "archive", SESS + left("$C/w/assets", "--work/assets left behind"),
     names=["assets.tar.xz"],
     setup=GOOD_SITE + mktar("c/assets.tar.xz", SPHERE_MEMBER + "\n"
                             "add(tar, 'assets/meshes/evil_s42.obj', type=tarfile.LNKTYPE, linkname='/etc/passwd')"),
     may_change=SESS_CHANGE, timeout=100,
     why="An assets member hard-linked to /etc/passwd is refused naming assets.tar.xz; no link created.")
case("s42-relay-assets-block-device", "archive", SESS + left("$C/w/assets", "--work/assets left behind"),
     names=["assets.tar.xz"],
     setup=GOOD_SITE + mktar("c/assets.tar.xz", SPHERE_MEMBER + "\n"
                             "add(tar, 'assets/meshes/disk', type=tarfile.BLKTYPE, devmajor=8, devminor=0)"),
     may_change=SESS_CHANGE, timeout=100,
     why="A block device in the assets archive is refused naming assets.tar.xz before anything is unpacked.")
# ============================================================================ SIGKILL and re-run
case("s42-make-kill9-parent-only-then-rerun", "signal",
     killed(MK + ' --out "$C/out" --objects 3 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 1 --quiet', 5,
            group=False)
     + MK + ' --out "$C/out" --objects 3 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 1 --quiet; r=$?; '
     "if [ $r = 0 ]; then " + complete("out", 3) + "; else exit $r; fi", expect="either", may_change=OUT,
     timeout=120,
     why="The parent killed, its worker orphaned: the rerun either waits / refuses naming the other writer, or "
         "completes all 3 objects; never two writers corrupting one object folder.")
case("s42-pack-kill9-then-pack-again", "signal",
     killed(PACK + ' --assets "$C/assets"', 1.8) + PACK + ' --assets "$C/assets" --overwrite && test -f p/assets.tar.xz && '
     "test -f p/site.tar.xz && $PY -c \"import tarfile; [tarfile.open('p/'+n).getmembers() for n in "
     "('site.tar.xz','assets.tar.xz')]\"", expect="ok",
     setup=WHEELS + "mkdir -p assets/meshes assets/hdri\n"
     "for i in 1 2 3 4; do cp " + SPHERE + " assets/meshes/m$i.obj; cp " + HDR + " assets/hdri/h$i.hdr; done\n", may_change=PACK_CHANGE, timeout=120,
     why="A pack killed mid-write is redone with --overwrite (no 'in use' or half-archive confusion) and its "
         "archives read back whole.")
case("s42-relay-kill9-mid-unpack-then-rerun", "signal",
     killed(PROBE, 2.2) + PROBE + "; r=$?; if [ -e w/site ] && [ ! -e w/.site.unpacked ]; then echo 'FAULT: an "
     "unmarked half site left'; exit 0; fi; if [ -e w/.site.unpacked ] && [ $(ls w/site/pkg | wc -l) != 41 ]; then "
     "echo 'FAULT: a site marked unpacked holds '$(ls w/site/pkg | wc -l)' of 41 files'; exit 0; fi; exit $r",
     names=["--assets"],
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                 "for i in range(40): add(tar, f'pkg/b{i}.bin', os.urandom(1 << 20))", mode="w:xz"),
     may_change=SESS_CHANGE, timeout=120,
     why="A session killed while (or right after) unpacking site: the next one reaches the --assets refusal; a "
         "site it keeps is whole and marked, a half one is never trusted or left unmarked.")
case("s42-docs-kill9-then-check", "signal",
     killed(DOCS, 1.5) + DOCS + " >/dev/null 2>&1; " + DOCS + " --check", expect="ok", setup=REPO_COPY,
     may_change=REPO_CHANGE, timeout=120,
     why="docs killed mid-write then run again: --check then passes (no page left half written or a temp file "
         "beside it confusing the next run).")
# ============================================================================ outputs overlapping inputs via .. and /
case("s42-make-out-object-folder-via-dotdot", "overlap",
     MK + ' --out "$C/d/00001.data/../00000.data" ' + TINY, names=["--out"], setup=DS,
     why="--out that resolves (through ..) to an object folder of a dataset is refused naming --out: no dataset "
         "written into 00000.data.")
case("s42-make-resume-out-trailing-slashes", "overlap",
     MK + ' --out "$C/out//" --resume --workers 0 --quiet && ' + complete(), expect="ok", setup=OUTDS,
     may_change=OUT, timeout=100,
     why="`out//` is out: the dataset is resumed (as complete), not taken for another folder or refused.")
case("s42-sensor-out-equals-data-via-dot-slash", "overlap", SEN + ' --data "$C/d" --sensor phone --out "$C/d/./"',
     names=["--out"], setup=DS, why="--out d/./ is --data: refused naming --out before any image is replaced.")
case("s42-export-out-equals-data-via-dotdot", "overlap", EX + ' --data d --out "d/00000.data/.."',
     names=["--out"], setup=DS, why="--out d/00000.data/.. is --data: refused naming --out, no shard in the dataset.")
case("s42-export-data-object-folder-via-trailing-dotdot-out-inside", "overlap",
     EX + ' --data "d/00000.data/" --out "d/00000.data/aux/../shards"', names=["--out"], setup=DS,
     why="--out inside the one object folder given as --data (through aux/..) is refused naming --out.")
case("s42-gs-work-equals-out-trailing-slash", "overlap",
     GS + ' --out "$C/o" --work "$C/o/" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1 --check-variant none'
     ' --minutes 1 --reserve-s 30 --steps 1 --batch 1', names=["--work"], may_change=["$C/o", "$C/o/*"], timeout=60,
     why="--work o/ and --out o are one folder: refused naming --work and --out before any render.")
case("s42-gs-carry-above-work", "overlap",
     GS + ' --out "$C/o" --work "$C/c/w" --carry "$C/c/w/.." --cpu-rehearsal --objects 1 --images 3 --res 16 '
     '--spp 1 --check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1' + left("$C/c/w/site", "unpacked"),
     names=["--work"], setup=GOOD_SITE, may_change=["$C/o", "$C/o/*", "$C/c/w", "$C/c/w/*"], timeout=60,
     why="--work inside --carry (named through ..): the pack would be unpacked into itself; refused naming "
         "--work / --carry before unpacking.")
case("s42-pack-into-assets-via-dotdot", "overlap",
     PACK + ' --assets "$C/assets" --pack "$C/assets/meshes/.."', names=["--pack"],
     setup=WHEELS + "mkdir -p assets/meshes/s; cp " + SPHERE + " assets/meshes/s/", timeout=60,
     why="--pack that resolves to --assets (through meshes/..) is refused naming --pack; no archive in the library.")
case("s42-demo-out-equals-checkpoint-folder-via-dotdot", "overlap",
     DEMO + ' --out "$C/run/x/.." ' + DEMO_TINY + ' --checkpoint "$C/run/last.pt"', expect="either",
     setup='cp -r "$F/run" run; mkdir -p run/x',
     may_change=["$C/run/data", "$C/run/data/*", "$C/run/data/*/*", "$C/run/data/*/*/*", "$C/run/pred",
                 "$C/run/pred/*", "$C/run/pred/*/*", "$C/run/rerender", "$C/run/rerender/*",
                 "$C/run/rerender/*/*", "$C/run/summary.md"], timeout=120,
     why="--out (through x/..) is the folder holding --checkpoint: refused naming --out, or the demo writes "
         "only its own data/ pred/ rerender/ summary.md and never touches last.pt.")
