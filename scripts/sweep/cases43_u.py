"""Sweep 43, part u: the MODEL side (unips.train, unips.predict, weight files, shards, DiLiGenT and official
object folders, orchestrate.benchmark / error_calibration / ship / train_recipe), with cases that cases37-42 and
tests/test_bad_inputs.py do not hold.

Angles:
- chains: a fixture run (train) edited by hand, then predict -> evaluate / bench / ship read it;
- --resume after a trajectory flag changed (--res, --precision, --model-option, --max-images, --interior-crop),
  and after only bookkeeping flags changed (must work);
- weight files holding odd but loadable or crafted content: complex, bf16, nested dicts, `module.` prefixes,
  nn.Parameter values, zero-size and 0-d tensors, extra scalar tensors;
- shard indexes whose counts were edited (streamed and in-memory), a shard whose object lost an image;
- DiLiGenT folders with one image of another size or bit depth, light files in a European or Fortran notation,
  a listing shorter than the light files; official (unips-layout) folders named L001..L100 with gaps, natural
  order under --max-images; our folders with an image removed or added;
- paths with tab and newline characters through predict -> evaluate.

Cases whose command adds its own check print a line starting with `FAULT:` and exit 0 so that the harness flags it.
"""
from __future__ import annotations

import textwrap

CASES: list[dict] = []


def case(id: str, kind: str, cmd: str, expect: str = "refuse", names=(), setup: str = "", may_change=(),
         timeout: int = 120, why: str = "") -> None:
    CASES.append(dict(id=id, kind=kind, setup=setup, cmd=cmd, expect=expect, names=list(names),
                      may_change=list(may_change), timeout=timeout, why=why))


def py(code: str) -> str:
    """A bash heredoc running `code` with the toolkit's python in $C."""
    return "$PY - <<'PYEOF'\n" + textwrap.dedent(code).strip() + "\nPYEOF\n"


# ----------------------------------------------------------------------------------------------- commands
TR = ("$PY -m unips.train --model glc-test --res 16 --no-progress --threads 1 --batch 1 --pixels 50 "
      "--canonical-points 50 --max-images 4")
"""The cheapest training command (glc-test at 16 px); add --data, --out, --steps."""
TRR = "$PY -m unips.train --model glc-test --no-progress --threads 1"
RESUME = TRR + ' --data "$F/data8" --out "$C/run" --steps 3 --resume'
"""Resume a copy of the fixture run (2 steps of glc-test on data8, --res 128 --batch 4 ...) to step 3."""
RUN = ["$C/run", "$C/run/*", "$C/run/*/*"]
RUNCP = 'cp -r "$F/run" run\n'
"""Setup: run/, a copy of the 2-step glc-test training run."""
PR = "$PY -m unips.predict"
PRM = PR + " --method model --tta 1 --no-expected-error"
PRLS = PR + " --method least-squares"
PRSH = PR + " --method sh-uncalibrated"
EV = "$PY -m unips.evaluate"
BM = "$PY -m orchestrate.benchmark --threads 1 --rerender-objects 0 --diligent-subsets 0"
EC = "$PY -m orchestrate.error_calibration --assets none --objects 1 --threads 1 --pixels 50"
RC = "$PY -m orchestrate.train_recipe"
RCW = RC + ' --work "$C/w" --assets none --train-objects 1 --steps 1 --threads 1'
P = ["$C/p", "$C/p/*", "$C/p/*/*"]
W_ST = '"$C/w/m.safetensors"'
W_PT = '"$C/m.pt"'
PRM_RUN = PRM + ' --checkpoint "$C/run/final.safetensors"'
REPO_COPY = r"""mkdir repo
(cd "$REPO" && git ls-files -z --cached --others --exclude-standard | tar --null -T - --ignore-failed-read -cf - 2>/dev/null) | tar -xf - -C repo
"""
"""Setup: repo/, a copy of the working tree (orchestrate.ship writes the registry of the tree it runs from)."""
SHIP = 'cd "$C/repo" && PYTHONPATH="$C/repo" $PY -m orchestrate.ship --threads 1 --diligent none'
REPO_SAME = ('; r=$?; (cd "$C/repo" && git -C "$REPO" ls-files -z unips/weights | '
             'xargs -0 -I{} cmp -s "$REPO/{}" "$C/repo/{}") || { echo "FAULT: the registry copy changed"; exit 0; }; '
             'exit $r')
"""Command tail: a refusal that still changed the copy's registry (unips/weights) exits 0 with a FAULT line."""
REPO_CHANGE = ["$C/repo/unips/weights/*"]


def st_edit(code: str) -> str:
    """Setup: w/m.safetensors + w/m.json: the fixture run's final weights (glc-test) loaded as `s` (a dict of
    tensors; `k` its last key, `k0` its first, `vec` the first 1-D float tensor's key), edited by `code`, saved
    with the glc-test metadata, the sidecar copied beside them."""
    return py(textwrap.dedent("""
        import os, shutil, torch
        from safetensors.torch import load_file, save_file
        F = os.environ['F']
        os.makedirs('w', exist_ok=True)
        s = load_file(F + '/run/final.safetensors')
        keys = sorted(s); k, k0 = keys[-1], keys[0]
        vec = next(n for n in keys if s[n].dim() == 1 and s[n].is_floating_point() and s[n].numel() > 1)
        """) + textwrap.dedent(code).strip() + textwrap.dedent("""
        save_file({n: t.contiguous() for n, t in s.items()}, 'w/m.safetensors', metadata={'model_name': 'glc-test'})
        shutil.copy(F + '/run/final.json', 'w/m.json')
        """))


def pt_edit(code: str, dest: str = "m.pt") -> str:
    """Setup: DEST, the fixture run's last.pt loaded as `c` (weights_only; `k` the last weight name), edited by
    `code`, its checksum rewritten to match (an attacker or a tool that edits a checkpoint consistently), saved."""
    return py(textwrap.dedent("""
        import os, torch
        from unips.models.builder import CHECKSUM_KEY, content_digest
        c = torch.load(os.environ['F'] + '/run/last.pt', weights_only=True)
        k = sorted(c['model'])[-1]
        """) + textwrap.dedent(code).strip() + textwrap.dedent(f"""
        c[CHECKSUM_KEY] = content_digest(c)
        torch.save(c, {dest!r})
        """))


