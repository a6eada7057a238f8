"""Sweep 37, part a: the CAPTURE and SURFACE side (orchestrate.capture, orchestrate.surface, validate.rerender /
validate.refine in fitted mode and on damaged object folders, unips.evaluate on odd predictions).

Mechanisms aimed at: one writer per folder (a run must not write into a SUBFOLDER another run holds, nor read an
object folder another run is still writing), inputs are what they say (photos, masks, EXIF, PNG chunks, ICC
profiles, .npy pickles, fifos and devices under photo names), messages that name the right flag and file, and
nothing lost (hard links between inputs and outputs, interrupts, read-only mounts).

Run with scripts/sweep/run_sweep.py (see its docstring). Every case uses the 32/64-px fixtures of fixtures.sh; a
full capture of $F/photos takes about 13 s on 2 cores.
"""
from __future__ import annotations

import textwrap


def py(code: str) -> str:
    """A bash heredoc running `code` with the toolkit's python in $C."""
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


PH = 'cp -r "$F/photos" p\n'
"""A copy of the 8 fixture photos (64 px JPEG) as $C/p."""
CAPTURE = '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --no-refine --threads 1'
CAPTURE_ABS = '$PY -m orchestrate.capture --input "$C/p" --out "$C/o" --mask "$F/mask.png" --no-refine --threads 1'
"""CAPTURE with absolute paths: its processes show $C (the harness's leftover check, pgrep)."""
SURF = "$PY -m orchestrate.surface"
N0 = '"$F/pred/00000/normal.png"'
M0 = '"$F/data/00000.data/mask.png"'
OBJ8 = '"$F/data8/00000.data"'
PRED8 = '"$F/pred8/00000/normal.png"'
RR_FIT = "--fit --steps 10 --threads 1"
RF_FAST = "--steps 10 --threads 1"

PRE = """
import glob, json, os, shutil, struct, zlib
import numpy as np, cv2
from PIL import Image
F = os.environ["F"]; C = os.environ["C"]
photos = sorted(glob.glob("p/*.jpg"))
"""

FAKE_CAPTURE = py(PRE + """
os.makedirs("o/surface", exist_ok=True)
json.dump({"complete": True, "input": {}, "verdict": None, "timings": {}}, open("o/report.json", "w"))
""")
"""An earlier capture's --out (its signed report.json) without its files."""


def hold(folder: str, seconds: int = 90) -> str:
    """bash: another run holds `folder` (the lock every command takes on its --out) until `kill $h`."""
    return (f"mkdir -p {folder}\n"
            f"$PY -c 'import time; from scenes.files import folder_lock; fd = folder_lock(\"{folder}\"); "
            f"open(\"held.flag\", \"w\").close(); time.sleep({seconds})' & h=$!\n"
            "for i in $(seq 200); do [ -e held.flag ] && break; sleep 0.1; done\n")


def released(cmd: str) -> str:
    return f"{cmd}; rc=$?; kill $h 2>/dev/null; wait $h 2>/dev/null; exit $rc"


def exif_photos(code: str) -> str:
    """Setup: the fixture photos re-saved by PIL as JPEG with the EXIF `code` builds per photo (`exif_for(i, ex)`)."""
    return PH + py(PRE + textwrap.dedent(code) + """
for i, p in enumerate(photos):
    im = Image.open(p); im.load()
    ex = Image.Exif()
    exif_for(i, ex)
    im.save(p, quality=95, exif=ex.tobytes())
""")


def png_photos(extra: str = "") -> str:
    """Setup: the fixture photos as 8-bit PNG (the JPEGs removed), then `extra`."""
    return PH + py(PRE + """
for p in photos:
    cv2.imwrite(p[:-4] + ".png", cv2.imread(p)); os.remove(p)
pngs = sorted(glob.glob("p/*.png"))
""" + textwrap.dedent(extra))


PNG_CHUNK = """
def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)
def add_chunk(path, kind, data):  # after IHDR
    b = open(path, "rb").read()
    open(path, "wb").write(b[:33] + png_chunk(kind, data) + b[33:])
"""

CASES: list[dict] = []


def case(id: str, kind: str, setup: str, cmd: str, expect: str = "refuse", names=(), may_change=(), timeout=120,
         why: str = "") -> None:
    CASES.append({"id": "a37-" + id, "kind": kind, "setup": setup, "cmd": cmd, "expect": expect,
                  "names": list(names), "may_change": list(may_change), "timeout": timeout, "why": why})


O = ["$C/o/*", "$C/o"]

# ============================================================================ capture: photo files

case("cap-png-crc-broken", "input", png_photos("""
b = bytearray(open(pngs[3], "rb").read()); i = b.find(b"IDAT") + 10; b[i] ^= 0xff
open(pngs[3], "wb").write(bytes(b))
"""), CAPTURE, names=["--input", "photo03.png"], may_change=O,
     why="a PNG whose IDAT fails its CRC is damage libpng refuses: one line naming the file, never a grey hole")
case("cap-png-cut-mid-idat", "input", png_photos("""
b = open(pngs[5], "rb").read(); open(pngs[5], "wb").write(b[: len(b) * 2 // 3])
"""), CAPTURE, names=["--input", "photo05.png"], may_change=O,
     why="a PNG cut short (a copy that stopped) is read whole or refused naming it")
case("cap-png16-cut-mid-idat", "input", PH + py(PRE + """
for p in photos:
    im = cv2.imread(p).astype(np.uint16) * 257; cv2.imwrite(p[:-4] + ".png", im); os.remove(p)
pngs = sorted(glob.glob("p/*.png"))
b = open(pngs[2], "rb").read(); open(pngs[2], "wb").write(b[: len(b) // 2])
"""), CAPTURE, names=["--input", "photo02.png"], may_change=O,
     why="a 16-bit (linear) PNG cut short is refused naming it, like an 8-bit one")
case("cap-png-without-iend", "input", png_photos("""
b = open(pngs[1], "rb").read(); open(pngs[1], "wb").write(b[:-12])
"""), CAPTURE, expect="either", names=["photo01.png"], may_change=O,
     why="a PNG missing only its IEND chunk holds every row; accepted or refused naming it, never a traceback")
case("cap-tiff-uncompressed-cut", "input", PH + py(PRE + """
for p in photos:
    Image.open(p).save(p[:-4] + ".tif", compression=None); os.remove(p)
t = sorted(glob.glob("p/*.tif"))[4]
b = open(t, "rb").read(); open(t, "wb").write(b[: len(b) // 2])
"""), CAPTURE, names=["--input", "photo04.tif"], may_change=O,
     why="an uncompressed TIFF whose strips break off (no codec to complain) must still be refused naming it")
