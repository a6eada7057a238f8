"""Sweep 43, part t: the USER-PHOTO and PHYSICAL-CHECK side (orchestrate.capture, validate.rerender in both modes,
validate.refine, orchestrate.surface, unips.evaluate), from angles earlier sweeps used little:

- chains: a capture's outputs fed to refine / rerender / surface / evaluate, one of them edited or replaced by hand
  in between; report.json `stages` hand-edited before an --overwrite;
- reruns with flags changed (another --mask, --keep-work then without, known-scene then --fit into one --out);
- outputs replaced by links or folders between two runs;
- EXIF orientations 5-8, two APP1 segments, an IFD chain that loops, a big thumbnail;
- TIFF layouts: tiled, planar (with an orientation tag), 32-bit int, palette, big-endian, grey + alpha; a TIFF or
  PNG named as camera RAW;
- masks one pixel off or transposed, a 16-bit alpha mask; normal maps 8-bit, int32 / int16 TIFF, 8-bit codes in a
  16-bit file, planar TIFF;
- paths with newline / tab, and relative paths that go `..` through a symlinked folder.

Cases whose command adds its own check print a line starting with `FAULT:` and exit so that the harness flags it.
A capture of the 8 fixture photos with the fixtures' mask, without refinement, takes about 15 s on 2 cores.
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


CAPX = "$PY -m orchestrate.capture --no-refine --threads 1"
CAP = CAPX + ' --input p --out o --mask "$F/mask.png"'
"""A capture of p/ with the fixtures' mask, without refinement (about 15 s)."""
CAPM = CAPX + " --input p --out o --mask m.png"
"""A capture of p/ with the mask m.png of the case folder."""
CAP_SETUP = PH + CAP + " > cap_setup.log 2>&1\n"
CAPW_SETUP = PH + CAP + " --keep-work > cap_setup.log 2>&1\n"
SURF = "$PY -m orchestrate.surface"
N0 = '"$F/pred8/00000/normal.png"'
M0 = '"$F/data8/00000.data/mask.png"'
USER = 'cp -r "$F/data8/00000.data" u && rm u/scene.json\n'
"""Setup: u/, an object folder as a user has it: L*.png, mask.png, normal.tif, no scene.json (the fitted mode)."""
OBJ = 'cp -r "$F/data8/00000.data" d\n'
"""Setup: d/, an object folder with its scene.json (the known-scene mode)."""
FAST = " --steps 2 --ao-rays 0 --no-shadows --no-bas-relief --threads 1"
KNOWN = " --spp 1 --no-floors --threshold 0.5"
RR = "$PY -m validate.rerender"
RRU = RR + ' --data u --normals "$F/pred8/00000/normal.png" --out r' + FAST
RRD = RR + ' --data d --normals "$F/pred8/00000/normal.png" --out r' + KNOWN
RFARGS = " --refine-steps 2 --steps 2 --rounds 1 --ao-rays 0 --no-shadows --threads 1"
RF = "$PY -m validate.refine"
RFU = RF + ' --data u --normals "$F/pred8/00000/normal.png" --out rf' + RFARGS
EV = "$PY -m unips.evaluate"
EVP = EV + ' --pred p --gt "$F/data"'
PRED = 'cp -r "$F/pred" p\n'
"""Setup: p/, a copy of the 3-object predictions of $F/data."""


def deep(d: str) -> list[str]:
    return [f"$C/{d}", f"$C/{d}/*", f"$C/{d}/*/*", f"$C/{d}/*/*/*", f"$C/{d}/*/*/*/*", f"$C/{d}/.*",
            f"$C/{d}/*/.*"]


O = deep("o")
R = deep("r")
RFO = deep("rf")
P = deep("p")
S = deep("s")
OK_CAP = " && test -s o/normal.png && test -s o/report.json"
OK_SURF = " && test -s s/depth.npy && test -s s/report.json"
OK_EV = " && test -s p/metrics.json && test -s p/metrics.csv"


def taken_or_named(cmd: str, name: str, check: str) -> str:
    """Command: `cmd` must either refuse naming `name` (a right answer) or succeed with `check` holding; anything
    else prints a FAULT line and exits 1 (expect "ok": flagged as failed)."""
    return (f"{cmd} > out.log 2>&1; r=$?; cat out.log; if [ $r != 0 ]; then grep -qi -- '{name}' out.log && exit 0; "
            f"echo 'FAULT: refused without naming {name}'; exit 1; fi; {check}")


def check_py(code: str) -> str:
    """Command tail: Python run after the command; it prints FAULT and exits 0 (flagged exit0) or 1."""
    return " && " + py(PRE + textwrap.dedent(code))


CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


def exif_photos(code: str) -> str:
    """Setup: p/ with each photo re-saved by Pillow; `code` runs per photo with k, p, im, ex (its EXIF)."""
    return setup_py("for k, p in enumerate(photos):\n    im = Image.open(p); ex = im.getexif()\n"
                    + textwrap.indent(textwrap.dedent(code).strip(), "    ")
                    + "\n    im.save(p, quality=95, exif=ex.tobytes())\n")


# ============================================================================ capture: EXIF orientation 5-8
case("t43-cap-exif-6-and-8-square-photos", "input", CAP, names=["photo04.jpg"],
     setup=exif_photos("ex[0x0112] = 6 if k < 4 else 8"), may_change=O,
     why="Half the square photos say 'turn 90 deg clockwise', half 'counter-clockwise' (the camera turned between "
         "shots): the sizes still agree, yet the photos do not show one view; refused naming photo04.jpg (the first "
         "that differs), not a capture of two frames mixed.")
case("t43-cap-exif-5-all-mask-transposed", "input", CAPM + OK_CAP, expect="ok",
     setup=exif_photos("ex[0x0112] = 5") + py("""
        import cv2
        m = cv2.imread(__import__('os').environ['F'] + '/mask.png', 0)
        cv2.imwrite('m.png', m.T.copy())
        """), may_change=O,
     why="Every photo says orientation 5 (transposed): one orientation for all, read transposed; the mask drawn on "
         "the photos as shown (transposed too) fits them; the capture runs.")
case("t43-cap-png-exif-6-among-jpeg-6-nonsquare", "input", CAPM + OK_CAP, expect="ok",
     setup=setup_py("""
        for k, p in enumerate(photos):
            im = Image.open(p).resize((64, 48)); ex = im.getexif(); ex[0x0112] = 6
            if k < 4:
                im.save(p, quality=95, exif=ex.tobytes())
            else:
                os.remove(p); im.save(p[:-4] + ".png", exif=ex.tobytes())
        m = cv2.resize(cv2.imread(F + "/mask.png", 0), (64, 48), interpolation=cv2.INTER_NEAREST)
        cv2.imwrite("m.png", cv2.rotate(np.where(m > 127, 255, 0).astype(np.uint8), cv2.ROTATE_90_CLOCKWISE))
        """), may_change=O,
     why="JPEGs and PNGs (eXIf chunk) of one capture, all 'turn 90 deg clockwise', 64x48 stored: both are shown "
         "48x64 and the mask drawn on them fits; the capture runs (neither kind read unturned).")
