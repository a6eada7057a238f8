"""The optimiser of the fitted mode: light and reflectance fitted around a normal map by Adam.

On the scene of `validate.fitted.fit_scene`, light (per image, `validate.fitted.light_models`) and reflectance are
fitted by Adam on a robust L1 loss with Dr.Jit automatic differentiation through the BSDF and the light model
(`llvm_ad_rgb` on a CPU, `cuda_ad_rgb` on a GPU); visibility is recomputed (not differentiated) every
`refresh_every` steps, and the albedo is solved in closed form (linear least squares) at the same time;
the start is the closed-form Lambertian least-squares fit of `validate.fitted.light_models.closed_form_directional`.
`validate.refine` runs the same optimiser with the normals free too.

Score: rel_l1 = sum |render - input| / sum |input| over the mask pixels of all images (all channels), at
the fitting resolution (`prepare` downsamples the capture). The report with its reference levels is
`validate.fitted.fit_report`.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from scenes.cli.needs import Needs, value_of
from validate.fitted.fit_scene import FitConfig, FitScene, Progress, lambertian_start, to_jit
from validate.fitted.light_models import LIGHT_MODELS, report_lights
from validate.observations import Capture

FIT_NEEDS = (
    Needs("interreflection", lambda c, _: value_of(c, "ao_rays") > 0 or not value_of(c, "interreflection"),
          "with --ao-rays above 0 (the bounce is traced with those rays)"),
    Needs("max_pixels", lambda _, given: "downsample" not in given, "without --downsample (which sets the factor)"))
"""The fit's flags that act only with another (`scenes.cli.needs`), for the commands that take a `FitConfig`."""

log = logging.getLogger(__name__)


def choose_downsample(mask: np.ndarray, max_pixels: int) -> int:
    """Smallest integer factor f such that the mask has at most max_pixels pixels after f x f boxes."""
    return max(1, int(np.ceil(np.sqrt(mask.sum() / max_pixels))))


@dataclass
class FitResult:
    """What a fit produced (all at the fitting resolution)."""

    rel_l1: float
    """Score: relative L1 of the fitted render over the mask, all images."""
    per_image_rel_l1: list[float]
    """The same per image."""
    render: np.ndarray
    """(K, P, 3) fitted render of the mask pixels."""
    albedo: np.ndarray
    """(P, 3) fitted albedo."""
    lights: list[list[dict]]
    """report.json `lights`."""
    light_params: dict
    """Fitted light arrays (numpy), see validate.fitted.light_models.report_lights."""
    specular: dict
    """{'roughness': r, 'specular': s} of the principled lobe."""
    model: str
    """Light model used."""
    seconds: float
    """Wall time of the fit."""
    loss_history: list[float] = field(default_factory=list)
    """Training loss every refresh."""


def _np_params(fs: FitScene) -> dict:
    out = {}
    for k, v in fs.params.items():
        if k == "sh":
            out["sh"] = np.stack([np.array(c, np.float64).T for c in v], 1)  # (K, 9, 3)
        else:
            out[k] = np.array(v, np.float64).T
    res = {}
    if "dir" in out:
        res["directions"] = out["dir"] / np.linalg.norm(out["dir"], axis=1, keepdims=True)
        res["irradiance"] = np.exp(out["log_e"])
    if "pos" in out:
        res["positions"] = out["pos"]
        res["intensity"] = np.exp(out["log_e"])
    if "log_a" in out:
        res["ambient"] = np.exp(out["log_a"])
    if "sh" in out:
        res["sh"] = out["sh"]
    return res


def _normalise_albedo(fs: FitScene, params: dict) -> dict:
    """Scale albedo so its mean is 0.5 and lights inversely (the scale is not observable)."""
    m = float(fs.albedo_np.mean())
    if m <= 0:
        return params
    s = 0.5 / m
    out = dict(params)
    for key in ("irradiance", "intensity", "ambient", "sh"):
        if key in out:
            out[key] = out[key] / s
    fs.albedo_np = fs.albedo_np * s
    return out


