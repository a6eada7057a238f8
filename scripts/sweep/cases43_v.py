"""Sweep 43, part v: the GENERATOR and RELAY side (wildgen.make / sensor / export / preview, validate.rerender on
scene.json, orchestrate.gpu_session --pack / --carry, orchestrate.docs / demo), with cases that cases37-42 and the
tests do not hold.

Angles:
- mesh files as exporters write them: quads and n-gons, several objects in one OBJ, UVs without normals, normals of
  zero length or fewer normals than vertices, a missing MTL, PLY with extra properties, odd list widths, the
  toolkit's own PLY layout with zero normals or NaN texture coordinates, ASCII STL;
- maps and textures: HDR maps of 4096x1 / 1x4096, EXR maps with inf or an alpha channel, texture sets whose maps
  differ in size, carry alpha, hold EXR roughness outside [0, 1] or NaN, a grey normal or ARM map; asset folders
  linked into each other;
- the relay's --pack of an asset library with EXR maps (valid for wildgen.make) and texture maps the renderer refuses;
  carried archives whose member names collide after normalisation (./a vs a, a//b vs a/b, a file and a folder of
  one name) or differ only by case / Unicode form, names with tabs;
- chains: make -> sensor -> export -> train with one artefact edited by hand in between (a checksum, an object
  folder renamed or duplicated, one object's scene.json copied into another, index.json counts), --resume after a
  flag changes;
- paths with tabs and newlines for --out of sensor / export / preview.

Cases whose command adds its own check print a line starting with `FAULT:` and exit non-zero under expect "ok"
(flagged `failed`); `ok_or_refused` accepts a clean refusal as well as a run that passes its check.
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
PACK = GS + ' --pack "$C/p" --wheels "$C/whl" --assets "$C/assets"'
TR = ("$PY -m unips.train --model glc-test --res 16 --no-progress --threads 1 --batch 1 --pixels 50 "
      "--canonical-points 50 --max-images 4")
"""The cheapest training command (glc-test at 16 px); add --data, --out, --steps."""
RRD = ('$PY -m validate.rerender --data d --normals "$F/pred8/00000/normal.png" --out r --spp 1 --no-floors '
       '--threshold 0.5')
"""validate.rerender of the object folder d/ (a copy of data8/00000.data) in its known-scene mode, as cheap as it goes."""
DEMO = "$PY -m orchestrate.demo"
DS = 'cp -r "$F/data" d\n'
"""Setup: d/, a copy of the 3-object 32-px dataset (with its manifest.json)."""
OUTDS = 'cp -r "$F/data" out\n'
"""Setup: out/, a copy of the dataset, as wildgen.make would find it when resuming."""
OBJ = 'cp -r "$F/data8/00000.data" d\n'
"""Setup: d/, an object folder with its scene.json (the known-scene mode of validate.rerender)."""
OUT = ["$C/out", "$C/out/*", "$C/out/*/*", "$C/out/*/*/*"]
SH = ["$C/sh", "$C/sh/*"]
RUN = ["$C/run", "$C/run/*", "$C/run/*/*"]
R = ["$C/r", "$C/r/*", "$C/r/*/*"]
SESS_CHANGE = ["$C/o", "$C/o/*", "$C/o/*/*", "$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*", "$C/w/*/*/*/*"]
SPHERE = '"$F/assets/meshes/sphere/sphere.obj"'
TORUS = '"$F/assets/meshes/torus/torus.obj"'
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
PACK_LIB = (WHEELS + "mkdir -p assets/meshes assets/hdri\n"
            "for i in 1 2 3 4; do cp " + SPHERE + " assets/meshes/m$i.obj; done\n")
"""Setup: whl/ and assets/ with 4 meshes (a training split exists); the HDR maps are added by each case."""
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
    data=b'', dir=False)`)."""
    return (f'mkdir -p "$(dirname {path})"\n$PY - <<\'EOF\'\nimport io, os, tarfile\n'
            "def add(tar, name, data=b'', dir=False):\n"
            "    ti = tarfile.TarInfo(name); ti.mode = 0o755 if dir else 0o644\n"
            "    if dir:\n"
            "        ti.type = tarfile.DIRTYPE; tar.addfile(ti); return\n"
            "    ti.size = len(data); tar.addfile(ti, io.BytesIO(data))\n"
            f"with tarfile.open({path!r}, {mode!r}, format=tarfile.PAX_FORMAT) as tar:\n"
            + textwrap.indent(body.strip("\n"), "    ") + "\nEOF\n")


GOOD_SITE = mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')")
"""Setup: c/site.tar.xz, a valid one-package pack."""
SPHERE_BYTES = "open(os.environ['F'] + '/assets/meshes/sphere/sphere.obj', 'rb').read()"
"""Python expression (inside mktar): the bytes of the fixture sphere OBJ."""


