"""Sweep 42, part q: the USER-PHOTO and PHYSICAL-CHECK side (orchestrate.capture, validate.rerender,
validate.refine, orchestrate.surface, unips.evaluate and the reports / outputs they write), from angles the earlier
sweeps used little:

- the process environment: HOME unset or unwritable, TMPDIR missing / a file / unwritable, OMP_NUM_THREADS junk,
  LANG=C / LC_ALL=C with unicode names, PYTHONIOENCODING=ascii, COLUMNS tiny or junk, FORCE_COLOR (a refusal must
  still name the flag), stdin / stdout / stderr closed, stdout or stderr piped into a reader that quits (SIGPIPE);
- resource limits: `ulimit -f` (file size: Python ignores SIGXFSZ, so a write fails with EFBIG) and `ulimit -n`;
- names longer than 255 bytes, exactly 255 bytes, NFC / NFD twins;
- mtimes in the future (an --overwrite must not keep a "newer" stale file), sparse files with a 2 GB tail;
- photos of another colour type or coding: CMYK JPEG, progressive JPEG, PNG with a gAMA chunk or an ICC profile,
  interlaced PNG, grey 16-bit PNG among RGB JPEGs, 1-bit photos;
- masks and maps saved by an image editor: palette PNG, 16-bit grey, 1-bit, a 1-px white border, a grey normal map;
- a second run after the first was killed with SIGKILL at several points;
- outputs that overlap inputs through `..`, `/./` or trailing slashes.

The case runner is root here: chmod 000 stops nothing, so unreadable / unwritable places are made with /proc
(nobody can create files there) and files in place of folders.
Cases whose command adds its own check print a line starting with `FAULT:` and exit so that the harness flags it.
A capture of the 8 fixture photos with the fixtures' mask, without refinement, takes about 15 s on 2 cores.
"""
from __future__ import annotations

import textwrap


def py(code: str) -> str:
    """A bash heredoc running `code` with the toolkit's python in $C."""
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


PRE = """
import glob, io, json, os, shutil, struct, zlib, unicodedata
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
EV = "$PY -m unips.evaluate"
EVP = EV + ' --pred p --gt "$F/data"'
PRED = 'cp -r "$F/pred" p\n'
"""Setup: p/, a copy of the 3-object predictions of $F/data."""


def deep(d: str) -> list[str]:
    return [f"$C/{d}", f"$C/{d}/*", f"$C/{d}/*/*", f"$C/{d}/*/*/*", f"$C/{d}/*/*/*/*", f"$C/{d}/.*",
            f"$C/{d}/*/.*"]


O = deep("o")
R = deep("r")
RF = deep("rf")
P = deep("p")
OK_CAP = " && test -s o/normal.png && test -s o/report.json"
OK_SURF = " && test -s o/depth.npy && test -s o/report.json"
OK_EV = " && test -s p/metrics.json && test -s p/metrics.csv"


def left(path: str, what: str) -> str:
    """Command tail: a refusal that left `path` behind exits 0 with a FAULT line (flagged exit0)."""
    return f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r'


def taken_or_named(cmd: str, name: str, check: str) -> str:
    """Command: `cmd` must either refuse naming `name` (a right answer) or succeed with `check` holding; anything
    else prints a FAULT line and exits 1 (expect "ok": flagged as failed)."""
    return (f"{cmd} > out.log 2>&1; r=$?; cat out.log; if [ $r != 0 ]; then grep -qi -- '{name}' out.log && exit 0; "
            f"echo 'FAULT: refused without naming {name}'; exit 1; fi; {check}")


def killed(cmd: str, after_s: float) -> str:
    """Command head: `cmd` started, killed with SIGKILL (its whole process group) after `after_s` seconds."""
    return (f"set -m; ( {cmd} ) >/dev/null 2>&1 & p=$!; sleep {after_s}; kill -KILL -$p 2>/dev/null; "
            "wait $p 2>/dev/null; set +m; ")


def report_images(n: int) -> str:
    """Command tail: o/report.json must say `n` photos were read."""
    return (f"""$PY -c "import json,sys; n=json.load(open('o/report.json'))['input']['images']; """
            f"""print('images', n); sys.exit(0 if n == {n} else print('FAULT: report says', n, 'photos, not {n}') or 1)" """)


SAME_MASK = (""" && $PY -c "import cv2,sys,os; a=cv2.imread(os.environ['F']+'/mask.png',0)>127; """
             """b=cv2.imread('o/mask.png',0)>127; d=int((a!=b).sum()); print('mask pixels differing', d); """
             """sys.exit('FAULT: o/mask.png is not the mask given' if d > 8 else 0)" """)
"""Command tail: o/mask.png must be the fixtures' mask (a few pixels of slack)."""

JSON_OK = ("""; r=$?; for f in {files}; do [ -e "$f" ] || continue; $PY -c "import json,sys; json.load(open(sys.argv[1]))" "$f" """
           """|| {{ echo "FAULT: $f left cut short"; exit 0; }}; done; exit $r""")
