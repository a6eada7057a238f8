"""Sweep 41, part p: the GENERATOR and RELAY side (wildgen.make / sensor / export / preview, orchestrate.gpu_session
--pack / --carry / --cpu-rehearsal, orchestrate.train_recipe, orchestrate.demo, orchestrate.docs), with cases that
cases37-40 and the tests do not hold: OBJ material libraries pointing at devices, meshes in UTF-16 or with NaN,
--shards aimed at an export of another dataset / at --out / at --assets, runs killed with SIGKILL then resumed,
hand-deleted masks, user files in object-numbered folders, --ray addresses of the wrong kind, relay markers planted
as folders or links, tar members with NUL / NaN PAX headers / trailing slashes / newlines, a carry unpacked into
itself, wheels that are zip bombs or two versions of one package, recipe / demo flags refused before work, and docs
pages with a BOM, a hard link out of the tree, or two writers.

Cases whose command adds its own check print a line starting with `FAULT:` and exit so that the harness flags it.
"""
from __future__ import annotations

import textwrap

TINY = "--objects 1 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet"
MK = "$PY -m wildgen.make"
MKA = MK + ' --out "$C/out" --assets "$C/assets" ' + TINY
RES = f'{MK} --out "$C/out" --resume --workers 0 --quiet'
PV = "$PY -m wildgen.preview"
SEN = "$PY -m wildgen.sensor --quiet"
EX = "$PY -m wildgen.export --quiet"
GS = "$PY -m orchestrate.gpu_session"
SESS = (GS + ' --out "$C/o" --work "$C/w" --carry "$C/c" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1'
        " --check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
PROBE = SESS + ' --assets "$C/no-such-assets"'
"""A session whose --assets is checked only once the pack is unpacked: an accepted pack ends in a refusal naming
--assets (and nothing of it stays), a refused pack in one naming the archive."""
SESS_PLAIN = (GS + ' --out "$C/o" --work "$C/w" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1 '
              "--check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
RC = "$PY -m orchestrate.train_recipe"
RCW = RC + ' --work "$C/w" --assets none --train-objects 1 --steps 1 --threads 1'
DEMO = "$PY -m orchestrate.demo"
DS = 'cp -r "$F/data" d\n'
OUTDS = 'cp -r "$F/data" out\n'
OUT = ["$C/out", "$C/out/*", "$C/out/*/*", "$C/out/*/*/*"]
SESS_CHANGE = ["$C/o", "$C/o/*", "$C/o/*/*", "$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*", "$C/w/*/*/*/*"]
SPHERE = '"$F/assets/meshes/sphere/sphere.obj"'
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


def py(code: str) -> str:
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


def manifest(folder: str, code: str) -> str:
    return py("import json\n"
              f"p = '{folder}/manifest.json'\n"
              "m = json.load(open(p))\n"
              + textwrap.dedent(code).strip() + "\n"
              "json.dump(m, open(p, 'w'), indent=1)\n")


def mktar(path: str, body: str, mode: str = "w:xz", fmt: str = "tarfile.PAX_FORMAT") -> str:
    """Setup: the tar `path` written by `body` (Python, with `tar` open, `add(tar, name, data=b'', **attrs)`)."""
    return (f'mkdir -p "$(dirname {path})"\n$PY - <<\'EOF\'\nimport io, os, tarfile\n'
            "def add(tar, name, data=b'', pax=None, **kw):\n"
            "    ti = tarfile.TarInfo(name); ti.mode = 0o644; ti.size = len(data)\n"
            "    for k, v in kw.items(): setattr(ti, k, v)\n"
            "    if pax: ti.pax_headers = pax\n"
            "    tar.addfile(ti, io.BytesIO(data))\n"
            f"with tarfile.open({path!r}, {mode!r}, format={fmt}) as tar:\n"
            + textwrap.indent(body.strip("\n"), "    ") + "\nEOF\n")


GOOD_SITE = mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')")


def left(path: str, what: str) -> str:
    return (f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r')


def nosite() -> str:
    return left("$C/w/site", "--work/site left behind after a refusal")


def both(cmd_a: str, cmd_b: str, after: str = "") -> str:
    return (f"( {cmd_a} ) > a.log 2>&1 & p1=$!; ( {cmd_b} ) > b.log 2>&1 & p2=$!; wait $p1; r1=$?; wait $p2; r2=$?; "
            f'cat a.log b.log; echo "rc $r1 $r2"; [ $r1 = 0 ] || [ $r2 = 0 ] || exit 1; {after or "true"}')


def killed(cmd: str, after_s: float) -> str:
    """Command head: `cmd` started, killed with SIGKILL (its whole process group) after `after_s` seconds."""
    return (f"set -m; ( {cmd} ) >/dev/null 2>&1 & p=$!; sleep {after_s}; kill -KILL -$p 2>/dev/null; "
            "wait $p 2>/dev/null; set +m; ")


def complete(folder: str, n: int | None = None) -> str:
    cond = "m.get('complete')" + (f" and sum(e.get('status') == 'done' for e in m['objects']) == {n}" if n else "")
    return (f"$PY -c \"import json,sys; m=json.load(open('{folder}/manifest.json')); "
            f"sys.exit(0 if {cond} else 'FAULT: {folder}/manifest.json not complete')\"")


def index_objects(folder: str, n: int) -> str:
    return (f"$PY -c \"import json,sys; m=json.load(open('{folder}/index.json')); "
            f"k=sum(len(s['objects']) for s in m['shards']); "
            f"sys.exit(0 if m.get('complete') and k == {n} else f'FAULT: {folder}/index.json lists {{k}} objects')\"")


CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


# ============================================================================ wildgen.make: asset libraries
OBJ_HEAD = 'mkdir -p assets/meshes; { printf "mtllib %s\\nusemtl m\\n" "$1"; cat ' + SPHERE + '; } > assets/meshes/m.obj\n'
case("p41-make-obj-mtllib-link-to-dev-zero", "input", MKA + " --shapes mesh", expect="either",
     setup=OBJ_HEAD.replace('"$1"', "evil.mtl") + "ln -s /dev/zero assets/meshes/evil.mtl",
     may_change=OUT, timeout=100,
     why="An OBJ whose material library is a link to /dev/zero: the material is ignored or the mesh refused in one "
         "line naming it; the loader never reads an endless file (no hang, no memory blow-up).")
case("p41-make-mtl-texture-dev-zero", "input", MKA + " --shapes mesh", expect="either",
     setup=OBJ_HEAD.replace('"$1"', "m.mtl") + "printf 'newmtl m\\nKd 1 1 1\\nmap_Kd /dev/zero\\n' > assets/meshes/m.mtl",
     may_change=OUT, timeout=100,
     why="An MTL naming /dev/zero as its diffuse texture is ignored or named; never read until memory runs out.")
case("p41-make-mtl-texture-outside-library", "input", MKA + " --shapes mesh", expect="either",
     setup=OBJ_HEAD.replace('"$1"', "m.mtl") + "printf 'newmtl m\\nmap_Kd ../../../../../../etc/shadow\\n' "
     "> assets/meshes/m.mtl", may_change=OUT, timeout=100,
     why="An MTL texture path climbing out of the library (to an unreadable file): ignored or refused naming the "
         "mesh, no PermissionError traceback.")
case("p41-make-obj-utf16", "input", MKA + " --shapes mesh", names=["w.obj"], timeout=100,
     setup="mkdir -p assets/meshes; iconv -f utf-8 -t utf-16 " + SPHERE + " > assets/meshes/w.obj",
     why="An OBJ saved as UTF-16 (Notepad) parses to no vertex: refused naming w.obj before rendering, not a "
         "per-object failure.")
case("p41-make-obj-nan-vertex", "input", MKA + " --shapes mesh", names=["nan.obj"], timeout=100,
     setup="mkdir -p assets/meshes; printf 'v nan 0 0\\nv 1 0 0\\nv 0 1 0\\nv 0 0 1\\nf 1 2 3\\nf 2 3 4\\nf 1 3 4\\n' "
           "> assets/meshes/nan.obj",
     why="A vertex of 'nan' makes the normalisation NaN: the mesh is named as non-finite up front.")
case("p41-make-hdr-link-loop", "input", MKA + " --lights hdri", expect="either", names=[], may_change=OUT,
     setup="mkdir -p assets/hdri; cp \"$F/assets/hdri/apartment.hdr\" assets/hdri/ok.hdr; "
           "ln -s loop.hdr assets/hdri/loop.hdr", timeout=100,
     why="A map that is a link to itself (ELOOP) is skipped or named in one line, never a traceback.")
case("p41-make-texture-16bit-gray", "exit0", MKA + " && " + complete("out"), expect="ok", may_change=OUT,
     setup="mkdir -p assets/textures/g; " + py("""
        import numpy as np, cv2
        cv2.imwrite("assets/textures/g/g_col.png", np.random.default_rng(1).integers(0, 65535, (16, 16), np.uint16))
        """), timeout=110,
     why="A 16-bit grey base colour is a valid texture (converted to RGB): the run completes.")

# ============================================================================ wildgen.make: --shards
case("p41-make-shards-an-export-of-another-dataset", "writer",
     f'{MK} --out "$C/out" --shards "$C/sh" {TINY}' + left("$C/out/00000.data", "rendered before refusing --shards"),
     names=["--shards"], setup='cp -r "$F/shards" sh', may_change=["$C/out", "$C/out/*"], timeout=90,
     why="--shards holding an export of another dataset is replaced only with --overwrite: refused naming "
         "--shards before the render (the help: 'checked before the render').")
case("p41-make-shards-equals-out", "writer", f'{MK} --out "$C/out" --shards "$C/out" {TINY}', names=["--shards"],
     may_change=["$C/out", "$C/out/*"], timeout=60,
     why="Shards written into the dataset folder itself mix tars with object folders: refused naming --shards.")
case("p41-make-shards-equals-assets", "writer",
     f'{MK} --out "$C/out" --assets "$C/assets" --shards "$C/assets" {TINY}', names=["--shards"],
     setup='cp -r "$F/assets" assets', may_change=["$C/out", "$C/out/*"], timeout=60,
     why="Shards written into the asset library would be read back as assets next time: refused naming --shards.")
case("p41-make-shards-under-fixture-data-resume", "writer",
     f'{RES} --shards "$C/out/00001.data/sh"', names=["--shards"], setup=OUTDS, may_change=["$C/out/manifest.json"],
     timeout=60, why="--shards inside an object folder of --out would be shipped inside that object: refused.")
case("p41-make-kill9-then-resume-with-shards", "signal",
     killed(f'{MK} --out "$C/out" --objects 3 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet', 6)
     + f'{MK} --out "$C/out" --objects 3 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet '
       '--shards "$C/sh" && ' + complete("out", 3) + " && " + index_objects("sh", 3),
     expect="ok", may_change=OUT + ["$C/sh", "$C/sh/*"], timeout=120,
     why="A render killed with SIGKILL then run again with --shards resumes, completes the 3 objects and exports "
         "all 3 (no half-written object shipped or missing).")
case("p41-make-kill9-then-overwrite-other-seed", "signal",
     killed(f'{MK} --out "$C/out" {TINY}', 10)
     + f'{MK} --out "$C/out" --overwrite --seed 7 {TINY} && ' + complete("out", 1)
     + " && $PY -c \"import json,sys; sys.exit(0 if json.load(open('out/manifest.json'))['config']['seed'] == 7 "
       "else 'FAULT: seed not 7')\"",
     expect="ok", may_change=OUT, timeout=120,
     why="After a killed run (its lock owner dead), --overwrite with another seed starts afresh: complete, seed 7.")

# ============================================================================ wildgen.make: resume after hand edits
case("p41-make-resume-user-notes-in-next-object-folder", "writer",
     RES + " --objects 4; r=$?; test -f out/00003.data/notes.txt || { echo 'FAULT: notes.txt deleted'; exit 0; }; "
     "exit $r", expect="either", setup=OUTDS + "mkdir out/00003.data; echo 'my notes' > out/00003.data/notes.txt",
     may_change=["$C/out/manifest.json", "$C/out/0000[0-2].data", "$C/out/0000[0-2].data/*",
                 "$C/out/0000[0-2].data/*/*", "$C/out/00003.data/[!n]*", "$C/out/00003.data/*/*", "$C/out/.*"],
     timeout=110,
     why="A folder 00003.data the manifest does not list holds the user's notes.txt: the resume refuses naming it "
         "or renders around it; notes.txt is never deleted without --overwrite.")
case("p41-make-resume-done-mask-deleted", "input",
     RES + "; r=$?; [ $r != 0 ] || test -s out/00001.data/mask.png || { echo 'FAULT: exit 0, mask still missing'; "
     "exit 0; }; exit $r", expect="either", names=[], setup=OUTDS + "rm out/00001.data/mask.png",
     may_change=OUT, timeout=110,
     why="An object recorded done whose mask.png was deleted is re-rendered or refused naming it; never exit 0 with "
         "the dataset still missing the mask.")
case("p41-make-resume-manifest-nul-bytes", "input", RES + " --objects 4", names=["manifest.json"],
     setup=OUTDS + "n=$(stat -c %s out/manifest.json); head -c $n /dev/zero > out/manifest.json",
     timeout=60,
     why="A manifest of NUL bytes (a crash before the data reached disk) is refused naming manifest.json; the "
         "object folders are not deleted or re-rendered over.")
case("p41-make-resume-manifest-truncated", "input", RES + " --objects 4", names=["manifest.json"],
     setup=OUTDS + "n=$(stat -c %s out/manifest.json); head -c $((n/2)) out/manifest.json > m; mv m out/manifest.json",
     timeout=60, why="A manifest cut in half is refused naming manifest.json, nothing rendered over the objects.")
case("p41-make-overwrite-keeps-users-thesis", "writer",
     f'{MK} --out "$C/out" --overwrite {TINY}; r=$?; cmp out/thesis.tex thesis.bak || '
     "{ echo 'FAULT: thesis.tex changed'; exit 0; }; exit $r", expect="either",
     setup="mkdir out; echo 'my thesis' > out/thesis.tex; cp out/thesis.tex thesis.bak",
     may_change=["$C/out/0*", "$C/out/0*/*", "$C/out/0*/*/*", "$C/out/manifest.json", "$C/out/.*", "$C/out/preview*"],
     timeout=110,
     why="--overwrite deletes the dataset (manifest and object folders), not a user's other files: thesis.tex "
         "stays, or the folder is refused as not a dataset.")

# ============================================================================ wildgen.make: --ray
case("p41-make-ray-empty-string", "input", f'{MK} --out "$C/out" --ray "" {TINY}', names=["--ray"], timeout=60,
     why="An empty --ray address is refused naming --ray (not taken as 'auto' and a local cluster started).")
case("p41-make-ray-scheme-without-host", "input", f'{MK} --out "$C/out" --ray "ray://" {TINY}', names=["--ray"],
     timeout=60, why="ray:// with no host is refused naming --ray at once, no connection attempt that hangs.")
case("p41-make-ray-dashboard-url", "input", f'{MK} --out "$C/out" --ray "http://127.0.0.1:8265" {TINY}',
     names=["--ray"], timeout=60,
     why="The dashboard's http:// URL is not a Ray address: refused naming --ray, no hang.")
case("p41-make-ray-host-port-not-a-number", "input", f'{MK} --out "$C/out" --ray "127.0.0.1:abc" {TINY}',
     names=["--ray"], timeout=60, why="A port that is not a number is refused naming --ray.")

# ============================================================================ wildgen.sensor
case("p41-sensor-data-one-object-folder", "input", SEN + ' --data "$F/data/00000.data" --sensor phone --out "$C/s"',
     names=["--data"], may_change=["$C/s", "$C/s/*", "$C/s/*/*"], timeout=60,
     why="--data naming one object folder (not the dataset) is refused naming --data, not an empty conversion.")
case("p41-sensor-image-dangling-link", "input", SEN + ' --data "$C/d" --sensor phone --out "$C/s"',
     names=["L001"], setup=DS + "rm d/00000.data/L001.png; ln -s /nonexistent/L001.png d/00000.data/L001.png",
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"],
     why="An image replaced by a dangling link is named in one line (object and file), no traceback.")
case("p41-sensor-radiance-of-another-object", "input", SEN + ' --data "$C/d" --sensor phone --out "$C/s"',
     expect="either", names=[], setup=DS + "cp d/00001.data/aux/radiance_000.exr d/00000.data/aux/radiance_000.exr",
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"],
     why="A radiance map swapped in from another object: refused naming it (checksum), or converted; never a "
         "traceback.")
case("p41-sensor-kill9-then-rerun", "signal",
     killed(SEN + ' --data "$F/data8" --sensor webcam --out "$C/s"', 4)
     + SEN + ' --data "$F/data8" --sensor webcam --out "$C/s"; r=$?; [ $r != 0 ] || ' + complete("s", 3)
     + "; exit $r", expect="either", names=[], may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"], timeout=120,
     why="A conversion killed with SIGKILL then run again: completes (all 3 objects) or is refused in one line "
         "naming --out/--overwrite; never exit 0 on a half-converted dataset.")
case("p41-sensor-out-unicode-spaces", "exit0",
     SEN + ' --data "$F/data" --sensor phone --out "$C/my data/réglage ✓" && ' + complete("my data/réglage ✓"),
     expect="ok", may_change=["$C/my data", "$C/my data/*", "$C/my data/*/*", "$C/my data/*/*/*", "$C/my data/*/*/*/*"],
     why="An --out path with spaces and non-ASCII letters is an ordinary folder: the conversion completes.")

# ============================================================================ wildgen.export
case("p41-export-out-holds-export-of-another-dataset", "writer", EX + ' --data "$F/data8" --out "$C/sh"',
     names=["--out"], setup='cp -r "$F/shards" sh',
     why="--out holding the export of another dataset is replaced only with --overwrite: refused naming --out.")
case("p41-export-kill9-then-rerun", "signal",
     killed(EX + ' --data "$F/data8" --out "$C/sh" --aux', 3)
     + EX + ' --data "$F/data8" --out "$C/sh" --aux; r=$?; [ $r != 0 ] || ' + index_objects("sh", 3) + "; exit $r",
     expect="either", names=[], may_change=["$C/sh", "$C/sh/*"], timeout=120,
     why="An export killed with SIGKILL then run again completes with every object listed, or is refused naming "
         "--out/--overwrite; never exit 0 with an index that misses objects.")
case("p41-export-object-failed-in-manifest", "input",
     EX + ' --data "$C/d" --out "$C/sh"; r=$?; [ $r != 0 ] || ' + index_objects("sh", 2) + "; exit $r",
     expect="either", names=[], setup=DS + manifest("d", "m['objects'][1]['status'] = 'failed'"),
     may_change=["$C/sh", "$C/sh/*"],
     why="An object the manifest records as failed is not exported (2 objects) or the dataset is refused naming it.")
case("p41-export-unlisted-object-link", "input",
     EX + ' --data "$C/d" --out "$C/sh"; r=$?; [ $r != 0 ] || ' + index_objects("sh", 3) + "; exit $r",
     expect="either", names=[], setup=DS + "ln -s 00000.data d/00003.data",
     may_change=["$C/sh", "$C/sh/*"],
     why="A folder 00003.data the manifest does not list (a link to 00000) is not exported twice: 3 objects, or "
         "refused naming it.")

# ============================================================================ wildgen.preview
case("p41-preview-one-object-folder", "input", PV + ' "$F/data/00000.data" --out "$C/pv"', expect="either",
     may_change=["$C/pv", "$C/pv/*"], timeout=60,
     why="DIR naming one object folder: previewed as one object or refused naming it; no traceback.")
case("p41-preview-empty-folder", "input", PV + ' "$F/empty" --out "$C/pv"', names=["empty"], timeout=60,
     why="An empty folder holds no object: refused naming it, no empty contact sheet written.")
case("p41-preview-out-an-object-folder", "writer", PV + ' "$C/d" --out "$C/d/00001.data"', names=["--out"],
     setup=DS, timeout=60,
     why="--out naming an object folder of DIR would plant sheets among its images: refused naming --out.")
case("p41-preview-stats-on-shards", "input", PV + ' "$F/shards" --stats --out "$C/pv"', names=["shards"],
     timeout=60, why="A folder of shards is not a dataset folder: refused naming it (and --stats), no traceback.")

# ============================================================================ gpu_session: the carried archives
case("p41-relay-site-marker-a-folder", "archive", PROBE + nosite(), names=["--work"],
     setup=GOOD_SITE + "mkdir -p w/.site.unpacked; echo mine > w/.site.unpacked/keep.txt",
     may_change=["$C/o", "$C/o/*"], timeout=90,
     why="A folder where the pack's marker goes (.site.unpacked, a user's) is refused in one line, not an "
         "IsADirectoryError traceback; keep.txt stays.")
case("p41-relay-assets-marker-a-folder", "archive", PROBE + left("$C/w/assets", "--work/assets left behind") + " "
     "&& true", names=["--work"], setup=GOOD_SITE + mktar("c/assets.tar.xz", "add(tar, 'assets/meshes/m.obj', open("
     "os.environ['F'] + '/assets/meshes/sphere/sphere.obj', 'rb').read())")
     + "mkdir -p w/.assets.unpacked; echo mine > w/.assets.unpacked/keep.txt",
     may_change=["$C/o", "$C/o/*"], timeout=90,
     why="A folder where the assets' marker goes (.assets.unpacked, holding a user's file) is refused in one line "
         "naming it; nothing of the pack stays and keep.txt is untouched.")
case("p41-relay-site-marker-link-to-users-file", "archive", PROBE + nosite(), names=["--work"],
     setup=GOOD_SITE + "mkdir w; echo mine > victim.txt; ln -s \"$C/victim.txt\" w/.site.unpacked",
     may_change=SESS_CHANGE, timeout=90,
     why="A marker that is a link to a user's file: the link may go, the file it points to is never written.")
case("p41-relay-site-pax-path-with-nul", "archive", PROBE + nosite(), names=["site.tar.xz"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                 "add(tar, 'pkg/a.py', b'x', pax={'path': 'pkg/a\\x00/../../escape_p41.py'})"),
     may_change=["$C/o", "$C/o/*"],
     why="A PAX path holding a NUL byte is refused naming site.tar.xz before anything is unpacked (no ValueError "
         "traceback).")
case("p41-relay-site-pax-mtime-nan", "archive", PROBE + nosite(), expect="refuse", names=[], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'', pax={'mtime': 'nan'})"),
     may_change=["$C/o", "$C/o/*"],
     why="A PAX mtime of 'nan' is refused naming the archive (or the pack accepted and the probe's --assets "
         "refused); one line either way, nothing left in --work.")
case("p41-relay-site-pax-size-negative", "archive", PROBE + nosite(), names=["site.tar.xz"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, 'pkg/b.py', b'x', pax={'size': '-5'})"),
     may_change=["$C/o", "$C/o/*"], why="A negative PAX size is a damaged archive: refused naming site.tar.xz.")
case("p41-relay-site-file-member-trailing-slash", "archive", PROBE + nosite(), names=[], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, 'pkg/mod.py/', b'print(1)')"),
     may_change=["$C/o", "$C/o/*"],
     why="A regular-file member whose name ends in '/' is refused in one line (or unpacked as a file and the probe "
         "refused); never a traceback, nothing left.")
case("p41-relay-site-member-name-newline", "archive", PROBE + nosite(), names=["site.tar.xz"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, 'pkg/a\\nb.py', b'')"),
     may_change=["$C/o", "$C/o/*"],
     why="A member name holding a newline is not a name the pack writes: refused naming site.tar.xz.")
case("p41-relay-site-bz2-under-xz-name", "archive", PROBE + nosite(), names=[], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')", mode="w:bz2"),
     may_change=["$C/o", "$C/o/*"],
     why="A bzip2 tar named .tar.xz: refused naming it or read by content and the probe refused; one line, "
         "nothing left.")
case("p41-relay-site-gnu-longname-accepted", "archive", PROBE + nosite(), names=["--assets"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, 'pkg/' + 'd' * 150 + '/' + 'f' * 120 "
                 "+ '.py', b'')", fmt="tarfile.GNU_FORMAT"),
     may_change=SESS_CHANGE,
     why="A GNU-format archive with a long (but legal) member name is a valid pack: unpacked, then the probe's "
         "--assets refused, and what was unpacked is taken back.")
case("p41-relay-site-file-mode-0", "archive", PROBE + nosite(), names=["--assets"], timeout=90,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'', mode=0)\nadd(tar, 'pkg/x.py', b'y', mode=0)"),
     may_change=SESS_CHANGE,
     why="Members of mode 000 are unpacked readable (data filter) and taken back after the refusal: no "
         "PermissionError while cleaning up, nothing left.")
