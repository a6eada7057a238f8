"""Blender Cycles (the renderer PS-Wild used) vs our Mitsuba renderer on the same wildgen scene.

  python bench/bench_cycles.py                       # 128x128, spp 4..256, references at ~2048 spp
  python bench/bench_cycles.py --res 96 --levels 4,16,64 --ref-spp 1024
  python bench/bench_cycles.py --install-only        # just make sure Blender is there

Not a test: prints figures. What it does:
1. Makes one wildgen object (family 'mixed', procedural assets) and picks an image lit by one near
   area light plus the environment map.
2. Exports it to Blender with a generated Python script that reads the object folder itself:
   the mesh from aux/mesh.ply (positions, vertex normals, UVs; placed by shape.to_world), a
   Principled BSDF fed by the texture EXRs, a rectangular area light (power = FACTOR x area x
   radiance, FACTOR given by --area-factor, 4 by default), the world from aux/environment.exr with
   the light's rotation and scale, an orthographic camera. Cycles on the CPU, adaptive sampling,
   denoising, clamping and glossy filtering off, the same bounces (Mitsuba max_depth = bounces + 2),
   box pixel filter, --threads threads.
3. Renders three lightings (area only, environment only, both) with both renderers at a high sample
   count (each renderer's own reference) and the 'both' lighting at increasing sample counts.
4. Prints: mean brightness ratio Cycles / Mitsuba per lighting (object pixels and whole image), the
   per-pixel correlation, the normal agreement (Cycles' Normal pass vs our ground truth), and the time
   each renderer needs for a given noise level (RMSE against its own reference, log-log fit).

Blender comes from Debian's `blender` package (3.4): installed here with apt-get when missing and
running as root; otherwise the script says what is missing and exits 3.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from bench.cli_common import MIN_RES, check_work, claim_result, machine, parse, run_main, write_result  # noqa: E402
from bench.cycles_blender import (  # noqa: E402
    BLENDER_SCRIPT,
    TO_BLENDER,
    blender_job,
    blender_version,
    ensure_blender,
    read_multilayer,
)
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import Command, arg, check_fields, comma_list, option  # noqa: E402
from scenes.files import write_json  # noqa: E402

# --------------------------------------------------------------------------- scene choice


def make_scene(out: Path, res: int, seed: int, bounces: int, materials: str = "any") -> tuple[Path, dict, int]:
    """One 'mixed' wildgen object; returns its folder, scene.json and an image with one area light + the envmap."""
    from wildgen.config import GenConfig
    from wildgen.writer import make_object

    for index in range(50):
        cfg = GenConfig(lights=["mixed"], objects=1, images=10, width=res, height=res, spp=4, gt_spp=16, seed=seed,
                        bounces=bounces, materials=materials).validate()
        entry = make_object(cfg, index, out)
        if entry["status"] != "done":
            continue
        folder = out / entry["folder"]
        scene = json.loads((folder / "scene.json").read_text())
        for i, image in enumerate(scene["images"]):
            types = sorted(l["type"] for l in image["lights"])
            if types == ["area", "environment"]:
                return folder, scene, i
    raise SystemExit("error: no image with one area light and the environment among 50 objects")


def lightings(scene: dict, image: int) -> dict[str, list[dict]]:
    lights = scene["images"][image]["lights"]
    area = [l for l in lights if l["type"] == "area"]
    env = [l for l in lights if l["type"] == "environment"]
    return {"area": area, "env": env, "both": area + env}


# --------------------------------------------------------------------------- Mitsuba side


def mitsuba_renders(folder: Path, scene: dict, lights: dict[str, list[dict]], plan: list[tuple[str, int]],
                    threads: int) -> tuple[dict, list[float], object]:
    """Render `plan` [(lighting, spp)] with our renderer; steady-state seconds (after a warm-up at that spp)."""
    import drjit as dr

    from scenes.description import ImageDesc, SceneDescription
    from scenes.lights import light_from_dict
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_ground_truth, render_image

    dr.set_thread_count(threads)
    d = {k: v for k, v in scene.items() if k not in ("camera_lights", "format_version")}
    desc = SceneDescription.from_dict(d)
    names = list(lights)
    desc.images = [ImageDesc(lights=[light_from_dict(l, f"lights[{n!r}]") for l in lights[n]], seed=1) for n in names]
    built = build_scene(desc, base_dir=folder)
    gt = render_ground_truth(built, spp=64)
    images, times = {}, []
    warmed = set()
    for j, (name, spp) in enumerate(plan):
        k = names.index(name)
        seed = 7 if j < len(names) else 1  # references (first) with another seed than the levels
        if spp not in warmed:  # multijitter compiles once per sample count
            render_image(built, k, spp=spp, seed=0)
            warmed.add(spp)
        t0 = time.perf_counter()
        images[(name, spp)] = render_image(built, k, spp=spp, seed=seed)
        times.append(time.perf_counter() - t0)
    return images, times, gt


# --------------------------------------------------------------------------- figures


def rel_rmse(img: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    return float(np.sqrt(np.mean((img[mask] - ref[mask]) ** 2)) / max(ref[mask].mean(), 1e-12))


@dataclass
class Options:
    """The command line of bench/bench_cycles.py."""

    res: int = option(128, minimum=MIN_RES)
    """image side"""
    levels: Annotated[list[int], comma_list(int, "SPP,SPP")] = option(default_factory=lambda: [4, 16, 64, 256],
                                                                       minimum=1)
    """sample counts for the noise/time curves (two or more: a line is fitted through them)"""
    ref_spp: int = option(2048, minimum=1)
    """sample count of each renderer's own reference"""
    bounces: int = option(10, minimum=0)
    """bounces (Mitsuba max_depth = bounces + 2)"""
    threads: int = option(2, minimum=1)
    """CPU threads of both renderers"""
    seed: int = 3
    """wildgen seed of the object"""
    materials: Literal["diffuse", "specular", "metallic", "any"] = "any"
    """material class of the object"""
    area_factor: Annotated[float, arg(metavar="FACTOR")] = 4.0
    """Cycles area-light power = FACTOR x area x radiance"""
    keep: Annotated[str | None, arg(metavar="DIR")] = None
    """keep the renders in this folder"""
    out: Annotated[str | None, arg(metavar="FILE")] = None
    """also write the equal-noise figures as JSON here (docs/generator.md's table reads bench/results/cycles.json)"""
    install_only: bool = False
    """only make sure Blender is installed"""

    def validate(self) -> "Options":
        check_fields(self)
        if len(set(self.levels)) < 2:
            raise UsageError(f"--levels: got {','.join(map(str, self.levels))!r}, expected two or more different "
                             "sample counts, comma-separated (a line is fitted through them)")
        return self


