"""Sweep 37, part c: the GENERATOR and RELAY side (wildgen.make / preview / sensor / export, orchestrate.gpu_session
and its relay pack, orchestrate.train_recipe, orchestrate.demo, orchestrate.docs).

Mechanisms probed: untrusted archives (site.tar.xz / assets.tar.xz) never write outside their target and nothing is
unpacked before the arguments are checked; --help never touches a file; one writer per folder (real concurrency,
started with `&` and `wait`); late refusals (a bad value refused only after minutes of rendering); interrupts
(SIGINT / SIGTERM at start-up and mid-run) leave no traceback and a state the same command resumes; --overwrite
never removes an input that happens to lie in the folder it replaces; messages name the right flag and file.

Cases whose command adds its own check print a line starting with `FAULT:` and exit so that the harness flags it
(exit 0 where a refusal is expected, non-zero where success is expected).
"""
from __future__ import annotations

import textwrap

TINY = "--objects 1 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet"
"""The smallest render wildgen.make takes (one 16-px object, 2 images)."""
TINY_RAY = "--objects 1 --images 2 --res 16 --spp 1 --gt-spp 1 --quiet"
"""TINY without --workers (--ray schedules by its CPUs; the two are exclusive)."""
MK = "$PY -m wildgen.make"
GS = "$PY -m orchestrate.gpu_session"
SESS = (GS + ' --out "$C/o" --work "$C/w" --carry "$C/c" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1'
        " --check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
"""A CPU rehearsal of a session on the pack in $C/c, as small as it goes (bounded by its --minutes)."""
SESS_STOP = SESS + " --variant cuda_ad_rgb"
"""SESS refused right after the pack is unpacked (no CUDA here): what was unpacked can be looked at."""
RC = "$PY -m orchestrate.train_recipe"
DEMO = "$PY -m orchestrate.demo"
WHEELS = r"""mkdir -p whl
$PY - <<'EOF'
import zipfile
for name in ("mitsuba-3.9.1", "drjit-1.5.0"):
    with zipfile.ZipFile(f"whl/{name}-cp312-cp312-manylinux_2_28_x86_64.whl", "w") as z:
        z.writestr(name.split("-")[0] + "/__init__.py", "")
EOF
"""
"""Setup: whl/, two tiny wheels that pass the pack's name and version checks."""
LIB = r"""mkdir -p assets/meshes assets/hdri
m=$(ls -d "$F"/assets/meshes/*/*.obj | head -1); h=$(ls "$F"/assets/hdri/* | head -1)
for i in 1 2 3 4; do cp -r "$m" "assets/meshes/m$i.${m##*.}"; cp "$h" "assets/hdri/h$i.${h##*.}"; done
"""
"""Setup: assets/, a library of 4 meshes and 4 HDR maps (copies of the fixture's), enough to split."""
REPO_COPY = r"""mkdir repo
(cd "$REPO" && git ls-files -z --cached --others --exclude-standard | tar --null -T - --ignore-failed-read -cf - 2>/dev/null) | tar -xf - -C repo
"""
"""Setup: repo/, a copy of the working tree (orchestrate.docs writes into the tree it runs from)."""
DOCS = 'cd "$C/repo" && PYTHONPATH="$C/repo" $PY -m orchestrate.docs'


def mktar(path: str, body: str) -> str:
    """Setup: the xz tar `path` (relative to $C) written by `body` (Python, with `tar` open and `add(tar, name,
    data=b'', kind=None, link='', mode=0o644)`; kind a tarfile type constant for links and special files)."""
    return (f'mkdir -p "$(dirname {path})"\n$PY - <<\'EOF\'\nimport io, os, tarfile\n'
            "def add(tar, name, data=b'', kind=None, link='', mode=0o644, **pax):\n"
            "    ti = tarfile.TarInfo(name); ti.mode = mode\n"
            "    if pax: ti.pax_headers = pax\n"
            "    if kind is None:\n"
            "        ti.size = len(data); tar.addfile(ti, io.BytesIO(data)); return\n"
            "    ti.type = kind; ti.linkname = link; tar.addfile(ti)\n"
            f"with tarfile.open({path!r}, 'w:xz', format=tarfile.PAX_FORMAT) as tar:\n"
            + textwrap.indent(body.strip("\n"), "    ") + "\nEOF\n")


GOOD_SITE = mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')")


def left(path: str, what: str) -> str:
    """Command tail: a refusal that left `path` behind exits 0 with a FAULT line (flagged exit0)."""
    return (f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r')


def made(path: str, what: str) -> str:
    """Command tail for --help (expected exit 0): `path` created by it is a FAULT (exit 3, flagged failed)."""
    return (f'; r=$?; if [ -e "{path}" ]; then echo "FAULT: {what}"; exit 3; fi; exit $r')


def both(cmd_a: str, cmd_b: str, after: str = "") -> str:
    """Two commands started at once; ok when at least one succeeded and `after` holds; both outputs printed."""
    return (f"( {cmd_a} ) > a.log 2>&1 & p1=$!; ( {cmd_b} ) > b.log 2>&1 & p2=$!; wait $p1; r1=$?; wait $p2; r2=$?; "
            f'cat a.log b.log; echo "rc $r1 $r2"; [ $r1 = 0 ] || [ $r2 = 0 ] || exit 1; {after or "true"}')


COMPLETE = ("$PY -c \"import json,sys; m=json.load(open('out/manifest.json')); "
            "sys.exit(0 if m.get('complete') else 'FAULT: out/manifest.json not complete')\"")

CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


OUT = ["$C/out", "$C/out/*"]

# ============================================================================ wildgen.make: odd values
case("c37-make-level-0", "input", f'{MK} --out "$C/out" --level 0', names=["--level"],
     why="Levels run 1-5: 0 is refused naming --level before anything is written.")
case("c37-make-level-fraction", "input", f'{MK} --out "$C/out" --level 2.5', names=["--level"],
     why="A level is a whole number: 2.5 is refused naming --level, not rounded.")
case("c37-make-focal-nan", "input", f'{MK} --out "$C/out" --camera perspective --focal nan-300', names=["--focal"],
     why="A focal range holding nan must be refused naming --focal (nan passes every comparison).")
case("c37-make-focal-inf", "input", f'{MK} --out "$C/out" --camera perspective --focal 15-inf', names=["--focal"],
     why="An infinite focal length gives a zero field of view and a camera at infinity: refused naming --focal.")
case("c37-make-focal-three-numbers", "input", f'{MK} --out "$C/out" --camera perspective --focal 15-300-500',
     names=["--focal"], why="A-B is two numbers: a third is refused naming --focal, not silently dropped.")
case("c37-make-focal-negative", "input", f'{MK} --out "$C/out" --camera perspective --focal=-5-10',
     names=["--focal"], why="A negative focal length (given with = so that it is not read as a flag) is refused.")
case("c37-make-focal-exponent-overflow", "input", f'{MK} --out "$C/out" --camera perspective --focal 1e999-2e999',
     names=["--focal"], why="Numbers that overflow to inf when parsed are refused naming --focal.")
case("c37-make-focal-single-number", "input", f'{MK} --out "$C/out" --camera perspective --focal 50 {TINY}',
     expect="either", names=["--focal"], may_change=OUT,
     why="One number instead of A-B: either read as 50-50 or refused naming --focal; never a traceback.")
case("c37-make-focal-1mm-render", "engine", f'{MK} --out "$C/out" --camera perspective --focal 1-1 {TINY}',
     expect="either", may_change=OUT, timeout=110,
     why="At 1 mm the field of view is 173.6 deg and the camera almost touches the object: render, skip the object "
         "with its reason, or refuse naming --focal; never a traceback or non-finite camera.")
case("c37-make-focal-5000mm-render", "engine", f'{MK} --out "$C/out" --camera perspective --focal 5000-5000 {TINY}',
     expect="either", may_change=OUT, timeout=110,
     why="At 5000 mm (0.4 deg) the camera stands ~140 radii away: float32 precision must not crash the render.")
case("c37-make-cluster-8-at-16px", "engine", f'{MK} --out "$C/out" --cluster 8-8 {TINY}', expect="either",
     may_change=OUT, timeout=110,
     why="Eight objects slid together in 16 x 16 px: rendered or skipped with a reason, no traceback.")
case("c37-make-cluster-fraction", "input", f'{MK} --out "$C/out" --cluster 1.5-3', names=["--cluster"],
     why="Object counts are whole numbers: 1.5-3 is refused naming --cluster.")
case("c37-make-detail-strength-nan", "input", f'{MK} --out "$C/out" --detail 1 --detail-strength nan-20',
     names=["--detail-strength"], why="nan in a degree range is refused naming --detail-strength.")
case("c37-make-seed-beyond-64-bit", "engine", f'{MK} --out "$C/out" --seed 18446744073709551617 {TINY}',
     expect="either", names=["--seed"], may_change=OUT, timeout=110,
     why="A seed beyond 64 bits: rendered (object i draws from (seed, i)) or refused naming --seed; never an "
         "OverflowError traceback from the sampler seed.")
case("c37-make-exposure-level-0", "input", f'{MK} --out "$C/out" --exposure-level 0 {TINY}', names=["--exposure-level"],
     may_change=OUT, why="An exposure mapping the percentile to 0 makes every image black: refused naming the flag.")
case("c37-make-exposure-percentile-0", "engine", f'{MK} --out "$C/out" --exposure-percentile 0 {TINY}',
     expect="either", names=["--exposure-percentile"], may_change=OUT, timeout=110,
     why="The 0th percentile of the masked pixels may be 0 (an unlit pixel): the exposure factor would be infinite; "
         "refused naming the flag or handled, never non-finite images or a traceback.")
case("c37-make-margin-almost-1", "engine", f'{MK} --out "$C/out" --margin 0.999 {TINY}', expect="either",
     may_change=OUT, timeout=110,
     why="A margin leaving the object a speck of a pixel: skipped with its reason or refused, no traceback.")
case("c37-make-shard-encoding-without-shards", "input", f'{MK} --out "$C/out" --shard-encoding decoded {TINY}',
     names=["--shard-encoding"], may_change=OUT,
     why="--shard-encoding does nothing without --shards: refused as a flag that would be ignored, before rendering.")
case("c37-make-shards-a-fifo", "input", f'{MK} --out "$C/out" --shards "$C/sh" {TINY}', names=["--shards"],
     setup="mkfifo sh", timeout=60,
     why="--shards naming a pipe is refused before the render (checked before, not after minutes of work), no hang.")
case("c37-make-out-with-newline", "message", f'{MK} --out "$C/a\nb" {TINY}', expect="either",
     may_change=["$C/a*", "$C/a*/*"], timeout=110,
     why="A folder name with a newline: rendered, or refused in one line (the name quoted, not split over lines).")
case("c37-make-help-touches-nothing", "exit0", f'{MK} --help --out "$C/newout" --overwrite >/dev/null'
     + made("$C/newout", "--help created --out"), expect="ok",
     why="--help prints and exits 0 without creating --out (or deleting anything with --overwrite).")

# ============================================================================ wildgen.make: asset libraries
case("c37-make-assets-mesh-fifo", "input", f'{MK} --out "$C/out" --assets "$C/assets" --shapes mesh {TINY}',
     names=["m.ply"], setup=r"""mkdir -p assets/meshes assets/hdri; cp "$F"/assets/hdri/* assets/hdri/
mkfifo assets/meshes/m.ply""", timeout=60,
     why="Every asset is decoded before rendering: a pipe under a mesh's name is named, never read forever.")
case("c37-make-assets-mesh-link-dev-zero", "input",
     f'{MK} --out "$C/out" --assets "$C/assets" --shapes mesh {TINY}', names=["z.ply"],
     setup=r"""mkdir -p assets/meshes assets/hdri; cp "$F"/assets/hdri/* assets/hdri/
ln -s /dev/zero assets/meshes/z.ply""", timeout=60,
     why="A mesh that is a link to /dev/zero (an endless device) is named as not a regular file, not read.")
case("c37-make-assets-mesh-folder-link-to-root", "input",
     f'{MK} --out "$C/out" --assets "$C/assets" --shapes mesh {TINY}', names=["--assets"],
     setup=r"""mkdir -p assets/meshes assets/hdri; cp -r "$F"/assets/meshes/* assets/meshes/; cp "$F"/assets/hdri/* assets/hdri/
ln -s / assets/meshes/everything""", timeout=100,
     why="A mesh folder that is a link to / would make the asset scan walk the whole file system: refused naming "
         "the link (or skipped), within a bounded time, never a hang.")
case("c37-make-assets-mesh-dangling-link", "input", f'{MK} --out "$C/out" --assets "$C/assets" {TINY}',
     names=["gone.ply"], setup=r"""mkdir -p assets/meshes assets/hdri; cp "$F"/assets/hdri/* assets/hdri/
cp -r "$F"/assets/meshes/* assets/meshes/; ln -s "$C/nowhere.ply" assets/meshes/gone.ply""", timeout=90,
     why="A dangling link among the meshes is named (a link to nothing), not a FileNotFoundError traceback.")
case("c37-make-assets-meshes-is-a-file", "input", f'{MK} --out "$C/out" --assets "$C/assets" {TINY}',
     expect="either", names=["meshes"], may_change=OUT,
     setup=r"""mkdir -p assets/hdri; cp "$F"/assets/hdri/* assets/hdri/; echo "not a folder" > assets/meshes""",
     timeout=110, why="assets/meshes a file: ignored (maps only) or refused naming it; never a NotADirectoryError.")
case("c37-make-assets-truncated-exr", "input",
     f'{MK} --out "$C/out" --assets "$C/assets" --lights hdri {TINY}', names=["cut.exr"],
     setup=r"""mkdir -p assets/hdri; head -c 300 "$F/data/00000.data/aux/radiance_000.exr" > assets/hdri/cut.exr""",
     timeout=90, why="An environment map cut short (an OpenEXR header without its data) is named before rendering.")
case("c37-make-assets-mesh-newline-name", "engine",
     f'{MK} --out "$C/out" --assets "$C/assets" --shapes mesh {TINY}', expect="either", may_change=OUT,
     setup=r"""mkdir -p assets/meshes assets/hdri; cp "$F"/assets/hdri/* assets/hdri/
m=$(ls -d "$F"/assets/meshes/*/*.obj | head -1); cp -r "$m" "assets/meshes/a
b.${m##*.}"
""", timeout=110,
     why="A mesh whose name holds a newline: rendered (scene.json keeps the name) or refused in one line naming it.")
case("c37-make-assets-inside-out-overwrite", "writer",
     f'{MK} --out "$C/out" --assets "$C/out/assets" --overwrite {TINY}', expect="either",
     may_change=["$C/out/manifest.json", "$C/out/0*", "$C/out/.*"], timeout=110,
     setup=f'{MK} --out "$C/out" {TINY}\ncp -r "$F/assets" out/assets',
     why="--assets lying inside --out, with --overwrite: the dataset may be replaced, the asset library the run "
         "reads never (refused naming --assets, or left byte for byte).")
case("c37-make-shards-inside-assets-link", "writer",
     f'{MK} --out "$C/out" --assets "$C/assets" --shards "$C/sh" {TINY}', names=["--shards"],
     setup='cp -r "$F/assets" assets; ln -s assets/hdri sh', timeout=90,
     why="--shards a link into --assets: refused before the render (the shards would be read as assets next time).")

# ============================================================================ wildgen.make: one writer, resume, interrupts
case("c37-make-two-at-once", "writer", both(f'{MK} --out "$C/out" {TINY}', f'{MK} --out "$C/out" {TINY}', COMPLETE),
     expect="ok", may_change=OUT, timeout=115,
     why="Two makes into one --out at the same moment: one renders, the other is refused ('another run holds') "
         "or resumes after it; the dataset ends complete, no traceback.")
case("c37-make-and-sensor-at-once", "writer",
     both(f'{MK} --out "$C/out" {TINY}', '$PY -m wildgen.sensor --data "$F/data" --sensor phone --out "$C/out" --quiet'),
     expect="ok", may_change=OUT, timeout=115,
     why="wildgen.make and wildgen.sensor into the same folder at once: one is refused in one line; the folder is "
         "never a mix of both (no traceback).")
case("c37-make-interrupt-then-resume", "writer",
     f'timeout -s INT 14 {MK} --out "$C/out" --objects 3 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet; '
     'r=$?; echo "first rc $r"; [ $r = 130 ] || [ $r = 0 ] || exit 1; '
     f'{MK} --out "$C/out" --objects 3 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet || exit 1; '
     'if ls -a out | grep -q "^\\.tmp-"; then echo "FAULT: temporary folders left"; exit 1; fi; ' + COMPLETE,
     expect="ok", may_change=OUT, timeout=118,
     why="Ctrl-C mid-run exits 130 without a traceback; the same command finishes the dataset, leaving no .tmp- folder.")
case("c37-make-interrupt-during-import", "message", f'timeout -s INT 2 {MK} --out "$C/out" {TINY}', expect="either",
     may_change=OUT, why="Ctrl-C while the command is still importing its modules: exit 130, no KeyboardInterrupt "
                         "traceback, no half-made --out.")
case("c37-make-term-mid-render", "message", f'timeout -s TERM 9 {MK} --out "$C/out" --objects 4 --images 2 --res 16 '
     '--spp 1 --gt-spp 1 --workers 2 --quiet', expect="either", may_change=OUT, timeout=60,
     why="SIGTERM with worker processes running: exit 143, workers gone (no leftover process), no traceback.")
case("c37-make-resume-truncated-normal", "writer",
     f'{MK} --out "$C/out" {TINY} && cmp out/00000.data/normal.tif keep.tif || '
     '{ echo "FAULT: normal.tif not rendered again as it was"; exit 1; }',
     expect="ok", may_change=OUT, timeout=110,
     setup=f'{MK} --out "$C/out" {TINY}\ncp out/00000.data/normal.tif keep.tif\n'
           'head -c 100 keep.tif > out/00000.data/normal.tif',
     why="Re-running the same command finds the object's checksum wrong and renders it again, byte for byte the "
         "same (determinism), instead of keeping or reporting a damaged dataset as complete.")
case("c37-make-resume-manifest-done-but-folder-gone", "writer", f'{MK} --out "$C/out" {TINY} && {COMPLETE}',
     expect="ok", may_change=OUT, timeout=110, setup=f'{MK} --out "$C/out" {TINY}\nrm -r out/00000.data',
     why="A manifest recording object 00000 done whose folder was removed: the same command renders it again.")
case("c37-make-resume-object-image-link-out", "writer", f'{MK} --out "$C/out" {TINY}', expect="either",
     may_change=OUT, timeout=110,
     setup=f'{MK} --out "$C/out" {TINY}\nmkdir elsewhere; mv out/00000.data/mask.png elsewhere/mask.png\n'
           'ln -s "$C/elsewhere/mask.png" out/00000.data/mask.png',
     why="An object's mask replaced by a link to the same bytes elsewhere: re-rendered or refused, and the file the "
         "link points to is never written through.")

# ============================================================================ wildgen.make: --ray addresses
case("c37-make-ray-port-out-of-range", "input", f'{MK} --out "$C/out" --ray 127.0.0.1:70000 {TINY_RAY}',
     names=["--ray", "70000"], timeout=60, why="A port above 65535 is refused at once naming --ray and the address.")
case("c37-make-ray-ipv6-nothing-listens", "input", f'{MK} --out "$C/out" --ray "[::1]:1" {TINY_RAY}', names=["--ray"],
     timeout=90, why="An IPv6 address where nothing listens is refused after a bounded wait, naming --ray.")
case("c37-make-ray-client-nothing-listens", "input", f'{MK} --out "$C/out" --ray ray://127.0.0.1:1 {TINY_RAY}',
     names=["--ray"], timeout=110,
     why="A Ray client address (ray://) where nothing listens is refused within the bounded wait, not Ray's minutes.")
case("c37-make-ray-silent-server", "input",
     r"""$PY -c "import socket,time; s=socket.socket(); s.bind(('127.0.0.1',0)); s.listen(8); open('port','w').write(str(s.getsockname()[1])); c=[s.accept() for _ in range(8)]; time.sleep(300)" & sp=$!
for i in $(seq 50); do [ -s port ] && break; sleep 0.1; done
""" + f'{MK} --out "$C/out" --ray "127.0.0.1:$(cat port)" {TINY_RAY}; r=$?; kill $sp; exit $r',
     names=["--ray"], timeout=115,
     why="A port that accepts the connection and never answers is refused within the bounded wait naming --ray.")
case("c37-make-ray-auto-env-unreachable", "input", f'RAY_ADDRESS=127.0.0.1:1 {MK} --out "$C/out" --ray auto {TINY_RAY}',
     names=["RAY_ADDRESS"], timeout=90,
     why="--ray auto joins RAY_ADDRESS first: an unreachable one is refused naming RAY_ADDRESS (the user never "
         "typed the address).")
case("c37-make-ray-address-trailing-space", "input", f'{MK} --out "$C/out" --ray "127.0.0.1:1 " {TINY_RAY}',
     names=["--ray"], timeout=90, why="An address with a trailing space is refused naming --ray, one line.")

# ============================================================================ wildgen.preview / sensor / export
DATA_COPY = 'cp -r "$F/data" d'
case("c37-preview-normal-link-dev-zero", "input", '$PY -m wildgen.preview "$C/d"', names=["00000"],
     setup=DATA_COPY + '\nrm d/00000.data/normal.tif; ln -s /dev/zero d/00000.data/normal.tif',
     may_change=["$C/d/preview", "$C/d/preview/*"], timeout=90,
     why="A normal map that is a link to /dev/zero: that object is named (not read forever), the others drawn, exit 1.")
case("c37-preview-dir-is-a-fifo", "input", '$PY -m wildgen.preview "$C/p"', names=["p"], setup="mkfifo p", timeout=60,
     why="A dataset argument that is a pipe is refused in one line naming it, no hang.")
case("c37-preview-out-link-into-object", "writer", '$PY -m wildgen.preview "$C/d" --out "$C/lnk"', names=["--out"],
     setup=DATA_COPY + '\nln -s "$C/d/00001.data" lnk', timeout=90,
     why="--out a link into one of the object folders it reads: refused (the sheets would join the object's files).")
case("c37-preview-two-at-once", "writer",
     both('$PY -m wildgen.preview "$C/d" --out "$C/pv"', '$PY -m wildgen.preview "$C/d" --out "$C/pv"',
          "test -s pv/overview.png"), expect="ok", setup=DATA_COPY, may_change=["$C/pv", "$C/pv/*"], timeout=110,
     why="Two previews into one folder at once: one draws, the other is refused in one line; overview.png whole.")
case("c37-preview-stats-scene-json-deeply-nested", "input", '$PY -m wildgen.preview "$C/d" --stats', names=["00001"],
     setup=DATA_COPY + "\n$PY -c \"open('d/00001.data/scene.json','w').write('['*100000 + ']'*100000)\"",
     may_change=["$C/d/preview", "$C/d/preview/*"], timeout=90,
     why="A scene.json nested 100000 deep: object 00001 named as unreadable (no RecursionError traceback), exit 1.")
case("c37-preview-help-touches-nothing", "exit0", '$PY -m wildgen.preview "$C/d" --help >/dev/null'
     + made("$C/d/preview", "--help created DIR/preview"), expect="ok", setup=DATA_COPY,
     why="--help writes no preview folder into the dataset.")
case("c37-sensor-seed-negative", "input", '$PY -m wildgen.sensor --data "$F/data" --sensor phone --out "$C/s" --seed=-3',
     names=["--seed"], why="A negative noise seed is refused naming --seed before anything is written.")
case("c37-sensor-radiance-fifo", "input", '$PY -m wildgen.sensor --data "$C/d" --sensor phone --out "$C/s" --quiet',
     names=["radiance_000.exr"], setup=DATA_COPY + '\nrm d/00000.data/aux/radiance_000.exr\n'
                                                  'mkfifo d/00000.data/aux/radiance_000.exr',
     may_change=["$C/s", "$C/s/*"], timeout=90,
     why="Checksums are verified first: a pipe under a radiance file's name is named, never hashed forever.")
case("c37-sensor-interrupt-then-overwrite", "writer",
     'timeout -s INT 6 $PY -m wildgen.sensor --data "$F/data8" --sensor webcam --out "$C/s" --quiet; r=$?; '
     'echo "first rc $r"; [ $r = 130 ] || [ $r = 0 ] || exit 1; '
     '$PY -m wildgen.sensor --data "$F/data8" --sensor webcam --out "$C/s" --quiet --overwrite',
     expect="ok", may_change=["$C/s", "$C/s/*"], timeout=110,
     why="Ctrl-C mid-conversion: exit 130, no traceback; --overwrite then replaces the half-written output.")
case("c37-export-shard-name-a-link-out", "writer",
     '$PY -m wildgen.export --data "$F/data" --out "$C/sh" --overwrite --quiet', names=["000000.tar"],
     setup='echo "mine" > mine.tar; mkdir sh; ln -s "$C/mine.tar" sh/000000.tar', timeout=90,
     why="A user's link under a shard's name is never written through (mine.tar unchanged) nor replaced without an "
         "earlier export's index: refused naming it, even with --overwrite.")
case("c37-export-out-a-fifo", "input", '$PY -m wildgen.export --data "$F/data" --out "$C/sh" --quiet', names=["--out"],
     setup="mkfifo sh", timeout=60, why="--out naming a pipe is refused in one line naming --out.")
case("c37-export-index-fifo-overwrite", "input",
     '$PY -m wildgen.export --data "$F/data" --out "$C/sh" --overwrite --quiet', names=["index.json"],
     setup="mkdir sh; mkfifo sh/index.json", timeout=60,
     why="An index.json that is a pipe is named (not read forever) before an export replaces anything.")
case("c37-export-interrupt-during-import", "message",
     'timeout -s INT 2 $PY -m wildgen.export --data "$F/data" --out "$C/sh" --quiet', expect="either",
     may_change=["$C/sh", "$C/sh/*"], why="Ctrl-C during start-up: exit 130 without a KeyboardInterrupt traceback.")
case("c37-export-two-at-once", "writer",
     both('$PY -m wildgen.export --data "$F/data8" --out "$C/sh" --shard-size 1 --quiet',
          '$PY -m wildgen.export --data "$F/data" --out "$C/sh" --shard-size 1 --quiet',
          "$PY -c \"import json,sys; i=json.load(open('sh/index.json')); n=len(i['shards']); import os; "
          "t=sorted(f for f in os.listdir('sh') if f.endswith('.tar')); "
          "sys.exit(0 if i.get('complete', True) and len(t) == n else f'FAULT: index lists {n} shards, folder holds {t}')\""),
     expect="ok", may_change=["$C/sh", "$C/sh/*"], timeout=110,
     why="Two exports of different datasets into one folder at once: one is refused; the folder holds exactly the "
         "shards its index.json lists (never a mix of both).")

# ============================================================================ gpu_session: the relay's archives
ARCH = ["--carry", "site.tar.xz"]
case("c37-relay-site-hardlink-outside", "archive", SESS + left("$C/w/site/pkg/h", "hard link unpacked"), names=ARCH,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, 'pkg/h', kind=tarfile.LNKTYPE, "
                                  "link='/etc/passwd')"),
     why="A hard-link member (to /etc/passwd) is refused as not a plain file before anything is unpacked.")
case("c37-relay-site-hardlink-inside", "archive", SESS + left("$C/w/site", "--work/site left behind"), names=ARCH,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'x = 1')\nadd(tar, 'pkg/alias.py', "
                                  "kind=tarfile.LNKTYPE, link='pkg/__init__.py')"),
     why="A hard link to another member (one file under two names) is refused like a symlink; nothing left behind.")
