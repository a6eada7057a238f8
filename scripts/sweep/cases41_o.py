"""Sweep 41, part o: the MODEL side (unips.train, unips.predict, unips.evaluate, orchestrate.ship,
orchestrate.benchmark, orchestrate.error_calibration), with cases that cases37-40 and tests/ do not hold:
hand-edited run folders and sidecars, contradicting flags on --resume / --init-from, special files where a file
is read, links planted in an output folder before --overwrite, degenerate ground truth, official UniPS folders
with odd members. Commands that add their own check print a `FAULT:` line and exit 0 so the harness flags them.
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


TR = ("$PY -m unips.train --model glc-test --res 16 --no-progress --threads 1 --batch 1 --pixels 50 "
      "--canonical-points 50 --max-images 4")
"""The cheapest training command (glc-test at 16 px); add --data, --out, --steps."""
TR1 = TR + ' --data "$F/data" --out "$C/run" --steps 1'
TRR = "$PY -m unips.train --model glc-test --no-progress --threads 1"
RESUME = TRR + ' --data "$F/data8" --out "$C/run" --steps 3 --resume'
"""Resume a copy of the fixture run (2 steps of glc-test on data8) to step 3."""
RUN = ["$C/run", "$C/run/*", "$C/run/*/*"]
RUNCP = 'cp -r "$F/run" run\n'
PR = "$PY -m unips.predict"
PRM = PR + " --method model --tta 1 --no-expected-error"
PRLS = PR + " --method least-squares"
OBJ = '"$F/data/00000.data"'
EV = "$PY -m unips.evaluate"
BM = "$PY -m orchestrate.benchmark --threads 1"
BMD = BM + ' --data "$F/data" --rerender-objects 0 --counts 1 --images 4 --tta 1'
EC = '$PY -m orchestrate.error_calibration --assets none --objects 1 --threads 1 --pixels 50 --out "$C/ee.json"'
"""Error calibration, as small as it goes, writing its fit to $C/ee.json (never beside the shipped weights)."""
DS = 'cp -r "$F/data" d\n'
PREDCP = 'cp -r "$F/pred" p\n'
W = '"$REPO/unips/weights/glc-tiny.safetensors"'
WJ = '"$REPO/unips/weights/glc-tiny.json"'
SHIPPED = f"mkdir -p w; cp {W} w/m.safetensors; cp {WJ} w/m.json\n"
"""Setup: w/m.safetensors + w/m.json, a copy of the shipped weights."""
PRM_W = PRM + ' --checkpoint "$C/w/m.safetensors" --input ' + OBJ + ' --out "$C/p"'
P = ["$C/p", "$C/p/*", "$C/p/*/*"]
REPO_COPY = r"""mkdir repo
(cd "$REPO" && git ls-files -z --cached --others --exclude-standard | tar --null -T - --ignore-failed-read -cf - 2>/dev/null) | tar -xf - -C repo
"""
SHIP = 'cd "$C/repo" && PYTHONPATH="$C/repo" $PY -m orchestrate.ship --threads 1 --diligent none'
CAND = ('mkdir -p cand/run; cp "$REPO/unips/weights/glc-tiny.safetensors" cand/run/final.safetensors; '
        'cp "$REPO/unips/weights/glc-tiny.json" cand/run/final.json\n')
REPO_SAME = ('; r=$?; (cd "$C/repo" && git -C "$REPO" ls-files -z unips/weights | '
             'xargs -0 -I{} cmp -s "$REPO/{}" "$C/repo/{}") || { echo "FAULT: the registry copy changed"; exit 0; }; '
             'exit $r')
"""Command tail: a refusal that still changed the copy's registry exits 0 with a FAULT line."""
REPO_CHANGE = ["$C/repo/unips/weights/*"]


def sidecar(code: str, path: str = "w/m.json") -> str:
    """Setup: edit the JSON sidecar PATH by hand (`s` is the loaded dict)."""
    return py(f"import json\np = {path!r}\ns = json.load(open(p))\n" + textwrap.dedent(code).strip()
              + "\njson.dump(s, open(p, 'w'), indent=1)\n")


