"""Sweep 39, part h: the MODEL side again (unips.predict / train / evaluate, wildgen.export, orchestrate.ship /
benchmark / error_calibration), with cases sweeps 37 and 38 (cases37_*.py, cases38_*.py) and
tests/test_bad_inputs.py do not hold.

Mechanisms aimed at: a weights file's sidecar .json edited by hand or by an attacker (unknown keys, values of the
wrong kind or out of range, huge integers, deep nesting, a BOM, NaN) is refused naming the file before photos are
read, never silently changing the network (a string "false" read as true); safetensors header tricks (overlapping
offsets, trailing bytes, shapes whose product overflows); an expected-error model beside copied weights that is
corrupt or fitted for other weights; shards whose index.json and tar disagree in subtle ways (order, byte count,
a listed object missing, a shard name climbing out); a training run folder edited between two --resume runs
(log.jsonl emptied, cut, a folder, a dangling link out; final.safetensors replaced); predictions written by other
tools (16-bit RGBA PNG, EXR with extra channels, palette / grey PNG); contradicting flags. Ship and
error_calibration cases are refusals made before either would write into the repository's unips/weights.
"""
from __future__ import annotations

import textwrap

SHIPPED = "$REPO/unips/weights/glc-tiny"
OBJ = "$F/data/00000.data"
PRED = "$PY -m unips.predict --method model --no-expected-error --tta 1"
PRED_EE = "$PY -m unips.predict --method model --tta 1"
PRED_W = PRED + ' --checkpoint "$C/w/m.safetensors" --input ' + OBJ + ' --out "$C/out"'
TRAIN = "$PY -m unips.train --model glc-test --no-progress --threads 1"
RESUME = TRAIN + ' --data $F/data8 --out "$C/run" --steps 3 --resume'
EVAL = '$PY -m unips.evaluate --pred "$C/p" --gt $F/data'
TRAIN_S = TRAIN + ' --steps 1 --data "$C/s" --out "$C/run"'
BENCH = ('$PY -m orchestrate.benchmark --data $F/data --counts 1 --rerender-objects 0 --tta 1 --threads 1 '
         '--diligent-subsets 0 --out "$C/b"')
SHIP = "$PY -m orchestrate.ship --candidate $C/cand --val $F/data --diligent none --threads 1"
EC = '$PY -m orchestrate.error_calibration --work "$C/work" --assets none --objects 1 --pixels 10 --threads 1'
EXPORT = "$PY -m wildgen.export"

OUT = ["$C/out", "$C/out/*", "$C/out/*/*"]
RUN = ["$C/run", "$C/run/*"]
PMAY = ["$C/p/metrics.json", "$C/p/metrics.csv", "$C/p/*/error_map*", "$C/p/*/metrics*", "$C/p/*.lock",
        "$C/p/.*"]


def py(code: str) -> str:
    """A bash heredoc running `code` with the toolkit's python in $C."""
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


def left(path: str, what: str) -> str:
    """Command tail: a refusal that left `path` behind exits 0 with a FAULT line (flagged exit0)."""
    return f'; r=$?; if [ -e "{path}" ] || [ -L "{path}" ]; then echo "FAULT: {what}"; exit 0; fi; exit $r'


def sidecar(code: str, dst: str = "w/m") -> str:
    """Setup: the shipped weights copied to $C/<dst>.safetensors; their sidecar loaded as dict `d`, edited by
    `code`, written to $C/<dst>.json (json.dump, so NaN is written as the bare token NaN)."""
    return "mkdir -p \"$(dirname $C/" + dst + ")\"\ncp " + SHIPPED + ".safetensors " + dst + ".safetensors\n" + py(
        "import json, os\n"
        "d = json.load(open(os.environ['REPO'] + '/unips/weights/glc-tiny.json'))\n"
        + textwrap.dedent(code).strip() + "\n"
        f"if d is not None:\n    json.dump(d, open('{dst}.json', 'w'), indent=1)\n")