"""Command tail: each of {files} that exists must parse as JSON (a refusal that leaves a torn file is flagged)."""


def json_ok(*files: str) -> str:
    return JSON_OK.format(files=" ".join(files))


LONG255 = "$(printf 'n%.0s' $(seq 255))"
LONG300 = "$(printf 'n%.0s' $(seq 300))"

CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


# ============================================================================ the process environment
case("q42-cap-home-unset", "engine", "env -u HOME " + CAP + OK_CAP, expect="ok", setup=PH, may_change=O,
     why="A capture needs nothing from HOME (a cron job or a container without it): it runs and writes its outputs.")
case("q42-cap-home-unwritable", "engine", "HOME=/proc/nohome XDG_CACHE_HOME=/proc/nocache " + CAP + OK_CAP,
     expect="ok", setup=PH, may_change=O,
     why="A HOME nobody can write (matplotlib / torch caches) is no reason to fail: caches fall back, outputs written.")
case("q42-cap-tmpdir-missing", "engine", 'TMPDIR="$C/no-such-tmp" ' + CAP + OK_CAP, expect="ok", setup=PH,
     may_change=O, why="A TMPDIR that does not exist: Python's tempfile falls back; the capture still runs.")
case("q42-rr-tmpdir-proc", "engine", "TMPDIR=/proc " + RRU + " && test -s r/u/report.json", expect="ok",
     setup=USER, may_change=R, timeout=120,
     why="A TMPDIR nobody can write into (/proc): the check falls back to another temp folder and reports.")
case("q42-cap-omp-threads-abc", "engine", "OMP_NUM_THREADS=abc " + CAP + OK_CAP, expect="ok", setup=PH,
     may_change=O, why="OMP_NUM_THREADS=abc in the environment is a harmless warning at most, not a crash.")
case("q42-surf-lc-all-c-unicode-paths", "engine",
     'LC_ALL=C LANG=C ' + SURF + ' --normals "$C/normäl ✓/n.png" --mask "$C/normäl ✓/m.png" --out "$C/außen ✓"'
     ' && test -s "$C/außen ✓/depth.npy"', expect="ok",
     setup='mkdir "normäl ✓"; cp "$F/pred8/00000/normal.png" "normäl ✓/n.png"; cp "$F/data8/00000.data/mask.png" "normäl ✓/m.png"\n',
     may_change=["$C/außen ✓", "$C/außen ✓/*"],
     why="In the C locale unicode paths are still bytes a user typed: the surface is written where asked.")
case("q42-cap-lc-all-c-unicode-photo-names", "engine", "LC_ALL=C LANG=C " + CAP + OK_CAP + " && " + report_images(8),
     expect="ok", setup=PH + 'cd p; i=0; for f in *.jpg; do mv "$f" "Äpfel-ß-📷-$i.jpg"; i=$((i+1)); done\n',
     may_change=O, why="Photo names in UTF-8 under LC_ALL=C: all 8 photos read, report.json / report.html written.")
case("q42-ev-pythonioencoding-ascii-unicode-object", "engine",
     'PYTHONIOENCODING=ascii ' + EV + ' --pred p --gt "g/kätze ✓.data"' + OK_EV, expect="ok",
     setup='mkdir g p; cp -r "$F/data/00000.data" "g/kätze ✓.data"; cp -r "$F/pred/00000" "p/kätze ✓"\n',
     may_change=P,
     why="An object named with non-ASCII letters and an ASCII-only stdout: the table prints (escaped) and the "
         "metrics are written, no UnicodeEncodeError.")
case("q42-rr-pythonioencoding-ascii-unicode-out", "engine",
     'PYTHONIOENCODING=ascii ' + RRU.replace("--out r", '--out "rë ✓"') + ' && test -s "rë ✓/u/report.json"',
     expect="ok", setup=USER, may_change=["$C/rë ✓", "$C/rë ✓/*", "$C/rë ✓/*/*"],
     why="Printing a non-ASCII output path to an ASCII stdout must not crash the check after its work is done.")
case("q42-cap-columns-5-bad-max-side", "message", "COLUMNS=5 " + CAP + " --max-side abc", names=["--max-side", "abc"],
     setup=PH, may_change=O,
     why="A 5-column terminal must not wrap the one refusal line so that the flag and value are cut apart.")
case("q42-rr-columns-abc-bad-spp", "message", "COLUMNS=abc " + RRD + " --spp x1", names=["--spp", "x1"], setup=OBJ,
     may_change=R, why="COLUMNS=abc (junk) must not turn a plain argument error into a crash of the help formatter.")
case("q42-surf-force-color-bad-k", "message", "FORCE_COLOR=1 TERM=xterm-256color " + SURF0 + " --k abc",
     names=["--k", "abc"], may_change=O,
     why="With colour forced on, the refusal must still hold the flag name and value as plain text (not split by "
         "escape codes).")
