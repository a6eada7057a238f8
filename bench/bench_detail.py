"""Surface detail near the silhouette: how often Mitsuba's `normalmap` shades black or flips (docs/generator.md).

    python bench/bench_detail.py --objects 12 --res 64 --strengths 10,25,40

Renders the same objects (same seed: the detail is drawn from a stream of its own, so only the normal map
differs) without detail and with detail of each strength (`--detail 1 --detail-strength S-S`), and reports
over the mask pixels:
- `flipped`: the shading normal the camera sees (normal.tif) faces away from the camera (n_z < 0) while the
  geometry's (normal_base.tif) faces it;
- `black`: observations (pixel, image) that are black (below 1e-4 of the image's 99th percentile) with detail
  but lit without it (above 5 % of that percentile): shading killed by the normal map;
- the same two restricted to pixels near the silhouette (base normal within 30 deg of grazing), where the
  known issue lives;
- seconds per object with and without detail (the extra ground-truth pass of normal_base.tif included).
"""
from __future__ import annotations

import json
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import MIN_RES, check_given, claim_result, parse, run_main, write_result  # noqa: E402
from scenes.cli.options import CommaList, Command, arg, check_fields, comma_list, option  # noqa: E402
from wildgen.light_families import LIGHT_FAMILIES  # noqa: E402

RESULT_KEYS = ("strengths_deg", "rows")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def render(out: Path, args, extra: list[str]) -> float:
    from wildgen.make import main as make

    t0 = time.perf_counter()
    rc = make(
        [
            "--objects",
            str(args.objects),
            "--images",
            str(args.images),
            "--res",
            str(args.res),
            "--spp",
            str(args.spp),
            "--lights",
            ",".join(args.lights),
            "--seed",
            str(args.seed),
            "--quiet",
            "--out",
            str(out),
            *extra,
        ]
    )
    if rc != 0:
        raise SystemExit(f"wildgen.make failed ({rc})")
    return (time.perf_counter() - t0) / args.objects


@dataclass
class Options:
    """The command line of bench/bench_detail.py."""

    objects: int = option(12, minimum=1)
    """Objects rendered per strength (and without detail)."""
    images: int = option(6, minimum=1)
    """Images per object."""
    res: int = option(64, minimum=MIN_RES)
    """Image side in pixels."""
    spp: int = option(16, minimum=1)
    """Samples per pixel."""
    lights: Annotated[list[str], CommaList] = option(default_factory=lambda: ["directional", "point"],
                                                     choices=tuple(LIGHT_FAMILIES))
    """Light families for wildgen.make, comma-separated."""
    seed: int = 11
    """wildgen seed of the objects (the same for every strength)."""
    strengths: Annotated[list[float], comma_list(float, "DEG,DEG")] = option(
        default_factory=lambda: [10.0, 25.0, 40.0], minimum=0, maximum=60)
    """Detail strengths in degrees from 0 to 60 (--detail-strength S-S each), comma-separated."""
    out: Annotated[Path | None, arg(metavar="FILE")] = None
    """write the JSON rows here"""

    def validate(self) -> "Options":
        check_fields(self)
        check_given(self, "strengths")
        return self


COMMAND = Command(Options, prog="python bench/bench_detail.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    claim_result(args.out, RESULT_KEYS, COMMAND)
    from scenes.images import read_exr, read_mask, read_normals

    tmp = Path(tempfile.mkdtemp(prefix="bench_detail_"))
    rows = []
    try:
        base_s = render(tmp / "plain", args, [])
        print(
            f"{'strength':>8s} {'flipped':>8s} {'black':>8s} {'flipped@sil':>11s} {'black@sil':>9s} {'s/obj':>6s} "
            f"{'plain s/obj':>11s}"
        )
        for s in args.strengths:
            sec = render(tmp / f"d{s:g}", args, ["--detail", "1", "--detail-strength", f"{s:g}-{s:g}"])
            flip = black = sil = flip_sil = black_sil = obs = obs_sil = pix = 0
            for folder in sorted((tmp / f"d{s:g}").glob("*.data")):
                plain = tmp / "plain" / folder.name
                if not plain.is_dir():
                    continue
                m = read_mask(folder / "mask.png")
                n, b = read_normals(folder / "normal.tif")[m], read_normals(folder / "normal_base.tif")[m]
                near = b[:, 2] < np.sin(np.radians(30))
                f = (n[:, 2] < 0) & (b[:, 2] >= 0)
                flip += int(f.sum())
                flip_sil += int((f & near).sum())
                pix += int(m.sum())
                sil += int(near.sum())
                for r in sorted((folder / "aux").glob("radiance_*.exr")):
                    d = read_exr(r)[..., :3].mean(-1)[m]
                    q = read_exr(plain / "aux" / r.name)[..., :3].mean(-1)[m]
                    ref = max(float(np.percentile(q, 99)), 1e-12)
                    k = (d < 1e-4 * ref) & (q > 0.05 * ref)
                    black += int(k.sum())
                    black_sil += int((k & near).sum())
                    obs += len(q)
                    obs_sil += int(near.sum())
            row = {
                "strength_deg": s,
                "flipped": flip / max(pix, 1),
                "black": black / max(obs, 1),
                "flipped_near_silhouette": flip_sil / max(sil, 1),
                "black_near_silhouette": black_sil / max(obs_sil, 1),
                "s_per_object": sec,
                "plain_s_per_object": base_s,
            }
            rows.append(row)
            print(f"{s:8.0f} {row['flipped']:8.2%} {row['black']:8.2%} {row['flipped_near_silhouette']:11.2%} "
                  f"{row['black_near_silhouette']:9.2%} {sec:6.2f} {base_s:11.2f}", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(rows))
    if args.out:
        write_result(args.out, {"strengths_deg": args.strengths, "rows": rows}, indent=1)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
