"""The data of `unips.train`: cached samples, the batch of each step, the loss, and the probes of a validation.

A sample is one object folder prepared once (crop, normalise, resize to the working resolution) and kept
in memory. The batch of step `s` is a pure function of (samples, seed, s) and the settings: every random
choice (objects, image subsets, augmentation, pixels) comes from generators seeded by `(seed, s)`, so a
resumed run draws the same batches. The loss is the MSE between unit normals on masked points of the
canonical grid and on random masked pixels. `probe_samples` is one validation: the probes of
`unips.probes` (all images, one image, mask only, shuffled) over the cached validation objects.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import torch
import torch.nn.functional as F


@dataclass
class Sample:
    """One prepared object at the working resolution R, cached in memory."""

    name: str  # object name
    images: torch.Tensor  # (K, 3, R, R) float16 (halves the cache; values are ~1 after normalisation)
    mask: torch.Tensor  # (1, R, R) float32 in {0, 1}
    normals: torch.Tensor | None  # (3, R, R) float32 unit vectors inside the mask, 0 outside
    light_family: str | None  # lighting family from scene.json, if known
    level: int | None = None  # complexity level from scene.json (`wildgen.make --level`), if known
    digest: str = ""  # sha256 of the object as decoded (`content_digest`), set for cached samples: compared on resume

    @property
    def num_images(self) -> int:
        return int(self.images.shape[0])


def to_tensors(images: np.ndarray, mask: np.ndarray, normals: np.ndarray | None
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
    """Prepared arrays (K, R, R, 3) / (R, R) / (R, R, 3) -> channels-first float32 tensors."""
    imgs = torch.from_numpy(np.ascontiguousarray(images, dtype=np.float32)).permute(0, 3, 1, 2)  # (K, 3, R, R)
    m = torch.from_numpy(np.ascontiguousarray(mask, dtype=np.float32))[None]  # (1, R, R)
    n = None
    if normals is not None:
        n = torch.from_numpy(np.ascontiguousarray(normals, dtype=np.float32)).permute(2, 0, 1)  # (3, R, R)
        n = F.normalize(n, dim=0, eps=1e-8) * m  # unit inside the mask, 0 outside
    return imgs.contiguous(), m, None if n is None else n.contiguous()


def data_roots(data: str | Path, arg: str = "--data") -> list[Path]:
    """The entries of a --data value: one dataset directory or shard source (`unips.shard_data`), or several
    separated by commas (commas inside a shard pattern's braces, {a,b}, do not separate; an existing path whose
    name holds one is that one entry)."""
    from unips.shard_data import source_label

    parts, depth, start, text = [], 0, 0, str(data)
    if "," in text and os.path.exists(text):  # one folder whose name holds a comma ('set,1'): taken whole
        return [Path(text)]
    for i, c in enumerate(text + ","):
        depth += (c == "{") - (c == "}")
        if c == "," and depth <= 0:
            parts.append(text[start:i])
            start = i + 1
    if len(parts) > 1 and not all(p.strip() for p in parts):  # a stray comma: a path left out, or a typo
        raise ValueError(f"{arg}: {str(data)!r} holds an empty entry (a comma at an end, or two in a row); expected "
                         "paths separated by single commas")
    roots = [Path(p.strip()) for p in parts if p.strip()]
    if not roots:
        raise ValueError(f"{arg}: {str(data)!r} names no directory")
    names = [source_label(r) for r in roots]
    if len(set(names)) != len(names):
        raise ValueError(f"{arg}: {str(data)!r} names two directories with the same name (object names would collide)")
    return roots


def prepare_sample(obj: Any, res: int, require_normals: bool = True, name: str | None = None,
                   where: str = "--data") -> Sample:
    """The training sample of a loaded object (`unips.data.PSObject`): cropped, normalised, resized to `res`.
    `where`: the flag and source it came from, named in its error."""
    from unips.preprocess import prepare, resize_prepared

    if require_normals and obj.normals is None:
        raise ValueError(f"{where}: object {obj.name!r} has no ground-truth normals (normal.tif); training needs them")
    prep = resize_prepared(prepare(obj, margin=4), res, "--res")
    imgs, m, n = to_tensors(prep.images, prep.mask, prep.normals)
    return Sample(name or obj.name, imgs.to(torch.float16), m, n, obj.light_family, obj.level)


def content_digest(obj: Any) -> str:
    """sha256 of a loaded object's mask, ground-truth normals and every 7th pixel of its images, as decoded from
    its files: exact on every machine (integer files decode exactly), so two objects swapped under their names,
    or images rendered anew, are told from the data a checkpoint was trained on (`data_change`)."""
    h = hashlib.sha256()
    for a in (obj.mask, obj.normals, None if obj.images is None else obj.images[:, ::7, ::7]):
        h.update(b"-" if a is None else np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def load_samples(root: str | Path, res: int, require_normals: bool = True, arg: str = "--data") -> list[Sample]:
    """Load, crop, normalise and resize every object under `root` (one dataset directory or shard source, or
    several separated by commas: their objects are pooled and named DIRNAME/OBJECT). Shards are read in the
    order given (`unips.shard_data.iter_objects`): the samples of shards exported from a dataset are those of its
    folders, in the same order."""
    from unips.data import find_objects, load_object
    from unips.shard_data import is_shard_source, iter_objects, source_label

    roots = data_roots(root, arg)
    samples, seen = [], {}
    for r in roots:
        if is_shard_source(r):
            objects = iter_objects(r, arg)
        else:
            folders = find_objects(r, arg)  # FileNotFoundError naming the path when there is none
            for p in folders:  # one object through two names (a link) would be trained on twice
                first = seen.setdefault(os.path.realpath(p), p)
                if first is not p:
                    raise ValueError(f"{arg}: {str(p)!r} and {str(first)!r} are one object folder (one is a link to "
                                     "the other): it would be trained on twice; remove the link or that entry")
            objects = (load_object(p, arg=arg) for p in folders)
        for obj in objects:
            name = obj.name if len(roots) == 1 else f"{source_label(r)}/{obj.name}"
            sample = prepare_sample(obj, res, require_normals, name, f"{arg}: {str(r)!r}")
            sample.digest = content_digest(obj)  # once, for the cache (streamed samples: their shards' checksums)
            samples.append(sample)
    return samples


def describe_data(samples: Sequence[Any], root: str | Path, res: int, parts: Sequence[str] | None = None
                  ) -> dict[str, Any]:
    """Data description stored in checkpoints (and compared on resume, `data_change`); its digest is of `parts`
    (streamed shards: their checksums), by default of the samples' own digests."""
    roots = [str(r.resolve()) for r in data_roots(root)]
    digest = hashlib.sha256("\n".join([s.digest for s in samples] if parts is None else parts).encode()).hexdigest()
    return {"root": roots[0] if len(roots) == 1 else roots, "res": res, "objects": [s.name for s in samples],
            "images": [s.num_images for s in samples], "digest": digest}