case("q42-cap-cwd-deleted", "engine",
     'mkdir gone && cd gone && rmdir "$C/gone" && ' + CAP.replace("--input p --out o", '--input "$C/p" --out "$C/o"')
     + ' && test -s "$C/o/normal.png"', expect="either", setup=PH, may_change=O,
     why="Run from a folder deleted under it with absolute paths: works, or one clear line; no traceback.")

# ============================================================================ standard streams
case("q42-cap-stdin-stdout-closed", "engine",
     "( " + CAP + " <&- >&- ) 2> err.log; cat err.log; test -s o/normal.png && test -s o/report.json", expect="ok",
     setup=PH, may_change=O + ["$C/err.log"],
     why="A capture started with stdin and stdout closed (a daemon) still writes every output.")
case("q42-ev-stdout-closed", "engine", "( " + EVP + " >&- ) 2> err.log; cat err.log; test -s p/metrics.json",
     expect="ok", setup=PRED, may_change=P + ["$C/err.log"],
     why="The metrics table cannot be printed to a closed stdout, but metrics.json must still be written.")
case("q42-surf-stderr-closed", "engine", SURF0 + " 2>&-" + OK_SURF, expect="ok", may_change=O,
     why="With stderr closed the surface is still integrated and written.")
case("q42-ev-stdout-reader-quits", "engine",
     "set +o pipefail; " + EVP + " 2> err.log | : ; sleep 0.5; cat err.log; test -s p/metrics.json; "
     "! grep -q 'Traceback\\|BrokenPipe' err.log || { echo 'FAULT: broken pipe shown as a crash'; exit 1; }",
     expect="ok", setup=PRED, may_change=P + ["$C/err.log"],
     why="`evaluate | :` (a reader that quits at once): metrics.json written; no BrokenPipeError traceback.")
case("q42-cap-stderr-into-head-then-overwrite", "signal",
     CAP + " 2>&1 | head -1; sleep 1; " + CAP + " --overwrite" + OK_CAP, expect="ok", setup=PH, may_change=O,
     why="A capture whose progress went into `head -1` may die of the broken pipe; a run with --overwrite after it "
         "always completes from whatever was left.")
# ============================================================================ resource limits
case("q42-cap-ulimit-f-2k", "engine", "( ulimit -f 2; " + CAP + " )" + json_ok("o/report.json"),
     names=["large"], setup=PH, may_change=O,
     why="Files limited to 2 KiB: the first big write fails (EFBIG, SIGXFSZ is ignored by Python): one clear "
         "line, non-zero, and no report.json left cut short.")
case("q42-cap-ulimit-f-then-rerun", "engine",
     "( ulimit -f 2; " + CAP + " ) > first.log 2>&1; " + CAP + " --overwrite" + OK_CAP, expect="ok", setup=PH,
     may_change=O + ["$C/first.log"],
     why="After a capture stopped by a full disk / size limit, a rerun with --overwrite completes.")
case("q42-ev-ulimit-f-1k", "engine", "( ulimit -f 1; " + EVP + " )" + json_ok("p/metrics.json"),
     names=["large"], setup=PRED, may_change=P,
     why="Error maps cannot be written under a 1 KiB file limit: one clear line, no half metrics.json.")
case("q42-rr-ulimit-f-1k", "engine", "( ulimit -f 1; " + RRU + " )" + json_ok("r/u/report.json"),
     names=["large"], setup=USER, may_change=R,
     why="The check's figure cannot be written under a 1 KiB file limit: one clear line, no half report.json.")
case("q42-rf-ulimit-f-1k", "engine", "( ulimit -f 1; " + RFU + " )" + json_ok("rf/u/refine_report.json"),
     names=["large"], setup=USER, may_change=RF,
     why="The refined map cannot be written under a 1 KiB file limit: one clear line, no torn report.")
case("q42-cap-ulimit-n-24", "engine", "( ulimit -n 24; " + CAP + " )", expect="either", setup=PH, may_change=O,
     why="With 24 file descriptors the capture works or says in one line it ran out of files; no traceback.")
# ============================================================================ long names, NFC / NFD twins
case("q42-cap-out-name-300-bytes", "input", CAP.replace("--out o", f'--out "{LONG300}"'), names=["--out"],
     setup=PH, why="An output folder name longer than 255 bytes cannot exist: one line naming --out.")
case("q42-cap-out-name-255-bytes", "writer", CAP.replace("--out o", f'--out "{LONG255}"')
     + f' && test -s "{LONG255}/normal.png"', expect="ok", setup=PH,
     may_change=["$C/n*", "$C/n*/*", "$C/n*/*/*", "$C/.*"],
     why="A 255-byte folder name is legal: the capture writes there (no sibling temp name that grows past 255).")
