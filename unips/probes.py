"""Probes: does a model use the images, or only the object's outline?

A photometric stereo network must get its accuracy from the pixel intensities. Each probe feeds the
same object to the model with the photometric information removed in one way, and the figure that
says the model does photometric stereo is the **photometric gain**:

    gain = error(mask only) - error(all images)

Probes (inputs are prepared tensors: images `(K, 3, H, W)`, mask `(1, H, W)` in {0, 1}):
- ``all``: the K images as given;
- ``one``: the first image only (K = 1);
- ``mask``: every image replaced by the mask (1 inside, 0 outside): the outline and nothing else;
- ``shuffled``: at every pixel, its K observations permuted independently (seeded), so a pixel's
  intensities no longer match the lighting of the image they sit in; only for K >= 2.
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Sequence

import numpy as np
import torch

PROBE_TITLES = {"all": "all images", "one": "one image", "mask": "mask only", "shuffled": "shuffled"}
"""The probes, in table order, with their column titles (every probe table reads these)."""
PROBES = tuple(PROBE_TITLES)


def probe_images(images: torch.Tensor, mask: torch.Tensor, probe: str, seed: int = 0) -> torch.Tensor:
    """The model input of `probe` for images `(K, 3, H, W)` and mask `(1, H, W)`."""
    if probe == "all":
        return images
    if probe == "one":
        return images[:1]
    if probe == "mask":
        return mask.to(images.dtype)[None].expand(images.shape[0], 3, *mask.shape[-2:]).contiguous()
    if probe == "shuffled":
        k, c, h, w = images.shape
        gen = torch.Generator().manual_seed(int(seed))
        # One independent permutation of the K observations per pixel: argsort of random keys.
        order = torch.argsort(torch.rand(k, h * w, generator=gen), dim=0).to(images.device)  # (K, H*W)
        flat = images.reshape(k, c, h * w)
        return torch.gather(flat, 0, order[:, None, :].expand(k, c, h * w)).reshape(k, c, h, w)
    raise ValueError(f"probe: got {probe!r}, expected one of {', '.join(PROBES)}")


def applicable(probe: str, num_images: int) -> bool:
    """Whether `probe` means anything for an object with `num_images` images."""
    return probe != "shuffled" or num_images >= 2


def eval_pixels(mask: torch.Tensor, count: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Row and column indices of the masked pixels to score: all (count <= 0) or a seeded subset."""
    ys, xs = torch.nonzero(mask[0] > 0.5, as_tuple=True)
    if 0 < count < ys.numel():
        gen = torch.Generator().manual_seed(int(seed))
        keep = torch.randperm(ys.numel(), generator=gen)[:count].sort().values
        ys, xs = ys[keep], xs[keep]
    return ys, xs


@torch.no_grad()
def probe_object(model: torch.nn.Module, images: torch.Tensor, mask: torch.Tensor, normals: torch.Tensor,
                 probes: Sequence[str] = PROBES, pixels: int = 0, seed: int = 0,
                 device: torch.device | str = "cpu") -> dict[str, float]:
    """Mean angular error (degrees) of `model` on one prepared object under each probe.

    images `(K, 3, H, W)`, mask `(1, H, W)`, normals `(3, H, W)`; `pixels` > 0 scores a seeded subset
    of that many masked pixels (the encoder still sees the whole image). Probes that do not apply
    (shuffled with K = 1) are left out of the result.
    """
    from scenes.metrics import angular_error_deg
    from unips.models.glc import pixel_centre_coords

    ys, xs = eval_pixels(mask, pixels, seed)
    if ys.numel() == 0:
        raise ValueError("mask: is empty, nothing to score")
    h, w = mask.shape[-2:]
    coords = pixel_centre_coords(ys, xs, h, w)[None].to(device)  # (1, N, 2)
    gt = normals[:, ys, xs].T  # (N, 3)
    m = mask[None].to(device, torch.float32)  # (1, 1, H, W)
    out = {}
    for probe in probes:
        if not applicable(probe, images.shape[0]):
            continue
        x = probe_images(images.to(torch.float32), mask, probe, seed)[None].to(device)  # (1, k, 3, H, W)
        ctx = model.encode(x, m)
        pred = decode_in_chunks(model, ctx, x, m, coords)[0].cpu()  # (N, 3)
        # The project's one angular-error rule, on the scored pixels as an (N, 1) "image".
        err = angular_error_deg(pred.numpy()[:, None], gt.numpy()[:, None], np.ones((gt.shape[0], 1), bool))
        out[probe] = float(err.mean())
    return out


def decode_in_chunks(model: torch.nn.Module, contexts: torch.Tensor, images: torch.Tensor, mask: torch.Tensor,
                     coords: torch.Tensor) -> torch.Tensor:
    """`model.decode_pixels` over `coords (1, N, 2)` in chunks of the model's `pixel_chunk`."""
    chunk = int(getattr(getattr(model, "config", None), "pixel_chunk", 10000))
    parts = [model.decode_pixels(contexts, images, mask, coords[:, i:i + chunk])
             for i in range(0, coords.shape[1], chunk)]
    return torch.cat(parts, dim=1)


def summarise(per_object: Mapping[str, Mapping[str, float]], families: Mapping[str, str | None]
              ) -> dict[str, Any]:
    """Means per probe overall and per light family, with the photometric gain.

    per_object: name -> {probe: error}; families: name -> light family (None: "unknown").
    Returns {"mean": {probe: e}, "gain": g, "one_minus_all": d, "n": N, "families": {fam: {...}}}.
    """
    def block(names: Iterable[str]) -> dict[str, Any]:
        names = list(names)
        means = {}
        for probe in PROBES:
            vals = [per_object[n][probe] for n in names if probe in per_object[n]]
            if vals:
                means[probe] = float(np.mean(vals))
        res: dict[str, Any] = {"mean": means, "n": len(names)}
        if "mask" in means and "all" in means:
            res["gain"] = means["mask"] - means["all"]
        if "one" in means and "all" in means:
            res["one_minus_all"] = means["one"] - means["all"]
        return res

    out = block(per_object)
    fams: dict[str, list[str]] = {}
    for name in per_object:
        fams.setdefault(families.get(name) or "unknown", []).append(name)
    out["families"] = {f: block(v) for f, v in sorted(fams.items())}
    return out


def format_table(summary: Mapping[str, Any]) -> str:
    """Markdown table: rows per family + all, columns: the probes (`PROBE_TITLES`) and the gain."""
    from scenes.report.tables import markdown_table

    rows = []
    for fam, b in [*summary.get("families", {}).items(), ("all", summary)]:
        m = b["mean"]
        rows.append([fam, b["n"], *(f"{m[p]:.1f}" if p in m else "-" for p in PROBES),
                     f"{b['gain']:.1f}" if "gain" in b else "-"])
    return markdown_table(["family", "n", *PROBE_TITLES.values(), "photometric gain"], rows)
