"""Sweep 41, part n: the USER-PHOTO and CHECK side (orchestrate.capture, orchestrate.surface, validate.rerender,
validate.refine, wildgen.preview), with cases that cases37_*.py .. cases40_*.py and tests/test_bad_inputs.py do not
hold.

What a phone, a DSLR or a lab setup leaves and what an attacker plants:
- a mask saved into the photo folder, a multi-page TIFF, 16-bit TIFF photos, an sRGB ICC profile, EXIF exposure
  pairs that normalise, one photo without EXIF, all photos turned 180 deg, names differing only by case, a sparse
  2 GB file and a JPEG whose header claims a huge frame;
- masks of one colour, cut-outs, a soft 128-everywhere mask, a mask of a folder, a pipe or with unicode in its path;
- --input spelled `.`, `p/.` and with a trailing slash (the name of check/ and work/ folders), --out states (nested,
  a link to an empty folder, a user's file or folder beside the outputs, --overwrite of nothing), flags that
  contradict (--rotation-search with --no-refine) or run past their bounds;
- surface maps with vectors of length 2, an all-black mask, --mesh of an unknown format, negative --k / --focal-px,
  two writers into one --out;
- scene.json edited by hand (NaN exposure, a mesh path leading out, format_version 99) for rerender/refine, an
  unavailable --variant, out-of-range check flags, a dataset whose predictions lack an object;
- wildgen.preview into the dataset itself, a rerun without --overwrite, a manifest object name leading out.

Cases whose command adds its own check print a line starting with `FAULT:` and exit 0 (flagged exit0 where a
refusal is due) or exit 1 (failed where a success is due).
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
from PIL.TiffImagePlugin import IFDRational
F = os.environ["F"]; C = os.environ["C"]
photos = sorted(glob.glob("p/*.jpg"))
"""

PH = 'cp -r "$F/photos" p\n'


def setup_py(code: str, photos: bool = True) -> str:
    """Setup: (a copy of the 8 JPEG photos in p/, then) Python with PRE's names."""
    return (PH if photos else "") + py(PRE + textwrap.dedent(code))


CAPX = "$PY -m orchestrate.capture --no-refine --threads 1"
CAP = CAPX + ' --input p --out o --mask "$F/mask.png"'
"""A capture of p/ with the fixtures' mask, without refinement (about 13 s)."""
CAP_SETUP = PH + CAP + " > cap_setup.log 2>&1\n"
SURF = "$PY -m orchestrate.surface"
N0 = '"$F/pred8/00000/normal.png"'
M0 = '"$F/data8/00000.data/mask.png"'
SURF0 = f"{SURF} --normals {N0} --mask {M0} --out o"
USER = 'cp -r "$F/data8/00000.data" u && rm u/scene.json\n'
"""Setup: u/, an object folder as a user has it: L*.png, mask.png, normal.tif, no scene.json (the fitted mode)."""
OBJ = 'cp -r "$F/data8/00000.data" d\n'
"""Setup: d/, an object folder with its scene.json (the known-scene mode)."""
FAST = " --steps 2 --ao-rays 0 --no-shadows --no-bas-relief --threads 1"
RRU = '$PY -m validate.rerender --data u --normals "$F/pred8/00000/normal.png" --out r' + FAST
RRD = '$PY -m validate.rerender --data d --normals "$F/pred8/00000/normal.png" --out r --spp 1 --no-floors --threshold 0.5'
RFARGS = " --refine-steps 2 --steps 2 --rounds 1 --ao-rays 0 --no-shadows --threads 1"
RFU = '$PY -m validate.refine --data u --normals "$F/pred8/00000/normal.png" --out rf' + RFARGS
PV = "$PY -m wildgen.preview"


def deep(d: str) -> list[str]:
    return [f"$C/{d}", f"$C/{d}/*", f"$C/{d}/*/*", f"$C/{d}/*/*/*", f"$C/{d}/*/*/*/*", f"$C/{d}/.*",
            f"$C/{d}/*/.*"]


O = deep("o")
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


