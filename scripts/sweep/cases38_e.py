"""Sweep 38, part e: the MODEL side again (unips.predict / train / evaluate, orchestrate.ship / benchmark /
error_calibration, wildgen.export), with flag combinations and layouts sweep 37 (cases37_b.py) and
tests/test_bad_inputs.py do not hold.

Mechanisms aimed at: numbers out of range refused in one line naming the flag (--batch, --pixels, --val-every,
--tta, --res, --max-images, --counts, --shard-size ...); torchrun's variables in odd spellings (unicode digits,
LOCAL_RANK beyond WORLD_SIZE, an unusable join timeout); comma-separated --data lists that name one dataset twice
(directly, through a link, or a dataset and one of its own objects); resume with changed flags; DiLiGenT and
official UniPS layouts with odd light files, masks and image names, and results that would be wrong yet exit 0
(least squares on degenerate lights, natural order of L* names); untrusted files (a pickled .npy prediction, links
inside a dataset being exported) never read or archived from outside the target; one writer per folder (evaluate
into a folder predict still writes; two evaluations at once).

Ship and error_calibration cases are refusals only, made with arguments that keep them away from the repository's
unips/weights (--val of an empty folder for ship, --out in $C for error_calibration): never run them with valid
inputs.

Cases whose command adds its own check print a line starting with `FAULT:` and exit 0 where a refusal is expected
(the harness then flags exit0); a check that passed exits with a non-zero status (a clean run, not a refusal) and
names nothing.
"""
from __future__ import annotations

OBJ = "$F/data/00000.data"
PRED = "$PY -m unips.predict --method model --no-expected-error --tta 1"
PRED_LS = "$PY -m unips.predict --method least-squares"
PRED_SH = "$PY -m unips.predict --method sh-uncalibrated"
TRAIN = "$PY -m unips.train --model glc-test --steps 1 --no-progress --threads 1"
EVAL = "$PY -m unips.evaluate"
BENCH = "$PY -m orchestrate.benchmark --threads 1 --rerender-objects 0 --diligent-subsets 0"
SHIP = "$PY -m orchestrate.ship --threads 1"
EC = "$PY -m orchestrate.error_calibration --assets none --threads 1"
EXPORT = "$PY -m wildgen.export --quiet"

DIL = 'cp -r "$F/ballPNG" dil\n'
"""A copy of the DiLiGenT ball fixture as $C/dil."""

UNIPS_OBJ = """mkdir -p u/obj.data
for i in 0 1 2 3; do cp "$F/data/00000.data/L00$i.png" "u/obj.data/L00$i.png"; done
cp "$F/data/00000.data/mask.png" u/obj.data/mask.png
"""
"""An official UniPS layout object ($C/u/obj.data: L* images and mask.png, no scene.json)."""


def py(code: str) -> str:
    return "$PY - <<'PYEOF'\n" + code.strip() + "\nPYEOF\n"


def lights(expr: str) -> str:
    """Setup: $C/dil whose light_directions.txt becomes `expr` of the array `d` (numpy, one row per image)."""
    return DIL + py(f"""
import numpy as np
d = np.loadtxt('dil/light_directions.txt')
d = {expr}
np.savetxt('dil/light_directions.txt', d)
""")


CASES: list[dict] = []


def case(id_, kind, setup, cmd, expect="refuse", names=(), may=(), timeout=120, why=""):
    CASES.append(dict(id="e38-" + id_, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may), timeout=timeout, why=why))


OUT = ("$C/o", "$C/o/*", "$C/o/*/*")

# ----------------------------------------------------------------------------------------------- predict: flags
case("pred-max-images-negative", "input", "", f"{PRED} --input {OBJ} --out o --max-images -2",
     names=["--max-images"], may=OUT, why="a negative image count is no count: one line naming --max-images")
case("pred-max-images-beyond-count", "exit0", "",
     f"{PRED} --input {OBJ} --out o --max-images 1000000 && "
     "$PY -c \"import json,sys; d=json.load(open('o/00000/predict.json')); "
     "sys.exit(0 if d['num_images']==4 else 'FAULT: num_images '+str(d['num_images']))\"",
     expect="ok", may=OUT, why="more than the object has means all of them: exit 0 and predict.json says 4 images")
case("pred-res-negative", "input", "", f"{PRED} --input {OBJ} --out o --res -64", names=["--res"], may=OUT,
     why="a negative working side is refused naming --res, not passed to a resize")
