"""Is the stated expected error right on captures it has never seen? (docs/model.md, "Expected error")

    python bench/bench_expected_error.py --work /tmp/errbench --out bench/results/expected_error.json

Renders the calibration suite (`orchestrate.error_calibration.SUITE`: the five PS-Wild light families, levels 1-5,
4 to 16 images, sensor and capture presets) with the HELD-OUT meshes and HDR maps (`orchestrate.asset_split`: never
used by the calibration, which renders the training half) and another seed, `--objects` per row; states the shipped
model's error on every object (`unips.expected_error`) and compares it with the true angular error:

- object level: the stated mean within max(2 deg, 25 %) of the true mean (`HIT_RULE`) and the 80 % interval holding
  the true mean, the share of objects of each (target: at least 80 % hits; 70-90 % coverage), overall and per family;
- pixel level, per family (pixels pooled over its objects) and per object: sparsification. Dropping the pixels of
  highest stated error first, the mean true error of what remains, against the oracle (dropping by true error) and a
  random order (a flat line); the area between ours and the oracle as a share of the area between random and the
  oracle (`ause_ratio`; target at most 0.4; 0 is the oracle, 1 no better than random);
- probes where the stated error must rise: the same objects with half their images (K/2, at least 2), with 3 images,
  with every second photo shifted by 3 px (a moved camera), and with the mask grown by 4 px into the background.

With --diligent (default ../shared/data/diligent when it exists), DiLiGenT ball and cat are turned into 8-bit JPEG
photos (sRGB, quality 95; read back linear as `orchestrate.capture` reads photos) and stated the same way, with their
own masks (their error is the model map's, the one the stated error describes).
"""
from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import (  # noqa: E402
    DILIGENT,
    check_diligent,
    check_work,
    claim_result,
    machine,
    need_path,
    parse,
    run_main,
    write_result,
)
from scenes.cli.options import Command, arg, option  # noqa: E402

HIT_FLOOR_DEG = 2.0
HIT_SHARE = 0.25
HIT_RULE = f"|stated - true| <= max({HIT_FLOOR_DEG:g} deg, {HIT_SHARE:.0%} of true)"
GROW_PX = 4


def hit(stated: float, true: float) -> bool:
    return abs(stated - true) <= max(HIT_FLOOR_DEG, HIT_SHARE * true)


def sparsification(stated: np.ndarray, true: np.ndarray, steps: int = 50) -> dict:
    """The mean true error left after dropping the highest `stated` (ours) or `true` (oracle) first, at `steps`
    fractions in [0, 0.98]; `ause_ratio`: area(ours - oracle) / area(random - oracle), random being the flat mean."""
    fr = np.linspace(0.0, 0.98, steps)
    n = len(true)

    def curve(order: np.ndarray) -> np.ndarray:
        kept = true[order]  # ascending by the score: keep the first (1 - f) n
        csum = np.cumsum(kept)
        k = np.maximum(np.round((1 - fr) * n).astype(int), 1)
        return csum[k - 1] / k

    ours, oracle = curve(np.argsort(stated, kind="stable")), curve(np.argsort(true, kind="stable"))
    rand = np.full_like(fr, true.mean())
    gap_ours, gap_rand = np.trapezoid(ours - oracle, fr), np.trapezoid(rand - oracle, fr)
    return {"ause_ratio": float(gap_ours / gap_rand) if gap_rand > 0 else None,
            "fractions": np.round(fr, 3).tolist(), "ours": np.round(ours, 3).tolist(),
            "oracle": np.round(oracle, 3).tolist(), "random": round(float(true.mean()), 3)}


def grown(obj, px: int = GROW_PX):
    from scipy import ndimage

    return dataclasses.replace(obj, mask=ndimage.binary_dilation(obj.mask, iterations=px))


def state(net, em, obj) -> tuple[float, np.ndarray, np.ndarray, object]:
    """(stated mean, per-pixel stated (P,), per-pixel true (P,) on the true mask, stated) of `obj`."""
    from scenes.metrics import angles_deg
    from unips.expected_error import gather

    normals, ev = gather(net, obj, tta=net.contract.views)
    st = em.state(ev)
    m = ev.mask & np.any(obj.normals != 0, axis=-1)
    return st.mean, st.per_pixel[m], angles_deg(normals[m], obj.normals[m]), st


