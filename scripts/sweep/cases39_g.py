"""Sweep 39, part g: orchestrate.capture, orchestrate.surface, validate.rerender, validate.refine and
unips.evaluate, beyond sweeps 37/38 (cases37_*.py, cases38_*.py) and tests/test_bad_inputs.py.

What a new user does wrong and what an attacker plants:
- outputs of ANOTHER command already in --out (a predict object folder as capture --out, a rerender folder as
  refine --out, a refine folder as rerender --out, a capture folder as surface --out);
- report.json / metrics.json / refine_report.json edited by hand, truncated, turned into a list, a folder or a link,
  then --overwrite (the signed-keys rule of scenes.cli.outputs.claim_outputs);
- outputs hard-linked to a user's file, or made read-only, before --overwrite (an in-place write would change the
  user's copy: the harness sees that as data loss);
- folders renamed while a run works;
- valid but extreme inputs: 1x1 px photos, 4000 photos named (one damaged / one of another size), all black but one;
- sizes after --max-side: the working-size map or mask handed to the next command with a photo-size one;
- contradicting flags (--no-floors with the default threshold, --lights calibrated with --light-model point,
  --mask given twice, --input-encoding against a PNG's own sRGB chunk);
- numeric fit flags never swept (--batch-images, --refresh-every, --lr, --min-nz, --ao-rays, --downsample,
  --max-pixels).

Every case uses the 32/64-px fixtures of fixtures.sh (a capture of $F/photos takes about 13 s on 2 cores).
"""
from __future__ import annotations

import textwrap


def py(code: str) -> str:
    """A bash heredoc running `code` with the toolkit's python in $C."""
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


PRE = """
import glob, json, os, shutil
import numpy as np, cv2
F = os.environ["F"]; C = os.environ["C"]
"""


def setup_py(code: str) -> str:
    return py(PRE + textwrap.dedent(code))


PH = 'cp -r "$F/photos" p\n'
CAP = '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --no-refine --threads 1'
CAP_SETUP = PH + CAP + " > cap_setup.log 2>&1\n"
CAP_SMALL_SETUP = PH + CAP + " --max-side 32 --keep-work > cap_setup.log 2>&1\n"
SURF = "$PY -m orchestrate.surface"
N0 = '"$F/pred8/00000/normal.png"'
M0 = '"$F/data8/00000.data/mask.png"'
SURF0 = f"{SURF} --normals {N0} --mask {M0} --out o"
RR = ('$PY -m validate.rerender --data "$F/data8/00000.data" --normals "$F/pred8/00000/normal.png" '
      '--spp 4 --no-floors --threshold 0.5 --supersample 1')
RF = '$PY -m validate.refine --data "$F/data8/00000.data" --normals "$F/pred8/00000/normal.png"'
RF_FAST = " --refine-steps 2 --steps 2 --rounds 1 --ao-rays 0 --no-shadows --threads 1"
RRFIT = ('$PY -m validate.rerender --data "$F/data8/00000.data" --normals "$F/pred8/00000/normal.png" --out r '
         '--fit --steps 2 --ao-rays 0 --no-shadows --no-bas-relief --threads 1')
EV = "$PY -m unips.evaluate"
EV_SETUP = 'cp -r "$F/pred8" pd\n$PY -m unips.evaluate --pred pd --gt "$F/data8" > ev_setup.log 2>&1\n'
EV_CMD = f'{EV} --pred pd --gt "$F/data8"'


def deep(d: str) -> list[str]:
    return [f"$C/{d}/*", f"$C/{d}/*/*", f"$C/{d}/*/*/*", f"$C/{d}/*/*/*/*", f"$C/{d}/.*", f"$C/{d}/*/.*"]


O = deep("o")
# what a capture writes into o: everything else in o (another command's files, the user's) must stay the same
CAPOUT = ["$C/o/normal*", "$C/o/mask*", "$C/o/light_variation.png", "$C/o/expected_error*", "$C/o/report.*",
          "$C/o/.*", *deep("o/surface"), *deep("o/check"), *deep("o/refine"), *deep("o/work")]
SURFOUT = ["$C/o/depth.*", "$C/o/mesh.*", "$C/o/discontinuities.png", "$C/o/report.json", "$C/o/.*",
           "$C/o/shaded.png"]
