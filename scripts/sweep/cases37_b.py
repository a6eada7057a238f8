"""Sweep 37, part b: the MODEL side (unips.predict / train / evaluate, orchestrate.ship / error_calibration /
benchmark). Mechanisms probed: untrusted archives and names (shard members, pickles, zip members, DiLiGenT
listings) never write outside the target; weights are finite floats of the network's kind, checked before any
other work (photos, asset split, benchmark folder); a forged training checkpoint (re-checksummed, or without a
checksum) is refused by what it holds (scheduler, RNG, optimiser hyper-parameters, extra); one writer per folder;
messages name the right flag and file. Ship and error_calibration cases are all refusals made before either
would write into the repository's unips/weights (never run them with valid inputs).
"""
from __future__ import annotations

SHIPPED = "$REPO/unips/weights/glc-tiny"
OBJ = "$F/data/00000.data"
PRED_MODEL = "$PY -m unips.predict --method model --no-expected-error --tta 1"
TRAIN = "$PY -m unips.train --model glc-test --steps 1 --no-progress --threads 1"
RESUME = ("$PY -m unips.train --data $F/data8 --out $C/run --model glc-test --steps 2 --no-progress --resume")


def st(code: str, dst: str = "w/m", src: str = "SHIPPED") -> str:
    """Copy the shipped glc-tiny weights (or $F/run/final) to $C/<dst>.safetensors (+ .json), run `code` on the
    tensor dict `s` (`k`: its last tensor name, `k0`: its first), save with the model_name metadata."""
    base = "os.environ['REPO'] + '/unips/weights/glc-tiny'" if src == "SHIPPED" else \
        "os.environ['F'] + '/run/final'"
    return f"""mkdir -p "$(dirname {dst})"
$PY - {dst} <<'EOF'
import os, sys, json, shutil, torch
from safetensors.torch import load_file, save_file
base = {base}
dst = sys.argv[1]
shutil.copy(base + '.json', dst + '.json')
s = load_file(base + '.safetensors')
names = sorted(s)
k, k0 = names[-1], names[0]
meta = {{'model_name': json.load(open(base + '.json'))['model_name']}}
{code}
save_file(s, dst + '.safetensors', metadata=meta)
EOF
"""


def forge_pt(code: str, dst: str = "run/last.pt", checksum: str = "recompute") -> str:
    """Copy $F/run to $C/run and rewrite its last.pt: `code` edits the dict `ck`; the checksum is recomputed
    (an attacker's consistent forgery), dropped (a checkpoint from before checksums) or kept."""
    if dst == "run/last.pt" and "RESUME" in code:
        code = "ck['step'] = 1\n" + code.replace("RESUME", "")
    fix = {"recompute": "ck[CHECKSUM_KEY] = content_digest(ck)", "drop": "ck.pop(CHECKSUM_KEY, None)",
           "keep": "pass"}[checksum]
    return f"""cp -r $F/run run
$PY - {dst} <<'EOF'
import os, sys, math, torch
from unips.models.builder import content_digest, CHECKSUM_KEY
ck = torch.load(os.environ['F'] + '/run/last.pt', weights_only=False)  # the sweep's own fixture
{code}
{fix}
os.makedirs(os.path.dirname(sys.argv[1]) or '.', exist_ok=True)
torch.save(ck, sys.argv[1])
EOF
"""


def shard(code: str) -> str:
    """Rebuild $F/shards/000000.tar into $C/s/000000.tar after `code` edits `mem` (a list of dicts: name, data,
    and optionally type 'sym' / 'hard' / 'dir' with linkname, or pax for PAX headers), and write an index.json that
    agrees with it (sizes, sha256, the keys webdataset will read, in order): only the members are hostile."""
    return f"""mkdir -p s
$PY - <<'EOF'
import os, io, re, json, tarfile, hashlib
F = os.environ['F']
src = tarfile.open(F + '/shards/000000.tar')
mem = [dict(name=m.name, data=src.extractfile(m).read()) for m in src if m.isreg()]
{code}
with tarfile.open('s/000000.tar', 'w', format=tarfile.PAX_FORMAT) as t:
    for m in mem:
        ti = tarfile.TarInfo(m['name'])
        ti.mtime = 0
        kind = m.get('type')
        if kind == 'sym':
            ti.type, ti.linkname = tarfile.SYMTYPE, m['linkname']; t.addfile(ti)
        elif kind == 'hard':
            ti.type, ti.linkname = tarfile.LNKTYPE, m['linkname']; t.addfile(ti)
        elif kind == 'dir':
            ti.type = tarfile.DIRTYPE; t.addfile(ti)
        else:
            if m.get('pax'):
                ti.pax_headers = m['pax']
            ti.size = len(m['data']); t.addfile(ti, io.BytesIO(m['data']))
keys = []
for m in mem:
    name = m.get('pax', {{}}).get('path', m['name'])
    g = re.match(r'^((?:.*/|)[^.]+)[.]([^/]*)$', name)
    key = g.group(1) if g else name
    if key not in keys:
        keys.append(key)
idx = json.load(open(F + '/shards/index.json'))
b = open('s/000000.tar', 'rb').read()
e = idx['shards'][0]
e['bytes'], e['sha256'] = len(b), hashlib.sha256(b).hexdigest()
e['objects'] = [dict(folder=k + '.data', images=8, name=k) for k in keys]
idx['objects'] = len(keys)
json.dump(idx, open('s/index.json', 'w'), indent=1, sort_keys=True)
EOF
"""


