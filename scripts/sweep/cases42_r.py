"""Sweep 42, part r: the MODEL side (unips.train, unips.predict, unips.evaluate, orchestrate.benchmark,
orchestrate.error_calibration, orchestrate.train_recipe, published-weight loading, official / DiLiGenT folders),
with angles the earlier sweeps used little:
- the process environment: HOME unset or a file, TMPDIR missing or a file, OMP_NUM_THREADS garbage,
  CUDA_VISIBLE_DEVICES odd values, MASTER_PORT garbage under torchrun variables, TORCH_HOME / MPLCONFIGDIR a file,
  PYTHONIOENCODING=ascii with non-ASCII paths in a refusal;
- standard streams closed, on /dev/full, or piped into `head -1` (SIGPIPE);
- `ulimit -f` (file size) and `ulimit -n` (open files) small;
- names longer than 255 bytes, NFC / NFD twins, mtimes in the future, sparse files of tens of GiB;
- safetensors headers that lie (overlapping offsets, unknown dtype, huge header length, non-string metadata,
  duplicate tensor names, shape / offsets disagreeing, BOM, padding);
- shard members that are devices / FIFOs / sparse, a gzip named .tar, a shard linked to /dev/zero;
- JSON with BOM / duplicate keys / NaN / deep nesting (sidecars, predict.json, log.jsonl);
- a second run after the first was killed with SIGKILL at various points, two runs at once into one --out;
- outputs overlapping inputs through `..` and trailing slashes.
Commands that add their own check print a `FAULT:` line and exit 0 so that the harness flags it.
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
EC = '$PY -m orchestrate.error_calibration --assets none --objects 1 --threads 1 --pixels 50'
RCW = '$PY -m orchestrate.train_recipe --work "$C/w" --assets none --train-objects 1 --steps 1 --threads 1'
DS = 'cp -r "$F/data" d\n'
PREDCP = 'cp -r "$F/pred" p\n'
W = '"$REPO/unips/weights/glc-tiny.safetensors"'
WJ = '"$REPO/unips/weights/glc-tiny.json"'
SHIPPED = f"mkdir -p w; cp {W} w/m.safetensors; cp {WJ} w/m.json\n"
"""Setup: w/m.safetensors + w/m.json, a copy of the shipped weights."""
PRM_W = PRM + ' --checkpoint "$C/w/m.safetensors" --input ' + OBJ + ' --out "$C/p"'
P = ["$C/p", "$C/p/*", "$C/p/*/*"]
BO = ["$C/bo", "$C/bo/*", "$C/bo/*/*"]
REPO_COPY = r"""mkdir repo
(cd "$REPO" && git ls-files -z --cached --others --exclude-standard | tar --null -T - --ignore-failed-read -cf - 2>/dev/null) | tar -xf - -C repo
"""
INREPO = 'cd "$C/repo" && PYTHONPATH="$C/repo" '
LONG = "o" * 300
"""A path component of 300 bytes (the limit is 255)."""
NAME250 = "a" * 250
"""An object name of 250 bytes: its folder NAME250.data is 255 bytes, the longest a name may be."""
SPARSE = "20G"
OK_P0 = ('; r=$?; if [ $r = 0 ] && [ ! -s "$C/p/00000/normal.png" ]; then echo "FAULT: exit 0 without '
         'p/00000/normal.png"; fi; exit $r')
"""Command tail: exit 0 must leave the prediction of object 00000."""


def st_edit(code: str, path: str = "w/m.safetensors") -> str:
    """Setup: edit the safetensors header of PATH: `h` (dict; or set `raw` to header bytes), `body`, `n`."""
    return py(textwrap.dedent(f"""
        import json, struct
        p = {path!r}
        b = open(p, 'rb').read()
        n = struct.unpack('<Q', b[:8])[0]
        h = json.loads(b[8:8 + n]); body = b[8 + n:]
        raw = None
        keys = [k for k in h if k != '__metadata__']
        """) + textwrap.dedent(code).strip() + textwrap.dedent("""
        hb = raw if raw is not None else json.dumps(h).encode()
        open(p, 'wb').write(struct.pack('<Q', len(hb)) + hb + body)
        """))


def st_len(value: str, path: str = "w/m.safetensors") -> str:
    """Setup: the 8-byte header length of PATH replaced by `value` (a python expression; the rest kept)."""
    return py(f"""
        import struct
        p = {path!r}
        b = open(p, 'rb').read()
        open(p, 'wb').write(struct.pack('<Q', {value}) + b[8:])
        """)


def sidecar(code: str, path: str = "w/m.json") -> str:
    """Setup: edit the JSON sidecar PATH by hand (`s` is the loaded dict); `text` may replace the written text."""
    return py(f"import json\np = {path!r}\ns = json.load(open(p))\ntext = None\n" + textwrap.dedent(code).strip()
              + "\nopen(p, 'w').write(text if text is not None else json.dumps(s, indent=1))\n")


def kill9(cmd: str, cond: str, after: str, tries: int = 900) -> str:
    """Start `cmd` in its own process group, SIGKILL the whole group when `cond` holds (polled every 0.1 s), then run
    `after`; the first command's output is kept in $C/first.txt."""
    return (f'setsid {cmd} > "$C/first.txt" 2>&1 & pid=$!; for i in $(seq {tries}); do {cond} && break; '
            f'kill -0 $pid 2>/dev/null || break; sleep 0.1; done; kill -9 -- -$pid 2>/dev/null; '
            f'wait $pid 2>/dev/null; sleep 0.5; ' + after)