def report_images(n: int) -> str:
    """Command tail: o/report.json must say `n` photos were read."""
    return (f"""$PY -c "import json,sys; n=json.load(open('o/report.json'))['input']['images']; """
            f"""print('images', n); sys.exit(0 if n == {n} else print('FAULT: report says', n, 'photos, not {n}') or 1)" """)


CASES: list[dict] = []


def case(id, kind, setup, cmd, expect, names=(), may_change=(), timeout=120, why=""):
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


# ============================================================================ capture: what lies in the photo folder
case("n41-cap-mask-saved-into-photo-folder", "input",
     PH + 'cp "$F/mask.png" p/mask.png\n',
     taken_or_named(CAPX + " --input p --out o", "mask.png", report_images(8)), "ok", [], O,
     why="a user saves the mask beside the photos: it is used as the mask, skipped, or refused naming mask.png; "
         "never read as a ninth photo")
case("n41-cap-mask-saved-into-photo-folder-and-given", "input",
     PH + 'cp "$F/mask.png" p/mask.png\n',
     taken_or_named(CAPX + ' --input p --out o --mask p/mask.png', "mask.png", report_images(8)), "ok", [], O,
     why="the mask given with --mask and lying among the photos must not also be read as a photo")
case("n41-cap-multipage-tiff-among-jpegs", "input",
     setup_py("""
ims = [Image.open(p).convert("RGB") for p in photos[:2]]
ims[0].save("p/photo08.tif", save_all=True, append_images=ims[1:])
"""), CAP, "refuse", ["photo08.tif"], O,
     why="docs: a TIFF of several pages is refused naming it (which page would be the photo?)")
case("n41-cap-tiff16-photos", "input",
     setup_py("""
for p in photos:
    a = cv2.imread(p).astype(np.uint16) * 257
    cv2.imwrite(p[:-4] + ".tif", a); os.remove(p)
"""), CAP + OK_CAP, "ok", [], O,
     why="16-bit TIFF photos (a raw developer's export) are documented linear input: the capture runs")
case("n41-cap-jpeg-srgb-icc-embedded", "input",
     setup_py("""
from PIL import ImageCms
icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
for p in photos:
    Image.open(p).convert("RGB").save(p, quality=95, icc_profile=icc)
"""), CAP + OK_CAP, "ok", [], O,
     why="an sRGB ICC profile (what every phone embeds) is read with the sRGB curve: the capture runs")
case("n41-cap-jpeg-lab-icc-embedded", "input",
     setup_py("""
from PIL import ImageCms
icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("LAB")).tobytes()
for p in photos:
    Image.open(p).convert("RGB").save(p, quality=95, icc_profile=icc)
"""), CAP, "refuse", ["photo00.jpg"], O,
     why="a JPEG whose ICC profile is neither the sRGB curve nor linear is refused naming the file and the profile")
case("n41-cap-one-photo-without-icc-among-icc", "input",
     setup_py("""
from PIL import ImageCms
icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
for p in photos[1:]:
    Image.open(p).convert("RGB").save(p, quality=95, icc_profile=icc)
"""), CAP + OK_CAP, "either", [], O,
     why="one 8-bit JPEG without a profile among sRGB-profiled ones is sRGB either way: read alike or refused in one "
         "line naming photo00.jpg")
case("n41-cap-names-differ-by-case", "input",
     setup_py("""
shutil.copy(photos[1], "p/PHOTO00.JPG")
os.remove(photos[1])
"""), taken_or_named(CAP, "photo00", report_images(8)), "ok", [], O,
     why="photo00.jpg and PHOTO00.JPG are two files on Linux: both read (8 photos) or refused naming them")
case("n41-cap-photo-sparse-2gb", "input",
     PH + 'truncate -s 2G p/photo08.jpg\n', CAP, "refuse", ["photo08.jpg"], O, timeout=60,
     why="a 2 GB file of zeros under a photo name (a failed copy) is no JPEG: refused quickly naming it, not read "
         "whole into memory")
