"""Is this capture usable? What the images alone say before any model runs: the per-pixel light variation, an
object mask when none is given, and the warnings a person can act on.

- `validate.diagnosis.mask_seed.variation_map`: how much each pixel changes across the images (standard deviation
  of its gray value over the images, relative to the bright level of the capture); the object changes with the
  light, a far or dark background does not.
- `auto_mask`: Otsu's threshold on the variation map as the seed, refined by GrabCut (OpenCV) on the capture's
  brightest image, the largest connected part kept and its holes filled, except holes the background shows
  through (they vary like it: `mask_seed.HOLE_LEVEL`). Its confidence is Otsu's
  separability (between-class over total variance of the variation map, 1 = two perfectly apart classes).
  It refuses (ValueError asking for `--mask FILE`) where it cannot tell object from background: a backdrop that
  changes with the light about as much as the object (the border of the frame varies like the object), a separability
  below `MIN_SEPARABILITY`, or a mask that fills almost nothing or almost the whole frame; all-black images: named.
- `mask_doubts`: whether an automatic mask may be wrong though it was found (`doubtful_mask`, never fatal): the
  light variation is the only evidence of where the object is, and a mask it does not support (one that leaves out
  much of what changes with the light, is made largely of what hardly changes, or largely of one flat surface lit
  alike in every photo, or holds a flat surface reaching out beside the rest, or changes when the variation is
  read on a logarithmic scale) may have followed a lit surface under the object, a highlight, or only a part of it.
- `capture_warnings`: `too_few_images`, `too_dark`, `saturated`, `frontal_light`, `one_sided_light`,
  `camera_moved`, each a `CaptureWarning` with a message saying what to change; the fatal ones stop.

Light directions are estimated from the images alone on the object's outline, where the normal lies in the image
plane along the outline's normal (the occluding contour): the brightness along the outline, summed as a vector of
its outward normals, points to the light's azimuth, and its length over the object's bright level grows with the
light's angle from the view (turned into an angle by an analytic Lambertian sphere's curve, `_outline_curves`);
light from all around (an environment) leaves the vector short but the outline bright, so the outline's mean
brightness gives a second angle and the larger is taken. Elongated shapes, albedo patterns and highlights on the
outline bias it (real objects read low), so frontal light also asks the light spread (`light_spread_deg`: each
pixel's brightness variation over its mean across the images, the albedo cancels, as the ring of lights giving a
sphere the same). Both light warnings are hints, never fatal; once a map exists (the capture's model map) they read
the lights from the shading under it (`validate.diagnosis.light_reading`). Camera motion:
`validate.diagnosis.camera_motion`.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from validate.diagnosis.camera_motion import camera_motion, camera_shifts
from validate.diagnosis.flat_region import flat_outside_share, flat_share
from validate.diagnosis.light_reading import shading_light_angles
from validate.diagnosis.mask_seed import all_black, border_ring, gray, grown_object, log_seed, variation_seed
from validate.judgeable import MIN_IMAGES as COUNTS

MIN_IMAGES, FEW_IMAGES = COUNTS["photos"], COUNTS["advised"]
"""Fewer images than MIN_IMAGES are fatal, fewer than FEW_IMAGES a warning (`validate.judgeable.MIN_IMAGES`)."""
DARK_LEVEL = 0.03
"""Linear level below which the object's bright part (99th percentile in the mask) counts as too dark."""
SATURATED_SHARE = 0.02  # share of the object's pixels clipped in one image above which it is reported
FRONTAL_DEG = 30.0
"""Frontal light (no normal information off the view axis) needs both: the light spread (`light_spread_deg`)
below this, and no image lit from further than this off the viewing direction by the strength of the light on its
outline (`light_angles`; this keeps light from one side, which varies little, from reading as frontal). Lights
within 15 to 20 deg of the axis spread like a ring of 26 to 29 deg on DiLiGenT's real objects (wider than on a
sphere), all 96 lights (up to 43 deg) like 41 to 43 deg; rendered captures lit further off the axis read 32 deg
and more (bench/bench_usable.py)."""
ONE_SIDED_DEG = 10.0  # images lit from further off the view axis than this count for the one-sided test
ONE_SIDED_GAP_DEG = 180.0, 165.0
"""One-sided light: the largest gap between the lights' azimuths is wider than a half turn (the definition, and the
threshold for lights read from the outline), and for lights read from the shading under a map, wider than the second
value: a misread light leans toward the empty side and narrows the gap its true neighbours leave. Chosen on the
development suites of bench/bench_light_warnings.py alone (150 to 180 in steps of 5: 165 best, 340 of 360 against 338 at
180), then confirmed on its held-out suites (253 -> 257 of 268) and the real captures (10 of 10 either way)."""
SHIFT_PX = 1.5
"""A shift between photos longer than this (2 px or more), the same in a good share of the compared pairs, means
the camera moved (`validate.diagnosis.camera_motion`)."""
MIN_SEPARABILITY = 0.6
"""Otsu's separability of the variation map below which the automatic mask refuses."""
BACKDROP_RATIO = 0.5
"""The automatic mask refuses where the border of the frame varies at least this much of the object's variation."""

