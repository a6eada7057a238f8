"""Predict surface normals for one object folder or a directory of them.

    python -m unips.predict --method {model,least-squares,sh-uncalibrated} [--checkpoint CKPT] [--model NAME]
                            --input PATH --out DIR [--max-images K] [--device cpu] [--res R] [--tta N]
                            [--scalable]

For each object, ``DIR/<object>/`` receives ``normal.png`` (16-bit, (n + 1) / 2, the full original
frame, background 32768), ``normal.exr`` (float32), ``normal_vis.png`` (8-bit picture) and
``predict.json`` (method, checkpoint, images used, time). ``<object>`` is the input folder's name minus
a trailing ``.data`` (``foo.data`` -> ``foo``; DiLiGenT's ``ballPNG`` stays ``ballPNG``), the name
`unips.evaluate` matches ground truth by.

Inference itself is the library `unips.inference` (this module parses arguments and writes files). ``--method model``
loads a network with `unips.models.load_model`; without ``--checkpoint`` it uses the shipped weights of
`unips.models.DEFAULT_MODEL` (the registry's pretrained entry) and refuses to run when that file is absent (never random
weights). The network sees the preprocessing of its registry entry's contract (`unips.models.input_contract`; ours:
`unips.preprocess.prepare`), at the crop's own size or at ``--res R``, and its output is put back into the original
frame. ``--tta N`` averages the network's predictions over N flipped / transposed views of the object (test-time
augmentation, N forward passes; `unips.inference.model_normals`). ``--model glc-unips --checkpoint DIR`` and ``--model
sdm-unips --checkpoint DIR`` run the authors' published UniPS and SDM-UniPS weights (their checkpoint folders) with
their preprocessing (`unips.glc_preprocess`, `unips.sdm_preprocess`; one view unless ``--tta`` says otherwise);
``--scalable`` runs SDM-UniPS on the 512 px interleaved sub-images of a large working image, as the authors'
``--scalable`` does. Each object's memory is estimated before any work and a run that would not fit is refused in one
line.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np

from scenes.cli.errors import INPUT_ERRORS, UsageError, one_line, report_error
from scenes.cli.limits import check_memory, gib
from scenes.cli.needs import Needs
from scenes.cli.options import REQUIRED, Command, arg, check_fields, option
from scenes.cli.outputs import check_output_folder, claim_outputs, output_lock
from scenes.cli.progress import Progress
from scenes.cli.supervise import run_supervised
from scenes.files import read_json, shown_name, write_json
from scenes.folder.format import EXPECTED_ERROR_FILES, PREDICTION_FILES, PREDICTION_INFO, object_name
from scenes.folder.layouts import detect_layout
from scenes.images import write_normal_exr, write_normal_map, write_normal_visual
from unips.data import find_objects, load_object
from unips.expected_error import for_weights, gather, model_path, write_stated
from unips.inference import (
    DEFAULT_TTA,
    METHODS,
    TTA_VIEWS,
    check_device,
    check_model_name,
    load_network,
    model_contract,
    predict_object,
    prediction_memory,
    scalable_patch,
)

log = logging.getLogger(__name__)


CONSTANT_DEG = 2.0
"""A map whose normals deviate from their mean direction by less than this on average (degrees) is flagged
as constant: a curved object's maps deviate by tens of degrees, a plane's by 0."""
"""A prediction whose normals inside the mask all lie within this angle (degrees) of their mean is flagged
as constant (`predict.json` "constant_map", a warning): a degenerate result unless the object is a plane."""


def constant_map(normals: np.ndarray, mask: np.ndarray) -> bool:
    """True when the normals inside the mask deviate from their mean direction by less than CONSTANT_DEG on
    average (a mean, not a maximum: a near-constant map with a few stray pixels is still flagged)."""
    inside = normals[mask].astype(np.float64)
    if len(inside) < 2:
        return False
    inside = inside / np.maximum(np.linalg.norm(inside, axis=1, keepdims=True), 1e-12)
    mean = inside.mean(axis=0)
    norm = np.linalg.norm(mean)
    if norm < 1e-8:
        return False
    deviation = np.degrees(np.arccos(np.clip(inside @ (mean / norm), -1.0, 1.0)))
    return bool(deviation.mean() < CONSTANT_DEG)


PREDICTION_OUTPUTS = ("normal.png", "normal.exr", "normal_vis.png", PREDICTION_INFO)
"""The files unips.predict writes into <out>/<object>/ (predict.json first: it marks the folder as this command's)."""


def check_out_folder(folder: Path, overwrite: bool = False) -> None:
    """The rule of every command (`scenes.cli.outputs.claim_outputs`) for one object's output folder: an earlier
    prediction (its predict.json present) is replaced only with --overwrite; normal maps without predict.json
    beside them were not written by unips.predict and are never replaced."""
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"--out: {str(folder)!r} is an existing file, expected a folder for the prediction")
    others = [folder / f for f in PREDICTION_FILES if f not in PREDICTION_OUTPUTS and (folder / f).exists()]
    stated = [folder / f for f in EXPECTED_ERROR_FILES if os.path.lexists(folder / f)]
    claim_outputs([folder / f for f in PREDICTION_OUTPUTS] + others + stated, overwrite, owner="unips.predict",
                  marker=folder / PREDICTION_INFO,
                  signed={folder / PREDICTION_INFO: ("object", "method", "images_used")})
    if stated and not _stated_before(folder / PREDICTION_INFO):  # the earlier run stated none: not its files
        raise UsageError(f"--out: {str(stated[0])!r} was not written by unips.predict (the earlier prediction's "
                         f"{PREDICTION_INFO} states no expected error); it is never replaced, even with --overwrite: "
                         "move it away or use another --out")
    if others:  # a prediction file of another kind beside ours: the lookup would not find what this run writes
        raise UsageError(f"--out: {str(others[0])!r} was not written by unips.predict; it is never replaced: "
                         "move it away or use another --out")