case("c37-relay-site-char-device", "archive", SESS + left("$C/w/site", "--work/site left behind"), names=ARCH,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nti = tarfile.TarInfo('pkg/null'); "
                                  "ti.type = tarfile.CHRTYPE; ti.devmajor, ti.devminor = 1, 3; tar.addfile(ti)"),
     why="A character-device member (/dev/null's numbers; as root it would be made) is refused before unpacking.")
case("c37-relay-site-fifo-member", "archive", SESS + left("$C/w/site", "--work/site left behind"), names=ARCH,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, 'pkg/pipe', kind=tarfile.FIFOTYPE)"),
     why="A FIFO member is refused (a later reader of the site would block on it).")
case("c37-relay-site-pax-path-escape", "archive", SESS, names=ARCH,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\n"
                                  "add(tar, 'pkg/ok.py', b'x = 1', path='../../../evil_c37-relay-site-pax-path-escape')"),
     why="A PAX 'path' record overriding a harmless ustar name with ../../../evil is checked as the real name: "
         "refused, nothing written outside --work.")
case("c37-relay-site-member-dot-as-file", "archive", SESS + left("$C/w/site", "--work/site left behind"),
     names=ARCH, setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, '.', b'data')"),
     why="A file member named '.' (the target folder itself) is refused in one line, no IsADirectoryError traceback.")