case("n41-cap-first-photo-header-claims-huge", "input",
     setup_py("""
b = bytearray(open(photos[0], "rb").read())
i = 2
while True:
    assert b[i] == 0xFF
    m = b[i + 1]; n = (b[i + 2] << 8) | b[i + 3]
    if m in (0xC0, 0xC1, 0xC2):
        b[i + 5:i + 9] = struct.pack(">HH", 65000, 65000); break
    i += 2 + n
open(photos[0], "wb").write(bytes(b))
"""), CAP, "refuse", ["photo00.jpg"], O, timeout=90,
     why="a first JPEG whose header claims 65000 x 65000 px (the memory estimate reads it) is refused quickly "
         "naming it, never decoded into 12 GB or a traceback")
case("n41-cap-all-photos-exif-180", "input",
     setup_py("""
for p in photos:
    im = Image.open(p); ex = im.getexif(); ex[0x0112] = 3
    im.save(p, quality=95, exif=ex.tobytes())
"""), CAP + OK_CAP, "either", [], O,
     why="every photo says 'turned 180 deg' (a camera held upside down): the same orientation for all, read turned "
         "(the square mask fits) or refused in one line; never a traceback")
case("n41-cap-exif-exposure-two-levels", "input",
     setup_py("""
for k, p in enumerate(photos):
    im = Image.open(p); ex = im.getexif()
    e = ex.get_ifd(0x8769); e[0x829A] = IFDRational(1, 100) if k % 2 else IFDRational(1, 50); e[0x8827] = 100
    im.save(p, quality=95, exif=ex.tobytes())
"""), CAP + OK_CAP + """ && $PY -c "import json; print(json.load(open('o/report.json'))['input'].get('exposure'))" """,
     "ok", [], O,
     why="docs: where every photo gives time and ISO the photos are brought to the first one's exposure; two levels "
         "a stop apart are normal bracketing and run through")
case("n41-cap-exif-one-photo-lacks-exposure", "input",
     setup_py("""
for p in photos[1:]:
    im = Image.open(p); ex = im.getexif()
    e = ex.get_ifd(0x8769); e[0x829A] = IFDRational(1, 100); e[0x8827] = 200
    im.save(p, quality=95, exif=ex.tobytes())
"""), CAP + OK_CAP, "ok", [], O,
     why="docs: where some photo lacks a field none is rescaled (input.exposure says which): runs, no traceback")
case("n41-cap-exif-iso-zero", "input",
     setup_py("""
for p in photos:
    im = Image.open(p); ex = im.getexif()
    e = ex.get_ifd(0x8769); e[0x829A] = IFDRational(1, 100); e[0x8827] = 0
    im.save(p, quality=95, exif=ex.tobytes())
"""), CAP, "refuse", ["photo00.jpg"], O,
     why="docs: an ISO of 0 is refused naming the file and the value as written")
case("n41-cap-exif-ifd-garbage", "input",
     setup_py("""
b = open(photos[2], "rb").read()
app1 = b"Exif\\x00\\x00" + b"II*\\x00" + struct.pack("<I", 8) + struct.pack("<H", 0xFFFF) + os.urandom(64)
seg = b"\\xff\\xe1" + struct.pack(">H", len(app1) + 2) + app1
open(photos[2], "wb").write(b[:2] + seg + b[2:])
"""), CAP, "either", [], O,
     why="an EXIF block whose entry count (65535) runs past its end (a broken writer): ignored or refused in one "
         "line naming photo02.jpg; never a traceback")

# ============================================================================ capture: masks
case("n41-cap-mask-red-on-black", "input",
     PH + py("""
import numpy as np, cv2, os
m = cv2.imread(os.environ["F"] + "/mask.png", cv2.IMREAD_GRAYSCALE)
c = np.zeros(m.shape + (3,), np.uint8); c[m > 0] = (0, 0, 255)
cv2.imwrite("red.png", c)
"""), CAPX + " --input p --out o --mask red.png" + OK_CAP, "ok", [], O,
     why="docs: a colour mask is read from the largest of its channels: any one colour on black works")
