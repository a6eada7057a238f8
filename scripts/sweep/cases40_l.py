"""Sweep 40, part l: the MODEL side (unips.train / predict / evaluate, orchestrate.ship / benchmark /
error_calibration), with cases that cases37_*.py .. cases39_*.py and tests/test_bad_inputs.py do not hold.

- torchrun variables given oddly (TORCHELASTIC_RUN_ID set by hand, two processes both rank 0, an unresolvable
  MASTER_ADDR, a MASTER_PORT where something else listens, stray variables around a single process);
- training runs interrupted (SIGKILL mid-run, then --resume), a log ending in NUL bytes (a crash on ext4), last.pt a
  FIFO or a link into another run, --resume with --overwrite or with another --model-option, shard patterns whose
  brace range is reversed or of another width, an empty shard;
- model files as a user or an attacker hands them over: a bare state_dict, a pickled nn.Module, a training .pt with
  one tensor of another shape (checksum rewritten), a .pt whose `extra` pickles a datetime, a legacy (non-zip) .pt, a
  safetensors header that is a JSON list, an unknown dtype, a negative dimension, invalid UTF-8, a header padded with
  spaces (valid), a sidecar naming `model_name` twice;
- predict / evaluate folders: a 16-bit mask, a dangling object link, outputs over the input dataset, an 8-bit-code
  normal map stored in a 16-bit PNG, a ground truth whose normal.tif is smaller than its mask, paths with spaces and
  non-ASCII letters;
- ship (in a copy of the tree: a wrong success would write the registry), benchmark and error_calibration
  arguments that must be refused before any work.

Cases whose command adds its own check print a line starting with `FAULT:`.
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
TR2 = TR1.replace("--batch 1", "--batch 2")
"""One step with a batch two processes can split."""
TRR = "$PY -m unips.train --model glc-test --no-progress --threads 1"
"""Training with the fixture run's own settings (for --resume of a copy of $F/run)."""
RUN = ["$C/run", "$C/run/*", "$C/run/*/*"]
PR = "$PY -m unips.predict"
PRM = PR + " --method model --tta 1 --no-expected-error"
PRLS = PR + " --method least-squares"
EV = "$PY -m unips.evaluate"
BM = "$PY -m orchestrate.benchmark --threads 1"
BMD = BM + " --rerender-objects 0 --counts 1 --images 4"
"""The benchmark of --data only, as small as it goes."""
EC = '$PY -m orchestrate.error_calibration --assets none --objects 1 --threads 1 --pixels 50'
RUNCP = 'cp -r "$F/run" run\n'
"""Setup: run/, a copy of the 2-step glc-test training run."""
DS = 'cp -r "$F/data" d\n'
"""Setup: d/, a copy of the 3-object 32-px dataset."""
PREDCP = 'cp -r "$F/pred" p\n'
W = '"$REPO/unips/weights/glc-tiny.safetensors"'
WJ = '"$REPO/unips/weights/glc-tiny.json"'
SHIPPED = f"mkdir -p w; cp {W} {WJ} w/\n"
"""Setup: w/glc-tiny.safetensors + .json, a copy of the shipped weights."""
FREEPORT = ('port=$($PY -c "import socket; s=socket.socket(); s.bind((\'127.0.0.1\', 0)); '
            'print(s.getsockname()[1])")')
REPO_COPY = r"""mkdir repo
(cd "$REPO" && git ls-files -z --cached --others --exclude-standard | tar --null -T - --ignore-failed-read -cf - 2>/dev/null) | tar -xf - -C repo
"""
"""Setup: repo/, a copy of the working tree (orchestrate.ship writes the registry of the tree it runs from)."""
SHIP = 'cd "$C/repo" && PYTHONPATH="$C/repo" $PY -m orchestrate.ship --threads 1'
CAND = 'mkdir -p cand/run; cp "$REPO/unips/weights/glc-tiny.safetensors" "$REPO/unips/weights/glc-tiny.json" cand/run/; ' \
       'mv cand/run/glc-tiny.safetensors cand/run/final.safetensors; mv cand/run/glc-tiny.json cand/run/final.json\n'
"""Setup: cand/run/final.safetensors (+ .json): a candidate of the shipped architecture (the shipped weights)."""
REPO_SAME = ('; r=$?; (cd "$C/repo" && git -C "$REPO" ls-files -z unips/weights | '
             'xargs -0 -I{} cmp -s "$REPO/{}" "$C/repo/{}") || { echo "FAULT: the registry copy changed"; exit 0; }; '
             'exit $r')
"""Command tail: a refusal that still changed the copy's registry (unips/weights) exits 0 with a FAULT line."""