RROUT = lambda d: [f"$C/{d}/*/report.json", f"$C/{d}/*/figure.png", f"$C/{d}/*/explained.png",  # noqa: E731
                   f"$C/{d}/summary.csv", f"$C/{d}/.*", f"$C/{d}/*/.*", f"$C/{d}/*/R*.png"]
RFOUT = lambda d: [f"$C/{d}/*/normal.png", f"$C/{d}/*/refine_report.json", f"$C/{d}/*/expected_error*",  # noqa: E731
                   f"$C/{d}/.*", f"$C/{d}/*/.*"]
EVOUT = ["$C/pd/metrics.json", "$C/pd/metrics.csv", "$C/pd/*/error_map.png", "$C/pd/.*", "$C/pd/*/.*"]

CASES: list[dict] = []


def case(id, kind, setup, cmd, expect, names=(), may_change=(), timeout=120, why=""):
    assert id.startswith("g39-"), id
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


def edit_json(path: str, code: str) -> str:
    """Setup lines editing the JSON file `path` (relative to $C) with `code` acting on `r`."""
    return setup_py(f"""
        p = {path!r}
        r = json.load(open(p))
        {code}
        json.dump(r, open(p + ".tmp", "w")); os.replace(p + ".tmp", p)
    """)


# ============================================================== capture: another command's folder as --out
case("g39-cap-out-is-a-predict-object-folder", "writer", 'cp -r "$F/pred8/00000" o', CAP, "refuse", ["--out"], [],
     why="a predict object folder (normal.png, normal.exr, expected_error*) holds files of the names capture writes: "
         "refused before any write, nothing of predict's replaced")
case("g39-cap-out-is-a-predict-object-folder-overwrite", "writer", 'cp -r "$F/pred8/00000" o', CAP + " --overwrite",
     "refuse", ["--out", "report.json"], [],
     why="--overwrite replaces a capture's own files only: a folder without the capture's report.json is "
         "predict's, never replaced (the message says no report.json)")
case("g39-cap-out-is-a-predict-dataset-folder", "writer", 'cp -r "$F/pred8" o', CAP + " && test -s o/normal.png",
     "ok", [], CAPOUT,
     why="a predict dataset folder has only <object>/ folders, none of the capture's names: the capture may write "
         "beside them, and every predict file stays byte-identical")

# ============================================================== capture: report.json edited by hand, then --overwrite
case("g39-cap-report-values-edited-then-overwrite", "writer",
     CAP_SETUP + edit_json("o/report.json", 'r["verdict"] = {"level": "edited by hand"}; r["my_note"] = 1'),
     CAP + " --overwrite && " + py('import json; r = json.load(open("o/report.json")); '
                                   'assert "my_note" not in r and r["verdict"]["level"] != "edited by hand", r'),
     "ok", [], CAPOUT,
     why="a report that keeps the capture's keys (input, verdict, timings) is still the capture's: --overwrite "
         "replaces it with a fresh one, and none of the hand edits survive")
case("g39-cap-report-key-removed-then-overwrite", "writer",
     CAP_SETUP + edit_json("o/report.json", 'del r["verdict"]'), CAP + " --overwrite", "refuse", ["report.json"], [],
     why="a report.json without the capture's keys is no longer recognisably the capture's: refused before any "
         "write, even with --overwrite; no other output touched")
case("g39-cap-report-a-json-list-then-overwrite", "writer",
     CAP_SETUP + "echo '[]' > o/report.json", CAP + " --overwrite", "refuse", ["report.json"], [],
     why="a report.json that is a JSON list holds no keys: not the capture's, never replaced, refused in one line")
case("g39-cap-report-cut-in-half-then-overwrite", "writer",
     CAP_SETUP + 'head -c $(( $(stat -c %s o/report.json) / 2 )) o/report.json > t && mv t o/report.json',
     CAP + " --overwrite", "refuse", ["report.json"], [],
     why="a truncated report.json cannot be read: the command refuses naming it (no JSON traceback) and replaces "
         "nothing")
case("g39-cap-report-a-folder-then-overwrite", "writer",
     CAP_SETUP + "rm o/report.json && mkdir o/report.json && echo mine > o/report.json/keep.txt",
     CAP + " --overwrite", "refuse", ["report.json"], [],
     why="a folder where report.json goes is never replaced, even with --overwrite; its content is kept")