case("c37-relay-site-file-then-child", "archive", SESS + left("$C/w", "--work left behind by a refused pack"),
     names=ARCH, setup=mktar("c/site.tar.xz", "add(tar, 'pkg', b'a file')\nadd(tar, 'pkg/mod.py', b'x = 1')"),
     why="A file member and a later member that needs it as a folder: refused in one line; the refused pack leaves "
         "no --work behind.")
case("c37-relay-site-member-size-beyond-archive", "archive", SESS + left("$C/w", "--work left behind"), names=ARCH,
     setup=r"""mkdir -p c
$PY - <<'EOF'
import io, lzma, tarfile
buf = io.BytesIO()
with tarfile.open(fileobj=buf, mode="w", format=tarfile.USTAR_FORMAT) as tar:
    ti = tarfile.TarInfo("pkg/__init__.py"); data = b"x" * 600; ti.size = len(data); tar.addfile(ti, io.BytesIO(data))
raw = bytearray(buf.getvalue()[:512 + 1024])          # header + the data, no end-of-archive blocks
raw[124:136] = b"%011o\0" % (8 * 2**30)               # the header now claims 8 GiB
raw[148:156] = b" " * 8
raw[148:156] = b"%06o\0 " % sum(raw[:512])
open("c/site.tar.xz", "wb").write(lzma.compress(bytes(raw), format=lzma.FORMAT_XZ))
EOF
""", timeout=90,
     why="A member whose header claims 8 GiB in a 1.5 KiB archive: refused as damaged, never a disk filled with it.")