case("t43-cap-planar-tiff-exif-6-nonsquare", "input",
     taken_or_named(CAPM, "orientation", """$PY -c "import json,sys; s=json.load(open('o/report.json'))['input']['size']; """
                    """print('size', s); sys.exit(0 if s == [64, 48] else 'FAULT: planar TIFFs read unturned (EXIF orientation 6 ignored): ' + str(s))" """),
     expect="ok", setup=setup_py("""
        import tifffile
        for k, p in enumerate(photos):
            im = cv2.resize(cv2.imread(p), (64, 48))[..., ::-1].astype(np.uint16) * 257
            tifffile.imwrite(p[:-4] + ".tif", np.ascontiguousarray(np.moveaxis(im, -1, 0)), planarconfig="separate",
                             photometric="rgb", extratags=[(274, "H", 1, 6, False)])
            os.remove(p)
        m = cv2.resize(cv2.imread(F + "/mask.png", 0), (64, 48), interpolation=cv2.INTER_NEAREST)
        cv2.imwrite("m.png", cv2.rotate(np.where(m > 127, 255, 0).astype(np.uint8), cv2.ROTATE_90_CLOCKWISE))
        """), may_change=O + ["$C/out.log"],
     why="16-bit TIFFs stored planar (RRR GGG BBB) that say EXIF orientation 6 are shown 48 wide x 64 tall, as the same "
         "TIFFs stored contiguous are (OpenCV turns those): read turned (report size [64, 48], the mask fits) or "
         "refused naming the orientation; never read unturned, normals in a frame turned from the photo's "
         "(the planar reader skips the orientation: the mask's size is then refused for the wrong reason).")
case("t43-cap-planar-and-contig-tiff-exif-6-square", "input",
     taken_or_named(CAP + " --keep-work", "orientation", py(PRE + textwrap.dedent("""
        import cv2
        src = sorted(glob.glob("src/*.png"))
        work = sorted(glob.glob("o/work/p.data/L*.png"))
        bad = []
        for s, w in zip(src, work):
            a = cv2.imread(s, 0).astype(float); b = cv2.imread(w, -1).astype(float).mean(axis=2)
            turned = np.corrcoef(cv2.rotate(a, cv2.ROTATE_90_CLOCKWISE).ravel(), b.ravel())[0, 1]
            plain = np.corrcoef(a.ravel(), b.ravel())[0, 1]
            print(os.path.basename(w), "turned", round(turned, 3), "as stored", round(plain, 3))
            bad += [w] if turned < plain else []
        if bad:
            print("FAULT: photos with EXIF orientation 6 read unturned:", bad); raise SystemExit(1)
        """))), expect="ok",
     setup=setup_py("""
        import tifffile
        os.makedirs("src")
        for k, p in enumerate(photos):
            im = cv2.imread(p)
            im[:10, :40] = 255  # a mark that tells a turn from none
            cv2.imwrite(f"src/{k}.png", im)
            rgb = im[..., ::-1].astype(np.uint16) * 257
            arr = np.ascontiguousarray(np.moveaxis(rgb, -1, 0)) if k % 2 else rgb
            tifffile.imwrite(p[:-4] + ".tif", arr, planarconfig="separate" if k % 2 else "contig", photometric="rgb",
                             extratags=[(274, "H", 1, 6, False)])
            os.remove(p)
        """), may_change=O, timeout=120,
     why="Square 16-bit TIFFs, all saying orientation 6, half planar and half contiguous: every photo is turned the "
         "same way (or the capture is refused); a mix of turned and unturned photos passes every size check and "
         "would be a capture of two views, silently.")

# ============================================================================ capture: TIFF layouts and RAW names
case("t43-cap-tiff-tiled-16bit-photos", "input", CAP + OK_CAP, expect="ok", setup=setup_py("""
        import tifffile
        for p in photos:
            rgb = cv2.imread(p)[..., ::-1].astype(np.uint16) * 257
            tifffile.imwrite(p[:-4] + ".tif", rgb, tile=(16, 16), photometric="rgb"); os.remove(p)
        """), may_change=O,
     why="Tiled 16-bit TIFFs (16x16 tiles, as some scanners and stitchers write) are TIFFs like striped ones: read "
         "whole, the capture runs.")
case("t43-cap-tiff-int32-photos", "input", CAP, names=["--input", "photo00.tif"], setup=setup_py("""
        import tifffile
        for p in photos:
            tifffile.imwrite(p[:-4] + ".tif", cv2.imread(p)[..., ::-1].astype(np.int32) * 1000, photometric="rgb")
            os.remove(p)
        """), may_change=O,
     why="Signed 32-bit integer TIFFs have no agreed white: refused in one line naming --input and photo00.tif "
         "(8 or 16-bit integers, or float, expected), not scaled by a guess.")
case("t43-cap-tiff-palette-photos", "input", CAP, expect="either", setup=setup_py("""
        for p in photos:
            Image.open(p).convert("L").convert("P").save(p[:-4] + ".tif"); os.remove(p)
        """), may_change=O,
     why="Palette TIFFs of grey levels: read through their palette as colour (the capture runs) or refused in one "
         "line naming the file; never the palette indices taken as light, never a traceback.")
case("t43-cap-tiff-big-endian-16bit-photos", "input", CAP + OK_CAP, expect="ok", setup=setup_py("""
        import tifffile
        for p in photos:
            rgb = cv2.imread(p)[..., ::-1].astype(np.uint16) * 257
            tifffile.imwrite(p[:-4] + ".tif", rgb, byteorder=">", photometric="rgb"); os.remove(p)
        """), may_change=O,
     why="Big-endian ('MM') 16-bit TIFFs, as older Mac software writes them, are read like little-endian ones.")
case("t43-cap-tiff-grey-alpha-16bit-photos", "input", CAP, expect="either", setup=setup_py("""
        import tifffile
        for p in photos:
            g = cv2.imread(p, 0).astype(np.uint16) * 257
            ga = np.stack([g, np.full_like(g, 65535)], -1)
            tifffile.imwrite(p[:-4] + ".tif", ga, photometric="minisblack", extrasamples=[2]); os.remove(p)
        """), may_change=O,
     why="Grey + opaque alpha 16-bit TIFFs: read as grey photos (alpha dropped, 16 bits kept) or refused in one "
         "line naming the file; no traceback.")
case("t43-cap-tiff-named-dng", "input", CAP, names=["--input"], setup=setup_py("""
        import tifffile
        for p in photos:
            tifffile.imwrite(p[:-4] + ".dng", cv2.imread(p)[..., ::-1].astype(np.uint16) * 257, photometric="rgb")
            os.remove(p)
        """), may_change=O,
     why="Developed 16-bit TIFFs renamed .dng (DNG is a TIFF container, so the bytes look right) hold no raw "
         "sensor data: refused in one line naming --input and the file, not developed as RAW.")
