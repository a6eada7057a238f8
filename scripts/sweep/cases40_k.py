"""Sweep 40, part k: the USER-PHOTO side once more (orchestrate.capture, orchestrate.surface, validate.rerender /
validate.refine on user-like folders without scene.json, wildgen.preview on user folders), with cases that
cases37_*.py, cases38_*.py, cases39_*.py and tests/test_bad_inputs.py do not hold.

What a user's camera, editor or file manager leaves and what an attacker plants:
- photo kinds not swept yet: palette and grey PNG, opaque RGBA PNG, grey JPEG among colour ones, CMYK TIFF, half-float
  and RGBA EXR, a JPEG with a motion-photo video or junk after its end, a PNG whose text chunk is a
  decompression bomb;
- EXIF values a writer got wrong: a negative exposure time, an exposure time stored as text, ISO as two values,
  35 mm-equivalent focal lengths of 1 mm / 65535 mm / differing in one photo (the surface's camera);
- names: a link loop, a backslash, a `.part` download or a trailing space after the suffix, DiLiGenT-like digit
  names with a light file but no listing;
- empty / special paths where a folder is expected (`--input ""`, `--input -`, `--out ""`, `--out` a FIFO,
  /dev/null), links to /dev/zero where surface reads its map, mask or camera;
- surface maps of odd shapes (NPY header lying about a huge shape, 4 channels, 2-D, Fortran order, .npz, EXR of
  one channel, every normal edge-on), cameras in other formats (binary .npy, a comment line, an infinite focal),
  --mesh naming a path, outputs replaced by links before --overwrite;
- user-like object folders (an object folder without scene.json: the fitted mode) with gaps or duplicates among
  their L* images, a folder of another object as --normals, a capture's --out given as --data; wildgen.preview of a
  folder of photos, of a capture's --out and of its work folder.

Cases whose command adds its own check print a line starting with `FAULT:` and exit 0 so that the harness flags it
(exit0 where a refusal is due), or exit 1 (failed where a success is due).
Every case uses the 32/64-px fixtures of fixtures.sh (a capture of $F/photos takes about 13 s on 2 cores).
"""
from __future__ import annotations

import textwrap


def py(code: str) -> str:
    """A bash heredoc running `code` with the toolkit's python in $C."""
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


PRE = """
import glob, io, json, os, shutil, struct, zlib
import numpy as np, cv2
from PIL import Image
F = os.environ["F"]; C = os.environ["C"]
photos = sorted(glob.glob("p/*.jpg"))
"""

PH = 'cp -r "$F/photos" p\n'


def setup_py(code: str, photos: bool = True) -> str:
    """Setup: (a copy of the 8 JPEG photos in p/, then) Python with PRE's names."""
    return (PH if photos else "") + py(PRE + textwrap.dedent(code))


CAP = '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --no-refine --threads 1'
"""A capture of p/ with the fixtures' mask, without refinement (about 13 s)."""
CAP_NOMASK = "$PY -m orchestrate.capture --input p --out o --no-refine --threads 1"
CAP_SETUP = PH + CAP + " > cap_setup.log 2>&1\n"
CAP_WORK_SETUP = PH + CAP + " --max-side 32 --keep-work > cap_setup.log 2>&1\n"
SURF = "$PY -m orchestrate.surface"
N0 = '"$F/pred8/00000/normal.png"'
M0 = '"$F/data8/00000.data/mask.png"'
SURF0 = f"{SURF} --normals {N0} --mask {M0} --out o"
USER = 'cp -r "$F/data8/00000.data" u && rm u/scene.json\n'
"""Setup: u/, an object folder as a user has it: L*.png, mask.png, normal.tif, no scene.json (the fitted mode)."""
FAST = " --steps 2 --ao-rays 0 --no-shadows --no-bas-relief --threads 1"
RRU = '$PY -m validate.rerender --data u --normals "$F/pred8/00000/normal.png" --out r' + FAST
RFU = ('$PY -m validate.refine --data u --normals "$F/pred8/00000/normal.png" --out rf'
       " --refine-steps 2 --steps 2 --rounds 1 --ao-rays 0 --no-shadows --threads 1")
PV = "$PY -m wildgen.preview"


def deep(d: str) -> list[str]:
    return [f"$C/{d}", f"$C/{d}/*", f"$C/{d}/*/*", f"$C/{d}/*/*/*", f"$C/{d}/*/*/*/*", f"$C/{d}/.*",
            f"$C/{d}/*/.*"]


O = deep("o")
SURFOUT = ["$C/o/depth.*", "$C/o/mesh.*", "$C/o/discontinuities.png", "$C/o/report.json", "$C/o/.*",
           "$C/o/shaded.png"]