TRAIN_S = f"{TRAIN} --data $C/s --out $C/run"

PUB_SDM = """mkdir -p pub/normal
$PY - <<'EOF'
import torch
from unips.models import create_model
m = create_model('sdm-unips-tiny')
torch.save({'module.' + k: v for k, v in m.state_dict().items()}, 'pub/normal/nml.pytmodel')
EOF
"""

EVIL_DIR = """mkdir -p "$C/../evil_$(basename $C)" && touch -d '2 hours ago' "$C/../evil_$(basename $C)"
"""

def mal_pickle(path: str, legacy: bool = False) -> str:
    opt = ", _use_new_zipfile_serialization=False" if legacy else ""
    return f"""mkdir -p "$(dirname {path})"
$PY - <<'EOF'
import os, torch
class P:
    def __reduce__(self):
        return (os.system, ('touch /tmp/pwn_' + os.path.basename(os.environ['C']),))
torch.save({{'format': 'unips-train/1', 'model_name': 'glc-test', 'model': P()}}, '{path}'{opt})
EOF
"""


def both(a: str, b: str) -> str:
    """Two commands started together into one folder; exit 0 when exactly one of them was refused."""
    return (f"( {a} ) & pa=$!; ( {b} ) & pb=$!; wait $pa; ra=$?; wait $pb; rb=$?; echo \"exits $ra $rb\"; "
            "[ $ra -ne 0 -o $rb -ne 0 ] && [ $ra -eq 0 -o $rb -eq 0 ]")


CASES: list[dict] = []


def case(id_, kind, setup, cmd, expect="refuse", names=(), may=(), timeout=120, why=""):
    CASES.append(dict(id="b37-" + id_, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may), timeout=timeout, why=why))


OUT = ("$C/o", "$C/o/*", "$C/o/*/*")

# ------------------------------------------------------------------ unips.predict: our model files
case("pred-st-bf16-nan", "weights", st("s[k] = s[k].to(torch.bfloat16); s[k].view(-1)[0] = float('nan')"),
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors", "NaN"],
     may=OUT, why="a NaN stored as bfloat16 is as non-finite as one in float32: refused naming the file and tensor")
case("pred-st-complex", "weights", st("s[k] = s[k].to(torch.complex64)"),
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors"], may=OUT,
     why="complex weights are not the float weights the network holds: refused, not cast (imaginary part dropped)")
case("pred-st-bool", "weights", st("s[k] = s[k] > 0"),
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors", "bool"],
     may=OUT, why="a boolean tensor where a float weight belongs is a damaged file, refused naming the tensor")
case("pred-st-uint8", "weights", st("s[k0] = (s[k0].abs() * 10).clamp(0, 255).to(torch.uint8)"),
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors", "uint8"],
     may=OUT, why="uint8 values for a float weight would be cast silently: refused")
case("pred-st-truncated-half", "weights",
     "mkdir -p w; cp " + SHIPPED + ".json w/m.json; head -c 2000000 " + SHIPPED + ".safetensors > w/m.safetensors",
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors"], may=OUT,
     why="a truncated download is one line naming the file, no traceback, nothing written")
case("pred-st-header-only", "weights",
     "mkdir -p w; cp " + SHIPPED + ".json w/m.json; $PY -c \"import struct,sys; b=open('" + SHIPPED +
     ".safetensors','rb').read(); n=struct.unpack('<Q',b[:8])[0]; open('w/m.safetensors','wb').write(b[:8+n])\"",
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors"], may=OUT,
     why="a header with no tensor bytes after it is truncated, refused in one line")
case("pred-st-header-length-huge", "weights",
     "mkdir -p w; cp " + SHIPPED + ".json w/m.json; $PY -c \"import struct; open('w/m.safetensors','wb').write("
     "struct.pack('<Q', 2**62) + b'{}' * 8)\"",
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors"], may=OUT,
     timeout=60, why="a header claiming 4 EiB must be refused without trying to allocate it")
case("pred-st-empty-file", "weights", "mkdir -p w; cp " + SHIPPED + ".json w/m.json; : > w/m.safetensors",
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors"], may=OUT,
     why="a zero-byte weights file (a failed copy) is refused naming it")
case("pred-st-metadata-other-network", "weights", st("meta = {'model_name': 'sdm-unips-tiny'}"),
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.json", "m.safetensors"],
     may=OUT, why="the weights' own record names another network than the sidecar: the sidecar belongs elsewhere")
case("pred-st-tensor-transposed", "weights",
     st("kk = next(n for n in names if s[n].dim() == 2 and s[n].shape[0] != s[n].shape[1])\n"
        "s[kk] = s[kk].t().contiguous()"),
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors", "shape"],
     may=OUT, why="a transposed matrix has the right number of values but the wrong shape: refused naming it")
case("pred-st-extra-tensor", "weights", st("s['evil.extra'] = torch.zeros(3)"),
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["evil.extra"], may=OUT,
     why="an unexpected tensor means other weights: refused naming it, never ignored")
case("pred-st-missing-tensor", "weights", st("del s[k0]"),
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.safetensors"], may=OUT,
     why="a missing tensor would leave random weights: refused naming the file")