def st_header(code: str) -> str:
    """Setup: w/m.safetensors + m.json: the shipped weights with their safetensors header edited by `code`
    (Python with `h`, the parsed header dict, and `raw` its bytes; `code` may set `out`, the new header bytes)."""
    return SHIPPED + py(textwrap.dedent("""
        import json, shutil
        src = 'w/glc-tiny.safetensors'
        data = open(src, 'rb').read()
        n = int.from_bytes(data[:8], 'little')
        raw = data[8:8 + n]
        h = json.loads(raw)
        out = None
        """) + textwrap.dedent(code).strip() + textwrap.dedent("""
        if out is None:
            out = json.dumps(h).encode()
        open('w/m.safetensors', 'wb').write(len(out).to_bytes(8, 'little') + out + data[8 + n:])
        shutil.copy('w/glc-tiny.json', 'w/m.json')
        """))


PRM_W = PRM + ' --checkpoint "$C/w/m.safetensors" --input "$F/data/00000.data" --out "$C/p"'
PRM_PT = PRM + ' --checkpoint "$C/m.pt" --input "$F/data/00000.data" --out "$C/p"'
P = ["$C/p", "$C/p/*", "$C/p/*/*"]


def ckpt_edit(code: str, dest: str = "m.pt") -> str:
    """Setup: DEST, the fixture run's last.pt loaded as `c` (weights_only), edited by `code`, its checksum
    rewritten to match (an attacker who edits a checkpoint and its checksum together), saved."""
    return py(textwrap.dedent("""
        import torch
        from unips.models.builder import CHECKSUM_KEY, content_digest
        import os
        c = torch.load(os.environ['F'] + '/run/last.pt', weights_only=True)
        """) + textwrap.dedent(code).strip() + textwrap.dedent(f"""
        c[CHECKSUM_KEY] = content_digest(c)
        torch.save(c, {dest!r})
        """))


# ============================================================================ unips.train: torchrun variables
case("l40-train-env-torchelastic-id-by-hand", "engine",
     FREEPORT + "; TORCHELASTIC_RUN_ID=sweep WORLD_SIZE=2 RANK=0 LOCAL_RANK=0 MASTER_ADDR=127.0.0.1 "
     "MASTER_PORT=$port UNIPS_JOIN_TIMEOUT_S=5 " + TR2, names=[], timeout=75, may_change=RUN,
     why="TORCHELASTIC_RUN_ID copied from a torchrun job into a lone process (world 2, no second rank): the run "
         "skips the supervisor and hands the join to torch's env:// rendezvous; it must be refused within a bounded "
         "wait, naming the variables, not wait torch's 30 minutes (or silently run alone).")
case("l40-train-env-two-processes-both-rank-0", "concurrency",
     FREEPORT + "; export WORLD_SIZE=2 LOCAL_RANK=0 RANK=0 MASTER_ADDR=127.0.0.1 MASTER_PORT=$port "
     "UNIPS_JOIN_TIMEOUT_S=6; "
     '( ' + TR.replace('--batch 1', '--batch 2') + ' --data "$F/data" --out "$C/a" --steps 1 ) > a.log 2>&1 & p1=$!; sleep 1; '
     '( ' + TR.replace('--batch 1', '--batch 2') + ' --data "$F/data" --out "$C/b" --steps 1 ) > b.log 2>&1 & p2=$!; '
     'wait $p1; r1=$?; wait $p2; r2=$?; cat a.log b.log >&2; echo "rc $r1 $r2"; '
     '[ $r1 != 0 ] && [ $r2 != 0 ] && exit 2; echo "FAULT: a run with two rank-0 processes succeeded"; exit 0',
     names=["WORLD_SIZE"], timeout=90, may_change=["$C/a", "$C/a/*", "$C/b", "$C/b/*", "$C/a.log", "$C/b.log"],
     why="Two processes both started as RANK=0 of a world of 2 (a copy-paste of the same line): neither is the "
         "other's partner, so both are refused (the second cannot take the port, the first meets nobody) within "
         "UNIPS_JOIN_TIMEOUT_S, naming the variables.")
case("l40-train-env-master-addr-unresolvable", "engine",
     "WORLD_SIZE=2 RANK=1 LOCAL_RANK=1 MASTER_ADDR=no-such-host.invalid MASTER_PORT=29517 "
     "UNIPS_JOIN_TIMEOUT_S=5 " + TR2, names=["MASTER_ADDR", "no-such-host.invalid"], timeout=75, may_change=RUN,
     why="A host name that does not resolve is named (MASTER_ADDR and its value) within the bounded wait, no "
         "C++ trace of torch's store, no hang.")
