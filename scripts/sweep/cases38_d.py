"""Sweep 38, part d: the CAPTURE and SURFACE side, new cases beyond sweep 37 (cases37_*.py) and
tests/test_bad_inputs.py.

orchestrate.capture with flag combinations (--max-side, --input-encoding, --convention, --keep-work, --mask,
--checkpoint/--model, --threads) and odd photo sets (mixed formats and bit depths, sizes that differ only after
EXIF rotation, duplicates, hidden files, sub-folders, unicode names, two photos, very dark or clipped photos, RAW
names on non-RAW bytes); orchestrate.surface (--intrinsics / --k / --focal-px, masks, odd maps);
validate.rerender / validate.refine (numeric flags, odd object folders); unips.evaluate.

Mechanisms: nothing lost, one writer per folder, inputs are what they say, one-line messages naming the flag and
file, no exit 0 with a wrong result (outputs are checked where a success is expected).

Run with scripts/sweep/run_sweep.py; every case uses the 32/64-px fixtures of fixtures.sh (a capture of $F/photos
takes about 13 s on 2 cores).
"""
from __future__ import annotations

import textwrap


def py(code: str) -> str:
    """A bash heredoc running `code` with the toolkit's python in $C."""
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


PH = 'cp -r "$F/photos" p\n'
CAP = '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --no-refine --threads 1'
CAP_NOMASK = '$PY -m orchestrate.capture --input p --out o --no-refine --threads 1'
SURF = "$PY -m orchestrate.surface"
N0 = '"$F/pred/00000/normal.png"'
M0 = '"$F/data/00000.data/mask.png"'
OBJ8 = '"$F/data8/00000.data"'
PRED8 = '"$F/pred8/00000/normal.png"'
RR = '$PY -m validate.rerender --data "$F/data8/00000.data" --normals "$F/pred8/00000/normal.png" --out r'
RF = '$PY -m validate.refine --data "$F/data8/00000.data" --normals "$F/pred8/00000/normal.png" --out rf'
EV = "$PY -m unips.evaluate"
O = ["$C/o/*", "$C/o/*/*", "$C/o/*/*/*", "$C/o/*/*/*/*"]
O2 = ["$C/o2/*", "$C/o2/*/*", "$C/o2/*/*/*", "$C/o2/*/*/*/*"]

PRE = """
import glob, json, os, shutil, struct, zlib
import numpy as np, cv2
from PIL import Image
F = os.environ["F"]; C = os.environ["C"]
photos = sorted(glob.glob("p/*.jpg"))
"""


def setup_py(code: str, photos: bool = True) -> str:
    return (PH if photos else "") + py(PRE + textwrap.dedent(code))


def K(text: str) -> str:
    return f"printf -- '{text}' > K.txt\n"


SURF_K = f'{SURF} --normals {N0} --mask {M0} --intrinsics K.txt --out o'

CASES: list[dict] = []


def case(id, kind, setup, cmd, expect, names=(), may_change=(), timeout=120, why=""):
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


# ------------------------------------------------------------------ capture: photo sets
case("d38-cap-two-photos", "input", PH + "rm p/photo0[2-7].jpg", CAP, "refuse", ["--input"], O,
     why="two photos cannot determine a normal (too_few_images is fatal below 3): one line, exit non-zero")
case("d38-cap-three-photos-runs", "exit0", PH + "rm p/photo0[3-7].jpg", CAP + " && test -s o/normal.png", "either",
     [], O, why="three photos are the documented minimum: either it runs through with a warning or refuses in one line")
case("d38-cap-photos-only-in-a-subfolder", "input", "mkdir p; cp -r \"$F/photos\" p/sub", CAP, "refuse",
     ["--input"], O, why="a folder whose photos all lie one level down holds no photo: say so naming --input, do not recurse silently")
case("d38-cap-subfolder-of-other-photos-beside", "input",
     PH + "mkdir p/rejects; cp \"$F/photos/photo00.jpg\" p/rejects/x.jpg",
     CAP + " && test -s o/normal.png",
     "either", [], O, why="a sub-folder beside the photos is neither read as photos nor a traceback")
case("d38-cap-all-photos-hidden", "input", PH + "cd p; for f in *.jpg; do mv \"$f\" \".$f\"; done", CAP, "refuse",
     ["--input"], O, why="hidden files are skipped, so a folder of only hidden photos holds no photo: one line naming --input")