case("g39-cap-report-a-link-out-then-overwrite", "writer",
     CAP_SETUP + "mv o/report.json keep.json && ln -s ../keep.json o/report.json",
     CAP + " --overwrite", "refuse", ["report.json"], [],
     why="report.json made a link to a file outside --out: refused (a link where a file is written), never written "
         "through; keep.json stays byte-identical")
case("g39-cap-normal-png-hardlinked-then-overwrite", "writer",
     CAP_SETUP + "ln o/normal.png mine.png",
     CAP + " --overwrite --convention opencv", "ok", [], CAPOUT,
     why="o/normal.png hard-linked to the user's mine.png: --overwrite (with another frame, so the map differs) must "
         "replace the name atomically, never write into the shared inode: mine.png stays byte-identical")
case("g39-cap-report-hardlinked-then-overwrite", "writer",
     CAP_SETUP + "ln o/report.json mine.json",
     CAP + " --overwrite", "ok", [], CAPOUT,
     why="the report is rewritten twice per run (complete false, then true): a hard link to it (mine.json) must not "
         "see either write")
case("g39-cap-normal-exr-a-fifo-then-overwrite", "writer",
     CAP_SETUP + "rm o/normal.exr && mkfifo o/normal.exr",
     CAP + " --overwrite", "refuse", ["normal.exr"], [], timeout=90,
     why="a named pipe where normal.exr goes (not a plain file): refused naming it before any write, no hang on "
         "opening it, nothing else replaced")

# ============================================================== capture: sizes after --max-side
case("g39-cap-max-side-0-mask-at-half-size", "input",
     PH + setup_py('m = cv2.imread(F + "/mask.png", -1); cv2.imwrite("m32.png", cv2.resize(m, (32, 32), '
                   'interpolation=cv2.INTER_NEAREST))'),
     CAP.replace('"$F/mask.png"', "m32.png") + " --max-side 0", "refuse", ["--mask"], O,
     why="with --max-side 0 the working size is the photos' (64 px): a 32 px mask is neither size, refused naming "
         "--mask")
case("g39-cap-max-side-33-mask-at-32", "input",
     PH + setup_py('m = cv2.imread(F + "/mask.png", -1); cv2.imwrite("m32.png", cv2.resize(m, (32, 32), '
                   'interpolation=cv2.INTER_NEAREST))'),
     CAP.replace('"$F/mask.png"', "m32.png") + " --max-side 33", "refuse", ["--mask"], O,
     why="--max-side 33 makes the working size 33 px: a 32 px mask fits neither that nor the photos, refused naming "
         "--mask (never resampled silently)")
case("g39-cap-max-side-32-keep-work-sizes", "exit0", PH,
     CAP + " --max-side 32 --keep-work && " + py("""
        import cv2, glob
        s = lambda p: cv2.imread(p, -1).shape[:2]
        assert s("o/normal.png") == (64, 64), s("o/normal.png")
        assert s("o/mask.png") == (64, 64), s("o/mask.png")
        assert s("o/normal_model.png") == (32, 32), s("o/normal_model.png")
        w = glob.glob("o/work/*.data/mask.png"); assert len(w) == 1, w
        assert s(w[0]) == (32, 32), s(w[0])
     """), "ok", [], O,
     why="docs: normal.png / mask.png at the photos' size, normal_model.png and the --keep-work folder at the "
         "working size; a wrong size here breaks every later command")
case("g39-cap-nonsquare-max-side-33-sizes", "exit0",
     PH + setup_py("""
        for p in glob.glob("p/*.jpg"):
            cv2.imwrite(p, cv2.imread(p)[12:52], [cv2.IMWRITE_JPEG_QUALITY, 95])
        cv2.imwrite("m.png", cv2.imread(F + "/mask.png", -1)[12:52])
     """),
     CAP.replace('"$F/mask.png"', "m.png") + " --max-side 33 && " + py("""
        import cv2
        s = lambda p: cv2.imread(p, -1).shape[:2]
        assert s("o/normal.png") == (40, 64), s("o/normal.png")
        assert s("o/mask.png") == (40, 64), s("o/mask.png")
        assert max(s("o/normal_model.png")) == 33, s("o/normal_model.png")
     """), "ok", [], O,
     why="64x40 photos at --max-side 33 work at 33x21 (an odd rounding): outputs must come back at exactly 64x40")