case("pred-res-zero", "input", "", f"{PRED} --input {OBJ} --out o --res 0", names=["--res"], may=OUT,
     why="a zero working side is refused naming --res")
case("pred-tta-zero", "input", "", f"$PY -m unips.predict --method model --no-expected-error --tta 0 "
     f"--input {OBJ} --out o", names=["--tta"], may=OUT, why="0 views is not among 1,2,4,8")
case("pred-tta8-res40-two-images-expected-error", "engine", "",
     f"$PY -m unips.predict --method model --tta 8 --res 40 --max-images 2 --input {OBJ} --out o",
     expect="ok", may=OUT, why="all views, an odd working side and halves of one image each must still work or "
                              "state why there is no expected error")
case("pred-one-image-expected-error", "engine", "",
     f"$PY -m unips.predict --method model --tta 2 --max-images 1 --input {OBJ} --out o && "
     "$PY -c \"import json,sys; d=json.load(open('o/00000/predict.json')); "
     "sys.exit(0 if ('expected_error_deg' not in d or d.get('expected_error_note')) or d['expected_error_deg'] "
     "else 'FAULT')\"",
     expect="ok", may=OUT, why="one image has no two halves: the map is written and the note says why there is no "
                              "expected error (no traceback, no made-up figure)")
case("pred-sh-with-tta", "input", "", f"{PRED_SH} --input {OBJ} --out o --tta 2", names=["--tta"], may=OUT,
     why="--tta is for --method model only: refused naming it (a silently ignored flag misleads)")
case("pred-sh-expected-error-explicit", "input", "", f"{PRED_SH} --input {OBJ} --out o --expected-error",
     expect="either", may=OUT,
     why="the baseline states no error: either refused naming --expected-error or a note, never a traceback")
case("pred-checkpoint-pt-with-other-model", "weights", "",
     f"$PY -m unips.predict --method model --no-expected-error --tta 1 --checkpoint $F/run/last.pt "
     f"--model glc-tiny --input {OBJ} --out o", names=["--model"], may=OUT,
     why="a glc-test training .pt with --model glc-tiny: one line naming --model and the file's model")
case("pred-checkpoint-is-a-prediction", "weights", "",
     f"$PY -m unips.predict --method model --no-expected-error --tta 1 --checkpoint $F/pred/00000/normal.exr "
     f"--input {OBJ} --out o", names=["--checkpoint"], may=OUT,
     why="an EXR handed as the weights is refused naming --checkpoint")
case("pred-nan-checkpoint-before-bad-mask", "order",
     "cp -r " + OBJ + " d\n" + py("""
import numpy as np, cv2, shutil, os, json
from safetensors.torch import load_file, save_file
m = cv2.imread('d/mask.png', cv2.IMREAD_UNCHANGED); m[0, 0] = 77; cv2.imwrite('d/mask.png', m)
base = os.environ['REPO'] + '/unips/weights/glc-tiny'
s = load_file(base + '.safetensors'); k = sorted(s)[3]; s[k] = s[k].clone(); s[k].view(-1)[0] = float('inf')
save_file(s, 'w.safetensors', metadata={'model_name': json.load(open(base + '.json'))['model_name']})
shutil.copy(base + '.json', 'w.json')
"""), f"{PRED} --checkpoint w.safetensors --input d --out o", names=["w.safetensors"], may=OUT,
     why="non-finite weights are refused first, before a bad mask is even read")

# ------------------------------------------------------------------------------------- predict: DiLiGenT layout
case("pred-ls-lights-all-same", "exit0", lights("np.tile(d[0], (len(d), 1))"),
     f"{PRED_LS} --input dil --out o", names=["light_directions.txt"], may=OUT,
     why="every light the same direction: least squares is singular; exit 0 with a map would be a wrong result")
case("pred-ls-lights-coplanar", "exit0",
     lights("np.stack([d[:, 0], np.zeros(len(d)), np.sqrt(1 - d[:, 0]**2)], 1)"),
     f"{PRED_LS} --input dil --out o", names=["light_directions.txt"], may=OUT,
     why="lights in one plane (rank 2) leave one normal component undetermined: refuse, not exit 0")
case("pred-dil-lights-nan-row", "input", lights("np.vstack([d[:5], [[np.nan]*3], d[6:]])"),
     f"{PRED_LS} --input dil --out o", names=["light_directions.txt"], may=OUT,
     why="a NaN light direction is refused naming the file")