case("pred-sidecar-dev-zero", "input",
     "mkdir -p w; cp " + SHIPPED + ".safetensors w/m.safetensors; ln -s /dev/zero w/m.json",
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.json"], may=OUT,
     timeout=60, why="a sidecar that is a link to an endless device must be refused, never read until memory runs out")
case("pred-sidecar-fifo", "input", "mkdir -p w; cp " + SHIPPED + ".safetensors w/m.safetensors; mkfifo w/m.json",
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.json"], may=OUT,
     timeout=60, why="a pipe where the sidecar belongs must be refused at once, not block the command")
case("pred-pt-fifo", "input", "mkfifo m.pt",
     f"{PRED_MODEL} --checkpoint $C/m.pt --input {OBJ} --out $C/o", names=["m.pt"], may=OUT, timeout=60,
     why="a pipe given as --checkpoint must be refused at once, not block")
case("pred-sidecar-model-name-a-path", "weights",
     st("pass") + "$PY -c \"import json; d=json.load(open('w/m.json')); d['model_name']='../../evil_x'; "
     "json.dump(d, open('w/m.json','w'))\"",
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input {OBJ} --out $C/o", names=["m.json"], may=OUT,
     why="a model name read from a file is looked up in the registry, never used as a path; refused naming the file")
case("pred-pt-malicious-reduce", "archive", mal_pickle("m.pt"),
     f"{PRED_MODEL} --checkpoint $C/m.pt --input {OBJ} --out $C/o", names=["m.pt"], may=OUT,
     why="a pickle that would run a shell command is refused by the weights-only reader; no /tmp/pwn_ file appears")
case("pred-pt-legacy-malicious-reduce", "archive", mal_pickle("m.pt", legacy=True),
     f"{PRED_MODEL} --checkpoint $C/m.pt --input {OBJ} --out $C/o", names=["m.pt"], may=OUT,
     why="the legacy (non-zip) torch format is unpickled too: it must take the same weights-only path, no code run")
case("pred-pt-zip-member-above", "archive",
     "$PY - <<'EOF'\nimport zipfile\nz = zipfile.ZipFile('m.pt', 'w')\nz.writestr('archive/data.pkl', b'\\x80\\x02}q\\x00.')"
     "\nz.writestr('../../evil_b37_zip', b'x')\nz.writestr('archive/version', b'3')\nz.close()\nEOF\n",
     f"{PRED_MODEL} --checkpoint $C/m.pt --input {OBJ} --out $C/o", names=["m.pt"], may=OUT,
     why="a zip .pt whose member names climb out is read, never unpacked; refused as no training checkpoint")
case("pred-pt-optimizer-nan-but-weights-fine", "weights",
     forge_pt("st = ck['optimizer']['state']\nfor s in st.values():\n    for v in s.values():\n"
              "        if torch.is_tensor(v) and v.is_floating_point(): v.fill_(float('nan'))"),
     f"{PRED_MODEL} --checkpoint $C/run/last.pt --input {OBJ} --out $C/o", expect="ok", may=OUT,
     why="prediction reads only the weights of a .pt; a NaN optimiser moment does not concern it")
case("pred-pt-no-checksum-nan-weight", "weights",
     forge_pt("kk = sorted(ck['model'])[0]\nck['model'][kk].view(-1)[0] = float('inf')", checksum="drop"),
     f"{PRED_MODEL} --checkpoint $C/run/last.pt --input {OBJ} --out $C/o", names=["last.pt"], may=OUT,
     why="a checkpoint without a checksum (older format) is still checked for non-finite weights")
case("pred-pt-config-a-string", "weights", forge_pt("ck['config'] = 'glc-test'"),
     f"{PRED_MODEL} --checkpoint $C/run/last.pt --input {OBJ} --out $C/o", names=["last.pt", "config"], may=OUT,
     why="a forged config of the wrong kind is one line naming the file, no traceback")
case("pred-pt-model-name-other", "weights", forge_pt("ck['model_name'] = 'glc-tiny'"),
     f"{PRED_MODEL} --checkpoint $C/run/last.pt --input {OBJ} --out $C/o", names=["last.pt"], may=OUT, expect="either",
     why="glc-test tensors under glc-tiny's name: refused naming the file, or built from the checkpoint's own config "
         "(which describes the whole network: glc-tiny and glc-test are one class), either is right")
case("pred-nan-weights-before-truncated-photo", "order",
     st("s[k].view(-1)[0] = float('nan')") + "cp -r " + OBJ + " obj; head -c 300 obj/L001.png > t && mv t obj/L001.png",
     f"{PRED_MODEL} --checkpoint $C/w/m.safetensors --input $C/obj --out $C/o", names=["m.safetensors", "NaN"],
     may=OUT, why="weights are checked before any photo is read: the refusal names the weights, not the image")
case("pred-model-disagrees-with-file", "message", "",
     f"{PRED_MODEL} --model glc-tiny --checkpoint $F/run/final.safetensors --input {OBJ} --out $C/o",
     names=["--model", "glc-test"], may=OUT,
     why="--model glc-tiny with a glc-test file: the flags contradict each other, refused naming both")
case("pred-sdm-model-with-our-file", "message", "",
     f"{PRED_MODEL} --model sdm-unips-tiny --checkpoint {SHIPPED}.safetensors --input {OBJ} --out $C/o",
     names=["--model"], may=OUT, why="our glc-tiny file is not published SDM-UniPS weights: one line naming --model")