def left(path: str, what: str) -> str:
    """Command tail: a refusal that left `path` behind exits 0 with a FAULT line (flagged exit0)."""
    return (f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r')


def nosite() -> str:
    return left("$C/w/site", "--work/site unpacked before the arguments were checked")


def complete(folder: str = "out", n: int | None = None) -> str:
    cond = "m.get('complete')" + (f" and sum(e.get('status') == 'done' for e in m['objects']) == {n}" if n else "")
    return (f"$PY -c \"import json,sys; m=json.load(open('{folder}/manifest.json')); "
            f"sys.exit(0 if {cond} else 'FAULT: {folder}/manifest.json not complete')\"")


def index_objects(folder: str, n: int) -> str:
    """Command: FAULT unless FOLDER/index.json is a complete export of N objects (each listed once)."""
    return (f"$PY -c \"import json,sys; i=json.load(open('{folder}/index.json')); "
            "names=[o['name'] for s in i['shards'] for o in s['objects']]; "
            f"sys.exit(0 if i.get('complete') and i['objects'] == {n} and len(names) == {n} == len(set(names)) "
            f"else 'FAULT: {folder}/index.json holds %r objects %r' % (i.get('objects'), names))\"")


NORMALS_UNIT = py("""
    import glob, sys
    import cv2, numpy as np
    from scenes.exr import read_exr
    ds = sorted(glob.glob('out/*.data'))
    if not ds:
        sys.exit('FAULT: no object folder in out/')
    for d in ds:
        n = read_exr(d + '/aux/normal.exr')
        m = cv2.imread(d + '/mask.png', cv2.IMREAD_UNCHANGED)
        m = (m if m.ndim == 2 else m[..., 0]) > 0
        v = n.reshape(n.shape[0], n.shape[1], -1)[m][:, :3]
        if v.size == 0:
            sys.exit(f'FAULT: {d}: empty mask')
        ln = np.linalg.norm(v, axis=1)
        if not np.all(np.isfinite(v)) or np.mean(np.abs(ln - 1) > 0.05) > 0.02:
            sys.exit(f'FAULT: {d}: ground-truth normals not unit/finite inside the mask (length {np.nanmin(ln):.3g}..{np.nanmax(ln):.3g}, nan {int(np.isnan(v).any(1).sum())})')
    print('normals ok')
    """)
"""Command: FAULT unless every rendered object's ground-truth normals are finite unit vectors inside its mask."""


def ok_or_refused(cmd: str, check: str) -> str:
    """A command that may refuse cleanly (any non-zero exit: accepted; a traceback is flagged by the harness) or
    succeed, in which case `check` must pass (use with expect 'ok')."""
    return f'{{ {cmd} ; }}; r=$?; if [ $r != 0 ]; then echo "refused (rc $r)"; exit 0; fi; {check}'


CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


def mesh(name: str, code: str) -> str:
    """Setup: assets/meshes/NAME written by `code` (Python; `p` is the path, numpy as np, struct)."""
    return "mkdir -p assets/meshes\n" + py(f"import numpy as np, struct\np = 'assets/meshes/{name}'\n"
                                           + textwrap.dedent(code).strip())


def text(name: str, body: str) -> str:
    """Setup: assets/meshes/NAME with `body` (a Python string literal's content, \\n for newlines)."""
    return "mkdir -p assets/meshes\n" + py(f"open('assets/meshes/{name}', 'w').write({body!r})")


CUBE_V = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
CUBE_Q = "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
"""A cube of 8 vertices and 6 quads (outward-facing)."""

# ============================================================================ wildgen.make: meshes as exporters write them
MESH = MKA + " --shapes mesh"
case("v43-make-obj-quads-only", "input", MESH + " && " + complete() + " && " + NORMALS_UNIT, expect="ok",
     setup=text("cube.obj", CUBE_V + CUBE_Q), may_change=OUT, timeout=110,
     why="A cube of quads (what most modelling tools export) is a valid mesh, triangulated on reading: the run "
         "completes with unit ground-truth normals.")
case("v43-make-obj-ngon-caps", "input", MESH + " && " + complete() + " && " + NORMALS_UNIT, expect="ok",
     setup=mesh("prism.obj", """
        a = np.linspace(0, 2 * np.pi, 7)[:-1]
        lines = [f'v {np.cos(t):.6f} {np.sin(t):.6f} {z}' for z in (-1, 1) for t in a]
        lines += ['f ' + ' '.join(str(i) for i in range(6, 0, -1)), 'f ' + ' '.join(str(i) for i in range(7, 13))]
        lines += [f'f {i + 1} {(i + 1) % 6 + 1} {(i + 1) % 6 + 7} {i + 7}' for i in range(6)]
        open(p, 'w').write('\\n'.join(lines) + '\\n')
        """), may_change=OUT, timeout=110,
     why="A hexagonal prism whose caps are 6-gons is a valid closed mesh (n-gons are fan-triangulated): rendered, "
         "no face silently dropped into a hole.")
case("v43-make-obj-two-objects-one-file", "input", MESH + " && " + complete() + " && " + NORMALS_UNIT, expect="ok",
     setup="mkdir -p assets/meshes\n" + py("""
        import os
        a = open(os.environ['F'] + '/assets/meshes/sphere/sphere.obj').read()
        b = 'o lid\\n' + '''CUBEV''' + '''CUBEF'''
        n = sum(1 for l in a.splitlines() if l.startswith('v '))
        b = ''.join(l.split()[0] + ' ' + ' '.join(str(int(x) + n) for x in l.split()[1:]) + '\\n' if l.startswith('f ')
                    else (l + '\\n') for l in b.splitlines())
        open('assets/meshes/two.obj', 'w').write('o ball\\n' + a + '\\n' + b)
        """.replace("CUBEV", CUBE_V.replace("\n", "\\n")).replace("CUBEF", CUBE_Q.replace("\n", "\\n"))),
     may_change=OUT, timeout=110,
     why="An OBJ holding two objects (o ball, o lid) is one mesh of both parts (or the first): rendered, never a "
         "traceback from a Scene where a Trimesh was expected.")
case("v43-make-obj-uvs-without-normals", "input", MESH + " && " + complete() + " && " + NORMALS_UNIT, expect="ok",
     setup=text("uvcube.obj", CUBE_V + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                + "".join("f " + " ".join(f"{v}/{(k % 4) + 1}" for k, v in enumerate(l.split()[1:])) + "\n"
                          for l in CUBE_Q.splitlines())),
     may_change=OUT, timeout=110,
     why="UVs (vt) but no vn: the normals are computed, the UVs kept: the run completes with unit normals.")
case("v43-make-obj-vn-all-zero", "input", ok_or_refused(MESH, complete() + " && " + NORMALS_UNIT), expect="ok",
     setup=mesh("flat_n.obj", """
        import os
        src = open(os.environ['F'] + '/assets/meshes/sphere/sphere.obj').read().splitlines()
        out = ['vn 0 0 0' if l.startswith('vn ') else l for l in src]
        if not any(l.startswith('vn ') for l in src):
            nv = sum(1 for l in src if l.startswith('v '))
            out = [l for l in src if not l.startswith('f ')] + ['vn 0 0 0'] * nv + [
                'f ' + ' '.join(f"{t.split('/')[0]}//{t.split('/')[0]}" for t in l.split()[1:]) for l in src if l.startswith('f ')]
        open(p, 'w').write('\\n'.join(out) + '\\n')
        """), may_change=OUT, timeout=110,
     why="Vertex normals of zero length cannot shade: refused naming the file, or replaced by computed normals; "
         "never ground-truth normals of NaN or length 0 written into a dataset that exits 0.")
case("v43-make-obj-vn-one-for-all", "input", ok_or_refused(MESH, complete() + " && " + NORMALS_UNIT), expect="ok",
     setup=mesh("onevn.obj", """
        import os
        src = open(os.environ['F'] + '/assets/meshes/sphere/sphere.obj').read().splitlines()
        keep = [l for l in src if not l.startswith(('vn ', 'f '))] + ['vn 0 0 1']
        keep += ['f ' + ' '.join(t.split('/')[0] + '//1' for t in l.split()[1:]) for l in src if l.startswith('f ')]
        open(p, 'w').write('\\n'.join(keep) + '\\n')
        """), may_change=OUT, timeout=110,
     why="One vn shared by every corner (fewer normals than vertices): a sphere shaded as a flat card is not its "
         "geometry; refused naming the file or normals recomputed; the ground truth stays unit and finite.")
case("v43-make-obj-mtllib-missing", "input", MESH, expect="either",
     setup="mkdir -p assets/meshes; { echo 'mtllib gone.mtl'; echo 'usemtl skin'; cat " + SPHERE
           + "; } > assets/meshes/withmtl.obj", may_change=OUT, timeout=110,
     why="An OBJ naming a material library that is not there (the toolkit draws its own materials): rendered, or "
         "refused in one line naming the file; no traceback.")
case("v43-make-obj-mtllib-is-a-folder", "input", MESH, expect="either",
     setup="mkdir -p assets/meshes/lib.mtl; { echo 'mtllib lib.mtl'; cat " + SPHERE + "; } > assets/meshes/m.obj",
     may_change=OUT, timeout=110,
     why="mtllib naming a folder (IsADirectoryError inside trimesh): rendered without it or refused naming the "
         "file; no traceback.")
case("v43-make-ply-ascii-extra-properties", "input", MESH + " && " + complete(), expect="ok",
     setup=text("scan.ply", "ply\nformat ascii 1.0\ncomment scanner output\nelement vertex 4\nproperty float x\n"
                "property float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
                "property uchar alpha\nproperty float quality\nelement face 4\nproperty list uchar int vertex_indices\n"
                "property uchar flags\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
                "0 0 0 255 0 0 255 0.5\n1 0 0 0 255 0 255 0.5\n0 1 0 0 0 255 255 0.5\n0 0 1 9 9 9 255 0.5\n"
                "3 0 2 1 0\n3 0 1 3 0\n3 0 3 2 0\n3 1 2 3 0\n0 1\n"),
     may_change=OUT, timeout=110,
     why="A scanner PLY with colours, alpha, a quality value, a per-face flag and an edge element is a valid "
         "tetrahedron: rendered.")
case("v43-make-ply-list-ushort-uint", "input", MESH + " && " + complete(), expect="ok",
     setup=text("wide.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
                "property double z\nelement face 4\nproperty list ushort uint vertex_indices\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"),
     may_change=OUT, timeout=110,
     why="double coordinates and a ushort/uint index list are valid PLY types: rendered.")
case("v43-make-ply-binary-list-uint-ushort", "input", MESH, expect="either",
     setup=mesh("bin.ply", """
        v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], '<f4')
        f = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
        head = ('ply\\nformat binary_little_endian 1.0\\nelement vertex 4\\nproperty float x\\nproperty float y\\n'
                'property float z\\nelement face 4\\nproperty list uint ushort vertex_indices\\nend_header\\n').encode()
        body = v.tobytes() + b''.join(struct.pack('<I3H', 3, *t) for t in f)
        open(p, 'wb').write(head + body)
        """), may_change=OUT, timeout=110,
     why="A binary PLY whose list count is 4 bytes wide and indices 2 bytes wide: read as the tetrahedron it is, "
         "or refused in one line naming bin.ply; never garbage faces or a traceback.")
case("v43-make-ply-float-indices", "input", MESH, names=["fidx.ply"],
     setup=text("fidx.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                "property float z\nelement face 4\nproperty list uchar float vertex_indices\nend_header\n"
                "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3.5\n3 0 3 2\n3 1 2 3\n"),
     may_change=OUT, timeout=110,
     why="Face indices of a float type, one of them 3.5 (no vertex has that index): refused naming fidx.ply, "
         "never truncated silently to vertex 3 (a different face than the file describes).")
case("v43-make-ply-ascii-quads", "input", MESH + " && " + complete() + " && " + NORMALS_UNIT, expect="ok",
     setup=text("qcube.ply", "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
                "property float z\nelement face 6\nproperty list uchar int vertex_index\nend_header\n"
                + CUBE_V.replace("v ", "")
                + "".join("4 " + " ".join(str(int(i) - 1) for i in l.split()[1:]) + "\n" for l in CUBE_Q.splitlines())),
     may_change=OUT, timeout=110,
     why="A PLY cube of quads, its list named vertex_index (as Blender writes it): rendered with unit normals.")
case("v43-make-ply-own-layout-zero-normals", "input", ok_or_refused(MESH, complete() + " && " + NORMALS_UNIT),
     expect="ok", setup=mesh("own0.ply", """
        v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
        f = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
        rows = np.concatenate([v, np.zeros((4, 3), np.float32), np.full((4, 2), 0.5, np.float32)], 1).astype('<f4')
        head = ('ply\\nformat binary_little_endian 1.0\\nelement vertex 4\\n'
                + ''.join(f'property float {k}\\n' for k in ('x', 'y', 'z', 'nx', 'ny', 'nz', 's', 't'))
                + 'element face 4\\nproperty list uchar int vertex_indices\\nend_header\\n').encode()
        body = rows.tobytes() + b''.join(struct.pack('<B3i', 3, *t) for t in f)
        open(p, 'wb').write(head + body)
        """), may_change=OUT, timeout=110,
     why="A PLY in the toolkit's own layout (read exactly, normals kept) whose normals are all zero: refused "
         "naming own0.ply or normals recomputed; never NaN or zero ground-truth normals with exit 0.")
case("v43-make-ply-own-layout-nan-uv", "input", MESH, names=["ownuv.ply"],
     setup=mesh("ownuv.ply", """
        v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
        n = v - v.mean(0); n /= np.linalg.norm(n, axis=1, keepdims=True)
        uv = np.full((4, 2), 0.5, np.float32); uv[2, 1] = np.nan
        rows = np.concatenate([v, n, uv], 1).astype('<f4')
        head = ('ply\\nformat binary_little_endian 1.0\\nelement vertex 4\\n'
                + ''.join(f'property float {k}\\n' for k in ('x', 'y', 'z', 'nx', 'ny', 'nz', 's', 't'))
                + 'element face 4\\nproperty list uchar int vertex_indices\\nend_header\\n').encode()
        f = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
        open(p, 'wb').write(head + rows.tobytes() + b''.join(struct.pack('<B3i', 3, *t) for t in f))
        """), timeout=90,
     why="A NaN texture coordinate samples NaN from every texture: the mesh is refused up front naming ownuv.ply.")
case("v43-make-stl-ascii", "input", MESH + " && " + complete(), expect="ok",
     setup=text("tet.stl", "solid tet\n" + "".join(
         f"facet normal 0 0 0\n outer loop\n  vertex {a}\n  vertex {b}\n  vertex {c}\n endloop\nendfacet\n"
         for a, b, c in (("0 0 0", "0 1 0", "1 0 0"), ("0 0 0", "1 0 0", "0 0 1"), ("0 0 0", "0 0 1", "0 1 0"),
                         ("1 0 0", "0 1 0", "0 0 1"))) + "endsolid tet\n"),
     may_change=OUT, timeout=110,
     why="An ASCII STL (facet normals written as 0 0 0, as many exporters do) is a valid tetrahedron: rendered.")

# ============================================================================ wildgen.make: HDR / EXR maps
HDRI = MKA + " --lights hdri"


def hdr_setup(code: str) -> str:
    return "mkdir -p assets/hdri\n" + py("import numpy as np, cv2\nfrom scenes.exr import write_exr\n"
                                         + textwrap.dedent(code).strip())


case("v43-make-hdr-4096x1", "input", HDRI, expect="either",
     setup=hdr_setup("cv2.imwrite('assets/hdri/strip.hdr', np.full((1, 4096, 3), 0.5, np.float32))"),
     may_change=OUT, timeout=110,
     why="A map one pixel tall (no latitude at all): rendered as a uniform-in-latitude environment or refused "
         "naming strip.hdr; never a traceback from a zero-height resampling or importance table.")
case("v43-make-hdr-1x4096", "input", HDRI, expect="either",
     setup=hdr_setup("cv2.imwrite('assets/hdri/pole.hdr', np.full((4096, 1, 3), 0.5, np.float32))"),
     may_change=OUT, timeout=110,
     why="A map one pixel wide (aspect 1:4096): rendered or refused naming pole.hdr; no traceback.")
case("v43-make-exr-map-inf", "input", HDRI, names=["inf.exr"], timeout=90,
     setup=hdr_setup("a = np.full((16, 32, 3), 0.5, np.float32); a[5, 7, 1] = np.inf\n"
                     "write_exr('assets/hdri/inf.exr', a)"),
     why="One infinite texel makes the map's integral infinite: named up front like a NaN one.")
case("v43-make-exr-map-rgba", "input", HDRI, expect="either",
     setup="mkdir -p assets/hdri\n" + py("""
        import numpy as np, OpenEXR
        a = np.full((16, 32), 0.5, np.float32)
        ch = {k: a.copy() for k in 'RGBA'}
        with OpenEXR.File({'compression': OpenEXR.ZIP_COMPRESSION, 'type': OpenEXR.scanlineimage}, ch) as f:
            f.write('assets/hdri/rgba.exr')
        """), may_change=OUT, timeout=110,
     why="An EXR environment map with an alpha channel (as many tools save): its RGB used, or refused naming "
         "rgba.exr; no traceback.")
case("v43-make-hdr-dangling-link", "input", HDRI, names=["gone.hdr"], timeout=90,
     setup="mkdir -p assets/hdri; cp " + HDR + " assets/hdri/a.hdr; ln -s /nonexistent/x.hdr assets/hdri/gone.hdr",
     why="A map link whose target is gone is named (every object drawing it would fail), not a traceback.")
case("v43-make-hdri-folder-linked-from-other-library", "input",
     HDRI + " && " + complete() + " && grep -q shared.hdr out/00000.data/scene.json || "
     "{ echo 'FAULT: the linked map was not used'; exit 3; }", expect="ok",
     setup="mkdir -p lib2/hdri assets; cp " + HDR + " lib2/hdri/shared.hdr; ln -s ../lib2/hdri assets/hdri",
     may_change=OUT, timeout=110,
     why="assets/hdri a relative link to another library's hdri/ (asset folders are often linked): its map is "
         "used and the run completes.")

# ============================================================================ wildgen.make: texture sets
TEX = "mkdir -p assets/textures/wood\n"


def tex(code: str) -> str:
    return TEX + py("import numpy as np, cv2\nfrom scenes.exr import write_exr\nd = 'assets/textures/wood/'\n"
                    + textwrap.dedent(code).strip())


case("v43-make-texture-maps-three-sizes", "input", MKA + " && " + complete(), expect="ok",
     setup=tex("""
        cv2.imwrite(d + 'wood_col.png', np.full((64, 64, 3), 120, np.uint8))
        cv2.imwrite(d + 'wood_rough.png', np.full((7, 5), 128, np.uint8))
        cv2.imwrite(d + 'wood_nor_gl.png', np.full((32, 8, 3), (255, 128, 128), np.uint8))
        """), may_change=OUT, timeout=110,
     why="Maps of one set in three sizes (and aspect ratios) are common: each is resampled, the run completes.")
case("v43-make-texture-base-rgba-transparent", "input", MKA + " && " + complete(), expect="ok",
     setup=tex("""
        a = np.zeros((16, 16, 4), np.uint8); a[..., :3] = 200; a[..., 3] = 0
        cv2.imwrite(d + 'wood_albedo.png', a)
        """), may_change=OUT, timeout=110,
     why="A base-colour PNG with an alpha channel (fully transparent) is read as its RGB: the run completes.")
case("v43-make-texture-16bit-rgba-roughness", "input", MKA + " && " + complete(), expect="ok",
     setup=tex("""
        cv2.imwrite(d + 'wood_col.png', np.full((16, 16, 3), 120, np.uint8))
        cv2.imwrite(d + 'wood_roughness.png', np.full((16, 16, 4), 30000, np.uint16))
        """), may_change=OUT, timeout=110,
     why="A 16-bit RGBA roughness map holds roughness in its first channel: scaled by 65535 and the run "
         "completes (not read as values up to 30000).")
case("v43-make-texture-exr-roughness-above-1", "input", MKA, names=["wood_rough.exr"], timeout=90,
     setup=tex("""
        cv2.imwrite(d + 'wood_col.png', np.full((16, 16, 3), 120, np.uint8))
        write_exr(d + 'wood_rough.exr', np.full((16, 16), 3.0, np.float32))
        """),
     why="A linear EXR roughness of 3 is outside [0, 1]: the asset check names wood_rough.exr up front.")
case("v43-make-texture-exr-roughness-nan", "input", MKA, names=["wood_rough.exr"], timeout=90,
     setup=tex("""
        cv2.imwrite(d + 'wood_col.png', np.full((16, 16, 3), 120, np.uint8))
        a = np.full((16, 16), 0.4, np.float32); a[3, 3] = np.nan
        write_exr(d + 'wood_rough.exr', a)
        """),
     why="One NaN roughness texel makes the BSDF NaN where sampled: named up front (NaN compares False).")
case("v43-make-texture-exr-metal-negative", "input", MKA, names=["wood_metal.exr"], timeout=90,
     setup=tex("""
        cv2.imwrite(d + 'wood_col.png', np.full((16, 16, 3), 120, np.uint8))
        write_exr(d + 'wood_metal.exr', np.full((16, 16), -0.25, np.float32))
        """),
     why="A negative metallic value is outside [0, 1]: named up front.")
case("v43-make-texture-normal-map-grey", "input", MKA, names=["wood_normal.png"], timeout=90,
     setup=tex("""
        cv2.imwrite(d + 'wood_col.png', np.full((16, 16, 3), 120, np.uint8))
        cv2.imwrite(d + 'wood_normal.png', np.full((16, 16), 128, np.uint8))
        """),
     why="A grey 'normal' map is a height map, not x/y/z: named up front, never read as a constant normal.")
case("v43-make-texture-arm-grey", "input", MKA, names=["wood_arm.png"], timeout=90,
     setup=tex("""
        cv2.imwrite(d + 'wood_col.png', np.full((16, 16, 3), 120, np.uint8))
        cv2.imwrite(d + 'wood_arm.png', np.full((16, 16), 90, np.uint8))
        """),
     why="An ARM map of one channel has no G (roughness) or B (metal) to read: named up front.")
case("v43-make-texture-base-tiff-float-above-1", "input", MKA, names=["wood_diff.tif"], timeout=90,
     setup=TEX + py("""
        import numpy as np, tifffile
        tifffile.imwrite('assets/textures/wood/wood_diff.tif', np.full((16, 16, 3), 2.5, np.float32))
        """),
     why="A float TIFF base colour of 2.5 is no reflectance: named up front (the renderer's [0, 1] rule).")
case("v43-make-textures-link-to-meshes", "input", MKA + " --shapes mesh && " + complete(), expect="ok",
     setup="mkdir -p assets/meshes; cp " + SPHERE + " assets/meshes/; ln -s meshes assets/textures",
     may_change=OUT, timeout=110,
     why="textures/ a link to meshes/ (no image in it) gives no texture set; the meshes are used: the run "
         "completes, no error from a mesh read as a texture.")
case("v43-make-assets-folders-linked-into-each-other", "input",
     MKA + " --shapes mesh --lights hdri && " + complete(), expect="ok",
     setup="mkdir -p assets/meshes assets/hdri; cp " + SPHERE + " assets/meshes/; cp " + HDR + " assets/hdri/\n"
           "ln -s ../hdri assets/meshes/maps; ln -s ../meshes assets/hdri/shapes",
     may_change=OUT, timeout=110,
     why="meshes/ linking to hdri/ and back (a loop between two folders) is walked once each: the sphere and the "
         "map are found, nothing hangs.")
case("v43-make-texture-set-name-with-tab", "input", MKA, expect="either",
     setup="mkdir -p \"assets/textures/old$(printf '\\t')oak\"\n" + py("""
        import glob, numpy as np, cv2
        d = glob.glob('assets/textures/old*oak')[0]
        cv2.imwrite(d + '/oak_col.png', np.full((16, 16, 3), 90, np.uint8))
        """), may_change=OUT, timeout=110,
     why="A texture folder whose name holds a tab: used (names are text) or refused in one line naming it; no "
         "traceback, no scene.json broken by the control character.")

# ============================================================================ wildgen.make: flags and --resume after a change
case("v43-make-resume-add-level", "input", RES + " --level 3", names=["--level"], setup=OUTDS, may_change=OUT,
     timeout=60,
     why="--level on --resume would change shapes/materials/lights the manifest records: refused naming --level.")
case("v43-make-resume-other-res", "input", RES + " --res 64", names=["--res"], setup=OUTDS, may_change=OUT,
     timeout=60, why="A different resolution on --resume would mix 32 px and 64 px objects: refused naming --res.")
case("v43-make-resume-add-assets", "input", RES + ' --assets "$F/assets"', names=["--assets"], setup=OUTDS,
     may_change=OUT, timeout=60,
     why="A dataset made without assets resumed with --assets would change what is drawn: refused naming --assets.")
case("v43-make-resume-other-spp", "input", RES + " --spp 2", names=["--spp"], setup=OUTDS, may_change=OUT,
     timeout=60, why="Another spp on --resume changes the noise of later objects: refused naming --spp.")
case("v43-make-resume-add-shards", "writer", RES + ' --shards "$C/sh" && ' + index_objects("sh", 3), expect="ok",
     setup=OUTDS, may_change=OUT + SH, timeout=90,
     why="--shards on a finished dataset's resume renders nothing and exports it: 3 objects, each once.")
case("v43-make-resume-object-folder-duplicated", "input", RES, expect="either", setup=OUTDS
     + 'cp -r out/00000.data out/00007.data\n', may_change=["$C/out/manifest.json"], timeout=60,
     why="An object folder copied by hand under a name the manifest does not list: the resume refuses naming it "
         "or finishes; either way the copy is not deleted and no listed object is touched.")
OBJ1 = ["$C/out/manifest.json", "$C/out/00001.data", "$C/out/00001.data/*", "$C/out/00001.data/*/*"]
case("v43-make-resume-after-object-folder-renamed", "input",
     ok_or_refused(RES, complete("out", 3) + " && test -s out/00001.data/mask.png && test -s out/00001.old/mask.png"),
     expect="ok", setup=OUTDS + "mv out/00001.data out/00001.old\n", may_change=OBJ1, timeout=110,
     why="00001.data renamed to 00001.old: rendered again as 00001.data (or refused naming 00001); 00001.old, a "
         "folder the run did not make, is left as it is.")
case("v43-make-resume-grow-after-scene-json-swapped", "input",
     RES + " --objects 4 && " + complete("out", 4) + " && { cmp -s out/00000.data/scene.json out/00001.data/scene.json "
     "&& { echo 'FAULT: 00001 kept the scene.json of 00000'; exit 3; } || true; }", expect="ok",
     setup=OUTDS + "cp out/00000.data/scene.json out/00001.data/scene.json\n", may_change=OUT, timeout=120,
     why="00001's scene.json replaced by 00000's (its checksum no longer matches): a resume that adds an object "
         "renders 00001 again (or refuses naming it), never finishes a dataset whose 00001 is silently wrong.")
case("v43-make-level-then-explicit-lights", "input", f'{MK} --out "$C/out" --level 5 --lights frontal {TINY}'
     + " && " + complete() + " && grep -q frontal out/00000.data/scene.json || "
     "{ echo 'FAULT: --lights frontal not kept over --level 5'; exit 3; }", expect="ok", may_change=OUT, timeout=110,
     why="Flags given explicitly keep their values over --level: the object is lit by the frontal family.")
case("v43-make-preset-and-conflicting-camera", "input",
     f'{MK} --out "$C/out" --preset phone-flash --camera orthographic {TINY}', expect="either", may_change=OUT,
     timeout=110,
     why="A phone preset with an orthographic camera is an explicit override: rendered, or refused naming "
         "--camera if a flash needs a perspective camera; no traceback.")
case("v43-make-ray-address-with-tab", "input", f'{MK} --out "$C/out" --ray "$(printf "127.0.0.1:6379\\t")" {TINY}'
     + left("$C/out/manifest.json", "manifest written before --ray was checked"), names=["--ray"], timeout=60,
     why="A Ray address with a trailing tab (pasted from a table) is refused naming --ray before anything is "
         "written.")

# ============================================================================ chains: make -> sensor -> export -> train, edited between
case("v43-chain-sensor-then-image-swapped-then-export", "input",
     SEN + ' --data "$C/d" --sensor phone --out "$C/s" && cp s/00001.data/L001.png s/00001.data/L000.png && '
     + EX + ' --data "$C/s" --out "$C/sh"', names=["00001"], setup=DS,
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"] + SH, timeout=90,
     why="After wildgen.sensor, an image of its output replaced by another by hand: the export finds the "
         "checksum mismatch and names 00001, never ships two identical images.")
case("v43-chain-sensor-then-folder-duplicated-then-export", "input",
     SEN + ' --data "$C/d" --sensor webcam --out "$C/s" && cp -r s/00002.data s/00003.data && '
     + EX + ' --data "$C/s" --out "$C/sh"', names=["00003"], setup=DS,
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"] + SH, timeout=90,
     why="An object folder duplicated by hand after the sensor run is not in its manifest: the export names "
         "00003.data, never exports a duplicate object as a 4th sample.")
case("v43-sensor-scene-json-of-another-object", "input", SEN + ' --data "$C/d" --sensor phone --out "$C/s"',
     names=["00001"], setup=DS + "cp d/00000.data/scene.json d/00001.data/scene.json\n",
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"], timeout=90,
     why="00001's scene.json replaced by 00000's: the exposures and seeds it gives are another object's; the "
         "sensor names 00001 (the checksum differs), not images exposed by the wrong scene.")
case("v43-sensor-scene-json-swapped-checksummed", "input",
     ok_or_refused(SEN + ' --data "$C/d" --sensor phone --out "$C/s"', complete("s", 3)), expect="ok",
     setup=DS + "cp d/00000.data/scene.json d/00001.data/scene.json\n" + rechecksum("d", "00001", "scene.json"),
     may_change=["$C/s", "$C/s/*", "$C/s/*/*", "$C/s/*/*/*"], timeout=90,
     why="The same swap with the checksum updated: a clean refusal (the image count or seeds disagree) or a "
         "complete dataset; no traceback.")
case("v43-export-manifest-entry-listed-twice", "input",
     ok_or_refused(EX + ' --data "$C/d" --out "$C/sh"', index_objects("sh", 3)), expect="ok",
     setup=DS + manifest("d", "m['objects'].append(dict(m['objects'][1]))"), may_change=SH, timeout=60,
     why="A manifest listing 00001 twice (a merge by hand): refused naming manifest.json, or exported with each "
         "object once; never 00001 as two samples.")
case("v43-export-manifest-checksum-upper-hex", "input", EX + ' --data "$C/d" --out "$C/sh"', expect="either",
     setup=DS + manifest("d", "e = m['objects'][0]; e['files'] = {k: v.upper() for k, v in e['files'].items()}"),
     may_change=SH, timeout=60,
     why="Checksums re-typed in upper-case hex are the same digests: exported, or refused naming the object; "
         "no traceback.")
case("v43-export-manifest-done-entry-files-empty", "input", EX + ' --data "$C/d" --out "$C/sh"',
     names=["00001"], setup=DS + manifest("d", "m['objects'][1]['files'] = {}"), may_change=SH, timeout=60,
     why="A 'done' entry whose file list was emptied by hand vouches for nothing: refused naming 00001 (its folder "
         "holds files the manifest does not list), not exported unchecked.")
case("v43-export-object-folder-renamed-other-case-twin", "input",
     ok_or_refused(EX + ' --data "$C/d" --out "$C/sh"', index_objects("sh", 3)), expect="ok", setup=DS + "cp -r d/00001.data d/00001.Data\n", may_change=SH, timeout=60,
     why="A copy of 00001.data named 00001.Data (a case-folding twin, one folder on a Mac): not in the manifest, "
         "refused naming it or left out, never shipped as a second 00001.")
case("v43-chain-export-index-count-edited-then-train", "input",
     EX + ' --data "$C/d" --out "$C/sh" && ' + py("""
        import json
        i = json.load(open('sh/index.json')); i['objects'] = 30; json.dump(i, open('sh/index.json', 'w'))
        """) + "test -s sh/index.json && " + TR + ' --data "$C/sh" --out "$C/run" --steps 1', names=["index.json"], setup=DS,
     may_change=SH + RUN, timeout=120,
     why="index.json whose object count (30) disagrees with its shard lists (3): training names index.json rather "
         "than trust either number for its epochs.")
case("v43-chain-export-shard-duplicated-in-index-then-train", "input",
     EX + ' --data "$C/d" --out "$C/sh" && cp sh/000000.tar sh/000001.tar && ' + py("""
        import json
        i = json.load(open('sh/index.json')); s = dict(i['shards'][0]); s['name'] = '000001.tar'
        i['shards'].append(s); i['objects'] = 6; i['pattern'] = '{000000..000001}.tar'
        json.dump(i, open('sh/index.json', 'w'))
        """) + "test -s sh/index.json && " + TR + ' --data "$C/sh" --out "$C/run" --steps 1', names=["000001.tar"], setup=DS,
     may_change=SH + RUN, timeout=120,
     why="A shard copied and listed under a second name (same objects, same checksum): the same object names in "
         "two shards are named, not trained on twice as a 6-object dataset.")

# ============================================================================ paths with tab / newline characters
case("v43-sensor-out-with-tab", "input", SEN + ' --data "$F/data" --sensor webcam --out "$C/s$(printf "\\t")x"',
     expect="either", may_change=["$C/s*", "$C/s*/*", "$C/s*/*/*", "$C/s*/*/*/*"], timeout=90,
     why="An output folder whose name ends in a tab: written there or refused naming --out; no traceback, nothing "
         "written elsewhere.")
case("v43-export-out-with-newline", "input", EX + ' --data "$F/data" --out "$C/sh"$\'\\n\'"x"',
     expect="either", may_change=["$C/sh*", "$C/sh*/*"], timeout=60,
     why="--out with a newline in its name: exported there (index.json names shards by their own names) or "
         "refused naming --out; no traceback.")
case("v43-preview-object-folder-with-newline", "input", PV + ' "$C/d"', expect="either",
     setup="mkdir d; cp -r \"$F/data/00000.data\" \"d/ob\"$'\\n'\"j.data\"",
     may_change=["$C/d/preview", "$C/d/preview/*"], timeout=60,
     why="An object folder whose name holds a newline: its contact sheet written (preview.json lists it as JSON) "
         "or refused naming it; no traceback, no sheet written outside d/preview.")

# ============================================================================ validate.rerender: scene.json edited
case("v43-rr-scene-json-of-another-object", "input", RRD, expect="either",
     setup=OBJ + 'cp "$F/data8/00001.data/scene.json" d/scene.json\n', may_change=R, timeout=120,
     why="An object folder carrying another object's scene.json (its lights, its mesh path into aux/): re-rendered "
         "(the report then shows the mismatch) or refused naming scene.json; no traceback.")
case("v43-rr-scene-mesh-replaced-by-quads-obj", "input", RRD, expect="either",
     setup=OBJ + py("open('d/aux/cube.obj', 'w').write(" + repr(CUBE_V + CUBE_Q) + ")")
     + py("""
        import json
        s = json.load(open('d/scene.json'))
        def walk(o):
            if isinstance(o, dict):
                for k, v in o.items():
                    if isinstance(v, str) and v.endswith('mesh.ply'):
                        o[k] = v[:-len('mesh.ply')] + 'cube.obj'
                    else:
                        walk(v)
            elif isinstance(o, list):
                for v in o:
                    walk(v)
        walk(s); json.dump(s, open('d/scene.json', 'w'), indent=1)
        """), may_change=R, timeout=120,
     why="scene.json pointing at a quad OBJ instead of the rendered mesh: re-rendered (a large residual) or "
         "refused naming scene.json; no traceback from the quads.")
case("v43-rr-scene-mesh-path-with-newline", "archive", RRD, names=["scene.json"],
     setup=OBJ + "mv d/aux/mesh.ply \"d/aux/me\"$'\\n'\"sh.ply\"\n" + py("""
        import json
        s = json.load(open('d/scene.json'))
        txt = json.dumps(s).replace('aux/mesh.ply', 'aux/me\\\\nsh.ply')
        open('d/scene.json', 'w').write(txt)
        """), may_change=R, timeout=120,
     why="A mesh path holding a newline in scene.json (a hand edit or a planted file): refused naming scene.json "
         "or the file, never passed into a Mitsuba scene description that a newline could split.")
case("v43-rr-scene-image-count-beyond-files", "input", RRD, names=["L007"],
     setup=OBJ + "rm d/L007.png\n", may_change=R, timeout=120,
     why="scene.json describes 8 images but L007.png was deleted: refused naming the missing image, not a "
         "comparison of 7 renders silently reported as the object's.")

# ============================================================================ relay: --pack of an asset library
case("v43-pack-assets-exr-maps", "input", PACK + " && " + py("""
        import sys, tarfile
        with tarfile.open('p/assets.tar.xz') as t:
            m = [x for x in t.getmembers() if x.name.startswith('hdri/') or '/hdri/' in x.name]
        if not m or any(x.size == 0 for x in m):
            sys.exit('FAULT: EXR maps packed as %r' % [(x.name, x.size) for x in m])
        """), expect="ok",
     setup=PACK_LIB + py("""
        import numpy as np
        from scenes.exr import write_exr
        for i in range(5):
            write_exr(f'assets/hdri/h{i}.exr', np.full((16, 32, 3), 0.5 + i / 10, np.float32))
        """), may_change=["$C/p", "$C/p/*"], timeout=120,
     why="EXR environment maps are valid library maps (wildgen.make draws .hdr and .exr): the pack reduces and "
         "carries them, it does not refuse them as 'not an HDR map OpenCV reads'.")
case("v43-pack-assets-hdr-4096x1", "input", PACK, expect="either",
     setup=PACK_LIB + py("""
        import numpy as np, cv2
        for i in range(4):
            cv2.imwrite(f'assets/hdri/h{i}.hdr', np.full((16, 32, 3), 0.5, np.float32))
        cv2.imwrite('assets/hdri/a_strip.hdr', np.full((1, 4096, 3), 0.5, np.float32))
        """), may_change=["$C/p", "$C/p/*"], timeout=120,
     why="A 4096x1 map in the training split: reduced and packed, or refused naming a_strip.hdr; no traceback.")
case("v43-pack-assets-hdr-black", "input", PACK, names=["a_black.hdr"],
     setup=PACK_LIB + py("""
        import numpy as np, cv2
        for i in range(4):
            cv2.imwrite(f'assets/hdri/h{i}.hdr', np.full((16, 32, 3), 0.5, np.float32))
        cv2.imwrite('assets/hdri/a_black.hdr', np.zeros((16, 32, 3), np.float32))
        """), may_change=["$C/p", "$C/p/*"], timeout=120,
     why="A black map in the training split (wildgen.make refuses it up front: it lights nothing) is named when "
         "packing, as a faceless mesh is, not carried to fail the GPU session after its start-up.")
case("v43-pack-assets-texture-roughness-above-1", "input", PACK, names=["wood_rough.exr"],
     setup=PACK_LIB + py("""
        import numpy as np, cv2, os
        from scenes.exr import write_exr
        for i in range(5):
            cv2.imwrite(f'assets/hdri/h{i}.hdr', np.full((16, 32, 3), 0.5, np.float32))
        os.makedirs('assets/textures/wood')
        cv2.imwrite('assets/textures/wood/wood_col.png', np.full((16, 16, 3), 120, np.uint8))
        write_exr('assets/textures/wood/wood_rough.exr', np.full((16, 16), 3.0, np.float32))
        """), may_change=["$C/p", "$C/p/*"], timeout=120,
     why="A texture map wildgen.make refuses up front (roughness 3) is named when packing, not carried to fail "
         "the session on the GPU machine.")
case("v43-pack-assets-meshes-linked-between-folders", "input", PACK, expect="either",
     setup=PACK_LIB + py("""
        import numpy as np, cv2
        for i in range(5):
            cv2.imwrite(f'assets/hdri/h{i}.hdr', np.full((16, 32, 3), 0.5, np.float32))
        """) + "ln -s ../meshes assets/hdri/zz_meshes\nln -s ../hdri assets/meshes/zz_maps\n",
     may_change=["$C/p", "$C/p/*"], timeout=120,
     why="meshes/ and hdri/ linking into each other (inside the library): packed with each file once, or refused "
         "naming the link; no endless walk, no traceback.")

# ============================================================================ relay: carried archives with colliding names
case("v43-relay-site-member-dot-slash-twin", "archive", SESS + nosite(), names=["--carry", "a.py"],
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/a.py', b'x = 1')\nadd(tar, './pkg/a.py', b'x = 2')"),
     may_change=SESS_CHANGE, timeout=60,
     why="'pkg/a.py' and './pkg/a.py' are one file: the second would silently replace the first; refused naming "
         "--carry, nothing unpacked.")
case("v43-relay-site-member-double-slash-twin", "archive", SESS + nosite(), names=["--carry", "a.py"],
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/a.py', b'x = 1')\nadd(tar, 'pkg//a.py', b'x = 2')"),
     may_change=SESS_CHANGE, timeout=60,
     why="'pkg//a.py' normalises to 'pkg/a.py': a duplicate, refused naming --carry.")
case("v43-relay-site-file-then-folder-of-one-name", "archive", SESS + nosite(), names=["--carry"],
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg', b'not a folder')\nadd(tar, 'pkg/__init__.py', b'')"),
     may_change=SESS_CHANGE, timeout=60,
     why="A file 'pkg' and then a member inside 'pkg/': the archive cannot be unpacked as listed; refused in one "
         "line naming --carry, nothing left in --work.")
case("v43-relay-site-members-differ-by-case", "archive", SESS, expect="either",
     setup=mktar("c/site.tar.xz", "add(tar, 'pkg/__init__.py', b'')\nadd(tar, 'pkg/Mod.py', b'A = 1')\n"
                 "add(tar, 'pkg/mod.py', b'A = 2')"),
     may_change=SESS_CHANGE, timeout=120,
     why="Two members differing only in case are two files on Linux: unpacked both (or refused as not "
         "portable naming --carry); never one silently replacing the other in a way that fails later.")
case("v43-relay-assets-nfc-nfd-twin-meshes", "archive", SESS, expect="either",
     setup=GOOD_SITE + mktar("c/assets.tar.xz",
                             "import os\nb = " + SPHERE_BYTES + "\n"
                             "add(tar, 'assets/meshes/caf\\u00e9.obj', b)\nadd(tar, 'assets/meshes/cafe\\u0301.obj', b)"),
     may_change=SESS_CHANGE, timeout=120,
     why="Two mesh members whose names are NFC/NFD twins: two files, unpacked and used (or refused naming "
         "--carry); no KeyError, no traceback.")
case("v43-relay-assets-member-name-with-tab", "archive", SESS + nosite(), names=["--carry"],
     setup=GOOD_SITE + mktar("c/assets.tar.xz", "import os\nadd(tar, 'assets/meshes/a\\tb.obj', " + SPHERE_BYTES + ")"),
     may_change=SESS_CHANGE, timeout=60,
     why="An assets member whose name holds a tab (a control character): refused naming --carry, and the site "
         "unpacked a moment before is removed again.")
case("v43-relay-assets-member-line-separator", "archive", SESS, expect="either",
     setup=GOOD_SITE + mktar("c/assets.tar.xz", "import os\nadd(tar, 'assets/meshes/a\\u2028b.obj', "
                             + SPHERE_BYTES + ")"),
     may_change=SESS_CHANGE, timeout=120,
     why="U+2028 (a line separator to str.splitlines, not an ASCII control character) in a member name: "
         "used as a name, or refused naming --carry; no traceback, no name split into two.")
case("v43-relay-assets-dir-member-then-file-of-one-name", "archive", SESS + nosite(), names=["--carry"],
     setup=GOOD_SITE + mktar("c/assets.tar.xz", "import os\nadd(tar, 'assets/meshes/m.obj', dir=True)\n"
                             "add(tar, 'assets/meshes/m.obj', " + SPHERE_BYTES + ")"),
     may_change=SESS_CHANGE, timeout=60,
     why="A folder member and then a file member of the same name: the file would replace the folder (or fail "
         "half-way): refused naming --carry, nothing left unpacked.")

# ============================================================================ orchestrate.docs / demo
case("v43-docs-page-name-with-newline", "input", DOCS + " --check", expect="either",
     setup=REPO_COPY + "cp repo/docs/model.md \"repo/docs/mo\"$'\\n'\"del.md\" 2>/dev/null || "
           "cp \"$(ls repo/docs/*.md | head -1)\" \"repo/docs/mo\"$'\\n'\"del.md\"",
     may_change=["$C/repo/*", "$C/repo/*/*"], timeout=90,
     why="A copy of a page whose name holds a newline: checked like any page (reported stale or current) or "
         "named in one line; no traceback, no file written outside repo/.")
case("v43-docs-page-linked-to-another-page", "writer", DOCS, expect="either",
     setup=REPO_COPY + "p=$(ls repo/docs/*.md | head -1); cp \"$p\" repo/docs/zz_twin.md.keep; "
           "ln -s \"$(basename \"$p\")\" repo/docs/zz_twin.md",
     may_change=["$C/repo/*.md", "$C/repo/docs/*.md"], timeout=90,
     why="A page that is a link to another page: rewritten once through the real file (or refused naming the "
         "link); the link is not replaced by a file, and zz_twin.md.keep is not touched.")
case("v43-demo-out-with-tab-images-3", "input", DEMO + ' --out "$C/demo$(printf "\\t")out" --images 3',
     names=["--images"], timeout=60,
     why="--images 3 is below the 4 the baseline needs: refused naming --images before the folder with a tab in its "
         "name is made or anything rendered.")
