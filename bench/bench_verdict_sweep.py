"""Each constant of the verdict swept one at a time on rendered captures with ground truth (docs/check.md, "Verdict
constants").

    python bench/bench_verdict_sweep.py --assets ASSETS --out bench/results/verdict_sweep.json [CAPTURE ...]

Without CAPTUREs the bench renders its own suite into a work folder (`--work`, default a temporary folder):
`python -m wildgen.make --images 12 --res 64 --spp 32` with `--objects` objects cycling over the five light
families (directional, point, near_area, hdri, mixed) and `--directional-objects` more under directional light
only (the lights the check can judge, where its constants decide most), meshes from `--assets` half of the time
(held-out assets) else procedural shapes. A CAPTURE is an object folder with ground-truth normals (a `*.data`
folder of wildgen.make, a DiLiGenT `*PNG` folder) or a folder of them; the verdict never reads scene.json (the
light family is read from it only to label the rows).

Per capture, once: lights and reflectance are fitted (`validate.fitted.fit.fit_normals`, the check's default
`FitConfig`) around the truth and around wrong maps: the truth tilted by 10 and 25 degrees about a smoothly varying
axis (`validate.perturb`, `smooth`), mirrored left to right (n_x negated) and the constant (0, 0, 1) map; the
fitted renders are kept. A fit reads the images, the mask, the map and the saturated channels only, never the
verdict's constants, so the renders serve every value of the sweep.

Per constant value (one constant changed, the others at their defaults, `validate.fitted.verdict.VerdictRules`): the
images are explained again (`explain`, where the constant enters it), the verdict taken (`verdict`), and every map
scored on that explanation's observations (`judged_rel_l1`). Counted per value, over the captures:
- trusted;
- false trust: trusted, and a wrong map (one at least 10 degrees off, `WRONG_DEG`) scores at or below the truth (the
  error the verdict exists to prevent); of those, where that map is below the truth by more than the capture's
  resolution (`told_apart`);
- needless abstention: not trusted, yet the truth scores below every wrong map by more than the resolution.
"""
from __future__ import annotations

import dataclasses
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import check_work, claim_result, need_path, parse, run_main, write_result  # noqa: E402
from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error  # noqa: E402
from scenes.cli.options import Command, Positional, arg, check_fields, option  # noqa: E402
from scenes.files import read_json  # noqa: E402

SWEEP: dict[str, tuple[float, ...]] = {
    "shadow_fraction": (0.02, 0.05, 0.1, 0.2, 0.3),
    "outlier_sigmas": (2.5, 3.0, 4.0, 6.0, 10.0),
    "scale_floor": (0.003, 0.01, 0.03),
    "min_observations": (4, 5, 6, 8),
    "explained_relative": (0.02, 0.03, 0.05, 0.08, 0.12),
    "min_explained": (0.0, 0.25, 0.4, 0.5, 0.6, 0.75, 1.0),
    "dimension_noise": (0.0, 2.0, 4.0, 8.0, 16.0, 32.0),
}
"""The values of each `VerdictRules` field, its default among them."""
VERDICT_ONLY = ("min_explained", "dimension_noise")
"""Fields that `verdict` reads and `explain` does not: their values share one explanation."""
FAMILIES = "directional,point,near_area,hdri,mixed"
"""The light families of the rendered suite, cycled over its objects."""
WRONG = ("gt+10", "gt+25", "mirrored", "constant")
"""The wrong maps."""
WRONG_DEG = 9.99
"""A wrong map counts when it is at least this far from the truth (mean angular error, degrees): GT+10 is 10
degrees off at every pixel; a mirrored map of a nearly flat object can be closer, and is then left out."""