case("cap-tiff-float32-photos", "input", PH + py(PRE + """
for p in photos:
    a = cv2.imread(p).astype(np.float32) / 255; cv2.imwrite(p[:-4] + ".tif", a); os.remove(p)
"""), CAPTURE, expect="either", names=["photo00.tif"], may_change=O,
     why="float32 TIFF photos are read as linear or refused naming the file and what was expected, never a traceback")
case("cap-exr-one-nan", "input", PH + py(PRE + """
from scenes.exr import write_exr
for i, p in enumerate(photos):
    a = (cv2.imread(p)[..., ::-1].astype(np.float32) / 255) ** 2.2
    if i == 6: a[10, 10, 1] = np.nan
    write_exr(p[:-4] + ".exr", a); os.remove(p)
"""), CAPTURE, names=["--input", "photo06.exr", "NaN"], may_change=O,
     why="one NaN pixel in a float photo is refused naming the file before any model runs")
case("cap-exr-cut-short", "input", PH + py(PRE + """
from scenes.exr import write_exr
for i, p in enumerate(photos):
    write_exr(p[:-4] + ".exr", (cv2.imread(p)[..., ::-1].astype(np.float32) / 255) ** 2.2); os.remove(p)
e = sorted(glob.glob("p/*.exr"))[7]
b = open(e, "rb").read(); open(e, "wb").write(b[: len(b) // 2])
"""), CAPTURE, names=["--input", "photo07.exr"], may_change=O,
     why="an EXR cut in half is refused naming it (OpenEXR may fill missing lines with zeros)")
case("cap-exr-two-channels", "input", PH + py(PRE + """
import OpenEXR, Imath
for i, p in enumerate(photos):
    a = (cv2.imread(p, cv2.IMREAD_GRAYSCALE).astype(np.float32) / 255) ** 2.2
    h, w = a.shape
    hdr = OpenEXR.Header(w, h)
    hdr["channels"] = {"Y": Imath.Channel(Imath.PixelType(Imath.PixelType.FLOAT)),
                       "A": Imath.Channel(Imath.PixelType(Imath.PixelType.FLOAT))}
    o = OpenEXR.OutputFile(p[:-4] + ".exr", hdr)
    o.writePixels({"Y": a.tobytes(), "A": np.ones_like(a).tobytes()}); o.close(); os.remove(p)
"""), CAPTURE, expect="either", names=["photo00.exr"], may_change=O,
     why="a grey EXR with an alpha channel (Y, A) is read as grey or refused naming the file and its channels")
case("cap-bmp-named-jpg", "input", PH + py(PRE + """
cv2.imwrite("x.bmp", cv2.imread(photos[2])); os.replace("x.bmp", photos[2])
"""), CAPTURE, names=["--input", "photo02.jpg"], may_change=O,
     why="a BMP under a .jpg name is not what its name says: refused naming the file (its EXIF is read by the name)")
case("cap-tiff-named-jpg", "input", PH + py(PRE + """
Image.open(photos[1]).save("x.tif"); os.replace("x.tif", photos[1])
"""), CAPTURE, names=["--input", "photo01.jpg"], may_change=O,
     why="TIFF bytes under a .jpg name are refused naming the file and both kinds")
case("cap-jpeg-zero-bytes", "input", PH + ": > p/photo08.jpg\n", CAPTURE, names=["--input", "photo08.jpg"], may_change=O,
     why="an empty photo file (a failed copy) is refused naming it, not skipped")
case("cap-jpeg-progressive-cut", "input", PH + py(PRE + """
for p in photos:
    Image.open(p).save(p, quality=95, progressive=True)
b = open(photos[3], "rb").read(); open(photos[3], "wb").write(b[: int(len(b) * 0.6)])
"""), CAPTURE, names=["--input", "photo03.jpg"], may_change=O,
     why="a progressive JPEG cut after its first scans decodes to a whole blurry frame: still refused as truncated")
case("cap-jpeg-cmyk-among-rgb", "input", PH + py(PRE + """
Image.open(photos[4]).convert("CMYK").save(photos[4], quality=95)
"""), CAPTURE, expect="either", names=["photo04.jpg"], may_change=O,
     why="a CMYK JPEG among RGB ones is not the same camera setting: accepted only if read to the same values, "
         "else refused naming it")
case("cap-photo-fifo", "input", PH + "mkfifo p/photo08.jpg\n", CAPTURE, names=["--input", "photo08.jpg"],
     may_change=O, timeout=60,
     why="a pipe under a photo name is refused at once naming it (never opened: it would block for ever)")
case("cap-photo-link-to-dev-zero", "input", PH + "ln -s /dev/zero p/photo08.jpg\n", CAPTURE,
     names=["--input", "photo08.jpg"], may_change=O, timeout=60,
     why="a link to a device under a photo name is refused naming it, not read without end")
case("cap-photo-a-folder", "input", PH + "mkdir p/photo08.jpg\n", CAPTURE, names=["--input", "photo08.jpg"],
     may_change=O, why="a folder named like a photo is refused naming it rather than silently dropped")
case("cap-photo-name-with-newline", "input", PH + "mv p/photo03.jpg \"p/photo03\n.jpg\"\n", CAPTURE,
     expect="either", names=["--input"], may_change=O,
     why="a photo name holding a newline either works (names escaped in report.json/html) or is refused naming "
         "--input; never a traceback or a broken one-line message")
case("cap-photo-name-html-is-escaped", "input", PH + "mv p/photo02.jpg 'p/<script>alert(1)<'\"'\"'script>.jpg'\n",
     CAPTURE + " && ! grep -q '<script>alert' o/report.html", expect="either", names=["--input"], may_change=O,
     why="a photo named like HTML must be escaped in report.html (or the name refused), never injected into the page")

# ============================================================================ capture: EXIF and PNG chunks

case("cap-exif-fnumber-zero-is-unknown", "input", exif_photos("""
def exif_for(i, ex):
    e = ex.get_ifd(0x8769)
    e[0x829A] = 0.01; e[0x8827] = 100; e[0x829D] = 0.0 if i == 5 else 4.0
"""), CAPTURE, expect="either", names=["--input", "photo05.jpg"], may_change=O,
     why="FNumber 0 is what cameras write for a manual lens (unknown): read as no f-number (normalised by time and "
         "ISO) or refused naming the file; never an infinite exposure scale")
case("cap-exif-fnumber-only-ratio-too-far", "input", exif_photos("""
def exif_for(i, ex):
    e = ex.get_ifd(0x8769)
    e[0x829A] = 0.01; e[0x8827] = 100; e[0x829D] = 64.0 if i == 6 else 1.0
"""), CAPTURE, names=["--input", "photo06.jpg"], may_change=O,
     why="same time and ISO but f/1 against f/64 is 4096 times the light, beyond 10 stops: refused naming the photos")