def jpeg_object(obj, quality: int = 95):
    """`obj` as 8-bit sRGB JPEG photos read back linear, as `orchestrate.capture` reads 8-bit photos (the sRGB curve
    both ways, `scenes.colors`), all images scaled by one factor first (the brightest mask value to 1): one exposure
    for every photo, their relative brightness kept."""
    import cv2

    from scenes.colors import linear_to_srgb, srgb_to_linear

    out = []
    top = float(obj.images[:, obj.mask].max())
    for im in obj.images:
        codes = np.round(np.clip(linear_to_srgb(np.clip(im / max(top, 1e-12), 0, 1)), 0, 1) * 255).astype(np.uint8)
        ok, buf = cv2.imencode(".jpg", codes[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
        back = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1]
        out.append(srgb_to_linear(back / 255.0))
    return dataclasses.replace(obj, images=np.stack(out).astype(np.float32))


@dataclass
class BenchOptions:
    """The command line of bench_expected_error."""

    out: str = "bench/results/expected_error.json"
    """Where the results go."""
    work: Annotated[str | None, arg(help_behavior_hint="(default: a temporary folder)")] = None
    """Folder of the held-out asset split and the rendered suite (resumed when run again)."""
    assets: str = str(ROOT.parent / "shared" / "assets")
    """Asset folder; only its held-out half is rendered ('none': procedural shapes only)."""
    objects: int = option(5, minimum=1)
    """Objects per suite row."""
    seed: int = 9000
    """Seed of the first row (row i: seed + 100 i); the calibration uses 11000."""
    diligent: str = str(DILIGENT)
    """DiLiGenT folder (ballPNG, catPNG; refused when it lacks one); 'none' to skip."""
    threads: int = option(2, minimum=1)
    """Torch threads."""


COMMAND = Command(BenchOptions, prog="python bench/bench_expected_error.py", description=__doc__)
RESULT_KEYS = ("command", "error_model", "suite", "overall", "rows")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def before_work(opts: BenchOptions) -> None:
    """What the command line names on disk, checked before any work (each refusal one line)."""
    check_work(opts.work, inputs={"--assets": opts.assets})
    if opts.assets != "none":
        need_path(opts.assets, "--assets", "the asset folder (meshes, HDR maps, textures), or none")
    if opts.diligent != "none":
        check_diligent(opts.diligent, ("ballPNG", "catPNG"), "--diligent")
    claim_result(opts.out, RESULT_KEYS, COMMAND, inputs={"--assets": opts.assets, "--diligent": opts.diligent})


def main(argv: list[str] | None = None) -> int:
    import torch

    from orchestrate.asset_split import split_assets
    from orchestrate.error_calibration import FAULTS, SUITE, objects_of, render_suite
    from unips.data import load_object
    from unips.expected_error import for_weights
    from unips.inference import load_network

    opts = parse(COMMAND, argv)
    before_work(opts)
    torch.set_num_threads(opts.threads)
    work = Path(opts.work or tempfile.mkdtemp(prefix="errbench"))
    work.mkdir(parents=True, exist_ok=True)
    held = str(split_assets(Path(opts.assets), work)[1]) if opts.assets != "none" else None
    t0 = time.time()
    datasets = render_suite(work, held, opts.objects, opts.seed)
    render_s = time.time() - t0
    net = load_network(None)
    em, why = for_weights(net.checkpoint)
    if em is None:
        raise SystemExit(f"error: no error model: {why}")
    rows, pooled = [], {}
    for folder in objects_of(datasets):
        obj = load_object(folder)
        mean, pix, true, _ = state(net, em, obj)
        lo, hi = mean * em.ratio_quantiles[0], mean * em.ratio_quantiles[1]
        t = float(true.mean())
        probes = {}
        for name, variant in (*FAULTS.items(), ("mask_grown", grown)):
            probes[name] = round(state(net, em, variant(obj))[0], 2)
        row = {"object": f"{folder.parent.name}/{folder.name}", "row": folder.parent.name,
               "family": obj.light_family, "images": obj.num_images, "true_mean": round(t, 2),
               "stated_mean": round(mean, 2), "interval_80": [round(lo, 2), round(hi, 2)], "hit": hit(mean, t),
               "covered": bool(lo <= t <= hi), "ause_ratio": sparsification(pix, true)["ause_ratio"],
               "stated_when": probes}
        rows.append(row)
        fam = pooled.setdefault(obj.light_family, ([], []))
        fam[0].append(pix)
        fam[1].append(true)
        print(f"{row['object']:28s} {row['family']:12s} K={row['images']:2d} true {t:5.1f} stated {mean:5.1f} "
              f"[{lo:5.1f}, {hi:5.1f}] {'hit' if row['hit'] else 'miss'} {probes}", flush=True)
    families = {}
    for fam, (pix, true) in sorted(pooled.items()):
        sub = [r for r in rows if r["family"] == fam]
        sp = sparsification(np.concatenate(pix), np.concatenate(true))
        families[fam] = {"objects": len(sub), "hit_share": round(np.mean([r["hit"] for r in sub]), 3),
                         "coverage": round(np.mean([r["covered"] for r in sub]), 3),
                         "true_mean": round(np.mean([r["true_mean"] for r in sub]), 2),
                         "stated_mean": round(np.mean([r["stated_mean"] for r in sub]), 2),
                         "ause_ratio_pooled": round(sp["ause_ratio"], 3), "curve": sp}
    diligent = []
    if opts.diligent != "none":
        for name in ("ballPNG", "catPNG"):
            obj = jpeg_object(load_object(Path(opts.diligent) / name))
            mean, pix, true, _ = state(net, em, obj)
            lo, hi = mean * em.ratio_quantiles[0], mean * em.ratio_quantiles[1]
            t = float(true.mean())
            diligent.append({"object": name + " as JPEG photos", "images": obj.num_images, "true_mean": round(t, 2),
                             "stated_mean": round(mean, 2), "interval_80": [round(lo, 2), round(hi, 2)],
                             "hit": hit(mean, t), "covered": bool(lo <= t <= hi),
                             "ause_ratio": round(sparsification(pix, true)["ause_ratio"], 3),
                             "stated_when": {name: round(state(net, em, f(obj))[0], 2) for name, f in FAULTS.items()}})
            print(diligent[-1], flush=True)
    rises = {p: round(float(np.mean([r["stated_when"][p] > r["stated_mean"] for r in rows])), 3)
             for p in ("half_images", "three_images", "camera_moved", "mask_grown")}
    everything = sparsification(*(np.concatenate([x for f in pooled.values() for x in f[i]]) for i in (0, 1)))
    table = [{"set": fam, "objects": f["objects"], "true_mean": f["true_mean"], "stated_mean": f["stated_mean"],
              "hit_share": f["hit_share"], "coverage": f["coverage"], "ause_ratio": f["ause_ratio_pooled"]}
             for fam, f in families.items()]
    table.append({"set": "all held-out renders", "objects": len(rows),
                  "true_mean": round(float(np.mean([r["true_mean"] for r in rows])), 2),
                  "stated_mean": round(float(np.mean([r["stated_mean"] for r in rows])), 2),
                  "hit_share": round(float(np.mean([r["hit"] for r in rows])), 3),
                  "coverage": round(float(np.mean([r["covered"] for r in rows])), 3),
                  "ause_ratio": round(everything["ause_ratio"], 3)})
    table += [{"set": d["object"], "objects": 1, "true_mean": d["true_mean"], "stated_mean": d["stated_mean"],
               "hit_share": float(d["hit"]), "coverage": float(d["covered"]), "ause_ratio": d["ause_ratio"]}
              for d in diligent]
    result = {
        "command": "python bench/bench_expected_error.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "machine": machine(),
        "error_model": {"weights_sha256": em.weights_sha256[:12], "calibration": em.calibration},
        "suite": [name for name, _ in SUITE], "objects_per_row": opts.objects, "seed": opts.seed,
        "assets": "held-out split" if held else "none", "render_s": round(render_s, 1), "hit_rule": HIT_RULE,
        "overall": {"objects": len(rows), "hit_share": round(float(np.mean([r["hit"] for r in rows])), 3),
                    "coverage": round(float(np.mean([r["covered"] for r in rows])), 3),
                    "ause_ratio_median_object": round(float(np.median([r["ause_ratio"] for r in rows
                                                                       if r["ause_ratio"] is not None])), 3),
                    "stated_rises_share": rises},
        "rows": table, "families": families, "diligent": diligent, "objects": rows,
    }

    write_result(Path(opts.out), result, indent=1)
    o = result["overall"]
    print(f"{o['objects']} held-out objects: stated mean within {HIT_RULE} on {o['hit_share']:.0%}, 80 % interval "
          f"holds the true mean on {o['coverage']:.0%}; wrote {opts.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