case("t43-cap-png-named-arw-uppercase", "input", CAP, names=["--input"], setup=setup_py("""
        for p in photos:
            Image.open(p).save(p[:-4] + ".ARW", format="PNG"); os.remove(p)
        """), may_change=O,
     why="PNG bytes under an upper-case .ARW name: not a Sony RAW; refused in one line naming --input and the file.")

# ============================================================================ capture: odd EXIF blocks
EXIF_SEG = r"""
def app1(tiff):
    body = b"Exif\x00\x00" + tiff
    return b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body
def ifd(entries, nxt):
    out = struct.pack("<H", len(entries))
    for tag, typ, cnt, val in entries:
        out += struct.pack("<HHII", tag, typ, cnt, val)
    return out + struct.pack("<I", nxt)
def put(path, *segs):
    b = open(path, "rb").read()
    open(path, "wb").write(b[:2] + b"".join(segs) + b[2:])
"""


def seg(code: str) -> str:
    """Setup: p/ and Python with PRE's names and EXIF_SEG's helpers."""
    return setup_py(EXIF_SEG + textwrap.dedent(code))

case("t43-cap-exif-thumbnail-60k", "input", CAP + OK_CAP, expect="ok", setup=seg("""
        thumb = open(photos[0], "rb").read()
        thumb = (thumb * (60000 // len(thumb) + 1))[:60000]
        for p in photos:
            # IFD0 (orientation 1) -> IFD1 (JPEGInterchangeFormat, length) -> a 60 kB blob
            ifd0 = ifd([(0x0112, 3, 1, 1)], 8 + 18)
            ifd1 = ifd([(0x0201, 4, 1, 8 + 18 + 30), (0x0202, 4, 1, len(thumb))], 0)
            put(p, app1(b"II*\\x00" + struct.pack("<I", 8) + ifd0 + ifd1 + thumb))
        """), may_change=O,
     why="An EXIF block carrying a 60 kB thumbnail (IFD1), as cameras write, is no reason to refuse: the photos "
         "are read at their own size, the capture runs.")
case("t43-cap-exif-two-app1-orientations", "input", CAP, expect="either", setup=seg("""
        for p in photos:
            a = app1(b"II*\\x00" + struct.pack("<I", 8) + ifd([(0x0112, 3, 1, 1)], 0))
            b = app1(b"II*\\x00" + struct.pack("<I", 8) + ifd([(0x0112, 3, 1, 6)], 0))
            put(p, a, b)
        """), may_change=O,
     why="Two EXIF segments per photo saying orientation 1 and 6 (an editor that appended its own): read one way "
         "for every photo (the pixels turned as the recorded orientation says) or refused in one line naming the "
         "photo; never a traceback.")
case("t43-cap-exif-ifd-chain-loops", "input", CAP, expect="either", timeout=90, setup=seg("""
        for p in photos:
            put(p, app1(b"II*\\x00" + struct.pack("<I", 8) + ifd([(0x0112, 3, 1, 1)], 8)))
        """), may_change=O,
     why="IFD0's next-IFD offset points back at IFD0 (a loop): the EXIF reader stops (the capture runs) or the "
         "photo is refused in one line; no hang, no recursion traceback.")

# ============================================================================ capture: masks
case("t43-cap-mask-one-px-wider", "input", CAPM, names=["--mask", "m.png"], setup=PH + py("""
        import cv2, os
        m = cv2.imread(os.environ['F'] + '/mask.png', 0)
        cv2.imwrite('m.png', __import__('numpy').hstack([m, m[:, -1:]]))
        """), may_change=O,
     why="A mask 65x64 for 64x64 photos (an editor's canvas one pixel off) is refused naming --mask and both sizes, "
         "not cropped or resized silently.")
case("t43-cap-mask-transposed-nonsquare", "input", CAPM, names=["--mask", "m.png"], setup=setup_py("""
        for p in photos:
            Image.open(p).resize((64, 48)).save(p, quality=95)
        m = cv2.resize(cv2.imread(F + "/mask.png", 0), (64, 48), interpolation=cv2.INTER_NEAREST)
        cv2.imwrite("m.png", np.where(m.T > 127, 255, 0).astype(np.uint8))
        """), may_change=O,
     why="A 48x64 mask for 64x48 photos (saved transposed: rows and columns swapped) is refused naming --mask and both "
         "sizes; the capture does not turn it by a guess.")
case("t43-cap-mask-rgba16-alpha", "input",
     CAPM + OK_CAP + """ && $PY -c "import cv2,sys,os; a=cv2.imread(os.environ['F']+'/mask.png',0)>127; """
     """b=cv2.imread('o/mask.png',0)>127; d=int((a!=b).sum()); print('differing', d); """
     """sys.exit('FAULT: o/mask.png is not the alpha of m.png' if d > 8 else 0)" """, expect="ok",
     setup=PH + py("""
        import cv2, os, numpy as np
        m = cv2.imread(os.environ['F'] + '/mask.png', 0) > 127
        rgba = np.full(m.shape + (4,), 65535, np.uint16); rgba[..., 3] = np.where(m, 65535, 0)
        cv2.imwrite('m.png', rgba)
        """), may_change=O,
     why="A 16-bit RGBA mask, white everywhere, the object in its alpha (a cut-out saved from an editor): read from "
         "its alpha (not fully opaque), so o/mask.png is the object, not the whole frame.")
case("t43-cap-mask-name-with-newline", "input", CAPX + " --input p --out o --mask \"$(printf 'ma\\nsk.png')\"" + OK_CAP,
     expect="ok", setup=PH + "cp \"$F/mask.png\" \"$(printf 'ma\\nsk.png')\"", may_change=O,
     why="A mask file whose name holds a newline is a valid path: read, and the capture runs (report.json and "
         "report.html escape the name).")
case("t43-cap-out-name-with-tab", "input",
     CAPX + " --input p --out \"$(printf 'o\\tx')\" --mask \"$F/mask.png\" && test -s \"$(printf 'o\\tx')/report.json\"",
     expect="ok", setup=PH, may_change=deep("o\tx"),
     why="An output folder whose name holds a tab is a valid path: written, exit 0.")

# ============================================================================ capture: relative paths through links
case("t43-cap-input-dotdot-through-symlink", "input",
     CAPX + ' --input lnk/../p --out o --mask "$F/mask.png"' + OK_CAP, expect="ok",
     setup="mkdir -p real/sub; cp -r \"$F/photos\" real/p; ln -s real/sub lnk", may_change=O,
     why="lnk/../p goes up from the folder lnk points to (real/), as the kernel resolves it: the photos in real/p "
         "are read; a lexical '..' (p in the case folder, which does not exist) would be a wrong refusal.")