case("cap-exif-apex-aperture-huge", "input", exif_photos("""
def exif_for(i, ex):
    e = ex.get_ifd(0x8769)
    e[0x9201] = 6.64; e[0x8827] = 100; e[0x9202] = 40.0 if i == 2 else 4.0
"""), CAPTURE, names=["--input", "photo02.jpg"], may_change=O,
     why="an APEX ApertureValue of 40 (f/2^20) is a wrong field: refused naming the photo, not a 10^12 rescale")
case("cap-exif-colour-space-uncalibrated", "input", exif_photos("""
def exif_for(i, ex):
    if i == 3: ex.get_ifd(0x8769)[0xA001] = 0xFFFF
"""), CAPTURE, names=["--input", "photo03.jpg", "--input-encoding"], may_change=O,
     why="an 8-bit photo whose EXIF colour space is Uncalibrated (Adobe RGB cameras) is refused naming it and the flag")
case("cap-exif-colour-space-uncalibrated-with-srgb-given", "input", exif_photos("""
def exif_for(i, ex):
    ex.get_ifd(0x8769)[0xA001] = 0xFFFF
"""), CAPTURE + " --input-encoding srgb", expect="ok", may_change=O,
     why="the refusal's remedy (--input-encoding srgb) must work: the capture then runs")
case("cap-exif-orientation-9-everywhere", "input", exif_photos("""
def exif_for(i, ex):
    ex[0x0112] = 9
"""), CAPTURE, expect="either", names=["--input"], may_change=O,
     why="an orientation outside 1..8 on every photo is taken as upright or refused naming the value; no traceback")
case("cap-exif-orientation-0-on-one", "input", exif_photos("""
def exif_for(i, ex):
    if i == 4: ex[0x0112] = 0
"""), CAPTURE, expect="either", names=["--input", "photo04.jpg"], may_change=O,
     why="an orientation of 0 (no such value) on one photo is read as upright like the others or refused naming "
         "that photo; no traceback")
case("cap-exif-rotated-nonsquare-mask-unrotated", "input", PH + py(PRE + """
for p in photos:
    im = Image.open(p).crop((0, 8, 64, 56)); ex = Image.Exif(); ex[0x0112] = 6
    im.save(p, quality=95, exif=ex.tobytes())
m = cv2.imread(F + "/mask.png", cv2.IMREAD_GRAYSCALE)[8:56]
cv2.imwrite("m.png", m)
"""), CAPTURE.replace('"$F/mask.png"', "m.png"), names=["--mask", "m.png"], may_change=O,
     why="photos 64x48 whose EXIF says 'turn 90 deg' are 48x64 as shown: a mask 64x48 (the stored layout) is refused "
         "naming --mask and both sizes")
case("cap-exif-rotated-nonsquare-mask-rotated", "input", PH + py(PRE + """
for p in photos:
    im = Image.open(p).crop((0, 8, 64, 56)); ex = Image.Exif(); ex[0x0112] = 6
    im.save(p, quality=95, exif=ex.tobytes())
m = cv2.imread(F + "/mask.png", cv2.IMREAD_GRAYSCALE)[8:56]
cv2.imwrite("m.png", cv2.rotate(m, cv2.ROTATE_90_CLOCKWISE))
"""), CAPTURE.replace('"$F/mask.png"', "m.png")
     + " && $PY -c \"import cv2,sys; s=cv2.imread('o/normal.png',-1).shape; print(s); sys.exit(s[:2]!=(64,48))\"",
     expect="ok", may_change=O,
     why="the same photos with the mask drawn as shown (48 wide, 64 tall) work, and normal.png is 48x64 as shown")
case("cap-png-gamma-1.8", "input", png_photos(PNG_CHUNK + """
for p in pngs: add_chunk(p, b"gAMA", struct.pack(">I", 55556))
"""), CAPTURE, names=["--input", "photo00.png", "--input-encoding"], may_change=O,
     why="a PNG declaring gamma 1/1.8 is neither sRGB nor linear: refused naming the file and --input-encoding")
case("cap-png-srgb-chunk-beats-gama-1", "input", png_photos(PNG_CHUNK + """
for p in pngs:
    add_chunk(p, b"gAMA", struct.pack(">I", 100000)); add_chunk(p, b"sRGB", b"\\x00")
"""), CAPTURE + " && $PY -c \"import json,sys; e=json.load(open('o/report.json'))['input']['encoding']; print(e); "
     "sys.exit(any(k != 'srgb' for k in e))\"", expect="ok", may_change=O,
     why="the PNG standard says an sRGB chunk overrides gAMA: photos holding both (gAMA 1.0 and sRGB) are read as sRGB")
case("cap-png-icc-garbage", "input", png_photos(PNG_CHUNK + """
for p in pngs: add_chunk(p, b"iCCP", b"junk profile\\x00\\x00" + zlib.compress(b"not an ICC profile at all" * 8))
"""), CAPTURE, names=["--input", "photo00.png"], may_change=O,
     why="a colour profile that cannot be read is refused in one line naming the file and the profile")
case("cap-png-icc-lab", "input", png_photos("""
from PIL import ImageCms
icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("LAB")).tobytes()
for p in pngs: Image.open(p).save(p, icc_profile=icc)
"""), CAPTURE, names=["--input", "photo00.png"], may_change=O,
     why="a Lab ICC profile on RGB photos is no sRGB or linear curve: refused naming the file and the profile")
case("cap-png-curves-differ-one-linear", "input", png_photos(PNG_CHUNK + """
add_chunk(pngs[5], b"gAMA", struct.pack(">I", 100000))
"""), CAPTURE, names=["--input", "photo05.png"], may_change=O,
     why="one PNG declaring gamma 1 among undeclared 8-bit ones is read another way: refused naming it")

# ============================================================================ capture: masks

case("cap-mask-16bit-binary", "input", PH + py(PRE + """
m = cv2.imread(F + "/mask.png", cv2.IMREAD_GRAYSCALE); cv2.imwrite("m.png", (m > 0).astype(np.uint16) * 65535)
"""), CAPTURE.replace('"$F/mask.png"', "m.png"), expect="ok", may_change=O,
     why="a 16-bit 0/65535 mask is binary (any one value on the object): accepted")
case("cap-mask-1bit-png", "input", PH + py(PRE + """
Image.open(F + "/mask.png").convert("1").save("m.png")
"""), CAPTURE.replace('"$F/mask.png"', "m.png"), expect="ok", may_change=O,
     why="a 1-bit PNG mask (mode '1', what many editors save) is binary: accepted")
case("cap-mask-rgba-fully-transparent", "input", PH + py(PRE + """
m = np.full((64, 64, 4), 255, np.uint8); m[..., 3] = 0; cv2.imwrite("m.png", m)
"""), CAPTURE.replace('"$F/mask.png"', "m.png"), names=["--mask", "m.png"], may_change=O,
     why="a cut-out whose alpha is 0 everywhere marks no object: refused naming --mask (the white colour is ignored)")