def jedit(path: str, code: str) -> str:
    """Setup: edit the JSON file `path` by hand: `code` runs with `d` loaded, then it is written back."""
    return py(f"import json\np = {path!r}\nd = json.load(open(p))\n" + textwrap.dedent(code).strip()
              + "\njson.dump(d, open(p, 'w'), indent=1)\n")


SMALL_DIL = py("""
    import os, shutil, cv2, numpy as np
    F = os.environ['F']
    src, dst = F + '/ballPNG', 'dil/ballPNG'
    os.makedirs(dst)
    for i in range(1, 9):
        im = cv2.imread(f'{src}/{i:03d}.png', cv2.IMREAD_UNCHANGED)
        cv2.imwrite(f'{dst}/{i:03d}.png', cv2.resize(im, (77, 64), interpolation=cv2.INTER_AREA))
    for name in ('mask.png', 'Normal_gt.png'):
        im = cv2.imread(f'{src}/{name}', cv2.IMREAD_UNCHANGED)
        cv2.imwrite(f'{dst}/{name}', cv2.resize(im, (77, 64), interpolation=cv2.INTER_NEAREST))
    for name in ('light_directions.txt', 'light_intensities.txt', 'filenames.txt'):
        lines = open(f'{src}/{name}').read().splitlines()[:8]
        open(f'{dst}/{name}', 'w').write('\\n'.join(lines) + '\\n')
    """)
"""Setup: dil/ballPNG, DiLiGenT's ball cut to 8 images at 77x64 px (16-bit PNGs, light files of 8 rows)."""
DIL_LS = PRLS + ' --input "$C/dil/ballPNG" --out "$C/p"'


def dil_text(name: str, code: str) -> str:
    """Setup: the small DiLiGenT ball, then dil/ballPNG/NAME rewritten: `code` maps `lines` (its lines) to `out`."""
    return SMALL_DIL + py(f"p = 'dil/ballPNG/{name}'\nlines = open(p).read().splitlines()\n"
                          + textwrap.dedent(code).strip() + "\nopen(p, 'w', newline='').write(out)\n")


OBJ = '"$F/data/00000.data"'
OBJCP = 'cp -r "$F/data/00000.data" o.data\n'
"""Setup: o.data, a copy of one object folder of ours (4 images, scene.json)."""
SHCP = 'cp -r "$F/shards" sh\n'
"""Setup: sh/, a copy of the WebDataset shards (3 objects of data8, 8 images each)."""


def fault_unless(test: str, what: str) -> str:
    """Command tail: after a success, exit 0 with a FAULT line unless the bash `test` holds."""
    return f' && {{ {test} || {{ echo "FAULT: {what}"; exit 0; }}; }}'


# =================================================================== chains: a train artefact edited, then read
case("u43-chain-fixture-run-predict-evaluate", "engine",
     PRM_RUN + ' --input "$F/data" --out "$C/p" && ' + EV + ' --pred "$C/p" --gt "$F/data"'
     + fault_unless('[ -s "$C/p/metrics.json" ]', "evaluate wrote no metrics.json"),
     expect="ok", setup=RUNCP, may_change=P, timeout=90,
     why="The plain chain: a training run's final weights predict a dataset and the predictions are evaluated; "
         "both exit 0 and metrics.json is written (the baseline of the edited chains below).")
case("u43-chain-sidecar-renamed-glc-tiny-then-predict", "weights",
     PRM_RUN + ' --input ' + OBJ + ' --out "$C/p"', names=["final.json"],
     setup=RUNCP + jedit("run/final.json", "d['model_name'] = 'glc-tiny'"), may_change=P, timeout=60,
     why="The run's sidecar hand-edited to say glc-tiny (the config still glc-test's) while the .safetensors "
         "metadata says glc-test: refused naming the sidecar, never predicted and labelled glc-tiny.")
case("u43-chain-sidecar-extra-train-args-edited-predict-ok", "weights",
     PRM_RUN + ' --input ' + OBJ + ' --out "$C/p"' + fault_unless('[ -s "$C/p/00000/normal.png" ]', "no normal.png"),
     expect="ok",
     setup=RUNCP + jedit("run/final.json", "d['extra']['train_args']['res'] = 999; d['extra']['step'] = 77"),
     may_change=P, timeout=60,
     why="extra.train_args is provenance only (the registry says it is never read): a hand-edited value there "
         "does not stop a prediction.")
case("u43-chain-final-replaced-by-last-pt-renamed", "weights",
     PRM_RUN + ' --input ' + OBJ + ' --out "$C/p"', names=["final.safetensors"],
     setup=RUNCP + "cp run/last.pt run/final.safetensors\n", may_change=P, timeout=60,
     why="final.safetensors overwritten by a copy of last.pt (a torch zip under a safetensors name): refused "
         "naming the file and the rename that fixes it, not 'corrupt'.")
case("u43-chain-bench-checkpoint-and-ablation-same-config", "weights",
     BM + ' --data "$F/data" --images 4 --counts 1 --checkpoint "$C/run/final.safetensors" '
     '--ablation-checkpoint ' + W_ST + ' --out "$C/b"',
     names=["--ablation-checkpoint"],
     setup=RUNCP + st_edit("s[k0] = s[k0] * 1.001"), may_change=["$C/b", "$C/b/*"], timeout=90,
     why="The ablation column is 'the same model trained with uniform contexts': weights whose config has "
         "uniform_context false (a near copy of the benchmarked ones) would fill that column with a network that "
         "does not use uniform contexts; refused naming --ablation-checkpoint, not tabled under a false label.")
case("u43-chain-bench-ablation-uniform-but-other-shape", "weights",
     BM + ' --data "$F/data" --images 4 --counts 1 --checkpoint "$C/run/final.safetensors" '
     '--ablation-checkpoint "$C/w/m.safetensors" --out "$C/b"',
     expect="either", names=["--ablation-checkpoint"],
     setup=py("""
        import os, torch
        from unips.models.registry import build_model
        from unips.models.builder import save_checkpoint
        os.makedirs('w', exist_ok=True)
        torch.manual_seed(0)
        m = build_model('glc-test', uniform_context=True, context_dim=24)
        save_checkpoint('w/m.safetensors', m)
        """), may_change=["$C/b", "$C/b/*"], timeout=120,
     why="An ablation of another width (context_dim 24) is not 'the same model' with uniform contexts: a refusal "
         "naming --ablation-checkpoint is right; if tabled, never a traceback.")