def both(cmd1: str, cmd2: str) -> str:
    """Run two commands at once; exit 0 only when both did; print both outputs."""
    return (f'( {cmd1} ) > "$C/o1.txt" 2>&1 & a=$!; ( {cmd2} ) > "$C/o2.txt" 2>&1 & b=$!; wait $a; ra=$?; wait $b; '
            'rb=$?; cat "$C/o1.txt" "$C/o2.txt"; [ $ra = 0 ] && [ $rb = 0 ]')


SHARD_X = 'mkdir x; tar -xf "$F/shards/000000.tar" -C x; tar -tf "$F/shards/000000.tar" > order.txt; mkdir s\n'
"""Setup: x/, the members of the fixture shard; order.txt, their order; s/, an empty shard folder."""
SHARD_RETAR = 'tar --format=gnu -S -cf s/000000.tar -C x -T order.txt\n'
"""Setup: s/000000.tar rebuilt from x/ in the original member order (GNU format, sparse members kept sparse)."""
TRS = TR + ' --data "$C/s" --out "$C/run" --steps 1'
TAR_ADD = """
import tarfile, io, shutil
src = 'x'
names = open('order.txt').read().split()
with tarfile.open('s/000000.tar', 'w', format=tarfile.GNU_FORMAT) as t:
    for n in names:
        t.add(f'{src}/{n}', arcname=n)
        if n == AFTER:
            ti = tarfile.TarInfo(EXTRA); ti.type = KIND; ti.devmajor = 1; ti.devminor = 5; ti.mode = 0o644
            t.addfile(ti)
"""


REINDEX = py("""
    import json, hashlib, os
    i = json.load(open(os.environ['F'] + '/shards/index.json'))
    b = open('s/000000.tar', 'rb').read()
    i['shards'][0]['bytes'] = len(b) if len(b) < 2**31 else os.path.getsize('s/000000.tar')
    h = hashlib.sha256()
    with open('s/000000.tar', 'rb') as f:
        for chunk in iter(lambda: f.read(1 << 20), b''):
            h.update(chunk)
    i['shards'][0]['sha256'] = h.hexdigest()
    json.dump(i, open('s/index.json', 'w'), indent=1)
    """)
"""Setup: s/index.json, the fixture index rewritten to the planted shard's size and sha256 (as an attacker would)."""


def shard_with(extra: str, kind: str, after: str = "00000.L003.png") -> str:
    """Setup: s/000000.tar (+ index), the fixture shard with one more member EXTRA of tarfile type KIND after AFTER."""
    return SHARD_X + py(f"import tarfile\nAFTER = {after!r}; EXTRA = {extra!r}; KIND = {kind}\n" + TAR_ADD) + REINDEX


DIL = 'mkdir dl; cp -r "$F/ballPNG" dl/ballPNG\n'
PRLS_DIL = PRLS + ' --input "$C/dl/ballPNG" --out "$C/p" --max-images 8'
UNIPS_OBJ = ('mkdir -p u/obj.data; for i in 0 1 2 3; do cp "$F/data/00000.data/L00$i.png" "u/obj.data/L$i.png"; done; '
             'cp "$F/data/00000.data/mask.png" u/obj.data/mask.png\n')
"""Setup: u/obj.data, an official UniPS-layout folder (L0..L3.png + mask.png, no scene.json)."""

# ============================================================================ environment
case("r42-pred-home-unset", "env", "env -u HOME " + PRM_W + OK_P0, expect="ok", setup=SHIPPED, may_change=P,
     timeout=90, why="HOME is unset in cron jobs and containers: prediction needs no home folder and must succeed.")
case("r42-pred-tmpdir-missing", "env", 'TMPDIR="$C/no/such/tmp" ' + PRM_W + OK_P0, expect="ok", setup=SHIPPED,
     may_change=P, timeout=90,
     why="TMPDIR names a folder that does not exist: Python falls back to /tmp; prediction succeeds.")
case("r42-train-stream-tmpdir-missing", "env",
     'TMPDIR="$C/no/tmp" ' + TR + ' --data "$F/shards" --out "$C/run" --steps 1 --shuffle-buffer 2 '
     '--loader-workers 1', expect="ok", may_change=RUN, timeout=120,
     why="Streamed shards use loader worker processes (sockets / shared memory under TMPDIR): a missing TMPDIR "
         "must not break them; one step succeeds.")
case("r42-train-omp-threads-abc", "env", "OMP_NUM_THREADS=abc " + TR1, expect="ok", may_change=RUN, timeout=90,
     why="OMP_NUM_THREADS=abc is garbage that --threads 1 overrides: training succeeds (a warning at most).")
case("r42-bench-omp-threads-huge", "env", 'OMP_NUM_THREADS=100000 ' + BMD + ' --out "$C/bo"', expect="ok",
     may_change=BO, timeout=120,
     why="OMP_NUM_THREADS=100000 is overridden by --threads 1: the benchmark does not spawn 100000 threads; it "
         "finishes.")
case("r42-train-device-cuda-visible-empty", "env", 'CUDA_VISIBLE_DEVICES="" ' + TR1 + " --device cuda",
     names=["--device"], may_change=RUN, timeout=90,
     why="--device cuda with every GPU hidden (CUDA_VISIBLE_DEVICES empty): one line naming --device (and that "
         "no GPU is visible), before any run folder is written.")