def run_fit(
    fs: FitScene,
    steps: int,
    optimise_normals: bool = False,
    regulariser: Callable[[Any], Any] | None = None,
    holdout: np.ndarray | None = None,
    on_eval: Callable[[int, float], bool] | None = None,
    progress: Progress | None = None,
    label: str = "fit",
    wide_lobe: bool | None = None,
) -> list[float]:
    """Adam on the scene parameters of `fs` (and its normals when `optimise_normals`), refreshing
    visibility, occlusion, inter-reflection and the closed-form albedo every `refresh_every` steps.
    wide_lobe: run the grid search of the lobe at the start (default: when the normals are held).

    holdout: image indices never used in a step; `on_eval(step, holdout_rel_l1)` is called at each refresh
    when given and may return True to stop early. Returns the training-loss history (one per refresh)."""
    mi, dr = fs.mi, fs.dr
    cfg = fs.config
    train = np.setdiff1d(np.arange(fs.k), holdout if holdout is not None else [])
    opt = mi.ad.Adam(lr=cfg.lr)
    for name, val in fs.param_list(optimise_normals):
        opt[name] = val
    history: list[float] = []

    def pull() -> None:
        for name, _ in fs.param_list(optimise_normals):
            if name.startswith("sh"):
                fs.params["sh"][int(name[2:])] = opt[name]
            elif name == "normals":
                fs.normals = opt[name]
            else:
                fs.params[name] = opt[name]

    def refresh(wide_lobe: bool = False) -> None:
        pull()
        if optimise_normals:
            fs.n_np = np.array(dr.normalize(fs.normals), np.float64).T
        fs.refresh_visibility()
        D, S = fs.render_np()
        fs.solve_albedo(D, S)
        fs.refresh_indirect(fs.albedo_np[None] * D + S)
        fs.search_lobe(fs.rng.choice(train, size=min(cfg.batch_images, len(train)), replace=False), wide=wide_lobe)

    # Every step's image batch, drawn now and kept on the device (a new array per step would recompile).
    bsize = min(cfg.batch_images, len(train))
    plan = to_jit(
        mi.UInt32,
        np.concatenate([fs.rng.choice(train, size=bsize, replace=False) for _ in range(max(steps, 1))]).astype(
            np.uint32
        ),
    )
    fs.refresh_occlusion()
    # The wide lobe search once per light fit, not while normals move (the lobe was fitted to the lights).
    refresh(wide_lobe=(not optimise_normals) if wide_lobe is None else wide_lobe)
    for step in range(steps):
        if step and step % cfg.refresh_every == 0:
            refresh()
            if on_eval is not None and holdout is not None and len(holdout):
                r = fs.render(holdout)
                stop = on_eval(step, fs.score(r, holdout))
                if stop:
                    break
        batch = dr.gather(mi.UInt32, plan, dr.arange(mi.UInt32, bsize) + dr.opaque(mi.UInt32, step * bsize))
        decay = 0.1 + 0.9 * 0.5 * (1 + np.cos(np.pi * step / max(steps, 1)))  # cosine decay to 10 %
        opt.set_learning_rate(
            {name: cfg.lr * decay * (0.5 if name == "normals" else 1.0) for name, _ in fs.param_list(optimise_normals)}
        )
        pull()
        loss = fs.loss(batch)
        total = loss + regulariser(opt["normals"]) if (regulariser is not None and optimise_normals) else loss
        dr.backward(total)
        opt.step()
        if step % cfg.refresh_every == 0:
            history.append(float(loss.array[0]) if hasattr(loss, "array") else float(loss[0]))
        if progress is not None:
            progress(step + 1, steps, label)
    pull()
    refresh()
    return history


def fit_normals(
    images: np.ndarray,
    mask: np.ndarray,
    normals: np.ndarray,
    config: FitConfig | None = None,
    progress: Progress | None = None,
    label: str = "fit",
    saturated: np.ndarray | None = None,
    start: dict | None = None,
) -> FitResult:
    """Fit light and reflectance around a fixed normal map. images (K, H, W, 3), mask (H, W), normals
    (H, W, 3) unit inside the mask, saturated (K, H, W, 3) bool or None (censored observations, see
    `FitScene`), all at the fitting resolution (see `prepare`). start: the parameters to start from
    (`validate.fitted.light_models.closed_form_directional`'s form, one light model only) instead of the closed-form
    start."""
    config = (config or FitConfig()).validate()
    models = LIGHT_MODELS if config.light_model == "auto" else (config.light_model,)
    best: FitResult | None = None
    for model in models:
        t0 = time.perf_counter()
        steps = config.steps if len(models) == 1 else max(1, config.steps // 3)
        fs = FitScene(images, mask, normals, config, model, saturated)
        if start is not None and len(models) > 1:
            raise ValueError("start: a given start needs one light model, not 'auto'")
        fs.init_params(lambertian_start(fs) if start is None else start)
        hist = run_fit(fs, steps, progress=progress, label=f"{label} ({model})")
        render = fs.render()
        params = _normalise_albedo(fs, _np_params(fs))
        per = [fs.score(render[i : i + 1], [i]) for i in range(fs.k)]
        res = FitResult(
            rel_l1=fs.score(render),
            per_image_rel_l1=per,
            render=render.astype(np.float32),
            albedo=fs.albedo_np.astype(np.float32),
            lights=report_lights(model, params),
            light_params=params,
            specular={"roughness": float(fs.lobe[0]), "specular": float(fs.lobe[1])},
            model=model,
            seconds=time.perf_counter() - t0,
            loss_history=hist,
        )
        log.info("%s: model %s rel_l1 %.4f in %.1f s", label, model, res.rel_l1, res.seconds)
        if best is None or res.rel_l1 < best.rel_l1:
            best = res
        del fs
    assert best is not None
    return best


FIT_BYTES_PER_LANE = 1200
"""Memory of one (image, mask pixel) lane of the fit (Dr.Jit values, their gradients, the refresh's NumPy
arrays): twice the 600 bytes measured on a 256 px object with 8 images (llvm_ad_rgb)."""


def check_fit_memory(cap: Capture, f: int) -> None:
    """Refuse a fit this machine cannot hold: K x (mask pixels at 1/f) lanes (`FIT_BYTES_PER_LANE`), before any
    work, naming the flags that set the fitting resolution."""
    from scenes.cli.limits import check_memory

    k, pixels = int(cap.images.shape[0]), int(np.ceil(cap.mask.sum() / f**2))
    check_memory(k * pixels * FIT_BYTES_PER_LANE, "--max-pixels/--downsample",
                 f"the fit of {cap.name} ({k} images x {pixels} mask pixels at 1/{f} resolution)",
                 "lower --max-pixels or raise --downsample")


def prepare(cap: Capture, normals: np.ndarray, config: FitConfig) -> tuple[Capture, np.ndarray, int]:
    """Downsample a capture and its normal map (H, W, 3) for fitting. Returns (capture, normals, factor)."""
    from validate.observations import downsample_capture, downsample_normals

    f = config.downsample or choose_downsample(cap.mask, config.max_pixels)
    check_fit_memory(cap, f)
    small = downsample_capture(cap, f)
    n = downsample_normals(normals, small.mask, f)
    n = np.where(small.mask[..., None] & (np.linalg.norm(n, axis=-1, keepdims=True) < 0.5), np.float32([0, 0, 1]), n)
    return small, n.astype(np.float32), f