@dataclass
class SweepOptions:
    """The command line of bench/bench_verdict_sweep.py."""

    captures: Annotated[tuple[str, ...], Positional, arg(metavar="CAPTURE")] = ()
    """Object folders with ground-truth normals, or folders of them (`*.data`); none: render the suite."""
    out: Annotated[str, arg(metavar="FILE")] = "bench/results/verdict_sweep.json"
    """Where the measured sweep is written (JSON; docs/check.md's table is generated from it)."""
    work: Annotated[str | None, arg(metavar="DIR", help_behavior_hint="(default: a temporary folder)")] = None
    """Folder the suite is rendered into when no CAPTURE is given (kept; a suite already there is reused)."""
    assets: Annotated[str | None, arg(metavar="DIR")] = None
    """Asset folder of wildgen.make (meshes, HDR maps, textures): half of the suite's shapes are its meshes."""
    objects: int = option(20, minimum=0)
    """Objects of the rendered suite cycling over the five light families."""
    directional_objects: int = option(8, minimum=0)
    """Further objects under directional light only."""
    seed: int = 4747
    """Seed of the rendered suite (the directional objects: seed + 1)."""
    threads: int = option(1, minimum=1)
    """Dr.Jit threads of the fits and the renders."""

    def validate(self) -> "SweepOptions":
        check_fields(self)
        if not self.captures and self.objects + self.directional_objects == 0:
            raise UsageError("--objects: got 0 (and --directional-objects 0) without a CAPTURE, expected a suite of "
                             "one or more objects to render")
        return self


COMMAND = Command(SweepOptions, prog="python bench/bench_verdict_sweep.py", description=__doc__.split("\n\n")[0])
RESULT_KEYS = ("command", "settings", "defaults", "rows", "captures")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def render_suite(opts: SweepOptions, work: Path) -> list[Path]:
    """The object folders of the suite in `work` (rendered by wildgen.make unless already there)."""
    common = ["--images", "12", "--res", "64", "--spp", "32", "--workers", "1", "--threads", str(opts.threads),
              "--quiet"]
    if opts.assets:
        common += ["--assets", opts.assets, "--shapes", "any"]
    folders = []
    for name, objects, lights, seed in (("suite", opts.objects, FAMILIES, opts.seed),
                                        ("directional", opts.directional_objects, "directional", opts.seed + 1)):
        if objects == 0:
            continue
        out = work / name
        if not (out / "manifest.json").is_file():
            subprocess.run([sys.executable, "-m", "wildgen.make", "--objects", str(objects), "--lights", lights,
                            "--seed", str(seed), "--out", str(out), *common], check=True, cwd=ROOT)
        folders += sorted(out.glob("*.data"))
    return folders


def capture_folders(paths: tuple[str, ...]) -> list[Path]:
    """Each path as an object folder, or the `*.data` folders inside it."""
    out = []
    for p in map(Path, paths):
        inner = sorted(p.glob("*.data"))
        out += inner if inner and not (p / "mask.png").is_file() else [p]
    return out


def rules_for(name: str, value: float):
    """`VerdictRules` with one field changed (an integer field keeps its type)."""
    from validate.fitted.verdict import VerdictRules

    default = getattr(VerdictRules(), name)
    return dataclasses.replace(VerdictRules(), **{name: type(default)(value)})


def fitted_renders(cap, config) -> tuple[dict[str, np.ndarray], dict[str, float], dict[str, float]]:
    """The expensive part, once per capture: (map name -> fitted render (K, P, 3) at the fitting resolution, map
    name -> its angular error to the truth in degrees, map name -> fit seconds)."""
    from scenes.metrics import mean_angular_error
    from validate.fitted.fit import fit_normals, prepare
    from validate.perturb import perturb_normals

    gt, mask = cap.normal_gt, cap.mask
    maps = {"gt": gt, "gt+10": perturb_normals(gt, mask, "smooth", 10, 0),
            "gt+25": perturb_normals(gt, mask, "smooth", 25, 0), "mirrored": gt * np.float32([-1, 1, 1]),
            "constant": np.where(mask[..., None], np.float32([0, 0, 1]), 0).astype(np.float32)}
    renders, errors, seconds = {}, {}, {}
    for name, m in maps.items():
        small, nm, _ = prepare(cap, m, config)
        t0 = time.perf_counter()
        renders[name] = fit_normals(small.images, small.mask, nm, config, saturated=small.saturated).render
        seconds[name] = time.perf_counter() - t0
        errors[name] = mean_angular_error(m, gt, mask)
    return renders, errors, seconds


