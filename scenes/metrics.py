"""The angular error between normal maps, the one metric every scorer of normals uses (`unips.evaluate`, the
probes, the check's floors, the benchmarks).
"""
from __future__ import annotations

import numpy as np

from scenes.images import check_normal_array


def angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles in degrees between the vectors of two arrays of shape (..., 3), normalised first, in float64
    (light directions, normals): the one angle formula of the toolkit."""
    a = _unit(np.asarray(a, np.float64))
    b = _unit(np.asarray(b, np.float64))
    return np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))


def _unit(n: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    return n / np.maximum(norm, 1e-12)


def angular_error_deg(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W) angular error in degrees inside mask, 0 outside.

    Both maps are normalised first; a zero predicted normal inside the mask counts as 90 degrees.
    """
    pred = check_normal_array(pred, "pred")
    gt = check_normal_array(gt, "gt")
    mask = np.asarray(mask)
    if pred.shape != gt.shape:
        raise ValueError(f"pred: shape {pred.shape} differs from gt shape {gt.shape}")
    if mask.shape != pred.shape[:2]:
        raise ValueError(f"mask: shape {mask.shape} differs from the normal maps' {pred.shape[:2]}")
    mask = mask.astype(bool)
    err = angles_deg(pred, gt)
    err[~mask] = 0.0
    return err.astype(np.float32)


def mean_angular_error(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> float:
    """Mean angular error in degrees over the mask (which must not be empty)."""
    mask = np.asarray(mask).astype(bool)
    if not mask.any():
        raise ValueError("mask: is empty, cannot average the angular error")
    err = angular_error_deg(pred, gt, mask)
    return float(np.mean(err[mask], dtype=np.float64))