def ckpt_edit(code: str, dest: str = "run/last.pt") -> str:
    """Setup: DEST, the fixture run's last.pt edited by `code` (`c`), its checksum rewritten to match."""
    return py(textwrap.dedent("""
        import torch, os
        from unips.models.builder import CHECKSUM_KEY, content_digest
        c = torch.load(os.environ['F'] + '/run/last.pt', weights_only=True)
        """) + textwrap.dedent(code).strip() + textwrap.dedent(f"""
        c[CHECKSUM_KEY] = content_digest(c)
        torch.save(c, {dest!r})
        """))


def unchanged(path: str, what: str) -> str:
    """Command tail: FAULT (exit 0) when the file PATH no longer holds the bytes saved in PATH.orig-sum."""
    return (f'; r=$?; if ! sha1sum -c --status "{path}.sum" 2>/dev/null; then echo "FAULT: {what}"; exit 0; fi; exit $r')


def remember(path: str) -> str:
    return f'sha1sum "{path}" > "{path}.sum"\n'


# ============================================================================ unips.train: flag values
case("o41-train-res-huge", "input", TR.replace("--res 16", "--res 100000") + ' --data "$F/data" --out "$C/run" --steps 1',
     names=["--res"], may_change=RUN, timeout=60,
     why="--res 100000 caches crops of 10^10 pixels per object: refused naming --res before any allocation, not "
         "an out-of-memory kill.")
case("o41-train-decay-every-zero", "input", TR1 + " --schedule step --decay-every 0", names=["--decay-every"],
     may_change=RUN, timeout=60, why="--decay-every 0 with the step schedule divides by zero: refused naming it.")
case("o41-train-seed-beyond-64-bit", "input", TR1 + " --seed 99999999999999999999999", names=["--seed"],
     may_change=RUN, timeout=60,
     why="A seed beyond 64 bits cannot seed torch: refused naming --seed, not an OverflowError traceback.")
case("o41-train-out-holds-users-own-final", "writer", TR1, names=["--out"],
     setup=f'mkdir run; cp {W} run/final.safetensors; cp {WJ} run/final.json\n', timeout=60,
     why="--out holds a final.safetensors the user put there (no log.jsonl, no last.pt): training would replace a "
         "file it did not write; refused without --overwrite.")
case("o41-train-init-from-into-other-run-folder", "writer",
     TR + ' --data "$F/data8" --out "$C/run" --steps 1 --init-from "$REPO/unips/weights/glc-tiny.safetensors" '
     "--model glc-tiny", names=["--out"], setup=RUNCP, timeout=90,
     why="--init-from starts a NEW run; --out already holds another run (log.jsonl, last.pt, final): its files would "
         "be replaced, so it is refused without --overwrite (or the old run is kept intact).")
case("o41-train-resume-out-missing", "input", RESUME.replace('"$C/run"', '"$C/nowhere"'), names=["--resume"],
     timeout=60, why="--resume of a run folder that does not exist: nothing to continue, one line naming --resume "
                     "or last.pt, no folder created.")
case("o41-train-resume-other-seed", "input", RESUME + " --seed 7", names=["--seed"], setup=RUNCP, may_change=RUN,
     timeout=90, why="--resume promises bit-for-bit continuation; a different --seed than the run's contradicts it: "
                     "refused naming --seed (or the run's seed is used and said so; never silently mixed).")
case("o41-train-resume-other-lr", "input", RESUME + " --lr 0.1", names=["--lr"], setup=RUNCP, may_change=RUN,
     timeout=90, why="--resume with a peak --lr other than the run's: the schedule in last.pt disagrees; refused "
                     "naming --lr.")
case("o41-train-resume-other-schedule", "input", RESUME + " --schedule step", names=["--schedule"], setup=RUNCP,
     may_change=RUN, timeout=90,
     why="--resume with --schedule step of a cosine run: the scheduler state cannot mean the same; refused.")
case("o41-train-resume-last-pt-empty", "input", RESUME, names=["last.pt"], setup=RUNCP + ': > run/last.pt\n',
     may_change=RUN, timeout=60, why="A 0-byte last.pt (disk full at save): refused naming last.pt, no traceback.")
case("o41-train-resume-last-pt-truncated", "input", RESUME, names=["last.pt"],
     setup=RUNCP + 'truncate -s $(( $(stat -c %s run/last.pt) / 2 )) run/last.pt\n', may_change=RUN, timeout=60,
     why="last.pt cut in half: refused naming last.pt; log.jsonl and final.* kept.")
