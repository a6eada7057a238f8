"""Sweep 39, part j: the GENERATOR and RELAY side once more (wildgen.make / preview / sensor / export,
orchestrate.gpu_session --pack and CPU-rehearsal sessions, orchestrate.train_recipe, orchestrate.demo,
orchestrate.docs), with cases that cases37_*.py, cases38_*.py and tests/test_bad_inputs.py do not hold.

What a new user gets wrong and what an attacker plants:
- asset libraries with odd-but-valid or subtly broken files: an OBJ without faces, one whose coordinate overflows
  float32, a PLY header that lies about its vertex count, an STL of zero triangles, an HDR header without pixels, a
  1x1 HDR map, an EXR map holding NaN, a texture set without its base colour, mixed-case extensions;
- object folders edited by hand between a make and a resume / export / preview / sensor (scene.json changed, an
  image replaced by a folder or by a 1x1 PNG, a file renamed to upper case), manifest.json configuration values out
  of range (images 0, seed negative, margin above 1, NaN exposure, an unknown camera, a reversed focal range, ...),
  `complete` written as a string;
- relay packs whose archives disagree with what the session expects (an assets archive planting code into
  --work/site, an empty site archive, an assets archive of only a README);
- flags whose combination contradicts (reversed ranges, a check of more objects than are rendered, --pack with
  --carry, a recipe --init-from of another architecture).

Cases whose command adds its own check print a line starting with `FAULT:` and exit so that the harness flags it.
Every render is as small as wildgen.make allows (TINY: one 16-px object, 2 images, 1 spp).
"""
from __future__ import annotations

import textwrap