# =================================================================== train --resume after flags changed
for slug, flag, name in (("res", "--res 64", "--res"), ("precision-bf16", "--precision bf16", "--precision"),
                         ("model-option-dropout", "--model-option dropout=0.1", "--model-option")):
    case(f"u43-resume-other-{slug}", "input", RESUME + " " + flag, names=[name], setup=RUNCP, may_change=RUN,
         timeout=60,
         why=f"{flag} changes the trajectory of the run last.pt continues 'bit for bit': refused naming {name} "
             "and the checkpoint's value, before a step is taken or the log is cut.")
case("u43-resume-only-bookkeeping-flags-changed", "input",
     RESUME + " --log-every 1 --ckpt-every 1 --val-every 1000"
     + fault_unless("grep -q '\"step\": 3' \"$C/run/log.jsonl\"", "the resumed run logged no step 3"),
     expect="ok", setup=RUNCP, may_change=RUN, timeout=120,
     why="--log-every / --ckpt-every / --val-every do not change what is learnt: the resume goes on to step 3 "
         "(refusing them would make a run that was logged sparsely impossible to inspect).")
case("u43-resume-steps-equal-done", "input", RESUME.replace("--steps 3", "--steps 2"), expect="either",
     names=["--steps"], setup=RUNCP, may_change=RUN, timeout=60,
     why="--steps equal to the steps done: nothing to train; exit 0 saying so (final kept) or one line naming "
         "--steps; never a step taken past the schedule's end or a rewritten log.")
case("u43-resume-log-lines-swapped", "input", RESUME, expect="either", names=["log.jsonl"],
     setup=RUNCP + "tac run/log.jsonl > t && mv t run/log.jsonl\n", may_change=RUN, timeout=60,
     why="A log whose records run backwards (step 2 then 1) was edited by hand: refused naming log.jsonl, or "
         "resumed with the log put right; never a log holding step 2 twice.")
case("u43-resume-log-last-record-removed", "input", RESUME, expect="either", names=["log.jsonl"],
     setup=RUNCP + "head -n 1 run/log.jsonl > t && mv t run/log.jsonl\n", may_change=RUN, timeout=60,
     why="A log one record behind last.pt (records are written every --log-every steps, so a gap is normal): "
         "resumed to step 3, or refused naming log.jsonl; never a traceback.")
case("u43-resume-val-added", "input", RESUME + ' --val "$F/data" --val-every 1 --val-pixels 50', expect="either",
     names=["--val"], setup=RUNCP, may_change=RUN, timeout=120,
     why="Validation added on a resumed run changes no weight: continued (best.safetensors from the validations "
         "from now on) or refused naming --val; never a best_val compared with a missing one as a traceback.")

# =================================================================== --init-from: weight files with odd content
case("u43-init-from-pt-complex-weight", "weights",
     TR + ' --data "$F/data" --out "$C/run" --steps 1 --init-from ' + W_PT, names=["--init-from", "m.pt"],
     setup=pt_edit("c['model'][k] = c['model'][k].to(torch.complex64)"), may_change=RUN, timeout=60,
     why="A complex tensor where the model holds float32 (checksum rewritten): refused naming --init-from and "
         "the tensor, never cast (dropping the imaginary part) into a run.")
case("u43-init-from-pt-bf16-weights", "weights",
     TR + ' --data "$F/data" --out "$C/run" --steps 1 --init-from ' + W_PT, expect="ok",
     setup=pt_edit("c['model'] = {n: (t.to(torch.bfloat16) if t.is_floating_point() else t) "
                   "for n, t in c['model'].items()}"), may_change=RUN, timeout=90,
     why="bf16 weights are weights (the loaders accept float16, bfloat16 and float32): a bf16 copy of a run is "
         "a valid starting point.")
case("u43-init-from-pt-model-nested-one-level", "weights",
     TR + ' --data "$F/data" --out "$C/run" --steps 1 --init-from ' + W_PT, names=["m.pt"],
     setup=pt_edit("c['model'] = {'state_dict': c['model']}"), may_change=RUN, timeout=60,
     why="'model' holding {'state_dict': {...}} (another framework's nesting): refused in one line naming m.pt "
         "and the entry that is a dict, not a traceback from len() of a dict.")
case("u43-init-from-pt-extra-top-level-keys", "weights",
     TR + ' --data "$F/data" --out "$C/run" --steps 1 --init-from ' + W_PT, expect="either", names=["m.pt"],
     setup=pt_edit("c['ema'] = {n: t.clone() for n, t in c['model'].items()}; "
                   "c['notes'] = {'a': [1, 2, {'b': None}], 'when': 'yesterday'}"), may_change=RUN, timeout=90,
     why="A training checkpoint with extra keys (an EMA copy, notes) and a matching checksum: started from its "
         "'model' weights, or refused naming m.pt; never a traceback.")
case("u43-init-from-st-extra-zero-size-tensor", "weights",
     TR + ' --data "$F/data" --out "$C/run" --steps 1 --init-from ' + W_ST, names=["m.safetensors"],
     setup=st_edit("s['extra.empty'] = torch.zeros(0)"), may_change=RUN, timeout=60,
     why="A zero-size tensor the model does not hold: an unexpected tensor, refused naming the file and "
         "'extra.empty' (strict loading), not dropped unseen.")
case("u43-init-from-st-vector-as-0d-scalar", "weights",
     TR + ' --data "$F/data" --out "$C/run" --steps 1 --init-from ' + W_ST, names=["m.safetensors"],
     setup=st_edit("s[vec] = s[vec].mean()"), may_change=RUN, timeout=60,
     why="A bias vector replaced by a 0-d scalar would broadcast silently in copy_: refused naming the tensor and "
         "its shape (no dimensions) against the model's.")
case("u43-init-from-st-of-sdm-unips-tiny", "weights",
     TR + ' --data "$F/data" --out "$C/run" --steps 1 --init-from "$C/w/m.safetensors"', names=["--init-from"],
     setup=py("""
        import os
        from unips.models.registry import list_models, build_model
        from unips.models.builder import save_checkpoint
        os.makedirs('w', exist_ok=True)
        name = 'sdm-unips-tiny'
        save_checkpoint('w/m.safetensors', build_model(name))
        """), may_change=RUN, timeout=90,
     why="Weights of another registered network given to --model glc-test --init-from: refused naming --init-from "
         "and both networks, before data is read.")