case("o41-train-resume-last-pt-step-negative", "input", RESUME, names=["last.pt"],
     setup=RUNCP + ckpt_edit("c['step'] = -4"), may_change=RUN, timeout=60,
     why="A checksummed last.pt whose step is -4: no run is at a negative step; refused naming last.pt/step.")
case("o41-train-resume-last-pt-step-fractional", "input", RESUME, names=["last.pt"],
     setup=RUNCP + ckpt_edit("c['step'] = 1.5"), may_change=RUN, timeout=60,
     why="A checksummed last.pt whose step is 1.5: refused naming last.pt, not a traceback in range().")
case("o41-train-resume-last-pt-no-optimizer", "input", RESUME, names=["last.pt"],
     setup=RUNCP + ckpt_edit("c.pop(next(k for k in list(c) if 'optim' in k))"), may_change=RUN, timeout=60,
     why="last.pt without its optimiser state cannot continue bit for bit: refused naming last.pt.")
case("o41-train-resume-log-link-dev-null", "input", RESUME, names=["log.jsonl"],
     setup=RUNCP + 'rm run/log.jsonl; ln -s /dev/null run/log.jsonl\n', may_change=RUN, timeout=60,
     why="log.jsonl replaced by a link to /dev/null: the run's record is gone; refused naming log.jsonl (never "
         "appending to a device).")
case("o41-train-resume-log-step-a-string", "input", RESUME, expect="either",
     setup=RUNCP + "sed -i 's/\"step\": \\([0-9]*\\)/\"step\": \"\\1\"/' run/log.jsonl\n", may_change=RUN, timeout=90,
     why="log.jsonl edited so that step is a string: either read as the same step or refused naming log.jsonl; "
         "no traceback.")
case("o41-train-init-from-empty-file", "input", TR1 + ' --init-from "$C/m.safetensors"', names=["--init-from"],
     setup=': > m.safetensors; echo "{}" > m.json\n', may_change=RUN, timeout=60,
     why="An empty weights file: refused naming --init-from and the file.")
case("o41-train-init-from-without-sidecar", "input",
     TR1 + ' --init-from "$C/w/m.safetensors" --model glc-tiny', names=["m.json"],
     setup=SHIPPED + 'rm w/m.json\n', may_change=RUN, timeout=60,
     why="A .safetensors without its .json sidecar: the config is unknown; refused naming the missing m.json.")
case("o41-train-init-from-with-architecture-option", "input",
     TR1 + ' --init-from "$C/w/m.safetensors" --model glc-tiny --model-option decoder_dim=8',
     names=["--model-option"], setup=SHIPPED, may_change=RUN, timeout=60,
     why="--model-option decoder_dim=8 changes the shapes of the --init-from weights: refused naming the option.")
case("o41-train-model-option-not-json", "input", TR1 + " --model-option uniform_context=yes",
     names=["--model-option"], may_change=RUN, timeout=60,
     why="The value must be JSON (true/false): 'yes' is refused naming --model-option, not read as a string.")
case("o41-train-model-option-window-zero", "input", TR1 + " --model-option swin_window=0",
     names=["--model-option"], may_change=RUN, timeout=60,
     why="A Swin window of 0 cannot build a model: refused naming --model-option, no ZeroDivisionError.")
case("o41-train-resume-final-json-a-folder", "writer", RESUME, names=["final.json"],
     setup=RUNCP + 'rm run/final.json; mkdir run/final.json; echo mine > run/final.json/notes.txt\n',
     may_change=["$C/run/log.jsonl", "$C/run/last.pt", "$C/run/final.safetensors", "$C/run/*.lock", "$C/run/*.tmp*"],
     timeout=90,
     why="run/final.json is now a folder of the user's: the resumed run cannot write its sidecar there; refused "
         "naming final.json (best before training), the folder and its file kept.")
case("o41-train-two-resumes-at-once", "concurrency",
     "( " + RESUME + " ) > a.log 2>&1 & p1=$!; sleep 0.5; ( " + RESUME + " ) > b.log 2>&1 & p2=$!; "
     'wait $p1; r1=$?; wait $p2; r2=$?; cat a.log b.log; echo "rc $r1 $r2"; '
     + py("""
        import json, collections, sys
        steps = [json.loads(l).get('step') for l in open('run/log.jsonl') if l.strip() and '"loss"' in l]
        dup = [s for s, n in collections.Counter(steps).items() if n > 1]
        if dup:
            sys.exit('FAULT: log.jsonl holds step(s) %s twice' % dup)
        """) + 'r3=$?; [ $r3 = 0 ] && { [ $r1 = 0 ] || [ $r2 = 0 ]; }',
     expect="ok", setup=RUNCP, may_change=RUN, timeout=120,
     why="Two --resume of one run started together: one holds the folder and the other is refused in one line; "
         "log.jsonl records each step once (a FAULT line and exit 1 when a step is logged twice).")
