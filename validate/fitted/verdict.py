"""Where the fitted check can judge a normal map, decided from the images alone.

The fitted check explains the images with a physics (lights, a Lambertian and a specular lobe, shadows from the
geometry integrated from the judged map). Where that physics cannot explain a capture (sharp highlights of
metals, deep cast shadows, inter-reflections between parts) a wrong map can score better than the truth: it
bends its normals to explain what the physics lacks. So the verdict and the observations that are scored must
not come from the map being judged. Here they come from the images only:

1. **Observations** (`select_observations`): per pixel and image, shadows (darker than `SHADOW_FRACTION` of the
   pixel's bright level), saturated channels and outliers of the low-rank model below (highlights,
   inter-reflections; more than `OUTLIER_SIGMAS` robust standard deviations) are left out, as robust photometric
   stereo does. Every map of a capture is scored on the same observations.
2. **Explained pixels** (`explain`): under distant lights, the kept observations of a Lambertian surface form a
   matrix of rank 4 per colour channel (pixels x images: albedo times [normal, 1] against [light, ambient]),
   whatever the normals are; no normal map is needed to test it, and the generalised bas-relief ambiguity
   changes nothing in it. A pixel is explained when it keeps at least `MIN_OBSERVATIONS` observations and the
   rank-4 model reproduces them within `EXPLAINED_RELATIVE` of their mean. Near lights, environment light,
   metals and inter-reflections break the model: there the fitted light models were measured to rank a wrong
   map (the shipped model's, 11-18 degrees off) above the truth, so the check abstains
   (`bench/bench_verdict.py`).
3. **Constrained** (`explain`, `Explanation.light_dimensions`): being explained is not enough: 8 scaled copies of
   one image are explained by any map (rank 1), and lights that lie near one plane (rank 2) leave one component
   of every normal free. The rank-4 fit of the explained pixels' kept observations (channel mean) is read for its
   singular values; a dimension counts when its singular value exceeds `DIMENSION_NOISE` times what the image
   noise alone gives a matrix of that size (sigma (sqrt(P) + sqrt(K))). With fewer than three light dimensions
   the check abstains: a map and its mirror image (n_x negated, the lights turned with it) then score alike.
   Lights from one side only are not refused as such: with three dimensions the truth still ranked first
   (DiLiGenT ball, 8 and 40 images all lit from the right: the mirrored map scores 14 % higher).
4. **Verdict** (`verdict`): trusted when the capture is constrained and at least `MIN_EXPLAINED` of the mask is
   explained; otherwise the check abstains (`trusted: false` with the reason) and its score is printed but marked
   untrusted.
5. **Resolution** (`Explanation.resolution`, `told_apart`): the fitted physics is simpler than the world, so a map
   optimised against the score (refined) absorbs part of what the physics lacks into its normals and can score
   below the true surface. How far below is bounded by what no Lambertian explanation removes: the residual of
   the rank-4 model itself (`bound`, free normals and albedo per pixel and a free light per image, on the judged
   observations). Two maps whose judged scores differ by less than that are "not told apart": the images do not
   rank them. Measured (`bench/bench_verdict.py --optimised`, docs/check.md): refining the true map of DiLiGenT
   cat lowers its score by 0.012 (resolution 0.017), of a rendered glossy object by 0.011 (0.018); no map,
   refined or not, scored below the truth by more than the resolution on the 8 trusted captures measured.

The constants were chosen on rendered objects with ground truth and the two DiLiGenT objects at hand
(`bench/bench_verdict.py`, docs/check.md), never on one real capture alone.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from validate.judgeable import MIN_IMAGES
from validate.residuals import rel_l1_observations

BRIGHT_PERCENTILE = 90
"""A pixel's bright level: this percentile of its observations over the images (a percentile, not the maximum, so
one highlight does not set it)."""
SHADOW_FRACTION = 0.1
"""An observation darker than this fraction of its pixel's bright level (its 90th percentile over the images)
is a shadow (attached or cast): left out. Swept in docs/check.md, "Verdict constants" (0.02-0.3: no false trust,
0.1 trusted the most)."""
OUTLIER_SIGMAS = 4.0
"""An observation farther than this many robust standard deviations of the rank-4 model is an outlier
(highlight, inter-reflection): left out. Swept in docs/check.md, "Verdict constants" (2.5-10: no false trust)."""
SCALE_FLOOR = 0.01
"""The robust residual scale is at least this fraction of the mean kept observation (on noise-free images every
rounding would otherwise be an outlier). Swept in docs/check.md, "Verdict constants" (0.003-0.03: no verdict
changed on noisy renders)."""
MIN_OBSERVATIONS = MIN_IMAGES["verdict"]
"""Observations a pixel must keep to be judged (4 unknowns of the rank-4 model per channel, plus 1 to test it).
Swept in docs/check.md, "Verdict constants" (6 and 8 abstain on captures the default judges correctly)."""
EXPLAINED_RELATIVE = 0.05
"""A pixel is explained when the rms residual of the rank-4 model is within this fraction of its mean
kept observation (noise counts too: a capture this noisy cannot rank maps 10 degrees apart). Swept in
docs/check.md, "Verdict constants" (0.12 trusted an environment-lit capture falsely; 0.08 did not)."""
MIN_EXPLAINED = 0.5
"""Fraction of the mask pixels that must be explained for a trusted verdict: the guard against trusting near,
environment and mixed light. Swept in docs/check.md, "Verdict constants" (0 trusted 4 captures falsely, 0.25 and
up none; 0.5 the conservative end of that)."""
DIMENSION_NOISE = 8.0
"""A light dimension of the capture (a singular value of the explained observations) counts when it is at least
this many times the singular value of the image noise alone. Measured on DiLiGenT ball (bench/bench_verdict.py
--degenerate): 5 one-sided images whose third value is 4.1 times the noise let a mirrored map (54 degrees off)
score below the truth; 5 or 8 images with 17 or more rank the truth first. Swept in docs/check.md, "Verdict
constants" (0-8 alike on rendered suites, 16 and 32 refuse captures judged correctly)."""
RANK = 4
"""Rank of the distant-light Lambertian model per colour channel: [normal, 1] (3 + ambient)."""