R = deep("r")
RF = deep("rf")
PVO = deep("pv")
OK_CAP = " && test -s o/normal.png && test -s o/report.json"


def left(path: str, what: str) -> str:
    """Command tail: a refusal that left `path` behind exits 0 with a FAULT line (flagged exit0)."""
    return f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r'


def taken_or_named(cmd: str, name: str, check: str) -> str:
    """Command: `cmd` must either refuse naming `name` (a right answer) or succeed with `check` holding; anything
    else prints a FAULT line and exits 1 (expect "ok": flagged as failed)."""
    return (f"{cmd} > out.log 2>&1; r=$?; cat out.log; if [ $r != 0 ]; then grep -qi -- '{name}' out.log && exit 0; "
            f"echo 'FAULT: refused without naming {name}'; exit 1; fi; {check}")


CASES: list[dict] = []


def case(id, kind, setup, cmd, expect, names=(), may_change=(), timeout=120, why=""):
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


# ============================================================================ capture: photo kinds
case("k40-cap-palette-png-photos", "input",
     setup_py("""
for p in photos:
    Image.open(p).convert("RGB").quantize(256).save(p[:-4] + ".png"); os.remove(p)
"""), CAP, "either", [], O,
     why="8-bit palette PNG photos (a web export) are read as their colours or refused in one line naming a file, "
         "never a traceback or an index image read as grey levels")
case("k40-cap-grey-png-photos", "input",
     setup_py("""
for p in photos:
    Image.open(p).convert("L").save(p[:-4] + ".png"); os.remove(p)
"""), CAP, "either", [], O,
     why="a monochrome camera's 8-bit grey PNG photos are read (one channel for three) or refused in one line")
case("k40-cap-grey-jpeg-among-colour", "input",
     setup_py("""
Image.open(photos[3]).convert("L").save(photos[3], quality=95)
"""), CAP, "either", [], O,
     why="one photo saved grey among colour ones: read alike or refused naming photo03.jpg, never a shape traceback")
case("k40-cap-rgba-png-photos-opaque", "input",
     setup_py("""
for p in photos:
    Image.open(p).convert("RGBA").save(p[:-4] + ".png"); os.remove(p)
"""), CAP + OK_CAP, "ok", [], O,
     why="an editor's export with a fully opaque alpha is an RGB photo: read as such (the alpha says nothing)")
case("k40-cap-png-ztxt-bomb", "input",
     setup_py("""
def chunk(t, d):
    return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
for p in photos:
    Image.open(p).convert("RGB").save(p[:-4] + ".png"); os.remove(p)
q = "p/photo02.png"
b = open(q, "rb").read()
bomb = chunk(b"zTXt", b"Comment\\x00\\x00" + zlib.compress(b"\\x00" * (200 << 20), 9))
open(q, "wb").write(b[:33] + bomb + b[33:])
"""), CAP, "either", [], O, timeout=90,
     why="a zTXt chunk inflating to 200 MB (a decompression bomb in metadata) is skipped or refused naming "
         "photo02.png; never a traceback or memory blow-up")
case("k40-cap-cmyk-tiff-photos", "input",
     setup_py("""
for p in photos:
    Image.open(p).convert("CMYK").save(p[:-4] + ".tif"); os.remove(p)
"""), CAP, "either", [], O,
     why="CMYK TIFF photos (a print workflow's export) are converted or refused in one line naming a file; never "
         "four channels read as RGB(A)")
case("k40-cap-exr-half-float-photos", "input",
     setup_py("""
import OpenEXR
for p in photos:
    a = (cv2.imread(p)[..., ::-1].astype(np.float32) / 255) ** 2.2
    ch = {c: np.ascontiguousarray(a[..., i].astype(np.float16)) for i, c in enumerate("RGB")}
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, ch) as f:
        f.write(p[:-4] + ".exr")
    os.remove(p)
"""), CAP + OK_CAP, "ok", [], O,
     why="half-float EXR is the usual EXR a raw developer writes: linear photos, read like float32 ones")
case("k40-cap-exr-rgba-photos", "input",
     setup_py("""
import OpenEXR
for p in photos:
    a = (cv2.imread(p)[..., ::-1].astype(np.float32) / 255) ** 2.2
    ch = {c: np.ascontiguousarray(a[..., i]) for i, c in enumerate("RGB")}
    ch["A"] = np.ones(a.shape[:2], np.float32)
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, ch) as f:
        f.write(p[:-4] + ".exr")
    os.remove(p)
"""), CAP, "either", [], O,
     why="EXR photos with an alpha channel: read as RGB or refused in one line naming a file, never a traceback")
case("k40-cap-jpeg-motion-photo-video-appended", "input",
     setup_py("""
for p in photos:
    open(p, "ab").write(b"\\x00\\x00\\x00\\x18ftypmp42" + os.urandom(20000))
"""), CAP + OK_CAP, "ok", [], O,
     why="a phone's motion photo is a whole JPEG followed by a video; the JPEG is complete and reads as the photo")
