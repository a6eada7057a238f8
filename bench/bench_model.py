"""Model benchmark: parameter counts, CPU inference time and peak memory, glc-tiny training step.

Each timed case runs in its own subprocess so its peak RSS (VmHWM) is its own. Inputs are random
(random weights, random images) with a disk mask covering about 70 % of the square crop, like a
preprocessed object. Usage:

    python bench/bench_model.py              # full table (glc-unips, the published network, at 256 and 512: minutes)
    python bench/bench_model.py --quick      # glc-tiny / glc-test only
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.cli_common import parse, run_main  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import Command, arg, check_fields, option  # noqa: E402

CASES = {"infer": ("MODEL", "RES", "K"), "train": ("RES", "K", "BATCH", "PIXELS")}
"""The cases a subprocess of this script times (--case): kind -> its values, each a whole number >= 1 but MODEL (one
of `unips.models.list_models`)."""


def check_case(case: list[str]) -> None:
    """A UsageError naming --case unless `case` is one of `CASES` with its values."""
    form = " or ".join(f"{kind} {' '.join(values)}" for kind, values in CASES.items())
    values = CASES.get(case[0]) if case else None
    if values is None or len(case) != len(values) + 1:
        raise UsageError(f"--case: got {' '.join(case)!r}, expected {form}")
    for name, value in zip(values, case[1:]):
        if name == "MODEL":
            from unips.models import list_models

            if value not in list_models():
                raise UsageError(f"--case: got model {value!r}, expected one of {', '.join(list_models())}")
        elif not value.isdigit() or int(value) < 1:
            raise UsageError(f"--case: got {name} {value!r}, expected a whole number >= 1 ({form})")


def _status_mib(key: str) -> float:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith(key + ":")) / 1024


def _disk_mask(res: int):
    import torch

    yy, xx = torch.meshgrid(torch.arange(res), torch.arange(res), indexing="ij")
    c = res / 2 - 0.5
    return (((yy - c) ** 2 + (xx - c) ** 2) < (0.47 * res) ** 2).float()[None, None]  # (1, 1, R, R)


def run_inference_case(name: str, res: int, k: int, threads: int) -> dict:
    """One forward pass of `name` on (1, k, 3, res, res); time split into encoder and total."""
    import torch

    from unips.models import create_model

    torch.set_num_threads(threads)
    torch.manual_seed(0)
    model = create_model(name).eval()
    images = torch.rand(1, k, 3, res, res)
    mask = _disk_mask(res)
    with torch.no_grad():
        model(images[..., :32, :32], mask[..., :32, :32])  # warm-up (kernels, allocator)
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # reset VmHWM to the current RSS
    base = _status_mib("VmRSS")
    with torch.no_grad():
        t0 = time.perf_counter()
        model.encode(images, mask)
        t1, c1 = time.perf_counter(), time.process_time()
        model(images, mask)  # encodes again, then decodes in chunks
        t2, c2 = time.perf_counter(), time.process_time()
    return {"model": name, "res": res, "k": k, "pixels": int(mask.sum()), "encode_s": t1 - t0,
            "forward_s": t2 - t1, "forward_cpu_s": c2 - c1, "peak_rss_mib": _status_mib("VmHWM"),
            "extra_peak_mib": _status_mib("VmHWM") - base, "threads": threads}


def run_train_case(res: int, k: int, batch: int, pixels: int, threads: int, steps: int = 5) -> dict:
    """Seconds per optimisation step of glc-tiny on random data (k images per object)."""
    import numpy as np
    import torch

    from unips.models import create_model
    from unips.train_data import Sample, make_batch, normal_loss

    torch.set_num_threads(threads)
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    mask = _disk_mask(res)[0]
    samples = []
    for i in range(batch):
        n = torch.nn.functional.normalize(torch.randn(3, res, res) + torch.tensor([0, 0, 2.0])[:, None, None], dim=0)
        samples.append(Sample(f"o{i}", torch.from_numpy(rng.random((k, 3, res, res), dtype=np.float32)).half(),
                              mask, n * mask, None))
    model = create_model("glc-tiny")
    opt = torch.optim.AdamW(model.parameters(), lr=1e-4)
    times, cpu = [], []
    for step in range(steps + 1):
        t0, c0 = time.perf_counter(), time.process_time()
        b = make_batch(samples, step, seed=0, batch=batch, min_images=k, max_images=k, pixels=pixels,
                       canonical=model.config.canonical_resolution)
        pred = model.decode_pixels(model.encode(b.images, b.mask), b.images, b.mask, b.coords)
        loss, _ = normal_loss(pred, b)
        opt.zero_grad()
        loss.backward()
        opt.step()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return {"model": "glc-tiny", "res": res, "k": k, "batch": batch, "pixels": pixels,
            "step_s_median": float(np.median(times[1:])), "step_cpu_s_median": float(np.median(cpu[1:])),
            "threads": threads}


def _sub(args: list[str]) -> dict:
    out = subprocess.run([sys.executable, __file__, *args], cwd=REPO, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@dataclass
class Options:
    """The command line of bench/bench_model.py."""

    quick: bool = False
    """skip glc-unips inference"""
    threads: Annotated[int, arg(help_behavior_hint="(default: one per core)")] = option(
        os.cpu_count() or 1, minimum=1
    )
    """CPU threads of inference and training."""
    images: int = option(16, minimum=1)
    """Images of the glc-unips and glc-tiny inference cases."""
    case: Annotated[list[str] | None, arg(metavar="CASE")] = None
    """internal: the one case a subprocess of this script times (infer MODEL RES K, or train RES K BATCH PIXELS)"""

    def validate(self) -> "Options":
        check_fields(self)
        if self.case is not None:
            check_case(self.case)
        return self


COMMAND = Command(Options, prog="python bench/bench_model.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    a = parse(COMMAND, argv)
    if a.case:
        if a.case[0] == "infer":
            print(json.dumps(run_inference_case(a.case[1], int(a.case[2]), int(a.case[3]), a.threads)))
        else:
            print(json.dumps(run_train_case(*(int(v) for v in a.case[1:5]), threads=a.threads)))
        return 0

    from unips.models import create_model, list_models

    print("parameters")
    for name in list_models():
        print(f"  {name:10s} {create_model(name).num_parameters():>12,d}")
    # (model, resolution, images): the issue-12 budgets are 10 images at 256 px (< 10 s) and a DiLiGenT
    # object (96 images; its mask's square crop is about 400 px) (< 60 s).
    cases = [("glc-tiny", 256, a.images), ("glc-tiny", 512, a.images), ("glc-small", 256, 10), ("glc-small", 400, 96)]
    if not a.quick:
        cases = [("glc-unips", 256, a.images), ("glc-unips", 512, a.images)] + cases
    print(f"\nload average before: {os.getloadavg()[0]:.2f} (the machine may be shared: compare CPU s)")
    print(f"\ninference, disk mask, {a.threads} threads, random weights")
    print(
        f"  {'model':10s} {'res':>5s} {'images':>6s} {'pixels':>8s} {'encode s':>9s} {'forward s':>10s} {'CPU s':>8s} "
        f"{'peak RSS MiB':>13s} {'extra MiB':>10s}"
    )
    for name, res, k in cases:
        r = _sub(["--threads", str(a.threads), "--case", "infer", name, str(res), str(k)])
        print(f"  {name:10s} {res:5d} {k:6d} {r['pixels']:8d} {r['encode_s']:9.2f} {r['forward_s']:10.2f} "
              f"{r['forward_cpu_s']:8.1f} {r['peak_rss_mib']:13.0f} {r['extra_peak_mib']:10.0f}", flush=True)
    print(f"\ntraining step, glc-tiny, batch 4, 2500 random pixels, {a.threads} threads")
    print(f"  {'res':>5s} {'images':>7s} {'s/step':>8s} {'CPU s/step':>11s}")
    for res, k in [(64, 8), (64, 4), (128, 8)]:
        r = _sub(["--threads", str(a.threads), "--case", "train", str(res), str(k), "4", "2500"])
        print(f"  {res:5d} {k:7d} {r['step_s_median']:8.3f} {r['step_cpu_s_median']:11.3f}", flush=True)
    print(f"\nload average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
