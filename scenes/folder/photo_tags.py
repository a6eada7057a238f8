"""What a photo file says about itself, read by Pillow: EXIF exposure (time, ISO, f-number, APEX values),
orientation, colour space and 35 mm focal length, and the curve its values are encoded with (an embedded ICC
profile's, measured by LittleCMS; a PNG's sRGB or gAMA chunk), for `scenes.folder.photos`.

An EXIF field of an unexpected type or shape (several values, bytes, a rational over 0, a number beyond a float)
never raises anything but the one-line ValueError of the field it stands for: an exposure time or ISO that is
not one finite number > 0 is refused naming the tag; an f-number or focal length that is not is as good as none
(they are optional); a colour space that is not one whole number is kept as written, and refused as not sRGB
where it decides the curve (8-bit files in auto mode).
"""
from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np

_EXIF_IFD = 0x8769
_EXPOSURE_TIME, _ISO, _COLOR_SPACE, _F_NUMBER = 0x829A, 0x8827, 0xA001, 0x829D
_SHUTTER_APEX, _APERTURE_APEX = 0x9201, 0x9202
_EXPOSURE_TAGS = (_EXPOSURE_TIME, _ISO, _F_NUMBER, _SHUTTER_APEX, _APERTURE_APEX)
_ORIENTATION = 0x0112
_FOCAL_35MM = 0xA405  # FocalLengthIn35mmFilm: the lens as a 35 mm-equivalent focal length, whole mm
_EXIF_NAMES = {"exposure_time_s": ("ExposureTime", "exposure time in seconds"), "iso": ("ISOSpeedRatings", "ISO")}


def _single(value: Any) -> Any:
    """An EXIF field's one value: a tuple of one unwrapped, anything else as it is (several values stay a tuple)."""
    return value[0] if isinstance(value, (tuple, list)) and len(value) == 1 else value


def _positive(value: Any) -> float | None:
    """An optional EXIF field (f-number, 35 mm focal length) as a finite float > 0, else None: 0 means unknown in
    EXIF, and a value of another type or shape is as good as none."""
    try:
        number = float(_single(value))
    except (TypeError, ValueError, ArithmeticError):
        return None
    return number if np.isfinite(number) and number > 0 else None


def _written(value: Any) -> tuple[str, bool, int | None]:
    """An EXIF value as written (a rational 1/0 as '1/0'), whether it is a rational, and its denominator."""
    num, den = getattr(value, "numerator", None), getattr(value, "denominator", None)
    rational = isinstance(num, int) and isinstance(den, int) and den != 1
    return (f"{num}/{den}" if rational else repr(value)), rational, den


def _exif_number(value: Any, key: str) -> float:
    """One EXIF exposure field as a float: a finite number > 0, else ValueError naming the field and the value as
    written (a rational 1/0 as '1/0')."""
    value = value[0] if key == "iso" and isinstance(value, (tuple, list)) and value else _single(value)
    text, rational, den = _written(value)
    try:
        number = float("nan") if rational and den == 0 else float(value)
    except (TypeError, ValueError, ArithmeticError):  # several values, text, a rational over 0, beyond a float
        number = float("nan")
    if not (np.isfinite(number) and number > 0):
        tag, what = _EXIF_NAMES[key]
        raise ValueError(f"EXIF {tag} is {text}; expected a finite {what} > 0 (correct it, or remove the tag from "
                         "every photo to read them without exposure normalisation)")
    return number


def _apex(value: Any, key: str) -> float:
    """An APEX value (ShutterSpeedValue Tv or ApertureValue Av) as seconds (2^-Tv) or an f-number (2^(Av/2)),
    checked as the field it stands for."""
    try:
        v = float(_single(value))
    except (TypeError, ValueError, ArithmeticError):
        v = float("nan")
    usable = bool(np.isfinite(v) and abs(v) < 64)
    if key == "exposure_time_s" and not usable:  # named as written, not as the ExposureTime it stands for
        raise ValueError(f"EXIF ShutterSpeedValue is {_written(_single(value))[0]}; expected a finite APEX shutter "
                         "speed (-log2 of the exposure time in seconds; correct it, or remove the exposure tags from "
                         "every photo to read them without exposure normalisation)")
    number = 2.0 ** (-v if key == "exposure_time_s" else v / 2) if usable else float("nan")
    return _exif_number(number, key) if key in _EXIF_NAMES else number