case("k40-cap-jpeg-two-concatenated", "input",
     setup_py("""
b = open(photos[1], "rb").read()
open(photos[0], "ab").write(b)
"""), CAP, "either", [], O,
     why="a JPEG followed by another whole JPEG (a burst file): the first image is read or the file is refused "
         "naming photo00.jpg; never a traceback")

# ============================================================================ capture: EXIF values
EXIF_PRE = """
def save(p, **tags):
    im = Image.open(p).convert("RGB"); ex = Image.Exif(); ifd = ex.get_ifd(0x8769)
    for k, v in tags.items():
        ifd[int(k[1:], 16)] = v
    im.save(p, quality=95, exif=ex.tobytes())
"""
case("k40-cap-exif-exposure-negative", "input",
     setup_py(EXIF_PRE + """
from PIL.TiffImagePlugin import IFDRational
for i, p in enumerate(photos):
    save(p, x829a=IFDRational(-1 if i == 0 else 1, 100), x8827=100)
"""), CAP, "refuse", ["photo00.jpg"], O,
     why="an exposure time of -1/100 s is not a finite number above 0: refused naming the file and the value, "
         "never used to scale the photos by a negative factor")
case("k40-cap-exif-exposure-as-text", "input",
     setup_py(EXIF_PRE + """
for i, p in enumerate(photos):
    save(p, x829a="1/100", x8827=100)
"""), CAP, "either", [], O,
     why="an exposure time written as ASCII text is either read, ignored with a note, or refused naming the file; "
         "never a TypeError")
case("k40-cap-exif-iso-two-values", "input",
     setup_py(EXIF_PRE + """
from PIL.TiffImagePlugin import IFDRational
for i, p in enumerate(photos):
    save(p, x829a=IFDRational(1, 100), x8827=(100, 400 if i == 5 else 100))
"""), CAP, "either", [], O,
     why="ISOSpeedRatings holding two values: the first read, or refused naming the file; never a traceback")
case("k40-cap-exif-focal35-1mm", "input",
     setup_py(EXIF_PRE + """
for p in photos:
    save(p, xa405=1)
"""), taken_or_named(CAP, "focal", py("""
import json, sys
s = json.load(open("o/surface/report.json"))
d = s.get("depth") or {}
away = (s.get("solver") or {}).get("facing_away_pixels", 0)
if "perspective" in str(s.get("camera")) and (away > s.get("pixels", 1) / 2 or d.get("max", 1) > 100 * d.get("min", 1)):
    print(f"FAULT: surface integrated with {s['camera']}: {away} of {s['pixels']} pixels face away, depth "
          f"{d.get('min')} to {d.get('max')}, no warning, exit 0"); sys.exit(1)
""")), "ok", [], O,
     why="a 35 mm-equivalent focal of 1 mm (a 2 px focal length on 64 px, a 175 deg view) is a broken tag: refused "
         "naming it, or the surface falls back to orthographic; never a surface whose normals mostly face away "
         "under that camera (orchestrate.surface refuses them) written with exit 0")
case("k40-cap-exif-focal35-65535mm", "input",
     setup_py(EXIF_PRE + """
for p in photos:
    save(p, xa405=65535)
"""), CAP + OK_CAP + " && test -s o/surface/mesh.ply", "ok", [], O,
     why="a very long lens is all but orthographic: the surface is integrated as a pinhole camera all the same")
case("k40-cap-exif-focal35-differs-in-one", "input",
     setup_py(EXIF_PRE + """
for i, p in enumerate(photos):
    save(p, xa405=28 if i != 4 else 50)
"""), CAP + OK_CAP + " && grep -q orthographic o/report.json", "ok", [], O,
     why="photos disagreeing on the focal length give no one camera: the surface is orthographic and report.json "
         "says so")

# ============================================================================ capture: names in the folder
case("k40-cap-photo-link-loop", "input", PH + "ln -s photo08.jpg p/photo08.jpg\n", CAP, "refuse",
     ["photo08.jpg"], O, timeout=60,
     why="a link to itself (ELOOP) among the photos is refused naming it, never skipped or a traceback")
case("k40-cap-photo-name-with-backslash", "input", PH + "mv p/photo03.jpg 'p/ph\\oto03.jpg'\n",
     CAP + OK_CAP, "ok", [], O, why="a backslash is a valid character of a Linux file name: read like any other")
case("k40-cap-partial-download-beside", "input", PH + "head -c 3000 p/photo00.jpg > p/photo08.jpg.part\n",
     CAP, "either", [], O,
     why="a browser's unfinished download (photo08.jpg.part) is not a photo: skipped (better named) or refused "
         "naming it; never read")