case("p41-relay-site-20000-members", "archive", PROBE + nosite(), names=["--assets"], timeout=115,
     setup=mktar("c/site.tar.xz", "for i in range(20000):\n    add(tar, f'pkg/m{i}.py', b'')"),
     may_change=SESS_CHANGE,
     why="20000 small members unpack within limits, are checked without hanging, and are all removed again when "
         "the probe's --assets is refused.")
case("p41-relay-site-a-link-to-an-archive-elsewhere", "archive", PROBE + nosite(), names=[], timeout=90,
     setup=mktar("elsewhere/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')") + "mkdir c; ln -s ../elsewhere/site.tar.xz c/",
     may_change=SESS_CHANGE,
     why="site.tar.xz as a link to an archive elsewhere: followed or refused naming it; one line, nothing left.")
case("p41-relay-carry-equals-work", "writer", SESS.replace('--work "$C/w"', '--work "$C/c"') + ' --assets "$C/none"',
     names=[], setup=GOOD_SITE, may_change=["$C/o", "$C/o/*", "$C/c/site", "$C/c/site/*", "$C/c/site/*/*",
                                           "$C/c/.site.unpacked"], timeout=90,
     why="--work equal to --carry unpacks the pack beside its own archive: refused naming --work, or unpacked and "
         "the probe refused; site.tar.xz never changes.")

