"""The global tilt search of refinement (`validate.refine --rotation-search`): the whole normal map, with its lights,
turned about the x and y axes to the tilt of lowest residual, taken only where the images decide."""
from __future__ import annotations

import logging
from typing import Protocol

import numpy as np

from validate.fitted.fit import run_fit
from validate.fitted.fit_scene import FitScene, Progress, to_jit
from validate.fitted.verdict import TIES


class RotationSteps(Protocol):
    """What the search reads of `validate.refine.RefineConfig` (which imports this module)."""

    rotation_steps: int


log = logging.getLogger("validate.refine")  # the refinement's log, as before the search had its own module




def search_rotation(fs: FitScene, train: np.ndarray, config: RotationSteps, deltas_deg: tuple[float, ...] = (4.0, 2.0),
                    progress: Progress | None = None, label: str = "refine: rotation",
                    record: dict | None = None) -> np.ndarray:
    """Rotate the normals of `fs` (and its lights with them) by the global tilt of lowest residual on images
    `train`, found by a parabolic coordinate search over the x and y components of a rotation vector (a
    turn about the view axis z leaves every image as it is), steps `deltas_deg`. Each candidate: normals
    and lights of the current state rotated, `config.rotation_steps` Adam steps on the lights with the same
    image batches and rays (the candidates differ only by the rotation), then the censored rel_l1. Leaves
    `fs` at the best candidate; returns its rotation vector (radians). The identity is a candidate, so the
    residual never rises. `record`, when given, receives the chosen tilt and the spread of the candidates that
    score within `validate.fitted.verdict.TIES['rotation']` of it (the tilts the images cannot separate)."""
    from scipy.spatial.transform import Rotation

    if fs.model not in ("directional", "point"):
        return np.zeros(3)
    n0 = fs.n_np.copy()
    base = {k: np.array(v, np.float64).T for k, v in fs.params.items()}  # (K, 3) each
    lobe0 = list(fs.lobe)
    centre = fs.pos_np.mean(0)
    held = np.setdiff1d(np.arange(fs.k), train)
    cache: dict[tuple, float] = {}
    total = 1 + 2 * 3 * len(deltas_deg)
    last = [None]  # key of the candidate `fs` holds now

    def key(w: np.ndarray) -> tuple:
        return tuple(np.round(w, 9) + 0.0)  # + 0.0: -0.0 and 0.0 are one candidate

    def apply(w: np.ndarray) -> None:
        R = Rotation.from_rotvec(w).as_matrix()
        fs.n_np = n0 @ R.T
        fs.normals = to_jit(fs.mi.Vector3f, fs.n_np.astype(np.float32))
        p = {k: v.copy() for k, v in base.items()}
        if "dir" in p:
            p["dir"] = p["dir"] @ R.T
        if "pos" in p:
            p["pos"] = (p["pos"] - centre) @ R.T + centre
        fs.params = {k: to_jit(fs.mi.Vector3f, v.astype(np.float32)) for k, v in p.items()}
        fs.lobe = list(lobe0)
        fs._set_bsdf()
        fs.rng = np.random.default_rng([fs.config.seed, 104729])  # same batches and rays for every candidate
        run_fit(fs, config.rotation_steps, holdout=held, wide_lobe=False)
        last[0] = key(w)

    def score(w: np.ndarray) -> float:
        if key(w) not in cache:
            apply(w)
            cache[key(w)] = fs.score(fs.render(train), train)
            if progress is not None:
                progress(min(len(cache), total), total, label)
        return cache[key(w)]

    best = np.zeros(3)
    s_best = score(best)
    for d in np.radians(deltas_deg):
        for axis in range(2):  # tilts only (see above)
            e = np.zeros(3)
            e[axis] = d
            s_p, s_m = score(best + e), score(best - e)
            cands = [(s_best, best), (s_p, best + e), (s_m, best - e)]
            curv = s_p - 2 * s_best + s_m
            if curv > 0:  # the vertex of the parabola through the three, at most 2 steps away
                t = float(np.clip(0.5 * (s_m - s_p) / curv, -2, 2))
                if abs(t) > 0.05 and abs(abs(t) - 1) > 0.05:
                    cands.append((score(best + t * e), best + t * e))
            s_best, best = min(cands, key=lambda c: c[0])
    if record is not None:
        ties = [np.array(w) for w, v in cache.items() if TIES["rotation"].same(s_best, v)]
        best_key = np.array(key(best))
        spread = max(float(np.degrees(np.linalg.norm(w - best_key))) for w in ties)
        record.update(tilt_deg=float(np.degrees(np.linalg.norm(best))), equally_good=len(ties),
                      equally_good_spread_deg=spread, candidates=len(cache), tie_tolerance=TIES["rotation"].relative,
                      note=(f"{len(ties)} of {len(cache)} tilts score within {TIES['rotation'].relative:.1%} of the "
                            f"best, up to {spread:.1f} deg from it: the images do not decide among them"
                            if len(ties) > 1 else "one tilt scores best"))
    if last[0] != key(best):
        apply(best)  # back to the winner: same batches and rays, so the same state as at its evaluation
    log.info("%s: %.2f deg (rel_l1 %.5f -> %.5f on %d images)", label, np.degrees(np.linalg.norm(best)),
             cache[key(np.zeros(3))], s_best, len(train))
    return best