case("k40-cap-suffix-with-trailing-space", "input", PH + "mv p/photo07.jpg 'p/photo07.jpg '\n",
     taken_or_named(CAP, "photo07", "grep -q photo07 o/report.json || { echo 'FAULT: photo07.jpg (trailing space) "
                    "silently left out: 7 of 8 photos'; exit 1; }"), "ok", [], O,
     why="'photo07.jpg ' is a photo a file manager shows as .jpg: taken, or named in a refusal so the user sees "
         "one of eight photos is left out; never silently dropped (the capture then runs on 7)")
case("k40-cap-digit-pngs-with-light-file-no-mask", "input",
     setup_py("""
for i, p in enumerate(photos):
    cv2.imwrite(f"p/{i + 1:03d}.png", cv2.imread(p)); os.remove(p)
open("p/light_directions.txt", "w").write("\\n".join("0 0 1" for _ in photos) + "\\n")
"""), CAP, "either", [], O,
     why="001.png ... with light_directions.txt reads as a DiLiGenT folder (8-bit PNG, lights all frontal): run "
         "through or refused in one line; never a traceback")
case("k40-cap-diligent-rows-of-deleted-images", "input",
     'mkdir b && for i in 001 013 025 037 049 061 073 085; do cp "$F/ballPNG/$i.png" b/; echo "$i.png"; done '
     '> b/filenames.txt\ncp "$F/ballPNG/light_directions.txt" "$F/ballPNG/light_intensities.txt" '
     '"$F/ballPNG/mask.png" b/\n',
     "$PY -m validate.refine --data b --normals \"$F/ballPNG/Normal_gt.png\" --out rf --lights calibrated "
     "--refine-steps 2 --steps 2 --rounds 1 --ao-rays 0 --no-shadows --threads 1",
     "refuse", ["light_directions.txt"], RF,
     why="8 images kept of 96 but the 96 rows of light_directions.txt left: --lights calibrated cannot know which "
         "row is which image; refused naming the file (rows against images)")

# ============================================================================ capture: paths that are not folders
case("k40-cap-input-empty-string", "input", PH, '$PY -m orchestrate.capture --input "" --out o --no-refine',
     "refuse", ["--input"], O,
     why="--input '' is no folder: refused naming --input, not read as the current folder")
case("k40-cap-input-dash", "input", PH, '$PY -m orchestrate.capture --input - --out o --no-refine < /dev/null',
     "refuse", ["--input"], O, timeout=60, why="'-' is not a folder of photos (no stdin reading): refused naming --input")
case("k40-cap-out-empty-string", "writer", PH, '$PY -m orchestrate.capture --input p --out "" --mask "$F/mask.png" '
     '--no-refine --threads 1' + left("$C/normal.png", "--out '' wrote into the current folder"),
     "refuse", ["--out"], [],
     why="--out '' is no folder: refused naming --out, never the current folder filled with outputs")
case("k40-cap-out-a-fifo", "writer", PH + "mkfifo o\n", CAP, "refuse", ["--out"], [], timeout=60,
     why="a named pipe as --out is not a folder: refused naming --out, no hang opening it")
case("k40-cap-out-dev-null", "writer", PH, CAP.replace("--out o", "--out /dev/null"), "refuse", ["--out"], [],
     timeout=60, why="/dev/null as --out (a user who wants no files) is not a folder: refused naming --out")
case("k40-cap-out-path-spaces-unicode", "writer", PH,
     CAP.replace("--out o", '--out "$C/my out/é 写 🙂"') + ' && test -s "$C/my out/é 写 🙂/normal.png"', "ok", [],
     deep("my out"), why="an output path with spaces, accents, CJK and emoji is a folder like any other")

# ============================================================================ capture: flags
case("k40-cap-max-side-float", "input", PH, CAP + " --max-side 64.5", "refuse", ["--max-side"], O,
     why="--max-side takes whole pixels: 64.5 refused naming --max-side")
case("k40-cap-threads-float", "input", PH, CAP.replace("--threads 1", "--threads 1.5"), "refuse", ["--threads"],
     O, why="--threads takes a whole count: 1.5 refused naming --threads")
case("k40-cap-rotation-steps-negative", "input", PH,
     CAP.replace("--no-refine", "--rotation-search --rotation-steps -5"), "refuse", ["--rotation-steps"], O,
     why="a negative step count is refused naming --rotation-steps before any photo is read")
case("k40-cap-convention-twice", "input", PH, CAP + " --convention opengl --convention opencv", "either", [], O,
     why="a flag given twice: the last wins (argparse) or it is refused naming --convention; never a traceback")