case("c37-relay-site-name-too-long", "archive", SESS + left("$C/w", "--work left behind"), names=ARCH,
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, 'pkg/' + 'a' * 4000 + '.py', b'x')"),
     why="A member name of 4000 characters (beyond the file system's 255) is refused in one line, the name cut short.")
case("c37-relay-assets-corrupt-mesh-named", "order", SESS, names=["bad.ply"],
     setup=GOOD_SITE + mktar("c/assets.tar.xz", "add(tar, 'assets/meshes/bad.ply', os.urandom(3000))\n"
                                               "add(tar, 'assets/hdri/sky.hdr', os.urandom(3000))"),
     may_change=["$C/o", "$C/o/*", "$C/w", "$C/w/*"], timeout=110,
     why="A packed asset that does not decode is refused before rendering, naming the file (not only 'wildgen.make "
         "failed').")
case("c37-relay-assets-none-escaping-assets", "archive", SESS_STOP + " --assets none", expect="either",
     setup=GOOD_SITE + mktar("c/assets.tar.xz", "add(tar, 'assets/m.ply', b'ply')\n"
                                               "add(tar, 'assets/../../../escape_c37-relay-assets-none', b'x')"),
     may_change=["$C/o", "$C/o/*", "$C/w", "$C/w/*"],
     why="--assets none with an assets.tar.xz whose member leads out: ignored or refused; never written outside.")