# ---------------------------------------------------------------------------------------------- same score?
# One rule answers "do two judged scores of one capture differ?" (`Tie.same`); each use has its tolerance in
# TIES, and where two uses' tolerances differ the entry says why.

TIE_FLOOR = 0.002
"""Judged residuals closer than this (0.2 % of the mean observation) are tied whatever else: on noise-free renders
every map near the truth scores near 0."""
SEPARATION = 0.02
"""A 2 % relative difference of judged residuals: the margin a refined map must win by, and a bas-relief
transform must lose by, to count. A chosen margin, not yet swept like the verdict constants (docs/check.md);
the capture's own resolution (`resolution_tie`) is what says whether the images tell two maps apart."""
HOLDOUT_FALL = 0.3
"""The share by which the residual on the refinement's held-out images (never used in a step) must fall for a refined
map to be kept, beside the judged residual's `SEPARATION`. Measured on held-out renders (bench/bench_refine_rule.py,
docs/check.md "Keeping the refined map"): the judged fall alone kept 7 of 64 judged captures that got worse by more
than 0.5 deg; with this held-out fall as well, 1 (chosen on seed 9500, confirmed on 9600)."""
ROTATION_TIE = 0.005
"""Candidate tilts of one rotation search whose residual is within this fraction of the best one's are equally
good (DiLiGenT cat: tilts 1.5 deg apart gave final maps 6.9 to 8.4 deg off at one residual)."""


@dataclass(frozen=True)
class Tie:
    """Two judged scores count as the same when |other - reference| <= max(relative * reference, absolute)."""

    relative: float
    absolute: float
    why: str
    """Why this use has this tolerance."""

    def same(self, reference: float, other: float) -> bool:
        """True when `other` does not differ from `reference` (NaN never differs: nothing is told apart)."""
        if not (np.isfinite(reference) and np.isfinite(other)):
            return True
        return bool(abs(other - reference) <= max(self.relative * reference, self.absolute))