case("k40-cap-srgb-encoding-16bit-png", "input",
     setup_py("""
for p in photos:
    cv2.imwrite(p[:-4] + ".png", cv2.imread(p).astype(np.uint16) * 257); os.remove(p)
"""), CAP + " --input-encoding srgb" + OK_CAP + " && grep -q srgb o/report.json", "ok", [], O,
     why="16-bit PNG exported from an sRGB workflow with --input-encoding srgb is read with the sRGB curve, "
         "recorded in report.json")
case("k40-cap-mask-exr-binary", "input", PH + py(PRE + """
from scenes.exr import write_exr
m = (cv2.imread(F + "/mask.png", 0) > 127).astype(np.float32)
write_exr("m.exr", m)
"""), CAP.replace('"$F/mask.png"', "m.exr"), "either", [], O,
     why="a float EXR mask of 0 and 1 is binary: read, or refused in one line naming --mask")
case("k40-cap-mask-npy", "input", PH + py(PRE + """
np.save("m.npy", cv2.imread(F + "/mask.png", 0) > 127)
"""), CAP.replace('"$F/mask.png"', "m.npy"), "either", [], O,
     why="a boolean NPY mask: read, or refused in one line naming --mask and m.npy (expected an image)")
case("k40-cap-mask-inverted", "input", PH + py(PRE + """
cv2.imwrite("m.png", 255 - cv2.imread(F + "/mask.png", 0))
"""), CAP, "either", [], O,
     why="a mask white on the background is taken as given (the docs) or doubted; the run ends in one verdict "
         "line or a refusal, never a traceback")
CASES[-1]["cmd"] = CAP.replace('"$F/mask.png"', "m.png")

# ============================================================================ surface: special files
case("k40-surf-normals-link-dev-zero", "input", "ln -s /dev/zero n.npy\n",
     f"{SURF} --normals n.npy --out o", "refuse", ["--normals"], SURFOUT, timeout=60,
     why="a link to /dev/zero as the map is not a regular file: refused naming --normals, never read without end")
case("k40-surf-mask-link-dev-zero", "input", "ln -s /dev/zero m.png\n",
     f"{SURF} --normals {N0} --mask m.png --out o", "refuse", ["--mask"], SURFOUT, timeout=60,
     why="a link to /dev/zero as the mask: refused naming --mask, no hang")
case("k40-surf-intrinsics-link-dev-zero", "input", "ln -s /dev/zero K.txt\n",
     f"{SURF0} --intrinsics K.txt", "refuse", ["--intrinsics"], SURFOUT, timeout=60,
     why="np.loadtxt of /dev/zero never ends: refused naming --intrinsics as not a regular file")
case("k40-surf-out-dev-null", "writer", "", SURF0.replace("--out o", "--out /dev/null"), "refuse", ["--out"], [],
     timeout=60, why="/dev/null is not a folder: refused naming --out")

# ============================================================================ surface: odd maps
NPY_PRE = """
n = cv2.imread(F + "/pred8/00000/normal.png", -1)[..., ::-1].astype(np.float32) / 65535 * 2 - 1
m = cv2.imread(F + "/data8/00000.data/mask.png", 0) > 0
n[~m] = 0
"""
case("k40-surf-npy-header-huge-shape", "input",
     py(PRE + """
hdr = "{'descr': '<f4', 'fortran_order': False, 'shape': (100000, 100000, 3), }"
hdr = hdr + " " * (118 - len(hdr)) + "\\n"
open("n.npy", "wb").write(b"\\x93NUMPY\\x01\\x00" + struct.pack("<H", len(hdr)) + hdr.encode() + b"\\x00" * 1000)
"""), f"{SURF} --normals n.npy --out o", "refuse", ["n.npy"], SURFOUT, timeout=60,
     why="an NPY header claiming 120 GB with 1 kB of data is refused naming the file, not allocated")
case("k40-surf-npy-four-channels", "input", py(PRE + NPY_PRE + """
np.save("n.npy", np.concatenate([n, np.ones_like(n[..., :1])], -1))
"""), f"{SURF} --normals n.npy --mask {M0} --out o", "refuse", ["n.npy"], SURFOUT,
     why="an (H, W, 4) array is not a normal map: refused naming the file and the shape")
case("k40-surf-npy-two-dimensional", "input", py(PRE + NPY_PRE + """
np.save("n.npy", n[..., 2].copy())
"""), f"{SURF} --normals n.npy --mask {M0} --out o", "refuse", ["n.npy"], SURFOUT,
     why="an (H, W) array (only n_z) is not a normal map: refused naming the file")
case("k40-surf-npy-fortran-order", "input", py(PRE + NPY_PRE + """
np.save("n.npy", np.asfortranarray(n))
"""), f"{SURF} --normals n.npy --mask {M0} --out o && test -s o/depth.npy", "ok", [], SURFOUT,
     why="a Fortran-ordered array (MATLAB / Julia export) holds the same map: integrated like a C-ordered one")