case("n41-cap-mask-cutout-alpha", "input",
     PH + py("""
import numpy as np, cv2, os
m = cv2.imread(os.environ["F"] + "/mask.png", cv2.IMREAD_GRAYSCALE)
c = np.full(m.shape + (4,), 200, np.uint8); c[..., 3] = np.where(m > 0, 255, 0)
cv2.imwrite("cut.png", c)
"""), CAPX + " --input p --out o --mask cut.png" + OK_CAP, "ok", [], O,
     why="docs: a cut-out (alpha not fully opaque) is read from its alpha, the grey colour ignored")
case("n41-cap-mask-grey-128-everywhere", "input",
     PH + py("""
import numpy as np, cv2
cv2.imwrite("g.png", np.full((64, 64), 128, np.uint8))
"""), CAPX + " --input p --out o --mask g.png", "refuse", ["--mask", "g.png"], O,
     why="docs: one value that is not white everywhere is refused saying the value")
case("n41-cap-mask-all-white-fills-frame", "input",
     PH + py("""
import numpy as np, cv2
cv2.imwrite("w.png", np.full((64, 64), 255, np.uint8))
"""), CAPX + " --input p --out o --mask w.png", "either", [], O,
     why="docs: all white means the object fills the frame: accepted (or refused in one line by a later check)")
case("n41-cap-mask-a-folder", "input",
     PH + "mkdir m.png\n", CAPX + " --input p --out o --mask m.png", "refuse", ["--mask", "m.png"], O,
     why="a folder named like a mask is no mask file: refused naming --mask and it")
case("n41-cap-mask-fifo", "input",
     PH + "mkfifo m.png\n", CAPX + " --input p --out o --mask m.png", "refuse", ["--mask", "m.png"], O, timeout=60,
     why="a pipe as the mask is refused at once naming it, never opened and waited on")
case("n41-cap-mask-is-a-photo", "input",
     PH, CAPX + " --input p --out o --mask p/photo03.jpg", "refuse", ["--mask"], O,
     why="one of the photos given as the mask (a slip of the shell) is no binary mask: refused naming --mask")

# ============================================================================ capture: --input spelling and names
case("n41-cap-input-dot-keep-work", "input",
     PH, 'cd p && ' + CAPX + ' --input . --out ../o --mask "$F/mask.png" --keep-work; r=$?; cd ..; ls -a o o/work o/check 2>/dev/null; '
     'if [ $r = 0 ]; then ls -d o/work/*.data >/dev/null 2>&1 || { echo "FAULT: no work/<name>.data"; exit 1; }; fi; exit $r',
     "either", [], O,
     why="--input . (run from inside the photo folder): the check/ and work/ folders get a real name, never "
         "check/./ (the --out folder itself) or a '.data' hidden folder")
case("n41-cap-input-slash-dot", "input",
     PH, CAPX + ' --input p/. --out o --mask "$F/mask.png" --keep-work; r=$?; ls -a o/work o/check 2>/dev/null; '
     'if [ $r = 0 ] && ! ls o/work/p.data >/dev/null 2>&1; then echo "FAULT: work folder not named after p"; exit 1; fi; exit $r',
     "either", [], O,
     why="--input p/. is the folder p: work/p.data (its name), or a one-line refusal; never '..data' or '.'")
case("n41-cap-input-named-like-html", "input",
     'cp -r "$F/photos" "<img src=x onerror=alert(1)>"\n',
     CAPX + ' --input "<img src=x onerror=alert(1)>" --out o --mask "$F/mask.png"; r=$?; '
     'if [ -f o/report.html ] && grep -qF "<img src=x onerror" o/report.html; then echo "FAULT: folder name injected into report.html"; exit 1; fi; exit $r',
     "either", [], O,
     why="a folder name holding HTML is escaped in report.html (or refused); the page never carries it raw")
