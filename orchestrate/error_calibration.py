"""Fit the expected-error model of a network's weights on renders with exact ground truth (one command).

    python -m orchestrate.error_calibration --work /tmp/errcal [--assets ../shared/assets] [--weights W] [--objects 16]

1. Splits --assets as the training recipe does (`orchestrate.asset_split`): only the training half is used here;
   the held-out meshes and HDR maps are left to the bench (`bench/bench_expected_error.py`).
2. Renders the suite `SUITE` with `wildgen.make` into --work: every PS-Wild light family, complexity levels 1-5,
   4 to 16 images, the sensor presets (noise, response, mosaic) and capture presets, a perspective camera;
   --objects per row, seed `--seed` + the row's index.
3. Runs the network on every object with the evidence of `unips.expected_error.gather` and measures the true
   angular error per pixel.
4. Fits `unips.expected_error.ErrorModel`: its pixel stage (Poisson GLM per pixel, up to --pixels pixels per object,
   objects weighted equally; every second object counted once more with its camera moved, every third with half
   its images and every fourth with 3 images, `FAULTS`), then its object stage (the object's mean); the interval
   is the 10th and 90th percentile of the ratio true / stated out of fold (`FOLDS`); writes it beside the weights
   (`<stem>.expected_error.json`) or to --out.

The rendered suite is resumed when the command is run again (wildgen.make resumes a dataset).
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.options import REQUIRED, Command, arg, check_fields, option

REPO = Path(__file__).resolve().parents[1]
FAMILIES = "directional,point,near_area,hdri,mixed"

SUITE: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("level1", ("--level", "1", "--lights", FAMILIES, "--images", "10")),
    ("level2", ("--level", "2", "--lights", FAMILIES, "--images", "6")),
    ("level3", ("--level", "3", "--lights", FAMILIES, "--images", "16")),
    ("level4", ("--level", "4", "--lights", FAMILIES, "--images", "8")),
    ("level5", ("--level", "5", "--lights", FAMILIES, "--images", "10", "--camera", "perspective")),
    ("few", ("--lights", FAMILIES, "--images", "4")),
    ("phone", ("--lights", FAMILIES, "--images", "10", "--sensor", "phone")),
    ("machine_vision", ("--lights", FAMILIES, "--images", "12", "--sensor", "machine-vision")),
    ("diligent", ("--preset", "diligent", "--images", "12")),
    ("phone_flash", ("--preset", "phone-flash", "--images", "8")),
)
"""The renders the error model is fitted on (and, with the held-out assets and another seed, judged on): name, the
wildgen.make flags of the row (each row cycles the five PS-Wild light families unless a preset sets the lights)."""
COMMON = ("--res", "128", "--spp", "16")
"""Flags every row shares."""


def camera_moved(obj, px: int = 3):
    """`obj` with every second image shifted by (px, px) pixels: the camera moved between photos."""
    import dataclasses

    images = obj.images.copy()
    images[1::2] = np.roll(images[1::2], (px, px), axis=(1, 2))
    return dataclasses.replace(obj, images=images)


def half_images(obj):
    """`obj` with its first K/2 images (at least 2)."""
    import dataclasses

    k = max(2, obj.num_images // 2)
    return dataclasses.replace(obj, images=obj.images[:k], light_directions=None, light_intensities=None,
                               image_names=obj.image_names[:k])


def three_images(obj):
    """`obj` with its first 3 images (the fewest a capture is usually given with)."""
    import dataclasses

    return dataclasses.replace(obj, images=obj.images[:3], light_directions=None, light_intensities=None,
                               image_names=obj.image_names[:3])


FAULTS = {"camera_moved": camera_moved, "half_images": half_images, "three_images": three_images}
"""Capture faults the evidence should see. The calibration adds every second object once more with its camera moved
(2 or 3 px, alternately; the true error is measured on the moved images against the unmoved truth), every third
with half its images and every fourth with 3 images, so that the fit learns what disagreement such captures show and
how the error grows with fewer images (`unips.expected_error.fit_object_stage`); the bench applies each to the
held-out objects as a probe."""


def fault_schedule(i: int, obj) -> list[tuple[str, object]]:
    """The calibration's copies of its `i`-th object `obj` (`FAULTS`): [(tag, fault or None)], the object itself
    first ('clean'), then its camera moved by 2 or 3 px (every second object, alternately), half its images (every
    third) and its first 3 images (every fourth, when it has more)."""
    out: list[tuple[str, object]] = [("clean", None)]
    if i % 2 == 0:
        out.append(("camera_moved", lambda o, px=2 + (i // 2) % 2: camera_moved(o, px)))
    if i % 3 == 1:
        out.append(("half_images", half_images))
    if i % 4 == 3 and obj.num_images > 3:
        out.append(("three_images", three_images))
    return out


def render_suite(work: Path, assets: str | None, objects: int, seed: int, rows=SUITE, quiet: bool = True) -> list[Path]:
    """Render (or resume) each row of `rows` into work/<name>; returns the dataset folders."""
    from orchestrate.steps import toolkit_env
    from scenes.cli.outputs import check_step_folder
    from scenes.cli.supervise import die_with_parent

    for name, _ in rows:  # every row's folder, before the first render
        check_step_folder(work / name, f"wildgen.make for suite row {name!r}")
    out, me = [], os.getpid()
    for i, (name, flags) in enumerate(rows):
        dest = work / name
        argv = [sys.executable, "-m", "wildgen.make", *flags, *COMMON, "--objects", str(objects), "--seed",
                str(seed + 100 * i), "--out", str(dest), *(["--assets", assets] if assets else []),
                *(["--quiet"] if quiet else [])]
        # from the user's folder, the toolkit on PYTHONPATH: a relative --work means what it says
        # the step goes when this process goes, however it goes (a kill of the work leaves no orphan render)
        done = subprocess.run(argv, capture_output=True, text=True, env=toolkit_env(),
                              preexec_fn=lambda: die_with_parent(me))
        if done.returncode != 0:
            said = (done.stderr.strip().splitlines() or ["no message"])[-1].removeprefix("error: ")
            raise UsageError(f"--work: wildgen.make for suite row {name!r} into {str(dest)!r} failed: {said}")
        out.append(dest)
    return out


def measure(net, folder: Path | object, max_pixels: int | None = None, rng: np.random.Generator | None = None,
            fault=None, name: str | None = None) -> dict:
    """One object's evidence and true error: {'features': (P, F), 'error': (P,), 'true_mean' (over every mask
    pixel), 'evidence': Evidence, 'family', 'images', 'name'} (P: all mask pixels, or `max_pixels` of them drawn with
    `rng`); `folder` an object folder or a loaded PSObject, `fault` one of FAULTS' functions applied to it first,
    `name` the object's (default its own; a faulted copy keeps the name of its object)."""
    from scenes.metrics import angles_deg
    from unips.data import load_object
    from unips.expected_error import gather

    obj = load_object(folder) if isinstance(folder, (str, Path)) else folder
    obj = fault(obj) if fault is not None else obj
    if obj.normals is None:
        raise ValueError(f"{folder}: no ground-truth normals")
    normals, ev = gather(net, obj)
    err = angles_deg(normals[ev.mask], obj.normals[ev.mask])
    true_mean = float(err.mean())
    feats = ev.features()
    if max_pixels is not None and len(err) > max_pixels:
        pick = (rng or np.random.default_rng(0)).choice(len(err), max_pixels, replace=False)
        feats, err = feats[pick], err[pick]
    return {"features": feats, "error": err, "true_mean": true_mean, "evidence": ev, "family": obj.light_family,
            "images": obj.num_images, "name": name or obj.name}