# =================================================================== predict: weight files with odd content
case("u43-pred-st-weight-zero-size", "weights", PRM + ' --checkpoint ' + W_ST + ' --input ' + OBJ + ' --out "$C/p"',
     names=["m.safetensors"], setup=st_edit("s[vec] = s[vec][:0]"), may_change=P, timeout=60,
     why="A weight stored with zero elements (a truncated export): refused naming the tensor's shape, never a "
         "network with an empty bias.")
case("u43-pred-st-extra-0d-step-scalar", "weights",
     PRM + ' --checkpoint ' + W_ST + ' --input ' + OBJ + ' --out "$C/p"', expect="either", names=["m.safetensors"],
     setup=st_edit("s['step'] = torch.tensor(2)"), may_change=P, timeout=60,
     why="An exporter that stores the step as a 0-d tensor beside the weights: refused naming 'step' as a tensor "
         "the network does not hold, or ignored; never a traceback.")
case("u43-pred-pt-module-prefixed-keys", "weights",
     PRM + ' --checkpoint ' + W_PT + ' --input ' + OBJ + ' --out "$C/p"', expect="either", names=["m.pt"],
     setup=pt_edit("c['model'] = {'module.' + n: t for n, t in c['model'].items()}"), may_change=P, timeout=60,
     why="A DistributedDataParallel-style checkpoint ('module.' before every name): loaded with the prefix "
         "dropped, or refused naming m.pt with the mismatch; never a list of hundreds of missing names.")
case("u43-pred-pt-weights-as-parameters", "weights",
     PRM + ' --checkpoint ' + W_PT + ' --input ' + OBJ + ' --out "$C/p"', expect="either", names=["m.pt"],
     setup=pt_edit("c['model'] = {n: torch.nn.Parameter(t, requires_grad=t.is_floating_point()) "
                   "for n, t in c['model'].items()}"), may_change=P, timeout=60,
     why="nn.Parameter values (model.named_parameters() saved as is) hold the same numbers: predicted, or refused "
         "in one line naming m.pt; never a traceback from the weights-only reader.")
case("u43-pred-pt-weight-is-a-strided-view", "weights",
     PRM + ' --checkpoint ' + W_PT + ' --input ' + OBJ + ' --out "$C/p"'
     + fault_unless('[ -s "$C/p/00000/normal.png" ]', "no normal.png"), expect="ok",
     setup=pt_edit("""
        t = c['model'][k]
        big = torch.zeros((2,) + tuple(t.shape), dtype=t.dtype); big[1] = t
        c['model'][k] = big[1]
        """), may_change=P, timeout=60,
     why="A weight saved as a view into a larger storage (torch.save keeps the whole storage) holds the right "
         "numbers: loaded and predicted.")
case("u43-pred-pt-optimizer-state-complex", "weights",
     PRM + ' --checkpoint ' + W_PT + ' --input ' + OBJ + ' --out "$C/p"', expect="either", names=["m.pt"],
     setup=pt_edit("""
        st = c['optimizer']['state']
        i = next(iter(st)); st[i]['exp_avg'] = st[i]['exp_avg'].to(torch.complex64)
        """), may_change=P, timeout=60,
     why="Prediction reads only the weights of a .pt: an optimiser moment edited to complex does not matter here "
         "(predicted), or the damaged checkpoint is refused naming m.pt; never a traceback.")
case("u43-pred-glc-unips-folder-of-our-files", "weights",
     PRM + ' --model glc-unips --checkpoint "$C/w" --input ' + OBJ + ' --out "$C/p"', names=["--checkpoint"],
     setup='mkdir -p w; cp "$REPO/unips/weights/glc-tiny.safetensors" "$REPO/unips/weights/glc-tiny.json" w/\n',
     may_change=P, timeout=60,
     why="A folder of our .safetensors given as the authors' published glc-unips weights: refused naming "
         "--checkpoint and the files the published folder holds, not read as a foreign format.")

# =================================================================== predict: flags
case("u43-pred-ls-scalable", "input", PRLS + ' --scalable --input ' + OBJ + ' --out "$C/p"', names=["--scalable"],
     may_change=P, timeout=30,
     why="--scalable is for --method model --model sdm-unips: refused naming it with --method least-squares.")
case("u43-pred-scalable-with-our-glc-file", "input",
     PR + ' --method model --tta 1 --no-expected-error --scalable --checkpoint "$C/run/final.safetensors" '
     '--input ' + OBJ + ' --out "$C/p"', names=["--scalable"], setup=RUNCP, may_change=P, timeout=60,
     why="--scalable without --model, with a file of glc-test (no sub-image patch): refused naming --scalable "
         "once the file's network is known, before any object is read.")
case("u43-pred-tta8-max-images-1-ok", "input",
     PR + ' --method model --no-expected-error --tta 8 --max-images 1 --checkpoint "$C/run/final.safetensors" '
     '--input ' + OBJ + ' --out "$C/p"'
     + fault_unless("grep -q '\"num_images\": 1' \"$C/p/00000/predict.json\"", "predict.json does not say 1 image"),
     expect="ok", setup=RUNCP, may_change=P, timeout=90,
     why="Eight views of one image is legitimate (the network takes single images): predicted, and predict.json "
         "records one image used.")
case("u43-pred-max-images-natural-order", "input",
     PRM_RUN + ' --max-images 2 --input "$C/u/obj.data" --out "$C/p"'
     + fault_unless("$PY -c \"import json,sys; d=json.load(open('$C/p/obj/predict.json')); "
                    "sys.exit(0 if d['images_used']==['L1.png','L2.png'] else 1)\"",
                    "--max-images 2 did not take L1, L2 (natural order)"),
     expect="ok", setup=RUNCP + py("""
        import os, shutil
        F = os.environ['F']
        os.makedirs('u/obj.data')
        for i, n in zip(range(4), ('L1', 'L2', 'L10', 'L11')):
            shutil.copy(f'{F}/data/00000.data/L00{i}.png', f'u/obj.data/{n}.png')
        shutil.copy(F + '/data/00000.data/mask.png', 'u/obj.data/mask.png')
        """), may_change=P, timeout=60,
     why="--max-images takes the first K in natural order: L1, L2 (not L1, L10 as a string sort gives).")