case("r42-train-env-master-port-garbage", "env",
     "WORLD_SIZE=2 RANK=0 LOCAL_RANK=0 MASTER_ADDR=127.0.0.1 MASTER_PORT=abc UNIPS_JOIN_TIMEOUT_S=5 "
     + TR + ' --data "$F/data" --out "$C/run" --steps 1 --batch 2'.replace("--batch 1 ", ""),
     names=["MASTER_PORT"], may_change=RUN, timeout=60,
     why="Under torchrun variables, MASTER_PORT=abc is not a port: one line naming MASTER_PORT and its value, no "
         "traceback, no hang waiting for a peer.")
case("r42-train-env-master-port-above-65535", "env",
     "WORLD_SIZE=2 RANK=0 LOCAL_RANK=0 MASTER_ADDR=127.0.0.1 MASTER_PORT=70000 UNIPS_JOIN_TIMEOUT_S=5 "
     + TR + ' --data "$F/data" --out "$C/run" --steps 1 --batch 2'.replace("--batch 1 ", ""),
     names=["MASTER_PORT"], may_change=RUN, timeout=60,
     why="MASTER_PORT=70000 lies beyond 65535: refused naming MASTER_PORT (not an OverflowError traceback).")
case("r42-pred-torch-home-a-file", "env", 'TORCH_HOME="$F/afile" XDG_CACHE_HOME="$F/afile" ' + PRM_W + OK_P0,
     expect="ok", setup=SHIPPED, may_change=P, timeout=90,
     why="TORCH_HOME / XDG_CACHE_HOME pointing at a file: predicting from a local file downloads nothing; it "
         "succeeds.")
case("r42-pred-ioencoding-ascii-unicode-input", "message",
     'PYTHONIOENCODING=ascii ' + PRM_W.replace('--input "$F/data/00000.data"', '--input "$C/données/objé.data"'),
     names=["--input"], setup=SHIPPED, may_change=P, timeout=60,
     why="A missing non-ASCII --input with an ASCII-only stderr: the refusal is still one line naming --input "
         "(escaped), not a UnicodeEncodeError traceback while printing it.")
case("r42-train-ioencoding-ascii-unicode-data", "message",
     'PYTHONIOENCODING=ascii ' + TR + ' --data "$C/données" --out "$C/run" --steps 1', names=["--data"],
     may_change=RUN, timeout=60,
     why="A missing non-ASCII --data printed to an ASCII stderr: one line naming --data, no encoding traceback.")
case("r42-pred-lc-all-c-unicode-paths", "env",
     'LC_ALL=C LANG=C ' + PRM + ' --checkpoint "$C/w/m.safetensors" --input "$C/dé" --out "$C/pé"',
     expect="ok", setup=SHIPPED + 'mkdir "dé"; cp -r "$F/data/00000.data" "dé/objé.data"\n',
     may_change=["$C/pé", "$C/pé/*", "$C/pé/*/*"], timeout=90,
     why="LC_ALL=C (a minimal container) with non-ASCII folder names: the names are bytes to Linux; prediction "
         "succeeds and writes pé/objé/.")

# ============================================================================ standard streams
case("r42-pred-stdout-closed", "stdio", PRM_W + " >&-" + OK_P0, expect="ok", setup=SHIPPED, may_change=P,
     timeout=90, why="Run from a daemon with stdout closed: prediction writes its files and exits 0; no crash on "
                     "printing.")
case("r42-eval-stdout-closed", "stdio", PREDCP + EV + ' --pred "$C/p" --gt "$F/data" >&-; r=$?; '
     '[ -s "$C/p/metrics.json" ] || echo "FAULT: no metrics.json"; exit $r', expect="ok", may_change=P, timeout=60,
     why="stdout closed: the metrics table cannot be printed but metrics.json is written; exit 0 (or the "
         "table is simply skipped).")
case("r42-pred-stderr-closed", "stdio", PRM_W + " 2>&-" + OK_P0, expect="ok", setup=SHIPPED, may_change=P,
     timeout=90, why="stderr closed: progress and log lines cannot be shown; the prediction is still written.")
case("r42-train-stderr-closed-refusal", "stdio",
     TR + ' --data "$C/nothing" --out "$C/run" --steps 1 2>&-; r=$?; [ -e "$C/run/last.pt" ] && '
     'echo "FAULT: a refused run left last.pt"; exit $r', names=[], may_change=RUN, timeout=60,
     why="A refusal with stderr closed must still exit non-zero (not 0 because the message could not be "
         "printed, nor a different crash).")
case("r42-eval-stdout-dev-full", "stdio", PREDCP + EV + ' --pred "$C/p" --gt "$F/data" > /dev/full; r=$?; '
     'python3 -c "import json,sys; json.load(open(sys.argv[1]))" "$C/p/metrics.json" || '
     'echo "FAULT: metrics.json unreadable"; exit $r', expect="either", may_change=P, timeout=60,
     why="stdout on a full disk (/dev/full): either the failed table is reported in one line (non-zero) or "
         "ignored; metrics.json is complete either way and no traceback.")
case("r42-eval-piped-into-head", "stdio", PREDCP + 'set -o pipefail; ' + EV + ' --pred "$C/p" --gt "$F/data" 2>&1 '
     '| head -1; r=$?; if [ -e "$C/p/metrics.json" ]; then python3 -c "import json,sys; '
     'json.load(open(sys.argv[1]))" "$C/p/metrics.json" || echo "FAULT: metrics.json half written"; fi; exit $r',
     expect="either", may_change=P, timeout=60,
     why="Output piped into `head -1` (SIGPIPE after one line): the command may stop, but never leaves a "
         "half-written metrics.json.")
