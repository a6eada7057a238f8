"""Our normal integrator (`scenes.surface`) side by side with the reference implementation of Bilateral Normal
Integration (Cao et al., ECCV 2022), run from ../shared/reference/ in a throw-away environment this script makes,
and with plain least squares (ours with k = 0): depth error and whole-process time.

    python bench/bench_surface.py --work DIR [--out bench/results/surface.json]

Cases, each with ground-truth normals, mask and depth:
- DiLiGenT cat and pot2 (../shared/data/surface/, perspective, K.txt), scored in mm;
- renders of `wildgen.make` (held-out meshes when --assets has them), 256 px, scored in scene units (objects span
  about 1): `single_persp` single objects seen by a short lens (35 mm-equivalent focal 18-35 mm), `cluster_ortho`
  2-4 objects in front of each other (orthographic), `cluster_persp` 2-3 objects, focal 24-50 mm.

MADE (the field's score, over the mask pixels with a true depth): perspective, the estimate times the median of true /
estimated depth; orthographic (depth
in pixel widths), the estimate times the known pixel size plus the median offset; then the mean absolute difference
over the mask. `boundary`: the same mean over the pixels within 3 px of a true depth jump (a neighbour's depth more
than 2 % away). Times: each method runs all cases in one process, timed whole (start-up and imports included),
the reference with the settings of its own DiLiGenT evaluation (k = 2, 100 iterations, tolerance 1e-4); the
reference is also run to convergence (`CONVERGED`, not timed against ours).
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.cli_common import ROOT, check_work, claim_result, need_path, parse, refusals, run_main, write_result  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import REQUIRED, Command, option  # noqa: E402

SUITES = {
    "single_persp": ["--camera", "perspective", "--focal", "18-35", "--cluster", "1-1"],
    "cluster_ortho": ["--camera", "orthographic", "--cluster", "2-4"],
    "cluster_persp": ["--camera", "perspective", "--focal", "24-50", "--cluster", "2-3"],
}
"""The rendered families and their wildgen.make flags."""
REFERENCE_PACKAGES = ("numpy", "scipy", "numba", "tqdm", "pyvista")
"""What the reference imports (its requirements.txt, unpinned: the pinned 2021 versions do not build here)."""
MIN_PIXELS = 2000
RESULT_KEYS = ("command", "whole_process_seconds", "rows", "cases")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""
REFERENCE_MODULE = "bilateral_normal_integration_cpu.py"
"""The reference's module in --reference."""
"""Rendered objects smaller than this in the image are left out (too few pixels to integrate)."""


@dataclass
class SurfaceBenchOptions:
    """The command line of bench/bench_surface.py."""

    work: str = REQUIRED
    """Working folder: renders, cases, the reference's environment and outputs (reused when present)."""
    out: str = str(ROOT / "bench" / "results" / "surface.json")
    """Where the results go."""
    reference: str = str(ROOT.parent / "shared" / "reference" / "bilateral_normal_integration")
    """Folder of the reference implementation (bilateral_normal_integration_cpu.py)."""
    surface_data: str = str(ROOT.parent / "shared" / "data" / "surface")
    """DiLiGenT objects with ground-truth depth (<object>/normal_map.png, mask.png, K.txt, depth_gt.npz)."""
    assets: str = str(ROOT.parent / "shared" / "assets")
    """Assets for the renders."""
    objects: int = option(8, minimum=1)
    """Rendered objects per family."""
    seed: int = option(21000, minimum=0)
    """Seed of the renders."""


COMMAND = Command(SurfaceBenchOptions, prog="python bench/bench_surface.py",
                  description="Our normal integrator against the reference BiNI and least squares: MADE and time.")