def judge(images: np.ndarray, mask: np.ndarray, saturated: np.ndarray | None, renders: dict[str, np.ndarray],
          sweep: dict[str, tuple[float, ...]] = SWEEP, wrong: list[str] | None = None) -> dict[str, dict[float, dict]]:
    """The cheap part, per constant value: constant -> value -> {explained, light_dimensions, resolution, trusted,
    judged (map -> judged rel_l1), truth_first, below_truth_told_apart, truth_first_told_apart}. images (K, H, W, 3)
    at the fitting resolution, renders (K, P, 3) of its mask pixels, "gt" and other maps; wrong: the maps the
    truth must score below (default: every map but "gt")."""
    from validate.fitted.verdict import VerdictRules, explain, judged_rel_l1, told_apart, verdict

    observed = images[:, mask]
    wrong = [k for k in renders if k != "gt"] if wrong is None else wrong
    cache: dict = {}
    out: dict[str, dict[float, dict]] = {}
    for name, values in sweep.items():
        out[name] = {}
        for value in values:
            rules = rules_for(name, value)
            # The fields only the verdict reads do not change the explanation: one per explaining rule set.
            key = dataclasses.replace(rules, **{f: getattr(VerdictRules(), f) for f in VERDICT_ONLY})
            if key not in cache:
                cache[key] = explain(images, mask, saturated, key)
            ex = cache[key]
            trusted, _ = verdict(ex, rules)
            s = {k: judged_rel_l1(r, observed, ex) for k, r in renders.items()}
            out[name][value] = {
                "explained": ex.explained_fraction,
                "light_dimensions": ex.dimensions_above(rules.dimension_noise),
                "resolution": ex.resolution,
                "trusted": trusted,
                "judged": s,
                "truth_first": all(s["gt"] < s[k] for k in wrong),
                "below_truth_told_apart": [k for k in wrong if s[k] < s["gt"] and told_apart(s["gt"], s[k], ex)],
                "truth_first_told_apart": all(s["gt"] < s[k] and told_apart(s["gt"], s[k], ex) for k in wrong),
            }
    return out


def count(results: list[dict[str, dict[float, dict]]], name: str, value: float) -> dict:
    """The table row of one constant value over the captures' `judge` results."""
    rows = [r[name][value] for r in results]
    return {
        "trusted": sum(r["trusted"] for r in rows),
        "false_trust": sum(r["trusted"] and not r["truth_first"] for r in rows),
        "false_trust_told_apart": sum(r["trusted"] and bool(r["below_truth_told_apart"]) for r in rows),
        "needless_abstention": sum(not r["trusted"] and r["truth_first_told_apart"] for r in rows),
    }


COMPACT = ("value", "explained", "light_dimensions", "trusted", "truth_first", "truth_first_told_apart",
           "wrong_maps_told_apart_below_truth")
"""The columns of a capture's row per constant value in the JSON (`captures[].sweep`)."""


def _compact(value: float, r: dict) -> list:
    return [value, round(r["explained"], 3), r["light_dimensions"], r["trusted"], r["truth_first"],
            r["truth_first_told_apart"], len(r["below_truth_told_apart"])]


def _round(x, digits: int):
    """`x` with its floats rounded and NaN as None (a capture with nothing explained has no resolution)."""
    if isinstance(x, float):
        return round(x, digits) if np.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _round(v, digits) for k, v in x.items()}
    if isinstance(x, list):
        return [_round(v, digits) for v in x]
    return x


def sweep_text(d: dict) -> str:
    """The sweep's JSON: indented, but one line per capture (the file stays small enough to commit)."""
    top = json.dumps({**d, "captures": None}, indent=1, allow_nan=False)
    lines = ",\n".join("  " + json.dumps(c, allow_nan=False) for c in d["captures"])
    return top.replace('"captures": null', '"captures": [\n' + lines + "\n ]") + "\n"