case("q42-cap-input-name-250-bytes-keep-work", "writer",
     CAPX + ' --input "$(printf "p%.0s" $(seq 250))" --out o --mask "$F/mask.png" --keep-work --max-side 32',
     expect="either", setup='cp -r "$F/photos" "$(printf "p%.0s" $(seq 250))"\n', may_change=O,
     why="The work folder <input name>.data would be 255 bytes: it works, or one clear line; never a traceback.")
case("q42-surf-out-name-300-bytes", "input", SURF0.replace("--out o", f'--out "{LONG300}"'), names=["--out"],
     why="An output name past 255 bytes: one line naming --out, before integrating.")
case("q42-surf-out-name-255-bytes", "writer", SURF0.replace("--out o", f'--out "{LONG255}"')
     + f' && test -s "{LONG255}/depth.npy"', expect="ok", may_change=["$C/n*", "$C/n*/*", "$C/.*"],
     why="A 255-byte output folder is legal: depth, mesh and report are written there.")
case("q42-ev-pred-name-300-bytes", "input", EV + f' --pred "{LONG300}" --gt "$F/data"', names=["--pred"],
     why="A --pred name that cannot exist (over 255 bytes): one line naming --pred.")
case("q42-ev-pred-nfd-gt-nfc", "input", EV + ' --pred p --gt "g/$(printf "caf\\xc3\\xa9").data"',
     names=["caf"],
     setup='mkdir g p; cp -r "$F/data/00000.data" "g/$(printf "caf\\xc3\\xa9").data"; '
           'cp -r "$F/pred/00000" "p/$(printf "cafe\\xcc\\x81")"\n', may_change=P,
     why="The prediction is named in NFD, the ground truth in NFC: on Linux these are two names; the missing "
         "prediction is named (or matched knowingly), never an exit 0 that scores nothing.")
case("q42-ev-pred-nfc-and-nfd-twins", "input",
     EV + ' --pred p --gt "g/$(printf "caf\\xc3\\xa9").data" && ' + py("""
        import json
        m = json.load(open("p/metrics.json"))
        s = json.dumps(m)
        print(s[:400])
        want = json.load(open("ref.json"))
        import sys
        sys.exit(0 if abs(float(m["mean_mae_deg"] if "mean_mae_deg" in m else 0) - float(want.get("mean_mae_deg", 0))) < 1e-6
                 else "FAULT: the NFD twin was scored instead of the NFC prediction")
        """),
     expect="ok",
     setup='mkdir g p q; cp -r "$F/data/00000.data" "g/$(printf "caf\\xc3\\xa9").data"; '
           'cp -r "$F/pred/00000" "p/$(printf "caf\\xc3\\xa9")"; cp -r "$F/pred/00001" "p/$(printf "cafe\\xcc\\x81")"; '
           'cp -r "$F/pred/00000" "q/$(printf "caf\\xc3\\xa9")"; $PY -m unips.evaluate --pred q --gt '
           '"g/$(printf "caf\\xc3\\xa9").data" > /dev/null 2>&1; cp q/metrics.json ref.json\n',
     may_change=P,
     why="A pred folder holding NFC and NFD twins of one object: the byte-exact name is scored (same metrics as "
         "with the twin absent).")

# ============================================================================ mtimes, sparse files
case("q42-cap-outputs-future-mtime-then-overwrite", "writer",
     CAP + " --overwrite --convention opencv && ! cmp -s o/normal.png first_normal.png || "
     "{ echo 'FAULT: normal.png with a future mtime was kept'; exit 1; }", expect="ok",
     setup=CAP_SETUP + "cp o/normal.png first_normal.png; find o -exec touch -d '2100-01-01' {} +\n", may_change=O,
     why="Outputs dated 2100 (a camera clock, a restored backup): --overwrite with another convention replaces "
         "them; nothing is skipped as 'newer'.")
case("q42-ev-metrics-future-mtime-map-changed", "writer",
     EVP + " --overwrite && ! cmp -s p/metrics.json first.json || "
     "{ echo 'FAULT: metrics.json with a future mtime kept after the map changed'; exit 1; }", expect="ok",
     setup=PRED + EVP + " > /dev/null 2>&1; cp p/metrics.json first.json; "
     "cp p/00001/normal.png p/00000/normal.png; rm -f p/00000/normal.exr; find p -name 'metrics*' -exec touch -d '2100-01-01' {} +\n",
     may_change=P, why="A re-evaluation with --overwrite after a map changed must recompute, whatever the mtimes say.")
case("q42-cap-photos-mtime-future-and-epoch", "input", CAP + OK_CAP + " && " + report_images(8), expect="ok",
     setup=PH + "touch -d '2100-01-01' p/photo0[0-3].jpg; touch -d @0 p/photo0[4-7].jpg\n", may_change=O,
     why="Photo mtimes in 2100 and 1970 (camera clock unset) change nothing: all 8 read.")