case("t43-cap-out-dotdot-through-symlink-is-input", "writer",
     CAPX + ' --input real/p --out lnk/../p --mask "$F/mask.png"', names=["--out"],
     setup="mkdir -p real/sub; cp -r \"$F/photos\" real/p; ln -s real/sub lnk", may_change=["$C/p", "$C/p/*"],
     why="--out lnk/../p is real/p, the photo folder itself, through the link: refused naming --out before "
         "anything is written there (a lexical '..' would see ./p, a different, missing folder).")
case("t43-surf-normals-dotdot-through-symlink", "input",
     SURF + ' --normals lnk/../n.png --mask lnk/../m.png --out s' + OK_SURF, expect="ok",
     setup='mkdir -p real/sub; cp ' + N0 + ' real/n.png; cp ' + M0 + ' real/m.png; ln -s real/sub lnk',
     may_change=S, why="Files named through a link and '..' are the files the kernel finds (real/n.png): read, "
                       "the surface written.")
case("t43-rf-data-dotdot-through-symlink", "input",
     RF + ' --data lnk/../u --normals "$F/pred8/00000/normal.png" --out rf' + RFARGS, expect="ok",
     setup="mkdir -p real/sub; " + USER.replace(" u ", " real/u ").replace(" u/", " real/u/") + "ln -s real/sub lnk",
     may_change=RFO, timeout=120,
     why="--data lnk/../u is real/u (the kernel's '..'): refined, exit 0, the object named u.")
case("t43-eval-gt-dotdot-through-symlink", "input", EV + ' --pred p --gt lnk/../ds' + OK_EV, expect="ok",
     setup=PRED + 'mkdir -p real/sub; cp -r "$F/data" real/ds; ln -s real/sub lnk', may_change=P,
     why="--gt lnk/../ds is real/ds: the three objects are scored, exit 0.")
case("t43-rr-data-dotdot-through-symlink", "input",
     RR + ' --data lnk/../d --normals "$F/pred8/00000/normal.png" --out r' + KNOWN + " && test -s r/d/report.json",
     expect="ok", setup='mkdir -p real/sub; cp -r "$F/data8/00000.data" real/d; ln -s real/sub lnk', may_change=R,
     why="The known-scene check of lnk/../d reads real/d: exit 0, r/d/report.json written.")

# ============================================================================ capture: reruns with flags changed
case("t43-cap-rerun-other-mask-overwrite", "writer",
     CAPM + " --overwrite" + OK_CAP + """ && $PY -c "import cv2,sys; a=cv2.imread('m.png',0)>127; """
     """b=cv2.imread('o/mask.png',0)>127; d=int((a!=b).sum()); print('differing', d); """
     """sys.exit('FAULT: o/mask.png is still the first run mask' if d > 8 else 0)" """, expect="ok",
     setup=CAP_SETUP + py("""
        import cv2, os, numpy as np
        m = cv2.imread(os.environ['F'] + '/mask.png', 0) > 127
        m2 = cv2.erode(m.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        cv2.imwrite('m.png', np.where(m2, 255, 0).astype(np.uint8))
        """), may_change=O,
     why="A second capture with a smaller mask and --overwrite replaces o/mask.png with the new one (and the map "
         "cut to it), not the first run's.")
case("t43-cap-rerun-other-mask-without-overwrite", "writer", CAPM, names=["--overwrite"],
     setup=CAP_SETUP + py("""
        import cv2, os, numpy as np
        m = cv2.imread(os.environ['F'] + '/mask.png', 0)
        cv2.imwrite('m.png', cv2.erode(m, np.ones((5, 5), np.uint8)))
        """),
     why="Changing --mask between two runs into one --out without --overwrite is refused naming --overwrite; the "
         "first capture stays whole.")
case("t43-cap-keep-work-then-overwrite-without", "writer",
     CAP + " --overwrite" + OK_CAP + check_py("""
        r = json.load(open("o/report.json"))
        print("work_folder", r["stages"]["work_folder"])
        if os.path.exists("o/work/p.data/L000.png") and r["stages"]["work_folder"] is None:
            w = cv2.imread("o/work/p.data/L000.png", -1).astype(float).mean(axis=2)
            a = cv2.imread("p/photo00.jpg", 0).astype(float)
            if np.corrcoef(w.ravel(), a.ravel())[0, 1] < 0.5:
                print("FAULT: o/work/p.data holds the earlier photos beside a report that lists no work folder"); raise SystemExit(1)
        """), expect="ok",
     setup=CAPW_SETUP + setup_py("""
        for p in photos:
            Image.open(p).transpose(Image.FLIP_LEFT_RIGHT).save(p, quality=95)
        """, photos=False), may_change=O,
     why="A --keep-work capture, the photos then retaken (mirrored), and a rerun with --overwrite without "
         "--keep-work: the old work/p.data (the earlier photos) is removed or at least not left beside a report "
         "that says no work folder was written (commands reading it would take the old photos for this capture).")
case("t43-cap-report-stages-check-edited-to-users-folder", "writer",
     CAP + " --overwrite; r=$?; for f in o/check/mine/report.json o/check/mine/figure.png "
     "o/refine/mine/normal.png; do test -e $f || { echo \"FAULT: $f (the user's) removed\"; exit 1; }; done; exit $r",
     expect="ok", setup=CAP_SETUP + "mkdir -p o/check/mine o/refine/mine\n"
     "echo '{\"my\": \"notes\"}' > o/check/mine/report.json\ncp \"$F/mask.png\" o/check/mine/figure.png\n"
     "cp " + N0 + " o/refine/mine/normal.png\n" + py("""
        import json
        r = json.load(open("o/report.json"))
        r["stages"]["check"] = "check/mine/report.json"
        json.dump(r, open("o/report.json", "w"))
        """),
     may_change=["$C/o", "$C/o/*.png", "$C/o/*.exr", "$C/o/*.npy", "$C/o/*.json", "$C/o/*.html", "$C/o/surface",
                 "$C/o/surface/*", "$C/o/check/p", "$C/o/check/p/*", "$C/o/.*", "$C/o/*/.*"],
     why="report.json's stages edited by hand to name check/mine, the user's own folder of files named like the "
         "check's (report.json, figure.png): --overwrite removes only what the capture wrote; the user's files "
         "stay (a value read from a file never chooses what is deleted).")
case("t43-cap-report-stages-work-edited-to-users-folder", "writer",
     CAP + " --overwrite; r=$?; for f in o/work/mine.data/L000.png o/work/mine.data/mask.png; do test -e $f || "
     "{ echo \"FAULT: $f (the user's) removed\"; exit 1; }; done; exit $r",
     expect="ok", setup=CAP_SETUP + "mkdir -p o/work/mine.data o/check/mine\n"
     "cp \"$F/data8/00000.data/L000.png\" \"$F/data8/00000.data/mask.png\" o/work/mine.data/\n" + py("""
        import json
        r = json.load(open("o/report.json"))
        r["stages"]["check"] = "check/mine/report.json"; r["stages"]["work_folder"] = "work/mine.data"
        json.dump(r, open("o/report.json", "w"))
        """),
     may_change=["$C/o", "$C/o/*.png", "$C/o/*.exr", "$C/o/*.npy", "$C/o/*.json", "$C/o/*.html", "$C/o/surface",
                 "$C/o/surface/*", "$C/o/check", "$C/o/check/*", "$C/o/check/*/*", "$C/o/.*", "$C/o/*/.*"],
     why="report.json's stages edited to name work/mine.data, a folder of the user's own images: the capture never "
         "wrote them; --overwrite leaves them.")
