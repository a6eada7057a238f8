"""Predict surface normals for one object folder or a directory of them.

    python -m unips.predict --method {model,least-squares,sh-uncalibrated} [--checkpoint CKPT]
                            --input PATH --out DIR [--max-images K] [--device cpu] [--res R] [--tta N]

For each object, ``DIR/<object>/`` receives ``normal.png`` (16-bit, (n + 1) / 2, the full original
frame, background 32768), ``normal.exr`` (float32), ``normal_vis.png`` (8-bit picture) and
``predict.json`` (method, checkpoint, images used, time). ``<object>`` is the input folder's name minus
a trailing ``.data`` (``foo.data`` -> ``foo``; DiLiGenT's ``ballPNG`` stays ``ballPNG``), the name
`unips.evaluate` matches ground truth by.

Inference itself is the library `unips.inference` (this module parses arguments and writes files).
``--method model`` loads a network with `unips.checkpoint.load_model`; without ``--checkpoint`` it
uses the shipped ``unips/weights/glc-tiny.safetensors`` and refuses to run when that file is absent
(never random weights). The network sees the UniPS preprocessing (`unips.preprocess.prepare`), at the
crop's own size or at ``--res R``, and its output is put back into the original frame. ``--tta N``
averages the network's predictions over N flipped / transposed views of the object (test-time
augmentation, N forward passes; `unips.inference.model_normals`).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from scenes.cli import INPUT_ERRORS, UsageError, UsageErrorParser, one_line, report_error
from scenes.objfolder import PREDICTION_FILES, object_name, write_normal_exr, write_normal_map, write_normal_visual
from scenes.layouts import detect_layout
from unips.data import find_objects, load_object
from unips.inference import DEFAULT_TTA, METHODS, TTA_VIEWS, check_tta, load_network, predict_object

log = logging.getLogger(__name__)


CONSTANT_DEG = 0.5
"""A prediction whose normals inside the mask all lie within this angle (degrees) of their mean is flagged
as constant (`predict.json` "constant_map", a warning): a degenerate result unless the object is a plane."""


def constant_map(normals: np.ndarray, mask: np.ndarray) -> bool:
    """True when every normal inside the mask is within CONSTANT_DEG of their mean direction."""
    inside = normals[mask].astype(np.float64)
    if len(inside) < 2:
        return False
    mean = inside.mean(axis=0)
    norm = np.linalg.norm(mean)
    if norm < 1e-8:
        return False
    cos = inside @ (mean / norm) / np.maximum(np.linalg.norm(inside, axis=1), 1e-12)
    return bool(np.all(cos >= np.cos(np.radians(CONSTANT_DEG))))


def check_out_folder(folder: Path) -> None:
    """Refuse to write into `folder` when it holds normal maps that unips.predict did not write (no
    predict.json beside them): files this command did not create are never replaced."""
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"--out: {str(folder)!r} is an existing file, expected a folder for the prediction")
    if folder.is_dir() and not (folder / "predict.json").is_file():
        theirs = [f for f in ("normal.png", "normal_vis.png", *PREDICTION_FILES) if (folder / f).exists()]
        if theirs:
            raise UsageError(f"--out: {str(folder)!r} already holds {', '.join(sorted(set(theirs)))} not written by "
                             "unips.predict (no predict.json); use another --out")


def write_prediction(out_dir: Path, normals: np.ndarray, info: dict[str, Any]) -> None:
    """Write normal.png, normal.exr, normal_vis.png and predict.json into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    write_normal_map(out_dir / "normal.png", normals)
    write_normal_exr(out_dir / "normal.exr", normals)
    write_normal_visual(out_dir / "normal_vis.png", normals)
    (out_dir / "predict.json").write_text(json.dumps(info, indent=2, sort_keys=True))