case("cap-mask-float-tiff-nan", "input", PH + py(PRE + """
m = (cv2.imread(F + "/mask.png", cv2.IMREAD_GRAYSCALE) > 0).astype(np.float32); m[0, 0] = np.nan
cv2.imwrite("m.tif", m)
"""), CAPTURE.replace('"$F/mask.png"', "m.tif"), names=["--mask", "m.tif"], may_change=O,
     why="a float TIFF mask holding NaN is no binary mask: refused naming --mask and the file")
case("cap-mask-bmp-named-png", "input", PH + py(PRE + """
cv2.imwrite("m.bmp", cv2.imread(F + "/mask.png", cv2.IMREAD_GRAYSCALE)); os.replace("m.bmp", "m.png")
"""), CAPTURE.replace('"$F/mask.png"', "m.png"), names=["--mask", "m.png"], may_change=O,
     why="a mask must be what its name says too: BMP bytes named .png are refused naming --mask")
case("cap-mask-png-cut-short", "input", PH + py(PRE + """
b = open(F + "/mask.png", "rb").read(); open("m.png", "wb").write(b[: len(b) // 2])
"""), CAPTURE.replace('"$F/mask.png"', "m.png"), names=["--mask", "m.png"], may_change=O,
     why="a mask file cut short is refused naming --mask, never read as a partial (smaller) object")
case("cap-mask-third-size-with-max-side", "input", PH + py(PRE + """
m = cv2.imread(F + "/mask.png", cv2.IMREAD_GRAYSCALE); cv2.imwrite("m.png", cv2.resize(m, (48, 48), interpolation=cv2.INTER_NEAREST))
"""), CAPTURE.replace('"$F/mask.png"', "m.png") + " --max-side 32", names=["--mask", "48"], may_change=O,
     why="with --max-side 32 a mask may be 64 (the photos) or 32 (the working size); 48 is refused naming both sizes")
case("cap-mask-working-size-accepted", "input", PH + py(PRE + """
m = cv2.imread(F + "/mask.png", cv2.IMREAD_GRAYSCALE); cv2.imwrite("m.png", cv2.resize(m, (32, 32), interpolation=cv2.INTER_NEAREST))
"""), CAPTURE.replace('"$F/mask.png"', "m.png") + " --max-side 32", expect="ok", may_change=O,
     why="docs/capture.md: a mask file may have the working size; accepted, normal.png still at the photos' size")
case("cap-mask-trailing-slash", "input", PH, CAPTURE.replace('"$F/mask.png"', '"$F/mask.png/"'),
     names=["--mask"], may_change=O, expect="either",
     why="a mask path with a trailing slash is no file: refused naming --mask; or read (the path names one file, "
         "that file is read: Python drops the slash), either is fine")
case("cap-mask-link-to-an-output", "writer", PH + FAKE_CAPTURE + 'cp "$F/mask.png" o/mask.png\nln -s o/mask.png m.png\n',
     CAPTURE.replace('"$F/mask.png"', "m.png") + " --overwrite", names=["--mask"], may_change=O,
     why="a mask reached through a link to --out/mask.png, which the run replaces, is refused naming --mask")
case("cap-mask-hardlinked-to-an-output-is-kept", "writer",
     PH + FAKE_CAPTURE + 'cp "$F/mask.png" o/mask.png\nln o/mask.png m.png\n',
     CAPTURE.replace('"$F/mask.png"', "m.png") + " --overwrite", expect="either", may_change=["$C/o/*", "$C/o/*/*",
                                                                                                "$C/o/*/*/*"],
     why="the user's m.png is a hard link of the earlier o/mask.png: --overwrite replaces o/mask.png by a new file, "
         "never writes through the link into m.png")

# ============================================================================ capture: --out / --input overlaps, links

case("cap-input-is-its-own-keep-work-folder", "writer", FAKE_CAPTURE + py(PRE + """
os.makedirs("o/work"); shutil.copytree(F + "/data8/00000.data", "o/work/00000.data")
"""), '$PY -m orchestrate.capture --input o/work/00000.data --out o --keep-work --overwrite --no-refine --threads 1',
     names=["--input"], may_change=[],
     why="--keep-work would replace OUT/work/00000.data, which is --input itself: refused before anything is written")
case("cap-input-is-out-surface", "writer", FAKE_CAPTURE + 'rmdir o/surface; cp -r "$F/photos" o/surface\n',
     '$PY -m orchestrate.capture --input o/surface --out o --mask "$F/mask.png" --no-refine --threads 1 --overwrite',
     names=["surface"], may_change=[],
     why="the photos lie in OUT/surface, where the run writes its surface: refused (a command never writes into what "
         "it reads)")
case("cap-input-is-out-check-name", "writer", FAKE_CAPTURE + 'mkdir -p o/check; cp -r "$F/photos" o/check/photos\n',
     '$PY -m orchestrate.capture --input o/check/photos --out o --mask "$F/mask.png" --threads 1 --overwrite',
     names=["--input"], may_change=[],
     why="the check writes OUT/check/<name>/ with <name> = photos: that is --input itself; refused")
case("cap-out-refine-a-link-out", "security", PH + FAKE_CAPTURE
     + 'mkdir -p elsewhere; ln -s "$C/elsewhere" o/refine\n',
     '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --threads 1 --overwrite',
     names=["--out", "refine"], may_change=[],
     why="OUT/refine is a link out of --out: refused naming it before any work, never followed")
case("cap-out-surface-a-link-out", "security", PH + FAKE_CAPTURE
     + 'rmdir o/surface; mkdir -p elsewhere; ln -s "$C/elsewhere" o/surface\n',
     CAPTURE + " --overwrite", names=["--out", "surface"], may_change=[],
     why="OUT/surface is a link out of --out: refused, nothing written there")
case("cap-out-surface-mesh-a-link", "security", PH + FAKE_CAPTURE
     + 'echo \'{"camera": 1, "solver": 1, "depth": 1}\' > o/surface/report.json\n'
     + 'ln -s /tmp/pwn_a37_mesh.ply o/surface/mesh.ply\n',
     CAPTURE + " --overwrite", names=["mesh.ply"], may_change=[],
     why="OUT/surface/mesh.ply is a (dangling) link: refused naming it, never written through to /tmp")
case("cap-out-check-a-file", "writer", PH + FAKE_CAPTURE + "echo mine > o/check\n",
     CAPTURE + " --overwrite", names=["check"], may_change=[],
     why="a file where the check's folder goes is the user's: refused naming it, before the photos are read")

# ============================================================================ one writer per folder: subfolders held