case("d38-cap-appledouble-and-ds-store-skipped", "input",
     PH + "head -c 4096 /dev/urandom > p/.DS_Store; head -c 300 /dev/urandom > p/._photo00.jpg",
     CAP + " && test -s o/normal.png", "ok", [], O,
     why="macOS leaves ._NAME.jpg and .DS_Store junk beside photos copied from a Mac; hidden files are skipped")
case("d38-cap-duplicate-photo", "input", PH + "cp p/photo00.jpg p/photo00_copy.jpg", CAP, "either", [], O,
     why="one photo copied among the others adds no light: accept or refuse in one line, never a traceback")
case("d38-cap-half-the-photos-duplicated", "input",
     PH + "for i in 4 5 6 7; do cp p/photo00.jpg p/photo0$i.jpg; done", CAP, "either", [], O,
     why="half the photos the same frame (a lamp that stuck) is not all the same: accept with a warning or refuse in one line")
case("d38-cap-unicode-names", "input",
     PH + "cd p; i=0; for f in *.jpg; do mv \"$f\" \"写真_é_${i}_🙂.jpg\"; i=$((i+1)); done",
     CAP + " && test -s o/normal.png && test -s o/report.html", "ok", [], O,
     why="UTF-8 names (CJK, accents, emoji) are text and must be read like any other")
case("d38-cap-names-with-leading-dash-and-spaces", "input",
     PH + "cd p; mv -- photo00.jpg '-rf photo.jpg'; mv photo01.jpg ' photo 01 .jpg'",
     CAP + " && test -s o/normal.png", "ok", [], O,
     why="names starting with a dash or holding spaces are photos like any other")
case("d38-cap-uppercase-and-jpeg-extensions", "input",
     PH + "cd p; mv photo00.jpg photo00.JPG; mv photo01.jpg photo01.JpEg; mv photo02.jpg photo02.jpeg",
     CAP + " && test -s o/normal.png", "ok", [], O, why="extensions in any case are read (JPG, JpEg, jpeg)")
case("d38-cap-half-jpeg-half-png", "input",
     setup_py("""
for p in photos[::2]:
    cv2.imwrite(p[:-4] + ".png", cv2.imread(p)); os.remove(p)
"""), CAP, "either", ["photo"], O,
     why="8-bit JPEG and 8-bit PNG are both sRGB: accept them together or refuse naming the first that differs")
case("d38-cap-one-16bit-png-among-8bit", "input",
     setup_py("""
for p in photos:
    cv2.imwrite(p[:-4] + ".png", cv2.imread(p)); os.remove(p)
im = cv2.imread("p/photo05.png").astype(np.uint16) * 257
cv2.imwrite("p/photo05.png", im)
"""), CAP, "refuse", ["photo05.png"], O,
     why="photos of mixed bit depths are refused in one line naming the first file that differs (docs/capture.md)")
case("d38-cap-one-smaller-photo", "input",
     setup_py("""
im = cv2.imread("p/photo04.jpg"); cv2.imwrite("p/photo04.jpg", im[:48])
"""), CAP, "refuse", ["photo04.jpg"], O,
     why="a photo of another size (a crop) is refused naming it")
case("d38-cap-nonsquare-one-stored-turned-and-tagged", "input",
     setup_py("""
for i, p in enumerate(photos):
    im = Image.open(p).convert("RGB").crop((0, 8, 64, 56))  # 64 x 48
    ex = Image.Exif()
    if i == 3:
        im = im.transpose(Image.Transpose.ROTATE_90)        # stored 48 x 64
        ex[0x0112] = 6                                       # displayed 64 x 48 again
    im.save(p, quality=95, exif=ex.tobytes())
m = np.array(Image.open(F + "/mask.png"))[8:56]
Image.fromarray(m).save("m.png")
"""), CAP.replace('"$F/mask.png"', "m.png"), "refuse", ["photo03.jpg"], O,
     why="a photo stored turned with an EXIF tag that turns it back still says another orientation: refused naming it")
case("d38-cap-nonsquare-one-tagged-turned", "input",
     setup_py("""
for i, p in enumerate(photos):
    im = Image.open(p).convert("RGB").crop((0, 8, 64, 56))
    ex = Image.Exif()
    if i == 6:
        ex[0x0112] = 6
    im.save(p, quality=95, exif=ex.tobytes())
m = np.array(Image.open(F + "/mask.png"))[8:56]
Image.fromarray(m).save("m.png")
"""), CAP.replace('"$F/mask.png"', "m.png"), "refuse", ["photo06.jpg"], O,
     why="one photo whose EXIF turns it to 48 x 64 among 64 x 48 ones: refused naming it, not cropped or stretched")