# The doubtful automatic mask (`mask_doubts`). Measured on rendered captures only (wildgen.make, 128 px, 12 or 16
# images, 62 objects of 5 runs: --lights directional,point,near_area,hdri,mixed,flash,grid96,verse, the ideal,
# phone and machine-vision sensors, --materials any, clusters, --level 4; auto_mask found a mask on 42 of them). The
# good automatic masks are those within IoU 0.9 of the true mask: 33 as rendered, and 155 where a lit flat cushion
# was painted in under the object (12 per object: turned 0, 30 or 60 deg from the camera, albedo 0.4 or 0.8, with
# or without the object's cast shadow) and auto_mask left it out. The wrong ones: auto_mask's own failures (IoU
# below 0.8: 7 as rendered, mostly shiny objects whose highlights alone seed it; 241 with the cushion, mostly
# taking it in), the true mask grown by 15, 30 or 50 % of the object's radius (126) or shifted by 25 or 50 % of it
# (168), and the true mask with the cushion added (504). Every number below is from these, none from real photos
# (the script: bench/bench_doubtful_mask.py).
SEED_AGREEMENT_MIN = 0.4
"""An automatic mask is doubtful where its IoU with its own seed (Otsu's threshold on the light variation:
`seed_agreement_iou`) is below this: the region GrabCut grew is not the one the light variation marks. Good
automatic masks measured 0.56 to 0.99 as rendered (median 0.90) and 0.45 or more with a cushion, except on one shiny
object whose light variation covers a third of it (0.29 to 0.31: there the light variation does not support even
the true mask); grown masks read median 0.47, shifted ones 0.47, auto_mask's failures as rendered 0.05 to 0.72."""
MISSED_SHARE_MAX = 0.1
"""An automatic mask is doubtful where more than this share of the pixels that change most with the light (its
seed: above Otsu's threshold of the light variation) lies outside it (beyond a rim of `MISSED_RIM`): part of the
object left out, or the mask on something else. Good automatic masks left out at most 0.002 as rendered and 0.06
with a cushion; shifted masks left out median 0.17 (135 of 168 above 0.1), auto_mask's failures as rendered up to
0.94 (5 of 7 above 0.1; of the other two, one leaves out 0.08 of the seed, one covers a tiny object and more)."""
MISSED_RIM = 0.05
"""Seed pixels within this fraction of the object's equivalent radius (at least 1 px) outside the mask do not count
as left out: the anti-aliased outline varies too (on a tiny rendered object it made 14 % of the seed outside the
true mask; with the rim, 0 on every true mask)."""
WEAK_LEVEL = 0.5
"""A pixel of the mask varies weakly, like a background, where its light variation is below this fraction of
Otsu's threshold (half the way down from the threshold that splits object and background); a quarter of the
threshold, or 5 % of the frame's strongest variation (its 99.5th percentile), told grown masks from good ones
worse (some backgrounds vary a little: lit environments, sensor noise)."""
WEAK_SHARE_MAX = 0.25
"""An automatic mask is doubtful where more than this share of it varies weakly (`WEAK_LEVEL`): it covers
background or a surface the light hardly changes. Good automatic masks held at most 0.083 as rendered and 0.175
with a cushion, except the one shiny object above (0.40 to 0.42); masks grown by 15 % of the radius held 0.19 to
0.81 (median 0.30), by 50 % median 0.56. Taken together the three rules found 115 of 126 grown masks, 149 of 168
shifted ones, 5 of auto_mask's 7 failures as rendered and 124 of its 241 failures with a cushion. A cushion that
Otsu's threshold puts with the object (turned toward the lamp, or any bright one against a black background: a flat
patch facing the camera varies like the middle of a sphere) is in the seed too, and nothing in the light variation
tells it from the object; the flat surface it is does (`FLAT_SHARE_MAX`): with it the rules find 159 of the 241."""
STILL_LIGHT_DEG = 15.0
"""An automatic mask is doubted where the light hardly moves (`light_spread_deg` over it below this): a flash at the
lens or a lamp that stays put lights every surface alike across the photos, so their variation (the automatic mask's
only evidence) cannot tell object from floor. Rendered flash captures read 4 to 8 deg; DiLiGenT's grid 26 to 43."""
FLAT_SHARE_MAX = 0.4
"""An automatic mask more than this share of which one flat surface explains (`validate.diagnosis.flat_region`) is
doubted: the surface under the object taken with it (or for it). Of 282 rendered objects' true masks one reads more
(0.50, a bright metal object), real objects' 0.14 at most; automatic masks that took a rendered floor 0.40 and
more. Flat objects (a blade seen from its side) read high too: the warning asks a look at mask_overlay.png."""
FLAT_OUTSIDE_MAX = 0.1
"""An automatic mask is doubted where more than this share of it is flat and lies outside the convex hull of the rest
(`validate.diagnosis.flat_region.flat_outside_share`): a cushion or table beside and under the object."""
SECOND_READING_MIN, SECOND_READING_BORDER_MAX = 0.9, 0.25
"""An automatic mask is doubted where the mask grown from the second reading of the light variation (its logarithm,
`validate.diagnosis.mask_seed`) overlaps it by less than this IoU, the pixels where the two differ counted only where
they are not one flat surface (a lit floor or cushion the logarithm lifts, which the flat measurements judge). The
second reading abstains where its seed covers more than the second share of the frame's border: there the logarithm
lifts a backdrop, a floor or the sensor's noise along with the object."""