# ============================================================== capture: extreme photo sets
case("g39-cap-photos-1x1", "input",
     setup_py("""
        os.mkdir("p")
        for i in range(8):
            cv2.imwrite(f"p/IMG_{i}.png", np.full((1, 1, 3), 20 + 25 * i, np.uint8))
     """),
     '$PY -m orchestrate.capture --input p --out o --mask none --no-refine --threads 1', "refuse", ["--input"], O,
     why="eight 1x1 px photos hold one pixel: refused in one line naming --input and the size, before the model runs")
case("g39-cap-4000-photos-named", "input",
     setup_py("""
        os.mkdir("p"); rng = np.random.default_rng(0)
        for i in range(4000):
            cv2.imwrite(f"p/IMG_{i}.png", rng.integers(20, 200, (32, 32, 3), dtype=np.uint8))
     """),
     '$PY -m orchestrate.capture --input p --out o --mask none --no-refine --threads 1', "refuse",
     ["4000"], O, timeout=120,
     why="4000 photos of 32 px: either it runs or, where the memory estimate exceeds the machine, one line naming "
         "the count before any photo is decoded (seen: refused naming --max-side and 4000 photos)")
case("g39-cap-300-photos-one-cut-short", "input",
     setup_py("""
        os.mkdir("p"); rng = np.random.default_rng(0)
        for i in range(300):
            cv2.imwrite(f"p/IMG_{i}.png", rng.integers(20, 200, (32, 32, 3), dtype=np.uint8))
        b = open("p/IMG_200.png", "rb").read(); open("p/IMG_200.png", "wb").write(b[: len(b) // 2])
     """),
     '$PY -m orchestrate.capture --input p --out o --mask none --no-refine --threads 1', "refuse",
     ["IMG_200.png"], O, timeout=120,
     why="among 300 photos (under the memory estimate) one PNG is cut short: refused naming that one file before "
         "the model runs on 300 photos, no traceback")
case("g39-cap-300-photos-last-other-size", "input",
     setup_py("""
        os.mkdir("p"); rng = np.random.default_rng(1)
        for i in range(300):
            cv2.imwrite(f"p/IMG_{i}.png", rng.integers(20, 200, (32, 33 if i == 299 else 32, 3), dtype=np.uint8))
     """),
     '$PY -m orchestrate.capture --input p --out o --mask none --no-refine --threads 1', "refuse",
     ["IMG_299.png"], O, timeout=120,
     why="the last of 300 photos in natural order (IMG_299 after IMG_100) is one pixel wider: refused naming it")
case("g39-cap-all-black-but-one", "input",
     PH + setup_py("""
        for p in sorted(glob.glob("p/*.jpg"))[1:]:
            cv2.imwrite(p, np.zeros((64, 64, 3), np.uint8))
     """),
     CAP, "refuse", ["--input"], O,
     why="seven black photos and one lit one: a single light cannot determine a normal (3 are the minimum); "
         "the command should refuse as for too_few_images, not hand back a map from one photo")
case("g39-cap-input-is-a-predict-object-folder", "input", "",
     '$PY -m orchestrate.capture --input "$F/pred8/00000" --out o --mask none --no-refine --threads 1',
     "refuse", ["00000"], O,
     why="a predict output given as photos (16-bit normal.png, 8-bit pictures, EXR, .npy, predict.json): refused "
         "in one line naming the folder or a file of it (mixed kinds/depths), never a normal map of normal maps")

# ============================================================== capture: contradicting flags
case("g39-cap-mask-given-twice", "message", PH,
     '$PY -m orchestrate.capture --input p --out o --mask none --mask "$F/mask.png" --no-refine --threads 1',
     "either", [], O,
     why="--mask given twice (none, then a file): either the last wins (documented argparse behaviour) or one line "
         "naming --mask; never a traceback")