case("d38-cap-jpeg-named-dng-among-jpegs", "input", PH + "mv p/photo07.jpg p/photo07.dng", CAP, "refuse",
     ["photo07.dng"], O, why="a JPEG under a RAW name is not what it says (and would mix RAW with JPEG): refused naming it")
case("d38-cap-all-jpegs-named-cr2", "input",
     PH + "cd p; for f in *.jpg; do mv \"$f\" \"${f%.jpg}.CR2\"; done", CAP, "refuse", ["photo00.cr2"], O,
     why="JPEG bytes under .CR2 names: LibRaw cannot read them; one line naming the first file, no traceback")
case("d38-cap-text-named-nef", "input", "mkdir p; for i in 0 1 2 3; do echo 'not a raw file' > p/IMG_$i.NEF; done",
     CAP, "refuse", ["img_0.nef"], O, why="text under RAW names is refused naming the file LibRaw cannot read")
case("d38-cap-fake-heic-among-jpegs", "input", PH + "printf '\\0\\0\\0\\x18ftypheic' > p/photo08.heic", CAP,
     "refuse", ["photo08.heic"], O, why="HEIC is refused by name (docs: other pictures there are refused by name)")
case("d38-cap-gif-among-jpegs", "input",
     setup_py("Image.open('p/photo00.jpg').convert('P').save('p/photo08.gif')"), CAP, "refuse", ["photo08.gif"], O,
     why="a GIF among the photos is a picture the command does not read: refuse naming it rather than drop it silently")
case("d38-cap-notes-beside-photos", "input",
     PH + "echo 'lamp at 45 deg' > p/notes.txt; echo '{}' > p/settings.json",
     CAP + " && test -s o/normal.png", "either", ["notes.txt"], O,
     why="a text file beside the photos is either skipped or refused naming it; never a traceback")
case("d38-cap-near-black-photos", "input",
     setup_py("""
for p in photos:
    im = cv2.imread(p).astype(np.float32) * 0.015
    cv2.imwrite(p[:-4] + ".png", np.round(im).astype(np.uint8)); os.remove(p)
"""), CAP, "either", [], O,
     why="photos at 1.5 % exposure: too_dark warns or refuses in one line; no traceback, no division by zero")
case("d38-cap-clipped-photos", "input",
     setup_py("""
for p in photos:
    im = np.clip(cv2.imread(p).astype(np.float32) * 6, 0, 255)
    cv2.imwrite(p[:-4] + ".png", im.astype(np.uint8)); os.remove(p)
"""), CAP + " && grep -q saturated o/report.json", "either", [], O,
     why="photos clipped over most of the object: the saturated warning is recorded (or a one-line refusal)")
case("d38-cap-input-a-symlink-to-fixtures", "input", 'ln -s "$F/photos" p',
     '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --no-refine --threads 1 --keep-work && test -s o/normal.png',
     "ok", [], O, why="a linked input folder is read, nothing is written into it (the fixtures stay the same)")
case("d38-cap-photos-linked-one-by-one", "input",
     'mkdir p; for f in "$F"/photos/*.jpg; do ln -s "$f" p/; done', CAP + " && test -s o/normal.png", "ok", [], O,
     why="photos that are links to readable files are photos")
case("d38-cap-input-a-file", "message", "", '$PY -m orchestrate.capture --input "$F/photos/photo00.jpg" --out o --no-refine',
     "refuse", ["--input", "photo00.jpg"], O, why="--input is a folder: a single file is refused naming the flag and the file")
case("d38-cap-input-empty-folder", "message", "", '$PY -m orchestrate.capture --input "$F/empty" --out o --no-refine',
     "refuse", ["--input"], O, why="an empty folder holds no photo: one line naming --input")

# ------------------------------------------------------------------ capture: flags
case("d38-cap-max-side-31", "message", PH, CAP + " --max-side 31", "refuse", ["--max-side", "31"], O,
     why="--max-side is 0 or at least 32 (docs): 31 is refused naming the flag and the value")