case("k40-surf-npz", "input", py(PRE + NPY_PRE + """
np.savez("n.npz", normal=n)
"""), f"{SURF} --normals n.npz --mask {M0} --out o", "refuse", ["--normals"], SURFOUT,
     why=".npz is not among the map formats (.png/.tif/.exr/.npy/.mat): refused naming --normals and the file")
case("k40-surf-exr-one-channel", "input", py(PRE + NPY_PRE + """
from scenes.exr import write_exr
write_exr("n.exr", n[..., 2])
"""), f"{SURF} --normals n.exr --mask {M0} --out o", "refuse", ["n.exr"], SURFOUT,
     why="an EXR of one channel (Y) is not a normal map: refused naming the file, not broadcast to three")
case("k40-surf-all-edge-on", "input", py(PRE + NPY_PRE + """
e = np.zeros_like(n); e[m] = (1, 0, 0)
np.save("n.npy", e)
"""), f"{SURF} --normals n.npy --mask {M0} --out o", "either", [], SURFOUT,
     why="every normal at n_z = 0 (edge-on) fixes no depth: refused naming --normals or integrated to a flat "
         "surface, never a NaN mesh with exit 0 or a traceback")
case("k40-surf-float-tiff-of-n", "input", py(PRE + NPY_PRE + """
cv2.imwrite("n.tif", n[..., ::-1].copy())
"""), f"{SURF} --normals n.tif --mask {M0} --out o", "either", [], SURFOUT,
     why="a float32 TIFF holding n itself (not (n + 1) / 2): read as n, or refused naming the file; never decoded "
         "as codes into wrong normals that face away")
case("k40-surf-one-pixel-map", "input", py(PRE + """
np.save("n.npy", np.array([[[0, 0, 1]]], np.float32))
"""), f"{SURF} --normals n.npy --out o --mesh ply,obj,glb", "either", [], SURFOUT,
     why="a 1x1 map has one vertex and no face: refused in one line or a one-point surface, never a traceback")

# ============================================================================ surface: cameras and meshes
case("k40-surf-intrinsics-npy-binary", "input", py(PRE + """
np.save("K.npy", np.array([[40, 0, 16], [0, 40, 16], [0, 0, 1]], np.float64))
"""), f"{SURF0} --intrinsics K.npy", "either", [], SURFOUT,
     why="a binary K.npy: read as the matrix or refused naming --intrinsics (a text file expected), never a "
         "UnicodeDecodeError")
case("k40-surf-intrinsics-comment-line", "input",
     "printf '# K from OpenCV calibrateCamera\\n40 0 16\\n0 40 16\\n0 0 1\\n' > K.txt\n",
     f"{SURF0} --intrinsics K.txt && grep -q perspective o/report.json", "ok", [], SURFOUT,
     why="a comment line above the matrix (np.savetxt header) is read by np.loadtxt: a perspective camera")
case("k40-surf-intrinsics-inf", "input", "printf 'inf 0 16\\n0 40 16\\n0 0 1\\n' > K.txt\n",
     f"{SURF0} --intrinsics K.txt", "refuse", ["--intrinsics"], SURFOUT,
     why="an infinite focal length is refused naming --intrinsics, not integrated")
case("k40-surf-intrinsics-principal-point-far-away", "input", "printf '40 0 1e6\\n0 40 16\\n0 0 1\\n' > K.txt\n",
     f"{SURF0} --intrinsics K.txt", "either", [], SURFOUT,
     why="a principal point a million pixels off the image: refused naming --intrinsics or integrated; never NaN "
         "depth with exit 0 or a traceback")
case("k40-surf-mesh-path-escape", "security", "",
     f"{SURF0} --mesh ../escape-k40-mesh" + left("$C/../escape-k40-mesh", "a --mesh item wrote a path"),
     "refuse", ["--mesh"], SURFOUT,
     why="--mesh takes formats, not paths: '../escape-k40-mesh' refused naming --mesh, nothing written outside")
case("k40-surf-mesh-uppercase", "input", "", f"{SURF0} --mesh PLY,OBJ", "either", [], SURFOUT,
     why="formats in upper case: accepted as ply,obj or refused naming --mesh; never a file named mesh.PLY beside")
case("k40-surf-mesh-link-out-then-overwrite", "writer",
     f"echo users-mesh > users.ply\n{SURF0} > s.log 2>&1\nrm o/mesh.ply && ln -s ../users.ply o/mesh.ply\n",
     f"{SURF0} --overwrite",
     "either", [], SURFOUT,
     why="an earlier run's mesh.ply replaced by a link to the user's users.ply: --overwrite replaces the link "
         "itself or refuses naming it; users.ply stays as it was")