# Runs inside the reference's throw-away environment: it imports the reference module from its folder (nothing is
# copied) and only NumPy; one process for all cases, as ours.
REFERENCE_DRIVER = """
import json, sys, time
from pathlib import Path
import numpy as np
sys.path.insert(0, sys.argv[1])
import bilateral_normal_integration_cpu as bini
cases, out = Path(sys.argv[2]), Path(sys.argv[3])
settings = (int(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6])) if len(sys.argv) > 4 else (100, 1e-4, 1e-3)
max_iter, tol, cg_tol = settings
out.mkdir(parents=True, exist_ok=True)
seconds = {}
for f in sorted(cases.glob("*.npz")):
    c = np.load(f)
    n = c["normals"][..., :3].astype(np.float64)
    k = c["K"] if c["K"].size else None
    t = time.perf_counter()
    depth, *_ = bini.bilateral_normal_integration(normal_map=n, normal_mask=c["mask"], k=2, K=k, max_iter=max_iter,
                                                  tol=tol, cg_tol=cg_tol)
    seconds[f.stem] = time.perf_counter() - t
    np.save(out / (f.stem + ".npy"), depth)
(out / "seconds.json").write_text(json.dumps(seconds))
"""

OURS_DRIVER = """
import json, sys, time
from pathlib import Path
import numpy as np
from scenes.surface.integrate import IntegrationConfig, Intrinsics, integrate
cases, out, k = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
out.mkdir(parents=True, exist_ok=True)
seconds = {}
for f in sorted(cases.glob("*.npz")):
    c = np.load(f)
    intr = Intrinsics.from_matrix(c["K"]) if c["K"].size else None
    t = time.perf_counter()
    s = integrate(c["normals"], c["mask"], intr, IntegrationConfig(k=k))
    seconds[f.stem] = time.perf_counter() - t
    np.save(out / (f.stem + ".npy"), s.depth)
(out / "seconds.json").write_text(json.dumps(seconds))
"""


def render(opts: SurfaceBenchOptions, work: Path) -> None:
    for name, flags in SUITES.items():
        if (work / "renders" / name / "manifest.json").is_file():
            continue
        cmd = [sys.executable, "-m", "wildgen.make", "--out", str(work / "renders" / name), "--objects",
               str(opts.objects), "--res", "256", "--images", "1", "--spp", "4", "--lights", "directional",
               "--seed", str(opts.seed), "--quiet", *flags]
        if Path(opts.assets).is_dir():
            cmd += ["--assets", opts.assets]
        print("+", " ".join(cmd), flush=True)
        subprocess.run(cmd, check=True, cwd=ROOT)


def rendered_case(folder: Path) -> dict | None:
    import numpy as np

    from scenes.images import read_exr, read_mask, read_normals

    scene = json.loads((folder / "scene.json").read_text())["camera"]
    mask = read_mask(folder / "mask.png")
    depth = read_exr(folder / "aux" / "depth.exr")
    depth = depth[..., 0] if depth.ndim == 3 else depth
    mask &= np.isfinite(depth) & (depth > 0)
    normals = read_normals(folder / "aux" / "normal.exr").astype(np.float64)
    mask &= normals[..., 2] > 0  # the few grazing pixels of the render's antialiased outline
    if mask.sum() < MIN_PIXELS:
        return None
    h, w = mask.shape
    k = np.zeros((0, 0))
    if scene["kind"] == "perspective":
        f = (w / 2) / np.tan(np.radians(scene["fov"]) / 2)  # fov is horizontal; pixel centres at integers
        k = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])
    pixel_size = 0.0 if k.size else 2 * scene["half_size"] / w  # 0: perspective, scored up to scale
    return {"normals": normals, "mask": mask, "K": k, "depth": np.where(mask, depth, np.nan), "pixel_size": pixel_size}


def diligent_case(folder: Path) -> dict:
    import numpy as np

    from scenes.images import read_mask, read_normals

    mask = read_mask(folder / "mask.png")
    normals = read_normals(folder / "normal_map.png").astype(np.float64)
    normals /= np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), 1e-12)
    depth = np.load(folder / "depth_gt.npz")["depth_gt"].astype(np.float64)  # NaN where unknown: not scored
    return {"normals": normals, "mask": mask, "K": np.loadtxt(folder / "K.txt"), "depth": depth, "pixel_size": 0.0}