case("pred-dil-lights-not-unit", "either", lights("d * 3.0"),
     f"{PRED_LS} --input dil --out o", expect="either", may=OUT,
     why="directions of length 3: normalised or refused naming the file, never a traceback")
case("pred-dil-lights-two-columns", "input", lights("d[:, :2]"),
     f"{PRED_LS} --input dil --out o", names=["light_directions.txt"], may=OUT,
     why="two numbers a row is not a direction: one line naming light_directions.txt")
case("pred-dil-intensities-negative", "input",
     DIL + py("""
import numpy as np
d = np.loadtxt('dil/light_intensities.txt'); d[3] = -d[3]; np.savetxt('dil/light_intensities.txt', d)
"""), f"{PRED_LS} --input dil --out o", names=["light_intensities.txt"], may=OUT,
     why="a negative intensity is refused naming light_intensities.txt (the images are divided by it)")
case("pred-dil-intensities-fewer-rows", "input",
     DIL + "head -n 10 dil/light_intensities.txt > t && mv t dil/light_intensities.txt\n",
     f"{PRED_LS} --input dil --out o", names=["light_intensities.txt"], may=OUT,
     why="10 intensities for all the images: refused naming the file, not broadcast or truncated")
case("pred-dil-mask-all-black", "input",
     DIL + py("""
import numpy as np, cv2
m = cv2.imread('dil/mask.png', cv2.IMREAD_UNCHANGED); cv2.imwrite('dil/mask.png', np.zeros_like(m))
"""), f"{PRED} --input dil --out o", names=["mask.png"], may=OUT,
     why="an empty mask leaves nothing to predict: one line naming mask.png, not an empty map with exit 0")
case("pred-dil-mask-grey-edge", "input",
     DIL + py("""
import numpy as np, cv2
m = cv2.imread('dil/mask.png', cv2.IMREAD_GRAYSCALE); m = cv2.GaussianBlur(m, (5, 5), 0)
cv2.imwrite('dil/mask.png', m)
"""), f"{PRED} --input dil --out o", names=["mask.png"], may=OUT,
     why="an anti-aliased (non-binary) mask is refused naming mask.png")
case("pred-dil-mask-other-size", "input",
     DIL + py("""
import cv2
m = cv2.imread('dil/mask.png', cv2.IMREAD_UNCHANGED); cv2.imwrite('dil/mask.png', m[:-3, :-5])
"""), f"{PRED} --input dil --out o", names=["mask.png"], may=OUT,
     why="a mask of another size than the images is refused naming it")
case("pred-dil-image-link-outside-listed", "input",
     DIL + 'rm dil/003.png && ln -s "$F/photos/$(ls $F/photos | head -1)" dil/003.png\n',
     f"{PRED} --input dil --out o", names=["003.png"], may=OUT,
     why="an image that is a link to a file outside the folder (another size and format): refused naming it")
case("pred-dil-listing-crlf-trailing-blank-lines", "input",
     DIL + "printf '\\r\\n\\r\\n\\r\\n' >> dil/filenames.txt\n",
     f"{PRED_LS} --input dil --out o", expect="ok", may=OUT,
     why="blank CRLF lines at the end of filenames.txt are not image names: read as the listing")
case("pred-dil-out-inside-dil-object", "writer", DIL, f"{PRED} --input dil --out dil/pred", names=["--out"],
     may=OUT, why="--out inside --input is refused naming --out; the DiLiGenT folder stays as it was")

# ------------------------------------------------------------------------------------- predict: official layout
case("pred-unips-natural-order", "exit0",
     "mkdir -p u\n" + py("""
import cv2, glob, os
src = sorted(glob.glob(os.environ['F'] + '/data8/00000.data/L*.png'))
for i, p in enumerate(src + src[:4]):
    cv2.imwrite(f'u/L{i + 1}.png', cv2.imread(p, cv2.IMREAD_UNCHANGED))
cv2.imwrite('u/mask.png', cv2.imread(os.environ['F'] + '/data8/00000.data/mask.png', cv2.IMREAD_UNCHANGED))
"""), f"{PRED} --input u --out o --max-images 10 && $PY -c \"import json,sys; "
      "d=json.load(open('o/u/predict.json')); want=['L%d.png' % i for i in range(1, 11)]; "
      "sys.exit(0 if d['images_used']==want else 'FAULT: first 10 in order '+str(d['images_used']))\"",
     expect="ok", may=OUT, why="L1..L12 in natural order: --max-images 10 takes L1..L10, not L1, L10, L11, L12, L2...")