def _stated_before(info: Path) -> bool:
    """Whether the earlier prediction whose record is `info` stated an expected error (and so wrote its files)."""
    try:
        return read_json(info).get("expected_error_deg") is not None
    except (OSError, ValueError, AttributeError):
        return False


def check_object(args: "PredictOptions", folder: Path) -> None:
    """Before any prediction: the object's folder is read without its images (mask, first image's size,
    ground truth, lights) and its memory estimated (`unips.inference.prediction_memory`) against what this
    machine has."""
    from scenes.folder.layouts import read_folder
    from unips.preprocess import crop_box

    fd = read_folder(folder, max_images=args.max_images, images=False, arg="--input")
    contract = model_contract(args.model)
    inputs = contract.preprocess
    k = min(len(fd.image_paths), contract.max_images or len(fd.image_paths))
    patch = contract.patch if args.scalable else None
    if contract.side is not None:
        side = contract.side
    elif inputs == "sdm-unips":
        from unips.sdm_preprocess import sdm_crop

        side = sdm_crop(fd.mask, margin=contract.margin).side
    else:
        side = crop_box(fd.mask, margin=contract.margin).size
    work = args.res if args.res is not None else side
    tta = (args.tta or contract.views) if args.method == "model" else 1
    need = prediction_memory(args.method, fd.shape, k, work, tta, inputs=inputs, patch=patch)
    at = (f"at {work} x {work} px (--res)" if args.res is not None else f"at {work} x {work} px from its crop")
    if patch is not None:
        at += f" in {(work // patch) ** 2} sub-images of {patch} px (--scalable)"
    advice = "lower --res or --max-images"
    if contract.patch is not None and patch is None and work > contract.patch:
        tiled = prediction_memory(args.method, fd.shape, k, work, tta, inputs=inputs, patch=contract.patch)
        advice = f"add --scalable ({contract.patch} px sub-images, about {gib(tiled)}), or {advice}"
    check_memory(need, ("--scalable" if patch is not None else "--res") if args.method == "model" else "--max-images",
                 f"--method {args.method} on {fd.name} ({k} images of {fd.shape[1]} x {fd.shape[0]} px"
                 + (f", the network {at}, {tta} view(s))" if args.method == "model" else ")"),
                 advice if args.method == "model" else "lower --max-images")


