"""How many images, and how many lit pixels per image, the fitted check and refinement need to judge a map.

    python bench/bench_min_images.py [--out min_images.json] [--threads T]

The minimum in `validate.judgeable` (MIN_IMAGES, MIN_LIT_PIXELS) and docs/check.md ("What can be judged")
come from this script. Every capture is an analytic Lambertian sphere (orthographic, smooth random albedo
0.4-0.9, directional lights of irradiance 2, Gaussian noise of sigma 0.003, about DiLiGenT's noise level
relative to the mean value), so it costs a few seconds per row. Per capture:

- ranking: the fitted score (rel_l1, `validate.fitted.fit.fit_normals`, light and albedo fitted with the map held)
  of the ground-truth map and of three perturbed maps (random 5 deg, random 10 deg, smooth 10 deg); `gap`
  is (lowest perturbed score - GT score) in units of the image noise (its rel_l1, known exactly here), and
  the capture "ranks" when the gap is at least one noise level (a smaller one would not survive another
  draw of the noise);
- refinement of the ground-truth map itself (`validate.refine.refine_normals`, fitted lights): the mean
  angular error it ends at (0 is the right answer; a capture that cannot pin the map lets it drift).

Sweeps: (1) the number of images K = 1, 2, 3, 4, 5, 6, 8 (lights drawn from 8 directions 35-70 deg from
the view axis; `--draws` draws per K); (2) the lit share of the mask on a 32 px sphere, 8 lights moved from
45 to 120 deg from the view axis (toward and behind the object's outline); (3) lit pixels per image
through the sphere's size (4 to 32 px), 8 lights in front. Lit pixels are counted by
`validate.judgeable.lit_pixels`, the rule's own definition. About 1.5 min on 2 CPU cores (`llvm_ad_rgb`).
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import claim_result, parse, run_main, write_result  # noqa: E402
from scenes.cli.options import Command, arg, option  # noqa: E402

NOISE = 0.003
IRRADIANCE = 2.0
PERTURBATIONS = (("random", 5.0), ("random", 10.0), ("smooth", 10.0))


def sphere(res: int) -> tuple[np.ndarray, np.ndarray]:
    """Normals (res, res, 3) and mask of a unit sphere filling 0.9 of an orthographic frame."""
    c = ((np.arange(res) + 0.5) / res * 2 - 1) / 0.9
    x, y = np.meshgrid(c, -c)
    r2 = x * x + y * y
    mask = r2 < 0.97
    n = np.stack([x, y, np.sqrt(np.clip(1 - r2, 0, None))], -1)
    return np.where(mask[..., None], n, 0).astype(np.float32), mask


def lights_at(polar_deg: float, count: int = 8) -> np.ndarray:
    """`count` unit directions toward the light at `polar_deg` from the view axis, azimuths all around."""
    t = np.radians(polar_deg)
    a = np.radians(np.arange(count) * 360.0 / count)
    return np.stack([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.full(count, np.cos(t))], 1)


FRONT = np.array([[np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)]
                  for e, a in zip(np.radians([40, 55, 70, 35, 50, 65, 45, 60]), np.radians(np.arange(8) * 45.0))])


def render(n: np.ndarray, mask: np.ndarray, lights: np.ndarray, seed: int) -> tuple[np.ndarray, float]:
    """(K, H, W, 3) Lambertian images, albedo / pi * E * max(0, n . l), plus noise, 0 outside the mask; and
    the noise as a relative L1 level (mean |noisy - clean| / mean |noisy| over the mask): the score of a
    perfect explanation."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    h, w = mask.shape
    field = gaussian_filter(rng.normal(size=(h, w, 3)), (max(h, w) / 8, max(h, w) / 8, 0))
    albedo = 0.4 + 0.5 * (field - field.min()) / max(np.ptp(field), 1e-12)
    shade = np.maximum(np.einsum("hwc,kc->khw", n, lights), 0)[..., None]
    clean = albedo[None] / np.pi * IRRADIANCE * shade
    imgs = np.maximum(clean + rng.normal(scale=NOISE, size=clean.shape), 0)
    imgs = np.where(mask[None, ..., None], imgs, 0).astype(np.float32)
    noise = float(np.abs(imgs - clean)[:, mask].mean() / imgs[:, mask].mean())
    return imgs, noise