def objects_of(datasets: list[Path]) -> list[Path]:
    from scenes.folder.layouts import find_object_folders

    out = []
    for d in datasets:
        out += find_object_folders(d, "--work")
    return out


@dataclass
class CalibrationOptions:
    """The command line of orchestrate.error_calibration."""

    work: Annotated[str, arg(metavar="DIR")] = REQUIRED
    """Folder of the asset split and the rendered suite (resumed when run again)."""
    assets: Annotated[str | None, arg(help_behavior_hint="(default: ../shared/assets)")] = None
    """Asset folder (hdri/, meshes/, textures/; 'none': procedural shapes and lights only); only its training half
    is rendered."""
    weights: Annotated[str | None, arg(help_behavior_hint="(default: the shipped weights of the default model)")] = None
    """Weights to fit the error model for."""
    out: Annotated[str | None, arg(help_behavior_hint="(default: beside --weights, <stem>.expected_error.json)")] = None
    """Where to write the fitted model."""
    objects: int = option(32, minimum=1)
    """Objects per suite row (10 rows)."""
    seed: int = option(11000, minimum=0)
    """Seed of the first row (row i: seed + 100 i): none of the seeds the shipped model was trained, validated or
    tested on (3000-8000), nor the bench's (9000)."""
    pixels: int = option(1500, minimum=1)
    """Pixels per object the model is fitted on (drawn with --seed)."""
    threads: int = option(2, minimum=1)
    """Torch threads."""
    overwrite: bool = False
    """Replace the fitted model an earlier run wrote at the output (a file this command did not write, never)."""

    def validate(self) -> "CalibrationOptions":
        """The flags, --work, --weights and the output (an earlier fit replaced only with --overwrite), before any
        work."""
        from scenes.cli.outputs import check_apart, check_no_holder_above, check_output_folder, claim_outputs
        from scenes.files import is_within, not_a_file

        check_fields(self)
        check_output_folder(self.work, "--work")
        self.assets = self.assets or str(REPO.parent / "shared" / "assets")
        if self.assets != "none" and not Path(self.assets).is_dir():
            raise UsageError(f"--assets: {self.assets!r} is not a folder (expected hdri/, meshes/, textures/, "
                             "or 'none')")
        assets = None if self.assets == "none" else self.assets
        # the suite is never rendered among the weights, nor into the asset library (read as assets next time)
        check_apart(self.work, {"--weights": self.weights, "--assets": assets}, "--work")
        if assets is not None and is_within(assets, self.work):  # the split and the suite's rows land among them
            raise UsageError(f"--assets: {assets!r} lies inside --work {self.work!r}, where the asset split and the "
                             "suite are written; expected an asset folder outside it")
        _check_own_work(Path(self.work))
        if self.weights is not None and (why := not_a_file(Path(self.weights))):
            raise UsageError(f"--weights: {self.weights!r} {why}")
        dest, flag = self.destination()
        if self.weights is not None and dest.resolve() == Path(self.weights).resolve():
            raise UsageError(f"--out: {str(dest)!r} is the --weights file itself; expected a .json file beside it")
        check_output_folder(dest.parent, flag)  # a read-only folder is refused before the suite is rendered
        check_no_holder_above(dest, flag)  # inside a folder another run writes, the two runs' files would mix
        claim_outputs([dest], self.overwrite, flag, "orchestrate.error_calibration",
                      signed={dest: ("weights_sha256", "features")})
        return self

    def destination(self) -> tuple[Path, str]:
        """Where the fitted model goes, and the flag that says so (--out, else --weights: beside them)."""
        from unips.expected_error import model_path
        from unips.models import DEFAULT_MODEL
        from unips.models.registry import pretrained_entry

        if self.out is not None:
            return Path(self.out), "--out"
        weights = Path(self.weights) if self.weights else pretrained_entry(DEFAULT_MODEL).weights_path
        return model_path(weights), "--weights" if self.weights else "--out"