case("pred-ls-with-nan-checkpoint", "message", st("s[k].view(-1)[0] = float('nan')"),
     "$PY -m unips.predict --method least-squares --checkpoint $C/w/m.safetensors --input $F/ballPNG --out $C/o",
     names=["--checkpoint"], may=OUT, why="--checkpoint is for --method model only; given to least squares it is refused")
case("pred-sh-with-res", "message", "",
     f"$PY -m unips.predict --method sh-uncalibrated --res 64 --input {OBJ} --out $C/o", names=["--res"], may=OUT,
     why="--res is a network flag; silently ignoring it for a baseline misleads")
case("pred-ls-with-tta", "message", "",
     "$PY -m unips.predict --method least-squares --tta 4 --input $F/ballPNG --out $C/o", names=["--tta"], may=OUT,
     why="--tta is for --method model only")

# ------------------------------------------------------------------ unips.predict: published weights folders
case("pred-pub-fifo", "input", "mkdir -p pub/normal; mkfifo pub/normal/nml.pytmodel",
     f"{PRED_MODEL} --model sdm-unips-tiny --checkpoint $C/pub --input {OBJ} --out $C/o", names=["nml.pytmodel"],
     may=OUT, timeout=60, why="a pipe named like the published file is refused at once, not read forever")
case("pred-pub-dev-zero", "input", "mkdir -p pub/normal; ln -s /dev/zero pub/normal/nml.pytmodel",
     f"{PRED_MODEL} --model sdm-unips-tiny --checkpoint $C/pub --input {OBJ} --out $C/o", names=["nml.pytmodel"],
     may=OUT, timeout=60, why="a link to /dev/zero as the published file is refused, never read to exhaustion")
case("pred-pub-a-folder", "input", "mkdir -p pub/normal/nml.pytmodel",
     f"{PRED_MODEL} --model sdm-unips-tiny --checkpoint $C/pub --input {OBJ} --out $C/o", names=["nml.pytmodel"],
     may=OUT, why="a folder named nml.pytmodel is not the weights file: one line naming it")
case("pred-pub-prefix-mixed", "weights",
     PUB_SDM + "$PY -c \"import torch; s=torch.load('pub/normal/nml.pytmodel'); k=sorted(s)[0]; "
     "s[k[len('module.'):]]=s.pop(k); torch.save(s,'pub/normal/nml.pytmodel')\"",
     f"{PRED_MODEL} --model sdm-unips-tiny --checkpoint $C/pub --input {OBJ} --out $C/o", names=["missing tensors"],
     may=OUT, why="one key without the DataParallel prefix: names do not match, refused naming them (no random weights)")
case("pred-pub-glc-two-encoders", "input",
     "mkdir -p pub; for n in a_enc b_enc x_agg x_pred; do : > pub/$n.pytmodel; done",
     f"{PRED_MODEL} --model glc-unips-tiny --checkpoint $C/pub --input {OBJ} --out $C/o",
     names=["a_enc.pytmodel", "b_enc.pytmodel"], may=OUT,
     why="two files match *_enc.pytmodel: ambiguous, refused naming both")
case("pred-pub-glc-one-file", "message", PUB_SDM,
     f"{PRED_MODEL} --model glc-unips-tiny --checkpoint $C/pub/normal/nml.pytmodel --input {OBJ} --out $C/o",
     names=["--checkpoint"], may=OUT, why="UniPS needs a folder of three files; one .pytmodel file is refused in one line")

# ------------------------------------------------------------------ unips.predict: layouts
case("pred-dil-extra-digit-image-no-listing", "input",
     "cp -r $F/ballPNG dil; rm dil/filenames.txt; cp dil/001.png dil/097.png",
     "$PY -m unips.predict --method least-squares --input $C/dil --out $C/o", names=["light_directions.txt"],
     may=OUT, why="97 digit images for 96 light directions: refused naming the light file, never paired off by one")
case("pred-dil-listing-bom-crlf", "exit0",
     "cp -r $F/ballPNG dil; printf '\\xef\\xbb\\xbf' > t; sed 's/$/\\r/' dil/filenames.txt >> t; mv t dil/filenames.txt",
     "$PY -m unips.predict --method least-squares --input $C/dil --out $C/o", expect="ok", may=OUT, timeout=120,
     why="a listing saved by a Windows editor (BOM, CRLF) names the same images")
case("pred-dil-image-link-to-other-size", "input",
     "cp -r $F/ballPNG dil; rm dil/005.png; ln -s $F/photos/photo00.jpg dil/005.png",
     "$PY -m unips.predict --method least-squares --input $C/dil --out $C/o", names=["005.png"], may=OUT,
     why="an image of another size (and format) among the photos is refused naming it")
case("pred-dil-listing-names-a-folder", "input", "cp -r $F/ballPNG dil; rm dil/003.png; mkdir dil/003.png",
     "$PY -m unips.predict --method least-squares --input $C/dil --out $C/o", names=["003.png"], may=OUT,
     why="a listed image that is a folder is refused naming it, not skipped")
case("pred-unips-sizes-differ", "input",
     "mkdir obj; cp " + OBJ + "/L00[0-3].png obj/; cp " + OBJ + "/mask.png obj/; "
     "$PY -c \"import cv2; im=cv2.imread('obj/L002.png', -1); cv2.imwrite('obj/L002.png', cv2.resize(im, (40, 40)))\"",
     f"{PRED_MODEL} --input $C/obj --out $C/o", names=["L002.png"], may=OUT,
     why="in the official layout an image of another size is refused naming it")