def measure(n: np.ndarray, mask: np.ndarray, imgs: np.ndarray, noise: float, cfg) -> dict:
    """Scores of the ground truth and the perturbed maps, and refinement of the ground truth (module doc)."""
    from scenes.metrics import mean_angular_error
    from validate.fitted.fit import fit_normals
    from validate.fitted.refinement import RefineConfig, refine_normals
    from validate.judgeable import lit_pixels
    from validate.perturb import perturb_normals

    t0 = time.perf_counter()
    gt = fit_normals(imgs, mask, n, cfg).rel_l1
    scores = {f"{kind} {a:g}": fit_normals(imgs, mask, perturb_normals(n, mask, kind, a, seed=1), cfg).rel_l1
              for kind, a in PERTURBATIONS}
    gap = (min(scores.values()) - gt) / noise
    r = refine_normals(imgs, mask, n, RefineConfig(fit=cfg))
    lit = lit_pixels(imgs, mask)
    return {"images": len(imgs), "mask_pixels": int(mask.sum()), "lit_pixels_min": int(lit.min()),
            "lit_pixels_median": float(np.median(lit)), "noise_rel_l1": noise, "gt_rel_l1": gt,
            "perturbed_rel_l1": scores, "gap_in_noise": gap, "ranks": bool(gap >= 1.0),
            "refine_gt_mae_deg": mean_angular_error(r.normals, n, mask), "seconds": time.perf_counter() - t0}


HEADER = f"{'lit px':>7} {'noise':>7} {'GT':>7} {'worst':>7} {'gap':>6} {'ranks':>6} {'refined GT':>10}"


def fmt(r: dict) -> str:
    """One table row: lit pixels (fewest of one image), noise level, rel_l1 of the GT map and of the best
    perturbed map ('worst' case for ranking), their gap in noise levels, and the refined GT map's error."""
    return (
        f"{r['lit_pixels_min']:>7} {r['noise_rel_l1']:>7.4f} {r['gt_rel_l1']:>7.4f} "
        f"{min(r['perturbed_rel_l1'].values()):>7.4f} "
        f"{r['gap_in_noise']:>6.1f} {str(r['ranks']):>6} {r['refine_gt_mae_deg']:>10.2f}"
    )


@dataclass
class Options:
    """The command line of bench/bench_min_images.py."""

    out: Annotated[str | None, arg(metavar="FILE")] = None
    """write every row as JSON here"""
    threads: Annotated[int | None, arg(metavar="T", help_behavior_hint="(default one per core)")] = option(
        None, minimum=1
    )
    """Dr.Jit threads"""
    draws: int = option(4, minimum=1, maximum=1000)
    """light subsets per image count (at most 1000: the mean of more moves by nothing the table shows)"""


COMMAND = Command(Options, prog="python bench/bench_min_images.py", description=__doc__.splitlines()[0])


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    claim_result(args.out, ("images", "crescent", "size"), COMMAND)  # the keys of every result: the three sweeps
    from scenes.renderer.variant import choose_variant, set_jit_threads
    from validate.fitted.fit_scene import FitConfig

    choose_variant("llvm_ad_rgb")
    set_jit_threads(args.threads)
    cfg = FitConfig(steps=40, batch_images=8, refresh_every=10, ao_rays=4, max_pixels=100000, seed=0)
    rows: dict[str, list] = {"images": [], "crescent": [], "size": []}

    print("rel_l1 of the GT map and of the lowest-scoring perturbed map; gap = their difference in noise levels;")
    print("ranks = gap >= 1; refined GT = mean angular error (deg) after refining the GT map (fitted lights)\n")
    print("(1) number of images K, 32 px sphere, lights 35-70 deg from the view axis")
    print(f"{'K':>3} {'draw':>4} " + HEADER)
    n, mask = sphere(32)
    rng = np.random.default_rng(0)
    for k in (1, 2, 3, 4, 5, 6, 8):
        for d in range(args.draws if k < 8 else 1):
            idx = np.sort(rng.choice(8, size=k, replace=False))
            r = measure(n, mask, *render(n, mask, FRONT[idx], seed=d), cfg)
            r.update(k=k, draw=d, lights=idx.tolist())
            rows["images"].append(r)
            print(f"{k:>3} {d:>4} " + fmt(r), flush=True)

    print("\n(2) lit fraction through the lights' angle from the view axis, 8 images, 32 px sphere")
    print(f"{'angle':>5} {'lit/mask':>8} " + HEADER)
    for polar in (45, 70, 90, 105, 120):
        r = measure(n, mask, *render(n, mask, lights_at(polar), seed=0), cfg)
        r.update(polar_deg=polar)
        rows["crescent"].append(r)
        print(f"{polar:>5} {r['lit_pixels_min'] / r['mask_pixels']:>8.2f} " + fmt(r), flush=True)

    print("\n(3) lit pixels per image through the sphere's size, 8 images, lights in front")
    print(f"{'res':>5} {'mask px':>8} " + HEADER)
    for res in (4, 5, 6, 8, 11, 16, 32):
        ns, ms = sphere(res)
        r = measure(ns, ms, *render(ns, ms, FRONT, seed=0), cfg)
        r.update(res=res)
        rows["size"].append(r)
        print(f"{res:>5} {r['mask_pixels']:>8} " + fmt(r), flush=True)
    if args.out:
        write_result(Path(args.out), rows, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
