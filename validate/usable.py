"""Is this capture usable? What the images alone say before any model runs: the per-pixel light variation, an
object mask when none is given, and the warnings a person can act on.

- `variation_map`: how much each pixel changes across the images (standard deviation of its gray value over
  the images, relative to the bright level of the capture); the object changes with the light, a far or dark
  background does not.
- `auto_mask`: Otsu's threshold on the variation map as the seed, refined by GrabCut (OpenCV) on the capture's
  brightest image, the largest connected part kept and its holes filled. Its confidence is Otsu's
  separability (between-class over total variance of the variation map, 1 = two perfectly apart classes).
  It refuses (ValueError asking for `--mask FILE`) where it cannot tell object from background: a backdrop
  that changes with the light about as much as the object (the border of the frame varies like the object),
  a separability below `MIN_SEPARABILITY`, or a mask that fills almost nothing or almost the whole frame.
- `capture_warnings`: `too_few_images`, `too_dark`, `saturated`, `frontal_light`, `one_sided_light`,
  `camera_moved`, each a `CaptureWarning` with a message saying what to change; the fatal ones stop.

Light directions are estimated from the images alone on the object's outline, where the surface normal lies
in the image plane along the outline's normal (the occluding contour): the brightness along the outline,
summed as a vector of its outward normals, points to the light's azimuth, and its length over the object's
bright level grows with the light's angle from the viewing direction; that length is turned into an angle
with the curve of an analytic Lambertian sphere (`_outline_curves`); light from all around (an environment) leaves
the vector short but the outline bright, so the mean brightness of the outline gives a second angle and the
larger is taken. Elongated shapes and albedo patterns on
the outline bias it: the two light warnings are hints, never fatal.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

MIN_IMAGES = 3
"""Fewer images do not determine a normal (three unknowns per pixel): fatal."""
FEW_IMAGES = 6
"""Below this many images a warning: unknown light needs more views than the three of calibrated stereo."""
DARK_LEVEL = 0.03
"""Linear level below which the object's bright part (99th percentile in the mask) counts as too dark."""
SATURATED_SHARE = 0.02
"""Share of the object's pixels clipped in one image above which it is reported."""
FRONTAL_DEG = 20.0
"""Every image lit from within this angle of the viewing direction: frontal light (no normal information off
the view axis). Set above 15 deg so that lights within 15 deg are caught on shapes less round than a sphere."""
ONE_SIDED_DEG = 10.0
"""Images lit from further off the view axis than this count for the one-sided test."""
SHIFT_PX = 1.0
"""A shift between two images above this many pixels, seen in at least two of them, means the camera moved
(`camera_shifts`)."""
MIN_SEPARABILITY = 0.6
"""Otsu's separability of the variation map below which the automatic mask refuses."""
BACKDROP_RATIO = 0.5
"""The automatic mask refuses where the border of the frame varies at least this much of the object's variation."""


@dataclass
class CaptureWarning:
    """One thing about the capture a person can change."""

    code: str
    """One of too_few_images, too_dark, saturated, one_sided_light, frontal_light, camera_moved."""
    message: str
    """What was found and what to change in the capture."""
    fatal: bool = False
    """The command stops (no normal map would mean anything)."""

    def to_dict(self) -> dict:
        return {"code": self.code, "message": self.message}


def _gray(images: np.ndarray) -> np.ndarray:
    return images.mean(axis=-1)  # (K, H, W)


def variation_map(images: np.ndarray) -> np.ndarray:
    """(H, W) float32: standard deviation over the images of each pixel's gray value, over the capture's bright
    level (99.5th percentile of the mean image), so about 0 for what the light does not change."""
    gray = _gray(images)
    level = max(float(np.percentile(gray.mean(axis=0), 99.5)), 1e-6)
    return (gray.std(axis=0) / level).astype(np.float32)