case("t43-cap-work-folder-replaced-by-link-then-keep-work-overwrite", "writer",
     CAP + " --keep-work --overwrite", expect="either",
     setup=CAPW_SETUP + "mkdir victim_evil && cp \"$F/data8/00000.data/L000.png\" victim_evil/\n"
     "rm -r o/work/p.data && ln -s ../../victim_evil o/work/p.data\n", may_change=O,
     why="The work folder replaced by a link to another folder between two runs: the rerun refuses naming it, or "
         "replaces the link; nothing is written into victim_evil (its L000.png stays).")
case("t43-cap-check-folder-replaced-by-file-then-overwrite", "writer", CAP + " --overwrite", expect="either",
     setup=CAP_SETUP + "rm -r o/check/p && echo mine > o/check/p\n", may_change=O,
     why="o/check/p replaced by a plain file: refused in one line naming it, or replaced; no traceback "
         "(NotADirectoryError) and no half-written outputs.")
case("t43-cap-normal-png-replaced-by-folder-then-overwrite", "writer", CAP + " --overwrite", expect="either",
     setup=CAP_SETUP + "rm o/normal.png && mkdir o/normal.png && echo mine > o/normal.png/note.txt\n",
     may_change=[p for p in O if p not in ("$C/o/*/*",)],
     why="normal.png replaced by a folder holding the user's note: refused in one line naming normal.png; the note "
         "stays (a folder is never removed as if it were the map).")

# ============================================================================ chains: capture outputs fed on
case("t43-chain-cap-work-mask-off-by-one-then-refine", "input",
     RF + " --data o/work/p.data --normals o/normal.png --out rf" + RFARGS, names=["mask.png"],
     setup=CAPW_SETUP + py("""
        import cv2, numpy as np
        m = cv2.imread('o/work/p.data/mask.png', 0)
        cv2.imwrite('o/work/p.data/mask.png', m[:-1])
        """), may_change=RFO,
     why="The work folder's mask cropped one row by hand (63x64 for 64x64 images): refused naming mask.png and both "
         "sizes, not refined with a mask shifted against the images.")
case("t43-chain-cap-opencv-exr-into-refine", "input",
     RF + " --data o/work/p.data --normals o/normal.exr --out rf" + RFARGS, names=["--normals"],
     setup=PH + CAP + " --keep-work --convention opencv > cap_setup.log 2>&1\n", may_change=RFO,
     why="A capture written with --convention opencv (z away from the camera) fed to refine, which reads the "
         "camera frame: refused naming --normals (most normals face away), not refined upside down.")
case("t43-chain-cap-work-as-evaluate-gt", "input", EV + " --pred pr --gt o/work/p.data", names=["--gt"],
     setup=CAPW_SETUP + "mkdir -p pr/p && cp o/normal.png pr/p/\n", may_change=deep("pr"),
     why="A capture's work folder has no ground-truth normals: evaluating against it is refused naming --gt (no "
         "ground truth), not exit 0 with an empty table.")
case("t43-chain-cap-rerender-work-with-its-map", "input",
     RR + " --data o/work/p.data --normals o/normal.png --out r" + FAST + " && test -s r/p.data/report.json -o -s "
     "r/p/report.json", expect="ok", setup=CAPW_SETUP, may_change=R,
     why="The fitted check of a capture's own work folder with its own map is the composition the docs describe: "
         "exit 0, a report written.")
case("t43-chain-cap-normal-png-8bit-then-surface", "input",
     SURF + " --normals o/normal.png --mask o/mask.png --out s" + OK_SURF, expect="ok",
     setup=CAP_SETUP + py("""
        import cv2
        n = cv2.imread('o/normal.png', -1)
        cv2.imwrite('o/normal.png', (n.astype('float64') / 257).round().astype('uint8'))
        """), may_change=S,
     why="The capture's normal.png re-saved as 8-bit (n + 1) / 2 by an editor is still a normal map (8-bit is "
         "read as such): the surface is integrated.")
case("t43-chain-cap-normal-png-8bit-codes-in-16bit-then-surface", "input",
     SURF + " --normals o/normal.png --mask o/mask.png --out s", names=["--normals"],
     setup=CAP_SETUP + py("""
        import cv2
        n = cv2.imread('o/normal.png', -1)
        cv2.imwrite('o/normal.png', (n.astype('float64') / 257).round().astype('uint16'))
        """), may_change=S,
     why="8-bit codes (0..255) saved into a 16-bit PNG decode near (-1, -1, -1): refused naming --normals (not "
         "unit / facing away), not integrated into a flat or inverted surface.")

# ============================================================================ refine / rerender: normal maps
case("t43-rf-normals-8bit-png", "input", RF + " --data u --normals n8.png --out rf" + RFARGS, expect="ok",
     setup=USER + py("""
        import cv2, os
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)
        cv2.imwrite('n8.png', (n.astype('float64') / 257).round().astype('uint8'))
        """), may_change=RFO,
     why="An 8-bit (n + 1) / 2 map is a valid starting map: refined, exit 0.")
case("t43-rf-normals-int32-tiff", "input", RF + " --data u --normals n.tif --out rf" + RFARGS,
     names=["--normals", "n.tif"], setup=USER + py("""
        import cv2, os, tifffile
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1]
        tifffile.imwrite('n.tif', n.astype('int32'), photometric='rgb')
        """), may_change=RFO,
     why="A normal map stored as signed 32-bit integers has no agreed encoding: refused naming --normals and n.tif "
         "(8 or 16-bit codes or float expected).")
case("t43-rf-normals-int16-signed-tiff", "input", RF + " --data u --normals n.tif --out rf" + RFARGS,
     names=["--normals", "n.tif"], setup=USER + py("""
        import cv2, os, tifffile, numpy as np
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1].astype(float) / 65535 * 2 - 1
        tifffile.imwrite('n.tif', np.round(n * 32767).astype('int16'), photometric='rgb')
        """), may_change=RFO,
     why="n * 32767 in a signed 16-bit TIFF (a convention of some tools) is not (n + 1) / 2: refused naming "
         "--normals, never decoded as unsigned codes.")
case("t43-rf-normals-8bit-codes-in-16bit-png", "input", RF + " --data u --normals n.png --out rf" + RFARGS,
     names=["--normals"], setup=USER + py("""
        import cv2, os
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)
        cv2.imwrite('n.png', (n.astype('float64') / 257).round().astype('uint16'))
        """), may_change=RFO,
     why="8-bit codes in a 16-bit PNG decode near (-1, -1, -1): refused naming --normals before any fit.")