def _check_own_work(work: Path) -> None:
    """Refuse a --work holding what this command does not write there (a dataset, a user's files): the suite's
    rows and the asset split would be rendered in among them. Hidden names (.DS_Store, an editor's) are no work."""
    from orchestrate.asset_split import SPLIT_FOLDERS

    ours = {name for name, _ in SUITE} | set(SPLIT_FOLDERS)
    other = sorted(p.name for p in work.iterdir() if p.name not in ours and not p.name.startswith(".")) if (
        work.is_dir()) else []
    if other:
        more = f" and {len(other) - 1} more" if len(other) > 1 else ""
        raise UsageError(f"--work: {str(work)!r} holds {other[0][:80]!r}{more}, which orchestrate.error_calibration "
                         f"does not write (its work folder holds the asset split and the suite's rows "
                         f"{', '.join(n for n, _ in SUITE)}); expected a new or empty folder, or an earlier run's "
                         "--work")


COMMAND = Command(CalibrationOptions, prog="python -m orchestrate.error_calibration", description=__doc__)


FOLDS = 5
"""The interval's ratios are measured out of fold: each object stated by the model fitted on the other folds."""


def _fit_stages(samples: list[dict], em) -> None:
    """Fit `em`'s pixel stage and then its object stage on `samples` (in place)."""
    from unips.expected_error import fit, fit_object_stage

    w, b, mean, std = fit([(s["features"], s["error"]) for s in samples])
    em.mean, em.std, em.coef, em.intercept, em.scale = mean.tolist(), std.tolist(), w.tolist(), b, 1.0
    raw = np.array([float(np.nanmean(em.per_pixel(s["evidence"]))) for s in samples])
    images = [s["evidence"].images for s in samples]
    em.object_images = [int(min(images)), int(max(images))]
    em.object_coef = fit_object_stage(raw, np.array(images),
                                      np.array([s["true_mean"] for s in samples]),
                                      np.array([s["name"] for s in samples]))


