"""Where one object's render time goes, stage by stage, and objects per hour: this tree against another commit.

  python bench/bench_profile.py --out bench/results/profile.json                  # this tree only
  python bench/bench_profile.py --baseline fc0f278~1 --out bench/results/profile.json   # also that commit, side by side
  python bench/bench_profile.py --settings default --objects 3 --rate-objects 4    # quicker

Not a test: prints a table and writes JSON (its `rows` feed the generated table in docs/generator.md). Each tree
(this one and, with --baseline, a git worktree of that commit made in a temporary folder) runs in its own fresh
Python process with one Dr.Jit thread, so a stage's wall time is its CPU time on one core. Per setting (`SETTINGS`:
the defaults 128 px / 10 images / 64 spp, and 256 px / 10 images / 256 spp) it renders objects 0..N-1 of the same
dataset with `wildgen.writer.make_object`, the function every engine calls, and times each stage by wrapping the
functions `wildgen.writer` calls (`sample_object`, `build_scene`, `render_ground_truth`, `render_images`,
`publish_folder`) plus Dr.Jit's kernel history:

  sampling        drawing the object, its material, lights and camera from the seed (`sample_object`)
  building        the Mitsuba scene from its description (`build_scene`)
  ground truth    the normal / depth / material pass (`render_ground_truth`)
  relighting      writing each image's lights into the scene (`BuiltScene.apply_image`: Mitsuba updates the
                  scene, and rebuilds its ray-tracing acceleration structure when an area light moved)
  tracing         Python and Mitsuba building each image's computation (up to its first `drjit.eval`)
  compiling       LLVM compiling kernels not in Dr.Jit's caches (kernel history: codegen + backend time)
  path tracing    executing the path tracer's kernels (kernel history: the kernels of 300 or more operations)
  reduction       everything else in rendering the images: summing each pixel's samples, reading them back, NumPy
  writing         encoding and writing PNG / EXR / scene.json, checksums, the atomic rename
The first object of a process also pays for imports and the asset scan: it is reported apart ("first object");
the table's figures are the mean over the objects after it. Kernels: per object, how many path-tracing kernels were
compiled, loaded from Dr.Jit's disk cache, or reused from memory.

Objects per hour come from the real CLI in each tree (`python -m wildgen.make` at the setting, default workers and
threads, a fresh output folder), alternately baseline / this tree, --rounds times: a run of SHORT_RUN objects and
one of N (--rate-objects), and the rate of a long run is (N - SHORT_RUN) objects over the difference of their wall
times, which cancels starting Python, the workers and their first kernels (the N-object run's own rate, start-up
included, is recorded too). Both trees must give byte-identical objects (the script compares the checksums in the
manifests) unless --allow-different-bytes is given (a commit that changes the bytes on purpose).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.cli_common import check_revision, claim_result, machine, parse, run_main, write_result  # noqa: E402
from scenes.cli.options import CommaList, Command, arg, option  # noqa: E402
from wildgen.light_families import LIGHT_FAMILIES  # noqa: E402

SETTINGS = {
    "default": {"res": 128, "images": 10, "spp": 64},
    "large": {"res": 256, "images": 10, "spp": 256},
}
"""The two object sizes the profile is taken at (wildgen.make's defaults, and PS-Wild's 256 spp at 256 px)."""
COUNTS = {"default": (5, 10), "large": (3, 0)}
"""Objects profiled, and objects of the longer wildgen.make run for objects per hour (0: not measured), per setting
(unless --objects / --rate-objects)."""
SHORT_RUN = 2  # objects of the shorter wildgen.make run: one per default worker

STAGES = (
    "sampling",
    "building",
    "ground_truth",
    "relighting",
    "tracing",
    "compiling",
    "path_tracing",
    "reduction",
    "writing",
)
BIG_KERNEL_OPS = 300  # the path tracer's kernels have thousands of operations; copies, seeding and sums a few dozen


# --------------------------------------------------------------------------- one tree, in its own process


def profile_objects(setting: str, objects: int, seed: int, lights: str) -> dict:
    """Runs in the tree under test (its modules first on sys.path): stage seconds of objects 0..N-1."""
    import drjit as dr

    from scenes.renderer.variant import choose_variant

    choose_variant("llvm_ad_rgb")
    dr.set_thread_count(1)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    import wildgen.writer as writer
    from wildgen.assets import AssetLibrary
    from wildgen.config import GenConfig

    s = SETTINGS[setting]
    cfg = GenConfig(lights=lights.split(","), objects=objects, images=s["images"], width=s["res"], height=s["res"],
                    spp=s["spp"], seed=seed)
    clock: dict[str, float] = {}
    kernels = {"compiled": 0, "from_disk": 0, "reused": 0}
    # While render_images renders an image: when its relighting ended, and when the first evaluation after it began.
    image: dict[str, float | None] = {}

    def timed(stage, fn):
        def wrapper(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                clock[stage] = clock.get(stage, 0.0) + time.perf_counter() - t0
        return wrapper

    real_eval = dr.eval

    def eval_spy(*args, **kwargs):
        if image.get("relit") is not None and image.get("traced") is None:
            image["traced"] = time.perf_counter()
        return real_eval(*args, **kwargs)

    from scenes.renderer.build import BuiltScene

    original_apply = BuiltScene.apply_image
    relight = timed("relighting", original_apply)

    def apply_image(built, index):
        if not image:  # building and the ground-truth pass relight too: theirs is their own stage
            return original_apply(built, index)
        relight(built, index)  # the update's own evaluations are relighting; tracing starts after it
        image.update(relit=time.perf_counter(), traced=None)

    def render_images(built, spp=None):
        import scenes.renderer.render as render

        images = []
        for i in range(len(built.desc.images)):
            dr.kernel_history()  # drop what came before
            relit_before = clock.get("relighting", 0.0)
            t0 = time.perf_counter()
            image.update(relit=None, traced=None)
            dr.eval = eval_spy
            try:
                images.append(render.render_image(built, i, spp=spp))
            finally:
                dr.eval = real_eval
            wall = time.perf_counter() - t0
            tracing_s = image["traced"] - image["relit"] if image["relit"] and image["traced"] else 0.0
            image.clear()
            history = dr.kernel_history()
            compile_s = sum(k.get("codegen_time", 0.0) + k.get("backend_time", 0.0) for k in history) / 1e3
            trace_s = 0.0
            for k in history:
                if (k.get("operation_count") or 0) >= BIG_KERNEL_OPS:
                    trace_s += k.get("execution_time", 0.0) / 1e3
                    kind = "reused" if k.get("cache_hit") and not k.get("cache_disk") else (
                        "from_disk" if k.get("cache_disk") else "compiled")
                    kernels[kind] += 1
            relit = clock.get("relighting", 0.0) - relit_before
            for stage, value in (("tracing", tracing_s), ("compiling", compile_s), ("path_tracing", trace_s),
                                 ("reduction", max(wall - relit - tracing_s - compile_s - trace_s, 0.0))):
                clock[stage] = clock.get(stage, 0.0) + value
        return images

    BuiltScene.apply_image = apply_image
    writer.sample_object = timed("sampling", writer.sample_object)
    writer.build_scene = timed("building", writer.build_scene)
    writer.render_ground_truth = timed("ground_truth", writer.render_ground_truth)
    writer.publish_folder = timed("publish", writer.publish_folder)
    writer.render_images = render_images
    lib = AssetLibrary.scan(cfg.assets)
    out = Path(tempfile.mkdtemp(prefix="bench_profile_"))
    rows = []
    try:
        for index in range(objects):
            clock.clear()
            kernels.update(compiled=0, from_disk=0, reused=0)
            t0 = time.perf_counter()
            entry = writer.make_object(cfg, index, out, lib)
            total = time.perf_counter() - t0
            if entry["status"] != "done":
                rows.append({"index": index, "status": entry["status"]})
                continue
            row = {stage: clock.get(stage, 0.0) for stage in STAGES if stage != "writing"}
            row["writing"] = entry["timings"]["write_s"] + clock.get("publish", 0.0)
            # sampling's wrapper sees only sample_object; the rest of make_object (localising assets) is building
            row["building"] += entry["timings"]["build_s"] - clock.get("building", 0.0)
            row.update(index=index, status="done", total_s=total, kernels=dict(kernels), files=entry["files"])
            rows.append(row)
    finally:
        shutil.rmtree(out, ignore_errors=True)
    return {"setting": setting, "objects": rows}


# --------------------------------------------------------------------------- side by side


def run_profile(tree: Path, setting: str, objects: int, seed: int, lights: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    code = (f"import sys, json; sys.path.insert(0, {str(tree)!r}); sys.path.insert(1, {str(REPO / 'bench')!r}); "
            f"import bench_profile as b; print(json.dumps(b.profile_objects({setting!r}, {objects}, {seed}, "
            f"{lights!r})))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tree, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"error: profiling {tree} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run_cli(tree: Path, setting: str, objects: int, seed: int, lights: str) -> tuple[float, dict]:
    """Wall seconds of `wildgen.make` in `tree` and the checksums of what it wrote."""
    s = SETTINGS[setting]
    out = Path(tempfile.mkdtemp(prefix="bench_profile_cli_")) / "ds"
    cmd = [sys.executable, "-m", "wildgen.make", "--out", str(out), "--objects", str(objects), "--res", str(s["res"]),
           "--images", str(s["images"]), "--spp", str(s["spp"]), "--seed", str(seed), "--lights", lights, "--quiet"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=tree, env=dict(os.environ, PYTHONPATH=str(tree)), capture_output=True, text=True)
    wall = time.perf_counter() - t0
    try:
        if proc.returncode != 0:
            raise SystemExit(f"error: wildgen.make in {tree} failed:\n{proc.stderr[-3000:]}")
        manifest = json.loads((out / "manifest.json").read_text())
        files = {e["name"]: e.get("files") for e in manifest["objects"]}
    finally:
        shutil.rmtree(out.parent, ignore_errors=True)
    return wall, files


def mean_stages(result: dict) -> dict:
    """Mean stage seconds over the objects after the first (the first pays for imports and the first compiles)."""
    done = [r for r in result["objects"] if r["status"] == "done"]
    steady = done[1:] or done
    out = {stage: sum(r[stage] for r in steady) / len(steady) for stage in STAGES}
    out["total_s"] = sum(r["total_s"] for r in steady) / len(steady)
    out["first_object_s"] = done[0]["total_s"] if done else None
    out["objects"] = len(steady)
    out["kernels"] = {
        k: sum(r["kernels"][k] for r in steady) / len(steady) for k in ("compiled", "from_disk", "reused")
    }
    return out


def baseline_tree(rev: str, where: Path) -> Path:
    tree = where / "baseline"
    proc = subprocess.run(["git", "worktree", "add", "--detach", str(tree), rev], cwd=REPO, capture_output=True,
                          text=True)
    if proc.returncode != 0:
        raise SystemExit(f"error: --baseline: cannot check out {rev!r}: {proc.stderr.strip()}")
    return tree


@dataclass
class Options:
    """The command line of bench/bench_profile.py."""

    baseline: Annotated[str | None, arg(metavar="REV")] = None
    """a git revision to profile side by side with this tree"""
    settings: Annotated[list[str], CommaList] = option(default_factory=lambda: list(SETTINGS),
                                                       choices=tuple(SETTINGS))
    """comma list of default, large"""
    objects: Annotated[int | None, arg(help_behavior_hint="(default: COUNTS)")] = option(None, minimum=1)
    """objects profiled per setting (the first is reported apart)"""
    rate_objects: Annotated[int | None, arg(help_behavior_hint="(default: COUNTS)")] = option(None, minimum=0)
    """objects of each wildgen.make run for objects per hour"""
    rounds: int = option(2, minimum=1)
    """wildgen.make runs per tree (alternating trees)"""
    lights: Annotated[list[str], CommaList] = option(default_factory=lambda: ["near_area"],
                                                     choices=tuple(LIGHT_FAMILIES))
    """light families of the profiled dataset"""
    seed: int = 7
    """wildgen seed of the profiled objects."""
    allow_different_bytes: bool = False
    """Go on when the baseline's files differ from this tree's (by default that stops the run)."""
    out: Annotated[str | None, arg(metavar="FILE")] = None
    """write the JSON here"""

COMMAND = Command(Options, prog="python bench/bench_profile.py", description=__doc__.splitlines()[0])
RESULT_KEYS = ("command", "lights", "rows")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    if args.baseline:
        check_revision(args.baseline)
    claim_result(args.out, RESULT_KEYS, COMMAND)
    settings, lights = args.settings, ",".join(args.lights)
    tmp = Path(tempfile.mkdtemp(prefix="bench_profile_trees_"))
    trees = {"this tree": REPO}
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True
    ).stdout.strip()
    revisions = {"this tree": head + ("+" if subprocess.run(["git", "diff", "--quiet", "HEAD"], cwd=REPO).returncode
                                      else "")}
    try:
        if args.baseline:
            trees = {"baseline": baseline_tree(args.baseline, tmp), **trees}
            revisions["baseline"] = subprocess.run(["git", "rev-parse", "--short", args.baseline], cwd=REPO,
                                                   capture_output=True, text=True).stdout.strip()
        rows = []
        for setting in settings:
            n_profile = args.objects or COUNTS[setting][0]
            n_rate = args.rate_objects or COUNTS[setting][1]
            stages, rates, checks = {}, {name: [] for name in trees}, {}
            for name, tree in trees.items():
                print(f"[{setting}] profiling {name} ({revisions[name]}) ...", flush=True)
                profiled = run_profile(tree, setting, n_profile, args.seed, lights)
                stages[name] = mean_stages(profiled)
                checks[name] = [r.get("files") for r in profiled["objects"]]
            walls = {name: [] for name in trees}
            for r in range(args.rounds if n_rate > SHORT_RUN else 0):
                for name, tree in trees.items():
                    short, _ = run_cli(tree, setting, SHORT_RUN, args.seed, lights)
                    wall, files = run_cli(tree, setting, n_rate, args.seed, lights)
                    rates[name].append((n_rate - SHORT_RUN) * 3600.0 / max(wall - short, 1e-9))
                    walls[name].append(wall)
                    checks[name].append(files)
                    print(f"[{setting}] wildgen.make {name} round {r + 1}: {SHORT_RUN} objects {short:.1f} s, "
                          f"{n_rate} objects {wall:.1f} s: {rates[name][-1]:.0f} objects/h", flush=True)
            same = checks["baseline"] == checks["this tree"] if args.baseline else None
            if same is False and not args.allow_different_bytes:
                raise SystemExit(f"error: [{setting}] the two trees wrote different bytes (object checksums differ); "
                                 "pass --allow-different-bytes when that is intended")
            for name in trees:
                rows.append({"setting": setting, **SETTINGS[setting], "tree": name, "revision": revisions[name],
                             "same_bytes_as_baseline": same,
                             **{k: round(v, 4) if isinstance(v, float) else v for k, v in stages[name].items()},
                             "objects_per_hour": round(sum(rates[name]) / len(rates[name]), 1) if rates[name] else None,
                             "run_objects": n_rate if rates[name] else None,
                             "run_objects_per_hour": round(n_rate * 3600.0 * len(walls[name]) / sum(walls[name]), 1)
                             if walls[name] else None})
    finally:
        if args.baseline:
            subprocess.run(["git", "worktree", "remove", "--force", str(tmp / "baseline")], cwd=REPO,
                           capture_output=True)
        shutil.rmtree(tmp, ignore_errors=True)
    header = (
        f"{'setting':8s} {'tree':10s} " + " ".join(f"{s[:9]:>9s}" for s in STAGES) + f" {'total':>7s} {'obj/h':>7s}"
    )
    print(header)
    for r in rows:
        print(f"{r['setting']:8s} {r['tree']:10s} " + " ".join(f"{r[s]:9.3f}" for s in STAGES)
              + f" {r['total_s']:7.2f} {r['objects_per_hour'] or 0:7.0f}")
    result = {"machine": machine(),
              "command": "python bench/bench_profile.py " + " ".join(sys.argv[1:]),
              "lights": lights, "seed": args.seed, "rows": rows}
    if args.out:
        write_result(Path(args.out), result, indent=1, newline=True)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