case("cap-out-surface-held-by-another-run", "writer", PH,
     hold("o/surface") + released(CAPTURE), names=["surface"], may_change=O,
     why="another run (orchestrate.surface --out o/surface) holds o/surface: a capture into o must not write its "
         "surface there (one writer per folder, subfolders included)")
case("cap-out-check-name-held-by-another-run", "writer", PH,
     hold("o/check/p") + released(CAPTURE), names=["check"], may_change=O,
     why="another run (validate.rerender --out o/check) holds o/check/p: the capture's check must not mix into it")
case("cap-while-surface-into-its-surface-folder", "writer", PH,
     CAPTURE + " & c=$!; for i in $(seq 300); do [ -e o/report.json ] && break; sleep 0.1; done; "
     f'{SURF} --normals {N0} --mask {M0} --out o/surface; rc=$?; wait $c; exit $rc',
     names=["--out", "another run"], may_change=O,
     why="orchestrate.surface --out o/surface while a capture holds o: refused (a folder inside a held one)")
case("cap-two-captures-nested-outs", "writer", PH + 'cp -r "$F/photos" q\n',
     CAPTURE + " & c=$!; for i in $(seq 300); do [ -e o/report.json ] && break; sleep 0.1; done; "
     '$PY -m orchestrate.capture --input q --out o/inner --mask "$F/mask.png" --no-refine --threads 1; rc=$?; '
     "wait $c; exit $rc", names=["--out"], may_change=O,
     why="a second capture into a folder inside the first one's --out is refused while the first runs")
case("rerender-out-object-held-by-another-run", "writer", "",
     hold("r/00000") + released('$PY -m validate.rerender --data "$F/data" --normals "$F/pred" --out r --spp 1 '
                                "--no-floors"),
     names=["00000"], may_change=["$C/r/*", "$C/r/*/*"],
     why="another run holds r/00000: rerender --out r must not write its report for 00000 into that folder")
case("rerender-data-object-being-written", "writer", 'cp -r "$F/data" d\n',
     hold("d/00001.data") + released('$PY -m validate.rerender --data d --normals "$F/pred" --out r --spp 1 '
                                     "--no-floors"),
     names=["00001"], may_change=["$C/r/*", "$C/r/*/*"],
     why="an object folder of --data that another run is still writing (held) is not read as if whole")
case("evaluate-pred-object-being-written", "writer", 'cp -r "$F/pred" p\n',
     hold("p/00001") + released('$PY -m unips.evaluate --pred p --gt "$F/data"'),
     names=["00001"], may_change=["$C/p/*", "$C/p/*/*"],
     why="p/00001 is held by a predict still writing it: evaluate must neither score its partial map nor write "
         "error_map.png into it")
case("refine-out-object-held-by-another-run", "writer", "",
     hold("r/00000") + released(f"$PY -m validate.refine --data {OBJ8} --normals {PRED8} --out r {RF_FAST}"),
     names=["00000"], may_change=["$C/r/*", "$C/r/*/*"],
     why="refine writes r/00000/: while another run holds that folder the refinement is refused, not mixed in")
case("surface-normals-being-written", "writer", 'mkdir -p p; cp ' + N0 + ' p/normal.png\n',
     hold("p") + released(f"{SURF} --normals p/normal.png --mask {M0} --out o"),
     names=["--normals", "being written"], may_change=O,
     why="a normal map in a folder another run holds is not yet whole: refused naming --normals")

# ============================================================================ capture: interrupts

case("cap-ctrl-c-then-rerun-names-overwrite", "writer", PH,
     "timeout -s INT 9 " + CAPTURE + "; echo \"first: $?\"; " + CAPTURE,
     names=["--overwrite"], may_change=["$C/o/*", "$C/o/*/*", "$C/o/*/*/*"],
     why="after Ctrl-C the same command is refused naming --overwrite (its own partial files), never a 'not written "
         "by' refusal and never silent reuse")
case("cap-sighup-leaves-no-worker", "engine", PH,
     "set -m; " + CAPTURE_ABS + " 2>e.txt & c=$!; sleep 3; kill -HUP $c; wait $c; rc=$?; cat e.txt >&2; sleep 1; "
     "if pgrep -f \"$C/p\"; then echo 'a worker is left running'; exit 3; fi; "
     "if [ $rc -gt 1 ] && grep -q interrupted e.txt; then exit 0; fi; echo \"expected a stop in one line, exit $rc\"; exit 4",
     expect="ok", may_change=["$C/o/*", "$C/o/*/*", "$C/o/*/*/*"],
     why="a closed terminal (SIGHUP) stops the capture whole: non-zero exit with the one line, no worker left "
         "(the command exits 0 here when that holds)")
case("cap-double-ctrl-c", "engine", PH,
     "set -m; " + CAPTURE_ABS + " & c=$!; sleep 3; kill -INT $c; sleep 0.05; kill -INT $c; wait $c; rc=$?; "
     "[ $rc -eq 130 ] || echo \"exit $rc, expected 130\"; exit $rc",
     names=["interrupted"], may_change=["$C/o/*", "$C/o/*/*", "$C/o/*/*/*"],
     why="two Ctrl-C in a row end the capture as one does: exit 130, one line, no traceback")
case("cap-kill-supervisor-leaves-no-worker", "engine", PH,
     CAPTURE_ABS + " & c=$!; sleep 7; kill -KILL $c; wait $c; sleep 2; "
     "if pgrep -f \"$C/p\" >/dev/null; then echo 'a worker is left running'; exit 3; fi; exit 0",
     expect="ok", may_change=["$C/o/*", "$C/o/*/*", "$C/o/*/*/*"],
     why="SIGKILL of the command (OOM killer) must take its worker with it, no orphan goes on writing into --out "
         "(the command exits 0 here when none is left)")
case("cap-read-only-out-mount", "writer", PH + "mkdir o\n",
     "mount -t tmpfs -o ro tmpfs o || exit 77; trap 'umount o' EXIT; " + CAPTURE,
     names=["--out", "not writable"], may_change=O,
     why="a read-only --out is refused before any work, in one line naming --out")
case("cap-read-only-surface-subfolder", "writer", PH + FAKE_CAPTURE,
     "mount -t tmpfs -o ro tmpfs o/surface || exit 77; trap 'umount o/surface' EXIT; " + CAPTURE + " --overwrite",
     names=["surface"], may_change=O,
     why="a read-only OUT/surface (a mount) is refused before the photos are read, not after the model has run")

# ============================================================================ capture: odd flag values, weights

case("cap-max-side-negative", "message", PH, CAPTURE + " --max-side -1", names=["--max-side"], may_change=O,
     why="--max-side -1 is refused naming the flag and what is allowed")
case("cap-max-side-hex", "message", PH, CAPTURE + " --max-side 0x40", names=["--max-side", "0x40"], may_change=O,
     why="--max-side 0x40 is not an integer the docs allow: refused naming the flag and the value")