def data_change(saved: dict[str, Any], now: dict[str, Any]) -> str | None:
    """How the data described by `now` differs from the data a checkpoint was trained on (`saved`, both
    `describe_data`), or None when it is the same (a record an older checkpoint lacks is not compared)."""
    if saved.get("objects") != now["objects"]:
        return "other object names"
    if "images" in saved and saved["images"] != now["images"]:
        i = next(i for i, (a, b) in enumerate(zip(saved["images"], now["images"])) if a != b)
        return f"object {now['objects'][i]!r} has {now['images'][i]} images, {saved['images'][i]} in the checkpoint"
    if "digest" in saved and saved["digest"] != now["digest"]:
        return "the same names hold other images, masks or ground-truth normals"
    return None


# -- batches ----------------------------------------------------------------------------------

@dataclass
class Batch:
    """One training batch; every field on the training device."""

    images: torch.Tensor  # (B, k, 3, R, R) float32
    mask: torch.Tensor  # (B, 1, R, R) float32
    coords: torch.Tensor  # (B, N, 2) decode coordinates: canonical grid points, then random pixels
    target: torch.Tensor  # (B, N, 3) ground-truth unit normals at coords
    weight: torch.Tensor  # (B, N) 1 for a valid canonical point / random pixel, 0 for padding
    is_canonical: torch.Tensor  # (N,) bool, True for the canonical-grid part


def step_rng(seed: int, step: int, stream: int) -> np.random.Generator:
    """Generator for one purpose (`stream`) of one step, independent of everything else."""
    return np.random.default_rng([int(seed), int(step), int(stream)])


def batch_indices(seed: int, step: int, batch: int, n: int) -> list[int]:
    """Object indices of a step: consecutive slots of per-epoch permutations seeded by (seed, epoch)."""
    out = []
    for i in range(step * batch, (step + 1) * batch):
        epoch, pos = divmod(i, n)
        perm = np.random.default_rng([int(seed), 1_000_003, epoch]).permutation(n)
        out.append(int(perm[pos]))
    return out