def build_parser() -> argparse.ArgumentParser:
    p = UsageErrorParser(prog="python -m unips.predict", description=__doc__.split("\n\n")[0])
    p.add_argument("--method", required=True, choices=METHODS, help="network or classical baseline")
    p.add_argument("--checkpoint", type=Path, default=None,
                   help="model file (.safetensors with its .json, or a training .pt); --method model only")
    p.add_argument("--input", required=True, type=Path, help="an object folder or a directory of them")
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument("--max-images", type=int, default=None, help="use the first K images of each object")
    p.add_argument("--device", default="cpu", help="torch device for --method model (cpu, cuda, cuda:0)")
    p.add_argument("--res", type=int, default=None,
                   help="working resolution of the network (the crop is resized to R x R); --method model only")
    p.add_argument("--tta", type=int, default=None,
                   help=f"views averaged (test-time augmentation by flips and transposes), one of "
                        f"{', '.join(map(str, TTA_VIEWS))}; N forward passes (default {DEFAULT_TTA}); --method model only")
    return p


def _check_args(args: argparse.Namespace) -> None:
    if args.max_images is not None and args.max_images < 1:
        raise UsageError(f"--max-images: must be >= 1, got {args.max_images}")
    if args.res is not None and args.res < 8:
        raise UsageError(f"--res: must be >= 8, got {args.res}")
    if args.tta is not None:
        check_tta(args.tta, "--tta")
    if args.method != "model":
        for flag, value in (("--checkpoint", args.checkpoint), ("--res", args.res), ("--tta", args.tta)):
            if value is not None:
                raise UsageError(f"{flag}: only used with --method model, not --method {args.method}")


def main(argv: list[str] | None = None) -> int:
    """One object: a failure is one line `error: ...`, exit 2. A dataset: a failed object is recorded, the others
    go on, the failures are listed at the end (`failed NAME: reason`) and the exit status is 1."""
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    failures: list[tuple[str, str]] = []
    try:
        args = build_parser().parse_args(argv)
        _check_args(args)
        if args.out.exists() and not args.out.is_dir():
            raise UsageError(f"--out: {str(args.out)!r} is an existing file, expected a folder")
        folders = find_objects(args.input)
        single = detect_layout(args.input) is not None
        names = [object_name(f) for f in folders]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise UsageError(f"--input: several object folders share the name(s) {dup} (e.g. foo and foo.data)")
        for name in names:
            check_out_folder(args.out / name)
        net = load_network(args.checkpoint, args.device) if args.method == "model" else None
        from tqdm import tqdm

        for folder, name in tqdm(list(zip(folders, names)), desc="objects", unit="obj", file=sys.stderr,
                                 disable=len(folders) < 2):
            try:
                _predict_one(args, net, folder, name)
            except (*INPUT_ERRORS, OSError, np.linalg.LinAlgError) as exc:
                if single:
                    raise
                failures.append((name, one_line(exc)))
                log.debug("%s failed", name, exc_info=True)
    except (*INPUT_ERRORS, OSError, np.linalg.LinAlgError) as exc:
        return report_error(exc)
    if failures:
        for name, why in failures:
            print(f"failed {name}: {why}", file=sys.stderr)
        print(f"error: {len(failures)} of {len(folders)} object(s) failed with --method {args.method}: "
              f"{', '.join(n for n, _ in failures)} (the others were written)", file=sys.stderr)
        return 1
    return 0


def _predict_one(args: argparse.Namespace, net, folder: Path, name: str) -> None:
    obj = load_object(folder, max_images=args.max_images)
    start = time.perf_counter()
    tta = (args.tta or DEFAULT_TTA) if net else None
    normals = predict_object(obj, args.method, net=net, res=args.res, tta=tta or 1)
    elapsed = time.perf_counter() - start
    constant = constant_map(normals, obj.mask)
    if constant:
        print(f"warning: {name}: --method {args.method} returned a constant normal map (all normals within "
              f"{CONSTANT_DEG} deg of one direction): degenerate unless the object is a plane; flagged in predict.json",
              file=sys.stderr)
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
        "num_images": obj.num_images,
        "images_used": obj.image_names,
        "time_s": round(elapsed, 4),
        "image_size": [int(obj.mask.shape[1]), int(obj.mask.shape[0])],
        "constant_map": constant,
    }
    write_prediction(args.out / name, normals, info)
    log.info("%s: %s in %.2f s", name, args.method, elapsed)


if __name__ == "__main__":
    sys.exit(main())