TINY = "--objects 1 --images 2 --res 16 --spp 1 --gt-spp 1 --workers 0 --quiet"
"""The smallest render wildgen.make takes (one 16-px object, 2 images)."""
MK = "$PY -m wildgen.make"
MKA = MK + ' --out "$C/out" --assets "$C/assets" ' + TINY
"""wildgen.make of one tiny object with the asset library in $C/assets."""
RES = f'{MK} --out "$C/out" --resume --workers 0 --quiet'
"""Resume the dataset in $C/out (a copy of $F/data) with its manifest's configuration."""
PV = "$PY -m wildgen.preview"
SEN = "$PY -m wildgen.sensor --quiet"
EX = "$PY -m wildgen.export --quiet"
GS = "$PY -m orchestrate.gpu_session"
SESS = (GS + ' --out "$C/o" --work "$C/w" --carry "$C/c" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1'
        " --check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
"""A CPU rehearsal of a session on the pack in $C/c, as small as it goes (bounded by its --minutes)."""
SESS_PLAIN = (GS + ' --out "$C/o" --work "$C/w" --cpu-rehearsal --objects 1 --images 3 --res 16 --spp 1 '
              "--check-variant none --minutes 1 --reserve-s 30 --steps 1 --batch 1")
"""The same session without a pack."""
PACK = GS + ' --pack "$C/p" --wheels "$C/whl"'
RC = "$PY -m orchestrate.train_recipe"
RCW = RC + ' --work "$C/w" --assets none --train-objects 1 --steps 1 --threads 1'
DEMO = "$PY -m orchestrate.demo"
DS = 'cp -r "$F/data" d\n'
"""Setup: d/, a copy of the 3-object 32-px dataset (with its manifest.json)."""
OUTDS = 'cp -r "$F/data" out\n'
"""Setup: out/, a copy of the dataset, as wildgen.make would find it when resuming."""
OUT = ["$C/out", "$C/out/*", "$C/out/*/*", "$C/out/*/*/*"]
SESS_CHANGE = ["$C/o", "$C/o/*", "$C/o/*/*", "$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*", "$C/w/*/*/*/*"]
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
"""Setup: whl/, two tiny wheels that pass the pack's name and version checks."""
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
    """Setup: record the current SHA-256 of FOLDER/OBJ.data/NAME in FOLDER/manifest.json (an attacker who edits a
    file and its checksum together)."""
    return manifest(folder, f"""
        import hashlib
        e = next(e for e in m['objects'] if str(e.get('name', '')).startswith('{obj}'))
        e['files']['{name}'] = hashlib.sha256(open('{folder}/{obj}.data/{name}', 'rb').read()).hexdigest()
        """)


def mktar(path: str, body: str, mode: str = "w:xz") -> str:
    """Setup: the tar `path` (relative to $C) written by `body` (Python, with `tar` open and `add(tar, name,
    data=b'')`)."""
    return (f'mkdir -p "$(dirname {path})"\n$PY - <<\'EOF\'\nimport io, os, tarfile\n'
            "def add(tar, name, data=b''):\n"
            "    ti = tarfile.TarInfo(name); ti.mode = 0o644; ti.size = len(data); tar.addfile(ti, io.BytesIO(data))\n"
            f"with tarfile.open({path!r}, {mode!r}, format=tarfile.PAX_FORMAT) as tar:\n"
            + textwrap.indent(body.strip("\n"), "    ") + "\nEOF\n")


GOOD_SITE = mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')")
"""Setup: c/site.tar.xz, a valid one-package pack (no assets)."""


def left(path: str, what: str) -> str:
    """Command tail: a refusal that left `path` behind exits 0 with a FAULT line (flagged exit0)."""
    return (f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r')


def nosite() -> str:
    return left("$C/w/site", "--work/site unpacked before the arguments were checked")


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


# ============================================================================ wildgen.make: asset libraries
case("j39-make-obj-without-faces", "input", MKA + " --shapes mesh", names=["noface.obj"], timeout=90,
     setup="mkdir -p assets/meshes; printf 'v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nv 0 0 1\\n' > assets/meshes/noface.obj",
     why="An OBJ of vertices only (a point cloud) holds no surface: named before rendering, not a per-object "
         "failure or an empty mask after the render.")
case("j39-make-obj-vertex-overflows-float32", "input", MKA + " --shapes mesh", names=["big.obj"], timeout=90,
     setup="mkdir -p assets/meshes; printf 'v 1e39 0 0\\nv 0 1 0\\nv 0 0 1\\nv 1 1 1\\nf 1 2 3\\nf 2 3 4\\n' "
           "> assets/meshes/big.obj",
     why="1e39 is finite in float64 but inf in float32 (what Mitsuba stores): the mesh is named as non-finite "
         "up front, not normalised into NaN vertices.")
case("j39-make-obj-face-index-beyond-vertices", "input", MKA + " --shapes mesh", names=["far.obj"], timeout=90,
     setup="mkdir -p assets/meshes; printf 'v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nf 1 2 99\\n' > assets/meshes/far.obj",
     why="A face naming vertex 99 of 3 is refused naming the file (trimesh drops such faces silently).")
case("j39-make-obj-relative-index-beyond", "input", MKA + " --shapes mesh", names=["rel.obj"], timeout=90,
     setup="mkdir -p assets/meshes; printf 'v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nf -1 -2 -7\\n' > assets/meshes/rel.obj",
     why="A relative face index reaching before the first vertex is refused naming the file.")
case("j39-make-obj-all-faces-degenerate", "input", MKA + " --shapes mesh", names=["line.obj"], timeout=90,
     setup="mkdir -p assets/meshes; printf 'v 0 0 0\\nv 1 0 0\\nv 2 0 0\\nv 3 0 0\\nf 1 2 3\\nf 2 3 4\\n' "
           "> assets/meshes/line.obj",
     why="A mesh whose faces all have zero area (collinear vertices) has no surface: named up front as "
         "unusable, not a division by zero when its normals are computed.")
case("j39-make-ply-header-count-lies", "input", MKA + " --shapes mesh", names=["lie.ply"], timeout=90,
     setup="mkdir -p assets/meshes; printf 'ply\\nformat ascii 1.0\\nelement vertex 100\\nproperty float x\\n"
           "property float y\\nproperty float z\\nelement face 1\\nproperty list uchar int vertex_indices\\n"
           "end_header\\n0 0 0\\n1 0 0\\n0 1 0\\n3 0 1 2\\n' > assets/meshes/lie.ply",
     why="A PLY header claiming 100 vertices over 3 lines of data is refused naming the file.")
case("j39-make-stl-zero-triangles", "input", MKA + " --shapes mesh", names=["none.stl"], timeout=90,
     setup="mkdir -p assets/meshes; " + py("""
        import struct
        open("assets/meshes/none.stl", "wb").write(b"\\0" * 80 + struct.pack("<I", 0))
        """),
     why="A binary STL of zero triangles is named as holding no surface before rendering.")
case("j39-make-obj-bytes-of-a-ply", "input", MKA + " --shapes mesh", names=["swap.obj"], timeout=90,
     setup="mkdir -p assets/meshes; cp \"$F/data/00000.data/aux/mesh.ply\" assets/meshes/swap.obj",
     why="A binary PLY saved under an .obj name is named (its suffix says text), not parsed as garbage vertices.")
case("j39-make-mesh-upper-case-suffix", "exit0", MKA + " --shapes mesh && " + COMPLETE, expect="ok",
     setup="mkdir -p assets/meshes; cp " + SPHERE + " assets/meshes/BALL.OBJ", may_change=OUT, timeout=110,
     why="An upper-case .OBJ is a mesh like .obj (suffixes are compared in lower case): the run completes.")
case("j39-make-hdr-upper-case-suffix", "exit0",
     MKA + " --lights hdri && " + COMPLETE + " && grep -q ROOM.HDR out/00000.data/scene.json || "
     "{ echo 'FAULT: ROOM.HDR not used'; exit 3; }", expect="ok",
     setup="mkdir -p assets/hdri; cp " + HDR + " assets/hdri/ROOM.HDR", may_change=OUT, timeout=110,
     why="An upper-case .HDR map is an environment map of the library: the hdri object uses it.")
case("j39-make-hdr-one-pixel", "input", MKA + " --lights hdri", expect="either", names=["tiny.hdr"],
     setup="mkdir -p assets/hdri; " + py("""
        import numpy as np, cv2
        cv2.imwrite("assets/hdri/tiny.hdr", np.full((1, 1, 3), 0.5, np.float32))
        """), may_change=OUT, timeout=110,
     why="A 1x1 map is a uniform environment: rendered, or refused in one line naming tiny.hdr; never a "
         "traceback from a zero-width resampling.")
case("j39-make-hdr-header-without-pixels", "input", MKA + " --lights hdri", names=["cut.hdr"], timeout=90,
     setup="mkdir -p assets/hdri; printf '#?RADIANCE\\nFORMAT=32-bit_rle_rgbe\\n\\n-Y 64 +X 128\\n' "
           "> assets/hdri/cut.hdr",
     why="A Radiance header with no pixel data is named before rendering, not read as a black map at render time.")
case("j39-make-exr-map-with-nan", "input", MKA + " --lights hdri", names=["nan.exr"], timeout=90,
     setup="mkdir -p assets/hdri; " + py("""
        import numpy as np
        from scenes.exr import write_exr
        a = np.full((16, 32, 3), 0.5, np.float32); a[3, 4] = np.nan
        write_exr("assets/hdri/nan.exr", a)
        """),
     why="One NaN texel makes every image lit by the map NaN: the map is named up front like a black one.")
case("j39-make-exr-map-negative", "input", MKA + " --lights hdri", names=["neg.exr"], timeout=90,
     setup="mkdir -p assets/hdri; " + py("""
        import numpy as np
        from scenes.exr import write_exr
        a = np.full((16, 32, 3), 0.5, np.float32); a[:, :8] = -4.0
        write_exr("assets/hdri/neg.exr", a)
        """),
     why="Negative radiance is no light: the map is named up front, not importance-sampled with negative weights.")
case("j39-make-texture-set-without-base-colour", "input", MKA, names=["--assets"], timeout=90,
     setup="mkdir -p assets/textures/wood; " + py("""
        import numpy as np, cv2
        cv2.imwrite("assets/textures/wood/wood_rough.png", np.full((8, 8), 128, np.uint8))
        cv2.imwrite("assets/textures/wood/wood_nor_gl.png", np.full((8, 8, 3), (255, 128, 128), np.uint8))
        """),
     why="A texture set missing its base-colour map is no set: the library then offers nothing and is refused "
         "naming --assets (not rendered procedurally as if no --assets were given).")
case("j39-make-texture-set-base-colour-only", "exit0", MKA + " && " + COMPLETE, expect="ok", may_change=OUT,
     timeout=110, setup="mkdir -p assets/textures/brick; " + py("""
        import numpy as np, cv2
        cv2.imwrite("assets/textures/brick/Brick_Diff.PNG", np.random.default_rng(0).integers(0, 255, (16, 16, 3), np.uint8))
        """),
     why="A set of just a base colour (mixed-case tag and suffix) is a valid set: the run completes.")
case("j39-make-texture-only-directx-normal", "exit0", MKA + " --detail 1 && " + COMPLETE, expect="ok",
     may_change=OUT, timeout=110, setup="mkdir -p assets/textures/t; " + py("""
        import numpy as np, cv2
        cv2.imwrite("assets/textures/t/t_col.png", np.full((16, 16, 3), 100, np.uint8))
        cv2.imwrite("assets/textures/t/t_nor_dx.png", np.full((16, 16, 3), (255, 128, 128), np.uint8))
        """),
     why="A set whose only normal map is DirectX-flavoured keeps no normal map; with --detail 1 a procedural one "
         "is drawn instead; the run completes.")
case("j39-make-assets-hdri-a-plain-file", "input", MKA + " --lights hdri", names=["--assets"], timeout=90,
     setup="mkdir assets; cp " + HDR + " assets/hdri",
     why="hdri/ being a file, not a folder, leaves the library empty: refused naming --assets, not a silent "
         "procedural run.")

# ============================================================================ wildgen.make: contradicting flags
case("j39-make-cluster-reversed", "input", f'{MK} --out "$C/out" --cluster 3-2 {TINY}', names=["--cluster"],
     why="A reversed range [3, 2] draws nothing: refused naming --cluster before anything is written.")
case("j39-make-detail-strength-reversed", "input", f'{MK} --out "$C/out" --detail 1 --detail-strength 25-5 {TINY}',
     names=["--detail-strength"], why="A reversed strength range is refused naming --detail-strength.")
case("j39-make-floor-above-1", "input", f'{MK} --out "$C/out" --floor 1.5 {TINY}', names=["--floor"],
     why="A fraction of 1.5 of the objects on a floor is refused naming --floor.")
case("j39-make-floor-nan", "input", f'{MK} --out "$C/out" --floor nan {TINY}', names=["--floor"],
     why="A nan fraction compares False everywhere (no floor, silently): refused naming --floor.")
case("j39-make-pose-tries-0", "input", f'{MK} --out "$C/out" --pose-tries 0 {TINY}', names=["--pose-tries"],
     why="Zero poses tried skips every object: refused naming --pose-tries, not a run that writes nothing.")
case("j39-make-shape-tries-0", "input", f'{MK} --out "$C/out" --shape-tries 0 {TINY}', names=["--shape-tries"],
     why="Zero shapes tried skips every object: refused naming --shape-tries.")
case("j39-make-texture-resolution-0", "input", f'{MK} --out "$C/out" --texture-resolution 0 {TINY}',
     names=["--texture-resolution"], why="A texture side of 0 px is refused naming --texture-resolution.")
case("j39-make-recycle-after-negative", "input", f'{MK} --out "$C/out" --recycle-after=-1 {TINY}',
     names=["--recycle-after"], why="A negative recycle count is refused naming --recycle-after.")

# ============================================================================ wildgen.make: manifest values out of range
def mres(id: str, code: str, names, why: str) -> None:
    case(id, "input", RES, names=names, setup=OUTDS + manifest("out", code), timeout=90, why=why)


mres("j39-make-manifest-images-0", "m['config']['images'] = 0; m['config']['objects'] = 4", ["manifest.json"],
     "Zero images per object in the manifest is refused naming manifest.json before the 4th object is rendered.")
mres("j39-make-manifest-seed-negative", "m['config']['seed'] = -1; m['config']['objects'] = 4", ["manifest.json"],
     "A negative seed in the manifest is refused as the flag is, naming manifest.json.")
mres("j39-make-manifest-margin-above-1", "m['config']['margin'] = 1.5; m['config']['objects'] = 4", ["manifest.json"],
     "A margin above the half image size leaves no room for the object: refused naming manifest.json.")
mres("j39-make-manifest-exposure-level-nan", "m['config']['exposure_level'] = float('nan'); m['config']['objects'] = 4",
     ["manifest.json"], "A NaN exposure level (JSON NaN) makes every image NaN: refused naming manifest.json.")
mres("j39-make-manifest-camera-unknown", "m['config']['camera'] = 'fisheye'; m['config']['objects'] = 4",
     ["manifest.json"], "An unknown camera kind in the manifest is refused naming manifest.json and 'fisheye'.")
mres("j39-make-manifest-focal-reversed", "m['config']['camera'] = 'perspective'; m['config']['focal'] = '300-15'; "
     "m['config']['objects'] = 4", ["manifest.json"],
     "A reversed focal range in the manifest is refused as the flag is, naming manifest.json.")
mres("j39-make-manifest-cluster-9", "m['config']['cluster'] = '9-9'; m['config']['objects'] = 4", ["manifest.json"],
     "Clusters of more than 8 objects are refused for the flag; from the manifest too, naming manifest.json.")
mres("j39-make-manifest-detail-5", "m['config']['detail'] = 5; m['config']['objects'] = 4", ["manifest.json"],
     "A detail fraction of 5 is refused naming manifest.json.")
mres("j39-make-manifest-gt-spp-0", "m['config']['gt_spp'] = 0; m['config']['objects'] = 4", ["manifest.json"],
     "A ground-truth pass of 0 samples is refused naming manifest.json, not normals of all zeros.")
mres("j39-make-manifest-sensor-unknown", "m['config']['sensor'] = 'lomo'; m['config']['objects'] = 4",
     ["manifest.json"], "An unknown sensor preset in the manifest is refused naming manifest.json and 'lomo'.")
mres("j39-make-manifest-variant-mono", "m['config']['variant'] = 'llvm_mono'; m['config']['objects'] = 4",
     ["manifest.json"], "A variant the flag refuses (mono) is refused from the manifest too, naming manifest.json.")
mres("j39-make-manifest-bounces-beyond-int32", "m['config']['bounces'] = 2**40; m['config']['objects'] = 4",
     ["manifest.json"], "Bounces beyond Mitsuba's 32-bit max_depth are refused naming manifest.json.")
mres("j39-make-manifest-complete-all-done-config-bad",
     "m['config']['images'] = -3", ["manifest.json"],
     "Even with every object done (nothing to render), a resume reads the configuration and refuses images -3 "
     "naming manifest.json rather than exit 0 on a manifest no flag could have written.")

# ============================================================================ readers: folders edited by hand
case("j39-export-scene-json-edited", "input", EX + ' --data "$C/d" --out "$C/sh"', names=["scene.json"],
     setup=DS + "echo >> d/00001.data/scene.json", may_change=["$C/sh", "$C/sh/*"],
     why="A scene.json edited after the render no longer matches the manifest's checksum: the export names it "
         "(and 00001) instead of shipping lights that no longer describe the images.")
case("j39-export-manifest-complete-a-string", "input", EX + ' --data "$C/d" --out "$C/sh"', names=["manifest.json"],
     setup=DS + manifest("d", "m['complete'] = 'false'"), may_change=["$C/sh", "$C/sh/*"],
     why="complete: 'false' (a string, truthy) is not a finished dataset: refused naming manifest.json.")
case("j39-export-object-folder-upper-case", "input", EX + ' --data "$C/d" --out "$C/sh"', names=["00001"],
     setup=DS + "mv d/00001.data d/00001.DATA", may_change=["$C/sh", "$C/sh/*"],
     why="The manifest lists 00001.data, which is gone (renamed .DATA): refused naming 00001, not an export of 2 "
         "objects presented as the dataset.")
case("j39-export-data-is-shards", "input", EX + ' --data "$F/shards" --out "$C/sh"', names=["--data"],
     may_change=["$C/sh", "$C/sh/*"],
     why="Exporting a folder of shards (no object folders) is refused naming --data, not an empty export.")
case("j39-export-user-file-in-object", "exit0",
     EX + ' --data "$C/d" --out "$C/sh"; r=$?; [ $r = 0 ] || exit $r; $PY -c "'
     "import tarfile,glob,sys; n=[m.name for t in glob.glob('sh/*.tar') for m in tarfile.open(t)]; "
     "sys.exit('FAULT: an unlisted file was exported' if any('secret' in x for x in n) else 0)\"", expect="either", names=["secret.txt"],
     setup=DS + "echo 'api_key=123' > d/00000.data/secret.txt", may_change=["$C/sh", "$C/sh/*"],
     why="A file the manifest does not list (a user's note, a planted key) is either refused naming it or left "
         "out; it never travels inside a shard as part of the object.")
case("j39-preview-scene-json-a-list", "input", PV + ' "$C/d" --out "$C/pv"', names=["00000"],
     setup=DS + "echo '[]' > d/00000.data/scene.json" + "\n" + rechecksum("d", "00000", "scene.json"),
     may_change=["$C/pv", "$C/pv/*"],
     why="A scene.json that is a list (checksum updated too) fails that object, named; the others are drawn, "
         "exit 1.")
case("j39-preview-image-replaced-by-folder", "input", PV + ' "$C/d" --out "$C/pv"', names=["00001"],
     setup=DS + "rm d/00001.data/L002.png; mkdir d/00001.data/L002.png", may_change=["$C/pv", "$C/pv/*"],
     why="An image that became a folder fails object 00001, named in one line; exit 1, no IsADirectoryError "
         "traceback.")
case("j39-preview-image-1px-checksummed", "input", PV + ' "$C/d" --out "$C/pv"', names=["00002"],
     setup=DS + py("""
        import numpy as np, cv2
        cv2.imwrite("d/00002.data/L001.png", np.zeros((1, 1, 3), np.uint16))
        """) + rechecksum("d", "00002", "L001.png"), may_change=["$C/pv", "$C/pv/*"],
     why="An image of 1x1 px among 32x32 ones (its checksum forged) is refused naming 00002 (sizes differ), not "
         "broadcast into a sheet.")
case("j39-preview-stats-overwrite-keeps-sheets", "exit0",
     PV + ' "$C/d" --stats --overwrite && test -s d/preview/overview.png && test -s d/preview/00000.png || '
     '{ echo "FAULT: --stats --overwrite removed the contact sheets"; exit 3; }', expect="ok",
     setup=DS + '$PY -m wildgen.preview "$C/d" >/dev/null 2>&1',
     may_change=["$C/d/preview/stats.png", "$C/d/preview/stats.json", "$C/d/preview/preview.json"],
     why="--overwrite replaces the dataset card only: the earlier contact sheets in the same folder stay "
         "byte-identical.")
case("j39-preview-out-a-fifo", "input", PV + ' "$F/data" --out "$C/pv"', names=["--out"], timeout=60,
     setup="mkfifo pv", why="--out naming a pipe is refused in one line, no hang and no traceback.")
case("j39-sensor-ideal-onto-ideal", "exit0",
     SEN + ' --data "$F/data" --sensor ideal --out "$C/s" && cmp "$F/data/00000.data/L000.png" '
     's/00000.data/L000.png || { echo "FAULT: ideal onto ideal changed the image"; exit 3; }', expect="ok",
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"],
     why="The ideal sensor is the render byte for byte: converting an ideal dataset to ideal changes no image.")
case("j39-sensor-scene-sensor-planted", "input", SEN + ' --data "$C/d" --sensor phone --out "$C/s"',
     names=["scene.json"], setup=DS + py("""
        import json
        p = "d/00000.data/scene.json"; s = json.load(open(p))
        s["sensor"] = {"name": "phone", "bits": 99, "seed": -5}
        json.dump(s, open(p, "w"))
        """) + rechecksum("d", "00000", "scene.json"),
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"],
     why="A sensor record planted in an ideal dataset's scene.json (checksum forged, 99 bits, a negative seed) "
         "is refused naming scene.json, not trusted.")
case("j39-sensor-out-a-plain-file", "input", SEN + ' --data "$F/data" --sensor phone --out "$C/s"',
     names=["--out"], setup="echo mine > s", why="--out naming a plain file is refused in one line; the file stays.")
case("j39-sensor-manifest-complete-no", "input", SEN + ' --data "$C/d" --sensor phone --out "$C/s"',
     names=["manifest.json"], setup=DS + manifest("d", "m['complete'] = 'no'"),
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"],
     why="complete: 'no' is a string, not true: the dataset is refused naming manifest.json.")
case("j39-sensor-two-into-one-out", "writer",
     both(SEN + ' --data "$F/data" --sensor phone --out "$C/s"', SEN + ' --data "$F/data" --sensor webcam --out "$C/s"',
          "$PY -c \"import json,sys; m=json.load(open('s/manifest.json')); sys.exit(0 if m.get('complete') else "
          "'FAULT: incomplete')\""),
     expect="ok", may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*", "$C/a.log", "$C/b.log"],
     why="Two conversions into one --out: one holds the folder, the other is refused in one line (--out); the "
         "folder holds one complete dataset, not a mix of phone and webcam images.")

# ============================================================================ gpu_session: packs and flags
case("j39-relay-assets-member-into-site", "archive", SESS + left("$C/w/site/sitecustomize.py", "planted into site"),
     names=["assets.tar.xz"], setup=GOOD_SITE + mktar(
         "c/assets.tar.xz", "add(tar, 'assets/hdri/x.hdr', b'')\n"
         "add(tar, 'assets/../site/sitecustomize.py', b'open(\"/tmp/pwn_j39_site\", \"w\")')"),
     may_change=SESS_CHANGE,
     why="An assets archive member climbing into --work/site would run code in every step: refused naming "
         "assets.tar.xz; no sitecustomize.py appears.")
case("j39-relay-site-empty-file", "archive", SESS + nosite(), names=["site.tar.xz"],
     setup="mkdir c; : > c/site.tar.xz",
     why="An empty site.tar.xz (an interrupted upload) is refused naming it; nothing unpacked.")
case("j39-relay-assets-only-readme", "input", SESS, names=["--carry"], may_change=SESS_CHANGE,
     setup=GOOD_SITE + mktar("c/assets.tar.xz", "add(tar, 'assets/README.md', b'# nothing')"), timeout=115,
     why="An assets archive holding only a README offers nothing to draw: refused naming --carry (or its "
         "assets), not a session that silently renders procedural objects.")
case("j39-gs-check-objects-beyond-objects", "order", SESS_PLAIN.replace("--check-variant none", "--check-variant "
     "scalar_rgb") + " --check-objects 5" + left("$C/w/data", "rendered before refusing --check-objects"),
     names=["--check-objects"], may_change=SESS_CHANGE, timeout=90,
     why="Checking 5 objects of a 1-object render is refused naming --check-objects (and --objects) before "
         "rendering.")
case("j39-gs-ckpt-minutes-0", "order", SESS_PLAIN + " --ckpt-minutes 0" + left("$C/w/data", "rendered"),
     names=["--ckpt-minutes"], may_change=SESS_CHANGE, timeout=90,
     why="Saving last.pt every 0 minutes (every step) is refused naming --ckpt-minutes before rendering.")
case("j39-gs-noise-cv-0", "order", SESS_PLAIN.replace("--check-variant none", "--check-variant scalar_rgb")
     + " --noise-cv 0" + left("$C/w/data", "rendered"), names=["--noise-cv"], may_change=SESS_CHANGE, timeout=90,
     why="A zero noise tolerance fails every check by construction: refused naming --noise-cv before rendering.")
case("j39-gs-spp-0", "order", SESS_PLAIN.replace("--spp 1", "--spp 0") + left("$C/w/data", "rendered"),
     names=["--spp"], may_change=SESS_CHANGE, timeout=90,
     why="0 samples per pixel is refused naming the session's --spp, not wildgen.make's after a start-up.")
case("j39-gs-lr-negative", "order", SESS_PLAIN + " --lr=-0.001" + left("$C/w/data", "rendered"),
     names=["--lr"], may_change=SESS_CHANGE, timeout=90,
     why="A negative learning rate (gradient ascent) is refused naming --lr before rendering.")
case("j39-gs-objects-0", "order", SESS_PLAIN.replace("--objects 1", "--objects 0") + left("$C/w/data", "rendered"),
     names=["--objects"], may_change=SESS_CHANGE, timeout=90,
     why="A session of 0 objects has nothing to train on: refused naming --objects.")
case("j39-pack-with-carry", "input", PACK + ' --assets none --carry "$C/c"' + left("$C/p/site.tar.xz", "packed"),
     names=["--carry"], setup=WHEELS + GOOD_SITE, may_change=["$C/p", "$C/p/*"], timeout=60,
     why="--pack writes a pack, --carry reads one: together they contradict, refused naming --carry.")
case("j39-pack-wheels-empty", "input", GS + ' --pack "$C/p" --wheels "$C/whl" --assets none', names=["--wheels"],
     setup="mkdir whl", timeout=60, why="An empty wheels folder is refused naming --wheels (mitsuba missing).")
case("j39-pack-wheel-other-python", "input", GS + ' --pack "$C/p" --wheels "$C/whl" --assets none',
     names=["--wheels"], setup=WHEELS + "cd whl; mv mitsuba-3.9.1-cp312-cp312-manylinux_2_28_x86_64.whl "
     "mitsuba-3.9.1-cp311-cp311-manylinux_2_28_x86_64.whl", timeout=60,
     why="A cp311 Mitsuba wheel does not import on the GPU image's Python 3.12: refused naming --wheels.")
case("j39-pack-wheel-member-escapes", "archive",
     GS + ' --pack "$C/p" --wheels "$C/whl" --assets none', names=["mitsuba"], timeout=60,
     setup=WHEELS + py("""
        import zipfile, os
        with zipfile.ZipFile("whl/mitsuba-3.9.1-cp312-cp312-manylinux_2_28_x86_64.whl", "w") as z:
            z.writestr("mitsuba/__init__.py", "")
            z.writestr("../../evil_j39_wheel.py", "x")
        """), may_change=["$C/p", "$C/p/*"],
     why="A wheel member climbing out of the site is refused naming the wheel; no evil_j39_wheel.py appears.")
case("j39-pack-assets-obj-without-faces", "input", GS + ' --pack "$C/p" --wheels "$C/whl" --assets "$C/assets"',
     names=["noface.obj"], timeout=110, setup=WHEELS + "mkdir -p assets/meshes assets/hdri\n"
     "for i in 1 2 3 4; do cp " + SPHERE + " assets/meshes/m$i.obj; cp " + HDR + " assets/hdri/h$i.hdr; done\n"
     "printf 'v 0 0 0\\nv 1 0 0\\nv 0 1 0\\n' > assets/meshes/a_noface.obj",
     may_change=["$C/p", "$C/p/*"],
     why="A mesh of no faces in the training split is named when packing, not carried to fail the GPU session.")

# ============================================================================ orchestrate.train_recipe
case("j39-recipe-lr-0", "input", RCW + " --lr 0" + left("$C/w", "--work created"), names=["--lr"],
     may_change=["$C/w", "$C/w/*"], why="A zero learning rate trains nothing: refused naming --lr before any step.")
case("j39-recipe-train-seed-trailing-comma", "input", RCW + " --train-seed 5000," + left("$C/w", "--work created"),
     names=["--train-seed"], may_change=["$C/w", "$C/w/*"],
     why="'5000,' holds an empty seed: refused naming --train-seed, not a set of seed 0.")
case("j39-recipe-assets-empty-folder", "input", RCW.replace("--assets none", '--assets "$C/a"')
     + left("$C/w", "--work created"), names=["--assets"], setup="mkdir a", may_change=["$C/w", "$C/w/*"],
     why="An empty asset folder has nothing to split: refused naming --assets before --work is made.")
case("j39-recipe-init-from-other-architecture", "order", RCW + ' --model glc-tiny --init-from '
     '"$F/run/final.safetensors"' + left("$C/w/train5000", "rendered before refusing"), names=["--init-from"],
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"], timeout=90,
     why="glc-test weights cannot continue a glc-tiny run: refused naming --init-from before any rendering.")
case("j39-recipe-init-from-a-folder", "input", RCW + ' --init-from "$F/run"' + left("$C/w", "--work created"),
     names=["--init-from"], may_change=["$C/w", "$C/w/*"],
     why="--init-from naming a run folder (not its weights file) is refused naming it.")

# ============================================================================ orchestrate.demo
case("j39-demo-data-a-link-to-fixtures", "writer", DEMO + ' --out "$C/d" --objects 3 --images 4 --res 32 --spp 8',
     names=["data"], setup='mkdir d; ln -s "$F/data" d/data', may_change=["$C/d", "$C/d/*"], timeout=110,
     why="data/ linked to a dataset elsewhere is not the demo's: refused naming data; nothing is written through "
         "the link (the harness checks $F).")
case("j39-demo-checkpoint-empty-file", "order", DEMO + ' --out "$C/d" --checkpoint "$C/w.safetensors" --objects 1 '
     '--images 4 --res 32 --spp 1' + left("$C/d/data", "rendered before reading the checkpoint"),
     names=["--checkpoint"], setup=": > w.safetensors", may_change=["$C/d", "$C/d/*"], timeout=90,
     why="An empty model file is refused naming --checkpoint before the data is rendered.")
case("j39-demo-checkpoint-training-pt", "order", DEMO + ' --out "$C/d" --checkpoint "$F/run/last.pt" --objects 1 '
     '--images 4 --res 32 --spp 1', expect="either", names=["--checkpoint"],
     may_change=["$C/d", "$C/d/*", "$C/d/*/*", "$C/d/*/*/*", "$C/d/*/*/*/*"], timeout=115,
     why="A training checkpoint (last.pt, with optimizer state) is read as weights only, or refused naming "
         "--checkpoint before rendering; never unpickled in full.")
case("j39-demo-seed-beyond-64-bit", "input", DEMO + ' --out "$C/d" --seed 18446744073709551616'
     + left("$C/d/data", "rendered"), names=["--seed"], may_change=["$C/d", "$C/d/*"],
     why="A seed beyond 64 bits is refused naming the demo's --seed, not wildgen.make's after a subprocess.")
case("j39-demo-objects-negative", "input", DEMO + ' --out "$C/d" --objects=-2' + left("$C/d", "--out created"),
     names=["--objects"], why="A negative object count is refused naming --objects before --out is created.")

# ============================================================================ orchestrate.docs
case("j39-docs-extra-argument", "input", DOCS + " docs/model.md", names=["model.md"], setup=REPO_COPY, timeout=110,
     why="orchestrate.docs takes no page argument: refused in one line naming it; nothing rewritten.")
case("j39-docs-end-without-begin", "input", DOCS + " --check", names=["surface.md"], timeout=110,
     setup=REPO_COPY + "printf '\\n<!-- END generated:flags:orchestrate.surface -->\\n' >> repo/docs/surface.md",
     why="A stray END marker is refused naming the page, not ignored by --check.")
case("j39-docs-unknown-block-name", "input", DOCS + " --check", names=["results.md", "no.such"], timeout=110,
     setup=REPO_COPY + "printf '\\n<!-- BEGIN generated:flags:no.such.module -->\\n<!-- END generated:flags:"
     "no.such.module -->\\n' >> repo/docs/results.md",
     why="A block naming a module that does not exist is refused naming the page and the block.")
case("j39-docs-page-a-folder", "input", DOCS + " --check", names=["results.md"], timeout=110,
     setup=REPO_COPY + "rm repo/docs/results.md; mkdir repo/docs/results.md",
     why="A doc page that is a folder is named in one line, no IsADirectoryError traceback.")
case("j39-docs-check-read-only-tree", "exit0", DOCS + " --check", expect="ok", timeout=110,
     setup=REPO_COPY + "chmod -R a-w repo/docs repo/README.md",
     why="--check on an up-to-date tree made read-only writes nothing and exits 0.")
case("j39-docs-crlf-page", "writer", DOCS + " --check", expect="either", names=["surface.md"], timeout=110,
     setup=REPO_COPY + "sed -i 's/$/\\r/' repo/docs/surface.md",
     why="A page saved with CRLF endings: reported stale naming surface.md, or found current; never a traceback.")