case("o41-train-data-path-dot-segments", "input",
     TR + ' --data "$F/data/./../data/" --out "$C/run" --steps 1 && test -f "$C/run/final.safetensors"', expect="ok",
     may_change=RUN, timeout=90,
     why="--data written with ./ and ../ segments and a trailing slash is the same dataset: trains (exit 0).")
case("o41-train-data-image-a-fifo", "input", TR + ' --data "$C/d" --out "$C/run" --steps 1', names=["L001.png"],
     setup=DS + 'rm d/00001.data/L001.png; mkfifo d/00001.data/L001.png\n', may_change=RUN, timeout=60,
     why="An image replaced by a FIFO: refused naming it without blocking on open.")
case("o41-train-data-normal-link-dev-zero", "input", TR + ' --data "$C/d" --out "$C/run" --steps 1',
     names=["normal.tif"], setup=DS + 'rm d/00002.data/normal.tif; ln -s /dev/zero d/00002.data/normal.tif\n',
     may_change=RUN, timeout=60,
     why="normal.tif a link to /dev/zero: refused naming it, no endless read.")
case("o41-train-data-normal-truncated", "input", TR + ' --data "$C/d" --out "$C/run" --steps 1',
     names=["normal.tif"], setup=DS + 'truncate -s 300 d/00000.data/normal.tif\n', may_change=RUN, timeout=60,
     why="A truncated ground-truth normal.tif: refused naming it (and the object), not trained on garbage.")
case("o41-train-data-mask-all-black", "input", TR + ' --data "$C/d" --out "$C/run" --steps 1', expect="either",
     setup=DS + py("""
        from PIL import Image
        im = Image.open('d/00001.data/mask.png'); Image.new(im.mode, im.size, 0).save('d/00001.data/mask.png')
        """), may_change=RUN, timeout=60,
     why="An object whose mask is empty has no pixel to learn from: refused naming it or skipped with a warning; "
         "no traceback, no NaN loss.")
case("o41-train-data-scene-json-nul-bytes", "input", TR + ' --data "$C/d" --out "$C/run" --steps 1',
     names=["scene.json"], setup=DS + 'head -c 200 /dev/zero > d/00000.data/scene.json\n', may_change=RUN,
     timeout=60, why="scene.json overwritten with NUL bytes: refused naming it, no UnicodeDecodeError traceback.")
case("o41-train-shards-tar-truncated", "input", TR + ' --data "$C/s" --out "$C/run" --steps 1',
     names=["000000.tar"], setup='cp -r "$F/shards" s; truncate -s 40000 s/000000.tar\n', may_change=RUN,
     timeout=60, why="A shard cut short (its sha256 in index.json no longer matches): refused naming the shard.")
# ============================================================================ unips.predict: weights and sidecars
case("o41-pred-sidecar-config-edited", "weights", PRM_W, names=["m.json"],
     setup=SHIPPED + sidecar("s['config']['decoder_dim'] = 64"), may_change=P, timeout=60,
     why="The sidecar's config no longer matches the tensors: refused naming the file, never random weights.")
case("o41-pred-sidecar-config-nan", "weights", PRM_W, names=["m.json"],
     setup=SHIPPED + sidecar("s['config']['dropout'] = float('nan')"), may_change=P, timeout=60,
     why="NaN written into the sidecar's config (json.dump writes NaN): refused naming the file.")
case("o41-pred-sidecar-utf16", "weights", PRM_W, expect="either",
     setup=SHIPPED + py("p='w/m.json'; t=open(p).read(); open(p,'w',encoding='utf-16').write(t)"), may_change=P,
     timeout=60, why="A sidecar re-saved as UTF-16 by an editor: read or refused naming m.json; no traceback.")
case("o41-pred-sidecar-of-test-run", "weights", PRM_W, names=["m.json"],
     setup=SHIPPED + 'rm w/m.json; ln -s "$F/run/final.json" w/m.json\n', may_change=P, timeout=60,
     why="The sidecar is a link to a glc-test run's final.json beside glc-tiny tensors: refused naming the file.")
