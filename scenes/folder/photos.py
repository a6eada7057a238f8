"""A plain folder of photos: any file names, 8/16-bit PNG and TIFF, JPEG, float EXR; no mask, no light files.

`read_photos` returns the images linear, in one float32 array, with what each file said about itself:

- files are taken in natural order (`IMG_2.jpg` before `IMG_10.jpg`, `natsort`), by suffix (`PHOTO_SUFFIXES`);
- EXIF orientation is applied (OpenCV's decoder), so a photo shows as the camera was held;
- encoded values are linearised with colour-science's sRGB decoding where the file is sRGB: `encoding="auto"`
  takes 8-bit files as sRGB (as cameras and phones write JPEG and PNG; an EXIF colour space other than sRGB
  is refused in auto mode, since the curve would be unknown) and 16-bit and EXR files as linear; `srgb` or
  `linear` force one for all files;
- EXIF exposure time and ISO, where every image has them and they differ, normalise the images to the first
  image's exposure (a photo taken at twice the exposure is halved), recorded per image;
- a channel at the file's largest code is saturated (a lower bound of the true value), recorded;
- mixed sizes, orientations or bit depths are one ValueError naming the first file that differs.

Everything here is NumPy / OpenCV / Pillow; errors are ValueError / FileNotFoundError with one line naming the
argument (`--input`) and the file.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".exr")
"""File suffixes read as photos (case-insensitive)."""
ENCODINGS = ("auto", "srgb", "linear")
"""How encoded values become linear: `auto` (sRGB for 8-bit files, linear otherwise), or one for all files."""
_EXIF_IFD = 0x8769
_EXPOSURE_TIME, _ISO, _COLOR_SPACE = 0x829A, 0x8827, 0xA001
_SRGB_COLOR_SPACE = 1


@dataclass
class Photos:
    """The images of a folder of photos, linear, and what each file said about itself."""

    images: np.ndarray
    """(K, H, W, 3) float32 linear RGB, normalised to the first image's exposure where EXIF gives exposures."""
    saturated: np.ndarray
    """(K, H, W, 3) bool: the file's value was its largest code (the true value is at least this)."""
    names: list[str]
    """File names, in the order of `images`."""
    encoding: list[str]
    """Per image: 'srgb' or 'linear', how its values were linearised."""
    bit_depth: int
    """8, 16 or 32 (float EXR), the same for every file."""
    exposure: list[dict[str, Any]] = field(default_factory=list)
    """Per image: EXIF `exposure_time_s` and `iso` where present, and the `scale` applied (1 when none)."""


def photo_files(folder: str | Path, flag: str = "--input") -> list[Path]:
    """The photo files of `folder` in natural order; FileNotFoundError / ValueError naming `flag`."""
    from natsort import natsorted, ns

    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{flag}: {str(folder)!r} is not a folder")
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in PHOTO_SUFFIXES]
    if not files:
        raise ValueError(f"{flag}: no photos in {str(folder)!r} (expected files ending in {', '.join(PHOTO_SUFFIXES)})")
    return natsorted(files, key=lambda p: p.name, alg=ns.IGNORECASE)


def _exif(img: Any) -> dict[str, Any]:
    ifd = img.getexif().get_ifd(_EXIF_IFD)
    out: dict[str, Any] = {}
    if _EXPOSURE_TIME in ifd:
        out["exposure_time_s"] = float(ifd[_EXPOSURE_TIME])
    if _ISO in ifd:
        iso = ifd[_ISO]
        out["iso"] = float(iso[0] if isinstance(iso, (tuple, list)) else iso)
    if _COLOR_SPACE in ifd:
        out["color_space"] = int(ifd[_COLOR_SPACE])
    return out


def _read_exif(path: Path) -> dict[str, Any]:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as img:
            return _exif(img)
    except (UnidentifiedImageError, OSError):
        return {}  # no EXIF to read; the pixels are read (or refused) by OpenCV