case("r42-pred-dataset-piped-into-head", "stdio", SHIPPED + PRM + ' --checkpoint "$C/w/m.safetensors" '
     '--input "$F/data" --out "$C/p" 2>&1 | head -1; for o in 00000 00001 00002; do '
     'if [ -e "$C/p/$o/normal.png" ] && [ ! -e "$C/p/$o/predict.json" ]; then '
     'echo "FAULT: $o has normal.png without predict.json after SIGPIPE"; fi; done; ' + PRM +
     ' --checkpoint "$C/w/m.safetensors" --input "$F/data" --out "$C/p" 2>&1 | tail -3; exit ${PIPESTATUS[0]}',
     expect="either", may_change=P, timeout=120,
     why="A prediction piped into head -1 (killed by SIGPIPE), then run again: no object is left half written, "
         "and the rerun either completes or names --overwrite in one line.")
# ============================================================================ resource limits
case("r42-pred-ulimit-f-small", "limits", SHIPPED + "ulimit -f 4; " + PRM_W + '; r=$?; if [ -e "$C/p/00000/predict.json" ] '
     '&& [ ! -e "$C/p/00000/normal.png" ]; then echo "FAULT: a failed object left predict.json (the mark of a finished '
     'prediction) without normal.png"; exit 0; fi; exit $r', names=["File too large"], may_change=P, timeout=90,
     why="`ulimit -f 4` (4 KiB files): writing normal.exr fails with EFBIG; one line naming the file and the "
         "error, non-zero; no traceback; the failed object is not left marked finished (predict.json without maps).")
case("r42-pred-ulimit-f-then-rerun", "limits", SHIPPED + "(ulimit -f 4; " + PRM_W + " >/dev/null 2>&1); " + PRM_W
     + '; r=$?; if [ $r = 0 ]; then $PY -c "import imageio.v3 as i,sys; a=i.imread(sys.argv[1]); '
     'assert a.shape[:2]==(32,32), a.shape" "$C/p/00000/normal.png" || echo "FAULT: normal.png left broken"; '
     'fi; exit $r', expect="either", may_change=P, timeout=120,
     why="After a run stopped by the file-size limit, the rerun either completes (its own partial folder "
         "replaced) or names --overwrite; exit 0 never leaves a truncated normal.png.")
case("r42-train-ulimit-f-last-pt-then-resume", "limits",
     '(ulimit -f 1000; ' + TR1.replace("--steps 1", "--steps 2 --ckpt-every 1") + ' >/dev/null 2>&1); '
     + TR.replace("--batch 1", "--batch 1") + ' --data "$F/data" --out "$C/run" --steps 2 --ckpt-every 1 --resume',
     expect="either", may_change=RUN, timeout=120,
     why="A run whose last.pt (2 MB) hit `ulimit -f 1000`: the resume either continues from an intact earlier "
         "state or refuses naming last.pt; never loads a truncated last.pt with a traceback.")
case("r42-eval-ulimit-f-tiny", "limits", PREDCP + "ulimit -f 1; " + EV + ' --pred "$C/p" --gt "$F/data"',
     names=["File too large"], may_change=P, timeout=60,
     why="`ulimit -f 1`: the error maps / metrics cannot be written; one line naming the file, non-zero.")
case("r42-train-stream-ulimit-n-small", "limits",
     "ulimit -n 48; " + TR + ' --data "$F/shards" --out "$C/run" --steps 1 --shuffle-buffer 2 --loader-workers 2',
     expect="either", may_change=RUN, timeout=120,
     why="Streaming loader workers under 48 open files: either it works or one line says EMFILE; no hang of a "
         "worker that died.")
# ============================================================================ long names, unicode twins, mtimes
case("r42-pred-eval-object-name-255-bytes", "names",
     setup=SHIPPED + f'mkdir d; cp -r "$F/data/00000.data" d/{NAME250}.data\n',
     cmd=PRM + ' --checkpoint "$C/w/m.safetensors" --input "$C/d" --out "$C/p" && ' + EV + ' --pred "$C/p" --gt "$C/d"',
     expect="ok", may_change=P, timeout=120,
     why="An object folder whose name is 255 bytes (the limit) is legal: predict and evaluate must not derive a "
         "longer name from it (error_map, temp files) and fail with ENAMETOOLONG.")
case("r42-train-object-name-255-bytes", "names", setup=f'mkdir d; cp -r "$F/data/00000.data" d/{NAME250}.data\n',
     cmd=TR + ' --data "$C/d" --out "$C/run" --steps 1', expect="ok", may_change=RUN, timeout=90,
     why="Training on an object whose folder name is 255 bytes: no derived cache name exceeds the limit.")
case("r42-pred-out-component-300-bytes", "names", PRM_W.replace('"$C/p"', f'"$C/{LONG}"'), names=["--out"],
     setup=SHIPPED, timeout=60,
     why="An --out whose last component is 300 bytes cannot exist: one line naming --out, no traceback.")
case("r42-train-out-component-300-bytes", "names", TR + f' --data "$F/data" --out "$C/{LONG}" --steps 1',
     names=["--out"], timeout=60, why="--out longer than NAME_MAX: refused naming --out before training.")
case("r42-ec-out-component-300-bytes", "names", EC + f' --work "$C/w" --out "$C/{LONG}.json"', names=["--out"],
     may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"], timeout=90,
     why="error_calibration's --out name is 300 bytes: refused naming --out before any rendering.")