case("d38-cap-max-side-32-full-size-outputs", "exit0", PH,
     CAP + " --max-side 32 && $PY -c \"import cv2,sys; a=cv2.imread('o/normal.png',-1).shape; b=cv2.imread('o/mask.png',-1).shape; "
     "c=cv2.imread('o/normal_model.png',-1).shape; print(a,b,c); sys.exit(0 if a[:2]==(64,64) and b[:2]==(64,64) and c[:2]==(32,32) else 1)\"",
     "ok", [], O, why="normal.png and mask.png at the photos' size, normal_model.png at the working size (docs 'Outputs')")
case("d38-cap-max-side-beyond-int64", "message", PH, CAP + " --max-side 99999999999999999999999", "either",
     ["--max-side"], O, why="a huge --max-side means the photos' own size or a one-line refusal; never an overflow traceback")
case("d38-cap-input-encoding-uppercase", "message", PH, CAP + " --input-encoding SRGB", "refuse",
     ["--input-encoding"], O, why="choices are auto/srgb/linear: one line naming the flag")
case("d38-cap-linear-encoding-recorded", "exit0", PH,
     CAP + " --input-encoding linear && grep -qi linear o/report.json", "ok", [], O,
     why="--input-encoding linear on JPEGs is accepted and the report says the photos were read linear")
case("d38-cap-opencv-flips-y-and-z", "exit0", PH,
     CAP + " && $PY -m orchestrate.capture --input p --out o2 --mask \"$F/mask.png\" --no-refine --threads 1 --convention opencv && "
     + "$PY -c \"\nimport cv2,numpy as np,sys\na=cv2.imread('o/normal.png',-1).astype(float);b=cv2.imread('o2/normal.png',-1).astype(float)\n"
     "m=cv2.imread('o/mask.png',-1)>0\nd=[np.abs(a[...,2]-b[...,2])[m].max(),np.abs(a[...,1]+b[...,1]-65535)[m].max(),np.abs(a[...,0]+b[...,0]-65535)[m].max()]\n"
     "print(d); sys.exit(0 if max(d)<4 else 1)\"",
     "ok", [], O + O2, timeout=240,
     why="--convention opencv writes (x, -y, -z) of the opengl map: anything else is an exit 0 with a wrong frame")
case("d38-cap-threads-1-byte-identical", "exit0", PH,
     CAP + " && $PY -m orchestrate.capture --input p --out o2 --mask \"$F/mask.png\" --no-refine --threads 1 && cmp o/normal.png o2/normal.png && cmp o/mask.png o2/mask.png",
     "ok", [], O + O2, timeout=240, why="--threads 1 promises byte-identical runs")
case("d38-cap-threads-0", "message", PH, CAP.replace("--threads 1", "--threads 0"), "refuse", ["--threads"], O,
     why="zero Dr.Jit threads is no value: one line naming --threads")
case("d38-cap-threads-negative", "message", PH, CAP.replace("--threads 1", "--threads -2"), "refuse", ["--threads"], O,
     why="a negative thread count is refused naming --threads")
case("d38-cap-rotation-steps-0", "message", PH,
     '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --threads 1 --rotation-search --rotation-steps 0',
     "refuse", ["--rotation-steps"], O, why="no steps of the light fit at each tilt: refused naming the flag before any photo is read")
case("d38-cap-mask-missing-file", "message", PH, '$PY -m orchestrate.capture --input p --out o --mask nosuch_mask.png --no-refine',
     "refuse", ["--mask", "nosuch_mask.png"], O, why="a mask file that does not exist is refused naming --mask and the path")
case("d38-cap-mask-dot-slash-auto-missing", "message", PH, '$PY -m orchestrate.capture --input p --out o --mask ./auto --no-refine',
     "refuse", ["--mask", "auto"], O, why="./auto is a file name, not the keyword: missing, refused naming it")
case("d38-cap-mask-larger-than-photos", "input",
     setup_py("cv2.imwrite('m.png', cv2.resize(cv2.imread(F + '/mask.png', -1), (128, 128), interpolation=cv2.INTER_NEAREST))"),
     CAP.replace('"$F/mask.png"', "m.png"), "refuse", ["--mask", "m.png"], O,
     why="a mask twice the photos' size (nor the working size) is refused naming it")
case("d38-cap-mask-none-keyword-writes-full-mask", "exit0", PH,
     CAP_NOMASK + " --mask none && $PY -c \"import cv2,sys; m=cv2.imread('o/mask.png',-1); sys.exit(0 if (m>0).all() else 1)\"",
     "either", [], O, why="--mask none: the whole frame is the scene; mask.png must then be all object")
