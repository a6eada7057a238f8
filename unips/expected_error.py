"""The expected angular error of a network's normal map, per pixel and per object, in degrees.

No one states how wrong a photometric-stereo map is likely to be. The evidence here is what the network and the
images say about themselves, gathered at prediction time (`gather`):

- `views_deg`: the angle between the map's first two views (the object and its mirror image, `unips.augment.DIHEDRAL`;
  free with the default two views);
- `halves_deg`: the angle between the maps from two disjoint random halves of the images (two more passes of one
  view on K/2 images each): where the images under-determine a normal, its two halves disagree;
- `lit`: the share of the images in which the pixel is lit (above `LIT` of its brightest value);
- `grazing`: 1 - n_z of the map (foreshortened surface near the outline);
- `edge_px`: the distance to the mask's outline;
- the image count K and the object's mean disagreements.

`ErrorModel` turns them into E[angular error | evidence] in two stages, both fitted on renders with exact ground truth
from the training assets (`orchestrate.error_calibration`, one command):

1. per pixel, a log-linear model (a Poisson GLM on the features of `FEATURES`, each object weighted equally): where on
   the object the error lies;
2. per object, log(stated mean) = c0 + c1 log(mean of the pixel map) + c2 log K (`object_coef`, least squares over
   the objects, K the image count): how large it is. c2 is measured within objects (`fit_object_stage`): the
   calibration's faulted copies with fewer images tell it apart from the objects' other differences; the pixel map
   is then scaled to the stated mean, which keeps its order (the sparsification) and makes its mean the stated one.

The 80 % interval is the stated mean times the 10th and 90th percentiles of the ratio true / stated measured out of
fold (each calibration object stated by the two stages fitted without it and its faulted copies). The fitted model
is a small JSON beside the weights it belongs to (`<weights stem>.expected_error.json`), tied to them by their
SHA-256: other weights get no stated error, and say why.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scenes.files import not_a_file, read_json
from scenes.folder.format import EXPECTED_ERROR_FILES
from scenes.metrics import angles_deg

LIT = 0.1
"""A pixel counts as lit in an image above this share of its brightest value over the images (shadowed below)."""
HALVES_SEED = 0
"""Seed of the random split of the images into two halves (the same split for the same image count)."""
FEATURES = ("halves", "views", "object_halves", "object_views", "grazing", "edge", "lit", "images")
"""The model's inputs per pixel, in order (`features`): log1p of the halves' and the views' angle (deg), log1p of
their object means, 1 - n_z, log1p of the outline distance (px), the lit share, log of K."""
SUFFIX = ".expected_error.json"
"""The fitted model of weights `W.safetensors` is `W.expected_error.json` beside them."""
INTERVAL = 0.8
"""The stated interval should hold the true mean error this often (the 10th to the 90th percentile)."""


@dataclass
class Evidence:
    """What a map says about itself, per pixel (H, W) float32 (0 outside the mask), and its image count."""

    views_deg: np.ndarray
    halves_deg: np.ndarray
    lit: np.ndarray
    grazing: np.ndarray
    edge_px: np.ndarray
    mask: np.ndarray  # (H, W) bool
    images: int

    def features(self) -> np.ndarray:
        """(P, len(FEATURES)) float64 features of the P mask pixels, in `FEATURES` order."""
        m = self.mask
        halves, views = self.halves_deg[m].astype(np.float64), self.views_deg[m].astype(np.float64)
        cols = [np.log1p(halves), np.log1p(views), np.full_like(halves, np.log1p(halves.mean())),
                np.full_like(halves, np.log1p(views.mean())), self.grazing[m], np.log1p(self.edge_px[m]), self.lit[m],
                np.full_like(halves, np.log(max(self.images, 1)))]
        return np.stack(cols, axis=1)


def lit_share(images: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W) share of the K images (K, H, W, 3) in which each mask pixel is above LIT of its brightest value."""
    gray = images.mean(axis=-1)  # (K, H, W)
    peak = gray.max(axis=0)
    return np.where(mask, (gray > LIT * np.maximum(peak, 1e-12)).mean(axis=0), 0.0).astype(np.float32)