case("r42-pred-eval-nfc-nfd-twins", "names",
     setup=SHIPPED + py("""
        import shutil, unicodedata, os
        os.mkdir('d')
        shutil.copytree(os.environ['F'] + '/data/00000.data', 'd/' + unicodedata.normalize('NFC', 'café') + '.data')
        shutil.copytree(os.environ['F'] + '/data/00001.data', 'd/' + unicodedata.normalize('NFD', 'café') + '.data')
        """),
     cmd=PRM + ' --checkpoint "$C/w/m.safetensors" --input "$C/d" --out "$C/p" && ' + EV + ' --pred "$C/p" --gt "$C/d"'
     '; r=$?; n=$(ls "$C/p" | grep -c caf); [ "$n" = 2 ] || echo "FAULT: $n prediction folders for 2 twins"; exit $r',
     expect="ok", may_change=P, timeout=120,
     why="Two objects whose names differ only in Unicode normalisation (NFC / NFD) are two folders on Linux: "
         "both are predicted into their own folders and evaluated, none overwrites the other.")
case("r42-train-resume-mtimes-in-future", "time", RESUME,
     setup=RUNCP + 'touch -d "2100-01-01" run/* \n', expect="ok", may_change=RUN, timeout=120,
     why="A run copied from a machine with a wrong clock (mtimes in 2100): resume goes by content, not dates.")
# ============================================================================ sparse huge files
case("r42-pred-checkpoint-sparse-tail", "sparse", PRM_W,
     setup=SHIPPED + f'truncate -s {SPARSE} w/m.safetensors\n', expect="either", may_change=P, timeout=60,
     why="A safetensors file followed by 20 GiB of (sparse) zeros: refused naming the file, or loaded from the "
         "header's offsets, within seconds; never read whole into memory.")
case("r42-train-init-from-sparse-zeros", "sparse",
     TR1 + ' --init-from "$C/big.pt"', setup=f'truncate -s {SPARSE} big.pt\n', names=["--init-from"],
     may_change=RUN, timeout=60,
     why="--init-from a 20 GiB file of zeros: refused in one line naming --init-from, quickly, not an OOM.")
case("r42-eval-pred-exr-sparse-huge", "sparse", EV + ' --pred "$C/p" --gt "$F/data"',
     setup=PREDCP + f'truncate -s {SPARSE} p/00000/normal.exr\n', expect="either", may_change=P, timeout=60,
     why="A prediction's normal.exr grown to 20 GiB of zeros past its data: refused naming it, or read from its "
         "header; never a 20 GiB read.")
case("r42-dil-light-directions-sparse-huge", "sparse", PRLS_DIL,
     setup=DIL + f'truncate -s {SPARSE} dl/ballPNG/light_directions.txt\n', names=["light_directions.txt"],
     may_change=P, timeout=60,
     why="light_directions.txt followed by 20 GiB of NUL bytes: refused naming the file, without reading it all.")

# ============================================================================ safetensors headers that lie
_same = """
sizes = {}
for k in keys:
    a, b = h[k]['data_offsets']; sizes.setdefault(b - a, []).append(k)
k1, k2 = next(v for v in sizes.values() if len(v) > 1)[:2]
"""
case("r42-st-offsets-overlap", "weights", PRM_W, names=["m.safetensors"],
     setup=SHIPPED + st_edit(_same + "h[k2]['data_offsets'] = list(h[k1]['data_offsets'])"), may_change=P,
     timeout=60, why="Two tensors claim the same bytes (one region read twice, another never): refused naming the "
                     "file, not loaded as a silently wrong network.")
case("r42-st-dtype-unknown", "weights", PRM_W, names=["m.safetensors"],
     setup=SHIPPED + st_edit("h[keys[0]]['dtype'] = 'F8_E9M9'"), may_change=P, timeout=60,
     why="A dtype string no reader knows: refused naming the file (and the dtype), no traceback.")
case("r42-st-header-length-huge", "weights", PRM_W, names=["m.safetensors"],
     setup=SHIPPED + st_len("2**62"), may_change=P, timeout=60,
     why="A header length of 2^62: refused naming the file at once, no MemoryError traceback, no allocation.")
case("r42-st-metadata-value-not-string", "weights", PRM_W, expect="either",
     setup=SHIPPED + st_edit("h['__metadata__'] = {'model_name': 'glc-tiny', 'step': 5, 'notes': None}"),
     may_change=P, timeout=60,
     why="__metadata__ values must be strings by the format: either refused naming the file or read with the "
         "stray values ignored; no traceback.")
case("r42-st-duplicate-tensor-name", "weights", PRM_W, names=["m.safetensors"],
     setup=SHIPPED + st_edit("""
        s = json.dumps(h)
        k = keys[0]
        dup = json.dumps({k: {'dtype': 'F32', 'shape': [0], 'data_offsets': [0, 0]}})[1:-1]
        raw = ('{' + dup + ', ' + s[1:]).encode()
        """), may_change=P, timeout=60,
     why="A header naming one tensor twice (the JSON reader keeps the last): ambiguous weights are refused naming "
         "the file, not silently read as one of the two.")
case("r42-st-shape-disagrees-offsets", "weights", PRM_W, names=["m.safetensors"],
     setup=SHIPPED + st_edit("k = next(k for k in keys if len(h[k]['shape']) == 1); h[k]['shape'] = [h[k]['shape'][0] + 1]"),
     may_change=P, timeout=60,
     why="A shape whose size disagrees with its byte range: refused naming the file.")
