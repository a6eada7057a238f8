"""The report of the fitted mode of the re-render check (`validate.rerender` on a folder without scene.json).

The verdict (`trusted`, `why`, `explained_fraction`, `explained.png`) and the observations of `judged_rel_l1` come
from the images alone (`validate.fitted.verdict`), so every map of a capture is judged on the same observations; the
check abstains (trusted false) where the images are not explained by the physics it can model.
Reference levels beside the score `rel_l1`: `noise_rel_l1` (the image noise, `validate.fitted.verdict.noise_rel_l1`),
and `floor_rel_l1`, the score the same fit (same budget, same seed) reaches with a normal map that carries no
information (constant (0, 0, 1), optionally also a silhouette-only map): a normal map scoring at or above
the floor explains nothing.
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scenes.files import to_plain
from scenes.renderer.variant import jit_threads, require_ad_variant
from validate.fitted import heightfield
from validate.fitted.ambiguity import bas_relief_test, not_tested
from validate.fitted.fit import FitResult, choose_downsample, fit_normals, prepare
from validate.fitted.fit_scene import FitConfig, Progress
from validate.fitted.verdict import Explanation, explain, judged_rel_l1, noise_rel_l1, told_apart, verdict
from validate.judgeable import check_judgeable
from validate.observations import Capture

RESOLUTION_NOTE = ("two judged scores of this capture closer than `resolution` are not told apart by the images: "
                   "a map fitted against the score (refined) can sit that far below the true surface, absorbing what "
                   "the physics lacks; compare maps by score only outside it")


def no_information_maps(mask: np.ndarray, kinds: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Normal maps carrying no photometric information: 'constant' (0, 0, 1), 'silhouette' (from the mask)."""
    out = {}
    for k in kinds:
        if k == "constant":
            out[k] = np.where(mask[..., None], np.float32([0, 0, 1]), 0).astype(np.float32)
        else:
            out[k] = heightfield.silhouette_normals(mask)
    return out


def full_config_dict(config: FitConfig) -> dict:
    d = asdict(config)
    d["floor_maps"] = list(config.floor_maps)
    return d