# =================================================================== official (unips-layout) and our object folders
case("u43-unips-L001-L100-with-gaps-ok", "input",
     PRM_RUN + ' --input "$C/u/obj.data" --out "$C/p"'
     + fault_unless("grep -q '\"num_images\": 4' \"$C/p/obj/predict.json\"", "not all four images were used"),
     expect="ok", setup=RUNCP + py("""
        import os, shutil
        F = os.environ['F']
        os.makedirs('u/obj.data')
        for i, n in zip(range(4), ('L001', 'L002', 'L005', 'L100')):
            shutil.copy(f'{F}/data/00000.data/L00{i}.png', f'u/obj.data/{n}.png')
        shutil.copy(F + '/data/00000.data/mask.png', 'u/obj.data/mask.png')
        """), may_change=P, timeout=60,
     why="An official UniPS folder names its images freely (no scene.json lists them): gaps in L001..L100 are "
         "normal; all four images are used.")
case("u43-ours-image-removed-gap", "input", PRSH + ' --input "$C/o.data" --out "$C/p"', names=["o.data"],
     setup=OBJCP + "rm o.data/L002.png\n", may_change=P, timeout=30,
     why="Our folder (scene.json present) with L002.png removed: refused naming the folder and the gap, not "
         "predicted from three images whose lights no longer match scene.json.")
case("u43-ours-image-added-beyond-scene", "input", PRSH + ' --input "$C/o.data" --out "$C/p"', names=["scene.json"],
     setup=OBJCP + "cp o.data/L003.png o.data/L004.png\n", may_change=P, timeout=30,
     why="A fifth image added to a folder whose scene.json records four lights: refused naming scene.json (the "
         "image does not belong to this scene).")
case("u43-ours-image-added-train", "input", TR + ' --data "$C/d" --out "$C/run" --steps 1', names=["scene.json"],
     setup='cp -r "$F/data" d; cp d/00001.data/L003.png d/00001.data/L004.png\n', may_change=RUN, timeout=60,
     why="The same extra image inside a training dataset: refused naming the object's scene.json before the "
         "first step (or the object named as failed), never trained on a light that was never rendered.")
case("u43-unips-mixed-png-and-jpg", "input", PRM_RUN + ' --input "$C/u/obj.data" --out "$C/p"', expect="either",
     names=["obj.data"], setup=RUNCP + py("""
        import os, shutil, cv2
        F = os.environ['F']
        os.makedirs('u/obj.data')
        for i in range(4):
            im = cv2.imread(f'{F}/data/00000.data/L00{i}.png', cv2.IMREAD_UNCHANGED)
            if i % 2:
                cv2.imwrite(f'u/obj.data/L{i}.jpg', (im // 257).astype('uint8'))
            else:
                shutil.copy(f'{F}/data/00000.data/L00{i}.png', f'u/obj.data/L{i}.png')
        shutil.copy(F + '/data/00000.data/mask.png', 'u/obj.data/mask.png')
        """), may_change=P, timeout=60,
     why="16-bit PNGs and 8-bit JPEGs in one official folder: predicted with each file scaled by its own range, or "
         "refused naming the folder; never a traceback.")
case("u43-unips-image-other-size", "input", PRSH + ' --input "$C/u/obj.data" --out "$C/p"', names=["L3.png"],
     setup=py("""
        import os, shutil, cv2
        F = os.environ['F']
        os.makedirs('u/obj.data')
        for i in range(4):
            shutil.copy(f'{F}/data/00000.data/L00{i}.png', f'u/obj.data/L{i}.png')
        im = cv2.imread('u/obj.data/L3.png', cv2.IMREAD_UNCHANGED)
        cv2.imwrite('u/obj.data/L3.png', cv2.resize(im, (40, 32)))
        """), may_change=P, timeout=30,
     why="One image of an official folder 40x32 among 32x32 ones: refused naming L3.png and both sizes.")

# =================================================================== DiLiGenT folders
case("u43-dil-small-ball-ls-ok", "input", DIL_LS + fault_unless('[ -s "$C/p/ballPNG/normal.png" ]', "no normal.png"),
     expect="ok", setup=SMALL_DIL, may_change=P, timeout=60,
     why="The small DiLiGenT ball (8 images, 77x64) is a valid DiLiGenT folder: least squares with its light "
         "files predicts it (the baseline of the edited folders below).")
case("u43-dil-one-image-other-size", "input", DIL_LS, names=["005.png"],
     setup=SMALL_DIL + py("""
        import cv2
        im = cv2.imread('dil/ballPNG/005.png', cv2.IMREAD_UNCHANGED)
        cv2.imwrite('dil/ballPNG/005.png', cv2.resize(im, (76, 64)))
        """), may_change=P, timeout=30,
     why="One DiLiGenT image a pixel narrower than the others: refused naming 005.png and both sizes.")
case("u43-dil-one-image-8-bit", "input", DIL_LS, expect="either", names=["002.png"],
     setup=SMALL_DIL + py("""
        import cv2
        im = cv2.imread('dil/ballPNG/002.png', cv2.IMREAD_UNCHANGED)
        cv2.imwrite('dil/ballPNG/002.png', (im // 257).astype('uint8'))
        """), may_change=P, timeout=30,
     why="One image re-saved as 8-bit among 16-bit ones: read on one scale (each file by its own range) or "
         "refused naming 002.png; never its raw codes taken as 257 times darker.")
case("u43-dil-one-image-rgba", "input", DIL_LS, expect="either", names=["003.png"],
     setup=SMALL_DIL + py("""
        import cv2, numpy as np
        im = cv2.imread('dil/ballPNG/003.png', cv2.IMREAD_UNCHANGED)
        a = np.full(im.shape[:2] + (1,), 65535, im.dtype)
        cv2.imwrite('dil/ballPNG/003.png', np.concatenate([im, a], axis=2))
        """), may_change=P, timeout=30,
     why="One image saved with an opaque alpha channel: read as RGB, or refused naming 003.png; never a "
         "traceback from a 4-channel stack.")
