"""One command for a short session on a GPU machine: render, check the variant, write shards, train, bring back.

    python -m orchestrate.gpu_session --pack .carry --wheels .whl      (here, before the session: Mitsuba,
                                                                       the wheels and the training assets)
    python -m orchestrate.gpu_session --carry .carry --init shipped --out $OUT --minutes 9 --objects 300
                                                                      (on the GPU machine)
    python -m orchestrate.ship --candidate OUT --val VAL               (here, after: ship or not, by rule)

Made for a machine that has torch and timm but no Mitsuba and no internet, whose commands run at most 10
minutes and whose folder `--out` comes back (at most 8 files). On a machine where torch sees no GPU it stops at
once (one line, exit 2) unless `--cpu-rehearsal` asks for a small run of the whole session on the CPU. In
`--minutes` of wall time, counted from the command's start (`scenes.cli.budget`), it:

1. renders `--objects` objects with `wildgen.make` (seed `--seed`, the pack's training assets) into `--work`,
   with the first usable variant of cuda_ad_rgb, llvm_ad_rgb (`--variant auto`; the log and summary.json say which);
2. renders the first `--check-objects` of them again with `--check-variant` (auto: llvm_ad_rgb when it runs
   here, else scalar_rgb) on one CPU core and compares them: variant_check.json (`compare_datasets`), with the
   seconds per object and objects per hour of both renders (`render_speed`);
3. writes the dataset as WebDataset shards of the reader's decoded arrays (`wildgen.make --shards
   --shard-encoding decoded`, the fastest to train on);
4. trains `--model` with `unips.train` on the shards (bf16 autocast on CUDA), from `--init` (the shipped
   weights or a previous run's, never from scratch when given; another architecture is refused), saving last.pt every
   `--ckpt-minutes` into `--out`/run and stopping before the budget (`--time-limit` of unips.train);
5. writes the learning curve (learning_curve.png from run/log.jsonl), model_card.json (a fragment for the
   model card: data, steps, time, hardware) and summary.json.

The budget holds whatever the stage: a budget not above `--reserve-s` is refused before anything runs; each
stage starts only while more than the reserve is left, a render still running when only the reserve is left is
stopped (what it finished stays in --work, and the same command resumes it), training stops itself before
that (`unips.train --time-limit`), and the reserve is kept for the files that follow; a stage stopped by the
budget is one line naming --minutes (exit 2).

What comes back: run/log.jsonl, run/last.pt, run/final.safetensors (+ final.json, loaded by
`unips.models.create_model(NAME, checkpoint_path=...)`), learning_curve.png, variant_check.json,
model_card.json, summary.json. Mitsuba and Dr.Jit travel as `--pack`'s site.tar.xz (docs/model.md).
"""
from __future__ import annotations

import sys

if __name__ == "__main__":  # the pack's packages first: the imports below need tyro, which travels in --carry
    from orchestrate.relay import boot_site

    boot_site(sys.argv[1:])

import json
import math
import os
import platform
import time
from contextlib import nullcontext
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Literal  # noqa: E402

from orchestrate import relay
from orchestrate.curve import curve_records, plot_curve
from orchestrate.relay import REPO, SITE_ARCHIVE, UPLOAD_LIMIT, pack, resolve_init, tree_bytes, unpack_carry  # noqa: F401
from orchestrate.steps import OutOfTime, StepFailed, check_step, run_step
from scenes.cli.budget import process_start
from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.needs import Needs
from scenes.cli.options import Command, check_fields, option
from scenes.cli.outputs import check_output_folder, output_lock
from scenes.files import is_within, read_json, write_json

SHARED_ASSETS = REPO.parent / "shared" / "assets"
RUN = "run"
WORK_FOLDERS = ("site", "assets", "data", "check", "shards")
"""What the session writes in --work: the pack's site and assets, the dataset, the check's renders, the shards."""
CHECK_VARIANTS = ("llvm_ad_rgb", "scalar_rgb")
"""The check's variants in auto's order (the first that runs here and differs from the render's)."""