# ============================================================================ gpu_session: flags
case("p41-gs-rehearsal-variant-cuda", "input", SESS_PLAIN + " --variant cuda_ad_rgb" + left("$C/w/data", "rendered"),
     names=["--variant"], may_change=SESS_CHANGE, timeout=90,
     why="A CPU rehearsal rendering with cuda_ad_rgb contradicts itself: refused naming --variant before rendering.")
case("p41-gs-minutes-equal-to-reserve", "input",
     SESS_PLAIN.replace("--minutes 1", "--minutes 0.5") + left("$C/w/data", "rendered"), names=["--minutes"],
     may_change=SESS_CHANGE, timeout=60,
     why="A budget of 30 s with a 30 s reserve leaves nothing: refused naming --minutes before anything runs.")
case("p41-gs-images-2", "input", SESS_PLAIN.replace("--images 3", "--images 2") + left("$C/w/data", "rendered"),
     names=["--images"], may_change=SESS_CHANGE, timeout=60,
     why="Two images per object determine no normal: refused naming --images (the help's 'at least 3').")

# ============================================================================ gpu_session --pack
case("p41-pack-two-versions-of-mitsuba", "input", GS + ' --pack "$C/p" --wheels "$C/whl" --assets none',
     names=["--wheels"], setup=WHEELS + py("""
        import zipfile
        with zipfile.ZipFile("whl/mitsuba-3.8.0-cp312-cp312-manylinux_2_28_x86_64.whl", "w") as z:
            z.writestr("mitsuba/__init__.py", "# old")
        """), may_change=["$C/p", "$C/p/*"], timeout=60,
     why="Two versions of mitsuba unpack over each other in one site: refused naming --wheels and both wheels.")