def calibrate(samples: list[dict], weights: Path, model_name: str, note: dict, seed: int = 0) -> "object":
    """The ErrorModel of `samples` (`measure`'s dicts; a sample's faulted copies share its `name`) for `weights`: both
    stages fitted on every sample, the interval's ratios true / stated out of fold (`FOLDS`, grouped by object)."""
    import dataclasses

    from unips.expected_error import FEATURES, ErrorModel, sha256

    em = ErrorModel(weights_sha256=sha256(weights), model_name=model_name, features=list(FEATURES), mean=[], std=[],
                    coef=[], intercept=0.0, scale=1.0, ratio_quantiles=[1.0, 1.0])
    names = sorted({s["name"] for s in samples})
    fold = dict(zip(names, np.random.default_rng(seed).permutation(len(names)) % FOLDS))
    true = np.array([s["true_mean"] for s in samples])
    out_of_fold = np.full(len(samples), np.nan)
    for k in range(FOLDS):
        held = np.array([fold[s["name"]] == k for s in samples])
        part = dataclasses.replace(em)
        _fit_stages([s for s, h in zip(samples, held) if not h], part)
        out_of_fold[held] = [part.state(s["evidence"]).mean for s, h in zip(samples, held) if h]
    _fit_stages(samples, em)
    ratio = true / out_of_fold
    em.ratio_quantiles = [float(np.quantile(ratio, 0.1)), float(np.quantile(ratio, 0.9))]
    hits = np.abs(out_of_fold - true) <= np.maximum(2.0, 0.25 * true)
    em.calibration = {**note, "objects": len(samples), "true_mean_deg": round(float(true.mean()), 2),
                      "out_of_fold": {"folds": FOLDS, "hit_share": round(float(hits.mean()), 3),
                                      "median_ratio_true_over_stated": round(float(np.median(ratio)), 4)}}
    return em


def main(argv: list[str] | None = None) -> int:
    """One line `error: ...` for a bad input; --work is held for the run (one calibration per work folder)."""
    from scenes.cli.outputs import output_lock

    try:
        opts = COMMAND.parse(argv).validate()
        with output_lock(opts.work, "--work"):
            return run(opts)
    except (*INPUT_ERRORS, OSError) as exc:
        return report_error(exc)


