"""The options of the known-scene re-render check and its renders (`validate.rerender`).

Every image's scene is rebuilt from scene.json once, wrapped so that the shading normal of each
camera-visible surface point can be swapped for the predicted one (`validate.known.normal_bsdf`), and rendered
with each image's recorded seed and spp: with the predicted normals (the score), with the ground-truth
normals, with the wrapper switched off (reproduction check), and the original scene with independent
seeds (noise floor).
"""
from __future__ import annotations

import gc
import hashlib
import time
from dataclasses import dataclass, field
from typing import Annotated, Any, Callable, Literal

import numpy as np

from scenes.cli.options import arg, check_fields, option
from validate.known.normal_bsdf import (
    MODE_PASSTHROUGH,
    MODE_PREDICTED,
    NormalSwap,
    VisibilityConfig,
    depth_map,
    wrapper_for,
)
from validate.known.projection import CameraProjection
from validate.observations import Capture
from validate.residuals import expose

SEED_MODES = ("same", "independent")


MIN_COVERAGE = 0.9
"""Default smallest share of the mask a prediction must cover (--min-coverage): a sparser map is refused."""


Progress = Callable[[int, int, str], None]
"""progress(done, total, label): called after each render."""


@dataclass
class RerenderConfig:
    """Options of the re-render check."""

    spp: Annotated[int | None, arg(help_behavior_hint="(default: the recorded spp)")] = option(None, minimum=1,
                                                                                                    maximum=65536)
    """Samples per pixel (at most 65536); None = the recorded render.spp (required for common random numbers)."""
    seed_mode: Literal[SEED_MODES] = "same"
    """'same': each image's recorded seed (noise largely cancels); 'independent': fresh seeds."""
    floors: bool = True
    """Also render the independent-seed noise floor and the reproduction check (2 more renders per image)."""
    visibility: VisibilityConfig = field(default_factory=VisibilityConfig)
    """How camera visibility of surface points is decided (on the command line: the depth-map rays per pixel
    side; the tolerances are fixed)."""
    threshold: Annotated[
        float | None, arg(help_behavior_hint="(default: 99th percentile of the noise-floor residual map)")
    ] = option(None, above=0)
    """Per-pixel relative residual counted in frac_above_threshold; None = 99th percentile of the
    noise-floor residual map (needs floors)."""
    figure_rows: int = option(4, minimum=1)
    """Images shown in figure.png."""
    save_renders: bool = False
    """Also write the re-rendered images as R000.png.. (16-bit, exposure applied)."""
    allow_missing: bool = False
    """Accept exactly-zero normals inside the mask as "no estimate" (counted in missing_pixels, coverage, and
    as 90 deg in mae_deg). They can never improve a score: such a point keeps the surface's own normal for
    light transport, but each of its pixels is scored as at least as wrong as a black render (relative residual
    >= 1, see `penalise_missing`). Otherwise they are an error."""
    min_coverage: float = option(MIN_COVERAGE, minimum=0, maximum=1)
    """Smallest share of the mask pixels that must hold an estimate (with allow_missing); a map below it is refused."""

    def validate(self) -> "RerenderConfig":
        check_fields(self)
        self.visibility.validate()
        return self


def independent_seed(seed: int) -> int:
    """A seed unrelated to `seed` (hash), deterministic, in Mitsuba's uint32 range."""
    return int.from_bytes(hashlib.sha256(f"rerender-independent:{seed}".encode()).digest()[:4], "little")


def _render_all(
    built: Any,
    indices: range,
    spp: int,
    seeds: list[int],
    exposures: list[float],
    tick: Callable[[str], None],
    label: str,
) -> tuple[np.ndarray, list[float]]:
    from scenes.renderer.render import render_image

    out, times = [], []
    for i in indices:
        t0 = time.perf_counter()
        radiance = render_image(built, i, spp=spp, seed=seeds[i])
        times.append(time.perf_counter() - t0)
        out.append(expose(radiance, exposures[i]))
        tick(f"{label} {i:03d}")
    return np.stack(out), times


@dataclass
class RenderPasses:
    """The images of one re-render check (each (K, H, W, 3), exposure applied) and their timings."""

    renders: np.ndarray
    """With the predicted normals (the score)."""
    rerender_s: list[float]
    """Per-image time of those renders."""
    gt: np.ndarray | None = None
    """With the ground-truth normals (when the folder has them)."""
    floor: np.ndarray | None = None
    """The original scene with independent seeds (noise floor)."""
    original_s: list[float] = field(default_factory=list)
    """Per-image time of the original scene's renders."""
    reproduce: np.ndarray | None = None
    """The wrapper switched off with the recorded seeds (should reproduce the inputs)."""
    build_s: float = 0.0
    depth_map_s: float = 0.0


def render_passes(data: Capture, pred: np.ndarray, valid: np.ndarray, config: RerenderConfig, spp: int,
                  seeds: list[int], fresh: list[int], tick: Callable[[str], None]) -> RenderPasses:
    """Render every pass of the check for one object (Mitsuba work only; no scoring)."""
    from scenes.renderer.build import build_scene

    desc, k = data.desc, len(data.desc.images)
    exposures = [float(im.exposure) for im in desc.images]
    recorded = [int(im.seed) for im in desc.images]
    reproduce = config.floors and spp == desc.render.spp

    # 1. The original scene with independent seeds: noise floor and the original render time. It is
    #    released before the wrapped scene is built (live Python BSDFs are traced into every kernel).
    floor_imgs, t_orig = None, []
    if config.floors:
        built = build_scene(desc, data.folder)
        floor_imgs, t_orig = _render_all(built, range(k), spp, fresh, exposures, tick, "noise floor")
        del built
        gc.collect()

    # 2. The wrapped scene: one build, normals and mode swapped through mi.traverse.
    t0 = time.perf_counter()
    camera = CameraProjection.from_camera(desc.camera)
    built = build_scene(desc, data.folder, bsdf_wrapper=wrapper_for(camera, config.visibility))
    swap = NormalSwap.attach(built.params, camera, config.visibility)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    built.park_lights()  # area-light rectangles out of the way: the depth map holds the object only
    swap.set_depth(depth_map(built.scene, camera, config.visibility.supersample))
    built.apply_image(0)
    t_depth = time.perf_counter() - t0

    repro_imgs = None
    if reproduce:
        swap.set_mode(MODE_PASSTHROUGH)
        repro_imgs, _ = _render_all(built, range(k), spp, recorded, exposures, tick, "reproduce")
    swap.set_normals(pred, valid)
    swap.set_mode(MODE_PREDICTED)
    renders, t_re = _render_all(built, range(k), spp, seeds, exposures, tick, "re-render")
    gt_imgs = None
    if data.normal_gt is not None:
        swap.set_normals(data.normal_gt, data.mask)
        gt_imgs, _ = _render_all(built, range(k), spp, seeds, exposures, tick, "GT normals")
    del swap, built
    gc.collect()
    return RenderPasses(renders=renders, rerender_s=t_re, gt=gt_imgs, floor=floor_imgs, original_s=t_orig,
                        reproduce=repro_imgs, build_s=t_build, depth_map_s=t_depth)