def raw_st(code: str, dst: str = "w/m") -> str:
    """Setup: $C/<dst>.safetensors from the shipped file's raw bytes: `hdr` (the parsed header dict), `data` (the
    bytes after it); `code` edits them; written back with an 8-byte length; sidecar copied unchanged."""
    return "mkdir -p \"$(dirname $C/" + dst + ")\"\ncp " + SHIPPED + ".json " + dst + ".json\n" + py(
        "import json, os\n"
        "raw = open(os.environ['REPO'] + '/unips/weights/glc-tiny.safetensors', 'rb').read()\n"
        "n = int.from_bytes(raw[:8], 'little')\n"
        "hdr = json.loads(raw[8:8 + n]); data = raw[8 + n:]\n"
        "names = sorted(k for k in hdr if k != '__metadata__')\n"
        + textwrap.dedent(code).strip() + "\n"
        "h = json.dumps(hdr).encode()\n"
        "h += b' ' * (-len(h) % 8)\n"
        f"open('{dst}.safetensors', 'wb').write(len(h).to_bytes(8, 'little') + h + data)\n")


def run_copy(code: str = "") -> str:
    """Setup: $C/run, a copy of the 2-step glc-test run, then bash `code`."""
    return 'cp -r "$F/run" run\n' + textwrap.dedent(code).strip() + "\n"


def shard(code: str) -> str:
    """Setup: $C/s, a copy of $F/shards whose index.json (dict `idx`, its shard entry `e`) is edited by `code`;
    the tar is unchanged unless `code` rewrites it (then `redigest()` makes bytes and sha256 agree again)."""
    return "mkdir -p s\ncp $F/shards/000000.tar s/\n" + py(
        "import json, os, hashlib\n"
        "idx = json.load(open(os.environ['F'] + '/shards/index.json'))\n"
        "e = idx['shards'][0]\n"
        "def redigest():\n"
        "    b = open('s/000000.tar', 'rb').read()\n"
        "    e['bytes'], e['sha256'] = len(b), hashlib.sha256(b).hexdigest()\n"
        + textwrap.dedent(code).strip() + "\n"
        "json.dump(idx, open('s/index.json', 'w'), indent=1)\n")


def pred_copy(code: str) -> str:
    """Setup: $C/p, a copy of $F/pred (no metrics yet), then Python `code` (os, numpy as np and cv2 loaded)."""
    return 'cp -r "$F/pred" p\n' + py("import os, numpy as np, cv2\n" + textwrap.dedent(code).strip())


CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 90, why: str = "") -> None:
    CASES.append(dict(id="h39-" + id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


NOOUT = left("$C/out", "--out created before the weights were refused")

# ============================================================================ predict: a hand-edited sidecar
case("side-config-unknown-key", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['bogus_width'] = 3"),
     why="A config key the network does not take is refused in one line naming the sidecar, not a TypeError "
         "traceback from the model's constructor.")
case("side-config-negative-heads", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['decoder_heads'] = -2"),
     why="A negative head count is out of range: refused naming the sidecar before photos are read.")
case("side-config-window-zero", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['swin_window'] = 0"),
     why="A Swin window of 0 cannot build the network: one line naming the sidecar, not a ZeroDivisionError.")
case("side-config-huge-int", "weights", PRED_W, expect="either", names=["m.json"], may_change=OUT,
     setup=sidecar("d['config']['pixel_chunk'] = 10 ** 40"),
     why="A pixel chunk beyond int64 either runs (one chunk) or is refused naming the sidecar; never an "
         "OverflowError traceback.")
case("side-config-float-layers", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['decoder_layers'] = 2.5"),
     why="2.5 decoder layers is not an integer: refused naming the sidecar (not truncated to 2 silently).")
case("side-config-bool-heads", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['decoder_heads'] = True"),
     why="true where a head count is expected (bool is an int in Python) would silently build a 1-head decoder "
         "whose weights still load: refused naming the sidecar.")
case("side-config-uniform-context-string", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['uniform_context'] = 'false'"),
     why="The string 'false' is truthy: read as is it silently turns on the ablation with the same weights; "
         "it must be refused naming the sidecar.")
case("side-config-pixel-token-unknown", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['pixel_token'] = 'rgbx'"),
     why="An unknown pixel-token kind is refused naming the sidecar before any photo is read.")
case("side-config-dropout-nan", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['dropout'] = float('nan')"),
     why="NaN is not JSON (the bare token Python writes): a non-finite config value is refused naming the sidecar.")
case("side-config-deeply-nested", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("""
         d['config']['ppm_scales'] = 'DEEP'
         s = json.dumps(d).replace('"DEEP"', '[' * 200000 + ']' * 200000, 1)
         open('w/m.json', 'w').write(s); d = None
     """),
     why="A sidecar nested 200000 deep (planted) makes json raise RecursionError: one line naming the file, "
         "no traceback.")
case("side-config-canonical-1", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['config']['canonical_resolution'] = 1"),
     why="A canonical resolution of 1 px cannot pass the Swin stages: refused naming the sidecar, not a shape "
         "traceback deep in the encoder.")
case("side-unknown-top-key", "weights", PRED_W, expect="either", names=["m.json"], may_change=OUT,
     setup=sidecar("d['__class__'] = 'os.system'; d['evil'] = {'a': [1, 2]}"),
     why="Unknown top-level keys are ignored (or refused naming the sidecar); never interpreted.")
case("side-model-name-empty", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['model_name'] = ''"),
     why="An empty model name is refused naming the sidecar (not a KeyError: '' traceback).")
case("side-format-a-number", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=sidecar("d['format'] = 1"),
     why="format must be the string unips-weights/1: a number is refused naming the sidecar.")
case("side-utf8-bom", "weights", PRED_W, expect="either", names=["m.json"], may_change=OUT,
     setup=sidecar("open('w/m.json', 'w', encoding='utf-8-sig').write(json.dumps(d)); d = None"),
     why="A sidecar saved by a Windows editor with a BOM is read or refused naming it; never a JSONDecodeError "
         "traceback.")
case("side-is-a-folder", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=f"mkdir -p w/m.json\ncp {SHIPPED}.safetensors w/m.safetensors\n",
     why="A folder where the sidecar should be is refused naming it (IsADirectoryError is no message).")
case("side-link-to-other-models-json", "weights", PRED_W + NOOUT, names=["m.json"],
     setup=f"mkdir -p w\ncp {SHIPPED}.safetensors w/m.safetensors\nln -s $F/run/final.json w/m.json\n",
     why="The shipped weights with a sidecar (linked) of glc-test: the shapes disagree; refused naming the file "
         "in one line, not a load_state_dict size-mismatch dump.")
case("side-given-as-checkpoint", "input",
     PRED + f" --checkpoint {SHIPPED}.json --input {OBJ} --out \"$C/out\"" + NOOUT, names=["--checkpoint"],
     why="The sidecar given as the model file is refused naming --checkpoint and what it takes.")

# ============================================================================ predict: safetensors header tricks
case("st-offsets-overlap", "weights", PRED_W + NOOUT, names=["m.safetensors"],
     setup=raw_st("hdr[names[1]]['data_offsets'] = hdr[names[0]]['data_offsets'] if "
                  "hdr[names[1]]['shape'] == hdr[names[0]]['shape'] else [0, hdr[names[1]]['data_offsets'][1] - "
                  "hdr[names[1]]['data_offsets'][0]]"),
     why="Two tensors over the same bytes (a header forged to alias) is refused naming the file.")
case("st-trailing-bytes", "weights", PRED_W + NOOUT, names=["m.safetensors"],
     setup=raw_st("data = data + b'PAYLOAD' * 1000"),
     why="Bytes after the last tensor (a payload smuggled in the file) make the file invalid: refused naming it.")
case("st-shape-product-overflow", "weights", PRED_W + NOOUT, names=["m.safetensors"],
     setup=raw_st("hdr[names[0]]['shape'] = [2 ** 62, 2 ** 62]"),
     why="A shape whose element count overflows 64 bits is refused naming the file (not a huge allocation).")
case("st-metadata-huge-value", "weights", PRED_W, expect="either", names=["m.safetensors"], may_change=OUT,
     setup=raw_st("hdr['__metadata__'] = dict(hdr.get('__metadata__') or {}, junk='x' * 5_000_000)"),
     why="5 MB of metadata is read (or refused naming the file); no memory blow-up or traceback.")
case("st-metadata-not-strings", "weights", PRED_W + NOOUT, names=["m.safetensors"],
     setup=raw_st("hdr['__metadata__'] = {'model_name': ['glc-tiny'], 'n': 3}"),
     why="safetensors metadata values must be strings: a list is refused naming the file.")
case("st-self-link-loop", "input", PRED_W + NOOUT, names=["m.safetensors"],
     setup=f"mkdir -p w\nln -s m.safetensors w/m.safetensors\ncp {SHIPPED}.json w/m.json\n",
     why="A link loop where the weights should be is refused naming the file (ELOOP is no message).")
case("st-float16-weights", "weights", PRED_W, expect="either", names=["m.safetensors"], may_change=OUT,
     setup="mkdir -p w\ncp " + SHIPPED + ".json w/m.json\n" + py("""
         import os
         from safetensors.torch import load_file, save_file
         s = load_file(os.environ['REPO'] + '/unips/weights/glc-tiny.safetensors')
         save_file({k: v.half() if v.is_floating_point() else v for k, v in s.items()}, 'w/m.safetensors',
                   metadata={'model_name': 'glc-tiny'})
     """),
     why="Half-precision weights are finite floats: run (cast) or refused naming the file; never a dtype traceback.")

# ============================================================================ predict: expected-error model beside weights
EE_SETUP = f"mkdir -p w\ncp {SHIPPED}.safetensors w/m.safetensors\ncp {SHIPPED}.json w/m.json\n"
case("ee-json-garbage", "weights",
     PRED_EE + f' --checkpoint "$C/w/m.safetensors" --input {OBJ} --out "$C/out"',
     expect="either", names=["m.expected_error.json"], may_change=OUT,
     setup=EE_SETUP + "printf '{not json' > w/m.expected_error.json\n",
     why="A corrupt error model beside the weights is refused naming it, or ignored with the error not stated; "
         "never a traceback.")
case("ee-json-nan-mean", "weights",
     PRED_EE + f' --checkpoint "$C/w/m.safetensors" --input {OBJ} --out "$C/out"'
     + " && $PY -c \"import json,math,sys; e=json.load(open('out/00000/predict.json')).get('expected_error_deg'); "
       "sys.exit('FAULT: expected error %r' % e if e and not math.isfinite(e['mean']) else 0)\"",
     expect="either", names=["m.expected_error.json"], may_change=OUT,
     setup=EE_SETUP + py("""
         import json, os
         d = json.load(open(os.environ['REPO'] + '/unips/weights/glc-tiny.expected_error.json'))
         d['mean'] = [float('nan')] * len(d['mean'])
         d['weights_sha256'] = __import__('hashlib').sha256(open('w/m.safetensors', 'rb').read()).hexdigest()
         json.dump(d, open('w/m.expected_error.json', 'w'))
     """),
     why="An error model with NaN coefficients is refused naming it, or skipped; never a NaN stated error.")
case("ee-json-of-other-weights", "weights",
     PRED_EE + ' --checkpoint "$C/w/m.safetensors" --input ' + OBJ + ' --out "$C/out"'
     + " && $PY -c \"import json,sys; e=json.load(open('out/00000/predict.json')).get('expected_error_deg'); "
       "sys.exit('FAULT: glc-tiny error model applied to glc-test weights' if e else 0)\"",
     expect="either", names=["m.expected_error.json"], may_change=OUT,
     setup=f"mkdir -p w\ncp $F/run/final.safetensors w/m.safetensors\ncp $F/run/final.json w/m.json\n"
           f"cp {SHIPPED}.expected_error.json w/m.expected_error.json\n",
     why="The shipped model's error model copied beside other weights (its weights_sha256 disagrees) must not "
         "state an error for them.")

# ============================================================================ predict: contradicting flags, outputs
case("scalable-with-glc-tiny", "input", PRED + f' --scalable --input {OBJ} --out "$C/out"' + NOOUT,
     names=["--scalable"],
     why="--scalable is SDM-UniPS only: with the shipped glc-tiny it is refused naming the flag, not ignored.")
case("ls-with-model-flag", "input",
     f'$PY -m unips.predict --method least-squares --model glc-test --input {OBJ} --out "$C/out"' + NOOUT,
     names=["--model"],
     why="--model is for --method model: with least squares it is refused naming it (as --checkpoint is).")
case("checkpoint-is-expected-error-json", "input",
     PRED + f' --checkpoint {SHIPPED}.expected_error.json --input {OBJ} --out "$C/out"' + NOOUT,
     names=["--checkpoint"],
     why="The error-model file given as weights is refused naming --checkpoint.")
case("overwrite-folder-without-predict-json", "writer",
     PRED + f' --overwrite --input {OBJ} --out "$C/out"', expect="either", names=["00000"],
     may_change=["$C/out/00000/normal*", "$C/out/00000/predict.json", "$C/out/00000/expected*", "$C/out/*.lock",
                 "$C/out/.*"],
     setup="mkdir -p out/00000\necho 'my notes' > out/00000/notes.txt\necho x > out/00000/normal.png\n",
     why="--overwrite replaces only folders holding its predict.json: a user's 00000/ (no predict.json) keeps "
         "its files byte for byte (normal.png too) or is refused naming it.")
case("max-images-one-with-expected-error", "engine",
     PRED_EE + f' --max-images 1 --input {OBJ} --out "$C/out"', expect="either", names=["--max-images"],
     may_change=OUT,
     why="One image cannot be split in two halves for the stated error: run without it or refuse naming "
         "--max-images; never a traceback.")

# ============================================================================ train: a run folder edited between resumes
case("resume-log-emptied", "writer", RESUME, expect="either", names=["log.jsonl"], may_change=RUN,
     setup=run_copy(": > run/log.jsonl"),
     why="A log.jsonl emptied by hand: resume continues (appending) or refuses naming it; no traceback.")
case("resume-log-cut-mid-line", "writer", RESUME, expect="either", names=["log.jsonl"], may_change=RUN,
     setup=run_copy("head -c 100 $F/run/log.jsonl > run/log.jsonl"),
     why="A log cut mid-record (a crash while writing): resume continues or refuses naming log.jsonl.")
case("resume-log-step-ahead", "writer", RESUME, expect="either", names=["log.jsonl"], may_change=RUN,
     setup=run_copy("echo '{\"step\": 99, \"loss\": 1.0, \"elapsed_s\": 5.0}' >> run/log.jsonl"),
     why="A log holding step 99 while last.pt is at step 2 (files of two runs mixed): refuse naming log.jsonl "
         "or continue; never a log with steps out of order silently.")
case("resume-log-a-folder", "writer", RESUME, names=["log.jsonl", "--"],
     setup=run_copy("rm run/log.jsonl && mkdir run/log.jsonl"),
     why="log.jsonl a folder: refused in one line naming it and a flag (--out / --resume; '--' checks some flag "
         "is named, sweep 39 saw a bare '[Errno 21] Is a directory'), leaving last.pt and the weights untouched.")
case("resume-log-dangling-link-out", "archive", RESUME, expect="either", names=["log.jsonl"], may_change=RUN,
     setup=run_copy('rm run/log.jsonl && ln -s "$C/../evil_h39_log.jsonl" run/log.jsonl'),
     why="A log.jsonl planted as a dangling link out of the run: never followed to create a file outside.")
case("resume-final-dangling-link-out", "archive", RESUME, expect="either", names=["final.safetensors"],
     may_change=RUN,
     setup=run_copy('rm run/final.safetensors && ln -s "$C/../evil_h39_final.safetensors" run/final.safetensors'),
     why="final.safetensors planted as a dangling link out of the run: writing the weights never creates the "
         "outside file.")
case("resume-final-replaced-by-shipped", "writer", RESUME, expect="either", names=["final.safetensors"],
     may_change=RUN, setup=run_copy(f"cp {SHIPPED}.safetensors run/final.safetensors\ncp {SHIPPED}.json run/final.json"),
     why="final.safetensors replaced by other weights between runs: resume reads last.pt only (ok) or refuses "
         "naming final.safetensors; never loads the glc-tiny file into glc-test.")
case("resume-last-pt-is-safetensors", "weights", RESUME, names=["last.pt"],
     setup=run_copy("cp run/final.safetensors run/last.pt"),
     why="A safetensors file renamed last.pt is no training checkpoint: refused naming last.pt, run unchanged.")
case("resume-no-last-pt-final-present", "input", RESUME, names=["last.pt"],
     setup=run_copy("rm run/last.pt"),
     why="--resume of a run whose last.pt is gone (final.safetensors kept) is refused naming last.pt; the run "
         "folder is not restarted over its files.")
case("resume-other-model", "input", RESUME.replace("--model glc-test", "--model glc-tiny"), names=["--model"],
     setup=run_copy(),
     why="--resume with --model glc-tiny of a glc-test run is refused naming --model, run unchanged.")
case("resume-other-data", "input", RESUME.replace("$F/data8", "$F/data"), expect="either", names=["--data"],
     may_change=RUN, setup=run_copy(),
     why="Resuming bit for bit on other data (4 images, not 8) is refused naming --data or continues; no traceback.")
case("resume-steps-below-done", "input", RESUME.replace("--steps 3", "--steps 1"), expect="either",
     names=["--steps"], may_change=RUN, setup=run_copy(),
     why="--steps 1 below the 2 steps done: refused naming --steps, or nothing trained; never a negative "
         "schedule or a traceback.")
case("init-from-sidecar-unknown-key", "weights",
     TRAIN + ' --steps 1 --data $F/data8 --out "$C/run" --model glc-tiny --init-from "$C/w/m.safetensors"'
     + left("$C/run", "--out created before --init-from was refused"), names=["m.json"],
     setup=sidecar("d['config']['bogus_width'] = 3"),
     why="--init-from weights whose sidecar holds an unknown config key are refused naming it before the run "
         "folder exists.")
case("model-option-value-not-json", "input",
     TRAIN + ' --steps 1 --data $F/data8 --out "$C/run" --model-option uniform_context=yes'
     + left("$C/run", "--out created"), names=["--model-option"],
     why="'yes' is no JSON value: refused naming --model-option (not read as the truthy string 'yes').")
case("model-option-string-false", "input",
     TRAIN + " --steps 1 --data $F/data8 --out \"$C/run\" --model-option 'uniform_context=\"false\"'"
     + left("$C/run", "--out created"), names=["--model-option"],
     why="The JSON string \"false\" where a bool is expected is refused naming --model-option (it would turn "
         "the ablation on).")

# ============================================================================ train: index.json and tar disagree
case("shard-index-bytes-off", "input", TRAIN_S, names=["index.json"], may_change=RUN,
     setup=shard("e['bytes'] += 512"),
     why="index.json's byte count disagrees with the tar (sha256 right): refused naming index.json or the shard.")
case("shard-index-object-missing-in-tar", "input", TRAIN_S, names=["index.json"], may_change=RUN,
     setup=shard("e['objects'].append(dict(e['objects'][0], folder='00009.data', name='00009')); "
                 "idx['objects'] = 4"),
     why="index.json lists 4 objects, the tar holds 3: refused naming index.json (not training on a short set).")
case("shard-index-order-reversed", "input", TRAIN_S, expect="either", names=["index.json"], may_change=RUN,
     setup=shard("e['objects'] = e['objects'][::-1]"),
     why="The objects listed in another order than the tar holds them: read (order is the tar's) or refused "
         "naming index.json.")
case("shard-index-incomplete", "input", TRAIN_S, names=["index.json"], may_change=RUN,
     setup=shard("idx['complete'] = False"),
     why="An export that never finished (complete false) is refused naming index.json.")
case("shard-index-name-climbs", "archive", TRAIN_S, names=["index.json"], may_change=RUN,
     setup=shard("e['name'] = '../../evil_h39.tar'; idx['pattern'] = '../../evil_h39.tar'"),
     why="A shard named ../../evil_h39.tar in index.json is refused: shards are read inside the folder only.")
case("shard-index-name-absolute", "archive", TRAIN_S, names=["index.json"], may_change=RUN,
     setup=shard("e['name'] = os.environ['F'] + '/shards/000000.tar'"),
     why="An absolute shard path in index.json (pointing elsewhere) is refused naming index.json.")
case("shard-members-interleaved", "input", TRAIN_S, names=["000000.tar"], may_change=RUN,
     setup=shard("""
         import io, tarfile
         src = tarfile.open(os.environ['F'] + '/shards/000000.tar')
         mem = [(m.name, src.extractfile(m).read()) for m in src if m.isreg()]
         a = [m for m in mem if m[0].startswith('00000.')]
         b = [m for m in mem if m[0].startswith('00001.')]
         rest = [m for m in mem if m not in a and m not in b]
         mixed = [x for pair in zip(a, b) for x in pair] + a[len(b):] + b[len(a):] + rest
         with tarfile.open('s/000000.tar', 'w', format=tarfile.PAX_FORMAT) as t:
             for name, data in mixed:
                 ti = tarfile.TarInfo(name); ti.size = len(data); t.addfile(ti, io.BytesIO(data))
         redigest()
     """),
     why="Two objects' members interleaved (webdataset groups consecutive keys): broken samples are refused "
         "naming the shard, never trained on as 6 half-objects.")
case("shard-index-sha-uppercase", "input", TRAIN_S, expect="either", names=["index.json"], may_change=RUN,
     setup=shard("e['sha256'] = e['sha256'].upper()"),
     why="An upper-case hex digest is the same digest: accepted, or refused naming index.json; no traceback.")

# ============================================================================ export
case("export-object-name-newline", "input", EXPORT + ' --data "$C/d" --out "$C/o"', expect="either",
     names=["--data"], may_change=["$C/o", "$C/o/*"],
     setup='mkdir d\ncp -r $F/data8/00000.data $\'d/a\\nb.data\'\n',
     why="An object folder whose name holds a newline becomes a shard key: exported with a key that reads back, "
         "or refused naming it.")
case("export-users-index-in-out", "writer", EXPORT + ' --data $F/data8 --out "$C/o"', names=["--out"],
     setup="mkdir o\necho '{\"mine\": true}' > o/index.json\n",
     why="An index.json the export did not write is in --out: refused naming --out, the user's file untouched.")
case("export-users-index-in-out-overwrite", "writer", EXPORT + ' --data $F/data8 --out "$C/o" --overwrite',
     expect="either", names=["--out"], may_change=["$C/o/*.tar", "$C/o/.*"],
     setup="mkdir o\necho '{\"mine\": true}' > o/index.json\n",
     why="--overwrite replaces only an earlier export's files: a user's index.json (not an export's) is refused "
         "or kept byte for byte.")
case("export-image-16bit-among-8bit", "input", EXPORT + ' --data "$C/d" --out "$C/o"', expect="either",
     names=["L001.png"], may_change=["$C/o", "$C/o/*"],
     setup="cp -r $F/data8 d\n" + py("""
         import cv2, numpy as np
         im = cv2.imread('d/00000.data/L001.png', cv2.IMREAD_UNCHANGED)
         cv2.imwrite('d/00000.data/L001.png', im.astype(np.uint16) * 257)
     """),
     why="One 16-bit image among 8-bit ones: exported as is (the loader scales by bit depth) or refused naming it.")

# ============================================================================ evaluate: predictions from other tools
case("eval-png16-rgba", "input", EVAL + " --allow-missing", expect="either", names=["normal.png"],
     may_change=PMAY, setup=pred_copy("""
         for o in os.listdir('p'):
             im = cv2.imread(f'p/{o}/normal.png', cv2.IMREAD_UNCHANGED)[..., :3].astype(np.uint16) * 257
             a = np.full(im.shape[:2] + (1,), 65535, np.uint16); a[:4] = 0
             if os.path.exists(f'p/{o}/normal.exr'): os.remove(f'p/{o}/normal.exr')
             cv2.imwrite(f'p/{o}/normal.png', np.concatenate([im, a], -1))
     """),
     why="A 16-bit RGBA normal map (another tool's) is read as RGB (alpha ignored or used as mask) or refused "
         "naming normal.png; never scored with the alpha as a colour.")
case("eval-png-grey16", "input", EVAL, names=["normal.png"], may_change=PMAY, setup=pred_copy("""
         for o in os.listdir('p'):
             if os.path.exists(f'p/{o}/normal.exr'): os.remove(f'p/{o}/normal.exr')
             cv2.imwrite(f'p/{o}/normal.png', np.full((32, 32), 30000, np.uint16))
     """),
     why="A one-channel 16-bit PNG is no normal map: refused naming normal.png.")
case("eval-png-palette", "input", EVAL, expect="either", names=["normal.png"], may_change=PMAY,
     setup=pred_copy("""
         from PIL import Image
         for o in os.listdir('p'):
             if os.path.exists(f'p/{o}/normal.exr'): os.remove(f'p/{o}/normal.exr')
             Image.open(f'p/{o}/normal.png').convert('RGB').convert('P').save(f'p/{o}/normal.png')
     """),
     why="A palette PNG is decoded to RGB and scored or refused naming normal.png; never its palette indices "
         "read as one channel.")
case("eval-exr-extra-channels", "input", EVAL, expect="either", names=["normal.exr"], may_change=PMAY,
     setup=pred_copy("""
         import OpenEXR, Imath
         for o in os.listdir('p'):
             f = OpenEXR.InputFile(f'p/{o}/normal.exr'); h = f.header()
             ch = {c: f.channel(c) for c in h['channels']}
             n = len(next(iter(ch.values())))
             for extra in ('A', 'Z', 'depth.V'):
                 ch[extra] = b'\\x00' * n
                 h['channels'][extra] = h['channels']['R']
             f.close()
             OpenEXR.OutputFile(f'p/{o}/normal.exr', h).writePixels(ch)
     """),
     why="An EXR with A, Z and a layered channel beside R, G, B is read by its R, G, B (or refused naming it); "
         "never channels taken by position.")
case("eval-exr-xyz-channels", "input", EVAL, expect="either", names=["normal.exr"], may_change=PMAY,
     setup=pred_copy("""
         import OpenEXR
         for o in os.listdir('p'):
             f = OpenEXR.InputFile(f'p/{o}/normal.exr'); h = f.header()
             ch = {c: f.channel(c) for c in h['channels']}
             f.close()
             h['channels'] = {n: h['channels'][c] for n, c in zip('XYZ', 'RGB')}
             OpenEXR.OutputFile(f'p/{o}/normal.exr', h).writePixels({n: ch[c] for n, c in zip('XYZ', 'RGB')})
             if os.path.exists(f'p/{o}/normal.png'): os.remove(f'p/{o}/normal.png')
     """),
     why="Normals stored as X, Y, Z channels (no R, G, B): read by those names or refused naming normal.exr; "
         "no KeyError traceback.")

# ============================================================================ benchmark / ship / error_calibration
case("bench-checkpoint-sidecar-unknown-key", "weights", BENCH + ' --checkpoint "$C/w/m.safetensors"'
     + left("$C/b", "--out created before the weights were refused"), names=["m.json"],
     setup=sidecar("d['config']['bogus_width'] = 3"),
     why="Weights whose sidecar the network cannot take are refused naming it before the benchmark folder exists.")
case("bench-ablation-other-model", "weights", BENCH + " --ablation-checkpoint $F/run/final.safetensors"
     + left("$C/b", "--out created before the ablation was refused"), names=["--ablation-checkpoint"],
     why="The ablation column must be the same network: glc-test weights beside the glc-tiny ones are refused "
         "naming --ablation-checkpoint before anything runs.")
case("bench-model-disagrees-with-checkpoint", "input",
     BENCH + f" --model glc-unips --checkpoint {SHIPPED}.safetensors" + left("$C/b", "--out created"),
     names=["--model"],
     why="--model glc-unips with a glc-tiny weights file contradicts it: refused naming --model.")
case("bench-diligent-subset-zero", "input",
     BENCH.replace("--diligent-subsets 0", "--diligent-subsets 2 --diligent-subset 0") + " --diligent $F"
     + left("$C/b", "--out created"), names=["--diligent-subset"],
     why="Random subsets of 0 images are refused naming --diligent-subset.")
case("ship-final-sidecar-string-bool", "weights", SHIP, names=["final.json"],
     setup="mkdir -p cand/run\ncp " + SHIPPED + ".safetensors cand/run/final.safetensors\n" + py("""
         import json, os
         d = json.load(open(os.environ['REPO'] + '/unips/weights/glc-tiny.json'))
         d['config']['uniform_context'] = 'false'
         json.dump(d, open('cand/run/final.json', 'w'))
     """),
     why="A candidate whose sidecar turns the ablation on by a string is refused naming final.json before scoring.")
case("ship-final-sidecar-deep", "weights", SHIP, names=["final.json"],
     setup="mkdir -p cand/run\ncp " + SHIPPED + ".safetensors cand/run/final.safetensors\n"
           "$PY -c \"open('cand/run/final.json','w').write('{\\\"model_name\\\": ' + '[' * 100000 + ']' * 100000 + '}')\"\n",
     why="A candidate sidecar nested 100000 deep is refused naming final.json, no RecursionError traceback.")
case("ec-weights-sidecar-unknown-key", "weights", EC + ' --weights "$C/w/m.safetensors" --out "$C/ee.json"'
     + left("$C/work", "--work created before the weights were refused"), names=["m.json"],
     setup=sidecar("d['config']['bogus_width'] = 3"),
     why="Weights whose sidecar cannot build the network are refused naming it before the suite is rendered.")
case("ec-out-is-the-weights", "writer", EC + ' --weights "$C/w/m.safetensors" --out "$C/w/m.safetensors" '
     '--overwrite' + left("$C/work", "--work created before --out was refused"), names=["--out"],
     setup=f"mkdir -p w\ncp {SHIPPED}.safetensors w/m.safetensors\ncp {SHIPPED}.json w/m.json\n",
     why="--out equal to the weights file (even with --overwrite) would replace the weights: refused naming --out.")
case("ec-overwrite-users-file", "writer", EC + ' --weights "$C/w/m.safetensors" --out "$C/mine.json" --overwrite'
     + left("$C/work", "--work created before --out was refused"), names=["--out"],
     setup=f"mkdir -p w\ncp {SHIPPED}.safetensors w/m.safetensors\ncp {SHIPPED}.json w/m.json\n"
           "echo '{\"my\": \"notes\"}' > mine.json\n",
     why="--overwrite never replaces a file this command did not write: the user's mine.json is refused at once.")