case("p41-pack-into-the-wheels-folder", "writer", GS + ' --pack "$C/whl" --wheels "$C/whl" --assets none',
     names=["--pack"], setup=WHEELS, timeout=60,
     why="--pack equal to --wheels writes the pack among the wheels it reads: refused naming --pack; the wheels stay.")
case("p41-pack-wheel-zip-bomb", "archive", GS + ' --pack "$C/p" --wheels "$C/whl" --assets none',
     names=["mitsuba"], setup=WHEELS + py("""
        import zipfile
        with zipfile.ZipFile("whl/mitsuba-3.9.1-cp312-cp312-manylinux_2_28_x86_64.whl", "w",
                             zipfile.ZIP_DEFLATED) as z:
            z.writestr("mitsuba/__init__.py", "")
            with z.open("mitsuba/evil_zeros.bin", "w", force_zip64=True) as f:
                block = bytes(1 << 24)
                for _ in range(72):
                    f.write(block)
        """), may_change=["$C/p", "$C/p/*"], timeout=120,
     why="A wheel of a few MiB that inflates to 1.1 GiB (beyond what a pack may unpack to) is refused naming the "
         "wheel when packing, not packed to be refused on the GPU machine.")
case("p41-pack-wheel-dist-info-only", "input", GS + ' --pack "$C/p" --wheels "$C/whl" --assets none',
     expect="either", setup=WHEELS + py("""
        import zipfile
        with zipfile.ZipFile("whl/mitsuba-3.9.1-cp312-cp312-manylinux_2_28_x86_64.whl", "w") as z:
            z.writestr("mitsuba-3.9.1.dist-info/METADATA", "Name: mitsuba")
        """), may_change=["$C/p", "$C/p/*"], timeout=60,
     why="A mitsuba wheel holding no package: refused naming it, or packed; never a traceback.")