case("cap-convention-capitalised", "message", PH, CAPTURE + " --convention OpenCV", names=["--convention", "OpenCV"],
     may_change=O, why="--convention OpenCV is refused naming the flag, the value and the choices")
case("cap-checkpoint-fifo", "weights", PH + "mkfifo w.safetensors\n", CAPTURE + " --checkpoint w.safetensors",
     names=["--checkpoint", "w.safetensors"], may_change=O, timeout=60,
     why="a pipe given as the weights is refused at once naming --checkpoint, never opened and waited on")
case("cap-checkpoint-dev-zero", "weights", PH + "ln -s /dev/zero w.pt\n", CAPTURE + " --checkpoint w.pt",
     names=["--checkpoint", "w.pt"], may_change=O, timeout=60,
     why="a link to /dev/zero given as the weights is refused naming --checkpoint, not read into memory without end")
case("cap-checkpoint-pickle-runs-nothing", "security", PH + py(PRE + """
import pickle
class Evil:
    def __reduce__(self):
        return (os.system, ("touch /tmp/pwn_a37_ckpt",))
pickle.dump({"model": Evil(), "state_dict": {}}, open("w.pt", "wb"))
"""), CAPTURE + " --checkpoint w.pt", names=["--checkpoint", "w.pt"], may_change=O,
     why="a .pt checkpoint holding a pickle that runs code is refused without running it (no /tmp/pwn_a37_ckpt)")

# ============================================================================ orchestrate.surface

case("surf-normals-npy-pickle", "security", py(PRE + """
import pickle
class Evil:
    def __reduce__(self):
        return (os.system, ("touch /tmp/pwn_a37_surf",))
np.save("n.npy", np.array([Evil()], dtype=object), allow_pickle=True)
"""), f"{SURF} --normals n.npy --out o", names=["--normals", "n.npy"], may_change=O,
     why="an .npy holding pickled objects is refused naming --normals, without running the pickle")
case("surf-normals-npy-channels-first", "input", py(PRE + """
from scenes.images import read_normals
n = read_normals(F + "/pred/00000/normal.png"); np.save("n.npy", np.ascontiguousarray(n.transpose(2, 0, 1)))
"""), f"{SURF} --normals n.npy --mask {M0} --out o", names=["--normals", "n.npy"], may_change=O,
     why="a (3, H, W) array (channels first, PyTorch's layout) is refused naming the file and the shape expected")
case("surf-normals-npy-big-endian", "input", py(PRE + """
from scenes.images import read_normals
n = read_normals(F + "/pred/00000/normal.png"); np.save("n.npy", n.astype(">f4"))
"""), f"{SURF} --normals n.npy --mask {M0} --out o", expect="ok", may_change=O,
     why="a big-endian float32 .npy holds the same vectors: integrated as the little-endian one")
case("surf-normals-npy-float16", "input", py(PRE + """
from scenes.images import read_normals
n = read_normals(F + "/pred/00000/normal.png"); np.save("n.npy", n.astype(np.float16))
"""), f"{SURF} --normals n.npy --mask {M0} --out o", expect="either", names=["--normals"], may_change=O,
     why="half floats are floats: integrated or refused naming --normals; no traceback")
case("surf-normals-npy-empty", "input", py(PRE + 'np.save("n.npy", np.zeros((0, 0, 3), np.float32))'),
     f"{SURF} --normals n.npy --out o", names=["--normals", "n.npy"], may_change=O,
     why="a 0x0 map is refused naming --normals, not a numpy error")
case("surf-normals-png-grey-alpha", "input", py(PRE + """
a = np.full((32, 32, 2), 128, np.uint8); Image.fromarray(a, "LA").save("n.png")
"""), f"{SURF} --normals n.png --out o", names=["--normals", "n.png"], may_change=O,
     why="a grey+alpha PNG holds no x, y, z: refused naming the file and that it must be RGB")
case("surf-normals-png-header-huge", "input", py(PRE + PNG_CHUNK + """
ihdr = struct.pack(">IIBBBBB", 200000, 200000, 16, 2, 0, 0, 0)
idat = zlib.compress(b"\\x00" * 1000)
open("n.png", "wb").write(b"\\x89PNG\\r\\n\\x1a\\n" + png_chunk(b"IHDR", ihdr) + png_chunk(b"IDAT", idat) + png_chunk(b"IEND", b""))
"""), f"{SURF} --normals n.png --out o", names=["--normals", "n.png"], may_change=O, timeout=60,
     why="a PNG whose header claims 200000 x 200000 16-bit pixels is refused quickly naming it, not allocated")
case("surf-normals-mat-v73", "input", py(PRE + """
open("n.mat", "wb").write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
                          .ljust(116) + b"\\x00" * 8 + b"\\x00\\x02IM" + b"\\x89HDF\\r\\n\\x1a\\n" + b"\\x00" * 600)
"""), f"{SURF} --normals n.mat --out o", names=["--normals", "n.mat"], may_change=O,
     why="a MATLAB v7.3 (HDF5) file that scipy cannot read is refused naming the file, not a traceback")
case("surf-normals-exr-nan-background", "input", py(PRE + """
from scenes.images import read_normals
from scenes.exr import write_exr
n = read_normals(F + "/pred/00000/normal.png"); m = cv2.imread(F + "/data/00000.data/mask.png", 0) > 0
n[~m] = np.nan; write_exr("n.exr", n)
"""), f"{SURF} --normals n.exr --mask {M0} --out o", expect="either", names=["--normals", "n.exr"], may_change=O,
     why="NaN outside the given mask (what many tools write) is accepted or refused naming the file; no traceback")
case("surf-mask-inverted", "input", py(PRE + """
m = cv2.imread(F + "/data/00000.data/mask.png", 0); cv2.imwrite("m.png", np.where(m > 0, 0, 255).astype(np.uint8))
"""), f"{SURF} --normals {N0} --mask m.png --out o", names=[], may_change=O,
     why="a mask of the background (zero normals inside it) is refused in one line, not integrated")
case("surf-mask-hardlinked-to-an-output", "writer", py(PRE + """
os.makedirs("o")
json.dump({"camera": "orthographic", "solver": {}, "depth": {}, "meshes": ["mesh.ply"]}, open("o/report.json", "w"))
shutil.copy(F + "/data/00000.data/mask.png", "o/discontinuities.png")
for n in ("depth.npy", "depth.exr", "mesh.ply"): open("o/" + n, "wb").write(b"earlier")
os.link("o/discontinuities.png", "m.png")
"""), f"{SURF} --normals {N0} --mask m.png --out o --overwrite", expect="either", may_change=O,
     why="m.png is a hard link of the earlier o/discontinuities.png: --overwrite replaces the output by a new file, "
         "the user's m.png keeps its bytes")