case("l40-train-env-master-port-is-not-a-store", "engine",
     FREEPORT + "; $PY -c \"import socket,time; s=socket.socket(); s.setsockopt(socket.SOL_SOCKET, "
     "socket.SO_REUSEADDR, 1); s.bind(('127.0.0.1', $port)); s.listen(8)\n"
     "while True:\n c,_=s.accept(); c.sendall(b'HTTP/1.0 200 OK\\\\r\\\\n\\\\r\\\\nhello'); time.sleep(0.1)\" & srv=$!; "
     "sleep 1; WORLD_SIZE=2 RANK=1 LOCAL_RANK=1 MASTER_ADDR=127.0.0.1 MASTER_PORT=$port UNIPS_JOIN_TIMEOUT_S=5 "
     + TR2 + "; r=$?; kill $srv; wait $srv 2>/dev/null; exit $r",
     names=["MASTER_PORT"], timeout=75, may_change=RUN,
     why="Something else (a web server) listens at MASTER_ADDR:MASTER_PORT: rank 1 is refused naming the address "
         "and port within the bounded wait, never a decoding traceback or a hang on the foreign reply.")
case("l40-train-env-stray-master-vars-single-process", "input", "WORLD_SIZE=1 RANK=0 LOCAL_RANK=0 MASTER_ADDR= "
     "MASTER_PORT=99999 " + TR1, expect="ok", may_change=RUN,
     why="A single process (WORLD_SIZE=1) with leftover MASTER_* variables needs no rendezvous: it trains.")
case("l40-train-env-local-rank-above-rank", "input",
     FREEPORT + "; WORLD_SIZE=2 RANK=0 LOCAL_RANK=1 MASTER_ADDR=127.0.0.1 MASTER_PORT=$port "
     "UNIPS_JOIN_TIMEOUT_S=4 " + TR2, names=["LOCAL_RANK"], timeout=60, may_change=RUN,
     why="LOCAL_RANK (1) above RANK (0) cannot happen (a node's local ranks are a part of the global ones): named "
         "at once, before the wait for a partner.")

# ============================================================================ unips.train: runs, resume, shards
case("l40-train-kill9-then-resume-log-steps-once", "signal",
     TR + ' --data "$F/data" --out "$C/run" --steps 8 --ckpt-every 2 --log-every 1 --warmup 1 > a.log 2>&1 & p=$!; '
     'for i in $(seq 1 900); do [ -e run/last.pt ] && [ "$(wc -l < run/log.jsonl 2>/dev/null || echo 0)" -ge 3 ] '
     '&& break; sleep 0.1; done; kill -9 $p; wait $p; sleep 2; '
     + TR + ' --data "$F/data" --out "$C/run" --steps 8 --ckpt-every 2 --log-every 1 --warmup 1 --resume || exit $?; '
     + py("""
        import json, sys
        steps = [json.loads(l)['step'] for l in open('run/log.jsonl') if l.strip() and '"loss"' in l]
        if steps != sorted(set(steps)) or steps[-1] != 8:
            print('FAULT: log.jsonl training steps after kill -9 and --resume:', steps)
            sys.exit(3)
        """),
     expect="ok", may_change=RUN + ["$C/a.log"], timeout=120,
     why="A run killed with SIGKILL between checkpoints is resumed from last.pt; the log keeps each step once (the "
         "lines written after the last checkpoint are dropped or replaced, not repeated) and ends at step 8.")
case("l40-train-resume-log-ends-in-nul-bytes", "input", TRR + ' --data "$F/data8" --out "$C/run" --steps 3 --resume',
     expect="either", setup=RUNCP + "head -c 4096 /dev/zero >> run/log.jsonl", may_change=RUN,
     why="After a power loss ext4 leaves a file's tail as NUL bytes: the resume either drops the zero tail (the "
         "last.pt step is intact) or refuses naming log.jsonl, never a JSON traceback.")
case("l40-train-resume-last-pt-a-fifo", "input", TRR + ' --data "$F/data8" --out "$C/run" --steps 3 --resume',
     names=["last.pt"], setup=RUNCP + "rm run/last.pt; mkfifo run/last.pt", timeout=40,
     why="last.pt replaced by a FIFO is named (not a checkpoint file), not opened and waited on forever.")
case("l40-train-resume-last-pt-link-into-another-run", "writer",
     TRR + ' --data "$F/data8" --out "$C/run" --steps 3 --resume', expect="either",
     setup=RUNCP + 'rm run/last.pt; ln -s "$F/run/last.pt" run/last.pt', may_change=RUN,
     why="last.pt a link to another run's checkpoint: refused naming the link, or resumed with the link replaced by "
         "a file of this run; the other run's last.pt (in the fixtures) is never written through the link.")
case("l40-train-resume-run-copied-with-hard-links", "writer",
     TRR + ' --data "$F/data8" --out "$C/run" --steps 4 --resume', expect="either",
     setup='cp -r "$F/run" run0; cp -al run0 run', may_change=RUN,
     why="A run branched with `cp -al` (hard links, a common way to fork an experiment): resuming the copy must "
         "not append to or rewrite the original's log.jsonl / last.pt through the shared inodes (refused naming "
         "the linked file, or written as new files); run0/ stays as it was.")