# ============================================================================ orchestrate.train_recipe
case("p41-recipe-work-inside-assets", "writer",
     RCW.replace("--assets none", '--assets "$C/a"').replace('--work "$C/w"', '--work "$C/a/w"')
     + left("$C/a/w", "--work created inside --assets"), names=["--work"], setup='cp -r "$F/assets" a', timeout=60,
     why="--work inside --assets would make its renders part of the asset split: refused naming --work.")
case("p41-recipe-train-seed-negative", "input", RCW + " --train-seed=-5" + left("$C/w", "--work created"),
     names=["--train-seed"], may_change=["$C/w", "$C/w/*"], timeout=60,
     why="A negative seed is refused naming --train-seed (as wildgen.make's --seed is).")
case("p41-recipe-train-seed-beyond-64-bit", "input",
     RCW + " --train-seed 5000,18446744073709551616" + left("$C/w", "--work created"), names=["--train-seed"],
     may_change=["$C/w", "$C/w/*"], timeout=60, why="A seed beyond 64 bits is refused naming --train-seed.")
case("p41-recipe-init-from-dangling-link", "input", RCW + ' --init-from "$C/w.safetensors"'
     + left("$C/w", "--work created"), names=["--init-from"], setup="ln -s /nonexistent/x.safetensors w.safetensors",
     timeout=60, why="A dangling link as weights is refused naming --init-from before --work is made.")