def write_prediction(out_dir: Path, normals: np.ndarray, info: dict[str, Any]) -> None:
    """Write predict.json, normal.png, normal.exr and normal_vis.png into ``out_dir``, each through a temporary
    name: a kill or a full disk leaves no truncated file, and predict.json (written first) marks the folder
    as this command's, so a rerun replaces what a killed run left."""
    out_dir.mkdir(parents=True, exist_ok=True)
    write_json(out_dir / PREDICTION_INFO, info, indent=2, sort_keys=True)
    write_normal_map(out_dir / "normal.png", normals)
    write_normal_exr(out_dir / "normal.exr", normals)
    write_normal_visual(out_dir / "normal_vis.png", normals)


@contextmanager
def taken_back_on_failure(out_dir: Path) -> Iterator[None]:
    """Writes of one object's outputs into `out_dir` that, failing (a full disk, `ulimit -f`), take back the files
    they made (and the folder), so that a first run leaves nothing and its rerun needs no --overwrite (an earlier
    run's files it replaced stay replaced: with --overwrite, a rerun is asked for anyway)."""
    made_dir = not out_dir.exists()
    new = [out_dir / f for f in (*PREDICTION_OUTPUTS, *EXPECTED_ERROR_FILES) if not os.path.lexists(out_dir / f)]
    try:
        yield
    except OSError:
        for f in new:
            f.unlink(missing_ok=True)
        if made_dir and out_dir.is_dir() and not any(out_dir.iterdir()):
            out_dir.rmdir()
        raise


FEWEST_IMAGES = {"least-squares": (3, "three non-coplanar lights at least"),
                 "sh-uncalibrated": (4, "ambient + 3 lighting components")}
"""The fewest images each classical method solves from, checked against --max-images before any work."""


@dataclass
class PredictOptions:
    """The command line of unips.predict."""

    method: Literal[METHODS] = REQUIRED
    """The network ('model') or a classical baseline."""
    checkpoint: Annotated[
        Path | None, arg(help_behavior_hint="(default: the shipped weights of unips.models.DEFAULT_MODEL)")
    ] = None
    """Model file (.safetensors with its .json, or a training .pt), or a folder of the authors' published weights
    (with --model); --method model only."""
    model: str | None = None
    """Registered network (unips.models.list_models()): the one that reads a folder of published weights
    (--model glc-unips or sdm-unips --checkpoint DIR); with a model file, the file's; without --checkpoint, its
    shipped weights."""
    input: Path = REQUIRED
    """An object folder or a directory of them."""
    out: Path = REQUIRED
    """Output directory: <out>/<object>/normal.png, normal.exr, normal_vis.png, predict.json."""
    max_images: Annotated[int | None, arg(help_behavior_hint="(default: all)")] = option(None, minimum=1)
    """Use the first K images of each object."""
    device: str = "cpu"
    """Torch device for --method model (cpu, cuda, cuda:0)."""
    res: Annotated[int | None, arg(help_behavior_hint="(default: the crop's own size)")] = option(None, minimum=8)
    """Working resolution of the network (the crop is resized to R x R); --method model only. UniPS (glc-unips): by
    default the published 512. SDM-UniPS: a multiple of its canonical resolution, by default the published side (a
    multiple of 512)."""
    tta: Annotated[Literal[TTA_VIEWS] | None,
                   arg(help_behavior_hint=f"(default: {str(DEFAULT_TTA)}; 1 for glc-unips, sdm-unips)")] = None
    """Views averaged (test-time augmentation by flips and transposes); N forward passes; --method model only."""
    scalable: bool = False
    """SDM-UniPS only (--model sdm-unips): predict a working image larger than 512 px as its 512 x 512 px interleaved
    sub-images, one after the other, as the authors' --scalable does: the network's memory is that of a 512 px
    image whatever the side (the working side or --res must be a multiple of 512)."""
    expected_error: bool = True
    """Also state the map's expected angular error per pixel and per object (`unips.expected_error`: two more passes
    of one view on two halves of the images), where an error model was fitted for the weights: expected_error_deg.npy,
    .exr, expected_error.png and predict.json `expected_error_deg`; --method model only."""
    overwrite: bool = False
    """Replace the predictions of an earlier run in --out (folders with its predict.json; nothing else is touched)."""

    def validate(self) -> "PredictOptions":
        check_fields(self)
        check_device(self.device)
        if self.method != "model":
            for flag, value in (("--checkpoint", self.checkpoint), ("--model", self.model), ("--res", self.res),
                                ("--tta", self.tta)):
                if value is not None:
                    raise UsageError(f"{flag}: only used with --method model, not --method {self.method}")
            if self.scalable:
                raise UsageError(
                    f"--scalable: only used with --method model --model sdm-unips, not --method {self.method}"
                )
        check_model_name(self.model)
        least = FEWEST_IMAGES.get(self.method)
        if least is not None and self.max_images is not None and self.max_images < least[0]:
            raise UsageError(f"--max-images: got {self.max_images}, expected at least {least[0]} with --method "
                             f"{self.method} ({least[1]})")
        if self.scalable:  # without --model, the network is known once its file is read: the published side till then
            from unips.models.contract import SDM_UNIPS_INPUTS

            patch = (model_contract(self.model) if self.model is not None else SDM_UNIPS_INPUTS).patch
            if patch is None:
                raise UsageError(
                    f"--scalable: only for the SDM-UniPS networks (--model sdm-unips), not --model {self.model}"
                )
            if self.res is not None and self.res % patch:
                raise UsageError(f"--res {self.res}: --scalable needs a multiple of its {patch} px sub-images")
        check_output_folder(self.out)
        return self