case("q42-surf-rerun-after-normals-touched-future", "writer",
     SURF0 + " --overwrite --k 0 && ! cmp -s o/report.json first.json || { echo 'FAULT: report not rewritten'; exit 1; }",
     expect="ok", setup=SURF0 + " > /dev/null 2>&1; cp o/report.json first.json; find o -exec touch -d '2100-01-01' {} +\n",
     may_change=O, why="--overwrite with another --k rewrites the report even though the old one is dated 2100.")
case("q42-surf-mask-sparse-2gb-tail", "input", SURF + ' --normals ' + N0 + ' --mask m.png --out o', expect="either",
     setup='cp "$F/data8/00000.data/mask.png" m.png; truncate -s 2G m.png\n', may_change=O, timeout=60,
     why="A mask PNG followed by 2 GB of (sparse) zeros: read as the PNG it is or refused in one line; no "
         "2 GB read into memory, no hang.")
case("q42-cap-mask-sparse-2gb-tail", "input", CAPX + ' --input p --out o --mask m.png', expect="either",
     setup=PH + 'cp "$F/mask.png" m.png; truncate -s 2G m.png\n', may_change=O, timeout=90,
     why="The capture's mask with a 2 GB sparse tail: taken or refused in one line, no hang, no memory blow-up.")
case("q42-rr-normals-npy-sparse-4gb", "input",
     '$PY -m validate.rerender --data u --normals n.npy --out r' + FAST, names=["n.npy"],
     setup=USER + py("""
        import numpy as np
        np.lib.format.open_memmap("n.npy", mode="w+", dtype="<f4", shape=(32768, 32768, 1))
        """), may_change=R, timeout=60,
     why="A 4 GB sparse .npy of the wrong shape (32768 x 32768 x 1) for a 32-px object: refused naming the file, "
         "without reading 4 GB first.")

# ============================================================================ photos of mixed colour type / coding
case("q42-cap-one-cmyk-jpeg-among-rgb", "input",
     taken_or_named(CAP, "photo03", "test -s o/normal.png && " + report_images(8)),
     expect="ok", setup=setup_py("""
        im = Image.open("p/photo03.jpg").convert("CMYK"); im.save("p/photo03.jpg", quality=95)
        """), may_change=O + ["$C/out.log"],
     why="One CMYK JPEG (a print-shop export) among RGB: converted to RGB correctly or refused naming it.")
case("q42-cap-all-cmyk-jpeg", "input", taken_or_named(CAP, "cmyk", "test -s o/normal.png && " + report_images(8)),
     expect="ok", setup=setup_py("""
        for f in photos:
            Image.open(f).convert("CMYK").save(f, quality=95)
        """), may_change=O + ["$C/out.log"],
     why="All photos CMYK JPEG: read with the right colours (Adobe inverted CMYK handled) or refused saying CMYK.")
case("q42-cap-progressive-jpeg-photos", "input", CAP + OK_CAP + " && " + report_images(8), expect="ok",
     setup=setup_py("""
        for f in photos:
            Image.open(f).save(f, quality=95, progressive=True)
        """), may_change=O,
     why="Progressive JPEGs (what many web tools write) are ordinary photos: all 8 read.")
case("q42-cap-png-gamma-1-photos", "input", taken_or_named(CAP, "gama", "test -s o/normal.png && " + report_images(8)),
     expect="ok", setup=setup_py("""
        for i, f in enumerate(photos):
            Image.open(f).save(f"p/photo{i:02d}.png", gamma=1.0) if False else None
            im = Image.open(f); b = io.BytesIO(); im.save(b, "PNG"); data = b.getvalue()
            chunk = b"gAMA" + struct.pack(">I", 100000)
            g = struct.pack(">I", 4) + chunk + struct.pack(">I", zlib.crc32(chunk) & 0xffffffff)
            data = data[:33] + g + data[33:]
            open(f[:-4] + ".png", "wb").write(data); os.remove(f)
        """), may_change=O + ["$C/out.log"],
     why="PNGs declaring gAMA 1.0 (linear): honoured or refused naming the chunk; never a crash.")
case("q42-cap-png-icc-srgb-photos", "input", CAP + OK_CAP + " && " + report_images(8), expect="ok",
     setup=setup_py("""
        from PIL import ImageCms
        icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
        for f in photos:
            Image.open(f).save(f[:-4] + ".png", icc_profile=icc); os.remove(f)
        """), may_change=O, why="PNG photos with an embedded sRGB ICC profile (iCCP chunk) are plain sRGB: all 8 read.")
case("q42-cap-interlaced-png-photos", "input", CAP + OK_CAP + " && " + report_images(8), expect="ok",
     setup=setup_py("""
        for f in photos:
            im = cv2.imread(f); cv2.imwrite(f[:-4] + ".png", im); os.remove(f)
        import subprocess
        """) + 'for f in p/*.png; do $PY -c "from PIL import Image; import sys; Image.open(sys.argv[1]).save(sys.argv[1], interlace=1)" "$f" || true; done\n',
     may_change=O, why="Interlaced (Adam7) PNG photos are ordinary photos: all 8 read.")