case("r42-st-header-padded-spaces", "weights", PRM_W + OK_P0, expect="ok",
     setup=SHIPPED + st_edit("raw = json.dumps(h).encode() + b' ' * 13"), may_change=P, timeout=60,
     why="Trailing spaces in the header are allowed by the format (alignment padding): the file loads.")
case("r42-st-shape-nan", "weights", PRM_W, names=["m.safetensors"],
     setup=SHIPPED + st_edit("raw = json.dumps(h).replace('\"shape\": [32]', '\"shape\": [NaN]', 1).encode()"),
     may_change=P, timeout=60, why="A shape holding NaN (invalid JSON for the format): refused naming the file.")
case("r42-st-extra-tensor-evil", "weights", PRM_W, expect="either",
     setup=SHIPPED + st_edit("""
        end = max(h[k]['data_offsets'][1] for k in keys)
        h['evil.extra'] = {'dtype': 'F32', 'shape': [1], 'data_offsets': [end, end + 4]}
        body = body + b'\\0\\0\\0\\0'
        """), may_change=P, timeout=60,
     why="An extra tensor the network has no parameter for: refused naming it, or ignored and said; never a "
         "traceback.")
case("r42-train-init-from-st-dtype-unknown", "weights",
     TR + ' --data "$F/data" --out "$C/run" --steps 1 --model glc-tiny --init-from "$C/w/m.safetensors"',
     names=["--init-from"], setup=SHIPPED + st_edit("h[keys[-1]]['dtype'] = 'Q4_K'"), may_change=RUN, timeout=60,
     why="--init-from weights with an unknown dtype: refused naming --init-from before a run folder is written.")
case("r42-bench-checkpoint-st-offsets-overlap", "weights",
     BMD + ' --checkpoint "$C/w/m.safetensors" --out "$C/bo"', names=["--checkpoint"],
     setup=SHIPPED + st_edit(_same + "h[k2]['data_offsets'] = list(h[k1]['data_offsets'])"), may_change=BO,
     timeout=90, why="Benchmark of weights whose tensors overlap: refused naming --checkpoint, no tables written.")
case("r42-ec-weights-st-header-huge", "weights", EC + ' --work "$C/w2" --weights "$C/w/m.safetensors" --out "$C/ee.json"',
     names=["--weights"], setup=SHIPPED + st_len("2**62"), may_change=["$C/w2", "$C/w2/*", "$C/w2/*/*"], timeout=90,
     why="error_calibration --weights with a lying header length: refused naming --weights before any rendering.")
case("r42-recipe-init-from-st-header-huge", "weights", RCW + ' --init-from "$C/w/m.safetensors"',
     names=["--init-from"], setup=SHIPPED + st_len("2**62"), may_change=["$C/w", "$C/w/*", "$C/w/*/*", "$C/w/*/*/*"],
     timeout=90, why="The recipe checks every step's arguments first: --init-from with a lying header is refused "
                     "naming --init-from before any rendering.")
# ============================================================================ JSON sidecars, predict.json, log.jsonl
case("r42-side-deep-nesting", "json", PRM_W, names=["m.json"],
     setup=SHIPPED + sidecar("text = json.dumps(s)[:-1] + ', \"notes\": ' + '[' * 200000 + ']' * 200000 + '}'"),
     may_change=P, timeout=60,
     why="A sidecar nested 200000 deep (planted): one line naming m.json, not a RecursionError traceback.")
case("r42-side-config-value-nan", "json", PRM_W, names=["m.json"],
     setup=SHIPPED + sidecar("s['config']['context_dim'] = float('nan')"), may_change=P, timeout=60,
     why="A sidecar whose config holds NaN for a layer width: refused naming m.json (or the key).")
case("r42-side-config-duplicate-key-other-value", "json", PRM_W, names=["m.json"],
     setup=SHIPPED + sidecar("text = json.dumps(s).replace('\"context_dim\": 32', '\"context_dim\": 32, "
                             "\"context_dim\": 64', 1)"), may_change=P, timeout=60,
     why="config naming context_dim twice with two values: ambiguous; refused naming m.json rather than "
         "silently taking the last one (the weights would not fit anyway).")
case("r42-eval-predict-json-deep-nesting", "json", EV + ' --pred "$C/p" --gt "$F/data"', expect="either",
     setup=PREDCP + py("""
        p = 'p/00001/predict.json'
        t = open(p).read().rstrip()
        open(p, 'w').write(t[:-1] + ', "evil": ' + '[' * 200000 + ']' * 200000 + '}')
        """), may_change=P, timeout=60,
     why="A predict.json nested 200000 deep: the object is refused naming it, or the file is not needed; never "
         "a RecursionError traceback.")
case("r42-train-resume-log-duplicate-step-key", "json", RESUME, expect="either", may_change=RUN,
     setup=RUNCP + py("""
        p = 'run/log.jsonl'
        lines = open(p).read().splitlines()
        lines[-1] = lines[-1][:-1] + ', "step": 99}'
        open(p, 'w').write('\\n'.join(lines) + '\\n')
        """), timeout=120,
     why="A log record with `step` twice (2 and 99): resume must not believe step 99 over last.pt; it refuses "
         "naming log.jsonl or trusts last.pt.")

# ============================================================================ shards: odd members
case("r42-train-shard-member-chardev", "archive", TRS, names=["000000.tar"],
     setup=shard_with("00000.evil.png", "tarfile.CHRTYPE"), may_change=RUN, timeout=90,
     why="A shard member that is a character device (planted): refused naming the shard / member; no device "
         "created, no read from a device.")