COMMAND = Command(Options, prog="python bench/bench_cycles.py", description=__doc__.split("\n\n")[0])
RESULT_KEYS = ("command", "blender", "rows")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    check_work(args.keep, "--keep")
    claim_result(args.out, RESULT_KEYS, COMMAND)
    blender = ensure_blender()
    version = blender_version(blender)
    print(f"{version} at {blender}")
    if args.install_only:
        return 0

    from scenes.description import multijitter_spp
    from scenes.renderer.variant import choose_variant

    variant = choose_variant("llvm_ad_rgb")
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_cycles_"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        folder, scene, image = make_scene(work / "data", args.res, args.seed, args.bounces, args.materials)
        lights = lightings(scene, image)
        levels = [multijitter_spp(s) for s in args.levels]
        ref = multijitter_spp(args.ref_spp)
        print(f"object {folder.name} image {image}: {scene['material']['material_class']} material, "
              f"{len(lights['area'])} area light + envmap, {args.res}x{args.res}, bounces {args.bounces}, "
              f"{args.threads} threads, mitsuba {variant}; load average {os.getloadavg()[0]:.2f}")

        plan = [(n, ref) for n in lights] + [("both", s) for s in levels]
        # References use another seed than the levels: Cycles' first N samples of a longer render are the N-spp render.
        renders = [{"area": n != "env", "env": n != "area", "spp": s, "seed": 7 if k < len(lights) else 1,
                    "out": str(work / f"cycles_{n}_{s}.exr")} for k, (n, s) in enumerate(plan)]
        job = blender_job(folder, scene, lights, renders, args.threads, args.area_factor, work)
        write_json(work / "job.json", job, indent=None)
        (work / "scene_to_blender.py").write_text(BLENDER_SCRIPT)
        t0 = time.perf_counter()
        r = subprocess.run(
            [
                blender,
                "-b",
                "--factory-startup",
                "-noaudio",
                "-t",
                str(args.threads),
                "--python",
                str(work / "scene_to_blender.py"),
                "--",
                str(work / "job.json"),
            ],
            capture_output=True,
            text=True,
        )
        cycles_wall = time.perf_counter() - t0
        if r.returncode != 0 or not (work / "cycles_times.json").exists():
            tail = "\n".join((r.stdout + r.stderr).strip().splitlines()[-15:])
            raise SystemExit(f"error: Blender failed (exit {r.returncode}):\n{tail}")
        cycles_times = json.loads((work / "cycles_times.json").read_text())["times"]
        cyc = {key: read_multilayer(Path(rd["out"])) for key, rd in zip(plan, renders)}

        t0 = time.perf_counter()
        mi_images, mi_times, gt = mitsuba_renders(folder, scene, lights, plan, args.threads)
        mitsuba_wall = time.perf_counter() - t0
        mask = gt.coverage > 0.999

        print(
            f"\nwall: Blender process {cycles_wall:.1f} s (incl. start and scene import), "
            f"Mitsuba {mitsuba_wall:.1f} s (incl. compiles)"
        )
        print(f"\nagreement at {ref} spp (each renderer's own reference), Cycles / Mitsuba:")
        print(f"{'lighting':9s} {'object ratio':>12s} {'R':>6s} {'G':>6s} {'B':>6s} {'image ratio':>11s} {'corr':>6s}")
        for n in lights:
            c, m = cyc[(n, ref)]["combined"], mi_images[(n, ref)]
            per = [c[mask][:, i].mean() / m[mask][:, i].mean() for i in range(3)]
            corr = np.corrcoef(c[mask].ravel(), m[mask].ravel())[0, 1]
            print(f"{n:9s} {c[mask].mean() / m[mask].mean():12.4f} {per[0]:6.3f} {per[1]:6.3f} {per[2]:6.3f} "
                  f"{c.mean() / m.mean():11.4f} {corr:6.4f}")

        # Superposition: in Mitsuba the area light is a real rectangle that also hides the environment behind it.
        lin_c = cyc[("both", ref)]["combined"][mask].mean() / (
            cyc[("area", ref)]["combined"][mask].mean() + cyc[("env", ref)]["combined"][mask].mean()
        )
        lin_m = mi_images[("both", ref)][mask].mean() / (
            mi_images[("area", ref)][mask].mean() + mi_images[("env", ref)][mask].mean()
        )
        print(f"both / (area + env) on object pixels: Cycles {lin_c:.4f}, Mitsuba {lin_m:.4f}")

        from scenes.geometry import camera_rotation

        cam = scene["camera"]
        R = camera_rotation(cam["origin"], cam["target"], cam["up"])
        nb = cyc[("both", ref)]["normal"]
        n_cycles = (nb @ TO_BLENDER) @ R.T  # Blender world -> Mitsuba world -> camera frame
        n_cycles /= np.maximum(np.linalg.norm(n_cycles, axis=-1, keepdims=True), 1e-12)
        n_ours = gt.normal / np.maximum(np.linalg.norm(gt.normal, axis=-1, keepdims=True), 1e-12)
        ang = np.degrees(np.arccos(np.clip((n_cycles[mask] * n_ours[mask]).sum(-1), -1, 1)))
        print(f"\nnormals (Cycles Normal pass vs our ground truth, {mask.sum()} object pixels): "
              f"mean {ang.mean():.3f} deg, median {np.median(ang):.3f}, 99th pct {np.percentile(ang, 99):.3f}")

        print(
            "\nnoise vs time, lighting 'both' (relative RMSE on object pixels against the renderer's own "
            f"{ref}-spp reference):"
        )
        print(f"{'spp':>5s} {'Cycles s':>9s} {'rmse':>7s} {'Mitsuba s':>10s} {'rmse':>7s}")
        k0 = len(lights)
        ct, ce, mt, me = [], [], [], []
        for j, s in enumerate(levels):
            ct.append(cycles_times[k0 + j])
            mt.append(mi_times[k0 + j])
            ce.append(rel_rmse(cyc[("both", s)]["combined"], cyc[("both", ref)]["combined"], mask))
            me.append(rel_rmse(mi_images[("both", s)], mi_images[("both", ref)], mask))
            print(f"{s:5d} {ct[-1]:9.3f} {ce[-1]:7.4f} {mt[-1]:10.3f} {me[-1]:7.4f}")
        both_ref = list(lights).index("both")
        print(f"{ref:5d} {cycles_times[both_ref]:9.3f} {'ref':>7s} {mi_times[both_ref]:10.3f} {'ref':>7s}")
        fits = {}
        # The time line is fitted to the levels only, where the equal-noise sample counts lie: the reference's count
        # (2048 -> 2070 = 45 x 46 for multijitter) is not a power of two, and Mitsuba's multijitter permutation
        # loops about twice per draw there (measured on this scene: 192 ns per sample at 2070 spp against 132 at
        # 1024), so a line through it overstated Mitsuba's time at 239 spp by 40 % (0.77 s fitted, 0.59 s measured
        # at 256 spp).
        for name, times, errors in (("Cycles", ct, ce), ("Mitsuba", mt, me)):
            per_spp, t0 = np.polyfit(np.array(levels, float), np.asarray(times), 1)  # time = t0 + per_spp * spp
            slope, icpt = np.polyfit(np.log(levels), np.log(errors), 1)  # log rmse = icpt + slope * log spp
            fits[name] = (t0, per_spp, slope, icpt)
            print(
                f"{name:8s}: time = {t0:.3f} s + {per_spp * 1e3:.3f} ms/spp "
                f"({per_spp / (args.res**2) * 1e9:.1f} ns per sample), "
                f"rmse ~ spp^{slope:.3f}"
            )
        rows = []
        for level, target in ((levels[len(me) // 2], me[len(me) // 2]), (levels[-1], me[-1])):
            row = {}
            for name, (t0, per_spp, slope, icpt) in fits.items():
                spp_needed = math.exp((math.log(target) - icpt) / slope)
                row[name] = (spp_needed, t0 + per_spp * spp_needed, per_spp * spp_needed)
            (cs, cw, cp), (ms, mw, mp) = row["Cycles"], row["Mitsuba"]
            print(f"equal noise {target:.4f}: Cycles {cs:.0f} spp {cw:.2f} s ({cp:.2f} s path tracing), "
                  f"Mitsuba {ms:.0f} spp {mw:.3f} s ({mp:.3f} s) -> Mitsuba {cw / mw:.1f}x faster per render, "
                  f"{cp / mp:.1f}x in path tracing alone")
            rows.append({"noise_of_spp": level, "relative_rmse": round(target, 5), "cycles_spp": round(cs),
                         "cycles_s": round(cw, 3), "mitsuba_spp": round(ms), "mitsuba_s": round(mw, 3),
                         "speedup": round(cw / mw, 2), "speedup_path_tracing": round(cp / mp, 2)})
        print(f"load average now {os.getloadavg()[0]:.2f}")
        if args.out:
            write_result(Path(args.out), {
                "machine": machine(),
                "command": "python bench/bench_cycles.py " + " ".join(sys.argv[1:]), "blender": version,
                "res": args.res, "threads": args.threads, "reference_spp": ref,
                "ns_per_sample": {name: round(f[1] / args.res ** 2 * 1e9, 1) for name, f in fits.items()},
                "rows": rows}, indent=1, newline=True)
            print(f"wrote {args.out}")
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