case("pred-unips-exr-nan", "input",
     "mkdir obj; cp " + OBJ + "/mask.png obj/; $PY - <<'EOF'\nimport os, glob\n"
     "import cv2, numpy as np\nfrom scenes.exr import write_exr\n"
     "for i, p in enumerate(sorted(glob.glob(os.environ['F'] + '/data/00000.data/L*.png'))):\n"
     "    im = cv2.imread(p, -1).astype(np.float32) / 65535\n    if i == 1: im[16, 16] = np.nan\n"
     "    write_exr('obj/L%03d.exr' % i, im[..., ::-1].copy())\nEOF",
     f"{PRED_MODEL} --input $C/obj --out $C/o", names=["L001.exr"], may=OUT,
     why="a NaN pixel in an EXR photo is refused naming the file, never fed to the network")
case("pred-unips-mixed-bit-depth", "input",
     "mkdir obj; cp " + OBJ + "/L00[0-3].png obj/; cp " + OBJ + "/mask.png obj/; "
     "$PY -c \"import cv2; im=cv2.imread('obj/L001.png', -1); cv2.imwrite('obj/L001.png', (im // 257).astype('uint8'))\"",
     f"{PRED_MODEL} --input $C/obj --out $C/o", expect="either", may=OUT,
     why="8-bit and 16-bit images in one object: scaled alike (each by its range) or refused naming L001.png")

# ------------------------------------------------------------------ unips.predict: writers
case("pred-two-models-into-one-out", "writer", "",
     both(f"{PRED_MODEL} --input $F/data --out $C/o", f"{PRED_MODEL} --input $F/data --out $C/o --tta 2"),
     expect="ok", may=OUT, timeout=120,
     why="two predictions into one folder: exactly one writes, the other is refused (held or already written)")
case("pred-interrupted-then-again", "writer", "",
     f"timeout -s INT 4 {PRED_MODEL} --input $F/data --out $C/o; {PRED_MODEL} --input $F/data --out $C/o --overwrite",
     expect="ok", may=OUT, timeout=120,
     why="Ctrl-C leaves no stale lock or half object: the same command with --overwrite then succeeds")

# ------------------------------------------------------------------ unips.train: hostile shards
RUN = ("$C/run", "$C/run/*")
case("train-shard-key-climbs-out", "archive",
     shard("mem = [dict(m, name=m['name'].replace('00000.', '../../evil_b37_key.', 1)) for m in mem]"),
     TRAIN_S, names=["--data", "000000.tar"], may=RUN,
     why="a sample key with ../ never becomes a folder: refused before anything is unpacked, no evil_ file")
case("train-shard-key-absolute", "archive",
     shard("mem = [dict(m, name=m['name'].replace('00000.', '/tmp/pwn_b37_abs.', 1)) for m in mem]"),
     TRAIN_S, names=["--data", "000000.tar"], may=RUN, why="an absolute member path is refused, nothing written in /tmp")
case("train-shard-member-symlink", "archive",
     shard("mem[0] = dict(name=mem[0]['name'], data=b'', type='sym', linkname='/etc/passwd')"),
     TRAIN_S, names=["--data", "000000.tar"], may=RUN, why="a symlink member is refused, never followed or extracted")
case("train-shard-member-hardlink", "archive",
     shard("mem[1] = dict(name=mem[1]['name'], data=b'', type='hard', linkname=mem[0]['name'])"),
     TRAIN_S, names=["--data", "000000.tar"], may=RUN, why="a hard-link member is refused (not a plain file)")
case("train-shard-member-dir", "archive",
     shard("mem.insert(1, dict(name='00000.sub', data=b'', type='dir'))"),
     TRAIN_S, names=["--data", "000000.tar"], may=RUN, why="a folder member is refused, not silently skipped")
case("train-shard-key-newline", "archive",
     shard("mem = [dict(m, name=m['name'].replace('00000.', '000\\n00.', 1)) for m in mem]"),
     TRAIN_S, names=["--data"], may=RUN, why="a key with a newline is no plain object name: refused in one line")
case("train-shard-key-too-long", "archive",
     shard("mem = [dict(m, name=m['name'].replace('00000.', 'a' * 300 + '.', 1)) for m in mem]"),
     TRAIN_S, names=["--data"], may=RUN, why="a 300-byte key would make a too-long folder name: refused by the key rule")
case("train-shard-suffix-dotdot", "archive",
     shard("mem.insert(1, dict(name='00000...', data=b'x'))"),
     TRAIN_S, names=["--data"], may=RUN, why="member suffix '..' names no file inside the sample folder: refused")
case("train-shard-aux-suffix-dotdot", "archive",
     shard("mem.insert(1, dict(name='00000.aux...', data=b'x'))"),
     TRAIN_S, names=["--data"], may=RUN, why="the aux/ member 'aux...' names the parent: refused before unpacking")
case("train-shard-pax-path-climbs", "archive",
     shard("mem[0] = dict(mem[0], pax={'path': '../../evil_b37_pax.L000.png'})"),
     TRAIN_S, names=["--data"], may=RUN,
     why="a PAX header rewriting a member's path out of the folder is refused like the plain name")