@dataclass
class SessionOptions:
    """The command line of orchestrate.gpu_session."""

    out: str = option("")
    """Folder that comes back ($OUT): run/ (log.jsonl, last.pt, final.safetensors + .json), learning_curve.png,
    variant_check.json, model_card.json, summary.json."""
    work: str = "/tmp/gpu_session"
    """Scratch folder of the rendered dataset, the check's renders and the shards (not brought back)."""
    minutes: float = option(9.0, above=0)
    """Wall-time budget of the whole command; training stops so that everything is written before it."""
    reserve_s: float = option(45.0, minimum=0)
    """Seconds of the budget kept for what follows the training steps (its start-up, the last files)."""
    objects: int = option(300, minimum=1)
    """Objects to render."""
    images: int = option(10, minimum=3)
    """Images per object (at least 3: with fewer lights no normal is determined, nothing photometric to learn)."""
    res: int = option(128, minimum=8)
    """Square resolution of the renders (and the training resolution)."""
    spp: int = option(32, minimum=1)
    """Samples per pixel of the images."""
    seed: int = option(5000, minimum=0)
    """Seed of the dataset (object i draws from (seed, i))."""
    variant: Literal["auto", "cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb"] = "auto"
    """Render variant; auto: cuda_ad_rgb when it runs here, else llvm_ad_rgb (else scalar_rgb, with a warning)."""
    check_variant: Literal["auto", "none", "cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb"] = "auto"
    """Variant of the check's second render; auto: llvm_ad_rgb when it runs here, else scalar_rgb; none: no check."""
    check_objects: int = option(3, minimum=1)
    """Objects rendered again for the check (all of them where --objects is fewer)."""
    noise_cv: float = option(4.0, above=0)
    """Assumed coefficient of variation of one path-traced sample: images agree when the relative RMS difference
    of two renders is at most noise_cv * sqrt(2 / spp)."""
    model: str | None = None
    """Registered model to train (`unips.models.list_models()`; default: the --init weights' model, else
    unips.models.DEFAULT_TRAIN_MODEL)."""
    init: str | None = None
    """Weights to continue from: `shipped` (the registry's shipped weights) or a previous run's final.safetensors /
    last.pt; their model must be the shipped architecture (refused in one line otherwise). Default: fresh weights."""
    steps: int = option(20000, minimum=1)
    """Length of the learning-rate schedule; the run stops earlier when the budget ends."""
    batch: int = option(16, minimum=1)
    """Objects per training step."""
    lr: float = option(1e-3, above=0)
    """Peak learning rate."""
    log_every: int = option(10, minimum=1)
    """Steps between records of the learning curve."""
    ckpt_minutes: float = option(1.0, above=0)
    """Minutes between saves of run/last.pt in --out."""
    device: Literal["auto", "cuda", "cpu"] = "auto"
    """Training device; auto: cuda when torch sees a GPU. On cuda the forward pass runs under bf16 autocast."""
    cpu_rehearsal: bool = False
    """Run on a machine where torch sees no GPU: a rehearsal of the whole session on the CPU (llvm_ad_rgb, torch
    on the CPU), within --minutes like a real session; give it small --objects, --res and --spp. Without it such
    a machine is refused at once."""
    overwrite: bool = False
    """Replace an earlier session's dataset, shards and run in --work / --out (with --pack: an earlier pack's
    archives and manifest.json)."""
    carry: str | None = None
    """Folder written by --pack (carried to the GPU machine): its site.tar.xz is unpacked into --work and put on
    the path, its assets.tar.xz unpacked and rendered with."""
    assets: str | None = None
    """Asset folder: with --pack, the one whose training split is packed (default ../shared/assets when it exists;
    `none`: no assets); in a session, the one rendered with (default: --carry's packed assets, else none)."""
    pack: str | None = None
    """Instead of a session: write what must be carried into this folder (site.tar.xz from --wheels) and check
    the upload limit."""
    wheels: str = ".whl"
    """With --pack: folder of the Python 3.12 x86-64 wheels of mitsuba, drjit and the packages the GPU machine
    lacks (docs/model.md gives the pip download command)."""

    def validate(self) -> "SessionOptions":
        check_fields(self)
        if self.pack is not None:  # packing writes the carry folder only: a session's flag would be ignored
            from dataclasses import fields

            given = next((f.name for f in fields(self) if f.name not in PACK_FLAGS and getattr(self, f.name) != (
                f.default_factory() if callable(f.default_factory) else f.default)), None)
            if given is not None:
                raise ValueError(f"--{given.replace('_', '-')}: a session's flag, not used with --pack (which only "
                                 "writes the carry folder); give it to the session that carries the folder")
        else:
            if self.minutes * 60 <= self.reserve_s:
                raise ValueError(f"--minutes: {self.minutes:g} min ({self.minutes * 60:g} s) is not above --reserve-s "
                                 f"{self.reserve_s:g} s (expected a budget above the seconds kept for the last files)")
            if not self.out:
                raise ValueError("--out: required (the folder that comes back), or --pack DIR")
            check_output_folder(self.out)
            check_output_folder(self.work, "--work")
            if is_within(self.out, self.work) or is_within(self.work, self.out):  # the session's files would mix
                raise ValueError(f"--work: {self.work!r} overlaps --out {self.out!r}; expected two separate folders "
                                 "(--out comes back whole, --work stays on the machine)")
            for flag, folder in (("--out", self.out), ("--work", self.work)):  # the session writes into both
                if self.carry and (is_within(folder, self.carry) or is_within(self.carry, folder)):
                    raise ValueError(f"{flag}: {folder!r} overlaps --carry {self.carry!r}; expected a folder apart "
                                     "from the pack (the session's files would mix with what was carried)")
            for flag, given in (("--init", self.init), ("--assets", self.assets)):  # read, in what is replaced
                if given not in (None, "none", "shipped") and (inside := next((n for n in WORK_FOLDERS if is_within(
                        given, Path(self.work) / n)), None)):
                    raise ValueError(f"{flag}: {given!r} lies inside --work's {inside}/, which the session writes "
                                     "(--overwrite empties it); expected a path outside it")
        return self