@dataclass
class CaptureWarning:
    """One thing about the capture a person can change."""

    code: str  # too_few_images, too_dark, saturated, one_sided_light, frontal_light, camera_moved, doubtful_mask
    message: str  # what was found and what to change in the capture
    fatal: bool = False  # the command stops (no normal map would mean anything)

    def to_dict(self) -> dict:
        return {"code": self.code, "message": self.message}


def auto_mask(images: np.ndarray, flag: str = "--mask", source: str = "--input") -> tuple[np.ndarray, dict]:
    """(H, W) bool object mask from the images alone, and how sure it is (see the module doc); ValueError
    naming `flag` where the images cannot separate object and background, `source` where they are all black."""
    if dark := all_black(images):  # the mask is not what is wrong
        raise ValueError(f"{source}: {dark}")
    scaled, threshold, separability = variation_seed(images)
    seed = scaled > threshold
    ring = border_ring(seed.shape)
    inside = float(scaled[seed].mean()) if seed.any() else 0.0
    border = float(scaled[ring].mean())
    why = None
    if separability < MIN_SEPARABILITY:
        shown = np.floor(separability * 1000) / 1000  # rounded down: 0.5996 must not read "0.60 < 0.6"
        why = (f"the light variation does not split into two classes (separability {shown:.3f} < "
               f"{MIN_SEPARABILITY:g})")
    elif inside <= 0 or border >= BACKDROP_RATIO * inside:
        why = (f"the border of the frame changes with the light like the object ({border / max(inside, 1e-9):.0%} of "
               "its variation): a lit backdrop")
    if why is None:
        mask = grown_object(images, seed, scaled, threshold)
        share = float(mask.mean())
        if not 0.002 <= share <= 0.9:
            why = f"the mask found covers {share:.1%} of the frame"
    if why is not None:
        raise ValueError(f"{flag}: auto cannot separate the object from the background: {why}; give a mask "
                         f"(--mask FILE: white object on black, the size of the photos)")
    agreement = float((mask & seed).sum() / max((mask | seed).sum(), 1))
    return mask, {"method": "otsu on the light variation, then grabcut", "separability": round(separability, 4),
                  "seed_agreement_iou": round(agreement, 4), "share_of_frame": round(share, 4)}