case("g39-cap-linear-encoding-against-srgb-chunk", "message",
     setup_py("""
        from PIL import Image, PngImagePlugin
        os.mkdir("p")
        for i, f in enumerate(sorted(glob.glob(F + "/photos/*.jpg"))):
            info = PngImagePlugin.PngInfo(); info.add(b"sRGB", b"\\x00")
            Image.open(f).convert("RGB").save(f"p/IMG_{i}.png", pnginfo=info)
     """),
     '$PY -m orchestrate.capture --input p --out o --mask "$F/mask.png" --input-encoding linear --no-refine '
     '--threads 1', "either", [], O,
     why="--input-encoding linear on 8-bit PNGs whose sRGB chunk says sRGB: either the flag is taken as asked, or "
         "the file's chunk wins and the report says so, or one line naming --input-encoding; never a traceback")

# ============================================================== capture: renames while it runs
case("g39-cap-input-renamed-while-running", "engine", PH,
     CAP + " & pid=$!; sleep 6; mv p p_moved; wait $pid", "either", [], [*O, "$C/p/*", "$C/p_moved/*"],
     why="the photo folder renamed mid-run: either the photos were already in memory (runs through) or one line "
         "naming the photo that vanished; no traceback, no process left")
case("g39-cap-out-renamed-while-running", "engine", PH,
     CAP + " & pid=$!; sleep 8; mv o o_moved; wait $pid", "either", [], [*O, *deep("o_moved")],
     why="--out renamed mid-run (the user tidies up): the run finishes into the folder it holds or stops in one "
         "line; no traceback, no half-written files left in a new o")

# ============================================================== surface
case("g39-surf-model-map-with-photo-size-mask", "input", CAP_SMALL_SETUP,
     f"{SURF} --normals o/normal_model.png --mask o/mask.png --out s", "refuse", ["--mask"], deep("s"),
     why="after --max-side 32, normal_model.png is 32 px and mask.png 64 px: refused naming --mask and both sizes")
case("g39-surf-model-map-with-work-mask", "exit0", CAP_SMALL_SETUP,
     f"{SURF} --normals o/normal_model.png --mask o/work/p.data/mask.png --out s && test -s s/depth.npy", "ok", [],
     deep("s"), why="the working-size map with the working-size mask (--keep-work) composes: surface runs")
case("g39-surf-final-map-with-work-mask", "input", CAP_SMALL_SETUP,
     f"{SURF} --normals o/normal.png --mask o/work/p.data/mask.png --out s", "refuse", ["--mask"], deep("s"),
     why="the photo-size map (64 px) with the working-size mask (32 px): refused naming --mask")
case("g39-surf-map-of-an-opencv-capture", "input", CAP_SETUP.replace("--threads 1", "--threads 1 --convention opencv"),
     f"{SURF} --normals o/normal.png --mask o/mask.png --out s", "refuse", ["--normals"], deep("s"),
     why="a capture written with --convention opencv has z away from the camera: surface (camera frame, z toward "
         "it) must refuse the map as facing away, naming --normals, not integrate it mirrored")
case("g39-surf-out-is-a-capture-folder", "writer", CAP_SETUP,
     f"{SURF} --normals o/normal.png --mask o/mask.png --out o", "refuse", ["--out"], [],
     why="a capture folder as surface --out holds the capture's report.json (and the map read): refused, nothing of "
         "the capture replaced")
case("g39-surf-out-is-a-capture-folder-overwrite", "writer", CAP_SETUP,
     f"{SURF} --normals o/normal.png --mask o/mask.png --out o --overwrite", "refuse", ["--out"], [],
     why="with --overwrite too: the capture's report.json lacks the surface's keys and the folder holds the input "
         "map; never replaced")
case("g39-surf-out-is-a-predict-object-folder", "writer", 'cp -r "$F/pred8/00000" o',
     SURF0 + " && test -s o/depth.npy", "ok", [], SURFOUT,
     why="a predict object folder holds none of the surface's names: surface writes beside them, predict's files "
         "stay byte-identical")
case("g39-surf-depth-hardlinked-then-overwrite", "writer", SURF0 + " > s.log 2>&1\nln o/depth.npy mine.npy",
     SURF0 + " --k 0 --overwrite", "ok", [], SURFOUT,
     why="depth.npy hard-linked to the user's mine.npy; a rerun with --k 0 (another depth) and --overwrite must "
         "replace the name, not write into the shared inode")
case("g39-surf-report-key-removed-then-overwrite", "writer", SURF0 + " > s.log 2>&1\n" + "echo '{}' > o/report.json",
     SURF0 + " --overwrite", "refuse", ["report.json"], [],
     why="the surface's report.json emptied by hand to {}: no longer recognisably its own, refused even with "
         "--overwrite; depth.npy and mesh.ply untouched")