case("r42-train-shard-member-sparse-huge", "archive", TRS, names=["000000.tar"],
     setup=SHARD_X + 'truncate -s 10G x/00001.L002.png\n' + SHARD_RETAR + REINDEX, may_change=RUN, timeout=90,
     why="A GNU sparse member of 10 GiB in a small shard (a decompression bomb): refused naming the shard, "
         "within seconds, not 10 GiB in memory.")
# ============================================================================ official UniPS / DiLiGenT folders
case("r42-pred-unips-image-link-dev-zero", "input", PRLS + ' --input "$C/u/obj.data" --out "$C/p"',
     names=["L4.png"], setup=UNIPS_OBJ + 'ln -s /dev/zero u/obj.data/L4.png\n', may_change=P, timeout=60,
     why="An official folder whose L4.png links to /dev/zero: refused naming L4.png, no endless read.")
case("r42-pred-dil-filenames-entry-dotdot", "input", PRLS_DIL, names=["filenames.txt"],
     setup=DIL + 'cp "$F/ballPNG/001.png" dl/evil.png; sed -i "1s|.*|../evil.png|" dl/ballPNG/filenames.txt\n',
     may_change=P, timeout=60,
     why="filenames.txt naming ../evil.png (outside the object folder): refused naming filenames.txt.")
case("r42-pred-dil-filenames-duplicate-entry", "input", PRLS_DIL, names=["filenames.txt"],
     setup=DIL + 'sed -i "2s|.*|001.png|" dl/ballPNG/filenames.txt\n', may_change=P, timeout=60,
     why="filenames.txt listing 001.png twice (002.png never): the same image under two lights is a silent "
         "error; refused naming filenames.txt.")
# ============================================================================ kill -9, then run again
case("r42-train-kill9-at-start-then-rerun", "signal",
     kill9(TR1, '[ -e "$C/run" ]', TR1 + '; r=$?; ls "$C/run"; exit $r'), expect="either", may_change=RUN,
     timeout=120,
     why="A run killed as soon as its folder appeared, then started again (no flags): it starts afresh, or "
         "names --resume / --overwrite in one line; never a traceback on the leftovers.")
case("r42-train-kill9-after-last-pt-then-resume", "signal",
     kill9(TR.replace("--max-images 4", "--max-images 4") + ' --data "$F/data" --out "$C/run" --steps 40 '
           '--ckpt-every 1', '[ -s "$C/run/last.pt" ]',
           TR + ' --data "$F/data" --out "$C/run" --steps 3 --ckpt-every 1 --resume'),
     expect="ok", may_change=RUN, timeout=120,
     why="Killed right after its first last.pt, then resumed (with a lower --steps is refused elsewhere; here "
         "the same data): resume from the saved step succeeds.")
case("r42-train-kill9-parent-only-leaves-no-writer", "signal",
     TR + ' --data "$F/data" --out "$C/run" --steps 400 --ckpt-every 1 >/dev/null 2>&1 & pid=$!; '
     'for i in $(seq 600); do [ -s "$C/run/last.pt" ] && break; kill -0 $pid 2>/dev/null || break; sleep 0.1; done; '
     'kill -9 $pid; wait $pid 2>/dev/null; sleep 4; a=$(stat -c %Y.%s "$C/run/log.jsonl"); sleep 3; '
     'b=$(stat -c %Y.%s "$C/run/log.jsonl"); left=$(pgrep -f -- "--out $C/run" | tr "\\n" " "); '
     '[ -n "$left" ] && kill -9 $left; if [ "$a" != "$b" ] || [ -n "$left" ]; then '
     'echo "FAULT: the command was killed (-9) but a process of it ($left) kept writing $C/run"; fi; exit 0',
     expect="ok", may_change=RUN, timeout=120,
     why="SIGKILL of the command's own process (what `kill -9 PID` of the pid the shell printed does): no child "
         "of it may keep training and writing the run folder, unseen, racing the next command.")
case("r42-pred-kill9-mid-dataset-then-rerun", "signal",
     SHIPPED + kill9(PRM + ' --checkpoint "$C/w/m.safetensors" --input "$F/data" --out "$C/p"',
                     '[ -e "$C/p/00000/predict.json" ]',
                     PRM + ' --checkpoint "$C/w/m.safetensors" --input "$F/data" --out "$C/p"; r=$?; '
                     'if [ $r = 0 ]; then for o in 00000 00001 00002; do [ -s "$C/p/$o/predict.json" ] || '
                     'echo "FAULT: $o missing after a successful rerun"; done; fi; exit $r'),
     expect="either", may_change=P, timeout=120,
     why="A prediction killed after its first object, run again without --overwrite: it completes the rest (or "
         "names --overwrite); exit 0 means every object is there.")
case("r42-eval-kill9-then-rerun", "signal",
     PREDCP + kill9(EV + ' --pred "$C/p" --gt "$F/data"', '[ -e "$C/p/00000/error_map.png" ]',
                    EV + ' --pred "$C/p" --gt "$F/data"; r=$?; if [ $r = 0 ]; then python3 -c "import json,sys; '
                    'd=json.load(open(sys.argv[1])); assert len(d[\'objects\'])==3, d[\'objects\']" '
                    '"$C/p/metrics.json" || echo "FAULT: metrics.json incomplete after rerun"; fi; exit $r',
                    tries=300),
     expect="either", may_change=P, timeout=120,
     why="An evaluation killed mid-way, run again without --overwrite: completes (its own partial maps) or "
         "names --overwrite; exit 0 means a complete metrics.json.")