def mask_doubts(images: np.ndarray, mask: np.ndarray) -> tuple[CaptureWarning | None, dict]:
    """Whether an automatic mask may be wrong (`doubtful_mask`, not fatal), and the measurements behind it: its IoU
    with the seed of the light variation (`SEED_AGREEMENT_MIN`), the share of the seed it leaves out
    (`MISSED_SHARE_MAX`), the share of it that varies weakly (`WEAK_SHARE_MAX`) and the share of it one flat surface
    explains (`FLAT_SHARE_MAX`, `validate.diagnosis.flat_region`); any one of the four, or a light that hardly moves
(`STILL_LIGHT_DEG`), where none of them can tell."""
    import cv2

    scaled, threshold, _ = variation_seed(images)
    seed = scaled > threshold
    radius = np.sqrt(mask.sum() / np.pi)
    rim = max(1, round(MISSED_RIM * radius))
    grown = cv2.dilate(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * rim + 1,) * 2)) > 0
    agreement = float((mask & seed).sum() / max((mask | seed).sum(), 1))
    missed = float((seed & ~grown).sum() / max(seed.sum(), 1))
    weak = float((mask & (scaled < WEAK_LEVEL * threshold)).sum() / max(mask.sum(), 1))
    flat, spread = flat_share(images, mask), light_spread_deg(images, mask)
    beside = flat_outside_share(images, mask)
    low = log_seed(scaled)
    border = float(low[border_ring(low.shape)].mean())
    second_iou = 1.0  # where the logarithm lifts the frame's border (a backdrop, a floor, noise) it cannot tell
    if border <= SECOND_READING_BORDER_MAX:
        second = grown_object(images, low, scaled, threshold, touching=mask)  # the parts it reads anew
        union = max(int((mask | second).sum()), 1)
        differ = (mask ^ second).sum() * (1 - flat_share(images, mask ^ second))  # a lit floor is flat, left out
        second_iou = 1 - float(differ) / union
    facts = {"seed_agreement_iou": round(agreement, 4), "varying_outside_share": round(missed, 4),
             "weak_inside_share": round(weak, 4), "flat_share": round(flat, 4),
             "flat_outside_share": round(beside, 4), "second_reading_iou": round(second_iou, 4),
             "second_reading_border_share": round(border, 4),
             "light_spread_deg": round(spread, 1)}
    seen = []
    if second_iou < SECOND_READING_MIN:
        seen.append(f"read from the logarithm of the light variation, the object's outline changes (the two masks "
                    f"overlap by {second_iou:.0%}, a flat surface aside): a shiny object's highlights taken for all of "
                    "it, or a dim part left out")
    if missed > MISSED_SHARE_MAX:
        seen.append(f"{missed:.0%} of the pixels that change most with the light lie outside it (part of the object "
                    "left out, or the mask on something else)")
    if weak > WEAK_SHARE_MAX:
        seen.append(f"{weak:.0%} of it hardly changes with the light, like a background (it may cover the surface "
                    "the object stands on, or the backdrop)")
    if agreement < SEED_AGREEMENT_MIN:
        seen.append(f"it overlaps the part of the picture that changes with the light by only {agreement:.0%}")
    if spread < STILL_LIGHT_DEG:  # every surface then varies alike: one profile says nothing
        seen.append(f"the light hardly moves across the photos (it spreads like a ring {spread:.0f} deg around the "
                    "axis), so what changes with it cannot tell the object from what surrounds it")
    elif flat > FLAT_SHARE_MAX:
        seen.append(f"{flat:.0%} of it is one flat surface lit alike in every photo (the table, cloth or backdrop "
                    "under the object?)")
    elif beside > FLAT_OUTSIDE_MAX:
        seen.append(f"{beside:.0%} of it is a flat surface reaching out beside the rest (the table or cloth under "
                    "the object?)")
    facts["doubtful"] = bool(seen)
    if not seen:
        return None, facts
    return CaptureWarning("doubtful_mask", "the automatic mask may not be the object: " + "; ".join(seen) +
                          ". Look at mask_overlay.png; if the outline does not follow the object, draw a mask and "
                          "give it (--mask FILE: white object on black, the size of the photos)"), facts