case("train-shard-key-unicode", "input",
     shard("mem = [dict(m, name=m['name'].replace('00001.', 'obj\\u00e9t 1.', 1)) for m in mem]"),
     TRAIN_S, expect="either", may=RUN, why="a printable unicode key with a space: trained on, or refused in one line")
case("train-shard-duplicate-member", "archive",
     shard("mem.insert(2, dict(name=mem[1]['name'], data=b'not a png'))"),
     TRAIN_S, names=["--data", "000000.tar"], may=RUN,
     why="one member name twice (two contents for one file) is refused, not last-wins")

# ------------------------------------------------------------------ unips.train: resume from forged runs
case("train-resume-scheduler-base-lr-nan", "weights", forge_pt("RESUMEck['scheduler']['base_lrs'] = [float('nan')]"),
     RESUME.replace("--steps 2", "--steps 3"), names=["--resume", "last.pt"], may=RUN,
     why="a NaN base learning rate in the scheduler (lr logged as null, then NaN weights): refused like the optimiser's")
case("train-resume-scheduler-a-string", "weights", forge_pt("RESUMEck['scheduler'] = 'cosine'"),
     RESUME, names=["--resume", "last.pt"], may=RUN, why="a scheduler state of the wrong kind: one line, no traceback")
case("train-resume-rng-without-numpy", "weights", forge_pt("RESUMEdel ck['rng']['numpy']"),
     RESUME, names=["--resume", "last.pt"], may=RUN, why="a random state missing a part: one line naming the file")
case("train-resume-rng-python-short", "weights", forge_pt("RESUMEck['rng']['python']['state'] = [1, 2, 3]"),
     RESUME, names=["--resume", "last.pt"], may=RUN, why="a python RNG state of the wrong length: refused, no traceback")
case("train-resume-best-val-a-string", "weights", forge_pt("RESUMEck['extra']['best_val'] = 'low'"),
     RESUME, names=["--resume", "last.pt"], may=RUN, why="extra.best_val must be a number: refused naming the file")
case("train-resume-extra-a-list", "weights", forge_pt("RESUMEck['extra'] = []"),
     RESUME, names=["--resume", "last.pt"], may=RUN, why="extra of the wrong kind: one line, no AttributeError")
case("train-resume-elapsed-nan", "weights", forge_pt("RESUMEck['extra']['elapsed_s'] = float('nan')"),
     RESUME, names=["--resume", "last.pt"], may=RUN,
     why="a NaN elapsed time would be written into log.jsonl as NaN (invalid JSON): refused")
case("train-resume-lr-a-string", "weights",
     forge_pt("RESUMEfor g in ck['optimizer']['param_groups']: g['lr'] = '0.001'"),
     RESUME, names=["--resume", "last.pt"], may=RUN,
     why="an lr stored as text escapes the finite check and fails inside AdamW: refused at load")
case("train-resume-betas-above-one", "weights",
     forge_pt("RESUMEfor g in ck['optimizer']['param_groups']: g['betas'] = (0.9, 2.0)"),
     RESUME, names=["--resume", "last.pt"], may=RUN,
     why="beta2 > 1 makes Adam's bias correction negative and every weight NaN: refused")
case("train-resume-checksum-kept-after-edit", "weights", forge_pt("ck['step'] = 1", checksum="keep"),
     RESUME, names=["--resume", "last.pt"], may=RUN, why="an edited checkpoint whose old checksum no longer fits: damaged")

# ------------------------------------------------------------------ unips.train: init-from, val, out
case("train-init-from-pt-of-other-model", "weights", "",
     "$PY -m unips.train --model glc-tiny --steps 1 --no-progress --threads 1 --data $F/data8 --out $C/run "
     "--init-from $F/run/last.pt", names=["--init-from", "last.pt"], may=RUN,
     why="glc-test weights cannot start a glc-tiny run: refused naming --init-from")
case("train-init-from-fifo", "input", "mkfifo w.safetensors",
     f"{TRAIN} --data $F/data8 --out $C/run --init-from $C/w.safetensors", names=["--init-from"], may=RUN, timeout=60,
     why="a pipe as --init-from is refused at once")
case("train-init-from-nan", "weights", st("s[k].view(-1)[0] = float('nan')", src="RUN"),
     f"{TRAIN} --data $F/data8 --out $C/run --init-from $C/w/m.safetensors", names=["--init-from", "m.safetensors"],
     may=RUN, why="NaN starting weights are refused before any data is read or run folder made")
case("train-init-from-malicious-pickle", "archive", mal_pickle("w/m.pt"),
     f"{TRAIN} --data $F/data8 --out $C/run --init-from $C/w/m.pt", names=["--init-from"], may=RUN,
     why="a code-running pickle as --init-from is refused, no /tmp/pwn_ file")
case("train-init-from-own-last-pt-overwrite", "writer", "cp -r $F/run run",
     f"{TRAIN} --data $F/data8 --out $C/run --init-from $C/run/last.pt --overwrite", expect="either", may=RUN,
     why="starting from the run's own last.pt while --overwrite replaces it: read first or refused, no traceback")
case("train-val-is-shards", "input", "",
     f"{TRAIN} --data $F/data8 --val $F/shards --out $C/run", names=["--val"], may=RUN, expect="ok",
     why="--val takes object folders or their shards (as --data): validated on the shards' objects")