def run(opts: CalibrationOptions) -> int:
    import torch

    from orchestrate.asset_split import split_assets
    from unips.inference import load_network
    from unips.models import DEFAULT_MODEL
    from unips.models.registry import pretrained_entry, read_model_card

    torch.set_num_threads(opts.threads)
    work = Path(opts.work)
    assets = None
    weights = Path(opts.weights) if opts.weights else pretrained_entry(DEFAULT_MODEL).weights_path
    try:  # before anything is written into --work (the asset split): refused weights leave it as it was
        net = load_network(weights)
    except (ValueError, FileNotFoundError) as exc:  # the reader names the file; the flag is ours
        raise type(exc)(f"--weights: {str(exc).removeprefix('--checkpoint: ')}") from None
    entry = pretrained_entry(DEFAULT_MODEL)
    read_model_card(entry.card_path)  # a card the fit would be recorded in is read before the work
    if opts.assets != "none":
        assets = str(split_assets(Path(opts.assets), work)[0])
    t0 = time.time()
    datasets = render_suite(work, assets, opts.objects, opts.seed)
    print(f"rendered the suite ({len(SUITE)} rows x {opts.objects} objects) in {work} in {time.time() - t0:.0f} s",
          flush=True)
    rng = np.random.default_rng(opts.seed)
    samples = []
    from unips.data import load_object

    folders = objects_of(datasets)
    for i, folder in enumerate(folders):
        obj, name = load_object(folder), f"{folder.parent.name}/{folder.name}"
        samples += [measure(net, obj, opts.pixels, rng, fault, name=name) for _, fault in fault_schedule(i, obj)]
        print(f"\r{i + 1}/{len(folders)} objects measured", end="", flush=True)
    print(flush=True)
    em = calibrate(samples, weights, net.meta.get("model_name", ""), {
        "suite": [name for name, _ in SUITE], "faults": "every second object also with its camera moved by 2 or 3 px, "
        "every third also with half its images, every fourth also with 3 images",
        "assets": "training split" if assets else "none (procedural)",
        "seed": opts.seed, "objects_per_row": opts.objects, "pixels_per_object": opts.pixels,
        "command": f"python -m orchestrate.error_calibration --work WORK --objects {opts.objects} --seed {opts.seed}"})
    from unips.expected_error import model_path

    dest = opts.destination()[0]
    dest.parent.mkdir(parents=True, exist_ok=True)
    em.save(dest)
    card = ""
    if dest == model_path(entry.weights_path) and weights == entry.weights_path and entry.card_path.is_file():
        record_in_card(entry.card_path, dest, em)  # the shipped model's card says which error model is its own
        card = f" and recorded it in {entry.card_path.name}"
    print(f"fitted the expected-error model of {weights.name} on {len(samples)} objects; wrote {dest}{card}")
    return 0


def record_in_card(card_path: Path, dest: Path, em) -> None:
    """The model card's `expected_error`: which file, fitted on what, by which command, its interval's ratios."""

    from scenes.files import write_json
    from unips.models.registry import read_model_card

    card = read_model_card(card_path)
    card["expected_error"] = {
        "file": dest.name, "weights_sha256": em.weights_sha256, "command": em.calibration.get("command"),
        "objects": em.calibration.get("objects"), "assets": em.calibration.get("assets"),
        "faults": em.calibration.get("faults"), "interval_80_ratios": [round(q, 3) for q in em.ratio_quantiles],
        "judged_by": "bench/bench_expected_error.py -> bench/results/expected_error.json (held-out assets)"}
    write_json(card_path, card, indent=1)


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    stopped = ("interrupted: the renders finished in --work are kept (the suite resumes); run the same command again")
    sys.exit(run_supervised("orchestrate.error_calibration", main, stopped))
