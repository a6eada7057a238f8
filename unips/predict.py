"""Predict surface normals for one object folder or a directory of them.

    python -m unips.predict --method {model,least-squares,sh-uncalibrated} [--checkpoint CKPT]
                            --input PATH --out DIR [--max-images K] [--device cpu] [--res R]

For each object, ``DIR/<object>/`` receives ``normal.png`` (16-bit, (n + 1) / 2, the full original
frame, background 32768), ``normal.exr`` (float32), ``normal_vis.png`` (8-bit picture) and
``predict.json`` (method, checkpoint, images used, time). ``<object>`` is the input folder's name minus
a trailing ``.data`` (``foo.data`` -> ``foo``; DiLiGenT's ``ballPNG`` stays ``ballPNG``), the name
`unips.evaluate` matches ground truth by.

``--method model`` loads a network with `unips.checkpoint.load_model`; without ``--checkpoint`` it
uses the shipped ``unips/weights/glc-tiny.safetensors`` and refuses to run when that file is absent
(never random weights). The network sees the UniPS preprocessing (`unips.preprocess.prepare`), at the
crop's own size or at ``--res R``, and its output is put back into the original frame.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from unips.data import PSObject, find_objects, load_object, object_name

log = logging.getLogger(__name__)

METHODS = ("model", "least-squares", "sh-uncalibrated")
DEFAULT_WEIGHTS = "weights/glc-tiny.safetensors"  # inside the unips package


class CLIError(Exception):
    """A usage or input error the CLI reports as one line."""


def default_checkpoint() -> Path:
    """Path of the shipped default weights; CLIError when they are not shipped (yet)."""
    from importlib import resources

    ref = resources.files("unips").joinpath(DEFAULT_WEIGHTS)
    if not ref.is_file():
        raise CLIError(f"no shipped weights yet (unips/{DEFAULT_WEIGHTS} is missing); "
                       "pass --checkpoint PATH to a .safetensors or .pt model file")
    return Path(str(ref))


@dataclass
class LoadedModel:
    """A network ready for inference and where it came from."""

    model: Any  # torch.nn.Module in eval mode on `device`
    meta: dict[str, Any]  # from unips.checkpoint.load_model
    checkpoint: Path  # the file it was loaded from
    device: str  # torch device string


def load_network(checkpoint: str | Path | None, device: str = "cpu") -> LoadedModel:
    """Load a model file (or the shipped default) onto ``device``."""
    import torch

    from unips.checkpoint import load_model

    if device.startswith("cuda") and not torch.cuda.is_available():
        raise CLIError(f"--device {device}: CUDA is not available on this machine")
    path = Path(checkpoint) if checkpoint is not None else default_checkpoint()
    model, meta = load_model(path, map_location=device)
    return LoadedModel(model=model.eval(), meta=dict(meta), checkpoint=path, device=device)


def run_model(net: LoadedModel, obj: PSObject, res: int | None = None, margin: int = 4) -> np.ndarray:
    """Normals (H, W, 3) of ``obj`` from the network, in the original frame, zero outside the mask."""
    import torch

    from unips.preprocess import prepare, resize_prepared, uncrop

    prepared = prepare(obj, margin=margin)
    work = resize_prepared(prepared, res) if res is not None else prepared
    images = torch.from_numpy(np.ascontiguousarray(work.images.transpose(0, 3, 1, 2)))[None]  # (1, K, 3, R, R)
    mask = torch.from_numpy(work.mask.astype(np.float32))[None, None]  # (1, 1, R, R)
    with torch.no_grad():
        out = net.model(images.to(net.device), mask.to(net.device))  # (1, 3, R, R)
    if tuple(out.shape) != (1, 3) + work.mask.shape:
        raise ValueError(f"model: returned shape {tuple(out.shape)}, expected (1, 3, {work.resolution}, "
                         f"{work.resolution})")
    n = out[0].permute(1, 2, 0).float().cpu().numpy()  # (R, R, 3)
    if not np.all(np.isfinite(n)):
        raise ValueError(f"model: produced non-finite normals for {obj.name}")
    norm = np.linalg.norm(n, axis=2, keepdims=True)
    n = np.where(work.mask[..., None] & (norm > 1e-8), n / np.maximum(norm, 1e-12), 0.0).astype(np.float32)
    return uncrop(n, prepared.crop, mask=obj.mask)


def predict_object(obj: PSObject, method: str, net: LoadedModel | None = None,
                   res: int | None = None) -> np.ndarray:
    """(H, W, 3) unit normals of ``obj`` by ``method`` (zero outside the mask)."""
    if method == "model":
        if net is None:
            raise ValueError("net: --method model needs a loaded network")
        return run_model(net, obj, res=res)
    from unips.baselines import run_baseline

    return run_baseline(method, obj)


def write_prediction(out_dir: Path, normals: np.ndarray, info: dict[str, Any]) -> None:
    """Write normal.png, normal.exr, normal_vis.png and predict.json into ``out_dir``."""
    from unips.normal_io import write_normal_exr, write_normal_png, write_normal_visual

    out_dir.mkdir(parents=True, exist_ok=True)
    write_normal_png(out_dir / "normal.png", normals)
    write_normal_exr(out_dir / "normal.exr", normals)
    write_normal_visual(out_dir / "normal_vis.png", normals)
    (out_dir / "predict.json").write_text(json.dumps(info, indent=2, sort_keys=True))


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one-line errors instead of usage + message
        raise CLIError(message)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="python -m unips.predict", description=__doc__.split("\n\n")[0])
    p.add_argument("--method", required=True, choices=METHODS, help="network or classical baseline")
    p.add_argument("--checkpoint", type=Path, default=None,
                   help="model file (.safetensors with its .json, or a training .pt); --method model only")
    p.add_argument("--input", required=True, type=Path, help="an object folder or a directory of them")
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument("--max-images", type=int, default=None, help="use the first K images of each object")
    p.add_argument("--device", default="cpu", help="torch device for --method model (cpu, cuda, cuda:0)")
    p.add_argument("--res", type=int, default=None,
                   help="working resolution of the network (the crop is resized to R x R); --method model only")
    return p


def _check_args(args: argparse.Namespace) -> None:
    if args.max_images is not None and args.max_images < 1:
        raise CLIError(f"--max-images: must be >= 1, got {args.max_images}")
    if args.res is not None and args.res < 8:
        raise CLIError(f"--res: must be >= 8, got {args.res}")
    if args.method != "model":
        for flag, value in (("--checkpoint", args.checkpoint), ("--res", args.res)):
            if value is not None:
                raise CLIError(f"{flag}: only used with --method model, not --method {args.method}")


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        args = build_parser().parse_args(argv)
        _check_args(args)
        folders = find_objects(args.input)
        names = [object_name(f) for f in folders]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise CLIError(f"--input: several object folders share the name(s) {dup} (e.g. foo and foo.data)")
        net = load_network(args.checkpoint, args.device) if args.method == "model" else None
        from tqdm import tqdm

        for folder, name in tqdm(list(zip(folders, names)), desc="objects", unit="obj", file=sys.stderr,
                                 disable=len(folders) < 2):
            obj = load_object(folder, max_images=args.max_images)
            start = time.perf_counter()
            normals = predict_object(obj, args.method, net=net, res=args.res)
            elapsed = time.perf_counter() - start
            info = {
                "object": name,
                "input": str(folder.resolve()),
                "layout": obj.layout,
                "method": args.method,
                "checkpoint": str(net.checkpoint.resolve()) if net else None,
                "model_name": net.meta.get("model_name") if net else None,
                "device": args.device if net else "cpu",
                "resolution": args.res,
                "num_images": obj.num_images,
                "images_used": obj.image_names,
                "time_s": round(elapsed, 4),
                "image_size": [int(obj.mask.shape[1]), int(obj.mask.shape[0])],
            }
            write_prediction(args.out / name, normals, info)
            log.info("%s: %s in %.2f s", name, args.method, elapsed)
    except (CLIError, ValueError, FileNotFoundError, OSError) as exc:
        msg = str(exc).replace("\n", " ")
        print(f"error: {msg}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