TIES = {
    "refinement": Tie(SEPARATION, 0.0, "a refined map is kept only when it lowers the residual by a clear relative "
                      "margin: the refinement fits the score itself, so a smaller gain is what fitting noise gives"),
    "refinement_holdout": Tie(HOLDOUT_FALL, 0.0, "the held-out images were never fitted to, but they are few (a tenth "
                              "of the capture) and noisier: only a large fall on them shows the refined map is "
                              "closer, not fitted to the other images' noise"),
    "bas_relief": Tie(SEPARATION, TIE_FLOOR, "the same margin as the refinement's, since a transform that refinement "
                      "could reach must lose by it; with the absolute floor, as on noise-free renders every transform "
                      "near the map scores near 0"),
    "rotation": Tie(ROTATION_TIE, 0.0, "candidates of one search share their image batches and rays, so their "
                    "residuals differ by less noise than two separate fits: a finer relative tolerance"),
}
"""The tolerance of each use of `Tie.same` but the capture's own resolution (`resolution_tie`)."""


def resolution_tie(ex: "Explanation") -> Tie:
    """Two maps of a capture are told apart by its images only beyond its resolution (module doc, 5): an absolute
    tolerance measured on the capture itself, not a fixed margin."""
    return Tie(0.0, ex.resolution, "the capture's resolution (Explanation.resolution)")


@dataclass
class Explanation:
    """What the images alone say about a capture (all at the fitting resolution)."""

    keep: np.ndarray
    """(K, P) bool: the observations every map is scored on."""
    explained: np.ndarray
    """(P,) bool: mask pixels that distant lights on a Lambertian surface explain."""
    residual: np.ndarray
    """(P,) rms residual of each pixel's kept observations under the rank-4 model, relative to their mean."""
    sigma: float
    """Image noise standard deviation (same units as the images)."""
    dimensions: tuple[float, ...] = ()
    """The first three singular values of the explained pixels' kept observations (channel mean, completed by the
    rank-4 model), in units of the noise's singular value (sigma (sqrt(P) + sqrt(K)))."""
    bound: float = float("nan")
    """The judged rel_l1 of the rank-4 model itself: what the best Lambertian explanation leaves (any normals and
    albedo per pixel, any light per image), on the observations every map is scored on."""

    @property
    def resolution(self) -> float:
        """The smallest difference of judged rel_l1 the capture resolves (module doc, 5): `bound`, at least
        `TIE_FLOOR`. Two maps closer than this are not told apart by the images."""
        return max(float(self.bound), TIE_FLOOR) if np.isfinite(self.bound) else float("nan")

    @property
    def light_dimensions(self) -> int:
        """How many of the three dimensions a normal has the lights reach above the noise (`DIMENSION_NOISE`)."""
        return self.dimensions_above(DIMENSION_NOISE)

    def dimensions_above(self, noise: float) -> int:
        """How many of the three dimensions reach `noise` times the noise's singular value (the one counting rule of
        `light_dimensions` and of a sweep of `DIMENSION_NOISE`)."""
        return int(sum(d >= noise for d in self.dimensions))

    @property
    def explained_fraction(self) -> float:
        return float(self.explained.mean()) if self.explained.size else 0.0


NOISE_EDGE_PX = 2
"""Pixels left out along the mask's edge for the noise estimate: the object's outline is a step, not noise."""
MIN_NOISE_PIXELS = 16
"""Fewer pixels inside the eroded mask than this: the noise is estimated over the whole mask instead."""


def channel_noise_sigmas(images: np.ndarray, inner: np.ndarray) -> list[float]:
    """Per image and channel of (K, H, W, 3) images, the noise standard deviation over the pixels `inner`:
    Immerkaer's Laplacian-difference estimate, median-based so that shading edges do not count."""
    from scipy.ndimage import convolve

    kern = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float64)
    # median |response| / 0.6745: a Gaussian's sigma from its median absolute value; / 6: the kernel's gain
    # (sqrt of the sum of its squared weights, 36) on white noise.
    return [
        float(np.median(np.abs(convolve(im[:, :, c].astype(np.float64), kern, mode="nearest")[inner]))) / 0.6745 / 6.0
        for im in images
        for c in range(im.shape[2])
    ]


def noise_sigma(images: np.ndarray, mask: np.ndarray) -> float:
    """Noise standard deviation of (K, H, W, 3) images inside the eroded mask (`channel_noise_sigmas`, their
    median), floored at one 16-bit code."""
    from scipy.ndimage import binary_erosion

    inner = binary_erosion(mask, iterations=NOISE_EDGE_PX)
    if inner.sum() < MIN_NOISE_PIXELS:
        inner = mask
    return max(float(np.median(channel_noise_sigmas(images, inner))), 1.0 / 65535.0)