def write_cases(opts: SurfaceBenchOptions, work: Path) -> dict[str, str]:
    """Every case as CASES/<family>-<name>.npz; returns name -> family."""
    import numpy as np

    cases = work / "cases"
    cases.mkdir(parents=True, exist_ok=True)
    family = {}
    items = [("diligent", p.name, lambda p=p: diligent_case(p))
             for p in sorted(Path(opts.surface_data).glob("*")) if (p / "depth_gt.npz").is_file()]
    for name in SUITES:
        found = sorted((work / "renders" / name).glob("*.data"))
        items += [(name, p.stem, lambda p=p: rendered_case(p)) for p in found]
    for fam, obj, load in items:
        case = load()
        if case is None:
            continue
        key = f"{fam}-{obj}"
        family[key] = fam
        np.savez(cases / f"{key}.npz", **case)
    return family


def reference_python(work: Path) -> Path:
    env = work / "reference_env"
    py = env / "bin" / "python"
    if not py.is_file():
        print(f"making the reference's throw-away environment in {env} ...", flush=True)
        subprocess.run([sys.executable, "-m", "venv", str(env)], check=True)
        subprocess.run([str(py), "-m", "pip", "install", "-q", *REFERENCE_PACKAGES], check=True)
    return py


def timed(cmd: list[str], log: Path, env: dict | None = None) -> float:
    """Seconds of one whole process; its output goes to `log` (the reference draws progress bars)."""
    t = time.perf_counter()
    with open(log, "w") as f:
        subprocess.run(cmd, check=True, cwd=ROOT, env=env, stdout=f, stderr=subprocess.STDOUT)
    return time.perf_counter() - t


def made(est, gt, mask, pixel_size, sel=None):
    import numpy as np

    mask = mask & np.isfinite(gt)  # every mask pixel is integrated; those with a true depth are scored
    sel = mask if sel is None else sel & mask
    if pixel_size:  # orthographic: known pixel size, unknown offset
        e = est * pixel_size
        e = e + np.median(gt[mask] - e[mask])
    else:
        e = est * np.median(gt[mask] / est[mask])
    return float(np.mean(np.abs(e[sel] - gt[sel]))) if sel.any() else None


def jump_band(gt, mask, rel=0.02, width=3):
    """Mask pixels within `width` px of a true depth jump (neighbours more than `rel` apart in depth)."""
    import numpy as np
    from scipy.ndimage import binary_dilation

    g = np.where(mask, gt, np.nan)
    jump = np.zeros(mask.shape, bool)
    for a, b, sl_a, sl_b in ((g[:, :-1], g[:, 1:], np.s_[:, :-1], np.s_[:, 1:]),
                             (g[:-1, :], g[1:, :], np.s_[:-1, :], np.s_[1:, :])):
        j = np.abs(a - b) > rel * np.minimum(a, b)
        jump[sl_a] |= j
        jump[sl_b] |= j
    return binary_dilation(jump, iterations=width) & mask


METHODS = ("ours", "reference", "reference_converged", "least_squares")
CONVERGED = ("150", "1e-7", "1e-6")
"""The reference run to convergence (max_iter, relative energy tolerance, CG tolerance): with its own DiLiGenT settings
the inner solves are loose (Jacobi CG to 1e-3), and their depth differs from the solution of its model (bench output
`reference_converged`; on cat 0.074 against 0.104, the same 0.074 after 60 reweightings of loose solves)."""