case("l40-train-resume-data-now-its-shards", "input",
     TRR + ' --data "$F/shards" --out "$C/run" --steps 3 --resume', expect="either", setup=RUNCP, may_change=RUN,
     why="The run was trained on data8; its WebDataset shards (the same objects) are the same data: resumed, or "
         "refused naming --data as other data; one line either way, no traceback.")
case("l40-train-shards-brace-reversed", "archive",
     TR + " --data \"$C/s/{000001..000000}.tar\" --out \"$C/run\" --steps 1", names=["--data", "000001"],
     setup='mkdir s; cp "$F/shards/000000.tar" "$F/shards/index.json" s/; cp s/000000.tar s/000001.tar',
     why="A brace range written backwards ({000001..000000}) is refused naming the pattern, not read as no shards, "
         "one shard, or the range reversed without a word.")
case("l40-train-shards-brace-other-width", "archive", TR + " --data \"$C/s/{0..0}.tar\" --out \"$C/run\" --steps 1",
     names=["--data"], setup='mkdir s; cp "$F/shards/000000.tar" "$F/shards/index.json" s/',
     why="{0..0}.tar names 0.tar, which does not exist (the shard is 000000.tar): refused naming the missing "
         "shard, not matched loosely.")
case("l40-train-shard-empty-tar", "archive", TR + " --data \"$C/s/{000000..000000}.tar\" --out \"$C/run\" --steps 1",
     names=["000000.tar"], setup='mkdir s; cp "$F/shards/index.json" s/; : > s/000000.tar',
     why="A zero-byte shard (a transfer cut short) beside its index is refused naming it, not trained on nothing.")
case("l40-train-data-is-predictions", "input", TR + ' --data "$F/pred" --out "$C/run" --steps 1', names=["--data"],
     why="The output of unips.predict (normal maps, no images, no masks) given as --data is refused naming the flag "
         "and what an object folder holds.")
case("l40-train-val-without-ground-truth", "input",
     TR1 + ' --val "$C/v" --val-every 1', names=["--val", "normal.tif"],
     setup='cp -r "$F/data" v; rm v/*.data/normal.tif', may_change=RUN,
     why="A validation set whose objects have no normal.tif cannot be scored: refused naming --val and the missing "
         "file, before training (not after the first steps, nor validated as zero error).")
case("l40-train-paths-with-spaces-and-accents", "input",
     TR + ' --data "$C/mes données" --out "$C/runs é/exp 1" --steps 1', expect="ok",
     setup='cp -r "$F/data" "mes données"', may_change=["$C/runs é", "$C/runs é/*", "$C/runs é/*/*"],
     why="Folders whose names hold spaces and non-ASCII letters are ordinary paths: the run trains and writes "
         "final.safetensors.")
# ============================================================================ unips.predict: model files
case("l40-pred-pt-bare-state-dict", "weights", PRM_PT, names=["m.pt"],
     setup=py("""
        import torch, os
        c = torch.load(os.environ['F'] + '/run/last.pt', weights_only=True)
        torch.save(c['model'], 'm.pt')
        """), may_change=P,
     why="torch.save(model.state_dict()) holds no model name or config: refused naming m.pt and what is missing, "
         "not guessed as the default network (whose shapes differ) nor a KeyError traceback.")
case("l40-pred-pt-pickled-module", "weights", PRM_PT, names=["m.pt"],
     setup=py("""
        import torch
        from unips.models import create_model
        torch.save(create_model('glc-test'), 'm.pt')
        """), may_change=P,
     why="torch.save(model) pickles the module's classes: a weights-only load refuses it; named in one line "
         "(save the state_dict / use unips.train's files), without running the pickle.")
case("l40-pred-pt-one-tensor-reshaped-checksummed", "weights", PRM_PT, names=["m.pt"],
     setup=ckpt_edit("""
        k = next(k for k, v in c['model'].items() if v.ndim == 2 and v.shape[0] != v.shape[1])
        c['model'][k] = c['model'][k].t().contiguous()
        """), may_change=P,
     why="A weight of the transposed shape (checksum rewritten to match) is refused naming the file and the "
         "tensor, not a size-mismatch traceback from load_state_dict.")
case("l40-pred-pt-extra-pickles-a-datetime", "weights", PRM_PT, names=["m.pt"],
     setup=py("""
        import torch, os, datetime
        c = torch.load(os.environ['F'] + '/run/last.pt', weights_only=True)
        c['extra']['saved_at'] = datetime.datetime(2026, 1, 1)
        torch.save(c, 'm.pt')
        """), may_change=P,
     why="A checkpoint whose `extra` holds a pickled datetime cannot be read weights-only: refused in one line "
         "naming m.pt (unsafe object), the pickle never run; no 'WeightsUnpickler error' page.")