case("pred-unips-exr-negative", "input",
     UNIPS_OBJ + py("""
import numpy as np, cv2, os
os.environ['OPENCV_IO_ENABLE_OPENEXR'] = '1'
from scenes.images import write_exr
for i in range(4):
    im = cv2.imread(f'u/obj.data/L00{i}.png', cv2.IMREAD_UNCHANGED)[..., ::-1].astype(np.float32) / 255
    if i == 2:
        im[5, 5] = -1.0
    write_exr(f'u/obj.data/L00{i}.exr', im); os.remove(f'u/obj.data/L00{i}.png')
"""), f"{PRED} --input u/obj.data --out o", names=["L002.exr"], may=OUT,
     why="a negative float radiance is refused naming the image")
case("pred-unips-txt-beside-images", "input",
     UNIPS_OBJ + "echo 'light 1' > u/obj.data/L_notes.txt\n", f"{PRED} --input u/obj.data --out o",
     expect="ok", may=OUT, why="a text file named L* is not an image (the official pattern skips .txt): predicted")
case("pred-unips-no-mask-sh", "engine", UNIPS_OBJ + "rm u/obj.data/mask.png\n",
     f"{PRED_SH} --input u/obj.data --out o", expect="either", may=OUT,
     why="no mask means the whole image: the baseline answers or refuses in one line, no traceback")
case("pred-unips-identical-images-sh", "exit0",
     UNIPS_OBJ + "for i in 1 2 3; do cp u/obj.data/L000.png u/obj.data/L00$i.png; done\n",
     f"{PRED_SH} --input u/obj.data --out o", names=["sh-uncalibrated"], may=OUT,
     why="4 copies of one image hold one lighting: the factorisation is undetermined; exit 0 with a map is wrong")
case("pred-unips-object-name-newline", "input",
     UNIPS_OBJ + "mv u/obj.data \"u/ob$(printf '\\n')j.data\"\n", f"{PRED} --input u --out o",
     expect="either", may=OUT,
     why="an object folder with a newline in its name: refused in one line or written under a sane name")

# ------------------------------------------------------------------------------------- predict: writers
case("pred-out-object-a-fifo", "writer", "mkdir o && mkfifo o/00000\n", f"{PRED} --input {OBJ} --out o",
     names=["00000"], timeout=60, why="the object's output is a fifo: refused naming it, no hang")
case("pred-while-evaluate-holds", "writer",
     "cp -r $F/pred p\n",
     f"{EVAL} --pred p --gt $F/data & e=$!; sleep 0.3; {PRED} --input $F/data --out p --overwrite; rc=$?; "
     "wait $e; exit $rc", expect="either", may=("$C/p/*", "$C/p/*/*"),
     why="predict --overwrite into a folder evaluate is reading: refused (folder held) or after it; no traceback")

# ------------------------------------------------------------------------------------------------- train: flags
T = f"{TRAIN} --data $F/data --out $C/run"
for flag, val in [("--batch", "0"), ("--batch", "-4"), ("--pixels", "0"), ("--min-images", "0"),
                  ("--val-every", "0"), ("--ckpt-every", "0"), ("--log-every", "0"), ("--res", "1"),
                  ("--val-pixels", "-1"), ("--canonical-points", "-5"), ("--clip-grad", "-1"),
                  ("--clip-grad", "inf"), ("--time-limit", "-1"), ("--ckpt-minutes", "nan"), ("--threads", "-2"),
                  ("--shuffle-buffer", "-1"), ("--warmup", "-10"), ("--min-lr-ratio", "2"),
                  ("--weight-decay", "nan"), ("--decay", "0")]:
    extra = " --schedule step" if flag == "--decay" else ""
    case(f"train{flag}-{val.replace('-', 'neg').replace('.', '')}", "input", "", f"{T} {flag} {val}{extra}",
         names=[flag], may=("$C/run", "$C/run/*"),
         why=f"{flag} {val} is out of range: one line naming {flag} before any data is read")
case("train-max-below-min-images", "input", "", f"{T} --max-images 2 --min-images 5",
     names=["--min-images"], may=("$C/run", "$C/run/*"),
     why="fewest images above most images: refused naming both, not a sampler that loops or crashes")