case("n41-cap-input-link-named-evil-to-photos", "input",
     'cp -r "$F/photos" p && ln -s p evil_n41_in\n',
     CAPX + ' --input evil_n41_in --out o --mask "$F/mask.png" --keep-work' + OK_CAP, "ok", [], O,
     why="a linked photo folder is read; work/<name>.data lands inside --out whatever the link's name")

# ============================================================================ capture: --out states
case("n41-cap-out-nested-missing-parents", "writer",
     PH, CAP.replace("--out o", "--out o/a/b/c") + " && test -s o/a/b/c/normal.png", "either", [], O,
     why="an --out whose parents do not exist is created (mkdir -p) or refused in one line naming --out")
case("n41-cap-out-link-to-empty-folder", "writer",
     PH + "mkdir real && ln -s real o\n", CAP, "either", [], O + deep("real"),
     why="--out a link to an empty folder: written into it, or refused naming --out; never the link replaced")
case("n41-cap-out-holds-users-notes", "writer",
     PH + "mkdir o && echo mine > o/notes.txt && mkdir o/photos_raw && echo x > o/photos_raw/a.txt\n",
     CAP + " && grep -q mine o/notes.txt && test -s o/photos_raw/a.txt", "either", [],
     ["$C/o", "$C/o/*.png", "$C/o/*.exr", "$C/o/*.npy", "$C/o/*.json", "$C/o/*.html", "$C/o/surface",
      "$C/o/surface/*", "$C/o/check", "$C/o/check/*", "$C/o/check/*/*", "$C/o/refine", "$C/o/refine/*",
      "$C/o/refine/*/*", "$C/o/.*"],
     why="an --out holding a user's notes and folder: the capture writes its own names beside them (or refuses); "
         "the user's files stay byte-identical")
case("n41-cap-overwrite-on-fresh-out", "writer",
     PH, CAP + " --overwrite" + OK_CAP, "ok", [], O,
     why="--overwrite with nothing to overwrite is no error: the capture runs")
case("n41-cap-overwrite-keeps-users-check-subfolder", "writer",
     CAP_SETUP + "mkdir -p o/check/mine && echo keep > o/check/mine/note.txt\n",
     CAP + " --overwrite --convention opencv; r=$?; test -s o/check/mine/note.txt || { echo 'FAULT: user folder in check/ removed'; exit 1; }; exit $r",
     "ok", [],
     ["$C/o", "$C/o/*.png", "$C/o/*.exr", "$C/o/*.npy", "$C/o/*.json", "$C/o/*.html", "$C/o/surface",
      "$C/o/surface/*", "$C/o/check", "$C/o/check/p", "$C/o/check/p/*", "$C/o/refine", "$C/o/refine/*",
      "$C/o/refine/*/*", "$C/o/.*", "$C/o/*/.*"],
     why="docs: --overwrite removes an earlier capture's check/ folders of another name, a user's never: "
         "o/check/mine/note.txt stays", timeout=120)
case("n41-cap-out-is-a-dataset", "writer",
     'cp -r "$F/data" ds\n' + PH, CAP.replace("--out o", "--out ds"), "either", [], deep("ds"),
     why="a dataset folder as --out (its object folders are not the capture's): written beside them or refused; "
         "manifest.json and every object file stay the same")

# ============================================================================ capture: flags
case("n41-cap-rotation-search-with-no-refine", "message",
     PH, CAP + " --rotation-search", "either", [], O,
     why="--rotation-search only acts in the refinement: with --no-refine it is refused naming both flags or "
         "ignored (a note); never a traceback")
case("n41-cap-rotation-steps-beyond-bound", "input",
     PH, CAP + " --rotation-steps 8001", "refuse", ["--rotation-steps", "8001"], O,
     why="docs: at most 100 times the default (8000): 8001 refused naming the flag before any photo is read")
case("n41-cap-threads-huge", "input",
     PH, CAP.replace("--threads 1", "--threads 100000"), "either", [], O,
     why="100000 Dr.Jit threads on 2 cores: capped, run, or refused naming --threads; never a hang or a crash")
