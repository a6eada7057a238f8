"""Camera RAW files (DNG, CR2, CR3, NEF, ARW, ORF, RW2, RAF), developed linear by LibRaw through rawpy.

`read_raw` develops one file the same way every time, so that its values stay proportional to the light:

- the sensor's black level is subtracted and its white level maps to 1 (LibRaw's scaling; the white level is
  the file's own, `adjust_maximum_thr=0` keeps LibRaw from lowering it to the brightest value found);
- the camera's as-shot white balance is applied (LibRaw falls back to its daylight balance where the file has
  none, and the record says so); highlights are left unclipped (`HighlightMode.Ignore`): the white balance
  scales each channel so that the most amplified one reaches 1 at the white level, so no channel is clipped
  below the sensor's own clipping (a grey at the white level comes out at the smallest over the largest
  multiplier, and is marked saturated);
- linear (bilinear) demosaic, no tone curve (gamma (1, 1)), no automatic brightening, 16-bit output;
- the camera's colours are converted to linear sRGB (`COLOR_SPACE`: Rec. 709 primaries, D65 white), the space
  every other photo is read into, with the camera matrix LibRaw knows (the DNG's ColorMatrix); colours outside
  sRGB are clipped at 0 and 1 by LibRaw;
- the orientation the file records is applied (LibRaw's default).

A value is saturated (a lower bound) where the raw sensor value within one pixel of it is at the white level,
or where a channel of the developed image is at its largest code. The exposure time and ISO come from
LibRaw's reading of the file's metadata (`rawpy.RawPy.other`). The record of each file (`RawRecord`) holds
the white-balance multipliers, the black and white levels, the channels, what was done and the rawpy /
LibRaw versions. Errors are one-line ValueErrors naming the flag and the file.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from scenes.files import caught_stderr as _libraw_said

RAW_SUFFIXES = (".dng", ".cr2", ".cr3", ".nef", ".arw", ".orf", ".rw2", ".raf")
"""File suffixes read as camera RAW files (case-insensitive)."""
COLOR_SPACE = "linear sRGB (Rec. 709 primaries, D65 white)"
"""The colour space RAW files are developed into: the one every other photo is read into."""
DEMOSAIC = "linear"
"""LibRaw's demosaic of RAW files: bilinear interpolation of the missing colours (no edge-directed guess)."""


def is_raw(path: str | Path) -> bool:
    """Whether `path` is read as a camera RAW file (by its suffix)."""
    return Path(path).suffix.lower() in RAW_SUFFIXES


def _libraw_message(err: Exception) -> str:
    msg = err.args[0] if err.args else type(err).__name__
    return (msg.decode(errors="replace") if isinstance(msg, bytes) else str(msg)).strip() or type(err).__name__


def _refusal(what: str, err: Exception, said: list[str]) -> str:
    detail = "; ".join([_libraw_message(err), *said])
    return (f"{what} ({detail}); expected a RAW file LibRaw {_libraw_version()} reads (DNG, CR2, CR3, NEF, ARW, ORF, "
            "RW2, RAF)")


def _open(path: Path, flag: str, said: list[str]) -> Any:
    import rawpy

    failure, raw = None, None
    with _libraw_said() as now:
        try:
            raw = rawpy.imread(str(path))
            raw.raw_image_visible  # noqa: B018 - unpacks the sensor data: a truncated file fails here, not later
        except (rawpy.LibRawError, rawpy.NotSupportedError, OSError) as err:
            failure = err
    if failure is not None:
        if raw is not None:
            raw.close()
        raise ValueError(_refusal(f"{flag}: cannot read {str(path)!r} as a camera RAW file", failure, now))
    said.extend(now)
    return raw


def _libraw_version() -> str:
    import rawpy

    return ".".join(str(v) for v in rawpy.libraw_version)


def raw_shape(path: str | Path, flag: str = "--input") -> tuple[int, int]:
    """(height, width) of the developed image of a RAW file, its orientation applied, without developing it."""
    with _open(Path(path), flag, []) as raw:
        s = raw.sizes
        return (s.width, s.height) if s.flip & 4 else (s.height, s.width)


def _oriented(sensor: np.ndarray, flip: int) -> np.ndarray:
    """A (H, W) array of the sensor grid turned as LibRaw turns the developed image (its `flip`: 1 mirrors the
    columns, 2 the rows, 4 swaps rows and columns after both)."""
    if flip & 2:
        sensor = sensor[::-1]
    if flip & 1:
        sensor = sensor[:, ::-1]
    return sensor.T if flip & 4 else sensor