case("o41-pred-checkpoint-is-the-sidecar", "weights",
     PRM + ' --checkpoint "$C/w/m.json" --input ' + OBJ + ' --out "$C/p"', names=["--checkpoint"], setup=SHIPPED,
     may_change=P, timeout=60, why="--checkpoint names the .json sidecar, not the weights: refused naming --checkpoint.")
case("o41-pred-checkpoint-no-suffix", "weights",
     PRM + ' --checkpoint "$C/w/m" --input ' + OBJ + ' --out "$C/p"', names=["--checkpoint"],
     setup=SHIPPED + 'cp w/m.safetensors w/m\n', may_change=P, timeout=60,
     why="A weights file without a suffix: either read by its content with its sidecar or refused naming "
         "--checkpoint; named either way as --checkpoint when refused.")
case("o41-pred-model-glc-unips-without-checkpoint", "weights",
     PRM + ' --model glc-unips --input ' + OBJ + ' --out "$C/p"', names=["glc-unips"], may_change=P, timeout=60,
     why="No published glc-unips weights are shipped: refused naming the model and how to get the weights, "
         "never random weights.")

# ============================================================================ unips.predict: --out states
case("o41-pred-out-is-a-file", "input", PRM + ' --input ' + OBJ + ' --out "$C/afile"', names=["--out"],
     setup='echo keep > afile\n', timeout=60, why="--out an existing file: refused naming --out; file kept.")
case("o41-pred-out-dangling-link-evil", "writer",
     PRM + ' --input ' + OBJ + ' --out "$C/p"', expect="either",
     setup='ln -s "/tmp/o41-evil-pred-$$" p\n', may_change=["$C/p"], timeout=60,
     why="--out is a dangling link to /tmp: refused, or the predictions go nowhere outside the case; a new evil "
         "folder under /tmp is a write outside the target.")
case("o41-pred-overwrite-predict-json-link-out", "writer",
     PRM + ' --input ' + OBJ + ' --out "$C/p" --overwrite',
     expect="either", setup=PREDCP + 'echo "{\\"mine\\": 1}" > keep.json; ' + remember("keep.json")
     + 'rm p/00000/predict.json; ln -s "$C/keep.json" p/00000/predict.json\n',
     may_change=P, timeout=60,
     why="predict.json in --out was replaced by a link to a user file: --overwrite replaces the link or refuses; "
         "it never writes through it into keep.json.")
case("o41-pred-overwrite-normal-png-link-out", "writer",
     PRM + ' --input ' + OBJ + ' --out "$C/p" --overwrite',
     expect="either", setup=PREDCP + 'cp "$F/mask.png" keep.png; ' + remember("keep.png")
     + 'rm p/00000/normal.png; ln -s "$C/keep.png" p/00000/normal.png\n', may_change=P, timeout=60,
     why="normal.png in --out is a link to a user image: --overwrite never writes through it.")
case("o41-pred-out-is-weights-folder", "writer",
     PRM + ' --checkpoint "$C/w/m.safetensors" --input "$C/d" --out "$C/w" --overwrite', expect="either",
     setup=SHIPPED + DS + 'mkdir -p w/00000; echo x > w/00000/notes.txt\n',
     may_change=["$C/w/0000[12]", "$C/w/0000[12]/*", "$C/w/*.lock"], timeout=90,
     why="--out is the folder of the weights with a user folder 00000/ (no predict.json): 00000 is refused or "
         "left alone even with --overwrite; the weights are never touched.")

# ============================================================================ unips.predict: input layouts
case("o41-pred-ours-no-images", "input", PRM + ' --input "$C/d/00000.data" --out "$C/p"', names=["00000"],
     setup=DS + 'rm d/00000.data/L*.png\n', may_change=P, timeout=60,
     why="An object folder with mask, normal and scene.json but no image: refused naming the object folder.")
case("o41-pred-ours-image-zero-bytes", "input", PRM + ' --input "$C/d/00000.data" --out "$C/p"',
     names=["L002.png"], setup=DS + ': > d/00000.data/L002.png\n', may_change=P, timeout=60,
     why="A 0-byte image: refused naming it.")
case("o41-pred-input-is-predictions", "input", PRM + ' --input "$F/pred" --out "$C/p"', names=["--input"],
     may_change=P, timeout=60,
     why="--input is a folder of predictions (normal.png, no images): refused naming --input, not 'no objects'.")