def halves(k: int, seed: int = HALVES_SEED) -> tuple[np.ndarray, np.ndarray]:
    """Two disjoint random halves of range(k) (sorted; for odd k one image is left out)."""
    perm = np.random.default_rng(seed).permutation(k)
    return np.sort(perm[: k // 2]), np.sort(perm[k // 2: 2 * (k // 2)])


def evidence_from(normals: np.ndarray, views: list[np.ndarray], half_maps: tuple[np.ndarray, np.ndarray],
                  images: np.ndarray, mask: np.ndarray) -> Evidence:
    """Evidence of a map `normals` (H, W, 3) from its first two views' maps, the two halves' maps and the images."""
    from scipy import ndimage

    def inside(x: np.ndarray) -> np.ndarray:
        return np.where(mask, x, 0.0).astype(np.float32)

    return Evidence(views_deg=inside(angles_deg(views[0], views[1])), halves_deg=inside(angles_deg(*half_maps)),
                    lit=lit_share(images, mask), grazing=inside(1.0 - np.clip(normals[..., 2], -1.0, 1.0)),
                    edge_px=ndimage.distance_transform_edt(mask).astype(np.float32), mask=mask.astype(bool),
                    images=int(len(images)))


def gather(net: Any, obj: Any, res: int | None = None, tta: int = 2, seed: int = HALVES_SEED
           ) -> tuple[np.ndarray, Evidence]:
    """The network's map of `obj` (as `unips.inference.run_model` gives it with `tta` views) and its evidence: two
    views (the map's own when `tta` >= 2, else two more passes) and two halves of the images (one view each)."""
    import dataclasses

    from unips.inference import run_model

    if obj.num_images < 2:
        raise ValueError(f"images: {obj.num_images}, the expected error needs at least 2 (two halves)")
    views: list[np.ndarray] = []
    normals = run_model(net, obj, res=res, tta=tta, views=views)
    if len(views) < 2:
        views = []
        run_model(net, obj, res=res, tta=2, views=views)

    def subset(idx: np.ndarray) -> Any:
        def pick(a: Any) -> Any:
            return None if a is None else a[idx]

        return dataclasses.replace(obj, images=obj.images[idx], light_directions=pick(obj.light_directions),
                                   light_intensities=pick(obj.light_intensities),
                                   image_names=[obj.image_names[i] for i in idx] if obj.image_names else [])

    a, b = halves(obj.num_images, seed)
    half_maps = (run_model(net, subset(a), res=res, tta=1), run_model(net, subset(b), res=res, tta=1))
    return normals, evidence_from(normals, views[:2], half_maps, obj.images, obj.mask)


# ---------------------------------------------------------------- the fitted model


@dataclass
class Stated:
    """The stated error of one map: per pixel (H, W) float32 (NaN outside the mask), its mean and 80 % interval."""

    per_pixel: np.ndarray
    mean: float
    interval_80: tuple[float, float]

    def summary(self) -> dict:
        """report.json's / predict.json's `expected_error_deg`."""
        return {"mean": round(self.mean, 2), "interval_80": [round(self.interval_80[0], 2),
                                                              round(self.interval_80[1], 2)]}


@dataclass
class ErrorModel:
    """E[angular error (deg) | evidence] = scale x exp(b + w . (f - mean) / std), per pixel (see the module doc)."""

    weights_sha256: str
    model_name: str
    features: list[str]
    mean: list[float]
    std: list[float]
    coef: list[float]
    intercept: float
    scale: float
    ratio_quantiles: list[float]  # the calibration objects' true / stated at the 10th and 90th percentile
    calibration: dict = field(default_factory=dict)  # what it was fitted on, the command, the objects' figures
    object_coef: list[float] = field(default_factory=lambda: [0.0, 1.0, 0.0])  # [c0, c1, c2] of the object stage
    object_images: list[int] = field(default_factory=lambda: [1, 1_000_000])  # the image counts c2 was measured on

    def object_mean(self, pixel_mean: float, images: int) -> float:
        """The stated mean (deg) of an object of `images` images whose pixel map (`per_pixel`) averages
        `pixel_mean`. The image count's term is held within the counts it was measured on (no extrapolation: 96
        photos count as the calibration's most)."""
        c0, c1, c2 = self.object_coef
        k = min(max(images, self.object_images[0], 1), self.object_images[1])
        return float(np.exp(c0 + c1 * np.log(max(pixel_mean, 1e-6)) + c2 * np.log(k)))

    def per_pixel(self, ev: Evidence) -> np.ndarray:
        """(H, W) float32 expected error (deg) of the pixel stage alone, NaN outside the mask (`state` scales it to
        the object's stated mean)."""
        if list(self.features) != list(FEATURES):
            raise ValueError(f"error model: features {self.features}, expected {list(FEATURES)} (fitted by another "
                             "version of the toolkit: fit it again, orchestrate.error_calibration)")
        x = (ev.features() - np.asarray(self.mean)) / np.asarray(self.std)
        out = np.full(ev.mask.shape, np.nan, np.float32)
        out[ev.mask] = self.scale * np.exp(np.clip(self.intercept + x @ np.asarray(self.coef), -10, 10))
        return out

    def state(self, ev: Evidence) -> Stated:
        """The stated error of the map behind `ev`."""
        pix = self.per_pixel(ev)
        if not ev.mask.any():
            return Stated(per_pixel=pix, mean=float("nan"), interval_80=(float("nan"), float("nan")))
        raw = float(np.nanmean(pix))
        m = self.object_mean(raw, ev.images)
        pix *= np.float32(m / raw)  # the map keeps its order and takes the object's stated mean
        lo, hi = self.ratio_quantiles
        return Stated(per_pixel=pix, mean=float(np.nanmean(pix)), interval_80=(m * lo, m * hi))

    def save(self, path: Path) -> None:
        from scenes.files import write_json

        write_json(path, asdict(self), indent=1)

    @classmethod
    def load(cls, path: Path) -> ErrorModel:
        """The model in `path`, every field checked (`check_fields`): one ValueError naming the file otherwise."""
        return cls.from_json(_read_json(path), path)

    @classmethod
    def from_json(cls, d: Any, path: Path) -> ErrorModel:
        """The model of `d`, the JSON value read from `path` (named in the ValueError of a field that fails)."""
        try:
            return cls(**check_fields(d))
        except ValueError as exc:
            raise ValueError(f"error model {str(path)!r}: {exc} (fit it again: orchestrate.error_calibration)"
                             ) from None


def _read_json(path: Path) -> Any:
    """The JSON value of an error model's file; ValueError naming it where it is not JSON."""
    try:
        return read_json(Path(path))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"error model {str(path)!r}: not valid JSON ({exc})") from None
    except RecursionError:  # nested deeper than the parser's stack
        raise ValueError(f"error model {str(path)!r}: nested too deeply to be an error model") from None


SMALLEST = 1e-6
"""The least a positive field of an error model may be (a spread or a scale): a subnormal spread divides the
features into infinities."""


def _numbers(d: dict, key: str, n: int | None, positive: bool = False, bound: float = 1e6) -> None:
    """d[key] a list of `n` numbers (a number when `n` is None), finite, of magnitude at most `bound`, positive if
    asked; ValueError naming the key otherwise."""
    v = d[key]
    values = [v] if n is None else v
    number = lambda x: isinstance(x, (int, float)) and not isinstance(x, bool)  # noqa: E731
    if not isinstance(values, list) or (n is not None and len(values) != n) or not all(map(number, values)):
        raise ValueError(f"{key} must be " + ("a number" if n is None else f"a list of {n} numbers")
                         + f", got {json.dumps(v)[:80]}")

    def fits(x: float) -> bool:
        try:
            x = float(x)  # an integer beyond float range overflows here: refused, not a traceback
        except OverflowError:
            return False
        return bool(np.isfinite(x)) and abs(x) <= bound and (x >= SMALLEST or not positive)

    if not all(map(fits, values)):
        raise ValueError(f"{key} {json.dumps(v)[:80]}: expected finite numbers "
                         + (f"from {SMALLEST:g} " if positive else "") + f"up to {bound:g} in magnitude")


def check_fields(d: Any) -> dict:
    """`d` (a loaded JSON value) if it holds an `ErrorModel`: every field, none other, of its type and range (a
    stated error made of NaN, infinities or a reversed interval is never written); ValueError otherwise."""
    from dataclasses import MISSING, fields

    if not isinstance(d, dict):
        raise ValueError(f"expected a JSON object, got {type(d).__name__}")
    known = {f.name: f for f in fields(ErrorModel)}
    missing = [k for k, f in known.items() if k not in d and f.default is MISSING and f.default_factory is MISSING]
    if extra := sorted(set(d) - set(known)):
        raise ValueError(f"unknown key(s) {', '.join(map(repr, extra))}")
    if missing:
        raise ValueError(f"missing key(s) {', '.join(map(repr, missing))}")
    for key in ("weights_sha256", "model_name"):
        if not isinstance(d[key], str):
            raise ValueError(f"{key} must be a string, got {json.dumps(d[key])[:80]}")
    if d["features"] != list(FEATURES):
        raise ValueError(f"features {json.dumps(d['features'])[:120]}, expected {list(FEATURES)} (fitted by another "
                         "version of the toolkit)")
    n = len(FEATURES)
    _numbers(d, "mean", n)
    _numbers(d, "std", n, positive=True)
    _numbers(d, "coef", n, bound=100.0)
    _numbers(d, "intercept", None, bound=100.0)
    _numbers(d, "scale", None, positive=True)
    _numbers(d, "ratio_quantiles", 2, positive=True)
    if d["ratio_quantiles"][0] > d["ratio_quantiles"][1]:
        raise ValueError(f"ratio_quantiles {d['ratio_quantiles']}: expected the 10th percentile first (low, high)")
    if "object_coef" in d:
        _numbers(d, "object_coef", 3, bound=100.0)
    if "object_images" in d:
        v = d["object_images"]
        if not (isinstance(v, list) and len(v) == 2 and all(type(x) is int for x in v) and 1 <= v[0] <= v[1]):
            raise ValueError(f"object_images must be two image counts [low, high], 1 <= low <= high, got "
                             f"{json.dumps(v)[:80]}")
    if not isinstance(d.get("calibration", {}), dict):
        raise ValueError("calibration must be a JSON object")
    return d


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def model_path(weights: Path) -> Path:
    """Where the fitted error model of `weights` lies (`SUFFIX` beside them, after the whole stem: glc.v2.safetensors
    has glc.v2.expected_error.json)."""
    weights = Path(weights)
    return weights.with_name(weights.stem + SUFFIX)


def for_weights(weights: Path | None) -> tuple[ErrorModel | None, str | None]:
    """(the error model fitted for exactly these weights, None) or (None, why there is none). A file under the
    model's name that names other weights (their SHA-256) is another's, passed over whatever it holds; one that
    names these weights and is damaged is a ValueError naming it (`ErrorModel.load`)."""
    if weights is None:
        return None, "no weights file"
    path = model_path(weights)
    if not os.path.lexists(path):
        return None, f"no error model was fitted for {Path(weights).name} ({path.name} is absent)"
    if why := not_a_file(path):
        raise ValueError(f"error model {str(path)!r} {why}")
    d = _read_json(path)  # read once: whose it is, then (if these weights') every field
    named = d.get("weights_sha256") if isinstance(d, dict) else None
    if isinstance(named, str) and named != sha256(weights):
        return None, f"{path.name} was fitted for other weights than {Path(weights).name} (SHA-256 differs)"
    return ErrorModel.from_json(d, path), None


# ---------------------------------------------------------------- fitting


def fit(samples: list[tuple[np.ndarray, np.ndarray]], ridge: float = 1e-3) -> tuple[np.ndarray, float, np.ndarray,
                                                                                     np.ndarray]:
    """Fit log E[err] = b + w . (f - mean) / std on `samples` ((P_i, F) features, (P_i,) true errors in deg per
    object), each object weighted equally (Poisson deviance, L-BFGS; a small ridge on w). Returns (w, b, mean, std)."""
    from scipy.optimize import minimize

    x = np.concatenate([f for f, _ in samples])
    y = np.concatenate([e for _, e in samples]).astype(np.float64)
    wt = np.concatenate([np.full(len(e), 1.0 / len(e)) for _, e in samples])
    wt /= wt.sum()
    mean, std = x.mean(axis=0), x.std(axis=0)
    std = np.where(std > 1e-9, std, 1.0)
    z = (x - mean) / std

    def loss(p: np.ndarray) -> tuple[float, np.ndarray]:
        eta = np.clip(p[0] + z @ p[1:], -30, 30)
        mu = np.exp(eta)
        r = wt * (mu - y)
        return float((wt * (mu - y * eta)).sum() + ridge * (p[1:] ** 2).sum()), np.concatenate(
            [[r.sum()], z.T @ r + 2 * ridge * p[1:]])

    p0 = np.zeros(z.shape[1] + 1)
    p0[0] = np.log(max(float((wt * y).sum()), 1e-6))
    res = minimize(loss, p0, jac=True, method="L-BFGS-B", options={"maxiter": 2000})
    return res.x[1:], float(res.x[0]), mean, std


def fit_object_stage(pixel_means: np.ndarray, images: np.ndarray, true_means: np.ndarray,
                     groups: np.ndarray | None = None) -> list[float]:
    """[c0, c1, c2] of log(true mean) = c0 + c1 log(pixel mean) + c2 log(images), least squares over the objects.

    With `groups` (one label per sample; an object and its faulted copies share one), c2 is measured within the
    groups (each group's own means taken out: the same object with fewer images), where the image count is not
    mixed up with the other differences between objects (the calibration's rows differ in K and in shape at once);
    then c0 and c1 over every sample with c2 held."""
    x1, xk = np.log(np.maximum(pixel_means, 1e-6)), np.log(np.maximum(images, 1)).astype(np.float64)
    y = np.log(np.maximum(true_means, 1e-6))
    if groups is None:
        coef, *_ = np.linalg.lstsq(np.stack([np.ones(len(y)), x1, xk], axis=1), y, rcond=None)
        return [float(c) for c in coef]
    _, g = np.unique(np.asarray(groups), return_inverse=True)

    def within(v: np.ndarray) -> np.ndarray:
        return v - (np.bincount(g, v) / np.bincount(g))[g]

    wk = within(xk)
    c2 = 0.0
    if np.abs(wk).max() > 1e-9:  # some object was seen with two image counts
        (_, c2), *_ = np.linalg.lstsq(np.stack([within(x1), wk], axis=1), within(y), rcond=None)
    (c0, c1), *_ = np.linalg.lstsq(np.stack([np.ones(len(y)), x1], axis=1), y - c2 * xk, rcond=None)
    return [float(c0), float(c1), float(c2)]


# ---------------------------------------------------------------- files

FILES = EXPECTED_ERROR_FILES
"""What a prediction folder gains (`scenes.folder.format.EXPECTED_ERROR_FILES`): the per-pixel stated error as NumPy
and EXR arrays, and a picture of it on the fixed scale 0..`PICTURE_MAX_DEG`."""
PICTURE_MAX_DEG = 45.0
"""Top of the picture's colour scale (larger errors share its colour): the same scale for every map."""


def error_picture(per_pixel: np.ndarray) -> np.ndarray:
    """(H, W + bar, 3) uint8 BGR picture of a stated-error map, white outside the mask, with its colour bar."""
    import cv2

    from scenes.report.charts import colorbar

    inside = np.isfinite(per_pixel)
    codes = np.clip(np.nan_to_num(per_pixel) / PICTURE_MAX_DEG * 255, 0, 255).astype(np.uint8)
    bgr = cv2.applyColorMap(codes, cv2.COLORMAP_INFERNO)
    bgr[~inside] = 255
    bar = colorbar(bgr.shape[0], PICTURE_MAX_DEG, cv2.COLORMAP_INFERNO, "deg", fmt="{:.0f}")
    h = max(bgr.shape[0], bar.shape[0])

    def pad(a: np.ndarray) -> np.ndarray:
        return np.pad(a, ((0, h - a.shape[0]), (0, 0), (0, 0)), constant_values=255)

    return np.concatenate([pad(bgr), pad(bar)], axis=1)


def write_stated(folder: Path, stated: Stated) -> None:
    """Write `FILES` of `stated` into `folder`."""
    from scenes.files import atomic_write
    from scenes.images import write_exr, write_picture

    def save(tmp: Path) -> None:
        with open(tmp, "wb") as f:  # a file object: np.save would add .npy to the temporary name
            np.save(f, stated.per_pixel.astype(np.float32), allow_pickle=False)

    folder.mkdir(parents=True, exist_ok=True)
    atomic_write(folder / FILES[0], save)
    write_exr(folder / FILES[1], stated.per_pixel)
    write_picture(folder / FILES[2], error_picture(stated.per_pixel))