case("g39-surf-report-values-edited-then-overwrite", "writer",
     SURF0 + " > s.log 2>&1\n" + edit_json("o/report.json", 'r["my_note"] = "hand edit"'),
     SURF0 + " --overwrite && ! grep -q my_note o/report.json", "ok", [], SURFOUT,
     why="a report with the surface's keys and a user's extra key is still the surface's: replaced whole")
case("g39-surf-glb-of-an-earlier-run-not-left-stale", "writer",
     SURF0 + " --mesh ply,glb > s.log 2>&1",
     SURF0 + " --k 0 --overwrite && test ! -e o/mesh.glb", "ok", [], SURFOUT,
     why="a rerun with --overwrite writing only ply (another surface, --k 0) must not leave the earlier run's "
         "mesh.glb beside the new report as if it were this surface (judgment: removed as its own output)")

# ============================================================== rerender
case("g39-rr-no-floors-default-threshold", "exit0", "",
     RR.replace(" --threshold 0.5", "") + " --out r && test -s r/00000/report.json", "ok", [], deep("r"),
     why="--no-floors leaves the default threshold (the noise floor's 99th percentile) without its floor: the "
         "check runs (frac_above_threshold omitted or computed otherwise), no refusal of a flag not given")
case("g39-rr-out-is-a-refine-folder", "writer",
     setup_py("""
        os.makedirs("rf/00000")
        shutil.copy(F + "/pred8/00001/normal.png", "rf/00000/normal.png")
        json.dump({"mode": "fitted", "accepted": False, "why": "test"}, open("rf/00000/refine_report.json", "w"))
     """),
     RR + " --out rf && test -s rf/00000/report.json", "ok", [], RROUT("rf"),
     why="a refine folder as rerender --out: no name in common, so the check writes beside refine's files and keeps "
         "them byte-identical")
case("g39-rr-out-is-a-predict-dataset-folder", "writer", 'cp -r "$F/pred8" pd',
     RR + " --out pd && test -s pd/00000/report.json", "ok", [], RROUT("pd"),
     why="a predict dataset folder as --out: report.json/figure.png land beside predict's files, which stay intact")
case("g39-rr-report-key-removed-then-overwrite", "writer",
     RR + " --out r > r.log 2>&1\n" + edit_json("r/00000/report.json", 'del r["mode"]'),
     RR + " --out r --overwrite", "refuse", ["report.json"], [],
     why="the check's report.json edited by hand (mode removed): refused even with --overwrite, figure.png kept")
case("g39-rr-report-hardlinked-then-overwrite", "writer",
     RR + " --out r > r.log 2>&1\nln r/00000/report.json mine.json",
     RR + " --out r --overwrite --seed-mode independent", "ok", [], RROUT("r"),
     why="report.json hard-linked to the user's mine.json: --overwrite replaces the name; mine.json stays the same")
case("g39-rr-figure-a-folder-then-overwrite", "writer",
     RR + " --out r > r.log 2>&1\nrm r/00000/figure.png && mkdir r/00000/figure.png && touch r/00000/figure.png/k",
     RR + " --out r --overwrite", "refuse", ["figure.png"], [],
     why="a folder where figure.png goes: refused before rendering, naming it; never replaced")
case("g39-rr-dataset-summary-a-folder", "writer", "mkdir -p r/summary.csv && echo mine > r/summary.csv/keep",
     '$PY -m validate.rerender --data "$F/data8" --normals "$F/pred8" --out r --spp 4 --no-floors --threshold 0.5',
     "refuse", ["summary.csv"], deep("r"),
     why="a folder named summary.csv in --out: refused naming it before any object is rendered, never replaced")
case("g39-rr-fit-downsample-beyond-image", "input", "", RRFIT + " --downsample 64", "refuse", ["--downsample"],
     deep("r"), timeout=90, why="a downsampling factor of 64 on a 32 px object leaves no pixel: refused naming it")
case("g39-rr-fit-max-pixels-0", "input", "", RRFIT + " --max-pixels 0", "refuse", ["--max-pixels"], deep("r"),
     timeout=90, why="--max-pixels 0 allows no mask pixel: refused naming the flag, not a division by zero")