case("n41-cap-srgb-on-exr-photos", "input",
     setup_py("""
import OpenEXR
for p in photos:
    a = (cv2.imread(p)[..., ::-1].astype(np.float32) / 255) ** 2.2
    ch = {c: np.ascontiguousarray(a[..., i]) for i, c in enumerate("RGB")}
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, ch) as f:
        f.write(p[:-4] + ".exr")
    os.remove(p)
"""), CAP + " --input-encoding srgb", "either", [], O,
     why="--input-encoding srgb on float EXR photos (linear by nature): taken as asked or refused naming the flag; "
         "no traceback")
case("n41-cap-model-glc-unips-without-checkpoint", "weights",
     PH, CAP + " --model glc-unips", "either", [], O,
     why="--model glc-unips without --checkpoint asks for its shipped weights: used, or refused naming --model "
         "(none shipped) before any photo is read")
case("n41-cap-checkpoint-folder-with-our-file", "weights",
     PH + 'mkdir w && cp "$F/run/last.pt" w/ 2>/dev/null || cp "$(ls "$F"/run/*.pt | head -1)" w/\n',
     CAP + " --checkpoint w --model sdm-unips", "refuse", ["--checkpoint"], O,
     why="a folder holding our training checkpoint is not the authors' published sdm-unips weights: refused naming "
         "--checkpoint before any photo is read")

# ============================================================================ surface
case("n41-surf-normals-length-two", "input",
     py("""
import numpy as np, cv2
n = cv2.imread("/tmp/x", 0)
""").replace('n = cv2.imread("/tmp/x", 0)', "import os\n"
"F = os.environ['F']\n"
"a = cv2.imread(F + '/pred8/00000/normal.png', cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float32) / 65535 * 2 - 1\n"
"m = cv2.imread(F + '/data8/00000.data/mask.png', 0) > 0\n"
"a[~m] = 0\n"
"np.save('n2.npy', (a * 2).astype(np.float32))"),
     f"{SURF} --normals n2.npy --mask {M0} --out o", "either", [], deep("o"),
     why="vectors of length 2 (a map scaled by a tool) are normalised or refused naming n2.npy; never integrated "
         "as slopes twice too steep with exit 0 and no word")
case("n41-surf-mask-all-black", "input",
     py("import numpy as np, cv2\ncv2.imwrite('z.png', np.zeros((32, 32), np.uint8))"),
     f"{SURF} --normals {N0} --mask z.png --out o", "refuse", ["--mask", "z.png"], deep("o"),
     why="an empty mask leaves nothing to integrate: refused naming --mask, not an empty mesh")
case("n41-surf-mask-other-size", "input",
     py("import numpy as np, cv2\ncv2.imwrite('m48.png', np.full((48, 48), 255, np.uint8))"),
     f"{SURF} --normals {N0} --mask m48.png --out o", "refuse", ["--mask", "m48.png"], deep("o"),
     why="a 48 px mask for a 32 px map is refused naming --mask and both sizes")
case("n41-surf-mesh-stl", "input",
     "", SURF0 + " --mesh stl", "refuse", ["--mesh", "stl"], deep("o"),
     why="stl is not among the mesh formats (ply, obj, glb): refused naming --mesh and the value")
case("n41-surf-mesh-empty", "input",
     "", SURF0 + " --mesh ''", "refuse", ["--mesh"], deep("o"),
     why="--mesh '' asks for no format: refused naming --mesh (never a run writing no mesh silently)")
case("n41-surf-k-negative", "input",
     "", SURF0 + " --k -1", "refuse", ["--k"], deep("o"),
     why="a negative sharpness turns the discontinuity weights into amplifiers: refused naming --k")
case("n41-surf-focal-px-negative", "input",
     "", SURF0 + " --focal-px -100", "refuse", ["--focal-px"], deep("o"),
     why="a negative focal length mirrors the camera: refused naming --focal-px")
case("n41-surf-intrinsics-nan", "input",
     "printf '40 0 16\\n0 nan 16\\n0 0 1\\n' > K.txt\n", SURF0 + " --intrinsics K.txt", "refuse",
     ["--intrinsics", "K.txt"], deep("o"),
     why="a NaN focal length in K.txt is refused naming the file, never NaN depth with exit 0")