COMMAND = Command(PredictOptions, prog="python -m unips.predict", description=__doc__.split("\n\n")[0], needs=(
    Needs("expected_error", lambda c, _: c.method == "model" or not c.expected_error, "with --method model"),
    Needs("device", lambda c, _: c.method == "model", "with --method model (the baselines run on the CPU)")))


def check_args(argv: list[str]) -> PredictOptions:
    """What can be checked of a prediction command line before its input exists (orchestrate.demo checks its
    prediction steps with this before rendering their data): the flags, --out, and the network file loaded;
    writes nothing."""
    args = COMMAND.parse(argv).validate()
    if args.method == "model":
        load_network(args.checkpoint, args.device, args.model)
    return args


def main(argv: list[str] | None = None) -> int:
    """One object: a failure is one line `error: ...`, exit 2. A dataset: a failed object is recorded, the others
    go on, the failures are listed at the end (`failed NAME: reason`) and the exit status is 1. --out is held for
    the length of the run (`scenes.cli.outputs.output_lock`)."""
    with ExitStack() as held:
        return _main(argv, held)


def _main(argv: list[str] | None, held: ExitStack) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    failures: list[tuple[str, str]] = []
    try:
        args = COMMAND.parse(argv).validate()
        held.enter_context(output_lock(args.out, inputs={"--input": args.input}))
        # (an --input another run is still writing: refused by output_lock.) The weights first (the published ones are
        # checked finite and of the network's kind): before any input
        net = load_network(args.checkpoint, args.device, args.model) if args.method == "model" else None
        if net is not None and args.scalable:
            scalable_patch(net)  # a file's network that cannot take --scalable: once, before any object
        errors = error_model(args, net)
        folders = find_objects(args.input, "--input")
        single = detect_layout(args.input) is not None
        names = [object_name(f) for f in folders]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise UsageError(
                f"--input: several object folders share the name(s) {', '.join(dup)} (e.g. foo and foo.data)"
            )
        for name in names:
            check_out_folder(args.out / name, args.overwrite)
        todo = []
        for folder, name in zip(folders, names):  # every object read (without its images) before any work
            try:
                check_object(args, folder)
                todo.append((folder, name))
            except INPUT_ERRORS as exc:
                if single or exc.__class__ is UsageError:  # a size this machine cannot hold: the flags' fault
                    raise
                failures.append((shown_name(name), one_line(exc)))
        written: list[str] = []
        where = args.out / todo[0][1] if single and todo else args.out
        print(f"predicting {len(todo)} object(s) with --method {args.method} into {where} ...", flush=True)
        if errors[1] and args.expected_error and net is not None:  # a baseline's predict.json says why, quietly
            print(f"note: no expected error is stated: {errors[1]}", flush=True)
        with Progress(f"predicting ({args.method})", "obj", total=len(todo), enabled=len(todo) >= 2) as shown:
            for folder, name in todo:
                try:
                    _predict_one(args, net, folder, name, errors)
                    written.append(name)
                except (*INPUT_ERRORS, OSError, np.linalg.LinAlgError) as exc:
                    if single:
                        raise
                    failures.append((shown_name(name), one_line(exc)))
                    log.debug("%s failed", name, exc_info=True)
                shown.advance()
    except (*INPUT_ERRORS, OSError, np.linalg.LinAlgError) as exc:
        return report_error(exc)
    if written:
        where = f"{args.out / written[0]}" if len(written) == 1 else f"{args.out}/<object>"
        print(f"wrote {len(written)} prediction(s): {where}/normal.exr (float), normal.png (16-bit), "
              f"normal_vis.png, predict.json")
    if failures:
        for name, why in failures:
            print(f"failed {name}: {why}", file=sys.stderr)
        others = f"the other {len(written)} were written" if written else "none was written"
        print(f"error: {len(failures)} of {len(folders)} object(s) failed with --method {args.method}: "
              f"{', '.join(n for n, _ in failures)} ({others})", file=sys.stderr)
        return 1
    return 0


