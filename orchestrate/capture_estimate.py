"""The capture's estimate of its own peak memory and time, before it reads the photos (`orchestrate.capture`), and
the refusal when the machine does not have the memory.

Linear fits to bench/bench_capture.py's measurements on 2 cores (4 to 96 photos of 0.05 to 25 megapixels, 16-bit PNG,
JPEG and camera RAW): memory 5 % above every measured peak or more (the fixed, per-photo and per-value terms the
smallest that are, by linear programming, with the surface's and the full-size terms set from their own
measurements), then widened by the run-to-run spread of one capture's peak (`PEAK_SPREAD`), time within a factor
1.5 of every measured time (docs/capture.md shows both side by side).
"""
from __future__ import annotations

BASE_MIB = 966.0
"""Memory before the photos: Python, torch, Mitsuba / Dr.Jit and the model."""
MIB_PER_IMAGE = 13.9
"""Memory per photo that does not grow with its size (the model's per-image state, the fit's per-image arrays)."""
MIB_PER_MVALUE = 13.4
"""Memory per 2^20 photo values at the working size (K x h x w x 3): the float32 stack, the model's and the check's
working copies."""
PEAK_SPREAD = 1.1
"""The fitted memory times this: one capture's peak varies from run to run (glibc's arenas and the threads'
timing), which single runs of the bench do not show. Measured on DiLiGenT ball, 96 JPEG photos, the same command
four times: 3603, 3608, 3629 and 4067 MiB (the last while another heavy job ran); the fitted terms, 5 % above the
bench's single runs, gave 3861; with this factor 4247."""
SMALLEST_SIDE = 32
"""The smallest working size a capture takes (`orchestrate.capture.MIN_SIDE`, the least --max-side but 0)."""
SECONDS_START = 6.4
"""Start-up: Python, torch, Mitsuba / Dr.Jit and the model loaded."""
SECONDS_BASE = 1.84
"""The fixed part of the check."""
SECONDS_REFINE = 17.3
"""The fixed part of the refinement, run from 5 photos on (the check cannot judge fewer)."""
SECONDS_PER_IMAGE = 0.399
"""The check and the refinement per photo, apart from its size."""
SECONDS_PER_IMAGE_MPIXEL = 1.188
"""The check and the refinement per photo and megapixel (their fitting resolution grows with the photos')."""
SECONDS_LIGHTS_PER_IMAGE = 0.13
"""Reading each photo's light from the shading under the model's map (`validate.diagnosis.light_reading`), added
after the bench's fit: 0.13 s a photo on 2 busy cores."""
SECONDS_PER_MVALUE = 1.396
"""Reading, the mask, the capture checks, the model and writing, per million photo values (K x H x W x 3)."""
SECONDS_SURFACE_PER_MPIXEL = 13.0
"""The surface of the final map per megapixel of the frame (bench_capture: 10 to 12 s over masks of about 60 % of
the frame; the surface command's own bound, `orchestrate.surface.SECONDS_PER_MPIXEL`, is per mask pixel)."""
SECONDS_PER_FULL_MVALUE = 0.01
"""Photos larger than the working size: decoding them at their own size, per million values (K x H x W x 3)."""
SECONDS_PER_FULL_MPIXEL = 0.5
"""Photos larger than the working size: the map and the mask brought to their size and written, per megapixel."""


def estimate(k: int, h: int, w: int, full: tuple[int, int] | None = None) -> dict:
    """The command's peak memory (MiB) and time (s, on 2 cores) for K photos worked on at h x w, before it runs
    (bench_capture compares them with what it measures); `full`: the photos' own (H, W) when larger (their
    decoding, and the map and mask written at their size, `orchestrate.capture_full`)."""
    values = k * h * w * 3
    from orchestrate.capture_full import BYTES_PER_FULL_PIXEL
    from orchestrate.surface import BYTES_PER_IMAGE_PIXEL, BYTES_PER_PIXEL
    from validate.judgeable import MIN_IMAGES

    refine = SECONDS_REFINE if k >= MIN_IMAGES["refine"] else 0.0
    mpx = h * w / 1e6
    check = SECONDS_BASE + refine + (SECONDS_PER_IMAGE + SECONDS_PER_IMAGE_MPIXEL * mpx) * k
    # The surface of the final map, at most every pixel, added whole: the memory estimate stays an upper bound.
    surface_mib = (BYTES_PER_PIXEL + BYTES_PER_IMAGE_PIXEL) * h * w / 2**20
    big = full is not None and full[0] * full[1] > h * w
    full_px = full[0] * full[1] if big else 0
    return {"peak_mib": round(PEAK_SPREAD * (BASE_MIB + MIB_PER_IMAGE * k + MIB_PER_MVALUE * values / 2**20
                                             + surface_mib + BYTES_PER_FULL_PIXEL * full_px / 2**20)),
            "seconds": round(SECONDS_START + check + SECONDS_LIGHTS_PER_IMAGE * k + SECONDS_PER_MVALUE * values / 1e6
                             + SECONDS_SURFACE_PER_MPIXEL * mpx + SECONDS_PER_FULL_MVALUE * k * full_px * 3 / 1e6
                             + SECONDS_PER_FULL_MPIXEL * full_px / 1e6, 1),
            "check_s": round(check, 1)}


def check_resources(k: int, h: int, w: int, full: tuple[int, int] | None = None) -> dict:
    """The estimate, refused in one line above the memory this machine has available."""
    from scenes.cli.limits import available_memory, check_memory

    need, what, available = estimate(k, h, w, full), f"{k} photos of {w} x {h} px", available_memory()
    least = estimate(k, min(h, SMALLEST_SIDE), min(w, SMALLEST_SIDE))["peak_mib"]  # at the smallest --max-side
    if available is not None and least * 2**20 > available:  # then a smaller --max-side would not help
        check_memory(need["peak_mib"] * 2**20, "--input", what, f"even at --max-side {SMALLEST_SIDE} they would "
                     f"need about {least / 1024:.1f} GiB: use fewer photos, or a machine with more memory", available)
    check_memory(need["peak_mib"] * 2**20, "--max-side", what,
                 "give a smaller --max-side (e.g. --max-side 1024) to downscale them, or use fewer photos", available)
    return need