case("r42-bench-kill9-then-rerun", "signal",
     kill9(BMD + ' --out "$C/bo"', '[ -e "$C/bo" ]', BMD + ' --out "$C/bo"'), expect="either", may_change=BO,
     timeout=120,
     why="A benchmark killed after creating --out, run again: either it writes its tables (nothing of its own "
         "finished was there) or names --overwrite; no traceback.")

# ============================================================================ two writers, overlapping paths
case("r42-train-two-fresh-runs-at-once", "concurrency", both(TR1, TR1.replace("--seed", "--seed") + " --seed 1"),
     expect="refuse", names=["--out"], may_change=RUN, timeout=120,
     why="Two fresh runs into one --out at the same time: one holds the folder, the other is refused naming "
         "--out; never two runs interleaving log.jsonl and last.pt.")
case("r42-bench-two-at-once-one-out", "concurrency", both(BMD + ' --out "$C/bo"', BMD + ' --out "$C/bo"'),
     names=["--out"], may_change=BO, timeout=120,
     why="Two benchmarks into one --out at once: one refused naming --out (one writer per folder).")
case("r42-pred-out-equals-input-via-dotdot", "overlap",
     PRM + ' --checkpoint "$C/w/m.safetensors" --input "$C/d/00000.data" --out "$C/d/00000.data/../00000.data/"',
     names=["--out"], setup=SHIPPED + DS, may_change=["$C/d/00000.data/00000", "$C/d/00000.data/00000/*"], timeout=60,
     why="--out spelled through `..` and a trailing slash is the input object itself: refused naming --out.")
case("r42-pred-out-is-input-dataset-trailing-slash", "overlap",
     PRM + ' --checkpoint "$C/w/m.safetensors" --input "$C/d" --out "$C/d/./"', names=["--out"],
     setup=SHIPPED + DS, timeout=60,
     why="--out d/./ is the input dataset: predictions would be mixed into the dataset (00000/ beside "
         "00000.data/); refused naming --out.")
case("r42-eval-pred-gt-same-via-dotdot", "overlap", EV + ' --pred "$C/d/../d/" --gt "$C/d"', names=["--pred"],
     setup=DS, timeout=60,
     why="--pred and --gt the same folder spelled differently: refused naming --pred, no metrics written into "
         "the dataset.")
case("r42-train-out-equals-data-via-dotdot", "overlap",
     TR + ' --data "$C/d" --out "$C/d/00000.data/../" --steps 1', names=["--out"], setup=DS, timeout=60,
     why="--out d/00000.data/.. is the training dataset: refused naming --out before any file is written.")
case("r42-train-val-equals-out-via-slashes", "overlap",
     TR + ' --data "$F/data" --val "$C/run//" --out "$C/run" --steps 1', names=["--val"], setup="mkdir run\n",
     may_change=RUN, timeout=60,
     why="--val run// is --out: a validation set cannot be the run folder; refused naming --val.")
case("r42-ec-out-is-weights-via-dotdot", "overlap",
     EC + ' --work "$C/w2" --weights "$C/w/m.safetensors" --out "$C/w/../w/./m.safetensors"', names=["--out"],
     setup=SHIPPED, may_change=["$C/w2", "$C/w2/*", "$C/w2/*/*"], timeout=90,
     why="--out spelled w/../w/./m.safetensors is the weights file: refused naming --out before any rendering.")
case("r42-pred-checkpoint-inside-out-overwrite", "overlap",
     PRM + ' --checkpoint "$C/p/00000/m.safetensors" --input ' + OBJ + ' --out "$C/p" --overwrite; r=$?; '
     '[ -s "$C/p/00000/m.safetensors" ] || echo "FAULT: --overwrite deleted the checkpoint it was reading"; exit $r',
     expect="either", setup=PREDCP + f'cp {W} p/00000/m.safetensors; cp {WJ} p/00000/m.json\n',
     may_change=["$C/p/*/normal*", "$C/p/*/predict.json", "$C/p/*/expected_error*"], timeout=90,
     why="The checkpoint lies inside a prediction folder that --overwrite replaces: refused naming --checkpoint, "
         "or the weights and sidecar are kept; never deleted.")
case("r42-registry-weights-link-dev-zero", "weights",
     INREPO + PRM + ' --model glc-tiny --input ' + OBJ + ' --out "$C/p"', names=["glc-tiny"],
     setup=REPO_COPY + 'rm repo/unips/weights/glc-tiny.safetensors; ln -s /dev/zero repo/unips/weights/glc-tiny.safetensors\n',
     may_change=P, timeout=90,
     why="The registry's shipped weights replaced by a link to /dev/zero: refused naming the weights file, no "
         "endless read.")
case("r42-registry-card-deep-nesting", "weights",
     INREPO + PRM + ' --model glc-tiny --input ' + OBJ + ' --out "$C/p"', expect="either",
     setup=REPO_COPY + py("""
        p = 'repo/unips/weights/model_card.json'
        t = open(p).read().rstrip()
        open(p, 'w').write(t[:-1] + ', "evil": ' + '[' * 200000 + ']' * 200000 + '}')
        """), may_change=P, timeout=90,
     why="A model card nested 200000 deep: prediction does not need the card, or names it in one line; never a "
         "RecursionError traceback.")
