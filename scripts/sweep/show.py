"""Print a sweep's flagged cases (or the named ones) with their command, expectation and output.

    python scripts/sweep/show.py CASES.py[,MORE.py] R0.json[,R1.json] [ID ...]
"""
from __future__ import annotations

import json
import runpy
import sys
from collections import Counter


def main() -> int:
    cases = {c["id"]: c for f in sys.argv[1].split(",") for c in runpy.run_path(f)["CASES"]}
    results = []
    for f in sys.argv[2].split(","):
        results += json.load(open(f))
    ids = sys.argv[3:]
    flags = Counter(f for r in results for f in r["flags"])
    print(f"{len(results)} cases, {sum(1 for r in results if r['flags'])} flagged: {dict(flags)}")
    for r in results:
        if (ids and r["id"] not in ids) or (not ids and not r["flags"]):
            continue
        c = cases.get(r["id"], {})
        print("=" * 100)
        print(f"{r['id']} [{c.get('kind')}] flags={r['flags']} rc={r.get('rc')} expect={c.get('expect')}")
        print("why:", c.get("why"))
        print("cmd:", c.get("cmd"))
        for k in ("missing_names", "lost", "fixtures_lost", "evil", "setup_err"):
            if r.get(k):
                print(f"{k}:", r[k])
        print("stdout:", r.get("stdout", "")[-800:])
        print("stderr:", r.get("stderr", "")[-1500:])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