case("train-out-is-shards-folder", "writer", "cp -r $F/shards s",
     f"{TRAIN} --data $C/s --out $C/s", names=["--out"], may=RUN,
     why="a run written into its own shards folder would mix checkpoints with shards: refused")
case("train-out-inside-val", "writer", "cp -r $F/data v",
     f"{TRAIN} --data $F/data8 --val $C/v --out $C/v/run", names=["--out"], may=RUN,
     why="a run inside its validation set would be read as an object next time: refused")
case("train-two-overwrites-into-one-out", "writer", "",
     both(f"{TRAIN} --data $F/data8 --out $C/run --overwrite", f"{TRAIN} --data $F/data --out $C/run --overwrite"),
     expect="either", may=RUN, timeout=120,
     why="two --overwrite runs into one folder: the second is refused while the first holds it (or runs after it)")

# ------------------------------------------------------------------ unips.evaluate
PRED_EVAL = "cp -r $F/pred p && $PY -m unips.evaluate --pred $C/p --gt $F/data >/dev/null\n"
case("eval-error-map-link-out-overwrite", "writer", PRED_EVAL + "echo keep > victim.png; rm p/00000/error_map.png; "
     "ln -s $C/victim.png p/00000/error_map.png",
     "$PY -m unips.evaluate --pred $C/p --gt $F/data --overwrite", expect="either", may=("$C/p/*", "$C/p/*/*"),
     why="--overwrite replaces the link, never writes through it into victim.png")
case("eval-metrics-json-link-out-overwrite", "writer", PRED_EVAL + "cp p/metrics.json victim.json; rm p/metrics.json; "
     "ln -s $C/victim.json p/metrics.json",
     "$PY -m unips.evaluate --pred $C/p --gt $F/data --overwrite", expect="either", may=("$C/p/*", "$C/p/*/*"),
     why="metrics.json as a link out of --pred: refused or replaced, victim.json stays as it was")
case("eval-object-folder-link-out", "archive",
     EVIL_DIR + "cp -r $F/pred p; mv p/00001 \"$C/../evil_$(basename $C)/00001\"; "
     "touch -d '2 hours ago' \"$C/../evil_$(basename $C)\"; ln -s \"$C/../evil_$(basename $C)/00001\" p/00001",
     "$PY -m unips.evaluate --pred $C/p --gt $F/data", expect="either", may=("$C/p/*", "$C/p/*/*"),
     why="an object folder linked out of --pred: refused or scored, but no error map written into the linked folder")
case("eval-gt-shards", "input", "cp -r $F/pred p",
     "$PY -m unips.evaluate --pred $C/p --gt $F/shards", names=["--gt"], may=("$C/p/*",),
     why="ground truth must be object folders: shards refused naming --gt")

# ------------------------------------------------------------------ orchestrate.ship (all refused before scoring)
SHIP = "$PY -m orchestrate.ship --candidate $C/cand --val $F/data --diligent none"
case("ship-final-nan", "weights", st("s[k].view(-1)[3] = float('nan')", dst="cand/run/final"),
     SHIP, names=["--candidate", "final.safetensors"], why="NaN candidate weights are refused before any scoring")
case("ship-final-of-test-model", "weights", "mkdir -p cand/run; cp $F/run/final.* cand/run/",
     SHIP, names=["--candidate", "glc-test"], why="a glc-test run has no shipped entry: refused naming --candidate")
case("ship-final-truncated-last-good", "weights",
     "mkdir -p cand/run; cp " + SHIPPED + ".json cand/run/final.json; head -c 1000 " + SHIPPED +
     ".safetensors > cand/run/final.safetensors; cp $F/run/last.pt cand/run/",
     SHIP, names=["final.safetensors"], why="a damaged final is refused, never silently replaced by last.pt")
case("ship-run-a-file", "input", "mkdir cand; echo x > cand/run", SHIP, names=["--candidate"],
     why="run/ as a file: one line naming --candidate")
case("ship-final-fifo", "input", "mkdir -p cand/run; cp " + SHIPPED + ".json cand/run/final.json; "
     "mkfifo cand/run/final.safetensors", SHIP, names=["final.safetensors"], timeout=60,
     why="a pipe as the candidate's weights is refused at once")
case("ship-last-pt-malicious-pickle", "archive", mal_pickle("cand/run/last.pt"), SHIP, names=["last.pt"],
     why="a code-running pickle as run/last.pt is refused; no /tmp/pwn_ file")
case("ship-sidecar-missing", "input", "mkdir -p cand/run; cp " + SHIPPED + ".safetensors cand/run/final.safetensors",
     SHIP, names=["final.json"], why="the weights' sidecar missing is refused naming it")
case("ship-card-fifo", "input", st("pass", dst="cand/run/final") + "mkfifo cand/model_card.json", SHIP,
     names=["model_card.json"], timeout=60, why="a pipe as model_card.json is refused at once, before scoring")

# ------------------------------------------------------------------ orchestrate.error_calibration (refused early)
EC = "$PY -m orchestrate.error_calibration --objects 1"
ECW = "mkdir -p w; cp " + SHIPPED + ".safetensors w/m.safetensors; cp " + SHIPPED + ".json w/m.json; cp -r $F/assets a\n"
case("ec-work-equals-assets", "writer", ECW, f"{EC} --work $C/a --assets $C/a --weights $C/w/m.safetensors --out $C/em.json",
     names=["--work", "--assets"], why="the suite rendered into the asset library is refused naming both")
