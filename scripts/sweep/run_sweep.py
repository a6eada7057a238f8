"""Run a sweep of bad inputs and faults against the toolkit's CLIs, as a new user and as an attacker would.

    bash scripts/sweep/fixtures.sh /tmp/sweep/fx             # shared fixtures, ~3 min
    python scripts/sweep/run_sweep.py --cases scripts/sweep/cases37.py --root /tmp/sweep/run \\
        --fixtures /tmp/sweep/fx --results /tmp/sweep/r.json [--half 0|1] [--only ID ...]
    python scripts/sweep/show.py scripts/sweep/cases37.py /tmp/sweep/r.json [ID ...]

A cases file defines CASES, a list of dicts:
    id       unique name
    kind     the mechanism it probes (archive, writer, input, weights, engine, message, ...)
    setup    bash run with `set -e` in the case folder $C before the command (may be "")
    cmd      bash command line; env: C (case folder), F (fixtures), PY (python), REPO (code under test)
    expect   "refuse" (non-zero exit), "ok" (exit 0) or "either"
    names    strings the output must contain (the bad argument, the file); checked case-insensitively
    may_change  globs (with $C) of files the command may change; everything else that existed must stay the same
    timeout  seconds (default 120)
    why      what a right answer is

Each case runs in its own folder; the fixtures are copied nowhere (a case that writes into $F is a data-loss flag).
Flags: traceback, hang, exit0 (expected a refusal), failed (expected success), unclear (more than 3 lines of
stderr that are not progress, or a required name missing), data-loss (a file that existed before changed or
vanished outside may_change), data-loss-fixtures, security (a new file named pwn/evil/escape appeared outside the
case folder: under /tmp or the case root's parent), leftover (a process of the case still running).
"""
from __future__ import annotations

import argparse
import fnmatch
import hashlib
import json
import os
import re
import runpy
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

EVIL = ("pwn", "evil", "escape")
CASE_ID = re.compile(r"^[a-z]\d\d-")
"""The folder of a case (of this or another sweep run at the same time): its own files are not escapes."""
PROGRESS = ("wrote ", "writing", "rendering", "[", "%", "progress", "note:", "warning:", "reading", "loading",
            "done", "->", "saved", "predict", "render", "epoch", "step", "so far", "since the last line")


def _snapshot(root: Path, skip: tuple[Path, ...] = ()) -> dict[str, str]:
    out: dict[str, str] = {}
    if not root.exists():
        return out
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        d = Path(dirpath)
        dirnames[:] = [n for n in dirnames if not any((d / n) == s for s in skip)]
        for name in filenames:
            p = d / name
            try:
                st = p.lstat()
                if p.is_symlink():
                    out[str(p)] = "link:" + os.readlink(p)
                elif p.is_file():
                    if st.st_size < 64 << 20:
                        out[str(p)] = hashlib.sha1(p.read_bytes()).hexdigest()
                    else:
                        out[str(p)] = f"size:{st.st_size}:{st.st_mtime_ns}"
                else:
                    out[str(p)] = "special"
            except OSError:
                out[str(p)] = "unreadable"
    return out


def _evil_outside(roots: list[Path], own: tuple[Path, ...], case_ids: set[str], since: float) -> list[str]:
    """New pwn/evil/escape names outside every case folder (of both halves) and the fixtures."""
    found = []
    for root in roots:
        for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
            d = Path(dirpath)
            dirnames[:] = [n for n in dirnames
                           if (d / n) not in own and n not in case_ids and not CASE_ID.match(n)
                           and not n.startswith((".", "pytest-of-"))
                           and not n.startswith("bash_jobs")]
            for name in dirnames + filenames:
                if any(e in name.lower() for e in EVIL):
                    p = d / name
                    try:
                        if p.lstat().st_mtime >= since:
                            found.append(str(p))
                    except OSError:
                        pass
    return found


def _unclear(stderr: str) -> bool:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    other = [ln for ln in lines if not any(k in ln.lower() for k in PROGRESS)]
    return len(other) > 3