case("u43-dil-lights-comma-decimal", "input", DIL_LS, names=["light_directions.txt"],
     setup=dil_text("light_directions.txt", "out = '\\n'.join(l.replace('.', ',') for l in lines) + '\\n'"),
     may_change=P, timeout=30,
     why="Directions written with decimal commas (a European spreadsheet: '-0,0635 -0,4317 0,8998') read as 6 "
         "numbers a line: refused naming light_directions.txt and the line, never six numbers cut to three.")
case("u43-dil-lights-fortran-exponent", "input", DIL_LS, names=["light_directions.txt"],
     setup=dil_text("light_directions.txt",
                    "out = '\\n'.join(' '.join(f'{float(v):.6E}'.replace('E', 'D') for v in l.split()) "
                    "for l in lines) + '\\n'"), may_change=P, timeout=30,
     why="Numbers in Fortran notation (6.350000D-02): not numbers Python reads; refused naming the file and line 1.")
case("u43-dil-lights-tab-separated-ok", "input", DIL_LS + fault_unless('[ -s "$C/p/ballPNG/normal.png" ]', "no map"),
     expect="ok", setup=dil_text("light_directions.txt", "out = '\\n'.join('\\t'.join(l.split()) for l in lines)"),
     may_change=P, timeout=60,
     why="Tab-separated light directions without a final newline are whitespace-separated numbers: read.")
case("u43-dil-lights-header-line", "input", DIL_LS, names=["light_directions.txt"],
     setup=dil_text("light_directions.txt", "out = 'x y z\\n' + '\\n'.join(lines) + '\\n'"), may_change=P, timeout=30,
     why="A header row 'x y z' above the numbers: refused naming the file and line 1 (not skipped: then the row "
         "count says 9 for 8 images anyway).")
case("u43-dil-listing-shorter-than-lights", "input", DIL_LS, names=["light_directions.txt"],
     setup=dil_text("filenames.txt", "out = '\\n'.join(lines[:7]) + '\\n'"), may_change=P, timeout=30,
     why="filenames.txt lists 7 images while the light files hold 8 rows: which row belongs to which image is "
         "unknown; refused naming the light file's row count, never the first 7 rows paired with 7 images.")
case("u43-dil-intensities-grey-one-column", "input", DIL_LS, names=["light_intensities.txt"],
     setup=dil_text("light_intensities.txt", "out = '\\n'.join(l.split()[0] for l in lines) + '\\n'"),
     may_change=P, timeout=30,
     why="Grey intensities (one number a row) where DiLiGenT gives RGB: refused naming light_intensities.txt and "
         "line 1, not broadcast.")
case("u43-dil-listing-names-with-tab-prefix", "input", DIL_LS, expect="either", names=["filenames.txt"],
     setup=dil_text("filenames.txt", "out = '\\n'.join('\\t' + l for l in lines) + '\\n'"), may_change=P, timeout=60,
     why="Listing lines indented with a tab: the names stripped (predicted) or refused naming filenames.txt; "
         "never 'file not found' for a name starting with a tab.")
case("u43-bench-diligent-cat-lights-extra-column", "input",
     BM + ' --diligent "$C/dil" --diligent-images 8 --checkpoint "$C/run/final.safetensors" --out "$C/b"'
     + '; r=$?; [ -e "$C/b/tables.md" ] && { echo "FAULT: tables.md written"; exit 0; }; exit $r',
     names=["light_directions.txt"],
     setup=RUNCP + SMALL_DIL + "cp -r dil/ballPNG dil/catPNG\n"
           + py("""
        p = 'dil/catPNG/light_directions.txt'
        lines = open(p).read().splitlines()
        open(p, 'w').write(''.join(l + ' 1.0\\n' for l in lines))
        """), may_change=["$C/b", "$C/b/*"], timeout=120,
     why="The benchmark's cat has light rows of four numbers: refused naming catPNG's light_directions.txt before "
         "tables.md is written (not a table with the cat left out).")

# =================================================================== shards: index counts edited
case("u43-shard-index-images-raised", "input", TR + ' --data "$C/sh" --out "$C/run" --steps 1', names=["index.json"],
     setup=SHCP + jedit("sh/index.json", "d['shards'][0]['objects'][1]['images'] = 12"), may_change=RUN, timeout=60,
     why="index.json says object 00001 has 12 images, its sample holds 8: refused naming the index and the "
         "object (the shard and its index disagree).")
case("u43-shard-index-images-lowered-streamed", "input",
     TR + ' --data "$C/sh" --out "$C/run" --steps 1 --shuffle-buffer 2 --loader-workers 0', names=["index.json"],
     setup=SHCP + jedit("sh/index.json", "d['shards'][0]['objects'][0]['images'] = 4"), may_change=RUN, timeout=60,
     why="The same disagreement read through the streaming loader (--shuffle-buffer): refused naming index.json, "
         "not trained on without a word because the stream skips the in-memory check.")
case("u43-shard-sample-lost-an-image-index-rewritten", "input", TR + ' --data "$C/sh" --out "$C/run" --steps 1',
     names=["00000"], setup=SHCP + py("""
        import hashlib, io, json, os, tarfile
        src = tarfile.open('sh/000000.tar')
        out = io.BytesIO()
        with tarfile.open(fileobj=out, mode='w', format=tarfile.USTAR_FORMAT) as t:
            for m in src.getmembers():
                if m.name == '00000.L002.png':
                    continue
                t.addfile(m, src.extractfile(m))
        data = out.getvalue()
        open('sh/000000.tar', 'wb').write(data)
        d = json.load(open('sh/index.json'))
        e = d['shards'][0]
        e['sha256'] = hashlib.sha256(data).hexdigest(); e['bytes'] = len(data)
        e['objects'][0]['images'] = 7
        json.dump(d, open('sh/index.json', 'w'), indent=1)
        """), may_change=RUN, timeout=60,
     why="Object 00000's L002 removed from the shard and the index rewritten to match (7 images): the sample's "
         "images are L000, L001, L003.. with a gap; refused naming 00000 as a folder with that gap would be.")
case("u43-shard-index-object-name-with-tab", "input", TR + ' --data "$C/sh" --out "$C/run" --steps 1',
     names=["index.json"], setup=SHCP + jedit("sh/index.json", "d['shards'][0]['objects'][0]['name'] = '00000\\t'"),
     may_change=RUN, timeout=60,
     why="An index naming object '00000<TAB>' where the shard holds 00000: the shard and index disagree; refused "
         "naming index.json (or the shard), with the name shown escaped.")