case("n41-surf-two-writers-one-out", "concurrency",
     "", f"( {SURF0} ) > a.log 2>&1 & p1=$!; ( {SURF0} --k 0 ) > b.log 2>&1 & p2=$!; wait $p1; r1=$?; wait $p2; r2=$?; "
         'cat a.log b.log; echo "rc $r1 $r2"; [ $r1 = 0 ] || [ $r2 = 0 ] || exit 1; '
         '$PY -c "import json; json.load(open(\'o/report.json\'))"',
     "ok", [], deep("o"),
     why="two surfaces into one --out at once: one writes, the other is refused in one line (one writer per folder); "
         "report.json whole")

# ============================================================================ rerender / refine
case("n41-rr-scene-exposure-nan", "input",
     OBJ + py("""
import json
s = json.load(open('d/scene.json')); s['images'][1]['exposure'] = float('nan')
json.dump(s, open('d/scene.json', 'w'), indent=1)
"""), RRD, "refuse", ["scene.json"], R,
     why="a NaN exposure in a hand-edited scene.json is refused naming scene.json, never a NaN report with exit 0")
case("n41-rr-scene-env-file-escapes", "archive",
     OBJ + 'echo pwn > planted_env.exr\n' + py("""
import json
s = json.load(open('d/scene.json')); s['environment']['file'] = '../planted_env.exr'
json.dump(s, open('d/scene.json', 'w'), indent=1)
"""), RRD, "refuse", ["scene.json"], R,
     why="a scene.json file path leading out of the object folder (../planted_env.exr) is refused naming it, never read")
case("n41-rr-scene-env-file-absolute", "archive",
     OBJ + py("""
import json
s = json.load(open('d/scene.json')); s['environment']['file'] = '/etc/passwd'
json.dump(s, open('d/scene.json', 'w'), indent=1)
"""), RRD, "refuse", ["scene.json"], R,
     why="an absolute path in scene.json (/etc/passwd as the environment map) is refused naming scene.json")
case("n41-rr-scene-format-version-99", "input",
     OBJ + py("""
import json
s = json.load(open('d/scene.json')); s['format_version'] = 99
json.dump(s, open('d/scene.json', 'w'), indent=1)
"""), RRD, "refuse", ["format_version"], R,
     why="a scene.json from a future format is refused naming format_version, never read as version 1")
case("n41-rr-scene-duplicate-images-key", "input",
     OBJ + py("""
t = open('d/scene.json').read()
t = t.replace('"format_version": 1', '"images": [], "format_version": 1', 1)
open('d/scene.json', 'w').write(t)
"""), RRD, "either", [], R,
     why="scene.json naming 'images' twice (the last, the real one, wins in json): read as json reads it or refused "
         "naming scene.json; never a traceback")
case("n41-rr-variant-unknown", "input",
     USER, RRU + " --variant foo_rgb", "refuse", ["--variant", "foo_rgb"], R,
     why="an unknown Mitsuba variant is refused naming --variant and the value, not a Mitsuba traceback")
case("n41-rr-variant-scalar-fitted", "input",
     USER, RRU + " --variant scalar_rgb", "either", [], R,
     why="the fitted mode needs automatic differentiation: scalar_rgb run or refused naming --variant in one line")
case("n41-rr-spp-beyond-65536", "input",
     OBJ, RRD.replace("--spp 1", "--spp 65537"), "refuse", ["--spp"], R,
     why="the help says at most 65536 samples per pixel: 65537 refused naming --spp before any render")
case("n41-rr-threshold-negative", "input",
     OBJ, RRD.replace("--threshold 0.5", "--threshold -0.5"), "refuse", ["--threshold"], R,
     why="a negative relative residual threshold counts every pixel: refused naming --threshold")
case("n41-rr-min-coverage-above-one", "input",
     USER, RRU + " --allow-missing --min-coverage 1.5", "refuse", ["--min-coverage"], R,
     why="a share above 1 can never be met: refused naming --min-coverage")