case("q42-cap-grey16-png-among-rgb-jpeg", "input",
     taken_or_named(CAP, "photo06", "test -s o/normal.png && " + report_images(8)), expect="ok",
     setup=setup_py("""
        g = cv2.imread("p/photo06.jpg", cv2.IMREAD_GRAYSCALE).astype(np.uint16) * 257
        cv2.imwrite("p/photo06.png", g); os.remove("p/photo06.jpg")
        """), may_change=O + ["$C/out.log"],
     why="One 16-bit grey PNG among 8-bit RGB JPEGs (two codings and two colour types at once): handled "
         "consistently or refused naming it.")
# ============================================================================ masks and maps edited by hand
case("q42-cap-mask-palette-png", "input", CAPX + " --input p --out o --mask m.png" + OK_CAP + SAME_MASK,
     expect="ok", setup=PH + py("""
        from PIL import Image
        import numpy as np, os
        a = np.array(Image.open(os.environ["F"] + "/mask.png"))
        im = Image.fromarray(np.where(a > 127, 0, 1).astype("uint8"), "P")
        im.putpalette([255, 255, 255, 0, 0, 0] + [0] * 762)
        im.save("m.png")
        """), may_change=O,
     why="A palette mask whose index 0 is WHITE (an editor's palette order): read by colour, not by index; the "
         "mask written is the one given.")
case("q42-cap-mask-16bit-grey", "input", CAPX + " --input p --out o --mask m.png" + OK_CAP + SAME_MASK,
     expect="ok", setup=PH + py("""
        import cv2, numpy as np, os
        a = cv2.imread(os.environ["F"] + "/mask.png", 0)
        cv2.imwrite("m.png", np.where(a > 127, 65535, 0).astype(np.uint16))
        """), may_change=O, why="A 16-bit grey mask (0 / 65535) is the same mask: taken, the written mask matches.")
case("q42-cap-mask-16bit-holding-0-255", "input", CAPX + " --input p --out o --mask m.png", expect="either",
     setup=PH + py("""
        import cv2, numpy as np, os
        a = cv2.imread(os.environ["F"] + "/mask.png", 0)
        cv2.imwrite("m.png", np.where(a > 127, 255, 0).astype(np.uint16))
        """), may_change=O,
     why="A 16-bit mask holding 0 / 255 (8-bit values in a 16-bit file): read as that mask or refused in one line; "
         "never an empty mask taken silently.")
case("q42-cap-mask-1bit", "input", CAPX + " --input p --out o --mask m.png" + OK_CAP + SAME_MASK, expect="ok",
     setup=PH + py("""
        from PIL import Image
        import os
        Image.open(os.environ["F"] + "/mask.png").convert("1").save("m.png")
        """), may_change=O, why="A 1-bit PNG mask is a mask: taken, the written mask matches.")
case("q42-cap-mask-1px-white-border", "input", CAPX + " --input p --out o --mask m.png", expect="either",
     setup=PH + py("""
        import cv2, os
        a = cv2.imread(os.environ["F"] + "/mask.png", 0)
        a[0, :] = a[-1, :] = a[:, 0] = a[:, -1] = 255
        cv2.imwrite("m.png", a)
        """), may_change=O,
     why="A mask with a 1-px white frame (an editor's selection border): taken or refused in one line; no crash.")
case("q42-cap-mask-jpeg-saved-grey-noise", "input", CAPX + " --input p --out o --mask m.jpg", expect="either", setup=PH + py("""
        import cv2, os
        a = cv2.imread(os.environ["F"] + "/mask.png", 0)
        cv2.imwrite("m.jpg", a, [cv2.IMWRITE_JPEG_QUALITY, 70])
        """), may_change=O,
     why="A mask re-saved as JPEG (ringing greys near the edge): thresholded to the same mask, or refused in one "
         "line that says to save it as PNG (what the toolkit does); never a traceback.")
case("q42-surf-mask-palette-white-index-0", "input", SURF + " --normals " + N0 + " --mask m.png --out o" + OK_SURF
     + """ && $PY -c "import json,sys; r=json.load(open('o/report.json')); w=int(open('want.txt').read()); """
       """print('pixels', r.get('pixels'), 'want', w); sys.exit(0 if r.get('pixels') == w else 'FAULT: the palette mask read by index')" """,
     expect="ok", setup=py("""
        from PIL import Image
        import numpy as np, os
        a = np.array(Image.open(os.environ["F"] + "/data8/00000.data/mask.png").convert("L"))
        im = Image.fromarray(np.where(a > 127, 0, 1).astype("uint8"), "P")
        im.putpalette([255, 255, 255, 0, 0, 0] + [0] * 762)
        im.save("m.png")
        open("want.txt", "w").write(str(int((a > 127).sum())))
        """), may_change=O,
     why="A palette mask with white at index 0: the object is the white pixels (the same pixel count as the "
         "original mask), not index 1.")