def _contour(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ring, outward normals (N, 2) x right, y up) of a band just inside the object's outline, a few percent of
    its radius wide: there the surface normal lies almost in the image plane, along the outline's normal."""
    import cv2

    radius = max(np.sqrt(mask.sum() / np.pi), 1.0)
    band = max(2, round(0.04 * radius))
    blur = cv2.GaussianBlur(mask.astype(np.float32), (0, 0), max(1.0, band / 1.5))
    gy, gx = np.gradient(blur)
    nx, ny = -gx, gy  # down the edge, outward; rows grow downward, y upward
    norm = np.hypot(nx, ny)
    inner = cv2.erode(mask.astype(np.uint8), np.ones((2 * band + 1, 2 * band + 1), np.uint8)) > 0
    ring = mask & ~inner & (norm > 1e-6)
    return ring, np.stack([nx[ring], ny[ring]], axis=1) / norm[ring][:, None]


def _contour_light(images: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per image: (strength, mean, azimuth in degrees) of the light on the outline: strength 4 |mean(I n)| and mean
    mean(I), both over the object's bright level (99th percentile), n the outline's outward normal. On a
    Lambertian sphere under one distant light the strength is about sin(polar angle) and the azimuth the light's;
    light from all around (an environment) leaves the strength small but the outline bright, which the mean sees."""
    ring, normals = _contour(mask)
    g = gray(images)
    values = g[:, ring]  # (K, N)
    level = np.maximum(np.percentile(g[:, mask], 99, axis=1), 1e-12)
    vx, vy = (values * normals[:, 0]).mean(axis=1), (values * normals[:, 1]).mean(axis=1)
    return 4 * np.hypot(vx, vy) / level, values.mean(axis=1) / level, np.degrees(np.arctan2(vy, vx))


@lru_cache(maxsize=8)
def _outline_curves(radius: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(polar angle in degrees, outline strength, outline mean) of a Lambertian sphere of `radius` pixels (the
    object's equivalent radius: the outline band's width in pixels matters) lit from that angle (the band inside
    the outline sees some light even from the front: the curves calibrate that away)."""
    radius = max(radius, 8)
    size = 2 * radius + 16
    rows, cols = np.mgrid[0:size, 0:size] + 0.5
    x, y = (cols - size / 2) / radius, -(rows - size / 2) / radius
    mask = x * x + y * y < 1
    z = np.sqrt(np.clip(1 - x * x - y * y, 0, 1))
    thetas = np.arange(0.0, 90.5, 1.0)
    t = np.radians(thetas)
    images = np.clip(x[None] * np.sin(t)[:, None, None] + z[None] * np.cos(t)[:, None, None], 0, None) * mask
    strength, mean, _ = _contour_light(np.repeat(images[..., None], 3, axis=-1), mask)
    return thetas, np.maximum.accumulate(strength), np.maximum.accumulate(mean)


def _outline_tilt_deg(images: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per image: the angle from the viewing direction that the outline's strength alone says (`light_angles`)."""
    strength, _, _ = _contour_light(images, mask)
    thetas, strength_curve, _ = _outline_curves(int(round(np.sqrt(mask.sum() / np.pi))))
    return np.interp(strength, strength_curve, thetas)


def light_angles(images: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per image: (angle from the viewing direction, azimuth), degrees, estimated from the light on the object's
    outline (module doc): the larger of the angles its strength and its mean say; NaN for an image with no light
    on the object."""
    strength, mean, azimuth = _contour_light(images, mask)
    thetas, strength_curve, mean_curve = _outline_curves(int(round(np.sqrt(mask.sum() / np.pi))))
    polar = np.maximum(np.interp(strength, strength_curve, thetas), np.interp(mean, mean_curve, thetas))
    dark = gray(images)[:, mask].max(axis=1) <= 0
    polar[dark], azimuth[dark] = np.nan, np.nan
    return polar, azimuth


@lru_cache(maxsize=1)
def _spread_curve() -> tuple[np.ndarray, np.ndarray]:
    """(angle in degrees, spread) of a Lambertian sphere lit in turn by 8 distant lights on a ring at that angle
    around the viewing direction (`_spread`)."""
    size = 96
    rows, cols = np.mgrid[0:size, 0:size] + 0.5
    x, y = (cols - size / 2) / 44, -(rows - size / 2) / 44
    mask = x * x + y * y < 1
    n = np.stack([x, y, np.sqrt(np.clip(1 - x * x - y * y, 0, 1))], axis=-1)[mask]
    angles = np.arange(0.0, 75.5, 1.0)
    spread = []
    for t in np.radians(angles):
        a = np.radians(np.arange(8) * 45.0)
        lights = np.stack([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.full(8, np.cos(t))], axis=-1)
        spread.append(_spread(np.clip(lights @ n.T, 0, None)))
    return angles, np.maximum.accumulate(np.array(spread))


def _spread(gray: np.ndarray) -> float:
    """Median over the object's pixels (K, N) that the mean image lights of each pixel's standard deviation over its
    mean across the images: how much the light's direction varies, with the albedo cancelled."""
    mean = gray.mean(axis=0)
    lit = mean > 0.05 * max(float(np.percentile(gray, 99)), 1e-12)
    return float(np.median(gray[:, lit].std(axis=0) / mean[lit])) if lit.any() else 0.0


def light_spread_deg(images: np.ndarray, mask: np.ndarray) -> float:
    """How far apart the lights of a capture are, as the angle of the ring of lights around the viewing direction
    that gives a Lambertian sphere the same spread (median of each pixel's standard deviation over its mean across
    the images; the albedo cancels). It reads the spread of the light's directions, not their angle from the axis:
    light from one side that hardly moves reads low too."""
    angles, curve = _spread_curve()
    return float(np.interp(_spread(gray(images)[:, mask]), curve, angles))


def _largest_gap_deg(angles: np.ndarray) -> float:
    a = np.sort(np.mod(angles, 360.0))
    gaps = np.diff(np.concatenate([a, [a[0] + 360.0]]))
    return float(gaps.max())


def _names(names: list[str], idx) -> str:
    idx = list(idx)
    return ", ".join(names[i] for i in idx[:4]) + (f" and {len(idx) - 4} more" if len(idx) > 4 else "")


def image_count_warning(k: int) -> CaptureWarning | None:
    """The warning of a capture of `k` photos, fatal below MIN_IMAGES (known before anything else is looked at)."""
    if k < MIN_IMAGES:
        return CaptureWarning("too_few_images", f"only {k} image(s): photometric stereo needs at least {MIN_IMAGES} "
                              f"photos under different lights (take {FEW_IMAGES} or more, the lamp moved around the "
                              "camera between shots)", fatal=True)
    if k < FEW_IMAGES:
        return CaptureWarning("too_few_images", f"{k} images: with unknown lights the normals are poorly determined "
                              f"below {FEW_IMAGES}; take more photos with the lamp in other places")
    return None


def _scaled_copy(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether photo b is photo a times a factor (the same photo, or its exposure scaled by EXIF): the same light."""
    sa, sb = float(a.sum(dtype=np.float64)), float(b.sum(dtype=np.float64))
    return np.array_equal(a, b) if min(sa, sb) <= 0 else float(np.abs(a * (sb / sa) - b).max()) <= 1e-4 * float(b.max())


def identical_photos_warning(images: np.ndarray) -> CaptureWarning | None:
    """Fatal when the photos show fewer than MIN_IMAGES lights, each the same up to brightness (copied, or under other
    EXIF exposures): too little for the light to tell, whatever the mask. Black photos: the darkness rule's."""
    if len(images) < 2 or float(images.max()) < 1.0 / 255:
        return None
    lights: list[int] = []  # the first photo of each light
    for i, im in enumerate(images):
        if len(lights) < MIN_IMAGES and not any(_scaled_copy(images[j], im) for j in lights):
            lights.append(i)
    if len(lights) >= MIN_IMAGES:
        return None
    what = f"the {len(images)} photos are identical" if len(lights) == 1 else \
        f"the {len(images)} photos show only {len(lights)} lights: the others are identical to one of them"
    return CaptureWarning("too_few_images", f"{what}, or differ only in brightness (a photo copied, a light that never "
                          f"moved): photometric stereo needs the lamp in another place for each photo, at least "
                          f"{MIN_IMAGES} places", fatal=True)


def unusable_photos(images: np.ndarray) -> CaptureWarning | None:
    """The fatal warning photos get before any mask is looked for: too few of them, or of too few lights."""
    return next((w for w in (image_count_warning(len(images)), identical_photos_warning(images)) if w and w.fatal),
                None)


def capture_warnings(images: np.ndarray, mask: np.ndarray, saturated: np.ndarray | None = None,
                     names: list[str] | None = None, normals: np.ndarray | None = None,
                     lights: bool = True) -> tuple[list[CaptureWarning], dict]:
    """The warnings of a capture (the fatal ones first) and the measurements behind them; with `lights`, also the
    light warnings (`light_warnings`, read under `normals` where given)."""
    k = len(images)
    names = names or [f"image {i}" for i in range(k)]
    facts: dict = {"images": k}
    count = image_count_warning(k)
    out: list[CaptureWarning] = [count] if count else []
    if count and count.fatal:
        return out, facts
    if same := identical_photos_warning(images):
        return [same], facts
    pairs, shifts = camera_shifts(images, mask)
    motion, support = camera_motion(pairs, shifts, SHIFT_PX)
    facts["camera_shift_px"] = None if motion is None else [int(motion[0]), int(motion[1])]
    facts["camera_shift_pairs"] = [[i, j, int(dx), int(dy)] for (i, j), (dx, dy) in zip(pairs, shifts) if dx or dy]
    if motion is not None:
        seen = sorted({i for n in support for i in pairs[n]})
        out.append(CaptureWarning("camera_moved", f"the camera moved: {len(support)} of {len(pairs)} pairs of photos "
                                  f"compared are shifted by about {np.hypot(*motion):.0f} px against each other "
                                  f"({_names(names, seen)}): fix the camera on a tripod and release it remotely or "
                                  "with a timer"))
    level = np.percentile(gray(images)[:, mask], 99, axis=1)
    facts["object_level_p99"] = np.round(level, 4).tolist()
    if float(level.max()) < 1.0 / 255:
        out.insert(0, CaptureWarning("too_dark", f"the object is all but black in every image (its bright part at "
                                     f"most {float(level.max()):.4f} of the full scale, below one 8-bit step): light "
                                     "it, or expose longer (16-bit files holding an 8-bit range: write them at full "
                                     "scale)", fatal=True))
        return out, facts
    if float(np.median(level)) < DARK_LEVEL:
        out.append(CaptureWarning("too_dark", f"the object is dark (its bright part at {np.median(level):.3f} of the "
                                  "full scale in the median image): expose longer or bring the lamp closer, so that "
                                  "its brightest part reaches about half the scale"))
    if len(black := np.nonzero(level < 1.0 / 255)[0]):  # one photo of nothing among lit ones: a lamp that failed
        out.append(CaptureWarning("too_dark", f"{len(black)} image(s) show the object all but black, below one 8-bit "
                                  f"step ({_names(names, black)}): did the lamp fire? retake or drop them"))
    if saturated is not None:
        share = saturated[:, mask].any(axis=-1).mean(axis=1)
        facts["saturated_share"] = np.round(share, 4).tolist()
        if len(over := np.nonzero(share > SATURATED_SHARE)[0]):
            out.append(
                CaptureWarning(
                    "saturated",
                    f"{len(over)} image(s) clip part of the object ({_names(names, over)}, "
                    f"up to {share.max():.0%} of it): expose shorter or move the lamp away",
                )
            )
    if lights:
        more, light_facts = light_warnings(images, mask, normals)
        out += more
        facts.update(light_facts)
    out.sort(key=lambda w: not w.fatal)
    return out, facts


def light_warnings(images: np.ndarray, mask: np.ndarray, normals: np.ndarray | None = None
                   ) -> tuple[list[CaptureWarning], dict]:
    """`frontal_light` and `one_sided_light`, and the light directions behind them: read from the shading under
    `normals` (`shading_light_angles`: a map of the object, e.g. the model's) where given, else from the light on
    the object's outline (`light_angles`, before any map exists; its angles from the axis read 3-5 times too small
    on real objects)."""
    facts: dict = {}
    out: list[CaptureWarning] = []
    if normals is None and not _contour(mask)[0].any():  # a whole-frame mask (--mask none): no outline to read
        facts["light_angles"] = "not measured: the mask has no outline inside the frame"
        return out, facts
    if normals is not None:
        polar, azimuth = shading_light_angles(images, mask, normals)
        facts["light_angles"] = "from the shading of the object under the model's map"
    else:
        polar, azimuth = light_angles(images, mask)
        facts["light_angles"] = "from the light on the object's outline"
    facts["light_polar_deg"] = np.round(polar, 1).tolist()
    facts["light_azimuth_deg"] = np.round(azimuth, 1).tolist()
    lit = np.isfinite(polar)
    if normals is not None:
        frontal = bool(lit.any()) and float(polar[lit].max()) < FRONTAL_DEG
        spread = float(polar[lit].max()) if lit.any() else 0.0
    else:
        spread = light_spread_deg(images, mask)
        facts["light_spread_deg"] = round(spread, 1)
        tilt = _outline_tilt_deg(images, mask)[lit]  # (the outline's mean is left out: an ambient light brightens it)
        frontal = bool(lit.any()) and float(tilt.max()) < FRONTAL_DEG and spread < FRONTAL_DEG
    if frontal:  # (one-sided then says nothing more)
        out.append(
            CaptureWarning(
                "frontal_light",
                "every image is lit from near the camera's direction (within about "
                f"{spread:.0f} deg of its axis; a flash or a lamp beside the lens): hold the lamp further to the "
                "side, 30 to 60 deg off the camera's axis, in turn above, below, left and right",
            )
        )
    off = lit & (polar > ONE_SIDED_DEG)
    wide = ONE_SIDED_GAP_DEG[0 if normals is None else 1]
    if not frontal and off.sum() >= 2 and _largest_gap_deg(azimuth[off]) > wide:
        mid = np.degrees(np.arctan2(np.sin(np.radians(azimuth[off])).mean(), np.cos(np.radians(azimuth[off])).mean()))
        sides = ["right", "upper right", "top", "upper left", "left", "lower left", "bottom", "lower right"]
        at = int(np.round(np.mod(mid, 360) / 45)) % 8
        out.append(CaptureWarning("one_sided_light", f"the light comes from one side only (the {sides[at]}; no photo "
                                  f"is lit from the {sides[(at + 4) % 8]}): take photos with the lamp on the other "
                                  "sides too, all around the camera"))
    return out, facts


def as_dicts(warnings: list[CaptureWarning]) -> list[dict]:
    return [w.to_dict() for w in warnings]