case("d38-cap-checkpoint-empty-file", "weights", PH + ": > w.safetensors",
     CAP + " --checkpoint w.safetensors", "refuse", ["--checkpoint", "w.safetensors"], O,
     why="an empty weights file is refused in one line naming the flag and the file, before any photo is read")
case("d38-cap-checkpoint-text-named-safetensors", "weights", PH + "echo 'version https://git-lfs.github.com/spec/v1' > w.safetensors",
     CAP + " --checkpoint w.safetensors", "refuse", ["--checkpoint", "w.safetensors"], O,
     why="a Git LFS pointer under a weights name (a clone without LFS) is refused naming the file")
case("d38-cap-checkpoint-empty-folder-without-model", "weights", PH + "mkdir wdir",
     CAP + " --checkpoint wdir", "refuse", ["--checkpoint"], O,
     why="a folder of published weights needs --model and must hold them: one line naming --checkpoint")
case("d38-cap-checkpoint-a-training-run-pt", "weights", PH, CAP + ' --checkpoint "$F/run/last.pt"', "either",
     ["--checkpoint"], O, why="a training run's last.pt is either read as a model or refused naming --checkpoint; no traceback")
case("d38-cap-checkpoint-glc-test-model", "weights", PH, CAP + ' --checkpoint "$F/run/final.safetensors"', "either",
     [], O, why="another trained model file is used (or refused in one line); never a traceback")
case("d38-cap-model-unknown-name", "weights", PH, CAP + " --model no-such-net", "refuse", ["--model", "no-such-net"], O,
     why="an unregistered --model is refused naming it, before any photo is read")
case("d38-cap-keep-work-then-capture-the-work-folder", "exit0", PH,
     CAP + " --keep-work && $PY -m orchestrate.capture --input o/work/p.data --out o2 --no-refine --threads 1 && test -s o2/normal.png",
     "either", [], O + O2, timeout=240,
     why="--keep-work writes an object folder other commands read: capture reads it back (or refuses in one line)")
case("d38-cap-overwrite-keeps-a-users-file-in-work", "writer", PH,
     CAP + " --keep-work && echo mine > o/work/notes.txt && " + CAP + " --overwrite && test -f o/work/notes.txt",
     "ok", [], O, timeout=240,
     why="--overwrite replaces only the command's own files: a user's note in work/ stays")
case("d38-cap-rerun-with-keep-work-needs-overwrite", "writer", PH,
     CAP + " && " + CAP + " --keep-work", "refuse", ["--overwrite"], O, timeout=240,
     why="a second run into an earlier capture's --out is refused naming --overwrite, with or without --keep-work")
case("d38-cap-out-is-a-file", "message", PH + "echo keep > o", CAP, "refuse", ["--out"], [],
     why="--out is a folder: an existing file is refused naming the flag and kept")
case("d38-cap-out-equals-input", "writer", PH, '$PY -m orchestrate.capture --input p --out p/ --mask "$F/mask.png" --no-refine',
     "refuse", ["--out"], [], why="--out equal to --input (spelled with a slash) is refused: it would mix outputs with photos")
case("d38-cap-out-is-the-mask-file", "writer", PH + 'cp "$F/mask.png" m.png',
     '$PY -m orchestrate.capture --input p --out m.png --mask m.png --no-refine', "refuse", ["--out"], [],
     why="--out naming the mask file is refused, the mask kept")

# ------------------------------------------------------------------ surface
case("d38-surf-focal-px-zero", "message", "", f"{SURF} --normals {N0} --mask {M0} --focal-px 0 --out o", "refuse",
     ["--focal-px"], O, why="a focal length of 0 px is no camera: one line naming --focal-px")
case("d38-surf-focal-px-inf", "message", "", f"{SURF} --normals {N0} --mask {M0} --focal-px inf --out o", "refuse",
     ["--focal-px"], O, why="an infinite focal length is refused (orthographic is: no --focal-px)")
case("d38-surf-k-inf", "message", "", f"{SURF} --normals {N0} --mask {M0} --k inf --out o", "refuse", ["--k"], O,
     why="infinite sharpness gives NaN weights: refused naming --k")
case("d38-surf-k-zero-ok", "exit0", "", f"{SURF} --normals {N0} --mask {M0} --k 0 --out o && test -s o/depth.npy", "ok",
     [], O, why="--k 0 is documented (one smooth surface)")