case("o41-pred-input-is-shards", "input", PRM + ' --input "$F/shards" --out "$C/p"', names=["--input"],
     may_change=P, timeout=60, why="--input is a WebDataset shard folder: refused naming --input (shards are for "
                                   "training), no traceback.")
case("o41-pred-unips-image-a-folder", "input", PRM + ' --input "$C/u.data" --out "$C/p"', names=["L9.png"],
     setup='mkdir u.data; cp "$F/data/00000.data"/L00[0-3].png u.data/; cp "$F/data/00000.data/mask.png" u.data/; '
           'mkdir u.data/L9.png\n', may_change=P, timeout=60,
     why="In an official UniPS folder, a folder named like an image (L9.png/): refused naming it, not an "
         "IsADirectoryError traceback.")
case("o41-pred-unips-same-stem-two-suffixes", "input", PRM + ' --input "$C/u.data" --out "$C/p"', expect="either",
     setup='mkdir u.data; cp "$F/data/00000.data"/L00[0-3].png u.data/; cp "$F/data/00000.data/mask.png" u.data/; '
           + py("from PIL import Image; Image.open('u.data/L000.png').convert('RGB').save('u.data/L000.jpg')"),
     may_change=P, timeout=60,
     why="L000.png and L000.jpg beside each other (the same photo twice): read both, or refused naming them; "
         "no traceback.")
case("o41-pred-dil-listing-empty", "input", PRLS + ' --input "$C/dil/ballPNG" --out "$C/p"',
     names=["filenames.txt"], setup='mkdir dil; cp -r "$F/ballPNG" dil/; : > dil/ballPNG/filenames.txt\n',
     may_change=P, timeout=60,
     why="An empty filenames.txt beside 96 images: refused naming it (or the images read in order with a note); "
         "never zero images silently.")
case("o41-pred-dil-lights-empty", "input", PRLS + ' --input "$C/dil/ballPNG" --out "$C/p"',
     names=["light_directions.txt"],
     setup='mkdir dil; cp -r "$F/ballPNG" dil/; : > dil/ballPNG/light_directions.txt\n', may_change=P, timeout=60,
     why="An empty light_directions.txt: least squares has no light; refused naming the file.")
case("o41-pred-two-objects-one-name", "writer", PRLS.replace("least-squares", "sh-uncalibrated")
     + ' --input "$C/in" --out "$C/p"', names=["00000"],
     setup='mkdir in; cp -r "$F/data/00000.data" in/; cp -r "$F/data/00001.data" in/00000; rm in/00000/scene.json\n',
     may_change=P, timeout=60,
     why="--input holds 00000.data (ours) and 00000 (official layout, another object): both are named 00000 and "
         "would land in one output folder; refused naming them (or written apart), never one silently replacing "
         "the other.")
case("o41-pred-input-trailing-dot-slash", "input",
     PRM + ' --input "$F/data/00000.data/./" --out "$C/p" && test -f "$C/p/00000/predict.json"', expect="ok",
     may_change=P, timeout=60,
     why="An object folder given as DIR/./ is the object 00000: its prediction lands in p/00000, not p/. or p/''.")
case("o41-pred-input-dataset-through-link", "input",
     PRM + ' --input "$C/ln" --out "$C/p" && '
     'test -f "$C/p/00002/predict.json"', expect="ok", setup='ln -s "$F/data" ln\n', may_change=P, timeout=60,
     why="--input a link to a dataset folder is that dataset: three predictions, exit 0.")
case("o41-pred-ls-dil-first-four-lights-nearly-coplanar", "input",
     PRLS + ' --input "$F/ballPNG" --out "$C/p" --max-images 4', names=["light"], may_change=P, timeout=60,
     why="DiLiGenT ball's first 4 lights are nearly coplanar (light matrix condition ~3.6e4, all x ~ -0.06): least "
         "squares returns a map about 87 deg off (4 deg with all 96); refused (or at least warned) naming the "
         "lights / --max-images, like exactly coplanar lights, never a silent exit 0.")
case("o41-pred-dil-intensities-absent", "input",
     PRLS + ' --input "$C/dil/ballPNG" --out "$C/p" --max-images 12', expect="ok",
     setup='mkdir dil; cp -r "$F/ballPNG" dil/; rm dil/ballPNG/light_intensities.txt\n', may_change=P, timeout=60,
     why="DiLiGenT without light_intensities.txt reads intensities of one (documented): least squares runs, exit 0.")