case("q42-surf-normals-grey-png", "input", SURF + " --normals n.png --out o", names=["n.png"],
     setup='$PY -c "import cv2,os; cv2.imwrite(\'n.png\', cv2.imread(os.environ[\'F\']+\'/pred8/00000/normal.png\', 0))"\n',
     may_change=O, why="A normal map an editor saved as greyscale holds no normals: refused naming the file.")
case("q42-ev-pred-normal-grey-png", "input", EV + " --pred p --gt g/00000.data", names=["normal"],
     setup='mkdir g p; cp -r "$F/data/00000.data" g/; mkdir p/00000; '
           '$PY -c "import cv2,os; cv2.imwrite(\'p/00000/normal.png\', cv2.imread(os.environ[\'F\']+\'/pred/00000/normal.png\', 0))"\n',
     may_change=P, why="A grey prediction (one channel) cannot be scored as normals: refused naming normal.png.")
case("q42-ev-gt-mask-palette", "input",
     EV + " --pred p --gt g/00000.data" + OK_EV + """ && $PY -c "import json,sys; s=open('p/metrics.json').read(); """
     """sys.exit(0 if '691' in s else 'FAULT: pixel count is not 691 (palette mask read by index?)')" """,
     expect="ok", setup='mkdir g p; cp -r "$F/data/00000.data" g/; cp -r "$F/pred/00000" p/\n' + py("""
        from PIL import Image
        import numpy as np
        a = np.array(Image.open("g/00000.data/mask.png").convert("L"))
        im = Image.fromarray(np.where(a > 127, 0, 1).astype("uint8"), "P")
        im.putpalette([255, 255, 255, 0, 0, 0] + [0] * 762)
        im.save("g/00000.data/mask.png")
        """), may_change=P,
     why="A ground-truth mask re-saved as a palette PNG (white at index 0): the same 691 pixels are scored.")
case("q42-rr-user-mask-palette", "input", RRU + " && test -s r/u/report.json", expect="ok", setup=USER + py("""
        from PIL import Image
        import numpy as np
        a = np.array(Image.open("u/mask.png").convert("L"))
        im = Image.fromarray(np.where(a > 127, 0, 1).astype("uint8"), "P")
        im.putpalette([255, 255, 255, 0, 0, 0] + [0] * 762)
        im.save("u/mask.png")
        """), may_change=R, why="A user folder's palette mask (white at index 0): the fitted check runs on the object.")
case("q42-rf-user-mask-16bit", "input", RFU + " && test -s rf/u/normal.png", expect="ok", setup=USER + py("""
        import cv2, numpy as np
        a = cv2.imread("u/mask.png", 0)
        cv2.imwrite("u/mask.png", np.where(a > 127, 65535, 0).astype(np.uint16))
        """), may_change=RF, why="A 16-bit grey mask in a user folder is a mask: the refinement runs.")

# ============================================================================ SIGKILL, then run again
case("q42-cap-kill9-at-3s-then-rerun", "signal",
     killed(CAP, 3) + taken_or_named(CAP, "--overwrite", "test -s o/normal.png && test -s o/report.json"),
     expect="ok", setup=PH, may_change=O + ["$C/out.log"],
     why="A capture killed while loading, then run again: completes, or names --overwrite; never a crash on "
         "what the first left.")
case("q42-cap-kill9-keep-work-then-overwrite", "signal",
     killed(CAP + " --keep-work --max-side 32", 12) + CAP + " --keep-work --max-side 32 --overwrite" + OK_CAP,
     expect="ok", setup=PH, may_change=O,
     why="Killed while writing its work folder, a --keep-work capture with --overwrite completes and rewrites it.")
case("q42-cap-kill9-then-no-temp-left", "signal",
     killed(CAP, 11) + CAP + " --overwrite" + OK_CAP + " && " + report_images(8) + " && ! ls -A o | grep -i 'tmp\\|partial\\|\\.part' "
     "|| { ls -A o; echo 'FAULT: temporary files of the killed run left in --out'; exit 1; }", expect="ok",
     setup=PH, may_change=O,
     why="After a killed capture and a completed --overwrite, --out holds the outputs, not the killed run's temp "
         "files.")
case("q42-surf-kill9-then-rerun", "signal",
     killed(SURF0, 3) + taken_or_named(SURF0, "--overwrite", "test -s o/depth.npy && test -s o/report.json"),
     expect="ok", may_change=O + ["$C/out.log"],
     why="A surface killed early, run again: completes or names --overwrite.")
case("q42-ev-kill9-then-rerun", "signal",
     killed(EVP, 3) + taken_or_named(EVP, "--overwrite", "test -s p/metrics.json"), expect="ok", setup=PRED,
     may_change=P + ["$C/out.log"], why="An evaluation killed early, run again: completes or names --overwrite.")