case("l40-pred-pt-legacy-serialisation", "weights", PRM_PT, expect="ok",
     setup=py("""
        import torch, os
        c = torch.load(os.environ['F'] + '/run/last.pt', weights_only=True)
        torch.save(c, 'm.pt', _use_new_zipfile_serialization=False)
        """), may_change=P,
     why="The same training checkpoint in torch's legacy (pre-1.6, non-zip) format is still a valid file: it "
         "predicts as the zip one does.")
case("l40-pred-pt-weights-fp16-checksummed", "weights", PRM_PT, expect="either",
     setup=ckpt_edit("c['model'] = {k: (v.half() if v.is_floating_point() else v) for k, v in c['model'].items()}"),
     may_change=P,
     why="A checkpoint whose weights were halved to float16 (checksum rewritten): predicted with them cast back to "
         "float32, or refused naming the dtype; never a dtype-mismatch traceback.")
case("l40-pred-st-header-a-list", "weights", PRM_W, names=["m.safetensors"],
     setup=st_header("out = json.dumps([h]).encode()"), may_change=P,
     why="A safetensors header that is a JSON list, not an object: refused naming the file as not safetensors.")
case("l40-pred-st-unknown-dtype", "weights", PRM_W, names=["m.safetensors"],
     setup=st_header("""
        k = next(k for k in h if k != '__metadata__')
        h[k]['dtype'] = 'F128'
        """), may_change=P,
     why="A tensor of dtype F128 (no such safetensors dtype) is refused naming the file, not a Rust panic page.")
case("l40-pred-st-negative-dimension", "weights", PRM_W, names=["m.safetensors"],
     setup=st_header("""
        k = next(k for k in h if k != '__metadata__' and len(h[k]['shape']) == 2)
        a, b = h[k]['shape']
        h[k]['shape'] = [-a, -b]
        """), may_change=P,
     why="A shape of negative sizes (whose product equals the byte count) is refused naming the file.")
case("l40-pred-st-header-invalid-utf8", "weights", PRM_W, names=["m.safetensors"],
     setup=st_header("""
        out = raw.replace(b'"dtype"', b'"dt\\xffe"', 1)
        """), may_change=P,
     why="A header with a byte that is not UTF-8 is refused naming the file (not a UnicodeDecodeError traceback).")
case("l40-pred-st-header-padded-with-spaces", "weights", PRM_W, expect="ok",
     setup=st_header("out = raw + b' ' * 13"), may_change=P,
     why="The safetensors format allows a header padded with trailing spaces (to align the data): a valid file, it "
         "predicts.")
case("l40-pred-sidecar-model-name-twice", "weights", PRM_W, expect="either",
     setup=SHIPPED + "cp w/glc-tiny.safetensors w/m.safetensors; " + py("""
        import json
        s = json.load(open('w/glc-tiny.json'))
        body = json.dumps(s)[1:-1]
        open('w/m.json', 'w').write('{"model_name": "glc-test", ' + body + '}')
        """), may_change=P,
     why="A sidecar naming model_name twice (glc-test, then glc-tiny): refused naming m.json as ambiguous, or read "
         "with the weights' own shapes deciding; never the first name's network loaded with a traceback.")
case("l40-pred-checkpoint-path-with-spaces-and-accents", "weights",
     PRM + ' --checkpoint "$C/mes poids/réseau 1.safetensors" --input "$F/data/00000.data" --out "$C/p"',
     expect="ok", setup='mkdir "mes poids"; cp ' + W + ' "mes poids/réseau 1.safetensors"; cp ' + WJ
     + ' "mes poids/réseau 1.json"', may_change=P,
     why="Weights in a folder with spaces and accents (sidecar beside them by the same stem) are read as usual.")
case("l40-pred-checkpoint-a-training-run-folder", "weights",
     PRM + ' --checkpoint "$F/run" --input "$F/data/00000.data" --out "$C/p"', expect="either", may_change=P,
     why="--checkpoint naming a unips.train run folder: refused in one line naming what to give "
         "(RUN/final.safetensors), or its final.safetensors used; not read as the authors' published layout with "
         "a confusing message.")
case("l40-pred-device-cuda-7", "input", PRM + ' --input "$F/data/00000.data" --out "$C/p" --device cuda:7',
     names=["--device", "cuda:7"],
     why="A GPU that does not exist here (no CUDA on this machine, or no 8th GPU) is named with --device before "
         "anything is read.")
case("l40-pred-device-cuda-negative", "input", PRM + ' --input "$F/data/00000.data" --out "$C/p" --device cuda:-1',
     names=["--device"],
     why="cuda:-1 is no device: refused naming --device.")