case("o41-pred-dil-mask-absent", "input", PRLS + ' --input "$C/dil/ballPNG" --out "$C/p" --max-images 8',
     expect="either", setup='mkdir dil; cp -r "$F/ballPNG" dil/; rm dil/ballPNG/mask.png\n', may_change=P,
     timeout=60, why="A DiLiGenT folder without mask.png: refused naming mask.png, or the whole image used; no "
                     "traceback.")
case("o41-pred-ls-max-images-two", "input", PRLS + ' --input "$F/ballPNG" --out "$C/p" --max-images 2',
     names=["--max-images"], may_change=P, timeout=60,
     why="Least squares needs at least 3 lights; --max-images 2 leaves an underdetermined system: refused naming "
         "--max-images (not a map of garbage with exit 0).")
case("o41-pred-device-empty", "input", PRM + ' --input ' + OBJ + ' --out "$C/p" --device ""', names=["--device"],
     may_change=P, timeout=60, why="--device '' is no device: refused naming --device.")
case("o41-pred-res-huge", "input", PRM + ' --input ' + OBJ + ' --out "$C/p" --res 200000', names=["--res"],
     may_change=P, timeout=60,
     why="--res 200000 would need terabytes: refused naming --res up front, not an out-of-memory kill.")

# ============================================================================ unips.evaluate
case("o41-eval-pred-empty-folder", "input", EV + ' --pred "$C/p" --gt "$F/data"', names=["--pred"],
     setup='mkdir p\n', may_change=["$C/p/*"], timeout=60,
     why="--pred holds no prediction: refused naming --pred (even --allow-missing cannot score nothing).")
case("o41-eval-gt-mask-all-black", "input", EV + ' --pred "$C/p" --gt "$C/d/00000.data"', names=["mask.png"],
     setup=PREDCP + DS + py("""
        from PIL import Image
        im = Image.open('d/00000.data/mask.png'); Image.new(im.mode, im.size, 0).save('d/00000.data/mask.png')
        """), may_change=["$C/p/metrics.*", "$C/p/*/error_map*", "$C/p/*.lock"], timeout=60,
     why="A ground-truth mask without a pixel: the mean error of nothing is not a number; refused naming mask.png, "
         "not exit 0 with NaN metrics.")
case("o41-eval-gt-normal-nan", "input", EV + ' --pred "$C/p" --gt "$C/d/00000.data"', expect="either",
     setup=PREDCP + DS + py("""
        import tifffile, numpy as np
        from PIL import Image
        w, h = Image.open('d/00000.data/mask.png').size
        tifffile.imwrite('d/00000.data/normal.tif', np.full((h, w, 3), np.nan, np.float32))
        """), may_change=["$C/p/metrics.*", "$C/p/*/error_map*", "$C/p/*.lock"], timeout=60,
     why="Ground truth of NaN everywhere: refused naming normal.tif, or scored as 'no normal' with a note; never a "
         "metrics.json of NaN with exit 0.")
case("o41-eval-metrics-json-link-user-file-no-overwrite", "writer",
     EV + ' --pred "$C/p" --gt "$F/data"',
     expect="either", setup=PREDCP + 'echo "{}" > keep.json; ' + remember("keep.json")
     + 'ln -s "$C/keep.json" p/metrics.json\n', may_change=["$C/p/metrics.csv", "$C/p/*/error_map*", "$C/p/*.lock"],
     timeout=60,
     why="p/metrics.json is a link to a user file and no --overwrite: refused, never written through.")

# ============================================================================ orchestrate.ship (in a repo copy)
case("o41-ship-candidate-run-empty", "input", SHIP + ' --candidate "$C/cand" --val "$F/data"' + REPO_SAME,
     names=["final.safetensors"], setup=REPO_COPY + 'mkdir -p cand/run\n', may_change=REPO_CHANGE, timeout=60,
     why="A candidate whose run/ is empty: refused naming final.safetensors / last.pt, nothing shipped.")
case("o41-ship-candidate-last-pt-truncated", "weights",
     SHIP + ' --candidate "$C/cand" --val "$F/data"' + REPO_SAME, names=["last.pt"],
     setup=REPO_COPY + 'mkdir -p cand/run; head -c 100000 "$F/run/last.pt" > cand/run/last.pt\n',
     may_change=REPO_CHANGE, timeout=60,
     why="A session cut short brought back a truncated last.pt only: refused naming it, nothing shipped.")