case("train-loader-workers-negative-streaming", "input", "", f"{TRAIN} --data $F/shards --out $C/run "
     "--shuffle-buffer 4 --loader-workers -1", names=["--loader-workers"], may=("$C/run", "$C/run/*"),
     why="a negative worker count is refused naming --loader-workers")
case("train-streaming-more-workers-than-shards", "input", "", f"{TRAIN} --data $F/shards --out $C/run "
     "--shuffle-buffer 4 --loader-workers 3", names=["--loader-workers"], may=("$C/run", "$C/run/*"),
     why="1 shard for 3 workers: refused (documented: at least processes x workers shards)")

# ------------------------------------------------------------------------------------------------- train: --data
case("train-data-twice", "input", "", f"{TRAIN} --data $F/data,$F/data --out $C/run", names=["--data"],
     may=("$C/run", "$C/run/*"), why="one dataset listed twice doubles its objects' weight silently: refused")
case("train-data-twice-through-link", "input", "ln -s $F/data d\n", f"{TRAIN} --data $F/data,$C/d --out $C/run",
     names=["--data"], may=("$C/run", "$C/run/*"),
     why="the same dataset through a link: the objects are the same files, refused as a duplicate")
case("train-data-dataset-and-own-object", "input", "", f"{TRAIN} --data $F/data,$F/data/00000.data "
     "--out $C/run", names=["--data"], may=("$C/run", "$C/run/*"),
     why="a dataset and one of its own objects overlap: refused naming --data")
case("train-data-trailing-comma", "input", "", f"{TRAIN} --data $F/data, --out $C/run", names=["--data"],
     may=("$C/run", "$C/run/*"), why="an empty element is not the current folder: refused naming --data")
case("train-data-brace-beyond-shards", "input", "",
     f"{TRAIN} --data \"$F/shards/{{000000..000003}}.tar\" --out $C/run", names=["000001.tar"],
     may=("$C/run", "$C/run/*"), why="a brace range naming shards that do not exist: refused naming the first")
case("train-data-shards-and-their-source", "input", "", f"{TRAIN} --data $F/shards,$F/data8 --out $C/run",
     expect="either", may=("$C/run", "$C/run/*"),
     why="shards and folders mixed in one --data: pooled or refused in one line, no traceback")
case("train-data-star-glob", "input", "", f"{TRAIN} --data '$F/shards/*.tar' --out $C/run", expect="either",
     may=("$C/run", "$C/run/*"), why="a * pattern (not braces): read or refused naming --data, no traceback")

# ------------------------------------------------------------------------------------------------- train: resume
RES = "cp -r $F/run run\n"
for flag, val in [("--batch", "3"), ("--res", "48"), ("--data", "$F/data"), ("--seed", "7"), ("--pixels", "77")]:
    data = "" if flag == "--data" else " --data $F/data8"
    case(f"train-resume-changed{flag}", "input", RES,
         f"$PY -m unips.train --model glc-test --steps 3 --no-progress --threads 1 --out $C/run --resume{data} "
         f"{flag} {val}", names=[flag], may=(),
         why=f"--resume continues bit for bit: a changed {flag} is refused naming it, the run left as it was")
case("train-resume-with-init-from", "input", RES,
     "$PY -m unips.train --model glc-test --steps 3 --no-progress --threads 1 --out $C/run --resume "
     "--data $F/data8 --init-from $F/run/final.safetensors", names=["--init-from"], may=(),
     why="--resume and --init-from contradict each other: refused naming them")

# ------------------------------------------------------------------------------------------------ train: torchrun
case("train-env-world-size-superscript", "message", "", f"WORLD_SIZE=² {T}", names=["WORLD_SIZE"],
     may=("$C/run", "$C/run/*"), why="'²'.isdigit() is True but int() refuses it: the line must name WORLD_SIZE")
case("train-env-rank-fullwidth-digit", "message", "", f"RANK=０ {T}", expect="either", names=["RANK"],
     may=("$C/run", "$C/run/*"), why="a full-width 0 is read as 0 or refused naming RANK, no traceback")
case("train-env-local-rank-beyond-world", "input", "",
     f"WORLD_SIZE=2 RANK=0 LOCAL_RANK=5 MASTER_ADDR=127.0.0.1 MASTER_PORT=1 UNIPS_JOIN_TIMEOUT_S=3 {T} --batch 2",
     names=["LOCAL_RANK"], may=("$C/run", "$C/run/*"), timeout=60,
     why="a local rank not below the world size is refused naming LOCAL_RANK, before any wait")