def error_model(args: PredictOptions, net) -> tuple[Any, str | None]:
    """(the expected-error model of the run's weights, None) or (None, why no error is stated)."""
    if not args.expected_error:
        return None, "--no-expected-error"
    if net is None:
        return None, f"--method {args.method}: the expected error is fitted for a network's weights only"
    if args.scalable:
        return None, "--scalable: no error model was fitted for the interleaved sub-images"
    return for_weights(net.checkpoint)


def _predict_one(args: PredictOptions, net, folder: Path, name: str,
                 errors: tuple[Any, str | None] = (None, "not asked")) -> None:
    obj = load_object(folder, max_images=args.max_images, arg="--input")
    start = time.perf_counter()
    tta = (args.tta or net.contract.views) if net else None
    patch = scalable_patch(net) if net and args.scalable else None
    em, why = errors
    stated = None
    if em is not None and obj.num_images >= 2:
        normals, evidence = gather(net, obj, res=args.res, tta=tta or 1)
        stated = em.state(evidence)
    else:
        why = why or f"{obj.num_images} image: two halves of the images are needed"
        normals = predict_object(obj, args.method, net=net, res=args.res, tta=tta or 1, patch=patch)
    elapsed = time.perf_counter() - start
    constant = constant_map(normals, obj.mask)
    if constant:
        print(
            f"warning: {name}: --method {args.method} returned a constant normal map (normals within "
            f"{CONSTANT_DEG} deg of one direction on average): degenerate unless the object is a plane; "
            "flagged in predict.json",
            file=sys.stderr,
        )
    info = {
        "object": name,
        "input": str(folder.resolve()),
        "layout": obj.layout,
        "method": args.method,
        "checkpoint": str(net.checkpoint.resolve()) if net else None,
        "model_name": net.meta.get("model_name") if net else None,
        "device": args.device if net else "cpu",
        "resolution": args.res,
        "tta": tta,
        "scalable": args.scalable,
        "num_images": obj.num_images,
        "images_used": obj.image_names,
        "time_s": round(elapsed, 4),
        "image_size": [int(obj.mask.shape[1]), int(obj.mask.shape[0])],
        "constant_map": constant,
        "expected_error_deg": stated.summary() if stated else None,
        "expected_error_model": model_path(net.checkpoint).name if stated else None,
        **({"expected_error_note": why} if stated is None else {}),
    }
    with taken_back_on_failure(args.out / name):
        write_prediction(args.out / name, normals, info)
        if stated is not None:
            write_stated(args.out / name, stated)
        else:  # an earlier run's stated error (claimed before any work) is not this map's
            for f in EXPECTED_ERROR_FILES:
                (args.out / name / f).unlink(missing_ok=True)
    log.info("%s: %s in %.2f s", name, args.method, elapsed)


if __name__ == "__main__":  # Ctrl-C kills the work whole (scenes.cli.supervise)
    sys.exit(run_supervised("unips.predict", main))