case("c37-relay-assets-fifo", "archive", SESS + left("$C/w", "--work left behind"), names=["assets.tar.xz"],
     setup=GOOD_SITE + "mkfifo c/assets.tar.xz", timeout=60,
     why="A carried assets.tar.xz that is a pipe is named before the site is unpacked, never read forever.")
case("c37-relay-setuid-world-writable-modes", "archive",
     "( " + SESS + " ) > s.log 2>&1 & sp=$!\n"
     'f="$C/w/site/pkg/run.py"; for i in $(seq 300); do [ -e "$f" ] && break; sleep 0.1; done\n'
     'bad=""; if [ -e "$f" ]; then if [ -u "$f" ] || [ -g "$f" ] || '
     '[ -n "$(find "$C/w/site" -perm -o+w 2>/dev/null)" ]; then bad=1; fi; ls -l "$f"; else echo "never unpacked"; fi\n'
     'kill -INT $sp 2>/dev/null; wait $sp; cat s.log\n'
     'if [ -n "$bad" ]; then echo "FAULT: setuid/setgid or world-write bits kept from the pack"; exit 1; fi; exit 0',
     expect="ok",
     setup="mkdir w\n" + mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'', mode=0o777)\n"
                                             "add(tar, 'pkg/run.py', b'print(1)', mode=0o6777)"),
     may_change=["$C/w", "$C/w/*", "$C/o", "$C/o/*"], timeout=90,
     why="Setuid, setgid and world-write bits in a pack are dropped on unpacking (the data filter); looked at while "
         "the rehearsal runs, which is then stopped with Ctrl-C.")