def run(opts: SweepOptions) -> dict:
    from scenes.renderer.variant import choose_variant, set_jit_threads

    choose_variant("llvm_ad_rgb")
    set_jit_threads(opts.threads)
    from validate.fitted.fit import prepare
    from validate.fitted.fit_scene import FitConfig
    from validate.fitted.verdict import VerdictRules
    from validate.observations import load_capture

    t_start = time.perf_counter()
    tmp = None
    if opts.captures:
        folders = capture_folders(opts.captures)
    else:
        if opts.work is None:
            tmp = tempfile.TemporaryDirectory(prefix="verdict_sweep_")
        folders = render_suite(opts, Path(opts.work or tmp.name))
    t_render = time.perf_counter() - t_start
    config = FitConfig().validate()
    results, captures = [], []
    fit_s = judge_s = 0.0
    for folder in folders:
        cap = load_capture(folder, arg="CAPTURE")
        if cap.normal_gt is None:
            print(f"{folder}: no ground truth, skipped", file=sys.stderr)
            continue
        scene = folder / "scene.json"
        family = read_json(scene).get("light_family", "-") if scene.is_file() else "-"
        t0 = time.perf_counter()
        renders, errors, seconds = fitted_renders(cap, config)
        t1 = time.perf_counter()
        small, _, _ = prepare(cap, cap.normal_gt, config)
        wrong = [k for k in WRONG if errors[k] >= WRONG_DEG]
        res = judge(small.images, small.mask, small.saturated, renders, wrong=wrong)
        t2 = time.perf_counter()
        fit_s, judge_s = fit_s + t1 - t0, judge_s + t2 - t1
        results.append(res)
        default = res["min_explained"][VerdictRules().min_explained]  # every constant at its default
        captures.append({"capture": f"{folder.parent.name}/{folder.name}", "light_family": family,
                         "mask_pixels": int(small.mask.sum()), "mae_deg": _round(errors, 2),
                         "fit_s": round(t1 - t0, 1), "sweep_s": round(t2 - t1, 1),
                         "default": _round({k: default[k] for k in ("explained", "light_dimensions", "resolution",
                                                                    "trusted", "judged")}, 4),
                         "sweep": {name: [_compact(v, res[name][v]) for v in vals] for name, vals in SWEEP.items()}})
        print(f"{folder.name:<12} {family:<12} explained {default['explained']:.2f} trusted {default['trusted']!s:<5} "
              f"truth first {default['truth_first']!s:<5} fits {t1 - t0:.0f} s, sweep {t2 - t1:.0f} s  "
              + " ".join(f"{k} {v:.4f}" for k, v in default["judged"].items()), flush=True)
    if not captures:  # a sweep of nothing would replace a measured one
        raise UsageError("CAPTURE: no capture with ground-truth normals was measured (each was skipped, above); "
                         "nothing is written")
    rows = []
    defaults = VerdictRules()
    for name, values in SWEEP.items():
        for v in values:
            rows.append({"constant": name.upper(), "value": v, "default": v == getattr(defaults, name),
                         **count(results, name, v)})
    if tmp is not None:
        tmp.cleanup()
    families = sorted({c["light_family"] for c in captures})
    return {
        "command": "python bench/bench_verdict_sweep.py " + " ".join(sys.argv[1:]),
        "settings": {"captures": len(captures), "objects": opts.objects,
                     "directional_objects": opts.directional_objects, "seed": opts.seed, "assets": bool(opts.assets),
                     "families": {f: sum(c["light_family"] == f for c in captures) for f in families},
                     "maps": ["gt", *WRONG],
                     "fit": dataclasses.asdict(config) | {"floor_maps": list(config.floor_maps)}},
        "defaults": dataclasses.asdict(defaults),
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "seconds": _round({"render": t_render, "fits": fit_s, "sweep": judge_s,
                           "total": time.perf_counter() - t_start}, 1),
        "rows": rows,
        "sweep_columns": list(COMPACT),
        "captures": captures,
    }


def main(argv: list[str] | None = None) -> int:
    opts = parse(COMMAND, argv)
    for capture in opts.captures:
        need_path(capture, "CAPTURE", "an object folder with ground-truth normals, or a folder of them")
    if opts.assets is not None:
        need_path(opts.assets, "--assets", "an asset folder of wildgen.make")
    check_work(opts.work, inputs={"--assets": opts.assets})
    out = claim_result(opts.out, RESULT_KEYS, COMMAND)
    try:
        d = run(opts)
    except INPUT_ERRORS as exc:
        return report_error(exc)
    write_result(out, text=sweep_text(d))
    for r in d["rows"]:
        print(f"{r['constant']:<20} {r['value']:<6} {'(default)' if r['default'] else '':<9} trusted {r['trusted']:<3} "
              f"false trust {r['false_trust']} ({r['false_trust_told_apart']} told apart)  needless abstention "
              f"{r['needless_abstention']}")
    print(f"wrote {out} ({d['seconds']['total']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