def _scatter(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(K, P, 3) mask-pixel values -> (K, H, W, 3) images, 0 outside the mask."""
    out = np.zeros((values.shape[0],) + mask.shape + (3,), np.float32)
    out[:, mask] = values
    return out


NOT_FITTED = ("floor_maps", "bas_relief")
"""Fields of a fit configuration that the fit around one map does not read (only the check's extra fits do):
two configurations differing only there give the same fit."""


def _fit_key(normals: np.ndarray, config: FitConfig) -> tuple:
    """What decides a fit of one capture: the map's bytes and every configuration field the fit reads."""
    fields = tuple((k, repr(v)) for k, v in sorted(asdict(config).items()) if k not in NOT_FITTED)
    return hashlib.sha256(np.ascontiguousarray(normals, np.float32).tobytes()).hexdigest(), fields


@dataclass
class JudgedCapture:
    """A capture and its normal map, prepared for fitting, with the verdict of its images: what the fitted check
    (`check_judged`) and the refinement (`validate.refine.refine_judged`) share, so a capture is read, reduced and
    explained once, and a fit they both need (the input map's, same configuration) is made once."""

    cap: Capture
    """The capture as read (full resolution)."""
    full: np.ndarray
    """(H, W, 3) the normal map to judge at full resolution (unit inside the mask)."""
    source: str
    """Where the map came from (its path, or "array")."""
    small: Capture
    """The capture at the fitting resolution."""
    normals: np.ndarray
    """(h, w, 3) the map at the fitting resolution."""
    downsample: int
    """Factor from the full to the fitting resolution."""
    explanation: Explanation
    """What the images alone explain (`validate.fitted.verdict.explain`): the same for every map of the capture."""
    trusted: bool
    why: str
    """The verdict (`validate.fitted.verdict.verdict`)."""
    fits: dict = field(default_factory=dict, repr=False)
    """Fits made so far, by `_fit_key`: the same fit asked twice is made once."""

    @property
    def observed(self) -> np.ndarray:
        """(K, P, 3) the images over the mask pixels at the fitting resolution."""
        return self.small.images[:, self.small.mask]

    def score(
        self, normals: np.ndarray, config: FitConfig, progress: Progress | None, label: str
    ) -> tuple[FitResult, float]:
        """Fit lights and reflectance around `normals` (fitting resolution) held fixed: (the fit, its judged
        rel_l1 on the observations every map of the capture shares). Deterministic for a given map and
        configuration, so a second request returns the first fit."""
        key = _fit_key(normals, config)
        if key not in self.fits:
            s = self.small
            res = fit_normals(s.images, s.mask, normals, config, progress, label, s.saturated)
            self.fits[key] = res, judged_rel_l1(res.render, self.observed, self.explanation)
        return self.fits[key]

    def check_fit(self, config: FitConfig) -> None:
        """Refuse a configuration that would reduce the capture otherwise than it was (the shared start holds for
        one fitting resolution)."""
        f = config.downsample or choose_downsample(self.cap.mask, config.max_pixels)
        if f != self.downsample:
            raise ValueError(f"config: fits at 1/{f} resolution, the judged capture was reduced to 1/{self.downsample}")


def judge(cap: Capture, full: np.ndarray, config: FitConfig, use: str, source: str = "array",
          args: tuple[str, str] = ("--data", "--data")) -> JudgedCapture:
    """A capture (read from a folder or built from arrays) and its normal map (H, W, 3, already checked:
    `validate.observations.unit_normals`), both reduced to the fitting resolution, the images checked to be judgeable
    for `use` (`validate.judgeable`) before any fitting, and explained (the verdict). `args`: the flags that gave
    the images and the mask, named when they are refused."""
    small, n_small, f = prepare(cap, full, config)
    check_judgeable(small, use, *args)  # before any fitting: enough images and lit pixels
    ex = explain(small.images, small.mask, small.saturated)  # from the images alone: the same for every map
    trusted, why = verdict(ex)
    return JudgedCapture(cap, full, source, small, n_small, f, ex, trusted, why)


def judge_capture(data: str | JudgedCapture, normals: str | np.ndarray | None, config: FitConfig, use: str,
                  out_dir: str | None, outputs: tuple[str, ...], owner: str,
                  overwrite: bool) -> tuple[JudgedCapture, Path | None]:
    """The judged capture for `use` and `out_dir/<object>/outputs` claimed for `owner`: an object folder (any
    layout, read once) and its normal map (claimed before judging), or a capture already judged (in memory, shared
    by the check and the refinement: its fitting resolution must be the one `config` asks for)."""
    from validate.observations import load_with_normals

    if isinstance(data, JudgedCapture):
        data.check_fit(config)
        check_judgeable(data.small, use)
        return data, claim_target(out_dir, data.cap.name, outputs, owner, overwrite)
    cap, full, source = load_with_normals(data, normals)
    target = claim_target(out_dir, cap.name, outputs, owner, overwrite)
    return judge(cap, full, config, use, source), target


def claim_target(out_dir: str | Path | None, name: str, outputs: tuple[str, ...], owner: str,
                 overwrite: bool) -> Path | None:
    """`out_dir/<name>` with its `outputs` claimed for `owner` (the one --overwrite rule), or None without out_dir.
    Its JSON report marks the folder's files as an earlier check's: without one there, or with a file of that name
    that is no report of `validate` (no mode and object), nothing is replaced, even with --overwrite."""
    if out_dir is None:
        return None
    from scenes.cli.outputs import claim_outputs

    target = Path(out_dir) / name
    record = next(target / n for n in outputs if n.endswith(".json"))
    claim_outputs([target / n for n in outputs], overwrite, owner=owner, marker=record,
                  signed={record: ("mode", "object")})
    return target


def provenance(mi: Any) -> dict:
    """The Mitsuba variant and Dr.Jit threads of a fitted report."""
    return {"variant": mi.variant(), "jit_threads": jit_threads()}


CHECK_OUTPUTS = ("report.json", "figure.png", "explained.png")
"""What the fitted check writes into <out>/<object>/."""


def rerender_fitted(
    data: str | JudgedCapture,
    normals: str | np.ndarray | None = None,
    config: FitConfig | None = None,
    out_dir: str | None = None,
    progress: Progress | None = None,
    overwrite: bool = False,
) -> dict:
    """Fitted mode of the re-render check for one object folder (any layout) and its `normals`, or for a capture
    already judged (`judge`: in memory, shared with a refinement); returns the report and writes
    `out_dir/<object>/report.json`, `figure.png` and `explained.png` when out_dir is given."""
    config = (config or FitConfig()).validate()
    require_ad_variant()
    jc, target = judge_capture(data, normals, config, "check", out_dir, CHECK_OUTPUTS, "validate.rerender", overwrite)
    report, res = check_judged(jc, config, progress)
    if target is not None:
        write_fitted(jc, target, res, report)
    return report


def check_judged(jc: JudgedCapture, config: FitConfig, progress: Progress | None = None) -> tuple[dict, FitResult]:
    """The fitted check of a judged capture's map: (report, the fit of the map)."""
    from scenes.metrics import mean_angular_error as mae_deg
    from validate.fitted.light_models import angular_errors_deg, directions_of

    mi = require_ad_variant()
    t0 = time.perf_counter()
    cap, small, n_small, ex, trusted = jc.cap, jc.small, jc.normals, jc.explanation, jc.trusted
    res, judged = jc.score(n_small, config, progress, "fit")
    floors, judged_floors = {}, {}
    for kind, nmap in no_information_maps(small.mask, config.floor_maps).items():
        fr, judged_floors[kind] = jc.score(nmap, config, progress, f"floor ({kind})")
        floors[kind] = fr.rel_l1
    if not config.bas_relief:
        ambiguity = not_tested("not tested (--no-bas-relief)")
    elif not trusted:
        ambiguity = not_tested("not tested: the check abstains on this capture")
    elif res.model != "directional":
        ambiguity = not_tested(f"not tested: the test needs the directional light model (fitted: {res.model})")
    else:
        ambiguity = bas_relief_test(
            small.images, small.mask, n_small, res, judged, ex, config, small.saturated, progress
        )
    report: dict[str, Any] = {
        "mode": "fitted",
        "object": cap.name,
        "folder": str(cap.folder),
        "layout": cap.layout,
        "prediction": jc.source,
        "images_count": int(cap.images.shape[0]),
        "image_names": cap.image_names,
        "mask_pixels": int(cap.mask.sum()),
        "trusted": trusted,
        "why": jc.why,
        "explained_fraction": ex.explained_fraction,
        "judged_rel_l1": to_plain(judged),
        "judged_floor_rel_l1": to_plain(min(judged_floors.values())) if judged_floors else None,
        "resolution": to_plain(ex.resolution),
        "resolution_note": RESOLUTION_NOTE,
        "told_apart_from_floor": (told_apart(judged, min(judged_floors.values()), ex) if judged_floors else None),
        "light_dimensions": ex.light_dimensions,
        "light_dimension_noise_units": [round(d, 2) for d in ex.dimensions],
        "ambiguity": ambiguity,
        "rel_l1": res.rel_l1,
        "noise_rel_l1": to_plain(noise_rel_l1(ex, jc.observed)),
        "floor_rel_l1": min(floors.values()) if floors else None,
        "floors": floors,
        "mae_deg": mae_deg(n_small, small.normal_gt, small.mask) if small.normal_gt is not None else None,
        "mae_resolution": fit_resolution_label(jc.downsample, small.mask.shape, cap.mask.shape),
        "light_model": res.model,
        "lights": res.lights,
        "specular": res.specular,
        "per_image_rel_l1": res.per_image_rel_l1,
        "fit_downsample": jc.downsample,
        "fit_resolution": list(small.mask.shape),
        "fit_mask_pixels": int(small.mask.sum()),
        "saturated_fraction": saturated_fraction(small),
        "note": (
            f"fitted and scored at 1/{jc.downsample} resolution ({small.mask.shape[1]}x{small.mask.shape[0]}, "
            "box filter)"
            if jc.downsample > 1
            else "fitted and scored at full resolution"
        ),
        "config": full_config_dict(config),
        **provenance(mi),
    }
    if small.light_directions is not None:
        err = angular_errors_deg(directions_of(res.model, res.light_params), small.light_directions)
        report["calibrated_light_error_deg"] = {
            "mean": float(err.mean()),
            "median": float(np.median(err)),
            "max": float(err.max()),
        }
    report["timings"] = {"fit_s": res.seconds, "total_s": time.perf_counter() - t0}
    return report, res


def write_fitted(jc: JudgedCapture, target: Path, res: FitResult, report: dict) -> None:
    """report.json, figure.png and explained.png of the fitted check into `jc.target`."""

    from scenes.files import write_json
    from scenes.folder.format import prediction_label
    from scenes.images import write_picture
    from scenes.metrics import angular_error_deg
    from validate.figures import explained_picture, rerender_figure
    from validate.residuals import relative_residual_map

    small, n_small, ex = jc.small, jc.normals, jc.explanation
    target.mkdir(parents=True, exist_ok=True)
    renders = _scatter(res.render, small.mask)
    k = renders.shape[0]
    rows = sorted(set(np.linspace(0, k - 1, min(k, 4)).round().astype(int).tolist()))
    write_picture(target / "explained.png", explained_picture(small.mask, ex.explained))
    rerender_figure(
        target / "figure.png",
        small.images,
        renders,
        small.mask,
        rows,
        relative_residual_map(renders, small.images, small.mask),
        None,
        n_small,
        title=f"{jc.cap.name}, {prediction_label(jc.source)} "
        f"(fitted lights, {'trusted' if jc.trusted else 'NOT TRUSTED'}): "
        f"judged rel_l1 {report['judged_rel_l1'] or float('nan'):.4f}, floor "
        f"{report['judged_floor_rel_l1'] or float('nan'):.4f}"
        + (
            f", MAE {report['mae_deg']:.2f} deg {report['mae_resolution']}" if report.get("mae_deg") is not None else ""
        ),
        angular_error=None if small.normal_gt is None else angular_error_deg(n_small, small.normal_gt, small.mask),
        explained=ex.explained,
    )
    write_json(target / "report.json", report, indent=1)


def fit_resolution_label(downsample: int, fitted: tuple[int, ...], full: tuple[int, ...]) -> str:
    """Where the fitted mode's numbers (its MAE too) were computed: 'at 32x32 (1/2 of 64x64)' or 'at 64x64 (full
    resolution)'; `unips.evaluate` scores at full resolution, so the two differ when this says 1/2."""
    size = f"{fitted[1]}x{fitted[0]}"
    return f"at {size} (1/{downsample} of {full[1]}x{full[0]})" if downsample > 1 else f"at {size} (full resolution)"


def saturated_fraction(cap: Capture) -> float:
    """Fraction of the mask observations (images x pixels x channels) that are saturated (censored)."""
    if cap.saturated is None:
        return 0.0
    return float(cap.saturated[:, cap.mask].mean())