case("u43-shard-val-index-counts-edited", "input",
     TR + ' --data "$F/data" --val "$C/sh" --val-every 1 --out "$C/run" --steps 1', names=["--val"],
     setup=SHCP + jedit("sh/index.json", "d['objects'] = 4"), may_change=RUN, timeout=60,
     why="A --val shard index whose object count disagrees with its shards: refused naming --val and index.json "
         "before training (not after the first step, at the first validation).")

# =================================================================== torchrun variables
case("u43-train-env-world-1-with-local-world-size", "engine",
     "WORLD_SIZE=1 RANK=0 LOCAL_RANK=0 LOCAL_WORLD_SIZE=8 GROUP_RANK=3 " + TR + ' --data "$F/data" --out "$C/run" '
     "--steps 1" + fault_unless('[ -s "$C/run/final.safetensors" ]', "no final.safetensors"), expect="ok",
     may_change=RUN, timeout=90,
     why="WORLD_SIZE=1 is a single process whatever LOCAL_WORLD_SIZE and GROUP_RANK say: it trains.")
case("u43-train-env-world-2-batch-odd", "engine",
     "WORLD_SIZE=2 RANK=0 LOCAL_RANK=0 MASTER_ADDR=127.0.0.1 MASTER_PORT=29571 UNIPS_JOIN_TIMEOUT_S=4 "
     + TR.replace("--batch 1", "--batch 3") + ' --data "$F/data" --out "$C/run" --steps 1',
     names=["--batch"], may_change=RUN, timeout=60,
     why="--batch 3 cannot be split between 2 processes: refused naming --batch before the rendezvous (no "
         "wait for a second process).")
case("u43-train-env-rank-with-newline", "engine",
     "WORLD_SIZE=1 RANK=$'0\\n' LOCAL_RANK=0 " + TR + ' --data "$F/data" --out "$C/run" --steps 1', expect="either",
     names=["RANK"], may_change=RUN, timeout=90,
     why="RANK='0<newline>' (a value read from a file with its line end): trained as rank 0, or refused naming "
         "RANK; never a traceback.")

# =================================================================== paths with tab / newline characters
case("u43-chain-object-name-with-newline-predict-evaluate", "input",
     PRSH + ' --input "$C/ds" --out "$C/p" && ' + EV + ' --pred "$C/p" --gt "$C/ds"'
     + fault_unless("$PY -c \"import csv,sys; rows=list(csv.reader(open('$C/p/metrics.csv', newline=''))); "
                    "sys.exit(0 if any('x\\ny' in r for r in rows) else 1)\"",
                    "metrics.csv does not hold the object name x<newline>y as one quoted field"),
     expect="either", names=["ds"],
     setup='mkdir ds; cp -r "$F/data/00000.data" "ds/x"$\'\\n\'"y.data"; cp -r "$F/data/00001.data" ds/\n',
     may_change=P, timeout=60,
     why="An object folder named x<newline>y: predicted and evaluated with the name kept whole (metrics.csv quotes "
         "it), or refused naming the folder; never a metrics.csv whose rows split the name in two.")
case("u43-pred-input-folder-with-tab", "input",
     PRSH + ' --input "$C/a"$\'\\t\'"b/o.data" --out "$C/p"' + fault_unless('[ -s "$C/p/o/normal.png" ]', "no map"),
     expect="ok", setup='mkdir "a"$\'\\t\'"b"; cp -r "$F/data/00000.data" "a"$\'\\t\'"b/o.data"\n', may_change=P,
     timeout=30,
     why="A tab in a folder name above the object is a valid path: predicted into p/o/.")
case("u43-train-out-with-newline-then-predict", "input",
     TR + ' --data "$F/data" --out "$C/r"$\'\\n\'"un" --steps 1 && ' + PRM + ' --checkpoint "$C/r"$\'\\n\'"un/'
     'final.safetensors" --input ' + OBJ + ' --out "$C/p"', expect="ok",
     may_change=P + ["$C/r*", "$C/r*/*"], timeout=120,
     why="A run folder whose name holds a newline is a valid path: trained, and its final weights (with their "
         "sidecar found beside them) predict.")
case("u43-pred-checkpoint-path-with-tab", "weights",
     PRM + ' --checkpoint "$C/w"$\'\\t\'"x/m.safetensors" --input ' + OBJ + ' --out "$C/p"', expect="ok",
     setup='mkdir "w"$\'\\t\'"x"; cp "$F/run/final.safetensors" "w"$\'\\t\'"x/m.safetensors"; '
           'cp "$F/run/final.json" "w"$\'\\t\'"x/m.json"\n', may_change=P, timeout=60,
     why="Weights in a folder with a tab in its name load like any others.")

# =================================================================== orchestrate.error_calibration
case("u43-ec-weights-sidecar-renamed-model", "weights",
     EC + ' --work "$C/w" --weights "$C/m/final.safetensors" --out "$C/ec.json"'
     + '; r=$?; [ -e "$C/w/val" ] || [ -n "$(ls -A "$C/w" 2>/dev/null)" ] && { echo "FAULT: --work written"; exit 0; }; '
       'exit $r', names=["--weights", "final.json"],
     setup='mkdir m; cp "$F/run/final.safetensors" "$F/run/final.json" m/\n'
           + jedit("m/final.json", "d['model_name'] = 'glc-tiny'"),
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/ec.json"], timeout=60,
     why="Weights whose sidecar says glc-tiny over glc-test tensors: refused naming --weights and the sidecar "
         "before the asset split or a suite row is written into --work.")
case("u43-ec-weights-pt-nested-model", "weights",
     EC + ' --work "$C/w" --weights ' + W_PT + ' --out "$C/ec.json"', names=["--weights", "m.pt"],
     setup=pt_edit("c['model'] = {'model': c['model']}"),
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/ec.json"], timeout=60,
     why="A .pt whose 'model' nests another dict: refused naming --weights before any render.")