# ---------------------------------------------------------------- the variant check


def compare_datasets(main: Path, check: Path, names: list[str], spp: int, noise_cv: float) -> dict:
    """Compare the object folders `names` rendered in `main` and again in `check` (another variant, same seed).

    Ground truth: mask and normal map equal bit for bit ('identical'), or else where they differ. Two variants
    draw different sub-pixel samples unless they share the sampler's order (the JIT variants), and the ground
    truth of a pixel is an average over its footprint, so masks can differ on the outline only and normals by
    a footprint's spread: reported as mask pixels off the outline (must be 0) and the angle between normals on
    pixels away from it. Images: the relative RMS difference of linear values inside the mask against
    noise_cv * sqrt(2 / spp), the Monte-Carlo noise of the difference of two independent renders."""
    import cv2
    import numpy as np

    from scenes.folder.layouts import read_folder
    from scenes.metrics import angles_deg

    tol = noise_cv * math.sqrt(2.0 / spp)
    objects = []
    for name in names:
        a, b = read_folder(main / name, arg="--work"), read_folder(check / name, arg="--work")
        kernel = np.ones((3, 3), np.uint8)
        m = a.mask.astype(np.uint8)
        outline = cv2.dilate(m, kernel).astype(bool) & ~cv2.erode(m, kernel).astype(bool)
        differ = a.mask != b.mask
        inner = cv2.erode((a.mask & b.mask).astype(np.uint8), kernel).astype(bool)
        ang = angles_deg(a.normals[inner], b.normals[inner]) if inner.any() else np.zeros(1)
        ia, ib = a.linear()[:, inner], b.linear()[:, inner]
        scale = float((ia + ib).mean() / 2) or 1.0
        rel_rms = float(np.sqrt(((ia - ib) ** 2).mean()) / scale)
        identical = bool(np.array_equal(a.mask, b.mask) and np.array_equal(a.normals, b.normals))
        objects.append({
            "name": name, "ground_truth_identical": identical,
            "mask_pixels": int(a.mask.sum()), "mask_differing": int(differ.sum()),
            "mask_differing_off_outline": int((differ & ~outline).sum()),
            "normal_angle_deg_mean": round(float(ang.mean()), 4), "normal_angle_deg_max": round(float(ang.max()), 4),
            "image_rel_rms": round(rel_rms, 4), "images_within_noise": rel_rms <= tol,
        })
    return {
        "objects": objects,
        "ground_truth_identical": all(o["ground_truth_identical"] for o in objects),
        "masks_differ_only_on_outline": all(o["mask_differing_off_outline"] == 0 for o in objects),
        "images_within_noise": all(o["images_within_noise"] for o in objects),
        "image_tolerance_rel_rms": round(tol, 4), "spp": spp, "noise_cv": noise_cv,
    }