case("surf-intrinsics-fifo", "input", "mkfifo K.txt\n", f"{SURF} --normals {N0} --mask {M0} --intrinsics K.txt --out o",
     names=["--intrinsics", "K.txt"], may_change=O, timeout=60,
     why="a pipe given as --intrinsics is refused at once naming it, never read and waited on")
case("surf-intrinsics-utf16", "input", py(PRE + """
open("K.txt", "w", encoding="utf-16").write("40 0 15.5\\n0 40 15.5\\n0 0 1\\n")
"""), f"{SURF} --normals {N0} --mask {M0} --intrinsics K.txt --out o", names=["--intrinsics", "K.txt"], may_change=O,
     why="intrinsics saved as UTF-16 (Windows Notepad) are refused naming the flag and the file, no codec traceback")
case("surf-intrinsics-comma-separated", "input", "printf '40,0,15.5\\n0,40,15.5\\n0,0,1\\n' > K.txt\n",
     f"{SURF} --normals {N0} --mask {M0} --intrinsics K.txt --out o", names=["--intrinsics", "K.txt"], may_change=O,
     why="a CSV matrix is refused naming --intrinsics and what is expected (3 rows of 3 numbers)")
case("surf-out-is-the-intrinsics-folder", "writer", "mkdir k; printf '40 0 15.5\\n0 40 15.5\\n0 0 1\\n' > k/K.txt\n",
     f"{SURF} --normals {N0} --mask {M0} --intrinsics k/K.txt --out k", names=["--out"], may_change=[],
     why="--out the very folder --intrinsics lies in is refused (a command never writes beside what it reads)")
case("surf-k-nan", "message", "", f"{SURF} --normals {N0} --mask {M0} --k nan --out o", names=["--k"], may_change=O,
     why="--k nan is refused naming the flag (a NaN weight would make every equation NaN)")
case("surf-focal-px-nan", "message", "", f"{SURF} --normals {N0} --mask {M0} --focal-px nan --out o",
     names=["--focal-px"], may_change=O, why="--focal-px nan is refused naming the flag")
case("surf-mesh-empty-item", "message", "", f"{SURF} --normals {N0} --mask {M0} --mesh ply, --out o",
     names=["--mesh"], may_change=O, why="--mesh 'ply,' (a trailing comma) is refused or read as ply; never a traceback")
case("surf-ctrl-c-leaves-no-temporaries", "writer", py(PRE + """
h = w = 1000
y, x = np.mgrid[:h, :w]; u = (x - w / 2) / (w / 2.2); v = (h / 2 - y) / (h / 2.2); r2 = u * u + v * v
m = r2 < 1; n = np.zeros((h, w, 3), np.float32); n[..., 0] = u; n[..., 1] = v; n[..., 2] = np.sqrt(np.clip(1 - r2, 0, 1))
n[~m] = 0; n[m] /= np.linalg.norm(n[m], axis=1, keepdims=True); np.save("n.npy", n)
"""), f"timeout -s INT 5 {SURF} --normals n.npy --out o; rc=$?; ls -a o 2>/dev/null; "
     "if ls -a o 2>/dev/null | grep -q tmp; then echo 'temporaries left in o'; exit 3; fi; exit $rc",
     names=["interrupted"], may_change=O,
     why="Ctrl-C during the integration ends in one line (exit 130) and leaves no temporary files in --out")

# ============================================================================ validate.rerender / refine: fitted, damaged folders

case("rerender-fit-opencv-convention-map", "input", py(PRE + """
from scenes.images import read_normals
n = read_normals(F + "/pred8/00000/normal.png"); n[..., 1:] *= -1; np.save("n.npy", n)
"""), f"$PY -m validate.rerender --data {OBJ8} --normals n.npy --out r {RR_FIT}", names=["--normals"],
     may_change=["$C/r/*", "$C/r/*/*"],
     why="a map in the OpenCV convention (capture --convention opencv: z away) faces away from the camera: refused "
         "naming --normals, not scored as a bad map")
case("rerender-fit-image-a-fifo", "input", f"cp -r {OBJ8} d.data; rm d.data/L003.png; mkfifo d.data/L003.png\n",
     f"$PY -m validate.rerender --data d.data --normals {PRED8} --out r {RR_FIT}", names=["L003.png"],
     may_change=["$C/r/*", "$C/r/*/*"], timeout=60,
     why="an image of the object folder that is a pipe is refused naming it at once, never opened and waited on")
case("rerender-fit-image-cut-short", "input", f"cp -r {OBJ8} d.data; rm d.data/scene.json\n" + py(PRE + """
b = open("d.data/L002.png", "rb").read(); open("d.data/L002.png", "wb").write(b[: len(b) // 2])
"""), f"$PY -m validate.rerender --data d.data --normals {PRED8} --out r {RR_FIT}", names=["L002.png"],
     may_change=["$C/r/*", "$C/r/*/*"],
     why="an image cut short inside an object folder is refused naming it, not fitted as a partial image")
case("rerender-fit-image-other-size", "input", f"cp -r {OBJ8} d.data; rm d.data/scene.json\n" + py(PRE + """
a = cv2.imread("d.data/L005.png", -1); cv2.imwrite("d.data/L005.png", cv2.resize(a, (40, 40)))
"""), f"$PY -m validate.rerender --data d.data --normals {PRED8} --out r {RR_FIT}", names=["L005.png"],
     may_change=["$C/r/*", "$C/r/*/*"],
     why="one image of another size in an object folder is refused naming it and both sizes")
case("rerender-scene-json-empty-file", "input", f"cp -r {OBJ8} d.data; : > d.data/scene.json\n",
     f"$PY -m validate.rerender --data d.data --normals {PRED8} --out r --spp 1 --no-floors", names=["scene.json"],
     may_change=["$C/r/*", "$C/r/*/*"],
     why="an empty scene.json is refused naming it, never silently taken as 'no scene' (fitted mode)")
case("rerender-ground-truth-normal-cut-short", "input", f"cp -r {OBJ8} d.data\n" + py(PRE + """
b = open("d.data/normal.tif", "rb").read(); open("d.data/normal.tif", "wb").write(b[: len(b) // 2])
"""), f"$PY -m validate.rerender --data d.data --normals {PRED8} --out r --spp 1 --no-floors", expect="either",
     names=["normal.tif"], may_change=["$C/r/*", "$C/r/*/*"],
     why="a damaged ground-truth normal.tif is named if refused; scored against it never, no traceback")
case("rerender-normals-is-an-earlier-rerender-out", "input", 'mkdir -p q/00000; echo "{}" > q/00000/report.json\n',
     f"$PY -m validate.rerender --data {OBJ8} --normals q/00000 --out r --spp 1 --no-floors",
     names=["--normals"], may_change=["$C/r/*", "$C/r/*/*"],
     why="a folder of reports (no normal map) given as --normals is refused naming the flag and what was expected")