case("c37-relay-changed-pack-resume", "archive", SESS_STOP, names=["--work", "--overwrite"],
     setup=GOOD_SITE + "mkdir -p w/site/pkg; : > w/site/pkg/__init__.py\n"
     "sha256sum c/site.tar.xz | cut -d' ' -f1 > w/.site.unpacked\n"
     + mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'v = 2')"),
     may_change=["$C/o", "$C/o/*"],
     why="--work/site unpacked from an earlier pack, the pack since replaced: refused naming --work and --overwrite "
         "(never the old site silently kept on the path, nor replaced without asking).")
case("c37-relay-marker-a-users-folder", "archive", SESS_STOP, expect="either",
     setup=GOOD_SITE + 'mkdir -p w/.site.unpacked; echo mine > w/.site.unpacked/notes.txt',
     may_change=["$C/w/site", "$C/w/site/*", "$C/o", "$C/o/*"],
     why="A user's folder under the unpack marker's name: its file is kept, no IsADirectoryError traceback.")
case("c37-relay-assets-arg-inside-work-overwrite", "writer", SESS_STOP + ' --assets "$C/w/assets" --overwrite',
     names=["--assets"],
     setup=GOOD_SITE + mktar("c/assets.tar.xz", "add(tar, 'assets/meshes/p.ply', b'ply')")
     + 'mkdir -p w/assets/meshes; echo "my own mesh" > w/assets/meshes/mine.ply',
     may_change=["$C/w/site", "$C/w/site/*", "$C/w/.site*", "$C/o", "$C/o/*"],
     why="--assets naming the user's library at --work/assets, with --overwrite: unpacking the pack's assets there "
         "would delete the very folder --assets names; refused naming --assets, the library kept.")
case("c37-relay-init-inside-work-site-overwrite", "writer",
     SESS_STOP + ' --init "$C/w/site/mine.safetensors" --overwrite', names=["--init"],
     setup=GOOD_SITE + 'mkdir -p w/site; cp "$REPO/unips/weights/glc-tiny.safetensors" w/site/mine.safetensors\n'
                       'cp "$REPO/unips/weights/glc-tiny.json" w/site/mine.json 2>/dev/null || true',
     may_change=["$C/w/.site*", "$C/o", "$C/o/*"],
     why="--init lying in --work/site, which --overwrite empties for the pack: the weights to continue would be "
         "deleted; refused naming --init, the file kept.")
case("c37-relay-carry-link-into-work", "writer", SESS.replace('--carry "$C/c"', '--carry "$C/lnk"'),
     names=["--carry"], setup=GOOD_SITE + 'mkdir -p w; mv c w/pack; ln -s "$C/w/pack" lnk',
     why="--carry a link to a folder inside --work: the overlap is found through the link and refused.")
case("c37-relay-carry-a-file", "input", SESS.replace('"$C/c"', '"$F/afile"'), names=["--carry", "afile"],
     why="--carry naming a plain file is refused in one line naming it.")
case("c37-relay-interrupt-during-import", "message", "timeout -s INT 2 " + SESS, expect="either",
     setup=GOOD_SITE, may_change=["$C/o", "$C/o/*", "$C/w", "$C/w/*"],
     why="Ctrl-C while the session imports: exit 130, no KeyboardInterrupt traceback.")