def _otsu(values: np.ndarray) -> tuple[float, float]:
    """(threshold, separability) of Otsu's method on `values` in [0, 1] (256 bins)."""
    hist, edges = np.histogram(np.clip(values, 0, 1), bins=256, range=(0, 1))
    p = hist / max(hist.sum(), 1)
    centers = (edges[:-1] + edges[1:]) / 2
    w0 = np.cumsum(p)
    mu = np.cumsum(p * centers)
    total = mu[-1]
    between = (total * w0 - mu) ** 2 / np.maximum(w0 * (1 - w0), 1e-12)
    k = int(np.argmax(between))
    var = float(np.sum(p * (centers - total) ** 2))
    return float(centers[k]), float(between[k] / var) if var > 0 else 0.0


def _largest_filled(mask: np.ndarray) -> np.ndarray:
    import cv2
    from scipy import ndimage

    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros_like(mask, bool)
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return ndimage.binary_fill_holes(labels == biggest)


def auto_mask(images: np.ndarray, flag: str = "--mask") -> tuple[np.ndarray, dict]:
    """(H, W) bool object mask from the images alone, and how sure it is (see the module doc); ValueError
    naming `flag` where the images cannot separate object and background."""
    import cv2

    var = variation_map(images)
    scaled = var / max(float(np.percentile(var, 99.5)), 1e-6)
    threshold, separability = _otsu(scaled)
    seed = scaled > threshold
    h, w = seed.shape
    ring = np.zeros_like(seed)
    b = max(1, round(0.03 * min(h, w)))
    ring[:b], ring[-b:], ring[:, :b], ring[:, -b:] = True, True, True, True
    inside = float(scaled[seed].mean()) if seed.any() else 0.0
    border = float(scaled[ring].mean())
    why = None
    if separability < MIN_SEPARABILITY:
        why = f"the light variation does not split into two classes (separability {separability:.2f} < {MIN_SEPARABILITY})"
    elif inside <= 0 or border >= BACKDROP_RATIO * inside:
        why = (f"the border of the frame changes with the light like the object ({border / max(inside, 1e-9):.0%} of "
               "its variation): a lit backdrop")
    if why is None:
        bright = _gray(images).max(axis=0)
        picture = (np.clip(bright / max(float(np.percentile(bright, 99.5)), 1e-6), 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)
        gc = np.where(seed, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
        gc[ring & ~seed] = cv2.GC_BGD
        bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
        cv2.grabCut(np.repeat(picture[..., None], 3, axis=2), gc, None, bgd, fgd, 5, cv2.GC_INIT_WITH_MASK)
        mask = _largest_filled(np.isin(gc, (cv2.GC_FGD, cv2.GC_PR_FGD)))
        share = float(mask.mean())
        if not 0.002 <= share <= 0.9:
            why = f"the mask found covers {share:.1%} of the frame"
    if why is not None:
        raise ValueError(f"{flag}: auto cannot separate the object from the background: {why}; give a mask "
                         f"(--mask FILE: white object on black, the size of the photos)")
    agreement = float((mask & seed).sum() / max((mask | seed).sum(), 1))
    return mask, {"method": "otsu on the light variation, then grabcut", "separability": round(separability, 4),
                  "seed_agreement_iou": round(agreement, 4), "share_of_frame": round(share, 4)}


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
    gray = _gray(images)
    values = gray[:, ring]  # (K, N)
    level = np.maximum(np.percentile(gray[:, mask], 99, axis=1), 1e-12)
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


def light_angles(images: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per image: (angle from the viewing direction, azimuth), degrees, estimated from the light on the object's
    outline (module doc): the larger of the angles its strength and its mean say; NaN for an image with no light
    on the object."""
    strength, mean, azimuth = _contour_light(images, mask)
    thetas, strength_curve, mean_curve = _outline_curves(int(round(np.sqrt(mask.sum() / np.pi))))
    polar = np.maximum(np.interp(strength, strength_curve, thetas), np.interp(mean, mean_curve, thetas))
    dark = _gray(images)[:, mask].max(axis=1) <= 0
    polar[dark], azimuth[dark] = np.nan, np.nan
    return polar, azimuth


def _largest_gap_deg(angles: np.ndarray) -> float:
    a = np.sort(np.mod(angles, 360.0))
    gaps = np.diff(np.concatenate([a, [a[0] + 360.0]]))
    return float(gaps.max())


def _best_shift(a: np.ndarray, b: np.ndarray, lit_a: np.ndarray, lit_b: np.ndarray, reach: int) -> tuple[int, int]:
    """The shift (dx, dy) of image b (log values) onto image a that leaves the least edge energy in their log ratio
    where both are lit. Taken only when it lies strictly inside the searched square (a minimum on its border is
    where the overlap of two differently lit images shrinks to a few smooth pixels, not a motion: measured on
    rendered objects) and cuts the energy at (0, 0) by more than a third; else (0, 0)."""
    r = reach
    ref, ref_lit = a[r:-r, r:-r], lit_a[r:-r, r:-r]
    h, w = ref.shape
    energy = {}
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            both = ref_lit & lit_b[r + dy:r + dy + h, r + dx:r + dx + w]
            gy, gx = np.gradient(b[r + dy:r + dy + h, r + dx:r + dx + w] - ref)
            energy[(dx, dy)] = float(np.hypot(gx, gy)[both].mean()) if both.sum() >= 50 else np.inf
    best = min(energy, key=energy.get)
    inside = max(abs(best[0]), abs(best[1])) < r
    return best if inside and best != (0, 0) and energy[best] < 0.65 * energy[(0, 0)] else (0, 0)


def camera_shifts(images: np.ndarray, reach: int = 6, sample: int = 24, references: int = 4) -> np.ndarray:
    """(K, 2) integer shift (x, y, y up) in pixels of each image against the image it shares the most lit object
    with among a few references spread over the capture (NaN for an image not compared: captures of more than
    `sample` images are checked on `sample` of them). A change of light changes the shading smoothly, so the log
    ratio of two images of a still camera is smooth where both are lit; a moved camera puts the outline and the
    texture of one beside those of the other, and the ratio gets edges (`_best_shift`, on images brought below
    256 px)."""
    import cv2

    gray = _gray(images)
    f = max(1, int(np.ceil(max(gray.shape[1:]) / 256)))
    if f > 1:
        gray = np.stack([cv2.resize(g, (g.shape[1] // f, g.shape[0] // f), interpolation=cv2.INTER_AREA) for g in gray])
    level = max(float(np.percentile(gray, 99)), 1e-6)
    logs = np.log(np.maximum(gray, 0.0) + 0.02 * level)
    lit = gray > 0.05 * level
    k = len(gray)
    checked = np.unique(np.linspace(0, k - 1, min(k, sample)).round().astype(int))
    refs = np.unique(np.linspace(0, k - 1, min(k, references)).round().astype(int))
    out = np.full((k, 2), np.nan)
    for i in checked:
        overlap = {int(j): (lit[i] & lit[j]).sum() / max(lit[j].sum(), 1) for j in refs if j != i}
        j = max(overlap, key=overlap.get) if overlap else None
        if j is None or overlap[j] < 0.3:
            continue
        dx, dy = _best_shift(logs[j], logs[i], lit[j], lit[i], reach)
        out[i] = (dx * f, -dy * f)
    return out


def _agree(shifts: np.ndarray) -> bool:
    """Two or more shifts that are the same motion (within a pixel), seen from either side (s or -s): what a camera
    moved between two groups of photos leaves; a lone shift is not taken."""
    for i in range(len(shifts)):
        for j in range(i + 1, len(shifts)):
            if min(np.abs(shifts[i] - shifts[j]).max(), np.abs(shifts[i] + shifts[j]).max()) <= 1:
                return True
    return False


def _names(names: list[str], idx) -> str:
    idx = list(idx)
    shown = ", ".join(names[i] for i in idx[:4])
    return shown + (f" and {len(idx) - 4} more" if len(idx) > 4 else "")


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


def capture_warnings(images: np.ndarray, mask: np.ndarray, saturated: np.ndarray | None = None,
                     names: list[str] | None = None) -> tuple[list[CaptureWarning], dict]:
    """The warnings of a capture (the fatal ones first) and the measurements behind them."""
    k = len(images)
    names = names or [f"image {i}" for i in range(k)]
    facts: dict = {"images": k}
    count = image_count_warning(k)
    out: list[CaptureWarning] = [count] if count else []
    if count and count.fatal:
        return out, facts
    shifts = camera_shifts(images)
    size = np.hypot(shifts[:, 0], shifts[:, 1])
    moved = np.nonzero(np.nan_to_num(size) > SHIFT_PX)[0]
    if not _agree(shifts[moved]):
        moved = moved[:0]  # one image alone with a shift is a chance minimum, not a camera that moved
    facts["camera_shift_px"] = [None if np.isnan(x) else [int(x), int(y)] for x, y in shifts]
    if len(moved):
        out.append(CaptureWarning("camera_moved", f"the camera moved: {len(moved)} image(s) are shifted against the "
                                  f"others ({_names(names, moved)}, up to {np.nanmax(size):.0f} px): fix the camera on "
                                  "a tripod and release it remotely or with a timer"))
    gray = _gray(images)[:, mask]
    level = np.percentile(gray, 99, axis=1)
    facts["object_level_p99"] = np.round(level, 4).tolist()
    if float(level.max()) < 1.0 / 255:
        out.insert(0, CaptureWarning("too_dark", "the object is black in every image (nothing above the darkest "
                                     "code): light it, or expose longer", fatal=True))
        return out, facts
    if float(np.median(level)) < DARK_LEVEL:
        out.append(CaptureWarning("too_dark", f"the object is dark (its bright part at {np.median(level):.3f} of the "
                                  "full scale in the median image): expose longer or bring the lamp closer, so that "
                                  "its brightest part reaches about half the scale"))
    if saturated is not None:
        share = saturated[:, mask].any(axis=-1).mean(axis=1)
        facts["saturated_share"] = np.round(share, 4).tolist()
        over = np.nonzero(share > SATURATED_SHARE)[0]
        if len(over):
            out.append(CaptureWarning("saturated", f"{len(over)} image(s) clip part of the object ({_names(names, over)}, "
                                      f"up to {share.max():.0%} of it): expose shorter or move the lamp away"))
    polar, azimuth = light_angles(images, mask)
    facts["light_polar_deg"] = np.round(polar, 1).tolist()
    facts["light_azimuth_deg"] = np.round(azimuth, 1).tolist()
    lit = np.isfinite(polar)
    if lit.any() and float(np.nanmax(polar)) < FRONTAL_DEG:  # (one-sided then says nothing more)
        out.append(CaptureWarning("frontal_light", f"every image is lit from within about {FRONTAL_DEG:.0f} deg of the "
                                  "camera's direction (a flash or a lamp beside the lens): hold the lamp further to "
                                  "the side, 30 to 60 deg off the camera's axis, in turn above, below, left and right"))
    frontal = lit.any() and float(np.nanmax(polar)) < FRONTAL_DEG
    off = lit & (polar > ONE_SIDED_DEG)
    if not frontal and off.sum() >= 2 and _largest_gap_deg(azimuth[off]) > 180.0:
        mid = np.degrees(np.arctan2(np.sin(np.radians(azimuth[off])).mean(), np.cos(np.radians(azimuth[off])).mean()))
        side = ["right", "upper right", "top", "upper left", "left", "lower left", "bottom", "lower right"][
            int(np.round(np.mod(mid, 360) / 45)) % 8]
        out.append(CaptureWarning("one_sided_light", f"the light comes from one side only (the {side}): take photos "
                                  "with the lamp on the other sides too, all around the camera"))
    out.sort(key=lambda w: not w.fatal)
    return out, facts


def as_dicts(warnings: list[CaptureWarning]) -> list[dict]:
    return [w.to_dict() for w in warnings]