case("q42-rr-kill9-then-overwrite", "signal", killed(RRU, 6) + RRU + " --overwrite && test -s r/u/report.json",
     expect="ok", setup=USER, may_change=R,
     why="A fitted check killed mid-way, then --overwrite: a complete report.")
case("q42-rf-kill9-then-overwrite", "signal", killed(RFU, 8) + RFU + " --overwrite && test -s rf/u/normal.png"
     " && test -s rf/u/refine_report.json", expect="ok", setup=USER, may_change=RF,
     why="A refinement killed mid-way, then --overwrite: a complete refined map and report.")

# ============================================================================ outputs overlapping inputs via .. / trailing slashes
case("q42-cap-out-is-input-via-dotdot", "writer", CAPX + ' --input p --out p/x/.. --mask "$F/mask.png"' + left("p/normal.png", "outputs written among the photos"),
     names=["--out"], setup=PH + "mkdir p/x\n",
     why="--out p/x/.. is the photo folder itself: refused naming --out, nothing written among the photos.")
case("q42-cap-out-is-input-trailing-slashes", "writer", CAPX + ' --input p/ --out ./p// --mask "$F/mask.png"'
     + left("p/normal.png", "outputs written among the photos"), names=["--out"], setup=PH,
     why="--input p/ and --out ./p// name one folder: refused naming --out.")
case("q42-cap-mask-inside-out-via-dotdot-overwrite", "writer",
     CAPX + ' --input p --out o/./ --mask o/sub/../mask.png --overwrite', names=["mask"],
     setup=CAP_SETUP + "mkdir -p o/sub; cp \"$F/mask.png\" o/mask.png; cp o/mask.png mask_given.png\n",
     may_change=["$C/o/*.png", "$C/o/*.exr", "$C/o/*.npy", "$C/o/*.json", "$C/o/*.html", "$C/o/surface",
                 "$C/o/surface/*", "$C/o/.*"],
     why="The --mask file is o/mask.png, an output --overwrite would replace while reading it: refused naming the "
         "mask (or the mask left as given).")
case("q42-surf-out-holds-mask-named-like-output", "writer",
     SURF + " --normals " + N0 + " --mask o/sub/../discontinuities.png --out o/./ --overwrite",
     names=["discontinuities.png"], setup="mkdir -p o/sub; cp " + M0 + " o/discontinuities.png\n",
     may_change=["$C/o/depth.*", "$C/o/mesh.*", "$C/o/report.json", "$C/o/.*"],
     why="The mask given is the very file the surface writes (o/discontinuities.png): refused naming it, the "
         "user's mask kept.")
case("q42-surf-out-is-normals-folder-trailing-slash", "writer",
     SURF + " --normals n/normal.png --out n/", expect="either",
     setup="mkdir n; cp " + N0 + " n/normal.png\n", may_change=["$C/n/depth.*", "$C/n/mesh.*", "$C/n/report.json",
                                                              "$C/n/discontinuities.png", "$C/n/.*"],
     why="The surface written beside its normal map (--out n/): done or refused in one line; the map itself stays.")
case("q42-ev-pred-dot-slash-trailing", "writer", EV + ' --pred ./p/./ --gt "$F/data/"' + OK_EV, expect="ok",
     setup=PRED, may_change=P, why="--pred ./p/./ and a --gt with a trailing slash are the same folders: scored.")
case("q42-ev-gt-is-pred-via-dotdot", "input", EV + " --pred p --gt p/00000/..", names=["--gt"], setup=PRED,
     may_change=P,
     why="--gt p/00000/.. is the prediction folder (no ground truth there): refused naming --gt, nothing scored.")
case("q42-rf-out-is-normals-folder-via-dotdot", "writer",
     '$PY -m validate.refine --data u --normals pr --out pr/x/..' + RFARGS
     + " ; r=$?; cmp -s pr/u/normal.png " + N0 + " || { echo 'FAULT: the starting map was replaced'; exit 0; }; exit $r",
     names=["--out"], setup=USER + 'mkdir -p pr/u pr/x; cp ' + N0 + ' pr/u/normal.png\n', may_change=["$C/pr/.*"],
     why="--out pr/x/.. is the --normals folder: pr/u/normal.png (the input) would be the output; refused.")
case("q42-rf-out-is-normals-folder-overwrite", "writer",
     '$PY -m validate.refine --data u --normals pr/ --out ./pr --overwrite' + RFARGS
     + " ; r=$?; cmp -s pr/u/normal.png " + N0 + " || { echo 'FAULT: the starting map was replaced by --overwrite'; exit 0; }; exit $r",
     names=["--out"], setup=USER + 'mkdir -p pr/u; cp ' + N0 + ' pr/u/normal.png\n', may_change=["$C/pr/.*"],
     why="--overwrite replaces an earlier refined map, not the starting map the run reads: refused naming --out.")