case("n41-rr-dataset-pred-missing-object", "input",
     'cp -r "$F/data8" ds && mkdir pr && cp -r "$F/pred8/00000" "$F/pred8/00002" pr/\n',
     '$PY -m validate.rerender --data ds --normals pr --out r --spp 1 --no-floors --threshold 0.5 > out.log 2>&1; r=$?; cat out.log; '
     'if [ $r = 0 ] && ! grep -q 00001 out.log r/summary.csv 2>/dev/null; then echo "FAULT: 00001 silently left out"; exit 1; fi; exit $r',
     "either", [], R, timeout=120,
     why="predictions lacking object 00001: refused naming it, or the run says 00001 was not checked; never a "
         "summary silently missing a row")
case("n41-rr-normals-is-the-data-normal", "input",
     OBJ, '$PY -m validate.rerender --data d --normals d/normal.tif --out r --spp 1 --no-floors --threshold 0.5',
     "either", [], R,
     why="the ground-truth normal.tif given as the prediction is a valid map (a sanity run): checked, or refused "
         "in one line; never a traceback")
case("n41-rf-lights-calibrated-user-folder", "input",
     USER, RFU + " --lights calibrated", "refuse", ["--lights"], RF,
     why="a user folder without scene.json or a light file has no calibrated lights: refused naming --lights")
case("n41-rf-holdout-one", "input",
     USER, RFU + " --holdout 1.0", "refuse", ["--holdout"], RF,
     why="holding out every image leaves none to fit: refused naming --holdout")
case("n41-rf-rounds-zero", "input",
     USER, RFU.replace("--rounds 1", "--rounds 0"), "either", [], RF,
     why="zero rounds: the start map back or a refusal naming --rounds; never a traceback")
case("n41-rf-refine-steps-beyond-bound", "input",
     USER, RFU.replace("--refine-steps 2", "--refine-steps 30001"), "refuse", ["--refine-steps"], RF,
     why="the help bounds --refine-steps at 100 times the default (30000): 30001 refused naming it")
case("n41-rf-normals-dataset-folder", "input",
     OBJ, '$PY -m validate.refine --data d --normals "$F/pred8" --out rf' + RFARGS, "either", [], RF,
     why="--normals a folder with <object>/normal.* for an object folder d (named 'd', not 00000): the object's "
         "map is not found, refused naming --normals; or matched by the scene's name")

# ============================================================================ preview
case("n41-pv-out-is-the-dataset", "writer",
     'cp -r "$F/data" ds\n', PV + " ds --out ds", "either", [], ["$C/ds/*.png", "$C/ds/preview.json", "$C/ds/.*"],
     why="--out the dataset itself: sheets beside the object folders or a refusal; manifest.json and every object "
         "file unchanged")
case("n41-pv-rerun-without-overwrite", "writer",
     'cp -r "$F/data" ds && $PY -m wildgen.preview ds --out pv > s.log 2>&1\n', PV + " ds --out pv", "refuse",
     ["--overwrite"], PVO,
     why="a second preview into an earlier one's folder is refused naming --overwrite; the sheets stay")
case("n41-pv-manifest-object-name-escapes", "archive",
     'cp -r "$F/data" ds\n' + py("""
import json
p = 'ds/manifest.json'; m = json.load(open(p))
m['objects'][0]['name'] = '../../../evil_n41_pv'
json.dump(m, open(p, 'w'), indent=1)
"""), PV + " ds --out pv", "either", [], PVO,
     why="a manifest object name leading out: ignored (sheets named by folder) or refused; no evil_n41_pv.png "
         "written outside --out")
case("n41-pv-object-folder-link-out", "archive",
     'cp -r "$F/data" ds && cp -r "$F/data8/00001.data" outside && ln -s ../outside ds/00009.data\n',
     PV + " ds --out pv", "either", [], PVO,
     why="an object folder that is a link out of the dataset: drawn, skipped or named; never a traceback")