def run_case(case: dict, root: Path, fixtures: Path, repo: Path, py: str, case_ids: set[str]) -> dict:
    c = root / case["id"]
    if c.exists():
        shutil.rmtree(c)
    c.mkdir(parents=True)
    env = dict(os.environ, C=str(c), F=str(fixtures), PY=py, REPO=str(repo), PYTHONPATH=str(repo),
               PYTHONDONTWRITEBYTECODE="1")
    res: dict = {"id": case["id"], "kind": case.get("kind", ""), "flags": []}
    if case.get("setup"):
        p = subprocess.run(["bash", "-c", "set -e\n" + case["setup"]], cwd=c, env=env, capture_output=True,
                           text=True, timeout=600)
        if p.returncode != 0:
            res["flags"].append("setup-failed")
            res["setup_err"] = p.stderr[-2000:]
            return res
    before = _snapshot(c)
    fx_before = _snapshot(fixtures)
    t0 = time.time()
    timeout = case.get("timeout", 120)
    proc = subprocess.Popen(["bash", "-c", case["cmd"]], cwd=c, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        rc = None
        res["flags"].append("hang")
    res.update(rc=rc, seconds=round(time.time() - t0, 1), stdout=out[-3000:], stderr=err[-4000:])
    text = out + err
    if "Traceback (most recent call last)" in text:
        res["flags"].append("traceback")
    expect = case.get("expect", "refuse")
    if rc is not None:
        if expect == "refuse" and rc == 0:
            res["flags"].append("exit0")
        if expect == "ok" and rc != 0:
            res["flags"].append("failed")
    if rc not in (0, None) and _unclear(err):
        res["flags"].append("unclear")
    missing = [n for n in case.get("names", []) if n.replace("$C", str(c)).replace("$F", str(fixtures)).lower()
               not in text.lower()]
    if missing and rc != 0:
        res["missing_names"] = missing
        if "unclear" not in res["flags"]:
            res["flags"].append("unclear")
    may = [g.replace("$C", str(c)).replace("$F", str(fixtures)) for g in case.get("may_change", [])]
    after = _snapshot(c)
    lost = [k for k, v in before.items() if after.get(k) != v and not any(fnmatch.fnmatch(k, g) for g in may)]
    if lost:
        res["flags"].append("data-loss")
        res["lost"] = lost[:10]
    fx_after = _snapshot(fixtures)
    fx_lost = [k for k, v in fx_before.items() if fx_after.get(k) != v]
    if fx_lost:
        res["flags"].append("data-loss-fixtures")
        res["fixtures_lost"] = fx_lost[:10]
    evil = _evil_outside([Path("/tmp"), root.parent], (fixtures,), case_ids, t0 - 1)
    if evil:
        res["flags"].append("security")
        res["evil"] = evil[:10]
    ps = subprocess.run(["pgrep", "-f", str(c)], capture_output=True, text=True).stdout.split()
    ps = [p for p in ps if int(p) != os.getpid()]
    if ps:
        res["flags"].append("leftover")
        for p in ps:
            try:
                os.kill(int(p), signal.SIGKILL)
            except OSError:
                pass
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=Path, required=True, nargs="+")
    ap.add_argument("--root", type=Path, required=True, help="folder for the case folders")
    ap.add_argument("--fixtures", type=Path, required=True)
    ap.add_argument("--results", type=Path, required=True)
    ap.add_argument("--repo", type=Path, default=Path(__file__).resolve().parents[2], help="code under test")
    ap.add_argument("--python", default=sys.executable)
    ap.add_argument("--half", type=int, choices=(0, 1), default=None, help="run every other case")
    ap.add_argument("--only", nargs="*", default=None)
    a = ap.parse_args()
    cases = []
    for f in a.cases:
        cases += runpy.run_path(str(f))["CASES"]
    ids = [c["id"] for c in cases]
    case_ids = set(ids)
    dup = {i for i in ids if ids.count(i) > 1}
    if dup:
        sys.exit(f"duplicate case ids: {sorted(dup)}")
    if a.only:
        cases = [c for c in cases if c["id"] in a.only]
    if a.half is not None:
        cases = cases[a.half::2]
    root = a.root.resolve()
    root.mkdir(parents=True, exist_ok=True)
    results = []
    for i, case in enumerate(cases):
        r = run_case(case, root, a.fixtures.resolve(), a.repo.resolve(), a.python, case_ids)
        results.append(r)
        print(f"[{i + 1}/{len(cases)}] {case['id']}: rc={r.get('rc')} {r.get('seconds', '')}s "
              f"{' '.join(r['flags']) or 'clean'}", flush=True)
        a.results.write_text(json.dumps(results, indent=1))
    flagged = [r for r in results if r["flags"]]
    print(f"{len(results)} cases, {len(flagged)} flagged -> {a.results}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