case("p41-recipe-minutes-0", "input", RCW + " --minutes 0 --help", expect="ok", timeout=60,
     why="--minutes 0 means no limit (documented): taken; --help only, so the case does not run the whole recipe.")
case("p41-recipe-work-a-fifo", "input", RCW, names=["--work"], setup="mkfifo w", timeout=60,
     why="--work naming a pipe is refused in one line; no hang.")

# ============================================================================ orchestrate.demo
case("p41-demo-res-huge", "input", DEMO + ' --out "$C/d" --res 100000' + left("$C/d/data", "rendered"),
     names=["--res"], may_change=["$C/d", "$C/d/*"], timeout=60,
     why="A 100000-px square is refused naming the demo's --res before anything is rendered.")
case("p41-demo-out-a-file", "input", DEMO + ' --out "$C/f"', names=["--out"], setup="echo mine > f", timeout=60,
     why="--out naming a plain file is refused naming --out; the file stays.")
case("p41-demo-checkpoint-header-length-huge", "weights",
     DEMO + ' --out "$C/d" --checkpoint "$C/w.safetensors" --objects 1 --images 4 --res 32 --spp 1'
     + left("$C/d/data", "rendered before reading the checkpoint"), names=["--checkpoint"],
     setup=py("""
        import struct
        open("w.safetensors", "wb").write(struct.pack("<Q", 1 << 60) + b"{}")
        """) + 'cp "$F/run/final.json" w.json\n', may_change=["$C/d", "$C/d/*"], timeout=60,
     why="A safetensors header claiming 2^60 bytes is refused naming --checkpoint before rendering (no MemoryError).")