case("u43-ec-out-a-copy-of-the-model-card", "writer",
     EC + ' --work "$C/w" --weights "$C/m/final.safetensors" --out "$C/model_card.json"', names=["--out"],
     setup='mkdir m; cp "$F/run/final.safetensors" "$F/run/final.json" m/; '
           'cp "$REPO/unips/weights/model_card.json" model_card.json\n',
     may_change=["$C/w", "$C/w/*", "$C/w/*/*"], timeout=60,
     why="--out naming an existing model card (a JSON file this command did not write): refused naming --out "
         "before rendering, never replaced after an hour of work.")
case("u43-ec-work-is-a-diligent-folder", "writer",
     EC + ' --work "$C/dil" --weights "$C/m/final.safetensors" --out "$C/ec.json"', names=["--work"],
     setup=SMALL_DIL + 'mkdir m; cp "$F/run/final.safetensors" "$F/run/final.json" m/\n',
     may_change=["$C/ec.json"], timeout=60,
     why="--work pointing at a DiLiGenT folder (the user's benchmark data): refused naming --work and one of its "
         "files; the suite's rows are never rendered among them.")

# =================================================================== orchestrate.train_recipe
case("u43-recipe-init-from-pt-complex", "weights", RCW + ' --init-from ' + W_PT,
     names=["--init-from"], setup=pt_edit("c['model'][k] = c['model'][k].to(torch.complex64)"),
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"], timeout=60,
     why="The recipe checks every step's arguments before the first: complex weights for --init-from are refused "
         "naming it before any data is rendered.")
case("u43-recipe-init-from-sidecar-renamed", "weights",
     RCW + ' --init-from "$C/m/final.safetensors"', names=["--init-from"],
     setup='mkdir m; cp "$F/run/final.safetensors" "$F/run/final.json" m/\n'
           + jedit("m/final.json", "d['model_name'] = 'glc-tiny'"),
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"], timeout=60,
     why="--init-from weights whose sidecar names another model than their metadata: refused before rendering, "
         "naming --init-from and the sidecar.")
case("u43-recipe-init-from-path-with-newline", "input",
     RCW + ' --init-from "$C/m"$\'\\n\'"x.safetensors"', names=["--init-from"],
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"], timeout=60,
     why="A missing --init-from whose name holds a newline: refused in one line with the name shown escaped "
         "(the message must not break into two lines that read like separate errors).")

# =================================================================== orchestrate.ship (in a copy of the tree)
case("u43-ship-candidate-sidecar-renamed-glc-tiny", "weights",
     SHIP + ' --candidate "$C/cand" --val "$F/data"' + REPO_SAME, names=["final.json"],
     setup=REPO_COPY + 'mkdir -p cand/run; cp "$F/run/final.safetensors" "$F/run/final.json" cand/run/\n'
           + jedit("cand/run/final.json", "d['model_name'] = 'glc-tiny'"),
     may_change=REPO_CHANGE, timeout=120,
     why="A glc-test run whose sidecar was renamed glc-tiny to pass as the shipped model: refused naming "
         "final.json (the metadata disagrees; the config is not the shipped one); the registry is untouched.")
case("u43-ship-candidate-summary-wall-s-huge-int", "input",
     SHIP + ' --candidate "$C/cand" --val "$F/data"' + REPO_SAME, names=["summary.json"],
     setup=REPO_COPY + 'mkdir -p cand/run; cp "$REPO/unips/weights/glc-tiny.safetensors" cand/run/final.safetensors; '
           'cp "$REPO/unips/weights/glc-tiny.json" cand/run/final.json; '
           "printf '{\"wall_s\": 1%0400d}' 0 > cand/summary.json\n",
     may_change=REPO_CHANGE, timeout=120,
     why="summary.json's wall_s a 401-digit integer: not a number of seconds; refused naming summary.json before "
         "any scoring, never written into the model card.")
case("u43-ship-candidate-card-hardware-with-escape-codes", "input",
     SHIP + ' --candidate "$C/cand" --val "$F/data"'
     + '; r=$?; grep -q $\'\\x1b\' "$C/repo/unips/weights/model_card.json" && { echo "FAULT: raw escape code in '
       'the card"; exit 0; }; exit $r',
     expect="either", names=["model_card.json"],
     setup=REPO_COPY + 'mkdir -p cand/run; cp "$REPO/unips/weights/glc-tiny.safetensors" cand/run/final.safetensors; '
           'cp "$REPO/unips/weights/glc-tiny.json" cand/run/final.json; '
           + py("""
        import json
        json.dump({'hardware': '\\x1b[2J\\x1b[31mH200\\x07', 'steps': 1}, open('cand/model_card.json', 'w'))
        """),
     may_change=REPO_CHANGE, timeout=120,
     why="A session record whose hardware text holds terminal escape codes: refused naming model_card.json, or "
         "recorded as JSON-escaped text; the printed line must not clear the user's terminal.")

# =================================================================== interrupted runs read by the next command
case("u43-train-kill9-then-predict-from-last-pt", "signal",
     "( " + TR + ' --data "$F/data" --out "$C/run" --steps 400 --ckpt-every 1 ) > t.log 2>&1 & p=$!; '
     'for i in $(seq 150); do [ -s "$C/run/last.pt" ] && break; sleep 0.2; done; sleep 1.5; kill -9 $p; wait $p; '
     + PRM + ' --checkpoint "$C/run/last.pt" --input ' + OBJ + ' --out "$C/p"'
     + fault_unless('[ -s "$C/p/00000/normal.png" ]', "no normal.png"),
     expect="ok", may_change=RUN + P + ["$C/t.log"], timeout=120,
     why="A run killed with SIGKILL while it saves last.pt every step leaves a whole last.pt (written atomically): "
         "the weights it holds predict.")
case("u43-train-kill9-then-init-from-its-last-pt", "signal",
     "( " + TR + ' --data "$F/data" --out "$C/run" --steps 400 --ckpt-every 1 ) > t.log 2>&1 & p=$!; '
     'for i in $(seq 150); do [ -s "$C/run/last.pt" ] && break; sleep 0.2; done; sleep 1; kill -9 $p; wait $p; '
     + TR + ' --data "$F/data" --out "$C/run2" --steps 1 --init-from "$C/run/last.pt"',
     expect="ok", may_change=RUN + ["$C/run2", "$C/run2/*", "$C/t.log"], timeout=120,
     why="The last.pt of a killed run is a valid --init-from for a new run in another folder (weights only), "
         "whatever step it stopped at.")