case("t43-rf-normals-rgba16-opaque", "input", RF + " --data u --normals n.png --out rf" + RFARGS, expect="ok",
     setup=USER + py("""
        import cv2, os, numpy as np
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)
        cv2.imwrite('n.png', np.dstack([n, np.full(n.shape[:2], 65535, np.uint16)]))
        """), may_change=RFO,
     why="A 16-bit RGBA normal map with an opaque alpha is the RGB map: refined, exit 0.")
case("t43-rf-normals-one-px-short", "input", RF + " --data u --normals n.npy --out rf" + RFARGS,
     names=["--normals"], setup=USER + py("""
        import cv2, os, numpy as np
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1].astype(np.float32) / 65535 * 2 - 1
        l = np.linalg.norm(n, axis=2, keepdims=True); n = np.where(l > 0.5, n / np.maximum(l, 1e-6), 0)
        np.save('n.npy', n[:, :-1].astype(np.float32))
        """), may_change=RFO,
     why="A 31x32 map for 32x32 images is refused naming --normals and both sizes, not padded or resized.")
case("t43-rf-mask-one-px-taller", "input", RFU, names=["mask.png"], setup=USER + py("""
        import cv2, numpy as np
        m = cv2.imread('u/mask.png', 0)
        cv2.imwrite('u/mask.png', np.vstack([m, m[-1:]]))
        """), may_change=RFO,
     why="A 32x33 mask.png among 32x32 images is refused naming mask.png and both sizes.")
case("t43-rf-normals-name-with-tab", "input",
     RF + " --data u --normals \"$(printf 'n\\tx.png')\" --out rf" + RFARGS, expect="ok",
     setup=USER + "cp " + N0 + " \"$(printf 'n\\tx.png')\"", may_change=RFO,
     why="A normal map whose name holds a tab is a valid path: read, refined, exit 0.")
case("t43-rf-rerun-other-normals-without-overwrite", "writer",
     RF + " --data u --normals n.png --out rf" + RFARGS, names=["--overwrite"],
     setup=USER + RFU + " > rf_setup.log 2>&1\ncp \"$F/pred8/00000/normal.exr\" n.exr 2>/dev/null; cp " + N0 + " n.png\n",
     why="A second refinement of the same object into one --out, from another starting map, without --overwrite: "
         "refused naming --overwrite; the first result stays.")
case("t43-rf-out-object-replaced-by-link-then-overwrite", "writer", RFU + " --overwrite", expect="either",
     setup=USER + RFU + " > rf_setup.log 2>&1\nmkdir victim_evil && cp " + N0 + " victim_evil/normal.png\n"
     "rm -r rf/u && ln -s ../victim_evil rf/u\n", may_change=RFO,
     why="rf/u replaced by a link to another folder between two runs: refused naming it, or the link replaced; "
         "victim_evil/normal.png is never overwritten.")
case("t43-rf-out-normal-replaced-by-folder-then-overwrite", "writer", RFU + " --overwrite", expect="either",
     setup=USER + RFU + " > rf_setup.log 2>&1\nrm rf/u/normal.png && mkdir rf/u/normal.png && "
     "echo mine > rf/u/normal.png/note.txt\n", may_change=[p for p in RFO if p != "$C/rf/*/*/*"],
     why="rf/u/normal.png replaced by a folder of the user's: refused in one line naming it; the note stays.")
case("t43-rf-calibrated-lights-on-a-capture-work-folder", "input",
     RF + " --data o/work/p.data --normals o/normal.png --out rf --lights calibrated" + RFARGS, names=["--lights"],
     setup=CAPW_SETUP, may_change=RFO,
     why="--lights calibrated on a capture's work folder (no calibrated lights recorded) is refused naming --lights, "
         "not refined with made-up directions.")

# ============================================================================ rerender: reruns and outputs
case("t43-rr-known-then-fit-same-out-without-overwrite", "writer",
     RR + ' --data d --normals "$F/pred8/00000/normal.png" --out r --fit' + FAST, names=["--overwrite"],
     setup=OBJ + RRD + " > rr_setup.log 2>&1\n",
     why="A known-scene check, then --fit into the same --out without --overwrite: refused naming --overwrite; the "
         "first report stays.")
case("t43-rr-fit-then-known-overwrite-no-stale-figures", "writer",
     RRD + " --overwrite" + check_py("""
        r = json.load(open("r/d/report.json"))
        left = [n for n in ("explained.png",) if os.path.exists("r/d/" + n)]
        print("mode", r.get("mode"), "left", left)
        if left:
            print("FAULT: the fitted run's", left, "left beside the known-scene report"); raise SystemExit(1)
        """), expect="ok",
     setup=OBJ + RR + ' --data d --normals "$F/pred8/00000/normal.png" --out r --fit' + FAST + " > rr_setup.log 2>&1\n",
     may_change=R,
     why="A fitted check then a known-scene check of the same object with --overwrite: the report is replaced, and "
         "the fitted run's own figures (explained.png) do not lie beside a report of another mode.")
case("t43-rr-summary-csv-link-to-user-file-overwrite", "writer", RRD + " --overwrite", expect="either",
     setup=OBJ + RRD + " > rr_setup.log 2>&1\necho 'my,table' > mine_evil.csv\nrm r/summary.csv && "
     "ln -s ../mine_evil.csv r/summary.csv\n", may_change=R,
     why="r/summary.csv replaced by a link to the user's own table: the rerun with --overwrite refuses naming it "
         "or replaces the link; mine_evil.csv stays as it was.")
case("t43-rr-known-normals-8bit", "input",
     RR + ' --data d --normals n8.png --out r' + KNOWN + " && test -s r/d/report.json", expect="ok",
     setup=OBJ + py("""
        import cv2, os
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)
        cv2.imwrite('n8.png', (n.astype('float64') / 257).round().astype('uint8'))
        """), may_change=R,
     why="An 8-bit map is judged like the 16-bit one (its quantisation is below the check's noise): exit 0.")
case("t43-rr-known-normals-name-with-newline", "input",
     RR + " --data d --normals \"$(printf 'n\\nx.png')\" --out r" + KNOWN + " && test -s r/d/report.json",
     expect="ok", setup=OBJ + "cp " + N0 + " \"$(printf 'n\\nx.png')\"", may_change=R,
     why="A map whose name holds a newline is a valid path: judged, exit 0; the report and summary.csv quote it.")
case("t43-rr-known-mask-transposed-crop", "input", RRD, names=["mask.png"], setup=OBJ + py("""
        import cv2
        m = cv2.imread('d/mask.png', 0)
        cv2.imwrite('d/mask.png', m[:, :31].T.copy())
        """), may_change=R,
     why="A 32x31 mask (cropped and saved transposed) beside 32x32 images: refused naming mask.png and the sizes.")