def render_speed(folder: Path, wall_s: float | None = None) -> dict:
    """Seconds per object of a wildgen.make run (the median of its manifest's per-object `total_s`, so a first
    object's compiles do not count) and the objects per hour that makes for one worker; with `wall_s`, also the
    run's own objects per hour (start-up and every worker included)."""
    import statistics

    done = [e for e in json.loads((folder / "manifest.json").read_text())["objects"] if e.get("status") == "done"]
    per = statistics.median(e["timings"]["total_s"] for e in done) if done else float("nan")
    out = {"objects": len(done), "seconds_per_object": round(per, 3),
           "objects_per_hour_one_worker": round(3600 / per, 1)}
    if wall_s:
        out["objects_per_hour_run"] = round(len(done) * 3600 / wall_s, 1)
    return out


# ---------------------------------------------------------------- the session (on the GPU machine)


def missing_mitsuba() -> str | None:
    """None when Mitsuba and Dr.Jit import here, else the one line that says what to carry."""
    try:
        import drjit  # noqa: F401
        import mitsuba  # noqa: F401
    except ImportError as exc:
        return (f"Mitsuba is not importable here ({exc}): carry it: here run `python -m orchestrate.gpu_session "
                "--pack .carry --wheels .whl`, then on the GPU machine carry .carry and unpack .carry/site.tar.xz into "
                "a folder on PYTHONPATH first (docs/model.md, 'Training on a GPU session')")
    return None