case("g39-rr-fit-batch-images-0", "input", "", RRFIT + " --batch-images 0", "refuse", ["--batch-images"],
     deep("r"), timeout=90, why="a batch of 0 images per Adam step: refused naming --batch-images")
case("g39-rr-fit-refresh-every-0", "input", "", RRFIT + " --refresh-every 0", "refuse", ["--refresh-every"],
     deep("r"), timeout=90, why="refreshing every 0 steps (a modulo by zero): refused naming --refresh-every")
case("g39-rr-fit-lr-negative", "input", "", RRFIT + " --lr -0.02", "refuse", ["--lr"], deep("r"), timeout=90,
     why="a negative learning rate climbs the residual: refused naming --lr")
case("g39-rr-fit-min-nz-above-1", "input", "", RRFIT + " --min-nz 1.5", "refuse", ["--min-nz"], deep("r"),
     timeout=90, why="|n_z| can never reach 1.5: refused naming --min-nz (a bound in (0, 1))")
case("g39-rr-fit-ao-rays-negative", "input", "", RRFIT + " --ao-rays -1", "refuse", ["--ao-rays"], deep("r"),
     timeout=90, why="a negative ray count: refused naming --ao-rays")
case("g39-rr-fit-lr-nan", "input", "", RRFIT + " --lr nan", "refuse", ["--lr"], deep("r"), timeout=90,
     why="a NaN learning rate makes every light NaN: refused naming --lr")

# ============================================================== refine
case("g39-rf-work-folder-with-photo-size-map", "input", CAP_SMALL_SETUP,
     '$PY -m validate.refine --data o/work/p.data --normals o/normal.png --out rf', "refuse", ["--normals"],
     deep("rf"), why="the --keep-work folder is 32 px after --max-side 32, normal.png 64 px: refused naming "
                     "--normals and both sizes before any fit")
case("g39-rf-calibrated-lights-with-point-model", "input", "",
     RF + " --out rf --lights calibrated --light-model point", "refuse", ["--light"], deep("rf"),
     why="calibrated lights are directional and held fixed: a point light model contradicts them, refused naming "
         "--light-model (and --lights)")
case("g39-rf-out-is-a-rerender-folder", "writer", RR + " --out r > r.log 2>&1\n",
     RF + RF_FAST + " --out r && test -s r/00000/refine_report.json", "ok", [], RFOUT("r"),
     why="a rerender folder as refine --out: refine writes normal.png and refine_report.json beside report.json and "
         "figure.png, which stay byte-identical")
case("g39-rf-report-keys-removed-then-overwrite", "writer",
     setup_py("""
        os.makedirs("rf/00000")
        shutil.copy(F + "/pred8/00001/normal.png", "rf/00000/normal.png")
        json.dump({"mode": "fitted"}, open("rf/00000/refine_report.json", "w"))
     """),
     RF + RF_FAST + " --out rf --overwrite", "refuse", ["refine_report.json"], [],
     why="refine_report.json edited by hand (accepted and why removed): not refine's, refused before the fit, "
         "normal.png kept")
case("g39-rf-normal-hardlinked-then-overwrite", "writer",
     setup_py("""
        os.makedirs("rf/00000")
        shutil.copy(F + "/pred8/00001/normal.png", "mine.png")
        os.link("mine.png", "rf/00000/normal.png")
        json.dump({"mode": "fitted", "accepted": False, "why": "earlier"}, open("rf/00000/refine_report.json", "w"))
     """),
     RF + RF_FAST + " --out rf --overwrite", "ok", [], RFOUT("rf"),
     why="an earlier refine's normal.png hard-linked to the user's mine.png (another object's map): --overwrite "
         "replaces the name atomically; mine.png stays byte-identical")

# ============================================================== evaluate
case("g39-ev-metrics-key-removed-then-overwrite", "writer", EV_SETUP + edit_json("pd/metrics.json", 'del r["gt"]'),
     EV_CMD + " --overwrite", "refuse", ["metrics.json"], [],
     why="metrics.json edited by hand (gt removed): not recognisably evaluate's, refused even with --overwrite; "
         "metrics.csv and the error maps kept")
case("g39-ev-metrics-a-list-then-overwrite", "writer", EV_SETUP + "echo '[1, 2]' > pd/metrics.json",
     EV_CMD + " --overwrite", "refuse", ["metrics.json"], [],
     why="metrics.json replaced by a JSON list: holds no keys, refused in one line (no AttributeError traceback)")