case("t43-rr-fit-normals-planar-tiff", "input",
     RR + " --data u --normals n.tif --out r" + FAST + check_py("""
        a = json.load(open("r/u/report.json"))
        print(sorted(a)[:12])
        """), expect="ok", setup=USER + py("""
        import cv2, os, numpy as np, tifffile
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1]
        tifffile.imwrite('n.tif', np.ascontiguousarray(np.moveaxis(n, -1, 0)), planarconfig='separate',
                         photometric='rgb')
        """), may_change=R,
     why="A 16-bit normal map stored planar in a TIFF is the same map: judged, exit 0 (not refused as non-unit "
         "because the channels were scrambled).")

# ============================================================================ surface
case("t43-surf-normals-int32-tiff", "input", SURF + " --normals n.tif --mask " + M0 + " --out s",
     names=["--normals", "n.tif"], setup=py("""
        import cv2, os, tifffile
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1]
        tifffile.imwrite('n.tif', n.astype('int32'), photometric='rgb')
        """), may_change=S,
     why="An int32 TIFF normal map is refused naming --normals and the file.")
case("t43-surf-normals-float64-tiff", "input", SURF + " --normals n.tif --mask " + M0 + " --out s" + OK_SURF,
     expect="ok", setup=py("""
        import cv2, os, tifffile, numpy as np
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1].astype(np.float64) / 65535 * 2 - 1
        l = np.linalg.norm(n, axis=2, keepdims=True); n = np.where(l > 0.5, n / np.maximum(l, 1e-9), 0)
        tifffile.imwrite('n.tif', n, photometric='rgb')
        """), may_change=S,
     why="A float64 TIFF of unit normals (what a MATLAB or NumPy user saves) is integrated, exit 0.")
case("t43-surf-normals-planar-tiff-same-depth", "input",
     SURF + " --normals " + N0 + " --mask " + M0 + " --out s1 && " + SURF + " --normals n.tif --mask " + M0
     + " --out s" + OK_SURF + """ && $PY -c "import numpy as np,sys; a=np.load('s1/depth.npy'); b=np.load('s/depth.npy'); """
     """d=float(np.nanmax(np.abs(a-b))); print('max depth difference', d); """
     """sys.exit('FAULT: the planar TIFF gives another surface' if not d < 1e-4 else 0)" """, expect="ok",
     setup=py("""
        import cv2, os, numpy as np, tifffile
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1]
        tifffile.imwrite('n.tif', np.ascontiguousarray(np.moveaxis(n, -1, 0)), planarconfig='separate',
                         photometric='rgb')
        """), may_change=S + deep("s1"),
     why="The same 16-bit map stored planar (RRR GGG BBB) integrates into the same depth as its PNG: no channel "
         "scrambled or swapped (OpenCV's reader alone scrambles planar 16-bit TIFFs).")
case("t43-surf-normals-tiled-tiff", "input", SURF + " --normals n.tif --mask " + M0 + " --out s" + OK_SURF,
     expect="ok", setup=py("""
        import cv2, os, tifffile
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1]
        tifffile.imwrite('n.tif', n, tile=(16, 16), photometric='rgb')
        """), may_change=S,
     why="A tiled 16-bit TIFF normal map is read whole and integrated.")
case("t43-surf-normals-palette-png", "input", SURF + " --normals n.png --mask " + M0 + " --out s", expect="either",
     setup=py("""
        import cv2, os
        from PIL import Image
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1]
        Image.fromarray((n // 257).astype('uint8')).quantize(256).save('n.png')
        """), may_change=S,
     why="A normal map saved as a 256-colour palette PNG (an editor's 'optimise'): its colours are quantised "
         "normals; integrated (as the palette's colours, which are near unit) or refused naming --normals; never "
         "the palette indices taken as codes.")
case("t43-surf-mask-transposed-nonsquare", "input", SURF + " --normals n.npy --mask m.png --out s",
     names=["--mask"], setup=py("""
        import cv2, os, numpy as np
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)[..., ::-1].astype(np.float32) / 65535 * 2 - 1
        l = np.linalg.norm(n, axis=2, keepdims=True); n = np.where(l > 0.5, n / np.maximum(l, 1e-6), 0)
        np.save('n.npy', n[:, :24].astype(np.float32))
        m = cv2.imread(os.environ['F'] + '/data8/00000.data/mask.png', 0)[:, :24]
        cv2.imwrite('m.png', m.T.copy())
        """), may_change=S,
     why="A 32x24 map with its mask saved transposed (24x32): refused naming --mask and both sizes.")
case("t43-surf-rerun-other-mask-without-overwrite", "writer",
     SURF + " --normals " + N0 + " --mask m.png --out s", names=["--overwrite"],
     setup=SURF + " --normals " + N0 + " --mask " + M0 + " --out s > s_setup.log 2>&1\n" + py("""
        import cv2, os, numpy as np
        m = cv2.imread(os.environ['F'] + '/data8/00000.data/mask.png', 0)
        cv2.imwrite('m.png', cv2.erode(m, np.ones((3, 3), np.uint8)))
        """),
     why="A second surface from another mask into the same --out without --overwrite is refused naming "
         "--overwrite; the first depth stays.")
case("t43-surf-rerun-other-mask-overwrite-report-says-it", "writer",
     SURF + " --normals " + N0 + " --mask m.png --out s --overwrite" + OK_SURF + check_py("""
        r = json.dumps(json.load(open("s/report.json")))
        print("m.png in report:", "m.png" in r)
        if "m.png" not in r and "mask.png" in r:
            print("FAULT: s/report.json still names the first run's mask"); raise SystemExit(1)
        """), expect="ok",
     setup=SURF + " --normals " + N0 + " --mask " + M0 + " --out s > s_setup.log 2>&1\n" + py("""
        import cv2, os, numpy as np
        m = cv2.imread(os.environ['F'] + '/data8/00000.data/mask.png', 0)
        cv2.imwrite('m.png', cv2.erode(m, np.ones((3, 3), np.uint8)))
        """), may_change=S,
     why="With --overwrite the second run's report describes the second run (its mask m.png), not the first's.")
case("t43-surf-normals-name-newline-and-tab", "input",
     SURF + " --normals \"$(printf 'n\\n\\tx.png')\" --mask " + M0 + " --out s" + OK_SURF, expect="ok",
     setup="cp " + N0 + " \"$(printf 'n\\n\\tx.png')\"", may_change=S,
     why="A map whose name holds a newline and a tab is a valid path: integrated, exit 0.")
case("t43-surf-normals-directx-green-flipped", "input",
     SURF + " --normals n.png --mask " + M0 + " --out s", expect="either", setup=py("""
        import cv2, os
        n = cv2.imread(os.environ['F'] + '/pred8/00000/normal.png', -1)
        n[..., 1] = 65535 - n[..., 1]  # BGR: green is index 1
        cv2.imwrite('n.png', n)
        """), may_change=S,
     why="A DirectX-style map (green flipped: y down, z still toward the camera) is a valid field of unit vectors; "
         "integrated (the surface mirrored in y) or refused naming --normals where its curl says it is not "
         "integrable in this frame; no traceback.")