case("rerender-normals-npy-pickle", "security", py(PRE + """
import pickle
class Evil:
    def __reduce__(self):
        return (os.system, ("touch /tmp/pwn_a37_rr",))
np.save("n.npy", np.array([Evil()], dtype=object), allow_pickle=True)
"""), f"$PY -m validate.rerender --data {OBJ8} --normals n.npy --out r --spp 1 --no-floors",
     names=["--normals", "n.npy"], may_change=["$C/r/*", "$C/r/*/*"],
     why="a pickled .npy given as --normals is refused without running it")
case("refine-on-a-capture-keep-work", "exit0", PH,
     CAPTURE + " --keep-work && $PY -m validate.refine --data o/work/p.data --normals o/normal.exr --out rf "
     + RF_FAST, expect="ok", may_change=["$C/o/*", "$C/o/*/*", "$C/o/*/*/*", "$C/o/*/*/*/*", "$C/rf/*", "$C/rf/*/*"],
     why="docs/capture.md: --keep-work writes an object folder for other commands; refine reads it with the "
         "capture's normal.exr (no scene.json: fitted)")
case("refine-out-is-the-captures-out", "writer", PH,
     CAPTURE + " --keep-work && $PY -m validate.refine --data o/work/p.data --normals o/normal.exr --out o "
     + RF_FAST, names=["--out"], may_change=["$C/o/*", "$C/o/*/*", "$C/o/*/*/*", "$C/o/*/*/*/*"],
     why="refine --out o, the capture's --out holding --data and --normals, is refused (it would write beside and "
         "into what it reads)")
case("refine-data-image-a-folder", "input", f"cp -r {OBJ8} d.data; rm d.data/L004.png; mkdir d.data/L004.png\n",
     f"$PY -m validate.refine --data d.data --normals {PRED8} --out rf {RF_FAST}", names=["L004.png"],
     may_change=["$C/rf/*", "$C/rf/*/*"],
     why="an image replaced by a folder is refused naming it (an object that silently lost a light is another "
         "capture)")
case("refine-ctrl-c", "writer", "",
     f"timeout -s INT 1.5 $PY -m validate.refine --data {OBJ8} --normals {PRED8} --out rf --steps 2000 --threads 1; "
     "rc=$?; if ls -aR rf 2>/dev/null | grep -q tmp; then echo 'temporaries left'; exit 3; fi; exit $rc",
     names=["interrupted"], expect="either", may_change=["$C/rf/*", "$C/rf/*/*"],
     why="Ctrl-C during the refinement ends in one line, exit 130, no temporaries left in --out (the refinement of 32 px may end first: either)")

# ============================================================================ unips.evaluate on odd predictions

case("evaluate-pred-npy-pickle", "security", "mkdir -p p/00000\n" + py(PRE + """
import pickle
class Evil:
    def __reduce__(self):
        return (os.system, ("touch /tmp/pwn_a37_ev",))
np.save("p/00000/normal.npy", np.array([Evil()], dtype=object), allow_pickle=True)
"""), '$PY -m unips.evaluate --pred p --gt "$F/data/00000.data"', names=["normal.npy"],
     may_change=["$C/p/*", "$C/p/*/*"], why="a pickled prediction is refused naming it, the pickle never run")
case("evaluate-pred-normal-a-fifo", "input", "mkdir -p p/00000; mkfifo p/00000/normal.png\n",
     '$PY -m unips.evaluate --pred p --gt "$F/data/00000.data"', names=["normal.png"],
     may_change=["$C/p/*", "$C/p/*/*"], timeout=60,
     why="a prediction that is a pipe is refused naming it at once, not opened and waited on")
case("evaluate-pred-exr-and-png-disagree", "input", 'cp -r "$F/pred" p\n' + py(PRE + """
from scenes.images import read_normals
from scenes.exr import write_exr
n = read_normals("p/00000/normal.png"); n[..., 1:] *= -1; write_exr("p/00000/normal.exr", n)
"""), '$PY -m unips.evaluate --pred p --gt "$F/data"', expect="either", names=["normal"],
     may_change=["$C/p/*", "$C/p/*/*"],
     why="two different maps for one object (normal.exr and normal.png): scored by the documented order (.exr first) "
         "or refused naming both, never a silent mix")
case("evaluate-pred-other-size", "input", "mkdir -p p/00000\n" + py(PRE + """
a = cv2.imread(F + "/pred/00000/normal.png", -1); cv2.imwrite("p/00000/normal.png", cv2.resize(a, (64, 64), interpolation=cv2.INTER_NEAREST))
"""), '$PY -m unips.evaluate --pred p --gt "$F/data/00000.data"', names=["00000", "64"],
     may_change=["$C/p/*", "$C/p/*/*"],
     why="a 64 px prediction of a 32 px object is refused naming the object and both sizes, never resized silently")
case("evaluate-pred-header-huge", "input", "mkdir -p p/00000\n" + py(PRE + PNG_CHUNK + """
ihdr = struct.pack(">IIBBBBB", 100000, 100000, 16, 2, 0, 0, 0)
open("p/00000/normal.png", "wb").write(b"\\x89PNG\\r\\n\\x1a\\n" + png_chunk(b"IHDR", ihdr)
    + png_chunk(b"IDAT", zlib.compress(b"\\x00" * 100)) + png_chunk(b"IEND", b""))
"""), '$PY -m unips.evaluate --pred p --gt "$F/data/00000.data"', names=["normal.png"],
     may_change=["$C/p/*", "$C/p/*/*"], timeout=60,
     why="a prediction whose PNG header claims 10^10 pixels is refused quickly naming it, not allocated")
case("evaluate-pred-rgba-transparent-background", "input", "mkdir -p p/00000\n" + py(PRE + """
a = cv2.imread(F + "/pred/00000/normal.png", -1); m = cv2.imread(F + "/data/00000.data/mask.png", 0) > 0
rgba = np.dstack([a, np.where(m, 65535, 0).astype(a.dtype)]); cv2.imwrite("p/00000/normal.png", rgba)
"""), '$PY -m unips.evaluate --pred p --gt "$F/data/00000.data"', expect="ok", may_change=["$C/p/*", "$C/p/*/*"],
     why="an RGBA prediction (alpha = the object) holds the same vectors in RGB: scored as the RGB map")
case("evaluate-pred-metrics-json-a-fifo", "writer", 'cp -r "$F/pred" p; mkfifo p/metrics.json\n',
     '$PY -m unips.evaluate --pred p --gt "$F/data" --overwrite', names=["metrics.json"],
     may_change=["$C/p/*", "$C/p/*/*"], timeout=60,
     why="a pipe where metrics.json goes is not the command's file: refused naming it, never opened and written")