case("train-env-join-timeout-garbage", "input", "",
     f"WORLD_SIZE=2 RANK=0 LOCAL_RANK=0 MASTER_ADDR=127.0.0.1 MASTER_PORT=29517 UNIPS_JOIN_TIMEOUT_S=soon {T} "
     "--batch 2", names=["UNIPS_JOIN_TIMEOUT_S"], may=("$C/run", "$C/run/*"), timeout=60,
     why="a join timeout that is no number is refused naming the variable (not read as the 300 s default)")
case("train-env-join-timeout-inf", "input", "",
     f"WORLD_SIZE=2 RANK=0 LOCAL_RANK=0 MASTER_ADDR=127.0.0.1 MASTER_PORT=29519 UNIPS_JOIN_TIMEOUT_S=inf {T} "
     "--batch 2", names=["UNIPS_JOIN_TIMEOUT_S"], may=("$C/run", "$C/run/*"), timeout=60,
     why="an infinite join timeout would wait for ever for the second process: refused naming the variable")
case("train-env-master-addr-empty", "input", "",
     f"WORLD_SIZE=2 RANK=0 LOCAL_RANK=0 MASTER_ADDR= MASTER_PORT=29521 UNIPS_JOIN_TIMEOUT_S=5 {T} --batch 2",
     names=["MASTER_ADDR"], may=("$C/run", "$C/run/*"), timeout=60,
     why="an empty MASTER_ADDR is refused naming it, within the bounded wait")
case("train-env-batch-not-divisible", "input", "",
     f"WORLD_SIZE=2 RANK=0 LOCAL_RANK=0 MASTER_ADDR=127.0.0.1 MASTER_PORT=29523 UNIPS_JOIN_TIMEOUT_S=5 {T} "
     "--batch 3", names=["--batch"], may=("$C/run", "$C/run/*"), timeout=60,
     why="a global batch of 3 on 2 processes is refused naming --batch before any rendezvous wait")

# ------------------------------------------------------------------------------------------------- train: writers
case("train-out-inside-data", "writer", "cp -r $F/data d\n", f"{TRAIN} --data $C/d --out $C/d/run",
     names=["--out"], why="a run folder inside the training data would be read as an object next time: refused")
case("train-out-is-an-object-of-data", "writer", "cp -r $F/data d\n", f"{TRAIN} --data $C/d --out $C/d/00001.data",
     names=["--out"], why="--out an object folder of --data: refused, the object untouched")
case("train-nan-init-before-broken-data", "order",
     "cp -r $F/data d && head -c 100 $F/data/00000.data/L001.png > d/00000.data/L001.png\n" + py("""
import os, json, shutil
from safetensors.torch import load_file, save_file
base = os.environ['F'] + '/run/final'
s = load_file(base + '.safetensors'); k = sorted(s)[-1]; s[k] = s[k].clone(); s[k].view(-1)[0] = float('nan')
save_file(s, 'w.safetensors', metadata={'model_name': json.load(open(base + '.json'))['model_name']})
shutil.copy(base + '.json', 'w.json')
"""), f"{TRAIN} --data $C/d --out $C/run --init-from w.safetensors", names=["w.safetensors"],
     may=("$C/run", "$C/run/*"), why="NaN starting weights are refused before the (broken) data is read")

# ---------------------------------------------------------------------------------------------------- evaluate
case("eval-pred-equals-gt", "writer", "cp -r $F/data d\n", f"{EVAL} --pred d --gt d", names=["--pred"],
     why="--pred equal to --gt would write metrics and error maps into the ground-truth dataset: refused")
case("eval-npy-pickle", "archive",
     "mkdir -p p/00000\n" + py("""
import pickle, os, numpy as np
class E:
    def __reduce__(self):
        return (os.system, ('touch /tmp/pwn_e38_eval_npy',))
a = np.empty(1, dtype=object); a[0] = E()
np.save('p/00000/normal.npy', a, allow_pickle=True)
"""), f"{EVAL} --pred p --gt $F/data/00000.data", names=["normal.npy"], may=("$C/p/*", "$C/p/*/*"),
     why="a pickled object array under the prediction's name is refused by name, never unpickled")