# ============================================================================ unips.predict: input folders
case("l40-pred-mask-16-bit", "input", PRM + ' --input "$C/d/00000.data" --out "$C/p"', expect="ok",
     setup=DS + py("""
        import cv2, numpy as np
        m = cv2.imread('d/00000.data/mask.png', cv2.IMREAD_GRAYSCALE)
        cv2.imwrite('d/00000.data/mask.png', (m > 127).astype(np.uint16) * 65535)
        """) + "rm -f d/manifest.json", may_change=P,
     why="A binary mask saved as 16-bit (0 / 65535) is the same mask: the object is predicted.")
case("l40-pred-dataset-with-dangling-object-link", "input", PRLS + ' --input "$C/d" --out "$C/p"', expect="either",
     setup=DS + 'rm d/manifest.json; ln -s "$C/gone/00009.data" d/00009.data', may_change=P,
     why="A dataset folder (no manifest) holding a dangling link 00009.data: the three real objects are predicted "
         "and 00009 named as failed (exit 1), or the run refused naming the link; never a traceback.")
case("l40-pred-out-is-input-dataset-overwrite", "writer", PRLS + ' --input "$C/d" --out "$C/d" --overwrite',
     names=["--out"], setup=DS,
     why="--out equal to --input (a dataset) with --overwrite: outputs would be written among the object folders; "
         "refused naming --out, the dataset untouched.")
case("l40-pred-input-unips-layout-bmp-and-jpg-mixed", "input", PRLS + ' --input "$C/u.data" --out "$C/p"',
     expect="either",
     setup=py("""
        import cv2, os, shutil
        src = os.environ['F'] + '/data/00000.data'
        os.mkdir('u.data')
        for i, ext in enumerate(['bmp', 'jpg', 'bmp', 'jpg']):
            im = cv2.imread(f'{src}/L00{i}.png', cv2.IMREAD_UNCHANGED)
            im8 = (im / 257).astype('uint8') if im.dtype.name == 'uint16' else im
            cv2.imwrite(f'u.data/L ({i + 1}).{ext}', im8)
        shutil.copy(f'{src}/mask.png', 'u.data/mask.png')
        """), may_change=P,
     why="An official UniPS folder mixing 8-bit BMP and JPEG images (same scale) has no lights: least squares is "
         "refused naming the missing light directions, or it runs; one line, no traceback.")

# ============================================================================ unips.evaluate
case("l40-eval-pred-png16-holding-8bit-codes", "input", EV + ' --pred "$C/p" --gt "$F/data"', names=["normal.png"],
     setup=PREDCP + py("""
        import cv2, glob, os
        for d in glob.glob('p/*'):
            for f in ('normal.exr', 'normal.npy'):
                if os.path.exists(f'{d}/{f}'):
                    os.remove(f'{d}/{f}')
            im = cv2.imread(f'{d}/normal.png', cv2.IMREAD_UNCHANGED)
            cv2.imwrite(f'{d}/normal.png', (im // 257).astype('uint16'))
        """), may_change=["$C/p/*", "$C/p/*/*"],
     why="A 16-bit normal.png whose codes only reach 255 (8-bit codes stored in a 16-bit file by a converter) "
         "decodes to vectors near (-1,-1,-1): refused naming normal.png (not unit length / wrong range), not "
         "scored as a 125-degree error.")
case("l40-eval-gt-normal-smaller-than-mask", "input", EV + ' --pred "$C/p" --gt "$C/d"', names=["normal.tif"],
     setup=PREDCP + DS + py("""
        import cv2
        n = cv2.imread('d/00001.data/normal.tif', cv2.IMREAD_UNCHANGED)
        cv2.imwrite('d/00001.data/normal.tif', cv2.resize(n, (16, 16), interpolation=cv2.INTER_NEAREST))
        """), may_change=["$C/p/*", "$C/p/*/*"],
     why="A ground-truth normal.tif of 16 px beside a 32-px mask is named (its size against the mask's), not "
         "resized silently or a broadcasting traceback.")
case("l40-eval-pred-object-a-file", "input", EV + ' --pred "$C/p" --gt "$F/data"', names=["00001"],
     setup=PREDCP + 'rm -r p/00001; echo "not a prediction" > p/00001', may_change=["$C/p/*", "$C/p/*/*"],
     why="pred/00001 is a plain file, not a prediction folder: 00001 is named as missing or unreadable (exit "
         "non-zero without --allow-missing), never a NotADirectoryError traceback.")
case("l40-eval-paths-with-spaces-and-accents", "input", EV + ' --pred "$C/préd ictions" --gt "$C/vérité terrain"',
     expect="ok", setup='cp -r "$F/pred" "préd ictions"; cp -r "$F/data" "vérité terrain"',
     may_change=["$C/préd ictions/*", "$C/préd ictions/*/*"],
     why="Folders whose names hold spaces and accents evaluate as usual (metrics.json written).")