def _exif(img: Any) -> dict[str, Any]:
    exif = img.getexif()
    # the Exif sub-IFD first, then IFD0 (TIFF/EP and some writers put the exposure there)
    ifd = {**{k: v for k, v in exif.items() if k in _EXPOSURE_TAGS}, **exif.get_ifd(_EXIF_IFD)}
    out: dict[str, Any] = {}
    if _EXPOSURE_TIME in ifd:
        out["exposure_time_s"] = _exif_number(ifd[_EXPOSURE_TIME], "exposure_time_s")
    elif _SHUTTER_APEX in ifd:  # only the APEX shutter speed: the same exposure, written another way
        out["exposure_time_s"] = _apex(ifd[_SHUTTER_APEX], "exposure_time_s")
    if _ISO in ifd:
        out["iso"] = _exif_number(ifd[_ISO], "iso")
    aperture = _positive(ifd[_F_NUMBER] if _F_NUMBER in ifd else
                         _apex(ifd[_APERTURE_APEX], "f_number") if _APERTURE_APEX in ifd else None)
    if aperture is not None:
        out["f_number"] = aperture
    if _COLOR_SPACE in ifd:  # one whole number, else kept as written: not sRGB, refused where it decides
        space = _single(ifd[_COLOR_SPACE])
        out["color_space"] = space if isinstance(space, int) and not isinstance(space, bool) else repr(space)
    if _ORIENTATION in exif:
        out["orientation"] = _single(exif[_ORIENTATION])
    if (focal := _positive(ifd.get(_FOCAL_35MM))) is not None:
        out["focal_35mm_mm"] = focal
    return out


def read_exif(path: Path) -> dict[str, Any]:
    """What Pillow reads of a photo: the EXIF fields (`exposure_time_s`, `iso`, `f_number`, `color_space`,
    `orientation`, `focal_35mm_mm`) it has, `declared_curve` (`declared_curve`) and `icc` where it embeds an ICC
    profile, `grey`, `exif_damaged` (Pillow's warning); {} where Pillow cannot open it. A CMYK file is a
    ValueError."""
    import warnings

    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")  # PIL warns of a damaged EXIF block without naming the file
            with Image.open(path) as img:
                exif = _exif(img)
                declared = declared_curve(img.info)
                if img.info.get("icc_profile"):  # it, not the EXIF colour space, tells the curve
                    exif["icc"] = True
                exif["grey"] = img.mode in ("1", "L", "LA", "I", "I;16", "I;16B", "F")  # read as colour by OpenCV
                if img.mode == "CMYK":  # ink amounts, which OpenCV turns into RGB without a word
                    raise ValueError("it holds CMYK values (a print separation), not the light the camera saw; "
                                     "expected an RGB or grey photo (export it again from the camera's file)")
    except (UnidentifiedImageError, OSError):
        return {}  # no EXIF to read; the pixels are read (or refused) by OpenCV
    if caught:
        exif["exif_damaged"] = str(caught[0].message).splitlines()[0]
    return {**exif, **({"declared_curve": declared} if declared else {})}


@functools.lru_cache(maxsize=8)
def icc_curve(profile: bytes) -> str:
    """The curve an embedded ICC profile gives its values, measured by LittleCMS (Pillow's ImageCms) on a grey ramp
    taken through it into sRGB: "srgb" (the sRGB curve, whatever its primaries: sRGB IEC61966-2.1, Display P3),
    "linear" (gamma 1), else the profile named (Adobe RGB's gamma 2.2, ...; an unreadable profile too)."""
    import io

    import colour
    from PIL import Image, ImageCms

    try:
        prof = ImageCms.ImageCmsProfile(io.BytesIO(profile))
        name = (prof.profile.profile_description or "").strip() or "without a description"
        mode = {"RGB": "RGB", "GRAY": "L"}.get(prof.profile.xcolor_space.strip())
        if mode is None:  # CMYK, Lab, ...: no curve of the file's RGB values
            return f"the {prof.profile.xcolor_space.strip()} ICC profile {name!r}"
        ramp = Image.fromarray(np.arange(256, dtype=np.uint8)[None]).convert(mode)
        into = ImageCms.buildTransform(prof, ImageCms.createProfile("sRGB"), mode, "RGB",
                                       ImageCms.Intent.RELATIVE_COLORIMETRIC)
        got = np.asarray(ImageCms.applyTransform(ramp, into), np.float64)[0]
    except (ImageCms.PyCMSError, OSError, ValueError, TypeError) as exc:
        return f"an ICC profile that LittleCMS cannot read ({str(exc).strip()[:80]})"
    codes = np.arange(256.0)[:, None]
    if np.abs(got - codes).max() <= 2:  # the 8-bit rounding of the transform
        return "srgb"
    if np.abs(got - 255 * colour.cctf_encoding(codes / 255, function="sRGB")).max() <= 2:
        return "linear"
    return f"the ICC profile {name!r}"


def declared_curve(info: dict[str, Any]) -> str | None:
    """The encoding a file declares: its ICC profile's curve (`icc_curve`), else a PNG's own chunks: "srgb" (an sRGB
    chunk, or gAMA 1/2.2), "linear" (gAMA 1), "gamma G" (another gAMA); None (none of them)."""
    if info.get("icc_profile"):
        return icc_curve(bytes(info["icc_profile"]))
    if "srgb" in info:
        return "srgb"
    gamma = info.get("gamma")
    if gamma is None:
        return None
    if not isinstance(gamma, (int, float)) or not np.isfinite(gamma) or gamma <= 0:  # a damaged chunk is no curve
        return f"gamma {gamma!r} (invalid)"
    if abs(gamma - 1.0) < 0.01:
        return "linear"
    return "srgb" if abs(gamma - 1 / 2.2) < 0.01 else f"gamma {gamma:.5g} (a PNG gAMA chunk)"