case("d38-surf-intrinsics-with-skew", "input", K("40 3 15.5\\n0 40 15.5\\n0 0 1\\n"), SURF_K, "refuse",
     ["--intrinsics", "K.txt"], O, why="a skew term the integration ignores would give a wrong surface with exit 0: refuse naming the file")
case("d38-surf-intrinsics-bottom-row-wrong", "input", K("40 0 15.5\\n0 40 15.5\\n0 0 2\\n"), SURF_K, "refuse",
     ["--intrinsics", "K.txt"], O, why="a matrix whose last row is not 0 0 1 is not the documented form: refused naming it")
case("d38-surf-intrinsics-negative-focal", "input", K("-40 0 15.5\\n0 40 15.5\\n0 0 1\\n"), SURF_K, "refuse",
     ["--intrinsics", "K.txt"], O, why="a negative fx mirrors the camera: refused naming the file")
case("d38-surf-intrinsics-4x4", "input", K("40 0 15.5 0\\n0 40 15.5 0\\n0 0 1 0\\n0 0 0 1\\n"), SURF_K, "refuse",
     ["--intrinsics", "K.txt"], O, why="a 4 x 4 matrix is not the 3 x 3 one: refused naming the file")
case("d38-surf-intrinsics-empty-file", "input", ": > K.txt", SURF_K, "refuse", ["--intrinsics", "K.txt"], O,
     why="an empty intrinsics file is refused naming it, no numpy warning or traceback")
case("d38-surf-intrinsics-anisotropic-ok", "exit0", K("40 0 15.5\\n0 44 15.5\\n0 0 1\\n"),
     SURF_K + " && test -s o/mesh.ply", "either", ["--intrinsics"], O,
     why="fx != fy is a valid camera: used (or refused naming the flag), never a traceback")
case("d38-surf-intrinsics-and-focal-px-agree", "message", K("40 0 15.5\\n0 40 15.5\\n0 0 1\\n"),
     SURF_K + " --focal-px 40", "refuse", ["--focal-px", "--intrinsics"], O,
     why="two camera descriptions at once are refused naming both flags, even when they agree")
case("d38-surf-mask-jpeg", "input", setup_py("cv2.imwrite('m.jpg', cv2.imread(F + '/data/00000.data/mask.png', -1))", False),
     f"{SURF} --normals {N0} --mask m.jpg --out o", "refuse", ["--mask", "m.jpg"], O,
     why="a JPEG mask is not binary at its edges: refused as capture does, naming the file")
case("d38-surf-mask-16bit-binary-ok", "exit0",
     setup_py("m = cv2.imread(F + '/data/00000.data/mask.png', -1); cv2.imwrite('m.png', (m > 0).astype(np.uint16) * 65535)", False),
     f"{SURF} --normals {N0} --mask m.png --out o && test -s o/depth.npy", "ok", [], O,
     why="a 16-bit binary mask (0 and 65535) is binary")
case("d38-surf-mask-one-pixel", "input",
     setup_py("m = np.zeros((32, 32), np.uint8); m[16, 16] = 255; cv2.imwrite('m.png', m)", False),
     f"{SURF} --normals {N0} --mask m.png --out o", "either", ["--mask"], O,
     why="a one-pixel object: a one-pixel surface or a one-line refusal; no empty-mesh traceback")
case("d38-surf-normals-npy-uint16-codes", "input",
     setup_py("np.save('n.npy', cv2.imread(F + '/pred/00000/normal.png', -1)[..., ::-1].copy())", False),
     f"{SURF} --normals n.npy --mask {M0} --out o", "refuse", ["--normals", "n.npy"], O,
     why="a .npy of 16-bit PNG codes is not unit normals: refused naming the file, not integrated as huge vectors")
case("d38-surf-normals-mat-unknown-variable", "input",
     setup_py("import scipy.io; scipy.io.savemat('n.mat', {'foo': np.zeros((32, 32, 3))})", False),
     f"{SURF} --normals n.mat --out o", "refuse", ["--normals", "n.mat"], O,
     why="a .mat without a normal-map variable is refused naming it")
case("d38-surf-normals-8bit-png-ok", "exit0",
     setup_py("cv2.imwrite('n.png', (cv2.imread(F + '/pred/00000/normal.png', -1) // 257).astype(np.uint8))", False),
     f"{SURF} --normals n.png --mask {M0} --out o && test -s o/depth.npy", "ok", [], O,
     why="8-bit (n + 1) / 2 maps are documented input")