case("l40-eval-pred-exr-half-float", "input",
     EV + ' --pred "$C/p" --gt "$F/data"' + " && $PY -c \"import json,sys; m=json.load(open('p/metrics.json')); "
     "print(json.dumps(m)[:300])\"", expect="ok",
     setup=PREDCP + py("""
        import glob, os
        import numpy as np
        from scenes.exr import read_exr, write_exr
        for d in glob.glob('p/*'):
            n = read_exr(f'{d}/normal.exr') if os.path.exists(f'{d}/normal.exr') else None
            if n is not None:
                write_exr(f'{d}/normal.exr', np.asarray(n, np.float16))
        """), may_change=["$C/p/*", "$C/p/*/*"],
     why="A normal.exr in half floats (as many EXR tools write) is a valid map: scored as the float32 one.")
case("l40-eval-gt-dataset-manifest-lists-extra-object", "input", EV + ' --pred "$C/p" --gt "$C/d" --allow-missing',
     expect="either",
     setup=PREDCP + DS + 'cp -r "$F/data/00001.data" escape.data\n' + py("""
        import json
        m = json.load(open('d/manifest.json'))
        m['objects'] = m.get('objects', []) + [dict(m['objects'][0], name='escape', folder='../escape.data', index=3)]
        json.dump(m, open('d/manifest.json', 'w'))
        """), may_change=["$C/p/*", "$C/p/*/*"],
     why="A manifest entry whose folder is '../escape.data' is refused naming manifest.json, or ignored; nothing is read or "
         "written outside --gt / --pred.")

# ============================================================================ orchestrate.ship (in a repo copy)
case("l40-ship-val-empty-folder", "input", SHIP + ' --candidate "$C/cand" --val "$F/empty" --diligent none' + REPO_SAME,
     names=["--val", "empty"], setup=REPO_COPY + CAND, timeout=90,
     why="An empty --val has nothing to score: refused naming it before anything is scored or recorded in the "
         "model card.")
case("l40-ship-val-is-predictions", "input", SHIP + ' --candidate "$C/cand" --val "$F/pred" --diligent none' + REPO_SAME,
     names=["--val"], setup=REPO_COPY + CAND, timeout=90,
     why="--val naming a folder of predictions (no images, no ground truth) is refused naming --val.")
case("l40-ship-diligent-without-ball-or-cat", "input",
     SHIP + ' --candidate "$C/cand" --val "$F/data" --diligent "$F/empty"' + REPO_SAME,
     names=["--diligent"], setup=REPO_COPY + CAND, timeout=110,
     why="--diligent given explicitly but holding neither ball nor cat: refused naming it (say `none` to skip), "
         "not a shipping decision recorded as if DiLiGenT had been scored.")
case("l40-ship-candidate-last-pt-of-test-model", "weights",
     SHIP + ' --candidate "$C/cand" --val "$F/data" --diligent none' + REPO_SAME, names=["glc-test"],
     setup=REPO_COPY + 'mkdir -p cand/run; cp "$F/run/last.pt" cand/run/', timeout=90,
     why="A session cut short (only run/last.pt) of another architecture (glc-test) is refused naming it, as a "
         "final.safetensors of it is, before scoring.")
case("l40-ship-candidate-final-and-last-of-different-models", "weights",
     SHIP + ' --candidate "$C/cand" --val "$F/data" --diligent none', expect="either",
     setup=REPO_COPY + CAND + 'cp "$F/run/last.pt" cand/run/', timeout=110, may_change=["$C/repo/unips/weights/*"],
     why="final.safetensors (shipped architecture) beside a last.pt of glc-test: final is the candidate and is "
         "scored (its lineage recorded in the copy's model card), or the mismatch is refused naming both.")
case("l40-ship-candidate-run-a-link-to-the-registry", "writer",
     SHIP + ' --candidate "$C/cand" --val "$F/data" --diligent none' + REPO_SAME, names=["--candidate"],
     setup=REPO_COPY + 'mkdir cand; ln -s "$C/repo/unips/weights" cand/run; '
     'ln -s glc-tiny.safetensors repo/unips/weights/final.safetensors 2>/dev/null || true', timeout=90,
     why="A candidate whose run/ is a link into the registry itself (the shipped weights scored against "
         "themselves, then copied onto themselves) is refused naming --candidate.")

# ============================================================================ orchestrate.benchmark
case("l40-bench-data-is-predictions", "input", BMD + ' --data "$F/pred" --out "$C/b"', names=["--data"],
     why="A folder of predictions as --data (no images, no normal.tif) is refused naming --data before the model "
         "is loaded.")
case("l40-bench-diligent-images-zero", "input",
     BM + ' --diligent "$C/dil" --diligent-images 0 --diligent-subsets 0 --out "$C/b"',
     names=["--diligent-images"], setup='mkdir dil; ln -s "$F/ballPNG" dil/ballPNG',
     why="--diligent-images 0 leaves nothing to predict: refused naming the flag before any DiLiGenT object is read.")
