"""Sweep 38, part f: the GENERATOR and RELAY side again (wildgen.make / preview / sensor / export,
orchestrate.gpu_session, orchestrate.ship, orchestrate.train_recipe, orchestrate.demo), with cases sweep 37
(cases37_c.py) and tests/test_bad_inputs.py do not hold.

Mechanisms aimed at: nothing unpacked or written before the arguments are checked (every gpu_session refusal is
checked to leave no --work/site behind), nothing lost (a hand-edited manifest.json or resumed work folder is never
"repaired" by deleting what it does not understand), one writer per folder, late refusals (a bad flag refused only
after rendering), one-line messages naming the flag and the file, and no exit 0 with a wrong result (a stats.json
holding NaN, a light list silently changed, a shard key that does not read back).

Cases whose command adds its own check print a line starting with `FAULT:` and exit so that the harness flags it.
"""
from __future__ import annotations

import textwrap

TINY = "--objects 1 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet"
"""The smallest render wildgen.make takes (one 16-px object, 2 images)."""
MK = "$PY -m wildgen.make"
GS = "$PY -m orchestrate.gpu_session"
SESS = (GS + ' --out "$C/o" --work "$C/w" --carry "$C/c" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1'
        " --check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
"""A CPU rehearsal of a session on the pack in $C/c, as small as it goes (bounded by its --minutes)."""
RC = "$PY -m orchestrate.train_recipe"
DEMO = "$PY -m orchestrate.demo"
SHIP = "$PY -m orchestrate.ship"
DS = 'cp -r "$F/data" d\n'
"""Setup: d/, a copy of the 3-object 32-px dataset (with its manifest.json)."""
OUTDS = 'cp -r "$F/data" out\n'
"""Setup: out/, a copy of the dataset, as wildgen.make would find it when resuming."""


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


def mktar(path: str, body: str) -> str:
    """Setup: the xz tar `path` written by `body` (Python, with `tar` open and `add(tar, name, data)`)."""
    return (f'mkdir -p "$(dirname {path})"\n$PY - <<\'EOF\'\nimport io, os, tarfile\n'
            "def add(tar, name, data=b''):\n"
            "    ti = tarfile.TarInfo(name); ti.mode = 0o644; ti.size = len(data); tar.addfile(ti, io.BytesIO(data))\n"
            f"with tarfile.open({path!r}, 'w:xz', format=tarfile.PAX_FORMAT) as tar:\n"
            + textwrap.indent(body.strip("\n"), "    ") + "\nEOF\n")


GOOD_SITE = mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')")
"""Setup: c/site.tar.xz, a valid one-package pack (no assets)."""


def evil_pt(path: str) -> str:
    """Setup: `path`, a torch file whose full unpickling would create /tmp/pwn_<case>."""
    return f"""mkdir -p "$(dirname {path})"
$PY - <<'EOF'
import os, torch
class P:
    def __reduce__(self):
        return (os.system, ('touch /tmp/pwn_' + os.path.basename(os.environ['C']),))
torch.save({{'format': 'unips-train/1', 'model_name': 'glc-tiny', 'model': P()}}, '{path}')
EOF
"""


def left(path: str, what: str) -> str:
    """Command tail: a refusal that left `path` behind exits 0 with a FAULT line (flagged exit0)."""
    return (f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r')


def nosite() -> str:
    return left("$C/w/site", "--work/site unpacked before the arguments were checked")


COMPLETE = ("$PY -c \"import json,sys; m=json.load(open('out/manifest.json')); "
            "sys.exit(0 if m.get('complete') else 'FAULT: out/manifest.json not complete')\"")


def lights_are(*fams: str) -> str:
    """Command tail (after a successful make): every object's light_family is one of `fams`, else FAULT exit 3."""
    return (" && $PY -c \"import json,sys; m=json.load(open('out/manifest.json')); "
            f"f={{o.get('light_family') for o in m['objects'] if o.get('status')=='done'}}; "
            f"sys.exit(0 if f <= set({list(fams)!r}) else 'FAULT: light families %s' % f)\"")


CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


OUT = ["$C/out", "$C/out/*"]
NOOUT = left("$C/out", "--out created before the arguments were checked")

# ============================================================================ wildgen.make: light lists
case("f38-make-lights-uppercase", "input", f'{MK} --out "$C/out" --lights NEAR_AREA {TINY}' + NOOUT,
     names=["--lights", "NEAR_AREA"],
     why="Family names are lower-case keys: NEAR_AREA is refused naming --lights and the value, before --out exists.")
case("f38-make-lights-space-after-comma", "input", f'{MK} --out "$C/out" --lights "near_area, point" {TINY}' + " && $PY -c \"import json,sys; "
     "l=json.load(open('out/manifest.json'))['config']['lights']; "
     "sys.exit(0 if l == ['near_area', 'point'] else 'FAULT: lights recorded as %r' % l)\"",
     expect="either", names=["--lights"], may_change=OUT, timeout=110,
     why="'near_area, point' either strips the space and renders both families or is refused naming --lights; "
         "never a family named ' point' recorded in the manifest or a traceback.")
case("f38-make-lights-duplicated-in-list", "input",
     f'{MK} --out "$C/out" --lights point,point,point {TINY}' + lights_are("point"), expect="either",
     names=["--lights"], may_change=OUT, timeout=110,
     why="A repeated family is harmless (or refused naming --lights): the objects must get that family only.")
case("f38-make-lights-flag-and-list-mixed", "input",
     f'{MK} --out "$C/out" --lights directional --lights point,directional {TINY}' +
     lights_are("directional", "point"), expect="either", names=["--lights"], may_change=OUT, timeout=110,
     why="Repeated --lights and a comma list together: the families given and no other (or one line naming --lights).")
case("f38-make-lights-tab-separated", "input", f'{MK} --out "$C/out" --lights "$(printf \'point\\tflash\')" {TINY}'
     + NOOUT, names=["--lights"],
     why="A tab is not a separator: 'point<TAB>flash' is an unknown family, refused naming --lights before --out.")
case("f38-make-lights-unknown-late-in-list", "input",
     f'{MK} --out "$C/out" --lights near_area,point,directional,hdri,teleport {TINY}' + NOOUT,
     names=["--lights", "teleport"],
     why="An unknown fifth family is refused naming it, before anything is written, not when object 4 is reached.")

# ============================================================================ wildgen.make: presets, sensor, camera
case("f38-make-preset-wrong-case", "input", f'{MK} --out "$C/out" --preset DiLiGenT {TINY}' + NOOUT,
     names=["--preset"], why="Preset names are exact keys: 'DiLiGenT' is refused naming --preset before --out exists.")
case("f38-make-preset-diligent-two-images", "engine", f'{MK} --out "$C/out" --preset diligent {TINY} && {COMPLETE}',
     expect="either", names=["--images"], may_change=OUT, timeout=110,
     why="The grid96 pattern with 2 images (flags given win over the preset) renders a complete dataset or is "
         "refused naming --images; never a traceback.")
case("f38-make-preset-display-orthographic", "engine",
     f'{MK} --out "$C/out" --preset display --camera orthographic {TINY} && {COMPLETE}', expect="either",
     names=["--camera"], may_change=OUT, timeout=110,
     why="The display preset with an orthographic camera keeps 6 of 12 patches: rendered complete or refused "
         "naming --camera, never a traceback.")
case("f38-make-sensor-wrong-case", "input", f'{MK} --out "$C/out" --sensor Phone {TINY}' + NOOUT,
     names=["--sensor"], why="'Phone' is not a sensor key: refused naming --sensor before --out exists.")
case("f38-make-sensor-phone-odd-sides", "engine",
     f'{MK} --out "$C/out" --sensor phone --width 17 --height 15 --objects 1 --images 2 --spp 1 --gt-spp 1 '
     f'--workers 0 --quiet && {COMPLETE}', expect="either", names=["--width"], may_change=OUT, timeout=110,
     why="An RGGB mosaic on odd sides (17 x 15) is demosaiced or refused naming --width/--height; never a "
         "shape-mismatch traceback after rendering (a late refusal).")
case("f38-make-sensor-webcam-8px", "engine",
     f'{MK} --out "$C/out" --sensor webcam --res 8 --objects 1 --images 2 --spp 1 --gt-spp 1 --workers 0 --quiet',
     expect="either", names=["--res"], may_change=OUT, timeout=110,
     why="The smallest side (8 px) with 35 % vignetting and a Bayer filter: an object written or skipped with its "
         "reason, or refused naming --res; no traceback.")
case("f38-make-camera-wrong-case", "input", f'{MK} --out "$C/out" --camera Perspective {TINY}' + NOOUT,
     names=["--camera"], why="'Perspective' is refused naming --camera before --out exists.")
case("f38-make-shapes-mesh-assets-without-meshes", "input",
     f'{MK} --out "$C/out" --shapes mesh --assets "$C/a" {TINY}' + NOOUT, names=["--shapes"],
     setup='mkdir -p a/hdri; cp "$(ls "$F"/assets/hdri/* | head -1)" a/hdri/',
     why="--shapes mesh with an asset folder holding no meshes is refused naming --shapes (and the folder) "
         "before anything is written, not after every object failed.")
case("f38-make-shape-kinds-space-after-comma", "input",
     f'{MK} --out "$C/out" --shape-kinds "blob, torus" {TINY}', expect="either", names=["--shape-kinds"],
     may_change=OUT, timeout=110,
     why="'blob, torus' is read as two kinds or refused naming --shape-kinds; never a kind ' torus' failing late.")
case("f38-make-materials-given-twice", "input",
     f'{MK} --out "$C/out" --materials diffuse --materials metallic {TINY}', expect="either",
     names=["--materials"], may_change=OUT, timeout=110,
     why="A single-valued flag given twice: the last wins (argparse) or one line names --materials; no traceback.")

# ============================================================================ wildgen.make: numbers
case("f38-make-exposure-percentile-101", "input", f'{MK} --out "$C/out" --exposure-percentile 101 {TINY}' + NOOUT,
     names=["--exposure-percentile"], why="A percentile above 100 is refused naming the flag before --out exists.")
case("f38-make-exposure-percentile-nan", "input", f'{MK} --out "$C/out" --exposure-percentile nan {TINY}' + NOOUT,
     names=["--exposure-percentile"], why="nan passes every range comparison: refused naming the flag.")
case("f38-make-exposure-level-inf", "input", f'{MK} --out "$C/out" --exposure-level inf {TINY}' + NOOUT,
     names=["--exposure-level"], why="An infinite exposure target gives infinite images: refused naming the flag.")
case("f38-make-exposure-level-negative", "input", f'{MK} --out "$C/out" --exposure-level=-0.5 {TINY}' + NOOUT,
     names=["--exposure-level"], why="A negative target makes negative radiance: refused naming the flag.")
case("f38-make-threads-negative", "input", f'{MK} --out "$C/out" --threads=-2 {TINY}' + NOOUT,
     names=["--threads"], why="A negative thread count is refused naming --threads, not handed to Dr.Jit.")
case("f38-make-max-retries-huge", "input", f'{MK} --out "$C/out" --max-retries 1e9 {TINY}' + NOOUT,
     names=["--max-retries"], why="'1e9' is not an integer: refused naming --max-retries before --out exists.")
case("f38-make-workers-huge-ray-free", "input", f'{MK} --out "$C/out" --workers 99999999999999999999 {TINY}',
     expect="either", names=["--workers"], may_change=OUT, timeout=110,
     why="A worker count beyond 64 bits is clamped to the objects or refused naming --workers; never an "
         "OverflowError traceback.")

# ============================================================================ wildgen.make: resume with changed flags
case("f38-make-resume-other-sensor", "writer", f'{MK} --out "$C/out" --resume --sensor phone --workers 0 --quiet',
     names=["sensor"], setup=OUTDS,
     why="Resuming a dataset made with the ideal sensor under --sensor phone would mix two sensors: refused naming "
         "the sensor (and --overwrite), the dataset untouched.")
case("f38-make-resume-add-preset", "writer", f'{MK} --out "$C/out" --resume --preset phone-flash --workers 0 --quiet',
     names=["--preset"], setup=OUTDS,
     why="A preset changes lights, images, size, camera and sensor: resuming a dataset under it is refused naming "
         "--preset, nothing rewritten.")
case("f38-make-resume-lights-reordered", "writer",
     f'{MK} --out "$C/out" --resume --lights near_area,near_area --objects 3 --workers 0 --quiet', expect="either",
     names=["--lights"], setup=OUTDS,
     why="near_area twice cycles the same family: either recognised as the manifest's configuration (nothing to do, "
         "exit 0, nothing changed) or refused naming --lights; the dataset is never rewritten.")
case("f38-make-resume-other-camera", "writer",
     f'{MK} --out "$C/out" --camera perspective --workers 0 --quiet --objects 3', names=["camera"], setup=OUTDS,
     why="The same command with another camera on an existing dataset is refused naming the camera and "
         "--overwrite, nothing changed.")

# ============================================================================ wildgen.make: manifest.json edited by hand
RES = f'{MK} --out "$C/out" --resume --workers 0 --quiet'
case("f38-make-manifest-status-unknown", "input", RES + f" && {COMPLETE}", expect="refuse", names=["manifest.json"],
     setup=OUTDS + manifest("out", "m['objects'][1]['status'] = 'finished-ish'"),
     may_change=["$C/out/manifest.json", "$C/out/00001.data", "$C/out/00001.data/*"], timeout=110,
     why="An object status the generator never writes is refused naming manifest.json (sweep 38's drafting saw it read "
         "as 'not finished' and rendered again without a word); objects 0 and 2 untouched.")
case("f38-make-manifest-status-failed-folder-present", "writer", RES, expect="either", setup=OUTDS +
     manifest("out", "m['objects'][1]['status'] = 'failed'; m['objects'][1]['reason'] = 'by hand'"),
     may_change=["$C/out/manifest.json", "$C/out/00001.data", "$C/out/00001.data/*"], timeout=110,
     why="A failed entry whose folder exists: re-rendered or kept as failed; the other objects' files unchanged.")
case("f38-make-manifest-status-running", "writer", RES + f" && {COMPLETE}", expect="either", setup=OUTDS +
     manifest("out", "m['objects'][2]['status'] = 'running'; m['complete'] = False"),
     may_change=["$C/out/manifest.json", "$C/out/00002.data", "$C/out/00002.data/*"], timeout=110,
     why="A stale 'running' entry (a killed run) is rendered again and the dataset ends complete, or refused in "
         "one line; objects 0 and 1 unchanged.")
case("f38-make-manifest-name-escapes", "archive", RES, expect="either", names=["manifest.json"], setup=OUTDS +
     manifest("out", "m['objects'][0]['name'] = '../../pwn_' + __import__('os').path.basename("
                     "__import__('os').environ['C'])"),
     may_change=["$C/out/manifest.json"],
     why="An object name that climbs out of --out is refused naming manifest.json or ignored; no file named after "
         "it is ever written outside --out.")
case("f38-make-manifest-index-twice", "input", RES, names=["manifest.json"], setup=OUTDS +
     manifest("out", "m['objects'][1]['index'] = 0"),
     why="Two entries for object 0 are refused naming manifest.json; nothing is rendered over either folder.")
case("f38-make-manifest-objects-a-string", "input", RES, names=["manifest.json"], setup=OUTDS +
     manifest("out", "m['config']['objects'] = '3'"),
     why="config.objects must be an integer: a string is refused naming manifest.json and the field.")
case("f38-make-manifest-lights-empty", "input", RES, names=["manifest.json"], setup=OUTDS +
     manifest("out", "m['config']['lights'] = []"),
     why="An empty light list (i % 0) is refused naming manifest.json, not a ZeroDivisionError.")
case("f38-make-manifest-lights-unknown", "input", RES, names=["manifest.json"], setup=OUTDS +
     manifest("out", "m['config']['lights'] = ['near_area', 'teleport']; m['config']['objects'] = 4"),
     why="An unknown family in the manifest's configuration is refused naming manifest.json and 'teleport' "
         "before any rendering.")
case("f38-make-manifest-width-huge", "input", RES, names=["manifest.json"], setup=OUTDS +
     manifest("out", "m['config']['width'] = 10**6; m['config']['objects'] = 4"),
     why="A manifest's width is checked as the flag is (8 to 8192): refused naming manifest.json, not a render "
         "that exhausts memory.")
case("f38-make-manifest-spp-negative", "input", RES, names=["manifest.json"], setup=OUTDS +
     manifest("out", "m['config']['spp'] = -4; m['config']['objects'] = 4"),
     why="A negative spp in the manifest is refused naming manifest.json before any rendering.")
case("f38-make-manifest-format-version-99", "input", RES, names=["manifest.json"], setup=OUTDS +
     manifest("out", "m['format_version'] = 99"),
     why="A manifest of a later format is refused naming manifest.json and its version, not read as version 1.")
case("f38-make-manifest-utf16", "input", RES, names=["manifest.json"], setup=OUTDS + py("""
        p = "out/manifest.json"; t = open(p, encoding="utf-8").read(); open(p, "w", encoding="utf-16").write(t)
        """),
     why="A manifest saved as UTF-16 by an editor is refused in one line naming manifest.json (no "
         "UnicodeDecodeError traceback) and nothing is overwritten.")
case("f38-make-manifest-entry-index-beyond-objects", "input", RES, expect="either", names=["manifest.json"],
     setup=OUTDS + manifest("out", "m['objects'][2]['index'] = 7"),
     may_change=["$C/out/manifest.json"],
     why="An entry for object 7 in a 3-object dataset is refused naming manifest.json or handled; object folders "
         "are never deleted.")

# ============================================================================ wildgen.preview
case("f38-preview-stats-exposure-nan", "exit0",
     '$PY -m wildgen.preview "$C/d" --stats --out "$C/pv"; r=$?; [ -f pv/stats.json ] || exit $r; '
     "$PY -c \"import json,sys; json.loads(open('pv/stats.json').read(), parse_constant=lambda c: "
     "sys.exit('FAULT: stats.json holds ' + c))\"; exit $r", expect="either", names=["00001"],
     setup=DS + py("""
        import json
        p = "d/00001.data/scene.json"; s = json.load(open(p)); s["images"][0]["exposure"] = float("nan")
        json.dump(s, open(p, "w"))
        """), may_change=["$C/pv", "$C/pv/*"],
     why="A scene.json exposure of NaN: the object is listed as failed or left out; stats.json must stay strict JSON "
         "(no NaN token) either way.")
case("f38-preview-stats-png-a-folder", "writer", '$PY -m wildgen.preview "$F/data" --stats --out "$C/pv" --overwrite',
     names=["stats.png"], setup="mkdir -p pv/stats.png; touch pv/stats.png/keep",
     why="A folder where stats.png goes is refused naming it, never removed with its content by --overwrite.")
case("f38-preview-object-folder-unicode-space", "input", '$PY -m wildgen.preview "$C/d" --out "$C/pv"',
     expect="either", names=["obj é 1.data"],
     setup='mkdir d; cp -r "$F/data/00000.data" "d/obj é 1.data"; cp -r "$F/data/00001.data" d/',
     may_change=["$C/pv", "$C/pv/*"],
     why="An object folder named with a space and an accent is drawn like any other (or named in one line); no "
         "encoding traceback.")
case("f38-preview-mask-all-black", "input", '$PY -m wildgen.preview "$C/d" --stats --out "$C/pv"', expect="either",
     names=["00000"], setup=DS + py("""
        import numpy as np, cv2
        m = cv2.imread("d/00000.data/mask.png", cv2.IMREAD_UNCHANGED); cv2.imwrite("d/00000.data/mask.png", m * 0)
        """), may_change=["$C/pv", "$C/pv/*"],
     why="An empty mask gives no normals to histogram: the object is failed with a reason or counted with 0 mask "
         "pixels; never a division by zero traceback or NaN.")

# ============================================================================ wildgen.sensor
SEN = '$PY -m wildgen.sensor --sensor phone --quiet'
case("f38-sensor-out-equals-data", "writer", SEN + ' --data "$C/d" --out "$C/d" --overwrite',
     names=["--out"], setup=DS,
     why="--out equal to --data with --overwrite would replace the source while reading it: refused naming --out, "
         "the dataset untouched.")
case("f38-sensor-out-inside-data", "writer", SEN + ' --data "$C/d" --out "$C/d/phone"', names=["--out"], setup=DS,
     why="An output inside the source dataset would be read as one of its objects next time: refused naming --out.")
case("f38-sensor-data-is-shards", "input", SEN + ' --data "$F/shards" --out "$C/s"' +
     left("$C/s/manifest.json", "manifest written for shards"), names=["--data"],
     why="A shard folder has no radiance files: refused naming --data (and what it is), no manifest in --out.")
case("f38-sensor-radiance-nan-checksummed", "input", SEN + ' --data "$C/d" --out "$C/s"', names=["radiance_001.exr"],
     setup=DS + py("""
        import hashlib, json
        from scenes.exr import read_exr, write_exr
        p = "d/00000.data/aux/radiance_001.exr"; a = read_exr(p).copy(); a.reshape(-1)[5] = float("nan"); write_exr(p, a)
        m = json.load(open("d/manifest.json"))
        m["objects"][0]["files"]["aux/radiance_001.exr"] = hashlib.sha256(open(p, "rb").read()).hexdigest()
        json.dump(m, open("d/manifest.json", "w"), indent=1)
        """), may_change=["$C/s", "$C/s/*"],
     why="A NaN radiance pixel whose checksum was updated is caught by the value check, naming the file; never a "
         "PNG with a garbage pixel and exit 0.")
case("f38-sensor-seed-beyond-64-bit", "input", SEN + ' --data "$F/data" --out "$C/s" --seed 99999999999999999999999',
     expect="either", names=["--seed"], may_change=["$C/s", "$C/s/*"],
     why="A seed beyond 64 bits is used or refused naming --seed; never an OverflowError traceback mid-conversion.")

# ============================================================================ wildgen.export
EX = '$PY -m wildgen.export --quiet'
case("f38-export-shard-size-0", "input", EX + ' --data "$F/data" --out "$C/sh" --shard-size 0' +
     left("$C/sh", "--out created"), names=["--shard-size"], why="0 objects per shard is refused naming the flag.")
case("f38-export-shard-size-huge", "input", EX + ' --data "$F/data" --out "$C/sh" --shard-size 99999999999999999999',
     expect="either", names=["--shard-size"], may_change=["$C/sh", "$C/sh/*"],
     why="A shard size beyond 64 bits makes one shard or is refused naming --shard-size; no overflow traceback.")
case("f38-export-aux-with-decoded", "input", EX + ' --data "$F/data" --out "$C/sh" --aux --encoding decoded' +
     left("$C/sh", "--out created"), names=["--aux"],
     why="--aux needs --encoding files (docs): the pair is refused naming --aux before anything is written.")
case("f38-export-out-equals-data", "writer", EX + ' --data "$C/d" --out "$C/d" --overwrite', names=["--out"],
     setup=DS, why="--out equal to --data is refused naming --out; the dataset untouched.")
case("f38-export-out-in-an-object-folder", "writer", EX + ' --data "$C/d" --out "$C/d/00001.data/sh"',
     names=["--out"], setup=DS,
     why="Shards written inside an object folder would become members of the next export: refused naming --out.")
case("f38-export-format-unknown", "input", EX + ' --data "$F/data" --out "$C/sh" --format tar' +
     left("$C/sh", "--out created"), names=["--format"], why="Only webdataset: 'tar' is refused naming --format.")
case("f38-export-dotted-object-name", "exit0",
     EX + ' --data "$C/d" --out "$C/sh"; r=$?; [ $r = 0 ] || exit $r; $PY -c "'
     "import tarfile,glob,sys; n=[m.name for t in glob.glob('sh/*.tar') for m in tarfile.open(t)]; "
     "bad=[x for x in n if x.startswith('a.b.')]; sys.exit('FAULT: members split at the wrong dot: %s' % bad[:2] "
     "if bad else 0)\"", expect="either", names=["a.b"],
     setup='mkdir d; cp -r "$F/data/00000.data" d/a.b.data; cp -r "$F/data/00001.data" d/',
     may_change=["$C/sh", "$C/sh/*"],
     why="WebDataset splits a member's key at its first dot: an object folder 'a.b.data' would read back as key 'a' "
         "with files 'b.L000.png'; refused naming the folder (or its key made plain), never written as is.")

# ============================================================================ gpu_session: flags, before any unpack
def gs(id: str, flags: str, names, why: str, setup: str = GOOD_SITE) -> None:
    case(id, "order", SESS + " " + flags + nosite(), names=names, setup=setup, why=why)


gs("f38-gs-minutes-nan", "--minutes nan", ["--minutes"],
   "A nan budget passes 'minutes > reserve' as False or True at random places: refused naming --minutes first.")
gs("f38-gs-minutes-inf", "--minutes inf", ["--minutes"],
   "An infinite budget never ends a render: refused naming --minutes before the pack is unpacked.")
gs("f38-gs-reserve-negative", "--reserve-s=-5", ["--reserve-s"],
   "A negative reserve is refused naming --reserve-s before the pack is unpacked.")
gs("f38-gs-reserve-nan", "--reserve-s nan", ["--reserve-s"],
   "A nan reserve is refused naming --reserve-s (every comparison with it is False).")
gs("f38-gs-cpu-rehearsal-device-cuda", "--device cuda", ["--device"],
   "--cpu-rehearsal with --device cuda contradict each other here: refused naming --device before any unpack.")
gs("f38-gs-batch-0", "--batch 0", ["--batch"], "Zero objects per step is refused naming --batch before any unpack.")
gs("f38-gs-steps-0", "--steps 0", ["--steps"], "A zero-step schedule is refused naming --steps before any unpack.")
gs("f38-gs-ckpt-minutes-nan", "--ckpt-minutes nan", ["--ckpt-minutes"],
   "A nan save interval is refused naming --ckpt-minutes (else last.pt is never or always saved).")
gs("f38-gs-check-objects-negative", "--check-objects=-1 --check-variant scalar_rgb", ["--check-objects"],
   "A negative count of checked objects is refused naming --check-objects before any unpack.")
gs("f38-gs-log-every-0", "--log-every 0", ["--log-every"],
   "Logging every 0 steps is refused naming --log-every before any unpack.")
gs("f38-gs-init-glc-test-weights", '--init "$F/run/final.safetensors"', ["--init"],
   "A glc-test run is not the shipped architecture: refused naming --init before any work (docs).")
gs("f38-gs-init-malicious-pickle", '--init "$C/i/last.pt"', ["--init"],
   "A last.pt whose unpickling runs code is refused by the tensors-only reader naming --init; /tmp/pwn_<case> never "
   "appears and nothing is unpacked.", setup=GOOD_SITE + evil_pt("i/last.pt"))
gs("f38-gs-init-text-as-safetensors", '--init "$C/i/final.safetensors"', ["--init", "final.safetensors"],
   "A text file named final.safetensors is refused naming --init and the file before any unpack.",
   setup=GOOD_SITE + "mkdir i; echo 'not weights' > i/final.safetensors")
case("f38-gs-user-model-card-in-out", "writer", SESS, expect="either", names=["model_card.json"],
     setup=GOOD_SITE + "mkdir o; echo '{\"mine\": true}' > o/model_card.json",
     may_change=["$C/w", "$C/w/*", "$C/o/run", "$C/o/run/*", "$C/o/*.png", "$C/o/summary.json",
                 "$C/o/variant_check.json"], timeout=115,
     why="A model_card.json the session did not write is never replaced (refused naming it, or kept byte for "
         "byte); the other outputs may be written.")

# ============================================================================ orchestrate.ship
SHP = SHIP + ' --candidate "$C/cand" --val "$F/data" --diligent none'
SHIPPED = "$REPO/unips/weights/glc-tiny"
case("f38-ship-threads-0", "input", SHP + " --threads 0", names=["--threads"],
     setup=f"mkdir -p cand/run; cp {SHIPPED}.safetensors cand/run/final.safetensors; cp {SHIPPED}.json "
           "cand/run/final.json",
     why="Zero torch threads is refused naming --threads before any scoring.")
case("f38-ship-diligent-a-file", "input", SHIP + ' --candidate "$C/cand" --val "$F/data" --diligent "$F/afile"',
     names=["--diligent"],
     setup=f"mkdir -p cand/run; cp {SHIPPED}.safetensors cand/run/final.safetensors; cp {SHIPPED}.json "
           "cand/run/final.json",
     why="A plain file given as the DiLiGenT folder is refused naming --diligent before the validation set is scored.")
case("f38-ship-val-equals-candidate", "input", SHIP + ' --candidate "$C/cand" --val "$C/cand" --diligent none',
     names=["--val"],
     setup=f"mkdir -p cand/run; cp {SHIPPED}.safetensors cand/run/final.safetensors; cp {SHIPPED}.json "
           "cand/run/final.json",
     why="The candidate folder is not a validation set: refused naming --val in one line.")
case("f38-ship-final-header-length-huge", "weights", SHP, names=["final.safetensors"],
     setup=f"mkdir -p cand/run; cp {SHIPPED}.json cand/run/final.json; " + py("""
        import struct
        open("cand/run/final.safetensors", "wb").write(struct.pack("<Q", 2**62) + b"{}" + b"\\0" * 64)
        """),
     why="A safetensors header claiming 2^62 bytes is refused naming final.safetensors, not a MemoryError.")
case("f38-ship-summary-fifo", "input", SHP, names=["summary.json"], timeout=60,
     setup=f"mkdir -p cand/run; cp {SHIPPED}.safetensors cand/run/final.safetensors; cp {SHIPPED}.json "
           "cand/run/final.json; mkfifo cand/summary.json",
     why="A fifo named summary.json is refused naming it, not read forever.")

# ============================================================================ orchestrate.train_recipe
RCW = RC + ' --work "$C/w" --assets none --train-objects 1 --steps 1 --threads 1'
case("f38-recipe-train-objects-0", "input", RCW.replace("--train-objects 1", "--train-objects 0") +
     left("$C/w", "--work created"), names=["--train-objects"],
     why="Zero training objects is refused naming --train-objects before --work is created.")
case("f38-recipe-minutes-negative", "input", RCW + " --minutes=-1" + left("$C/w", "--work created"),
     names=["--minutes"], why="A negative budget is refused naming --minutes before --work is created.")
case("f38-recipe-init-from-malicious-pickle", "archive", RCW + ' --init-from "$C/i/last.pt"', names=["--init-from"],
     setup=evil_pt("i/last.pt"), may_change=["$C/w", "$C/w/*"],
     why="The recipe's --init-from is read by the tensors-only reader before any step: refused naming it, no "
         "/tmp/pwn_<case> file.")
case("f38-recipe-train-set-of-another-config", "writer", RCW, names=["train5000"],
     setup='mkdir w; cp -r "$F/data" w/train5000',
     why="A work folder whose train5000 holds a dataset of another configuration (edited by hand, copied in) is "
         "refused in one line naming it (and --overwrite); its objects are never re-rendered over.")
case("f38-recipe-train-seed-space", "input", RC + ' --work "$C/w" --train-seed "5000, 5001" --lr nan' +
     left("$C/w", "--work created"), expect="refuse", names=["--"],
     why="'5000, 5001' is read as two seeds or refused naming --train-seed; never a folder 'train 5001' (--lr nan "
         "stops the recipe before it renders either way: the first run of this case rendered the full recipe).")

# ============================================================================ orchestrate.demo
case("f38-demo-checkpoint-malicious-pickle", "archive", DEMO + ' --out "$C/d" --objects 1 --checkpoint "$C/i/m.pt"' +
     left("$C/d/data", "rendered before the checkpoint was checked"), names=["--checkpoint"],
     setup=evil_pt("i/m.pt"),
     why="A checkpoint whose unpickling runs code is refused naming --checkpoint before rendering; no "
         "/tmp/pwn_<case> file.")
case("f38-demo-spp-huge", "input", DEMO + ' --out "$C/d" --spp 99999999999' + left("$C/d/data", "rendered"),
     names=["--spp"], why="An spp beyond Mitsuba's 32-bit sample count is refused naming --spp before rendering.")
case("f38-demo-data-other-seed-edited", "writer", DEMO + ' --out "$C/d" --objects 3 --images 4 --res 32 --spp 8',
     names=["data"], setup='mkdir d; cp -r "$F/data" d/data',
     why="A demo folder whose data/ was made with another seed and light set is refused naming data/ and "
         "--overwrite; its objects are not resumed into a mixed dataset.")
case("f38-demo-summary-a-folder", "writer", DEMO + ' --out "$C/d" --objects 1 --images 4 --res 32 --spp 1',
     expect="either", names=["summary.md"], setup="mkdir -p d/summary.md; echo mine > d/summary.md/keep",
     may_change=["$C/d/data", "$C/d/data/*", "$C/d/pred", "$C/d/pred/*", "$C/d/rerender", "$C/d/rerender/*",
                 "$C/d/*.png", "$C/d/*.json"], timeout=115,
     why="A folder where summary.md goes is refused naming it (ideally before rendering), never removed.")