case("ec-work-inside-assets", "writer", ECW,
     f"{EC} --work $C/a/work --assets $C/a --weights $C/w/m.safetensors --out $C/em.json", names=["--work"],
     may=("$C/a/work",), why="renders inside the asset library would be read as assets next time: refused")
case("ec-assets-a-suite-row-of-work", "writer",
     ECW + "for f in a/hdri/* a/meshes/*; do if [ -d \"$f\" ]; then cp -r \"$f\" \"${f}_2\"; "
     "elif [ -e \"$f\" ]; then cp \"$f\" \"${f%.*}_2.${f##*.}\"; fi; done; "
     "mkdir work; mv a work/level1",
     f"{EC} --work $C/work --assets $C/work/level1 --weights $C/w/m.safetensors --out $C/em.json; rc=$?; "
     "if ls -A work/level1 | grep -qvx -e hdri -e meshes; then echo \"FAULT: rendered into the asset library: "
     "$(ls work/level1 | tr '\\n' ' ')\"; exit 0; fi; exit $rc", names=["--work"],
     may=("$C/work/*", "$C/work/*/*"), timeout=120, why="the asset library at work/level1, where the suite's first row is rendered: refused naming --work "
     "before the split or any render")
case("ec-work-link-to-assets", "writer", ECW + "ln -s $C/a work",
     f"{EC} --work $C/work --assets $C/a --weights $C/w/m.safetensors --out $C/em.json", names=["--work"],
     why="--work as a link to the assets is the same folder: refused")
case("ec-out-the-weights-sidecar", "writer", ECW,
     f"{EC} --work $C/work --assets none --weights $C/w/m.safetensors --out $C/w/m.json --overwrite",
     names=["--out", "m.json"], may=("$C/work", "$C/work/*"),
     why="the fit must never replace the weights' own config sidecar, even with --overwrite")
case("ec-weights-pt-nan-no-work", "weights",
     forge_pt("kk = sorted(ck['model'])[0]\nck['model'][kk].view(-1)[0] = float('nan')", checksum="drop"),
     f"{EC} --work $C/work --assets none --weights $C/run/last.pt --out $C/em.json; rc=$?; "
     "[ -z \"$(ls -A work 2>/dev/null)\" ] || echo 'LEFT files in work'; exit $rc",
     names=["--weights", "last.pt"], may=("$C/work",), why="NaN weights are refused before anything is written in --work")
case("ec-out-a-folder", "input", ECW + "mkdir em.json",
     f"{EC} --work $C/work --assets none --weights $C/w/m.safetensors --out $C/em.json", names=["--out"],
     may=("$C/work", "$C/work/*"), why="--out naming an existing folder is refused in one line")

# ------------------------------------------------------------------ orchestrate.benchmark (refused early)
BM = "$PY -m orchestrate.benchmark --data $F/data --counts 1 --rerender-objects 0 --diligent-subsets 0 --threads 1"
case("bench-checkpoint-nan-no-out", "weights", st("s[k].view(-1)[0] = float('nan')"),
     f"{BM} --checkpoint $C/w/m.safetensors --out $C/b; rc=$?; [ ! -e b/tables.md ] || echo 'LEFT b/tables.md'; exit $rc",
     names=["--checkpoint", "m.safetensors"], may=("$C/b", "$C/b/*"),
     why="NaN weights are refused before any prediction or table")
case("bench-ablation-nan", "weights", st("s[k].view(-1)[0] = float('inf')"),
     f"{BM} --ablation-checkpoint $C/w/m.safetensors --out $C/b", names=["--ablation-checkpoint"],
     may=("$C/b", "$C/b/*"), why="non-finite ablation weights are refused before the main model's work, naming their flag")
case("bench-out-inside-diligent", "writer", "mkdir dil; cp -r $F/ballPNG dil/",
     "$PY -m orchestrate.benchmark --diligent $C/dil --out $C/dil/ballPNG/b --diligent-subsets 0 --threads 1",
     names=["--out"], may=("$C/dil/ballPNG/b", "$C/dil/ballPNG/b/*"),
     why="benchmark tables inside a DiLiGenT object folder would be read as its files: refused")
case("bench-out-equals-diligent", "writer", "mkdir dil; cp -r $F/ballPNG dil/",
     "$PY -m orchestrate.benchmark --diligent $C/dil --out $C/dil --diligent-subsets 0 --threads 1",
     names=["--out"], why="--out equal to --diligent is refused")
case("bench-glc-unips-missing-pred-file", "input", "mkdir pub; : > pub/x_enc.pytmodel; : > pub/x_agg.pytmodel",
     f"{BM} --model glc-unips-tiny --checkpoint $C/pub --out $C/b", names=["_pred.pytmodel"], may=("$C/b", "$C/b/*"),
     why="a published folder without its *_pred file is refused naming the pattern, before any work")
case("bench-diligent-subset-above-images", "input", "mkdir dil; cp -r $F/ballPNG dil/",
     "$PY -m orchestrate.benchmark --diligent $C/dil --diligent-subset 500 --out $C/b --threads 1",
     names=["--diligent-subset"], may=("$C/b", "$C/b/*"),
     why="subsets of 500 images from 96 cannot be drawn: refused before predicting")