# ============================================================================ evaluate
case("t43-eval-pred-int32-tiff-single", "input", EV + ' --pred p --gt "$F/data/00000.data"', names=["--pred"],
     setup="mkdir -p p/00000\n" + py("""
        import cv2, os, tifffile
        n = cv2.imread(os.environ['F'] + '/pred/00000/normal.png', -1)[..., ::-1]
        tifffile.imwrite('p/00000/normal.tif', n.astype('int32'), photometric='rgb')
        """), may_change=P,
     why="A prediction stored as an int32 TIFF is refused naming --pred and the file; nothing written.")
case("t43-eval-pred-planar-tiff-same-score", "input",
     EV + ' --pred p --gt "$F/data/00000.data"' + OK_EV + " && " + EV + ' --pred q --gt "$F/data/00000.data"'
     + """ && $PY -c "import json,sys; a=json.load(open('p/metrics.json'))['mean_mae_deg']; """
     """b=json.load(open('q/metrics.json'))['mean_mae_deg']; print(a, b); """
     """sys.exit('FAULT: planar TIFF scored differently' if abs(a-b) > 0.01 else 0)" """, expect="ok",
     setup="mkdir -p p/00000 q/00000 && cp \"$F/pred/00000/normal.png\" q/00000/\n" + py("""
        import cv2, os, numpy as np, tifffile
        n = cv2.imread(os.environ['F'] + '/pred/00000/normal.png', -1)[..., ::-1]
        tifffile.imwrite('p/00000/normal.tif', np.ascontiguousarray(np.moveaxis(n, -1, 0)), planarconfig='separate',
                         photometric='rgb')
        """), may_change=P + deep("q"),
     why="A prediction stored as a planar 16-bit TIFF scores as its PNG does (same vectors), not as scrambled "
         "channels.")
case("t43-eval-pred-8bit-png", "input", EV + ' --pred p --gt "$F/data/00000.data"' + OK_EV, expect="ok",
     setup="mkdir -p p/00000\n" + py("""
        import cv2, os
        n = cv2.imread(os.environ['F'] + '/pred/00000/normal.png', -1)
        cv2.imwrite('p/00000/normal.png', (n.astype('float64') / 257).round().astype('uint8'))
        """), may_change=P,
     why="An 8-bit (n + 1) / 2 prediction is scored, exit 0.")
case("t43-eval-gt-mask-one-px-wider", "input", EV + ' --pred p --gt g', names=["mask.png"],
     setup=PRED + 'cp -r "$F/data/00000.data" g\n' + py("""
        import cv2, numpy as np
        m = cv2.imread('g/mask.png', 0)
        cv2.imwrite('g/mask.png', np.hstack([m, m[:, -1:]]))
        """), may_change=P,
     why="A ground-truth mask 33x32 beside a 32x32 normal.tif is refused naming mask.png, not scored with a "
         "shifted mask.")
case("t43-eval-rerun-other-gt-without-overwrite", "writer", EV + ' --pred p --gt "$F/data8"', names=["--overwrite"],
     setup=PRED + EVP + " > ev_setup.log 2>&1\n",
     why="A second evaluation of the same predictions against another ground truth, without --overwrite: refused "
         "naming --overwrite; the first metrics stay.")
case("t43-eval-overwrite-after-prediction-removed", "writer",
     EVP + " --overwrite --allow-missing" + check_py("""
        m = json.load(open("p/metrics.json"))
        print(sorted(m["objects"]), m["missing"])
        if "00002" in m["objects"] or os.path.exists("p/00002/error_map.png"):
            print("FAULT: 00002 (no prediction now) still scored or its old error map kept"); raise SystemExit(1)
        """), expect="ok",
     setup=PRED + EVP + " > ev_setup.log 2>&1\nrm p/00002/normal.*\n", may_change=P,
     why="After 00002's prediction is removed, a rerun with --overwrite --allow-missing lists it as missing and "
         "removes its earlier error map (docs: a map of an object no longer scored goes).")
case("t43-eval-metrics-json-key-removed-then-overwrite", "writer", EVP + " --overwrite", names=["metrics.json"],
     setup=PRED + EVP + " > ev_setup.log 2>&1\n" + py("""
        import json
        m = json.load(open('p/metrics.json')); del m['gt']
        json.dump(m, open('p/metrics.json', 'w'))
        """),
     why="A metrics.json edited by hand so that it no longer holds the evaluation's keys is not recognisably ours: "
         "refused naming metrics.json even with --overwrite; nothing replaced.")
case("t43-eval-error-map-replaced-by-folder-then-overwrite", "writer", EVP + " --overwrite", expect="either",
     setup=PRED + EVP + " > ev_setup.log 2>&1\nrm p/00001/error_map.png && mkdir p/00001/error_map.png && "
     "echo mine > p/00001/error_map.png/note.txt\n", may_change=[p for p in P if p != "$C/p/*/*/*"],
     why="An error map replaced by a folder of the user's: refused in one line naming it, or the others written "
         "and that object failed; the note stays, no traceback.")
case("t43-eval-pred-folder-name-with-newline", "input",
     EV + " --pred \"$(printf 'p\\nq')\" --gt \"$F/data\" && test -s \"$(printf 'p\\nq')/metrics.json\"",
     expect="ok", setup="cp -r \"$F/pred\" \"$(printf 'p\\nq')\"", may_change=deep("p\nq"),
     why="A prediction folder whose name holds a newline is a valid path: scored, exit 0.")
case("t43-eval-gt-normal-tif-y-flipped-same-pred", "input",
     EV + " --pred p --gt g" + OK_EV + check_py("""
        m = json.load(open("p/metrics.json"))
        print("mae", m["mean_mae_deg"])
        """), expect="ok", setup=PRED + 'cp -r "$F/data/00000.data" g\n' + py("""
        import cv2
        n = cv2.imread('g/normal.tif', -1)
        n[..., 1] = 65535 - n[..., 1]
        cv2.imwrite('g/normal.tif', n)
        """), may_change=P,
     why="A ground truth in the other handedness (y flipped) is still a map of unit vectors: scored (a large error "
         "the table shows), exit 0; no traceback.")
case("t43-eval-pred-object-replaced-by-file-between-runs", "writer", EVP + " --overwrite", expect="refuse",
     names=["00001"], setup=PRED + EVP + " > ev_setup.log 2>&1\nrm -r p/00001 && echo mine > p/00001\n",
     may_change=[p for p in P if p != "$C/p/00001"],
     why="p/00001 turned into a plain file between two runs: that object has no prediction (or is refused by name); "
         "exit non-zero naming 00001 (missing without --allow-missing); the user's file stays.")