case("p41-demo-checkpoint-dangling-link", "input",
     DEMO + ' --out "$C/d" --checkpoint "$C/w.safetensors"' + left("$C/d/data", "rendered"),
     names=["--checkpoint"], setup="ln -s /nonexistent/w.safetensors w.safetensors", may_change=["$C/d", "$C/d/*"],
     timeout=60, why="A dangling link as checkpoint is refused naming --checkpoint before rendering.")

# ============================================================================ orchestrate.docs (on a copy)
STALE = py("""
    p = "repo/docs/surface.md"; s = open(p).read()
    i = s.index("<!-- BEGIN generated:flags:orchestrate.surface -->")
    i = s.index("\\n", i) + 1
    open(p, "w").write(s[:i] + "stale line\\n" + s[i:])
    """)
case("p41-docs-page-with-bom", "input", DOCS + " --check", expect="either", names=[], setup=REPO_COPY
     + "printf '\\xef\\xbb\\xbf' | cat - repo/docs/surface.md > s && mv s repo/docs/surface.md", timeout=110,
     why="A page saved with a UTF-8 BOM: current or reported stale naming it; no traceback.")
case("p41-docs-page-hard-linked-outside", "writer",
     DOCS + "; r=$?; cmp \"$C/outside.md\" \"$C/outside.bak\" || { echo 'FAULT: written through a hard link'; exit 3; }; exit $r",
     expect="ok", setup=REPO_COPY + STALE + "ln repo/docs/surface.md outside.md; cp outside.md outside.bak",
     may_change=REPO_CHANGE, timeout=110,
     why="Regenerating a stale page that is hard-linked to a file outside the tree replaces the page, never writes "
         "the outside file.")
case("p41-docs-two-writers", "concurrency",
     both(DOCS, DOCS, 'cd "$C/repo" && PYTHONPATH="$C/repo" $PY -m orchestrate.docs --check'), expect="ok",
     setup=REPO_COPY + STALE, may_change=REPO_CHANGE + ["$C/a.log", "$C/b.log"], timeout=120,
     why="Two regenerations at once of a stale tree: one waits or is refused, and the tree ends current "
         "(--check passes), no half-written page.")
case("p41-docs-nul-bytes-in-page", "input", DOCS + " --check", expect="either", names=[],
     setup=REPO_COPY + "printf '\\0\\0\\0' >> repo/docs/results.md", timeout=110,
     why="NUL bytes at the end of a page (a crash): reported naming results.md or found current; no traceback.")
