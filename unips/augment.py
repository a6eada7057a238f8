"""Training augmentations of GLC-UniPS, applied consistently to images, mask and normals.

Frame: camera x right, y up, z toward the camera; image rows go down (-y), columns right (+x).
A spatial operation on the image is a reflection of the scene, so it acts on normals (and on light
directions) by a 3x3 matrix:
- horizontal flip (columns reversed): x -> -x, so n -> (-n_x, n_y, n_z);
- vertical flip (rows reversed): y -> -y, so n -> (n_x, -n_y, n_z);
- transpose (row and column swapped): pixel (row i, col j) -> (row j, col i), i.e. (x, y) = (j, -i)
  -> (i, -j) = (-y, -x), so n -> (-n_y, -n_x, n_z).
All three matrices are orthogonal, so Lambertian shading n . l is unchanged when normals and lights
transform together; `tests/test_train.py` checks this against analytic renderings.
Per-image RGB permutation changes only the images (reflectance is not predicted).
Tensors are channels first: images `(K, 3, H, W)`, mask `(1, H, W)` or `(H, W)`, normals `(3, H, W)`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np
import torch

RNG = Union[np.random.Generator, torch.Generator]

# Action of each spatial operation on 3-vectors (normals, light directions) in the camera frame.
HFLIP_MATRIX = np.diag([-1.0, 1.0, 1.0])
VFLIP_MATRIX = np.diag([1.0, -1.0, 1.0])
TRANSPOSE_MATRIX = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Augmentation:
    """One sampled augmentation; applied in the order transpose, horizontal flip, vertical flip."""

    transpose: bool = False  # swap the image axes
    hflip: bool = False  # reverse the columns
    vflip: bool = False  # reverse the rows
    channel_perms: tuple[tuple[int, int, int], ...] = ()  # per image RGB order; () keeps all

    def vector_matrix(self) -> np.ndarray:
        """3x3 matrix taking a camera-frame direction of the original scene to the augmented one."""
        m = np.eye(3)
        if self.transpose:
            m = TRANSPOSE_MATRIX @ m
        if self.hflip:
            m = HFLIP_MATRIX @ m
        if self.vflip:
            m = VFLIP_MATRIX @ m
        return m


def _uniform(rng: RNG, n: int) -> np.ndarray:
    if isinstance(rng, np.random.Generator):
        return rng.random(n)
    if isinstance(rng, torch.Generator):
        return torch.rand(n, generator=rng, dtype=torch.float64).numpy()
    raise ValueError(f"rng: got {type(rng).__name__}, expected numpy.random.Generator or torch.Generator")


def _permutation(rng: RNG) -> tuple[int, int, int]:
    if isinstance(rng, np.random.Generator):
        return tuple(int(v) for v in rng.permutation(3))
    return tuple(int(v) for v in torch.randperm(3, generator=rng))


def sample_augmentation(rng: RNG, num_images: int, p: float = 0.5) -> Augmentation:
    """Draw each augmentation with probability `p` (per image for the RGB permutation)."""
    if not 0.0 <= p <= 1.0:
        raise ValueError(f"p: got {p}, expected a probability in [0, 1]")
    if num_images < 1:
        raise ValueError(f"num_images: got {num_images}, expected >= 1")
    t, h, v = (_uniform(rng, 3) < p).tolist()
    perms = []
    for u in _uniform(rng, num_images).tolist():
        perms.append(_permutation(rng) if u < p else (0, 1, 2))
    return Augmentation(transpose=bool(t), hflip=bool(h), vflip=bool(v), channel_perms=tuple(perms))


def transform_normals(normals: torch.Tensor, matrix: np.ndarray) -> torch.Tensor:
    """Apply a 3x3 matrix to normals `(3, H, W)` (channels first)."""
    m = torch.as_tensor(matrix, dtype=normals.dtype, device=normals.device)
    return torch.einsum("ij,jhw->ihw", m, normals)


def apply_augmentation(aug: Augmentation, images: torch.Tensor, mask: torch.Tensor,
                       normals: torch.Tensor | None = None
                       ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
    """Augmented (images `(K, 3, H, W)`, mask, normals `(3, H, W)` or None)."""
    if images.ndim != 4 or images.shape[1] != 3:
        raise ValueError(f"images: got {tuple(images.shape)}, expected (K, 3, H, W)")
    if aug.channel_perms and len(aug.channel_perms) != images.shape[0]:
        raise ValueError(f"aug.channel_perms: {len(aug.channel_perms)} permutations for {images.shape[0]} images")
    if aug.transpose:
        images, mask = images.transpose(-1, -2), mask.transpose(-1, -2)
        if normals is not None:
            normals = transform_normals(normals.transpose(-1, -2), TRANSPOSE_MATRIX)
    if aug.hflip:
        images, mask = images.flip(-1), mask.flip(-1)
        if normals is not None:
            normals = transform_normals(normals.flip(-1), HFLIP_MATRIX)
    if aug.vflip:
        images, mask = images.flip(-2), mask.flip(-2)
        if normals is not None:
            normals = transform_normals(normals.flip(-2), VFLIP_MATRIX)
    if aug.channel_perms and any(p != (0, 1, 2) for p in aug.channel_perms):
        idx = torch.tensor(aug.channel_perms, device=images.device)  # (K, 3)
        images = torch.gather(images, 1, idx[:, :, None, None].expand_as(images))
    return images.contiguous(), mask.contiguous(), None if normals is None else normals.contiguous()


def augment(images: torch.Tensor, mask: torch.Tensor, normals: torch.Tensor | None, rng: RNG,
            p: float = 0.5) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
    """Sample an augmentation from `rng` and apply it (see module docstring for the conventions)."""
    return apply_augmentation(sample_augmentation(rng, images.shape[0], p), images, mask, normals)


DIHEDRAL = tuple(Augmentation(transpose=t, hflip=h, vflip=v)
                 for t, h, v in ((False, False, False), (False, True, False), (False, False, True),
                                 (False, True, True), (True, False, False), (True, True, False),
                                 (True, False, True), (True, True, True)))
"""The 8 symmetries of the square (rotations by 90 deg and reflections), identity first, ordered so that
the first 2 and 4 are closed sets (identity + horizontal flip; + vertical flip and their product):
the views of test-time augmentation (`unips.inference.run_model(tta=...)`)."""


def invert_normals(aug: Augmentation, normals: torch.Tensor) -> torch.Tensor:
    """Normals `(3, H, W)` predicted on augmented images, taken back to the original frame and pixel grid.

    The inverse of `apply_augmentation` on normals: the vector matrix's transpose (it is orthogonal),
    then the spatial operations undone in reverse order. Channel permutations do not act on normals.
    """
    n = transform_normals(normals, aug.vector_matrix().T)
    if aug.vflip:
        n = n.flip(-2)
    if aug.hflip:
        n = n.flip(-1)
    if aug.transpose:
        n = n.transpose(-1, -2)
    return n.contiguous()


def interior_crop(images: torch.Tensor, mask: torch.Tensor, normals: torch.Tensor, rng: np.random.Generator,
                  min_fraction: float = 0.125, max_fraction: float = 0.6
                  ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None:
    """A random square lying entirely inside the mask, resized back to the input size, or None.

    The crop carries no outline (its mask is all ones), so a network can only get its normals from
    the images: the training cure for a model that predicts from the silhouette. The side is drawn
    in [min_fraction, max_fraction] * H and shrunk by 3/4 until a square fits; each cropped image is
    divided again by its mean over the crop (the normalisation of `unips.preprocess.prepare`).
    images `(K, 3, H, W)`, mask `(1, H, W)`, normals `(3, H, W)`; returns the same shapes.
    """
    import torch.nn.functional as F

    _, _, h, w = images.shape
    outside = (mask[0] < 0.5).to(torch.int64)
    integral = F.pad(outside.cumsum(0).cumsum(1), (1, 0, 1, 0))  # (H+1, W+1)
    min_side = max(2, round(min_fraction * min(h, w)))
    top = max(min_side, int(max_fraction * min(h, w)))
    side = int(rng.integers(min_side, top + 1))
    while side >= min_side:
        bad = (integral[side:, side:] - integral[:-side, side:] - integral[side:, :-side] + integral[:-side, :-side])
        ys, xs = torch.nonzero(bad == 0, as_tuple=True)  # top-left corners of squares fully inside
        if ys.numel():
            i = int(rng.integers(ys.numel()))
            y, x = int(ys[i]), int(xs[i])
            break
        side = side * 3 // 4
    else:
        return None
    crop = images[:, :, y:y + side, x:x + side]
    crop = F.interpolate(crop, size=(h, w), mode="bilinear", align_corners=False)
    means = crop.mean(dim=(1, 2, 3), keepdim=True)  # (K, 1, 1, 1)
    crop = crop / torch.where(means > 1e-8, means, torch.ones_like(means))
    n = F.interpolate(normals[None, :, y:y + side, x:x + side], size=(h, w), mode="bilinear", align_corners=False)[0]
    n = F.normalize(n, dim=0, eps=1e-8)
    return crop.contiguous(), torch.ones_like(mask), n.contiguous()