# ============================================================================ gpu_session: flags refused before work
SESS_PLAIN = (GS + ' --out "$C/o" --work "$C/w" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1 '
              "--check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
case("c37-gs-lr-nan", "order", SESS_PLAIN + " --lr nan" + left("$C/w/data", "rendered before refusing --lr"),
     names=["--lr"], may_change=["$C/o", "$C/o/*", "$C/w", "$C/w/*"], timeout=90,
     why="--lr nan is refused before rendering (not by unips.train after the render), naming --lr.")
case("c37-gs-noise-cv-inf", "input", SESS_PLAIN.replace("--check-variant none", "") + " --noise-cv inf",
     names=["--noise-cv"], timeout=90, why="An infinite noise tolerance makes the variant check pass anything: refused.")
case("c37-gs-res-huge", "order", SESS_PLAIN.replace("--res 16", "--res 100000") + left("$C/w/data", "rendered"),
     names=["--res"], may_change=["$C/o", "$C/o/*", "$C/w", "$C/w/*"], timeout=90,
     why="A resolution beyond the machine's memory is refused before anything runs, naming the session's --res.")
case("c37-gs-model-unknown", "input", SESS_PLAIN + " --model no-such-model", names=["--model", "no-such-model"],
     timeout=90, why="An unknown model is refused at once naming --model, before rendering.")
case("c37-gs-init-shipped-other-model", "input", SESS_PLAIN + " --init shipped --model glc-test",
     names=["--model"], timeout=90,
     why="Continuing the shipped weights as another architecture is refused before any work.")
case("c37-gs-seed-beyond-32-bit", "order", SESS_PLAIN + " --seed 4294967296", expect="either", names=["--seed"],
     may_change=["$C/o", "$C/o/*", "$C/w", "$C/w/*"], timeout=115,
     why="A seed beyond 32 bits: run, or refused before rendering naming the session's --seed (not a step's flag).")
case("c37-gs-help-touches-nothing", "exit0", f'{GS} --help --out "$C/o" --work "$C/w" --carry "$C/c" >/dev/null'
     + '; r=$?; if [ -e "$C/w" ] || [ -e "$C/o" ]; then echo "FAULT: --help created --work or --out"; exit 3; fi; '
     'exit $r', expect="ok", setup=GOOD_SITE,
     why="--help with a pack given unpacks nothing and creates neither --out nor --work.")

# ============================================================================ gpu_session --pack
PACK = GS + ' --pack "$C/p" --wheels "$C/whl"'
case("c37-pack-overwrite-assets-none-leaves-stale-assets", "writer",
     PACK + " --assets none --overwrite && $PY -c \"import json,os,sys; m=json.load(open('p/manifest.json')); "
     "sys.exit(0 if ('assets' in m) == os.path.exists('p/assets.tar.xz') else 'FAULT: p/assets.tar.xz of the "
     "earlier pack left beside a manifest.json that records no assets (the session would still unpack and render "
     "with it, and the upload total leaves it out)')\"",
     expect="ok", may_change=["$C/p", "$C/p/*"], timeout=110,
     setup=WHEELS + mktar("p/assets.tar.xz", "add(tar, 'assets/meshes/old.ply', b'ply')")
     + """echo '{"site": {"archive": "site.tar.xz", "bytes": 1, "wheels": []}, "tree_bytes": 1, "assets": {"bytes": 1}}' > p/manifest.json
""",
     why="Packing again with --overwrite --assets none replaces an earlier pack: its assets.tar.xz must go too (or "
         "be recorded), or the carried folder holds assets the manifest and the size check do not know of.")
case("c37-pack-into-assets-meshes", "writer", GS + ' --pack "$C/assets/meshes" --wheels "$C/whl" --assets "$C/assets"',
     names=["--pack", "--assets"], setup=WHEELS + LIB, timeout=110,
     why="--pack inside --assets: the pack's archives would be read as meshes by the next pack; refused naming both.")
case("c37-pack-equals-assets", "writer", GS + ' --pack "$C/assets" --wheels "$C/whl" --assets "$C/assets"',
     names=["--pack", "--assets"], setup=WHEELS + LIB, timeout=110,
     why="--pack the asset folder itself: refused (the command never writes into what it reads).")
case("c37-pack-manifest-fifo-overwrite", "input", PACK + " --assets none --overwrite", names=["manifest.json"],
     setup=WHEELS + "mkdir p; mkfifo p/manifest.json", timeout=60,
     why="A manifest.json that is a pipe is named (not read forever) before an earlier pack is replaced.")
case("c37-pack-manifest-deeply-nested", "input", PACK + " --assets none --overwrite", names=["manifest.json"],
     setup=WHEELS + "mkdir p\n$PY -c \"open('p/manifest.json','w').write('{\\\"site\\\":' * 50000 + '1' + '}' * 50000)\"",
     timeout=60, why="A manifest.json nested 50000 deep: refused naming it, no RecursionError traceback.")
case("c37-pack-manifest-a-list-overwrite", "writer", PACK + " --assets none --overwrite", names=["manifest.json"],
     setup=WHEELS + "mkdir p; echo '[1, 2, 3]' > p/manifest.json", timeout=60,
     why="A manifest.json that is not a pack's (a list) is never replaced, even with --overwrite.")
case("c37-pack-wheel-is-a-folder", "input", PACK + " --assets none", names=["--wheels", "drjit"],
     setup=WHEELS + "rm whl/drjit-*.whl; mkdir whl/drjit-1.5.0-cp312-cp312-manylinux_2_28_x86_64.whl", timeout=60,
     why="A folder under a wheel's name is named (is a folder), not an IsADirectoryError traceback.")
case("c37-pack-wheel-fifo", "input", PACK + " --assets none", names=["--wheels", "drjit"],
     setup=WHEELS + "rm whl/drjit-*.whl; mkfifo whl/drjit-1.5.0-cp312-cp312-manylinux_2_28_x86_64.whl", timeout=60,
     why="A pipe under a wheel's name is named before the first byte is read, no hang.")
case("c37-pack-wheel-member-twice", "input", PACK + " --assets none" + left("$C/p/site.tar.xz", "site written"),
     names=["--wheels", "mitsuba"], timeout=60,
     setup=WHEELS + r"""rm whl/mitsuba-*.whl
$PY - <<'EOF'
import warnings, zipfile
warnings.simplefilter("ignore")
with zipfile.ZipFile("whl/mitsuba-3.9.1-cp312-cp312-manylinux_2_28_x86_64.whl", "w") as z:
    z.writestr("mitsuba/__init__.py", "a = 1")
    z.writestr("mitsuba/__init__.py", "a = 2")
EOF
""", why="A wheel holding one name twice would make a pack the GPU machine refuses: refused here, before packing.")
case("c37-pack-with-a-session-flag", "input", PACK + ' --assets none --carry "$C/c"', names=["--carry"],
     setup=WHEELS, why="--carry is a session's flag: with --pack it is refused naming it, not ignored.")
case("c37-pack-help-touches-nothing", "exit0", PACK + " --assets none --help >/dev/null"
     + made("$C/p", "--help created --pack"), expect="ok", setup=WHEELS,
     why="--pack --help writes no pack folder.")
case("c37-pack-two-at-once", "writer",
     both(PACK + " --assets none", PACK + " --assets none",
          "$PY -c \"import tarfile; tarfile.open('p/site.tar.xz').getmembers()\""),
     expect="ok", setup=WHEELS, may_change=["$C/p", "$C/p/*"], timeout=110,
     why="Two packs into one folder at once: one writes, the other is refused (one writer); the archive is whole.")
case("c37-pack-assets-corrupt-hdr", "input", PACK + ' --assets "$C/assets"' + left("$C/p/manifest.json",
                                                                                   "a pack written"),
     names=["a_bad.hdr"], setup=WHEELS + LIB + 'head -c 5000 /dev/urandom > assets/hdri/a_bad.hdr', timeout=110,
     why="A training HDR map that does not decode is named (--assets and the file), and no pack is kept.")

# ============================================================================ orchestrate.train_recipe
case("c37-recipe-lr-nan", "order", RC + ' --work "$C/w" --lr nan', names=["--lr"], timeout=90,
     may_change=["$C/w", "$C/w/*"], why="--lr nan is refused before the first render (which takes minutes), naming --lr.")
case("c37-recipe-minutes-nan", "input", RC + ' --work "$C/w" --minutes nan', names=["--minutes"],
     timeout=90, may_change=["$C/w", "$C/w/*"], why="A nan budget is refused naming --minutes before any step.")
case("c37-recipe-init-from-text", "order", RC + ' --work "$C/w" --init-from "$F/afile"',
     names=["--init-from", "afile"], timeout=90, may_change=["$C/w", "$C/w/*"],
     why="Weights that are a text file are refused before rendering, not by the training step minutes later.")
case("c37-recipe-init-from-fifo", "order", RC + ' --work "$C/w" --init-from "$C/ckpt"',
     names=["--init-from", "ckpt"], setup="mkfifo ckpt", timeout=90, may_change=["$C/w", "$C/w/*"],
     why="Weights that are a pipe are named (not read forever) before rendering.")
case("c37-recipe-threads-huge", "input", RC + ' --work "$C/w" --threads 100000000',
     names=["--threads"], timeout=90, may_change=["$C/w", "$C/w/*"],
     why="A thread count far beyond the machine is refused naming --threads before work.")
case("c37-recipe-train-seed-garbage", "input", RC + ' --work "$C/w" --train-seed 5000,abc',
     names=["--train-seed"], timeout=60, why="A seed list with a non-number is refused naming --train-seed.")
case("c37-recipe-help-touches-nothing", "exit0", RC + ' --help --work "$C/w" --overwrite >/dev/null'
     + made("$C/w", "--help created --work"), expect="ok", why="--help creates no --work.")
case("c37-recipe-assets-inside-work-overwrite-interrupted", "writer",
     'timeout -s INT 45 ' + RC + ' --work "$C/w" --assets "$C/w/mine" --overwrite --train-objects 1 --steps 1',
     expect="either", setup=LIB.replace("1 2 3 4", "1 2 3 4 5 6 7 8") + 'mkdir w; mv assets w/mine',
     may_change=["$C/w/[!m]*", "$C/w/.*"], timeout=80,
     why="--assets inside --work with --overwrite (then Ctrl-C): the user's library is never removed or changed.")

# ============================================================================ orchestrate.demo
case("c37-demo-spp-0", "input", DEMO + ' --out "$C/d" --spp 0', names=["--spp"],
     why="--spp 0 is refused naming --spp before the render.")
case("c37-demo-seed-negative", "input", DEMO + ' --out "$C/d" --seed=-1', names=["--seed"],
     why="A negative dataset seed is refused naming --seed before the render.")
case("c37-demo-checkpoint-fifo", "order", DEMO + ' --out "$C/d" --objects 1 --checkpoint "$C/ck"' + left(
    "$C/d/data", "rendered before the checkpoint was refused"), names=["--checkpoint", "ck"], setup="mkfifo ck",
     may_change=["$C/d", "$C/d/*"], timeout=90,
     why="A pipe as --checkpoint is named before the render, never read forever.")
case("c37-demo-checkpoint-dev-zero", "order", DEMO + ' --out "$C/d" --objects 1 --checkpoint /dev/zero' + left(
    "$C/d/data", "rendered before the checkpoint was refused"), names=["--checkpoint"],
     may_change=["$C/d", "$C/d/*"], timeout=90,
     why="/dev/zero as --checkpoint is refused as not a regular file, before the render.")
case("c37-demo-data-a-users-file", "writer", DEMO + ' --out "$C/d" --objects 1 --res 32 --spp 1', names=["data"],
     setup='mkdir d; echo "my notes" > d/data', timeout=110,
     why="--out already holding a user's file named data (where the dataset goes): refused, the file kept.")
case("c37-demo-help-touches-nothing", "exit0", DEMO + ' --help --out "$C/d" >/dev/null'
     + made("$C/d", "--help created --out"), expect="ok", why="--help creates no --out.")
case("c37-demo-interrupt-mid-render", "message",
     'timeout -s INT 12 ' + DEMO + ' --out "$C/d" --objects 2 --images 4 --res 32 --spp 1', expect="either",
     may_change=["$C/d", "$C/d/*"], timeout=60,
     why="Ctrl-C while the demo's render step runs: exit 130 in one line, the child stopped too, no traceback.")

# ============================================================================ orchestrate.docs (on a copy of the tree)
case("c37-docs-unclosed-marker", "input",
     DOCS, names=["development.md"], setup=REPO_COPY + "printf '\\n<!-- BEGIN generated:flags:wildgen.make -->\\n' "
     ">> repo/docs/development.md", timeout=110,
     why="A BEGIN marker without its END is refused naming the page; no page is rewritten.")
case("c37-docs-page-fifo", "input", DOCS + " --check", names=["surface.md"],
     setup=REPO_COPY + "rm repo/docs/surface.md; mkfifo repo/docs/surface.md", timeout=110,
     why="A doc page that is a pipe is named (not read forever), even with --check.")
case("c37-docs-page-link-outside", "writer", DOCS, expect="either", may_change=["$C/repo/*"],
     setup=REPO_COPY + r"""$PY - <<'EOF'
import pathlib
p = pathlib.Path("repo/docs/model.md"); t = p.read_text()
i = t.index("<!-- BEGIN generated:flags:orchestrate.gpu_session -->")
pathlib.Path("outside.md").write_text(t[:i] + t[i:].replace("| flag |", "| stale |", 1))
p.unlink(); p.symlink_to(pathlib.Path("outside.md").resolve())
EOF
""", timeout=110,
     why="A doc page that is a link to a file outside the tree, out of date: the file outside is never written "
         "through (the link replaced, or refused).")
case("c37-docs-card-truncated", "input", DOCS + " --check", names=["model_card.json"],
     setup=REPO_COPY + 'f=repo/unips/weights/model_card.json; head -c 200 "$f" > x; mv x "$f"', timeout=110,
     why="A damaged model card is refused in one line naming model_card.json.")
case("c37-docs-readme-latin1", "input", DOCS, names=["README.md"],
     setup=REPO_COPY + "printf '\\ncaf\\xe9\\n' >> repo/README.md", timeout=110,
     why="A page that is not UTF-8 is refused naming it (and nothing rewritten with its bytes mangled).")
case("c37-docs-check-stale", "input", DOCS + " --check", names=["model.md"],
     setup=REPO_COPY + r"""$PY - <<'EOF'
import pathlib
p = pathlib.Path("repo/docs/model.md"); t = p.read_text()
p.write_text(t.replace("| `--noise-cv FLOAT` |", "| `--noise-cv STALE` |", 1))
EOF
""", timeout=110, why="--check finds the stale flag table, exits 1 naming model.md and changes nothing.")
case("c37-docs-help-touches-nothing", "exit0", DOCS + " --help >/dev/null", expect="ok", setup=REPO_COPY, timeout=110,
     why="--help rewrites no page (the copy's files stay byte-identical: the harness checks them all).")