case("g39-ev-metrics-values-edited-then-overwrite", "writer",
     EV_SETUP + edit_json("pd/metrics.json", 'r["my_note"] = 1'),
     EV_CMD + " --overwrite && ! grep -q my_note pd/metrics.json", "ok", [], EVOUT,
     why="metrics.json with evaluate's keys and a user's extra key is evaluate's: replaced whole")
case("g39-ev-metrics-hardlinked-then-overwrite-changed-map", "writer",
     EV_SETUP + "ln pd/metrics.json mine.json\n"
     'for f in normal.png normal.exr; do rm -f pd/00000/$f; cp "$F/pred8/00001/$f" pd/00000/$f; done\n',
     EV_CMD + " --overwrite", "ok", [], [*EVOUT, "$C/pd/00000/*"],
     why="metrics.json hard-linked to mine.json, then the map of 00000 changed: the new metrics replace the name, "
         "mine.json keeps the old figures")
case("g39-ev-error-map-a-folder-then-overwrite", "writer",
     EV_SETUP + "rm pd/00000/error_map.png && mkdir pd/00000/error_map.png && touch pd/00000/error_map.png/k",
     EV_CMD + " --overwrite", "refuse", ["error_map.png"], [],
     why="a folder where error_map.png goes: refused before any write, naming it, with --overwrite too")
case("g39-ev-metrics-csv-hardlinked-then-overwrite-changed-map", "writer",
     EV_SETUP + "ln pd/metrics.csv mine.csv\n"
     'for f in normal.png normal.exr; do rm -f pd/00001/$f; cp "$F/pred8/00002/$f" pd/00001/$f; done\n',
     EV_CMD + " --overwrite", "ok", [], [*EVOUT, "$C/pd/00001/*"],
     why="metrics.csv hard-linked to the user's mine.csv, then one map changed: --overwrite replaces the name; "
         "mine.csv keeps the earlier rows")
case("g39-ev-gt-mask-other-size", "input",
     'cp -r "$F/pred8" pd\nmkdir g && cp -r "$F/data8/00000.data" g/\n' + setup_py("""
        m = cv2.imread("g/00000.data/mask.png", -1)
        cv2.imwrite("g/00000.data/mask.png", cv2.resize(m, (16, 16), interpolation=cv2.INTER_NEAREST))
     """),
     f"{EV} --pred pd --gt g/00000.data", "refuse", ["mask.png"], EVOUT,
     why="a ground-truth mask of 16 px beside a 32 px normal map: refused naming mask.png, never resampled")
case("g39-ev-pred-all-zero-vectors", "input",
     'cp -r "$F/pred8" pd\n' + setup_py("""
        cv2.imwrite("pd/00000/normal.png", np.full((32, 32, 3), 32768, np.uint16))
        os.remove("pd/00000/normal.exr")
     """),
     f'{EV} --pred pd --gt "$F/data8/00000.data"', "refuse", ["00000"], EVOUT,
     why="a prediction of zero vectors everywhere (code 32768) holds no estimate: refused naming the object's map, "
         "not scored as 90 degrees")
case("g39-ev-pred-exr-one-inf", "input",
     'cp -r "$F/pred8" pd\n' + setup_py("""
        from scenes.exr import read_exr, write_exr
        n = np.array(read_exr("pd/00000/normal.exr"), np.float32); n[16, 16, 0] = np.inf
        os.remove("pd/00000/normal.exr"); write_exr("pd/00000/normal.exr", n)
        os.remove("pd/00000/normal.png")
     """),
     f'{EV} --pred pd --gt "$F/data8/00000.data"', "refuse", ["normal.exr"], EVOUT,
     why="an EXR prediction with one infinite value: refused naming normal.exr (non-finite), not a NaN metric")
case("g39-ev-pred-both-00000-and-00000-data", "message",
     'cp -r "$F/pred8" pd\ncp -r "$F/pred8/00001" pd/00000.data\n',
     f'{EV} --pred pd --gt "$F/data8"', "either", [], EVOUT,
     why="a prediction folder named like the ground-truth folder (00000.data) beside 00000: either ignored as no "
         "object's (00000 is scored) or refused naming it; never scored in place of 00000")