def _choose(requested: str, avoid: str | None = None, flag: str = "--variant") -> str:
    from scenes.renderer.variant import choose_variant

    if requested != "auto":
        try:
            return choose_variant(requested)
        except ValueError as exc:  # named by the flag given
            raise UsageError(str(exc).replace("--variant:", f"{flag}:", 1)) from None
    why = []
    for v in (v for v in (CHECK_VARIANTS if avoid else ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")) if v != avoid):
        try:
            return choose_variant(v)
        except (ValueError, RuntimeError) as exc:
            why.append(str(exc).removeprefix("--variant: "))
    raise UsageError(("--check-variant: no variant other than the render's runs here" if avoid
                      else "--variant: no Mitsuba variant runs here") + (f" ({why[0]})" if why else ""))


def _make_argv(opts: SessionOptions, out: Path, variant: str, objects: int, shards: Path | None,
               assets: str | None = None) -> list[str]:
    return [*(["--assets", assets] if assets else []), "--objects", str(objects), "--images", str(opts.images),
            "--res", str(opts.res), "--spp", str(opts.spp), "--seed", str(opts.seed), "--variant", variant,
            "--out", str(out), "--quiet",
            *(["--shards", str(shards), "--shard-encoding", "decoded"] if shards else []),
            *(["--overwrite"] if opts.overwrite else [])]


def _train_argv(opts: SessionOptions, shards: Path, run: Path, device: str, minutes: float,
                init: str | None = None) -> list[str]:
    return ["--data", str(shards), "--out", str(run), *(["--init-from", init] if init else ["--model", opts.model]),
            "--steps", str(opts.steps), "--batch", str(opts.batch), "--lr", str(opts.lr), "--res", str(opts.res),
            "--max-images", str(opts.images), "--device", device, "--precision", "bf16" if device == "cuda" else "fp32",
            "--ckpt-minutes", str(opts.ckpt_minutes), "--time-limit", f"{minutes:.4f}",
            "--log-every", str(opts.log_every), "--seed", "0", "--no-progress",
            *(["--overwrite"] if opts.overwrite else [])]


def _device(requested: str) -> str:
    import torch

    if requested == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if requested == "cuda" and not torch.cuda.is_available():
        raise UsageError("--device: 'cuda' but torch sees no GPU here")
    return requested


def require_gpu(opts: SessionOptions) -> None:
    """A machine where torch sees no GPU runs the session only as --cpu-rehearsal: UsageError at once otherwise."""
    import torch

    if not opts.cpu_rehearsal and not torch.cuda.is_available():
        raise UsageError(f"--device: {opts.device!r}, but torch sees no GPU here (expected a GPU machine: the session "
                         "renders and trains for --minutes; pass --cpu-rehearsal for a small rehearsal on the CPU)")


def _checked(opts: SessionOptions, packed: Path | None, paths: tuple[Path, Path, Path], device: str,
             init: str | None) -> tuple[str | None, str, str | None]:
    """The flags that need the carried packages (Mitsuba's variants, the steps' own checks): a refusal here
    leaves nothing of --carry unpacked. Returns the assets, the variant and the check variant."""
    data, shards, run = paths
    assets = None if opts.assets == "none" else opts.assets or (str(packed) if packed else None)  # 'none': none
    if why := missing_mitsuba():
        raise UsageError(why)
    variant = _choose(opts.variant)
    check = None if opts.check_variant == "none" else _choose(opts.check_variant, avoid=variant) \
        if opts.check_variant == "auto" else _choose(opts.check_variant, flag="--check-variant")
    if check is not None and check == variant:  # the same variant renders the same bytes: that checks nothing
        raise UsageError(f"--check-variant: {check} is the variant the data is rendered with (--variant "
                         f"{opts.variant}), expected another variant (or none): comparing a variant with itself "
                         "checks nothing")
    check_step("wildgen.make", _make_argv(opts, data, variant, opts.objects, shards, assets))
    check_step("unips.train", _train_argv(opts, shards, run, device, 1.0, init))
    return assets, variant, check


def session(opts: SessionOptions, t0: float | None = None) -> dict:
    """The whole session (module doc, steps 1-5); returns summary.json's content. `t0`: when the budget started
    (default: this process's start). --out and --work are held for the whole session
    (`scenes.cli.outputs.output_lock`: a second session into either is refused)."""
    t0 = process_start() if t0 is None else t0
    same = os.path.realpath(opts.out) == os.path.realpath(opts.work)  # one folder for both: held once
    with output_lock(opts.out, "--out"), nullcontext() if same else output_lock(opts.work, "--work"):
        return _session(opts, t0)


def _session(opts: SessionOptions, t0: float) -> dict:
    """`session` with its folders held."""
    deadline = t0 + opts.minutes * 60
    out, work = Path(opts.out), Path(opts.work)
    relay.claim_session_outputs(out, opts.overwrite)  # before anything is unpacked or rendered
    require_gpu(opts)
    init, opts.model = resolve_init(opts.init, opts.model)  # an architecture change is refused before any work
    device = "cpu" if opts.cpu_rehearsal and opts.device == "auto" else _device(opts.device)  # before any unpack
    data, again, shards, run = work / "data", work / "check", work / "shards", out / RUN

    def checked(packed: Path | None) -> tuple[str | None, str, str | None]:  # after the pack, if any, is unpacked
        return _checked(opts, packed, (data, shards, run), device, init)

    assets, variant, check = checked(None) if opts.carry is None else \
        unpack_carry(Path(opts.carry), work, opts.overwrite, then=checked)
    print(f"gpu session: rendering {opts.objects} objects with {variant}; check with {check or 'none'}; training "
          f"{opts.model} on {device}{' (bf16 autocast)' if device == 'cuda' else ''}; budget {opts.minutes:g} min",
          flush=True)
    py = sys.executable
    out.mkdir(parents=True, exist_ok=True)
    stages = deadline - opts.reserve_s  # what follows the stages keeps the reserve
    over = f"--minutes: {opts.minutes:g} min, less --reserve-s {opts.reserve_s:g} s, ran out"
    advice = ("; expected a budget that fits the session: lower --objects, --res or --spp, or raise --minutes (what "
              "was rendered stays in --work, and the same command resumes it)")

    def step(argv: list[str], until: float = stages) -> None:
        try:
            run_step([py, "-m", *argv], deadline=until, out_of_time=over)
        except OutOfTime as exc:
            raise UsageError(f"{exc}{advice}") from None

    step(["wildgen.make", *_make_argv(opts, data, variant, opts.objects, shards, assets)])
    t_render = time.time() - t0
    check_report: dict = {"variant": variant, "check_variant": None, "skipped": "--check-variant none"}
    if check:
        # one worker with one thread: the check's render times are one CPU core's (issue 42's comparison)
        step(["wildgen.make", *_make_argv(opts, again, check, min(opts.check_objects, opts.objects), None, assets),
              "--workers", "1", "--threads", "1"])
        from scenes.folder.layouts import find_object_folders

        names = [f.name for f in find_object_folders(again, "--work") if (data / f.name).is_dir()]
        check_report = {"variant": variant, "check_variant": check,
                        **compare_datasets(data, again, names, opts.spp, opts.noise_cv),
                        "speed": {variant: render_speed(data, t_render), f"{check}, one CPU core": render_speed(again)}}
        print(f"variant check {variant} vs {check} on {len(names)} objects: ground truth "
              f"{'identical' if check_report['ground_truth_identical'] else 'not identical'} (masks differ "
              f"{'only on the outline' if check_report['masks_differ_only_on_outline'] else 'off the outline'}), "
              f"images {'within' if check_report['images_within_noise'] else 'OUTSIDE'} noise", flush=True)
    write_json(out / "variant_check.json", check_report, indent=1)
    left = (deadline - time.time() - opts.reserve_s) / 60
    if left <= 0:  # each stage starts only while more than the reserve is left
        raise UsageError(f"--minutes: rendering and the check took {(time.time() - t0) / 60:.1f} of {opts.minutes:g} "
                         "minutes, none is left to train (lower --objects, --res or --spp, or raise --minutes)")
    t_train = time.time()
    # unips.train stops itself before `stages` (its --time-limit); stopped here only if it did not
    try:
        step(["unips.train", *_train_argv(opts, shards, run, device, left, init)], until=stages + opts.reserve_s / 2)
    except StepFailed as exc:  # the --time-limit this command gave train, said as the user's own flag
        if "--time-limit:" not in str(exc) or "before the first step" not in str(exc):
            raise
        raise UsageError(f"{over} before training's first step ({left:.2f} min were left after rendering and the "
                         f"check){advice}") from None
    records = curve_records(run / "log.jsonl")
    plot_curve(records, out / "learning_curve.png", f"{opts.model}, {opts.objects} objects, {device}")
    summary = _write_card(opts, out, run, records, variant, device, check_report, t_render, time.time() - t_train,
                          init, assets)
    summary["wall_s"] = round(time.time() - t0, 1)
    write_json(out / "summary.json", summary, indent=1)
    return summary


def _write_card(opts: SessionOptions, out: Path, run: Path, records: list[dict], variant: str, device: str,
                check: dict, t_render: float, t_train: float, init: str | None = None,
                assets: str | None = None) -> dict:
    """model_card.json (a fragment for a model card) and the content of summary.json."""
    import torch

    from unips.models import load_model

    model, meta = load_model(run / "final.safetensors")
    step = meta.get("extra", {}).get("step")
    gpu = torch.cuda.get_device_name(0) if device == "cuda" else None
    card = {
        "model": meta.get("model_name"),
        "weights": f"{RUN}/final.safetensors",
        "parameters": sum(p.numel() for p in model.parameters()),
        "data": f"wildgen.make seed {opts.seed}, {opts.objects} objects, {opts.res} px, {opts.images} images, "
        f"{opts.spp} spp, {variant}, assets: {_assets_note(opts, assets)}",
        "init_from": opts.init,
        "init_weights": init and Path(init).name,
        "steps": step, "schedule_steps": opts.steps, "batch": opts.batch, "lr": opts.lr,
        "precision": "bf16 autocast" if device == "cuda" else "fp32",
        "final_loss": records[-1]["loss"] if records else None,
        "train_minutes": round(t_train / 60, 2),
        "hardware": f"{gpu or platform.processor() or platform.machine()}, torch {torch.__version__}",
        "recipe": "python -m orchestrate.gpu_session " + " ".join(
            f"--{k.replace('_', '-')} {v}"
            for k, v in (("init", opts.init), ("minutes", opts.minutes), ("objects", opts.objects), ("res", opts.res),
                         ("spp", opts.spp), ("seed", opts.seed), ("model", opts.model), ("steps", opts.steps),
                         ("batch", opts.batch))),
    }
    write_json(out / "model_card.json", card, indent=1)
    big = [str(p.relative_to(out)) for p in out.rglob("*") if p.is_file() and p.stat().st_size > 16 * 2**20]
    return {"variant": variant, "check_variant": check.get("check_variant"), "device": device,
            "ground_truth_identical": check.get("ground_truth_identical"),
            "images_within_noise": check.get("images_within_noise"), "render_speed": check.get("speed"),
            "render_s": round(t_render, 1), "train_s": round(t_train, 1), "steps": step,
            "curve_points": len(records), "files_over_16_mib": big, "options": asdict(opts)}


def _assets_note(opts: SessionOptions, assets: str | None) -> str:
    """What the card says of the assets: the pack's manifest (its rule and counts) when they came from --carry."""
    manifest = Path(opts.carry or "-") / "manifest.json"
    try:  # a manifest that is not a pack's (a list, assets not a mapping) says nothing of them
        a = read_json(manifest)["assets"] if assets and opts.carry else {}  # (a pipe there: refused, not waited on)
        return (f"packed training split, {len(a['meshes'])} meshes, {len(a['hdri'])} HDR maps, "
                f"{len(a['texture_sets'])} texture sets ({a['rule']})")
    except (OSError, ValueError, TypeError, KeyError):
        return assets or "none (procedural shapes and lights only)"


PACK_FLAGS = ("pack", "wheels", "assets", "overwrite")  # the flags --pack reads; any other given with it is refused
COMMAND = Command(SessionOptions, prog="python -m orchestrate.gpu_session", description=__doc__, needs=(
    Needs("wheels", lambda c, _: c.pack is not None, "with --pack"),
    *(Needs(f, lambda c, _: c.check_variant != "none", "with the check on (not --check-variant none)")
      for f in ("check_objects", "noise_cv"))))


def main(argv: list[str] | None = None) -> int:
    t0 = process_start() if argv is None else time.time()  # the command's clock; a call from Python: from the call
    try:
        opts = COMMAND.parse(argv).validate()
        if opts.pack is not None:
            assets = opts.assets or (str(SHARED_ASSETS) if SHARED_ASSETS.is_dir() else "none")
            with output_lock(opts.pack, "--pack"):  # one writer per folder
                pack(Path(opts.pack), Path(opts.wheels), assets=None if assets == "none" else Path(assets),
                     overwrite=opts.overwrite)
            return 0
        summary = session(opts, t0)
    except StepFailed as exc:
        return report_error(exc, code=exc.code)
    except (*INPUT_ERRORS, OSError) as exc:
        return report_error(exc)
    print(f"gpu session done in {summary['wall_s']:.0f} s: {summary['steps']} steps; "
          f"wrote {opts.out}/{RUN}/final.safetensors (+ .json, last.pt, log.jsonl), learning_curve.png, "
          "variant_check.json, model_card.json, summary.json")
    return 0


if __name__ == "__main__":
    from scenes.cli.supervise import run_supervised

    sys.exit(run_supervised("orchestrate.gpu_session", main))