def _read_one(path: Path, flag: str) -> tuple[np.ndarray, int, dict[str, Any]]:
    """(H, W, 3) RGB codes as float64 in [0, 1] (EXR: linear floats), the bit depth, the EXIF fields. OpenCV
    decodes the pixels at their own depth and turns them as the EXIF orientation says."""
    if path.suffix.lower() == ".exr":
        from scenes.images import read_exr

        data = read_exr(path)
        data = np.repeat(data[..., None], 3, axis=2) if data.ndim == 2 else data[..., :3]
        return data.astype(np.float64), 32, {}
    import cv2

    raw = cv2.imread(str(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)
    if raw is None:
        raise ValueError(f"{flag}: cannot read {str(path)!r} as an image")
    if raw.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"{flag}: {str(path)!r} holds {raw.dtype} values, expected 8 or 16-bit integers (or an EXR)")
    depth = 8 if raw.dtype == np.uint8 else 16
    return raw[..., ::-1].astype(np.float64) / (255.0 if depth == 8 else 65535.0), depth, _read_exif(path)


def _linear(codes: np.ndarray, depth: int, encoding: str, exif: dict[str, Any], path: Path, flag: str) -> tuple[np.ndarray, str]:
    import colour

    kind = encoding if encoding != "auto" else ("srgb" if depth == 8 else "linear")
    if encoding == "auto" and depth == 8 and exif.get("color_space", _SRGB_COLOR_SPACE) != _SRGB_COLOR_SPACE:
        raise ValueError(f"{flag}: {str(path)!r} declares EXIF colour space {exif['color_space']} (not sRGB); give "
                         f"--input-encoding srgb or linear to say how its values are encoded")
    if kind == "srgb" and depth != 32:
        return np.asarray(colour.cctf_decoding(codes, function="sRGB"), np.float64), kind
    return codes, "linear"


def _exposure_scales(exifs: list[dict[str, Any]]) -> list[float]:
    """Per image: the factor that brings it to the first image's exposure (1 where EXIF does not tell)."""
    if not all("exposure_time_s" in e and "iso" in e for e in exifs):
        return [1.0] * len(exifs)
    light = [e["exposure_time_s"] * e["iso"] for e in exifs]
    if min(light) <= 0 or len(set(light)) == 1:
        return [1.0] * len(exifs)
    return [light[0] / v for v in light]


def _downscale(image: np.ndarray, max_side: int | None) -> np.ndarray:
    if max_side is None or max(image.shape[:2]) <= max_side:
        return image
    import cv2

    f = max_side / max(image.shape[:2])
    size = (max(1, round(image.shape[1] * f)), max(1, round(image.shape[0] * f)))
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA)


def read_photos(folder: str | Path, encoding: str = "auto", max_side: int | None = None,
                flag: str = "--input") -> Photos:
    """Every photo of `folder`, linear (see the module doc); `max_side` downscales (area average) so that the
    longer side is at most that many pixels."""
    if encoding not in ENCODINGS:
        raise ValueError(f"--input-encoding: got {encoding!r}, expected one of {', '.join(ENCODINGS)}")
    files = photo_files(folder, flag)
    images, saturated, kinds, exifs = [], [], [], []
    first: tuple[tuple[int, ...], int] | None = None
    for path in files:
        codes, depth, exif = _read_one(path, flag)
        if first is None:
            first = (codes.shape, depth)
        elif (codes.shape, depth) != first:
            what = ("bit depth" if codes.shape == first[0] else "orientation" if codes.shape[:2] == first[0][1::-1]
                    else "size")
            raise ValueError(f"{flag}: {path.name} differs in {what} from {files[0].name} "
                             f"({codes.shape[1]}x{codes.shape[0]} {depth}-bit, expected {first[0][1]}x{first[0][0]} "
                             f"{first[1]}-bit): every photo of a capture must come from one camera setting")
        lin, kind = _linear(codes, depth, encoding, exif, path, flag)
        if not np.all(np.isfinite(lin)):
            raise ValueError(f"{flag}: {path.name} holds NaN or infinite values")
        saturated.append(_downscale((codes >= 1.0).astype(np.uint8), max_side) > 0 if depth != 32
                         else np.zeros(_downscale(codes, max_side).shape, bool))
        images.append(_downscale(lin.astype(np.float32), max_side))
        kinds.append(kind)
        exifs.append(exif)
    scales = _exposure_scales(exifs)
    stack = np.stack([img * np.float32(s) for img, s in zip(images, scales)])
    exposure = [{**{k: v for k, v in e.items() if k != "color_space"}, "scale": s} for e, s in zip(exifs, scales)]
    return Photos(images=stack, saturated=np.stack(saturated), names=[p.name for p in files], encoding=kinds,
                  bit_depth=first[1], exposure=exposure)