def summary_rows(cases: list[dict]) -> list[dict]:
    """The docs' rows: every DiLiGenT object alone, then each rendered family's means (all pixels, near jumps)."""
    def mean(sel, method, key):
        vals = [r[method][key] for r in sel if r[method][key] is not None]
        return round(sum(vals) / len(vals), 4) if vals else None

    groups = [(r["case"] + " (mm)", [r]) for r in cases if r["family"] == "diligent"]
    groups += [(fam, [r for r in cases if r["family"] == fam]) for fam in SUITES]
    return [{"cases": name, "count": len(sel), **{m: mean(sel, m, "made") for m in METHODS},
             **{f"{m}_near_jumps": mean(sel, m, "made_boundary") for m in METHODS}} for name, sel in groups if sel]


def main(argv: list[str] | None = None) -> int:
    import os

    import numpy as np

    opts = parse(COMMAND, argv)
    check_work(opts.work, inputs={"--assets": opts.assets, "--surface-data": opts.surface_data,
                                  "--reference": opts.reference})
    with refusals():
        if not (Path(opts.reference) / REFERENCE_MODULE).is_file():
            raise UsageError(f"--reference: {opts.reference!r} holds no {REFERENCE_MODULE}; expected the folder of "
                             "the reference implementation of Bilateral Normal Integration")
    need_path(opts.surface_data, "--surface-data", "a folder of DiLiGenT objects with depth_gt.npz")
    claim_result(opts.out, RESULT_KEYS, COMMAND)
    work = Path(opts.work)
    work.mkdir(parents=True, exist_ok=True)
    render(opts, work)
    family = write_cases(opts, work)
    py = reference_python(work)
    (work / "reference_driver.py").write_text(REFERENCE_DRIVER)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(work / "numba_cache")}
    reference = [str(py), str(work / "reference_driver.py"), opts.reference, str(work / "cases")]
    # Numba compiles once into its cache; the timed run loads it, as a user's second run does.
    timed(reference + [str(work / "warm")], work / "reference_warm.log", env)
    ours = [sys.executable, "-c", OURS_DRIVER, str(work / "cases")]
    whole = {
        "reference": timed(reference + [str(work / "out_reference")], work / "reference.log", env),
        "ours": timed(ours + [str(work / "out_ours"), "2"], work / "ours.log"),
        "least_squares": timed(ours + [str(work / "out_ls"), "0"], work / "least_squares.log"),
    }
    timed(reference + [str(work / "out_reference_converged"), *CONVERGED], work / "reference_converged.log", env)
    rows = []
    for key, fam in family.items():
        c = np.load(work / "cases" / f"{key}.npz")
        band = jump_band(c["depth"], c["mask"])
        row = {"case": key, "family": fam, "pixels": int(c["mask"].sum()), "boundary_pixels": int(band.sum())}
        for method, folder in (("ours", "out_ours"), ("reference", "out_reference"),
                               ("reference_converged", "out_reference_converged"), ("least_squares", "out_ls")):
            est = np.load(work / folder / f"{key}.npy")
            secs = json.loads((work / folder / "seconds.json").read_text())[key]
            row[method] = {"made": made(est, c["depth"], c["mask"], float(c["pixel_size"])),
                           "made_boundary": made(est, c["depth"], c["mask"], float(c["pixel_size"]), band),
                           "seconds": round(secs, 3)}
        rows.append(row)
        print(f"{key:28s} MADE ours {row['ours']['made']:.4f}  reference {row['reference']['made']:.4f}  "
              f"least squares {row['least_squares']['made']:.4f}", flush=True)
    # the renders' own assets (reused renders keep those they were made with, whatever --assets says now)
    made_with = {json.loads((work / "renders" / name / "manifest.json").read_text())["config"].get("assets")
                 for name in SUITES}
    result = {"command": "python bench/bench_surface.py --work WORK", "assets": ", ".join(sorted(map(str, made_with))),
              "objects": opts.objects,
              "seed": opts.seed, "whole_process_seconds": whole,
              "rows": summary_rows(rows), "cases": rows, "machine": f"{os.cpu_count()} cores"}

    write_result(opts.out, result, indent=1)
    print(f"whole processes: ours {whole['ours']:.1f} s, reference {whole['reference']:.1f} s; wrote {opts.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