case("eval-npy-nan", "input",
     "mkdir -p p/00000\n" + py("""
import numpy as np, os
from scenes.images import read_normals
n = read_normals(os.environ['F'] + '/data/00000.data/normal.tif').astype(np.float32); n[10:20, 10:20] = np.nan
np.save('p/00000/normal.npy', n)
"""), f"{EVAL} --pred p --gt $F/data/00000.data", names=["normal.npy"], may=("$C/p/*", "$C/p/*/*"),
     why="NaN normals inside the mask are refused (or the object failed), not averaged into a NaN metric")
case("eval-two-at-once", "writer", "cp -r $F/pred p\n",
     f"{EVAL} --pred $C/p --gt $F/data > a.log 2>&1 & a=$!; {EVAL} --pred $C/p --gt $F/data > b.log 2>&1; b=$?; "
     "wait $a; a=$?; cat a.log b.log; if [ $a = 0 ] && [ $b = 0 ]; then echo 'FAULT: both wrote'; exit 0; fi; "
     "[ $a = 0 ] || [ $b = 0 ] || { echo 'FAULT: both failed'; exit 0; }; exit 3",
     names=[], may=("$C/p/*", "$C/p/*/*", "$C/a.log", "$C/b.log"),
     why="two evaluations into one --pred: one writes, the other is refused naming --pred (one writer per folder)")
case("eval-gt-diligent-without-truth", "input", DIL + "rm dil/Normal_gt.*\n" + "mkdir -p p && cp -r $F/pred/00000 p/dil\n",
     f"{EVAL} --pred p --gt dil", names=["dil"], may=("$C/p/*", "$C/p/*/*"),
     why="a DiLiGenT folder without Normal_gt has no truth: refused naming it, exit non-zero")

# --------------------------------------------------------------------------------------------------- benchmark
case("bench-counts-negative", "input", "", f"{BENCH} --data $F/data --counts -1 --out o", names=["--counts"],
     may=OUT, why="a negative image count: refused naming --counts")
case("bench-images-zero", "input", "", f"{BENCH} --data $F/data --images 0 --out o", names=["--images"],
     may=OUT, why="0 images per object: refused naming --images")
case("bench-out-equals-data", "writer", "cp -r $F/data d\n", f"{BENCH} --data d --out d", names=["--out"],
     why="tables.md and benchmark.json written into the dataset: refused naming --out")
case("bench-out-inside-data-object", "writer", "cp -r $F/data d\n", f"{BENCH} --data d --out d/00000.data/b",
     names=["--out"], why="--out inside an object of --data would add a folder the readers see: refused")
case("bench-threads-zero", "input", "", "$PY -m orchestrate.benchmark --data $F/data --threads 0 "
     "--rerender-objects 0 --out o", names=["--threads"], may=OUT, why="0 torch threads: refused naming --threads")
case("bench-rerender-objects-negative", "input", "", "$PY -m orchestrate.benchmark --data $F/data --threads 1 "
     "--rerender-objects -3 --out o", names=["--rerender-objects"], may=OUT,
     why="a negative object count is refused naming --rerender-objects")
case("bench-sdm-with-our-file", "weights", "", f"{BENCH} --data $F/data --model sdm-unips "
     "--checkpoint $F/run/final.safetensors --out o", names=["--model"], may=OUT,
     why="--model sdm-unips with a glc-test file: refused naming --model before any prediction")

# -------------------------------------------------------------------------------------------------------- ship
ROUT = "--val $F/empty"
case("ship-threads-zero", "input", "mkdir -p cand/run && cp $F/run/final.* cand/run/\n",
     f"{SHIP} --candidate cand {ROUT} --threads 0", names=["--threads"],
     why="0 threads is refused naming --threads (an empty --val keeps a missed check away from unips/weights)")
case("ship-final-sparse-17mib", "input", "mkdir -p cand/run && cp $F/run/final.json cand/run/ && "
     "truncate -s 17M cand/run/final.safetensors\n", f"{SHIP} --candidate cand {ROUT}",
     names=["final.safetensors"], why="a candidate over 16 MiB is refused in one line naming the file")
case("ship-candidate-link-loop", "input", "ln -s cand cand\n", f"{SHIP} --candidate cand {ROUT}",
     names=["--candidate"], why="a link to itself is refused naming --candidate, no traceback")
case("ship-candidate-equals-val", "input", "cp -r $F/data v && mkdir -p v/run && cp $F/run/final.* v/run/\n",
     f"{SHIP} --candidate v --val v --diligent none", names=["--candidate"],
     why="the candidate folder is the validation set: refused naming --candidate (and nothing is shipped)")