case("l40-bench-diligent-images-negative", "input",
     BM + ' --diligent "$C/dil" --diligent-images -3 --diligent-subsets 0 --out "$C/b"',
     names=["--diligent-images"], setup='mkdir dil; ln -s "$F/ballPNG" dil/ballPNG',
     why="A negative image count is refused naming --diligent-images (not a slice [:-3] that drops the last three).")
case("l40-bench-diligent-without-ball-or-cat", "input", BM + ' --diligent "$F/empty" --out "$C/b"',
     names=["--diligent"],
     why="A DiLiGenT folder holding neither ballPNG/ nor catPNG/ is refused naming --diligent, not an empty "
         "table written with exit 0.")
case("l40-bench-seed-beyond-64-bit", "input", BMD + ' --data "$F/data" --out "$C/b" --seed 99999999999999999999999',
     names=["--seed"],
     why="A seed beyond 64 bits is refused naming --seed, not an OverflowError from numpy's generator.")
case("l40-bench-checkpoint-dev-null", "weights", BMD + ' --data "$F/data" --out "$C/b" --checkpoint /dev/null',
     names=["--checkpoint", "/dev/null"],
     why="/dev/null as the model file reads as empty: refused naming --checkpoint, nothing written to --out.")
case("l40-bench-out-is-the-checkpoint", "writer",
     BMD + ' --data "$F/data" --checkpoint "$C/w/glc-tiny.safetensors" --out "$C/w/glc-tiny.safetensors"',
     names=["--out"], setup=SHIPPED,
     why="--out naming the weights file itself is refused naming --out; the weights are untouched.")
case("l40-bench-out-is-weights-folder-with-tables-md", "writer",
     BMD + ' --data "$F/data" --checkpoint "$C/w/glc-tiny.safetensors" --out "$C/w"', names=["tables.md"],
     setup=SHIPPED + 'echo "# my notes" > w/tables.md', may_change=["$C/w/benchmark.json"],
     why="An --out holding a user's tables.md (not written by the benchmark) is refused without --overwrite; the "
         "file is kept.")

# ============================================================================ orchestrate.error_calibration (fast)
case("l40-ec-assets-missing", "input", EC.replace("--assets none", '--assets "$C/nowhere"')
     + ' --work "$C/w" --out "$C/ee.json"', names=["--assets", "nowhere"], timeout=60,
     why="An asset folder that does not exist is named before the split or any render.")
case("l40-ec-assets-a-file", "input", EC.replace("--assets none", '--assets "$F/afile"')
     + ' --work "$C/w" --out "$C/ee.json"', names=["--assets", "afile"], timeout=60,
     why="A plain file as --assets is named as not a folder, before any render.")
case("l40-ec-work-inside-assets", "writer",
     EC.replace("--assets none", '--assets "$C/a"') + ' --work "$C/a/work" --out "$C/ee.json"',
     names=["--work"], setup='mkdir -p a; cp -r "$F/assets/meshes" "$F/assets/hdri" a/', timeout=60,
     may_change=["$C/a/work", "$C/a/work/*", "$C/a/work/*/*"],
     why="--work inside --assets would put the split's links and the renders among the assets (the next split "
         "would read them as meshes): refused naming --work.")
case("l40-ec-work-link-to-a-dataset", "writer", EC + ' --work "$C/w" --out "$C/ee.json"', names=["--work"],
     setup='cp -r "$F/data" d; ln -s d w', timeout=60,
     why="--work a link to a wildgen.make dataset (not a calibration work folder): refused naming --work before "
         "the suite is rendered or 'resumed' into it.")
case("l40-ec-out-an-existing-folder", "input", EC + ' --work "$C/w" --out "$C/outdir"', names=["--out", "outdir"],
     setup="mkdir outdir; echo mine > outdir/notes.txt", timeout=60,
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"],
     why="--out naming an existing folder (the file path expected) is refused naming it, before rendering.")
case("l40-ec-weights-a-folder", "weights", EC + ' --work "$C/w" --weights "$F/empty" --out "$C/ee.json"',
     names=["--weights"], timeout=60, may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"],
     why="An empty folder as --weights is named (no model file) before the suite is rendered.")
case("l40-ec-weights-dev-zero", "weights", EC + ' --work "$C/w" --weights "$C/z.safetensors" --out "$C/ee.json"',
     names=["--weights", "z.safetensors"], setup="ln -s /dev/zero z.safetensors", timeout=60,
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"],
     why="Weights that are a link to /dev/zero (endless zeros) are refused naming them, not read forever.")
case("l40-ec-out-under-a-file", "input", EC + ' --work "$C/w" --out "$F/afile/ee.json"', names=["--out", "afile"],
     timeout=60, may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"],
     why="--out whose parent is a plain file can never be written: refused naming --out before the suite is "
         "rendered (not after an hour of renders).")