def _sensor_clipped(raw: Any) -> np.ndarray:
    """(H, W) bool on the sensor grid: a raw value within one pixel is at the white level (the linear demosaic
    takes each pixel's missing colours from its 3 x 3 neighbours)."""
    import cv2

    at_white = (raw.raw_image_visible >= raw.white_level).astype(np.uint8)
    return cv2.dilate(at_white, np.ones((3, 3), np.uint8)) > 0


def _exposure(raw: Any) -> dict[str, float]:
    """EXIF exposure time (s) and ISO as LibRaw read them; absent where the file does not give them (LibRaw's 0)."""
    other, out = raw.other, {}
    if other.shutter_speed > 0:
        out["exposure_time_s"] = float(f"{other.shutter_speed:.6g}")  # LibRaw holds them as float32
    if other.iso_speed > 0:
        out["iso"] = float(f"{other.iso_speed:.6g}")
    if getattr(other, "aperture", 0) > 0:
        out["f_number"] = float(f"{other.aperture:.6g}")
    return out


def _record(raw: Any, saturation_from: str, said: list[str]) -> dict[str, Any]:
    import rawpy

    camera_wb = [float(v) for v in raw.camera_whitebalance]
    has_camera_wb = camera_wb[0] > 0 and camera_wb[2] > 0  # LibRaw's own test before it uses them
    return {
        "white_balance": camera_wb if has_camera_wb else [float(v) for v in raw.daylight_whitebalance],
        "white_balance_from": "camera (as shot)" if has_camera_wb else "LibRaw's daylight balance (the file has none)",
        "channels": raw.color_desc.decode(errors="replace"),
        "black_level": [int(v) for v in raw.black_level_per_channel],
        "white_level": int(raw.white_level),
        "demosaic": DEMOSAIC, "tone_curve": "none (gamma 1)", "highlights": "unclipped",
        "color_space": COLOR_SPACE, "orientation_flip": int(raw.sizes.flip), "saturation_from": saturation_from,
        "rawpy": rawpy.__version__, "libraw": _libraw_version(), **({"libraw_said": said} if said else {}),
    }


def read_raw(path: str | Path, flag: str = "--input"
             ) -> tuple[np.ndarray, np.ndarray, dict[str, float], dict[str, Any]]:
    """One RAW file developed linear (see the module doc): (H, W, 3) float64 linear sRGB in [0, 1], (H, W, 3)
    bool saturated, the exposure fields (`exposure_time_s`, `iso` where the file gives them) and the record of
    how it was developed."""
    import rawpy

    path, said = Path(path), []
    with _open(path, flag, said) as raw:
        black = max(int(v) for v in raw.black_level_per_channel)
        if int(raw.white_level) <= black:  # no range between dark and full: every developed value would be 0
            raise ValueError(f"{flag}: {str(path)!r} says its white level {int(raw.white_level)} is at or below its "
                             f"black level {black}; expected a RAW file whose white level lies above the black level")
        clipped = _oriented(_sensor_clipped(raw), raw.sizes.flip)
        failure = None
        with _libraw_said() as now:
            try:
                rgb = raw.postprocess(demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR, use_camera_wb=True,
                                      output_color=rawpy.ColorSpace.sRGB, output_bps=16, gamma=(1, 1),
                                      no_auto_bright=True, highlight_mode=rawpy.HighlightMode.Ignore,
                                      adjust_maximum_thr=0.0)
            except (rawpy.LibRawError, rawpy.NotSupportedError) as err:
                failure = err
        if failure is not None:
            raise ValueError(_refusal(f"{flag}: cannot develop {str(path)!r}", failure, now))
        said.extend(now)
        saturated = np.any(rgb == np.iinfo(np.uint16).max, axis=-1)
        if clipped.shape == saturated.shape:  # not for sensors LibRaw resamples (pixel aspect, Fuji's 45 degrees)
            saturated |= clipped
            source = "sensor values at the white level, and the largest code"
        else:
            source = "the largest code of the developed image"
        record = _record(raw, source, said)
        exposure = _exposure(raw)
    sat3 = np.repeat(saturated[..., None], 3, axis=2)
    return rgb.astype(np.float64) / np.iinfo(np.uint16).max, sat3, exposure, record