case("o41-ship-registry-card-malformed", "input",
     SHIP + ' --candidate "$C/cand" --val "$F/data"', names=["model_card.json"],
     setup=REPO_COPY + CAND + 'printf "{\\"lineage\\": [" > repo/unips/weights/model_card.json\n',
     may_change=REPO_CHANGE, timeout=120,
     why="The registry's model_card.json is cut short: refused naming it before scoring; never replaced by a card "
         "that loses the lineage.")
case("o41-ship-registry-card-link-out", "writer",
     SHIP + ' --candidate "$C/cand" --val "$F/data"', expect="either",
     setup=REPO_COPY + CAND + 'mkdir keep; cp repo/unips/weights/model_card.json keep/card.json; '
     + 'rm repo/unips/weights/model_card.json; '
     'ln -s "$C/keep/card.json" repo/unips/weights/model_card.json\n', may_change=REPO_CHANGE, timeout=120,
     why="model_card.json in the registry is a link to a file elsewhere: ship refuses or replaces the link; it "
         "never writes the lineage through it.")
# ============================================================================ orchestrate.benchmark
case("o41-bench-counts-empty", "input", BMD.replace("--counts 1", "--counts ''") + ' --out "$C/b"',
     names=["--counts"], may_change=["$C/b", "$C/b/*"], timeout=60, why="--counts '': refused naming --counts.")
case("o41-bench-data-is-diligent-object", "input", BMD.replace('"$F/data"', '"$F/ballPNG"') + ' --out "$C/b"',
     expect="either", may_change=["$C/b", "$C/b/*"], timeout=60,
     why="--data is a DiLiGenT object, not a synthetic dataset (help: object folders with normal.tif): refused "
         "naming --data and pointing to --diligent, or scored as one object; no traceback.")
case("o41-bench-checkpoint-sidecar-missing", "weights",
     BMD + ' --checkpoint "$C/w/m.safetensors" --out "$C/b"', names=["m.json"], setup=SHIPPED + 'rm w/m.json\n',
     may_change=["$C/b", "$C/b/*"], timeout=60,
     why="Weights without their sidecar: refused naming m.json before any table is written.")

# ============================================================================ orchestrate.error_calibration
case("o41-ec-objects-zero", "input", EC.replace("--objects 1", "--objects 0") + ' --work "$C/wk"',
     names=["--objects"], may_change=["$C/wk", "$C/wk/*", "$C/wk/*/*"], timeout=60,
     why="--objects 0 fits nothing: refused naming --objects before rendering.")
case("o41-ec-objects-a-billion", "input", EC.replace("--objects 1", "--objects 1000000000") + ' --work "$C/wk"',
     names=["--objects"], may_change=["$C/wk", "$C/wk/*", "$C/wk/*/*", "$C/wk/*/*/*"], timeout=60,
     why="--objects 10^9 per row is ten billion renders: refused naming --objects (or its disk need) before "
         "rendering, not an endless run.")
case("o41-ec-pixels-zero", "input", EC.replace("--pixels 50", "--pixels 0") + ' --work "$C/wk"',
     names=["--pixels"], may_change=["$C/wk", "$C/wk/*", "$C/wk/*/*"], timeout=60,
     why="--pixels 0: no pixel to fit on; refused naming --pixels before rendering.")
case("o41-ec-out-is-a-folder", "input", EC.replace('"$C/ee.json"', '"$C/od"') + ' --work "$C/wk"', names=["--out"],
     setup='mkdir od\n', may_change=["$C/wk", "$C/wk/*", "$C/wk/*/*"], timeout=60,
     why="--out names an existing folder: refused naming --out before rendering (not after an hour of work).")
case("o41-ec-weights-sidecar-link-dev-zero", "weights", EC.replace(' --out "$C/ee.json"', '') + ' --work "$C/wk" --weights "$C/w/m.safetensors"',
     names=["m.json"], setup=SHIPPED + 'rm w/m.json; ln -s /dev/zero w/m.json\n',
     may_change=["$C/wk", "$C/wk/*", "$C/wk/*/*"], timeout=60,
     why="The weights' sidecar is a link to /dev/zero: refused naming it without an endless read, before rendering.")