def noise_rel_l1(ex: "Explanation", observed: np.ndarray) -> float:
    """The image noise of a capture as a relative L1 level, comparable with a judged rel_l1: the mean absolute
    value of Gaussian noise of the capture's one noise estimate (`Explanation.sigma`, from `noise_sigma`),
    sigma sqrt(2 / pi), over the mean observation (K, P, 3) of the mask."""
    denom = float(np.abs(observed).mean()) if observed.size else 0.0
    return ex.sigma * float(np.sqrt(2 / np.pi)) / denom if denom > 0 else float("nan")


def _weighted_low_rank(m: np.ndarray, w: np.ndarray, rank: int, iters: int = 30) -> np.ndarray:
    """Alternating least squares for m (P, K) ~ B (P, r) @ S (r, K) over the entries with w = 1. Returns B @ S."""
    p, k = m.shape
    rank = min(rank, k)  # fewer images than the rank: the model is exact (and such a capture is not judged)
    filled = np.where(w > 0, m, (m * w).sum(1, keepdims=True) / np.maximum(w.sum(1, keepdims=True), 1))
    u, s, vt = np.linalg.svd(filled, full_matrices=False)
    S = (np.sqrt(s[:rank])[:, None] * vt[:rank])  # (r, K)
    ridge = 1e-9 * np.eye(rank)
    for _ in range(iters):
        # B_p = argmin sum_k w_pk (m_pk - B_p . S_k)^2  -> (S W_p S^T) B_p = S W_p m_p
        A = np.einsum("ik,pk,jk->pij", S, w, S) + ridge  # (P, r, r)
        b = np.einsum("ik,pk->pi", S, w * m)  # (P, r)
        B = np.linalg.solve(A, b[..., None])[..., 0]
        A = np.einsum("pi,pk,pj->kij", B, w, B) + ridge  # (K, r, r)
        b = np.einsum("pi,pk->ki", B, w * m)  # (K, r)
        S = np.linalg.solve(A, b[..., None])[..., 0].T
    return B @ S


@dataclass(frozen=True)
class VerdictRules:
    """The constants of the verdict in one value, so that a sweep can vary one of them at a time
    (`bench/bench_verdict_sweep.py`) without changing the module; the defaults are the module's constants, which
    every call without `rules` uses."""

    shadow_fraction: float = SHADOW_FRACTION
    outlier_sigmas: float = OUTLIER_SIGMAS
    scale_floor: float = SCALE_FLOOR
    min_observations: int = MIN_OBSERVATIONS
    explained_relative: float = EXPLAINED_RELATIVE
    min_explained: float = MIN_EXPLAINED
    dimension_noise: float = DIMENSION_NOISE


def select_observations(
    images: np.ndarray, saturated: np.ndarray | None = None, rules: VerdictRules | None = None
) -> np.ndarray:
    """(K, P) bool: observations that are neither shadowed nor saturated, from (K, P, 3) images alone."""
    rules = rules or VerdictRules()
    intensity = images.mean(axis=2)  # (K, P)
    bright = np.percentile(intensity, BRIGHT_PERCENTILE, axis=0)  # (P,)
    keep = intensity > rules.shadow_fraction * bright[None]
    if saturated is not None:
        keep &= ~saturated.any(axis=2)
    return keep