case("d38-surf-mesh-obj-glb-written", "exit0", "",
     f"{SURF} --normals {N0} --mask {M0} --mesh obj,glb --out o && test -s o/mesh.obj && test -s o/mesh.glb", "ok", [], O,
     why="each asked mesh format is written")
case("d38-surf-mesh-duplicate-format", "message", "", f"{SURF} --normals {N0} --mask {M0} --mesh ply,ply --out o",
     "either", ["--mesh"], O, why="a repeated format is written once or refused naming --mesh; never a traceback")
case("d38-surf-out-is-the-normals-file", "writer", f"cp {N0} n.png", f"{SURF} --normals n.png --out n.png", "refuse",
     ["--out"], [], why="--out naming the normal map is refused and the map kept")
case("d38-surf-capture-outputs-compose", "exit0", PH,
     CAP + f" && {SURF} --normals o/normal.exr --mask o/mask.png --out s --focal-px 60 && test -s s/mesh.ply", "ok", [],
     O + ["$C/s/*"], timeout=240, why="capture's normal.exr and mask.png are valid surface inputs")

# ------------------------------------------------------------------ rerender / refine
case("d38-rr-spp-negative", "message", "", RR + " --spp -1", "refuse", ["--spp"], ["$C/r/*"],
     why="negative samples per pixel: one line naming --spp")
case("d38-rr-threshold-nan", "message", "", RR + " --threshold nan --spp 1 --no-floors", "refuse", ["--threshold"], ["$C/r/*"],
     why="a NaN threshold counts nothing above it: refused naming --threshold")
case("d38-rr-figure-rows-negative", "message", "", RR + " --figure-rows -1 --spp 1 --no-floors", "refuse", ["--figure-rows"], ["$C/r/*"],
     why="negative figure rows are refused naming the flag")
case("d38-rr-supersample-0", "message", "", RR + " --supersample 0 --spp 1 --no-floors", "refuse", ["--supersample"], ["$C/r/*"],
     why="zero ray casts per pixel side decide no visibility: refused naming --supersample")
case("d38-rr-data-unicode-copy", "input", 'cp -r "$F/data8/00000.data" "ob jé_🙂.data"',
     f'$PY -m validate.rerender --data "ob jé_🙂.data" --normals {PRED8} --out r --spp 1 --no-floors --threshold 0.1',
     "ok", [], ["$C/r/*", "$C/r/*/*"], why="an object folder with spaces and unicode in its name is read like any other")
case("d38-rr-dataset-with-a-junk-folder", "input", 'cp -r "$F/data8" d; mkdir d/notes; echo x > d/notes/a.txt',
     '$PY -m validate.rerender --data d --normals "$F/pred8" --out r --spp 1 --no-floors --threshold 0.1', "either",
     ["notes"], ["$C/r/*", "$C/r/*/*"], why="a stray folder in a dataset is skipped or named; never a traceback")
case("d38-rf-patience-negative", "message", "", RF + " --patience -1 --refine-steps 5 --threads 1", "refuse", ["--patience"], ["$C/rf/*"],
     why="negative patience is refused naming the flag")
case("d38-rf-smoothness-negative", "message", "", RF + " --smoothness -1 --refine-steps 5 --threads 1", "refuse", ["--smoothness"], ["$C/rf/*"],
     why="a negative smoothness weight rewards roughness: refused naming the flag")
case("d38-rf-integrability-nan", "message", "", RF + " --integrability nan --refine-steps 5 --threads 1", "refuse", ["--integrability"], ["$C/rf/*"],
     why="a NaN weight poisons every step: refused naming the flag before any render")
case("d38-rf-silhouette-inf", "message", "", RF + " --silhouette inf --refine-steps 5 --threads 1", "refuse", ["--silhouette"], ["$C/rf/*"],
     why="an infinite weight is refused naming the flag")
case("d38-rf-rotation-steps-0-with-search", "message", "", RF + " --rotation-search --rotation-steps 0 --refine-steps 5 --threads 1", "refuse",
     ["--rotation-steps"], ["$C/rf/*"], why="no light-fit steps at each tilt: refused naming the flag")