def canonical_points(mask: torch.Tensor, normals: torch.Tensor, size: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Centres of the canonical size x size grid lying fully inside the mask.

    Returns coords `(n, 2)` and target normals `(n, 3)` (bilinear, renormalised). A point is kept
    when the bilinearly sampled mask is 1, i.e. all working-resolution neighbours are inside.
    """
    c = (2.0 * torch.arange(size, dtype=torch.float32) + 1.0) / size - 1.0
    gy, gx = torch.meshgrid(c, c, indexing="ij")
    grid = torch.stack([gx, gy], dim=-1).reshape(1, 1, -1, 2)  # (1, 1, s*s, 2)
    m = F.grid_sample(mask[None], grid, mode="bilinear", align_corners=False)[0, 0, 0]  # (s*s,)
    keep = m >= 0.999
    nrm = F.grid_sample(normals[None], grid, mode="bilinear", align_corners=False)[0, :, 0].T  # (s*s, 3)
    return grid[0, 0][keep], F.normalize(nrm[keep], dim=-1, eps=1e-8)


def random_pixels(mask: torch.Tensor, normals: torch.Tensor, count: int,
                  rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """`count` random masked pixels (with replacement only if fewer exist): coords `(count, 2)`, normals."""
    from unips.models.glc import pixel_centre_coords

    h, w = mask.shape[-2:]
    idx = torch.nonzero(mask[0].reshape(-1) > 0.5)[:, 0].numpy()
    pick = rng.choice(idx, size=count, replace=len(idx) < count)
    ys, xs = torch.from_numpy(pick // w), torch.from_numpy(pick % w)
    return pixel_centre_coords(ys, xs, h, w), normals[:, ys, xs].T


def curriculum_pool(levels: Sequence[int | None], step: int, steps: int, fraction: float) -> list[int]:
    """The sample indices step `step` of `steps` may draw under the curriculum: the first `fraction` of the steps
    is split evenly into one stage per distinct level; stage j allows the j lowest levels; after that, all.
    A ValueError names --curriculum when an object has no recorded level."""
    missing = [i for i, lv in enumerate(levels) if lv is None]
    if missing:
        raise ValueError(f"--curriculum: {len(missing)} of {len(levels)} objects have no recorded complexity level "
                         "(scene.json level; render them with wildgen.make --level N)")
    distinct = sorted(set(levels))
    span = fraction * steps
    stage = len(distinct) - 1 if step >= span else min(int(step * len(distinct) / span), len(distinct) - 1)
    return [i for i, lv in enumerate(levels) if lv <= distinct[stage]]


def make_batch(samples: Sequence[Sample], step: int, *, seed: int, batch: int, min_images: int,
               max_images: int, pixels: int, canonical: int, augment: bool = True,
               canonical_max: int = 0, interior_crop: float = 0.0, rank: int = 0, world: int = 1,
               pool: Sequence[int] | None = None) -> Batch:
    """The batch of `step`, a pure function of (samples, step, seed and the settings).

    `canonical_max` > 0 keeps a random subset of at most that many canonical-grid points per object.
    `interior_crop` is the probability that an object is replaced by a square cut from inside its mask
    (`unips.augment.interior_crop`); at 0 no draw is made, so older runs keep their trajectories.
    With `world` > 1 processes, rank `rank` gets objects rank, rank + world, ... of the global batch
    (every random draw is made for the whole batch, so the union over ranks is the 1-process batch).
    `pool` (`curriculum_pool`) restricts the objects drawn to those indices; None: all.
    """
    from unips.augment import apply_augmentation, sample_augmentation
    from unips.augment import interior_crop as cut_interior

    if pool is None:
        idx = batch_indices(seed, step, batch, len(samples))
    else:  # per-epoch permutations of the pool (its size names the stage, so each stage has its own order)
        idx = [pool[j] for j in batch_indices(seed * 1_000_033 + len(pool), step, batch, len(pool))]
    rng = step_rng(seed, step, 0)
    k_max = min(max_images, min(samples[i].num_images for i in idx))
    k = int(rng.integers(min_images, k_max + 1))
    imgs, masks, can, rnd = [], [], [], []
    for j, i in enumerate(idx):
        s = samples[i]
        subset = np.sort(rng.choice(s.num_images, size=k, replace=False))
        x = s.images[torch.from_numpy(subset)].to(torch.float32)
        m, n = s.mask, s.normals
        if augment:
            x, m, n = apply_augmentation(sample_augmentation(rng, k), x, m, n)
        if interior_crop > 0 and rng.random() < interior_crop:
            cut = cut_interior(x, m, n, rng)
            if cut is not None:
                x, m, n = cut
        cc, cn = canonical_points(m, n, canonical)
        if 0 < canonical_max < cc.shape[0]:
            keep = torch.from_numpy(np.sort(rng.choice(cc.shape[0], size=canonical_max, replace=False)))
            cc, cn = cc[keep], cn[keep]
        rp = random_pixels(m, n, pixels, rng)
        if j % world != rank:
            continue  # drawn anyway so that every rank's generator stays in step
        imgs.append(x)
        masks.append(m)
        can.append((cc, cn))
        rnd.append(rp)
    n_can = max(1, max(c.shape[0] for c, _ in can))
    coords, target, weight = [], [], []
    for (cc, cn), (rc, rn) in zip(can, rnd):
        pad = n_can - cc.shape[0]
        wc = torch.cat([torch.ones(cc.shape[0]), torch.zeros(pad)])
        # Pad with copies of the first random pixel (weight 0) so all samples share N.
        cc = torch.cat([cc, rc[:1].expand(pad, 2)])
        cn = torch.cat([cn, rn[:1].expand(pad, 3)])
        coords.append(torch.cat([cc, rc]))
        target.append(torch.cat([cn, rn]))
        weight.append(torch.cat([wc, torch.ones(rc.shape[0])]))
    is_can = torch.cat([torch.ones(n_can, dtype=torch.bool), torch.zeros(pixels, dtype=torch.bool)])
    return Batch(torch.stack(imgs), torch.stack(masks), torch.stack(coords), torch.stack(target),
                 torch.stack(weight), is_can)


def normal_loss(pred: torch.Tensor, batch: Batch) -> tuple[torch.Tensor, dict[str, float]]:
    """MSE between unit normals, averaged separately on the canonical grid and the random pixels."""
    err = ((pred - batch.target) ** 2).mean(dim=-1) * batch.weight  # (B, N)
    wc, wr = batch.weight[:, batch.is_canonical], batch.weight[:, ~batch.is_canonical]
    lc = err[:, batch.is_canonical].sum() / wc.sum().clamp_min(1.0)
    lr = err[:, ~batch.is_canonical].sum() / wr.sum().clamp_min(1.0)
    loss = lc + lr
    return loss, {"loss": float(loss.detach()), "loss_canonical": float(lc.detach()), "loss_random": float(lr.detach())}


# -- probes -----------------------------------------------------------------------------------

@torch.no_grad()
def probe_samples(model: torch.nn.Module, samples: Sequence[Sample], max_images: int, device: torch.device,
             probes: Sequence[str] = ("all",), pixels: int = 0, seed: int = 0) -> dict[str, Any]:
    """Probe errors (degrees) over the validation objects, overall and per light family.

    Each object uses its first `max_images` images at the working resolution; `pixels` > 0 scores a
    fixed seeded subset of that many masked pixels per object. Returns `unips.probes.summarise`'s
    dict plus "mean" (all images, the model-selection figure) and per-object errors.
    """
    from unips.probes import probe_object, summarise

    was_training = model.training
    model.eval()
    per_object = {}
    for i, s in enumerate(samples):
        per_object[s.name] = probe_object(model, s.images[:max_images], s.mask, s.normals, probes=probes,
                                          pixels=pixels, seed=seed + i, device=device)
    model.train(was_training)
    res = summarise(per_object, {s.name: s.light_family for s in samples})
    res["probes"] = res.pop("mean")
    res["mean"] = res["probes"]["all"]
    res["objects"] = per_object
    return res


def count_dataset_images(data: str, flag: str) -> tuple[int, int]:
    """(objects, images) under the dataset directories of --data / --val, counted without reading an image
    (shards: from their index)."""
    from scenes.folder.layouts import detect_layout, find_object_folders, layout_named
    from unips.shard_data import count_images, is_shard_source
    from unips.train_data import data_roots

    objects = images = 0
    for root in data_roots(data):
        if is_shard_source(root):
            more = count_images(root, flag)
            objects, images = objects + more[0], images + more[1]
            continue
        for folder in find_object_folders(root, flag):
            layout = detect_layout(folder)
            objects += 1
            try:
                images += len(layout_named(layout).images(folder)) if layout else 0
            except ValueError as exc:  # a listing of the folder that cannot be read (filenames.txt)
                raise ValueError(f"{flag}: {exc}") from None
    return objects, images