case("k40-surf-depth-dangling-link-escape", "security",
     'mkdir o && ln -s "$C/../escape-k40-depth.npy" o/depth.npy\n',
     SURF0 + left("$C/../escape-k40-depth.npy", "depth.npy written through a dangling link"),
     "refuse", ["depth.npy"], SURFOUT,
     why="a dangling link planted where depth.npy goes (no earlier run): refused naming it, nothing created "
         "where it points")

# ============================================================================ rerender / refine on user folders
case("k40-rr-user-folder-fitted-ok", "input", USER,
     RRU + " && test -s r/u/report.json", "ok", [], R,
     why="an object folder without scene.json is checked in the fitted mode: the report is written")
case("k40-rr-user-folder-gap-in-images", "input", USER + "rm u/L003.png\n", RRU, "either", [], R,
     why="L000..L007 with L003 gone (a deleted photo) in a folder without a scene: read in natural order or "
         "refused naming the gap; never a traceback")
case("k40-rr-user-folder-png-and-jpg-one-index", "input",
     USER + py(PRE + """
cv2.imwrite("u/L002.jpg", cv2.imread("u/L002.png"))
"""), RRU, "either", [], R,
     why="L002.png and L002.jpg (an export beside its original): one light seen twice, refused naming one of them "
         "or read as two images; never a traceback")
case("k40-rr-fit-light-model-auto-two-steps", "input", USER, RRU + " --light-model auto", "either", [], R,
     why="--light-model auto splits --steps 2 into thirds (0 each): refused naming --steps or run; never a "
         "traceback or a division by zero")
case("k40-rr-fit-batch-images-beyond-count", "input", USER, RRU + " --batch-images 1000 && test -s r/u/report.json",
     "ok", [], R, why="more images per step than the folder holds: all 8 each step (bounded), or one line; runs")
case("k40-rf-user-folder-normals-exr-nan-inside", "input",
     USER + py(PRE + NPY_PRE + """
from scenes.exr import write_exr
ys, xs = np.nonzero(m); n[ys[len(ys) // 2], xs[len(xs) // 2]] = np.nan
write_exr("n.exr", n)
"""), RFU.replace('"$F/pred8/00000/normal.png"', "n.exr"), "refuse", ["n.exr"], RF,
     why="a NaN normal inside the mask of the starting map is refused naming the file before any fit")
case("k40-rf-normals-folder-of-another-object", "input",
     USER + 'mkdir -p nf/00001 && cp "$F/pred8/00001/normal.png" nf/00001/\n',
     RFU.replace('"$F/pred8/00000/normal.png"', "nf"), "refuse", ["nf"], RF,
     why="--normals folder holding only another object's map (00001) for folder u: refused naming --normals, "
         "never that object's map")
case("k40-rf-user-folder-mask-removed", "input", USER + "rm u/mask.png\n", RFU, "either", [], RF,
     why="a user folder without mask.png (the UniPS layout: the whole image is the object) against a map that is "
         "zero outside: refused in one line or refined; never a traceback")
case("k40-rf-data-is-a-capture-out", "input", CAP_SETUP,
     '$PY -m validate.refine --data o --normals o/normal.png --out rf --refine-steps 2 --steps 2 --rounds 1 '
     "--ao-rays 0 --no-shadows --threads 1", "refuse", ["--data"], RF,
     why="a capture's --out is not an object folder (its normal.png, mask.png are outputs): refused naming --data")

# ============================================================================ wildgen.preview on user folders
case("k40-pv-folder-of-photos", "input", PH, f"{PV} p --out pv", "refuse", [], PVO,
     why="a folder of JPEG photos is no dataset or object folder: refused in one line naming it")
case("k40-pv-capture-out", "input", CAP_SETUP, f"{PV} o --out pv", "refuse", [], PVO,
     why="a capture's --out is not a dataset: refused in one line, never a contact sheet of its outputs")
case("k40-pv-capture-work-folder", "input", CAP_WORK_SETUP,
     f'{PV} o/work/*.data --out pv && ls pv/*.png', "either", [], PVO,
     why="the capture's work/<name>.data (an object folder without scene.json) gets a contact sheet or one line")
case("k40-pv-user-folder-no-scene", "input", USER, f"{PV} u --out pv", "either", [], PVO,
     why="an object folder without scene.json: a contact sheet of its images or one line naming scene.json")
case("k40-pv-stats-user-folder-no-scene", "input", USER, f"{PV} u --out pv --stats", "either", [], PVO,
     why="--stats of a folder without a scene: its failure listed under `failed` or one line; never a traceback")