case("d38-rf-refine-steps-0", "message", "", RF + " --refine-steps 0 --threads 1", "either", ["--refine-steps"],
     ["$C/rf/*", "$C/rf/*/*"], why="zero steps: the start map back unchanged or a refusal naming the flag; no traceback")
case("d38-rf-diligent-with-a-map-of-other-size", "input", "",
     '$PY -m validate.refine --data "$F/ballPNG" --normals "$F/pred/00000/normal.png" --out rf --lights calibrated --threads 1',
     "refuse", ["--normals"], ["$C/rf/*", "$C/rf/*/*"],
     why="a 32 px map for the DiLiGenT ball is refused naming --normals, before any fit")
case("d38-rf-data-with-ds-store", "input", 'cp -r "$F/data8/00000.data" d.data; head -c 1000 /dev/urandom > d.data/.DS_Store',
     f'$PY -m validate.refine --data d.data --normals {PRED8} --out rf --refine-steps 5 --rounds 1 --threads 1', "ok", [],
     ["$C/rf/*", "$C/rf/*/*"], why="a hidden junk file in an object folder is skipped")

# ------------------------------------------------------------------ evaluate
case("d38-ev-pred-8bit-png", "exit0",
     setup_py("""
os.makedirs('p/00000')
cv2.imwrite('p/00000/normal.png', (cv2.imread(F + '/pred/00000/normal.png', -1) // 257).astype(np.uint8))
""", False), f'{EV} --pred p --gt "$F/data/00000.data" && test -s p/metrics.json', "ok", [],
     ["$C/p/*", "$C/p/*/*"], why="an 8-bit prediction map is scored")
case("d38-ev-gt-diligent-pred-other-size", "input", 'mkdir -p p/ballPNG; cp "$F/pred/00000/normal.png" p/ballPNG/',
     f'{EV} --pred p --gt "$F/ballPNG"', "refuse", ["normal.png"], ["$C/p/*", "$C/p/*/*"],
     why="a 32 px prediction for the DiLiGenT ball is refused naming the file")
case("d38-ev-pred-object-folder-with-data-suffix", "input", 'mkdir -p p; cp -r "$F/pred/00000" p/00000.data',
     f'{EV} --pred p --gt "$F/data"', "refuse", [], ["$C/p/*", "$C/p/*/*"],
     why="predictions under .data names match no object: missing predictions are refused (no --allow-missing), naming --pred")
case("d38-ev-pred-is-the-gt-parent", "writer", 'cp -r "$F/data" d; cp -r "$F/pred" d/pred',
     f'{EV} --pred d/pred --gt d', "either", [], ["$C/d/pred/*", "$C/d/pred/*/*"],
     why="predictions inside the truth's folder: scored or refused, the truth's files untouched")

# ------------------------------------------------------------------ concurrency and links
case("d38-cap-two-readers-of-one-input", "writer", PH,
     '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --no-refine --threads 1 & a=$!; '
     '$PY -m orchestrate.capture --input p --out o2 --mask "$F/mask.png" --no-refine --threads 1 & b=$!; '
     'wait $a; ra=$?; wait $b; rb=$?; echo "$ra $rb"; [ $ra = 0 ] && [ $rb = 0 ] && test -s o/normal.png && test -s o2/normal.png',
     "ok", [], O + O2, timeout=240,
     why="two captures reading one photo folder into two outs both run: the lock is on the output, not the input")
case("d38-cap-out-inside-a-linked-input", "writer", 'ln -s "$F/photos" p',
     '$PY -m orchestrate.capture --input p --out p/o --mask "$F/mask.png" --no-refine --threads 1', "refuse",
     ["--out"], [], why="--out inside --input reached through a link is still inside it: refused, nothing written into the linked folder")
case("d38-surf-mask-is-the-normal-map", "input", "", f"{SURF} --normals {N0} --mask {N0} --out o", "refuse",
     ["--mask", "normal.png"], O, why="the normal map given as its own mask is not binary: refused naming --mask and the file")
case("d38-surf-two-outs-one-map-concurrently", "writer", f"cp {N0} n.png",
     f'{SURF} --normals n.png --mask {M0} --out o & a=$!; {SURF} --normals n.png --mask {M0} --out o2 & b=$!; '
     'wait $a; ra=$?; wait $b; rb=$?; [ $ra = 0 ] && [ $rb = 0 ] && cmp o/depth.npy o2/depth.npy',
     "ok", [], O + O2, why="two surfaces of one map into two folders both succeed with the same depth")