def explain(
    images: np.ndarray, mask: np.ndarray, saturated: np.ndarray | None = None, rules: VerdictRules | None = None
) -> Explanation:
    """The observations to score and the explained pixels of a capture: images (K, H, W, 3), mask (H, W),
    saturated (K, H, W, 3) or None; from the images alone. rules: the constants (default: the module's)."""
    rules = rules or VerdictRules()
    sigma = noise_sigma(images, mask)
    obs = images[:, mask].astype(np.float64)  # (K, P, 3)
    sat = None if saturated is None else saturated[:, mask]
    keep = select_observations(obs, sat, rules)  # (K, P)
    k, p, _ = obs.shape
    intensity = obs.mean(axis=2)  # (K, P)
    for _ in range(2):  # twice: fit, then drop the outliers (highlights, inter-reflections)
        w = keep.T.astype(np.float64)  # (P, K)
        model = np.stack([_weighted_low_rank(obs[:, :, c].T, w, RANK).T for c in range(3)], axis=2)  # (K, P, 3)
        res = np.sqrt(((obs - model) ** 2).mean(axis=2)).T  # (P, K) rms over channels
        kept = res[w > 0]
        floor = max(sigma, rules.scale_floor * float(intensity[keep].mean()) if keep.any() else sigma)
        scale = max(1.4826 * float(np.median(kept)) if kept.size else floor, floor)  # 1.4826 MAD: a Gaussian sigma
        keep = keep & (res.T <= rules.outlier_sigmas * scale)
    count = keep.sum(0)
    rms = np.sqrt((np.where(keep.T, res, 0.0) ** 2).sum(1) / np.maximum(count, 1))  # (P,)
    level = np.where(keep, intensity, 0.0).sum(0) / np.maximum(count, 1)  # (P,) mean kept observation
    # Relative, not in noise units: a capture whose noise is a large part of the signal cannot be judged either.
    explained = (count >= rules.min_observations) & (rms <= rules.explained_relative * level)
    judged = keep & explained[None]  # (K, P) the observations every map is scored on
    bound = rel_l1_observations(model, obs, where=judged) if judged.any() else float("nan")
    return Explanation(keep=keep, explained=explained, residual=rms / np.maximum(level, 1e-12), sigma=sigma,
                       dimensions=_dimensions(intensity, keep, explained, sigma), bound=bound)


def _dimensions(intensity: np.ndarray, keep: np.ndarray, explained: np.ndarray, sigma: float) -> tuple[float, ...]:
    """The first three singular values of the rank-4 completion of the explained pixels' kept observations
    (K, P) -> (P_e, K), over the noise's singular value sigma (sqrt(P_e) + sqrt(K))."""
    m, w = intensity[:, explained].T, keep[:, explained].T.astype(np.float64)  # (P_e, K)
    if m.shape[0] < RANK or m.shape[1] < 2:
        return (0.0, 0.0, 0.0)
    s = np.linalg.svd(_weighted_low_rank(m, w, RANK), compute_uv=False)
    s = np.concatenate([s, np.zeros(3)])[:3]
    return tuple(float(v) for v in s / (sigma * (np.sqrt(m.shape[0]) + np.sqrt(m.shape[1]))))


def verdict(ex: Explanation, rules: VerdictRules | None = None) -> tuple[bool, str]:
    """(trusted, why) of a capture's explanation; rules: the constants (default: the module's)."""
    rules = rules or VerdictRules()
    frac = ex.explained_fraction
    images = ex.keep.shape[0]
    dimensions = ex.dimensions_above(rules.dimension_noise)
    if images < rules.min_observations:
        return False, (f"only {images} images: a pixel needs at least {rules.min_observations} unshadowed "
                       "observations before the images can say whether a normal map explains it")
    if frac < rules.min_explained:
        return False, (
            f"only {frac:.0%} of the object is explained by distant lights on a Lambertian surface (at "
            f"least {rules.min_explained:.0%} needed): near or environment light, metals, cast "
            "shadows or inter-reflections the check cannot model; the score is not a judgement of the normals"
        )
    if ex.dimensions and dimensions < 3:
        return False, (
            f"the images vary in only {dimensions} independent way(s) above the noise (a normal has "
            "3): the lights are copies of one or lie near one plane, so any map is explained as well as "
            "the true one; the score is not a judgement of the normals; take photos with the light moved "
            "further, above, below and to the sides"
        )
    return True, (f"{frac:.0%} of the object is explained by distant lights on a Lambertian surface (at least "
                  f"{rules.min_explained:.0%} needed) and the lights vary in all 3 directions: scored on those pixels' "
                  "unshadowed, unsaturated observations")


def judged_rel_l1(
    render: np.ndarray, images: np.ndarray, ex: Explanation, only: tuple[int, ...] | None = None
) -> float:
    """rel_l1 of a fitted render (K, P, 3) against the images (K, P, 3) over the kept observations of the
    explained pixels: the same observations for every map of the capture; `only`: of those images alone."""
    where = ex.keep & ex.explained[None]  # (K, P) selection
    if only is not None:
        where = where & np.isin(np.arange(len(where)), list(only))[:, None]
    return rel_l1_observations(render, images, where=where)


def told_apart(a: float, b: float, ex: Explanation) -> bool:
    """Whether judged scores `a` and `b` of two maps of one capture differ by more than its resolution
    (`resolution_tie`); False when either is not finite."""
    return not resolution_tie(ex).same(a, b)