# ----------------------------------------------------------------------------------------------- error_calibration
ECO = "--out $C/ec.json --work $C/w"
case("ec-objects-zero", "input", "", f"{EC} {ECO} --objects 0", names=["--objects"],
     may=("$C/w", "$C/w/*", "$C/ec.json"), timeout=60, why="0 objects per row is refused before any render")
case("ec-pixels-zero", "input", "", f"{EC} {ECO} --pixels 0", names=["--pixels"],
     may=("$C/w", "$C/w/*", "$C/ec.json"), timeout=60, why="0 pixels per object is refused before any render")
case("ec-threads-negative", "input", "", f"$PY -m orchestrate.error_calibration --assets none {ECO} --threads -1",
     names=["--threads"], may=("$C/w", "$C/w/*", "$C/ec.json"), timeout=60,
     why="a negative thread count is refused naming --threads")
case("ec-work-a-file", "input", "echo hi > w\n", f"{EC} --out $C/ec.json --work $C/w", names=["--work"],
     timeout=60, why="--work a plain file is refused naming it, the file kept")
case("ec-out-a-fifo", "input", "mkfifo ec.json\n", f"{EC} {ECO} --objects 0", names=["--objects"],
     may=("$C/w", "$C/w/*"), timeout=60, why="--out a fifo is refused (no hang), or --objects first; no traceback")
case("ec-out-inside-work", "writer", "", f"{EC} --work $C/w --out $C/w/fit.json --objects 0",
     names=["--objects"], may=("$C/w", "$C/w/*"), timeout=60,
     why="bad --objects is named even when --out lies inside --work; nothing rendered")

# ------------------------------------------------------------------------------------------------------ export
case("export-shard-size-zero", "input", "", f"{EXPORT} --data $F/data --out s --shard-size 0",
     names=["--shard-size"], may=("$C/s", "$C/s/*"), why="0 objects per shard: refused naming --shard-size")
case("export-shard-size-negative", "input", "", f"{EXPORT} --data $F/data --out s --shard-size -5",
     names=["--shard-size"], may=("$C/s", "$C/s/*"), why="a negative shard size: refused naming --shard-size")
case("export-data-is-shards", "input", "", f"{EXPORT} --data $F/shards --out s", names=["--data"],
     may=("$C/s", "$C/s/*"), why="shards are not a dataset of object folders: refused naming --data")
case("export-out-in-object", "writer", "cp -r $F/data d\n", f"{EXPORT} --data d --out d/00000.data/sh",
     names=["--out"], why="shards inside an object folder of --data: refused naming --out")
case("export-image-link-to-passwd", "archive",
     "cp -r $F/data d && rm d/00001.data/L002.png && ln -s /etc/passwd d/00001.data/L002.png\n",
     f"{EXPORT} --data d --out s; rc=$?; if grep -aq 'root:' s/*.tar 2>/dev/null; then "
     "echo 'FAULT: /etc/passwd archived'; exit 0; fi; [ $rc = 0 ] && echo 'exported (checked: no leak)' && exit 3; "
     "exit $rc", names=["L002.png"], may=("$C/s", "$C/s/*"),
     why="an image that is a link to /etc/passwd is refused naming it, never archived into a shard")
case("export-aux-link-outside", "archive",
     "cp -r $F/data d && ln -s /etc/passwd d/00000.data/aux/notes.exr\n",
     f"{EXPORT} --data d --out s --aux; rc=$?; if grep -aq 'root:' s/*.tar 2>/dev/null; then "
     "echo 'FAULT: /etc/passwd archived'; exit 0; fi; [ $rc = 0 ] && echo 'exported (checked: no leak)' && exit 3; "
     "exit $rc", names=[], may=("$C/s", "$C/s/*"),
     why="with --aux, an aux file that is a link out of the object is refused or skipped, never archived")
case("export-mixed-layouts", "input", "mkdir d && cp -r $F/data/00000.data d/ && cp -r $F/ballPNG d/ballPNG\n",
     f"{EXPORT} --data d --out s", expect="either", may=("$C/s", "$C/s/*"),
     why="ours and DiLiGenT objects in one dataset: exported or refused in one line, no traceback")
case("export-decoded-unips-layout", "input", UNIPS_OBJ, f"{EXPORT} --data u --out s --encoding decoded",
     expect="either", may=("$C/s", "$C/s/*"),
     why="an official-layout dataset (no scene.json) as decoded shards: exported or refused in one line")