case("k40-pv-diligent-folder", "input",
     'mkdir b && for i in 001 002 003 004; do cp "$F/ballPNG/$i.png" b/; done\n'
     'head -4 "$F/ballPNG/light_directions.txt" > b/light_directions.txt; cp "$F/ballPNG/mask.png" b/\n',
     f"{PV} b --out pv", "either", [], PVO,
     why="a DiLiGenT object folder: a contact sheet or one line saying the layout is not previewed")

# ============================================================================ added after the first trials
def both(cmd_a: str, cmd_b: str, after: str = "") -> str:
    """Two commands started at once; ok when at least one succeeded and `after` holds; both outputs printed."""
    return (f"( {cmd_a} ) > a.log 2>&1 & p1=$!; ( {cmd_b} ) > b.log 2>&1 & p2=$!; wait $p1; r1=$?; wait $p2; r2=$?; "
            f'cat a.log b.log; echo "rc $r1 $r2"; [ $r1 = 0 ] || [ $r2 = 0 ] || exit 1; {after or "true"}')


case("k40-rr-and-rf-into-one-out-at-once", "concurrency", USER,
     both(RRU.replace("--out r", "--out x"), RFU.replace("--out rf", "--out x")), "ok", [], deep("x"), timeout=120,
     why="validate.rerender and validate.refine started at once with one --out: one holds the folder, the other "
         "finishes or is refused in one line (another run holds it); never two writers, never both refused")
case("k40-rf-normals-opencv-frame", "input",
     USER + py(PRE + NPY_PRE + """
o = n.copy(); o[..., 1:] *= -1
np.save("n.npy", o)
"""), RFU.replace('"$F/pred8/00000/normal.png"', "n.npy"), "refuse", ["--normals"], RF,
     why="a map in the OpenCV frame (y down, z away: every normal faces away) given to refine is refused naming "
         "--normals, not refined into nonsense")
case("k40-rr-user-normals-npy-other-size", "input",
     USER + py(PRE + NPY_PRE + """
np.save("n.npy", cv2.resize(n, (16, 16), interpolation=cv2.INTER_NEAREST))
"""), RRU.replace('"$F/pred8/00000/normal.png"', "n.npy"), "refuse", ["n.npy"], R,
     why="a 16 px map for a 32 px user folder is refused naming the map and both sizes, not resized silently")
case("k40-surf-png-rgba-alpha-is-mask", "input",
     py(PRE + """
n = cv2.imread(F + "/pred8/00000/normal.png", -1)
m = cv2.imread(F + "/data8/00000.data/mask.png", 0) > 0
a = np.where(m, 65535, 0).astype(np.uint16)
cv2.imwrite("n.png", np.dstack([n, a]))
"""), f"{SURF} --normals n.png --out o", "either", [], SURFOUT,
     why="a 16-bit RGBA normal map whose alpha is the object (a texture tool's export): the alpha taken as the "
         "mask, or refused naming the file; never a traceback")
case("k40-surf-mask-two-parts", "input",
     py(PRE + """
m = cv2.imread(F + "/data8/00000.data/mask.png", 0) > 0
m[:, 14:18] = False
cv2.imwrite("m.png", m.astype(np.uint8) * 255)
"""), f"{SURF} --normals {N0} --mask m.png --out o && test -s o/depth.npy && grep -q parts o/report.json",
     "ok", [], SURFOUT,
     why="a mask cut into two parts is valid (docs: each connected part gets the same median depth): integrated")
case("k40-cap-names-nfc-and-nfd", "input",
     PH + py("""
import os, unicodedata
os.rename("p/photo00.jpg", "p/" + unicodedata.normalize("NFC", "é0.jpg"))
os.rename("p/photo01.jpg", "p/" + unicodedata.normalize("NFD", "é1.jpg"))
"""), CAP + OK_CAP + " && grep -c jpg o/report.json", "ok", [], O,
     why="a name in NFC beside one in NFD (a Mac's copy) are two photos with UTF-8 names: both read")
case("k40-cap-overwrite-other-input-keep-work", "writer",
     PH + CAP + " --max-side 32 --keep-work > s.log 2>&1\nmv p q\n",
     taken_or_named(CAP.replace("--input p", "--input q") + " --max-side 32 --keep-work --overwrite", "--out",
                    "ls o/work o/check; if [ -e o/work/p.data ] || [ -e o/check/p ]; then echo 'FAULT: the earlier "
                    "capture of p left work/p.data and check/p beside the new capture of q after --overwrite'; "
                    "exit 1; fi"), "ok", [], O,
     why="a second capture of another folder (q) into the same --out with --overwrite replaces the earlier run's "
         "outputs: its work/p.data and check/p are the capture's own and go (as orchestrate.surface removes its "
         "meshes of formats not written now), or the run is refused in one line; never two captures' folders "
         "side by side under one report")
