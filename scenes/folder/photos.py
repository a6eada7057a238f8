"""A plain folder of photos: any file names, 8/16-bit PNG and TIFF, JPEG, float EXR, camera RAW; no mask, no light
files.

`read_photos` returns the images linear, in one float32 array, with what each file said about itself:

- files are taken in natural order (`IMG_2.jpg` before `IMG_10.jpg`, `natsort`), by suffix (`PHOTO_SUFFIXES`;
  other pictures, `OTHER_IMAGE_SUFFIXES`, are refused by name; hidden files are skipped);
- files are decoded strictly (`scenes.images.decode_image`): a JPEG its decoder reports truncated or corrupt, a
  TIFF that does not decode whole, is refused naming it (OpenCV would return it grey-filled or in part);
- EXIF orientation is applied (OpenCV's decoder), so a photo shows as the camera was held; every photo must say the
  same orientation (EXIF tag 0x0112, 1 where absent; LibRaw's flip for RAW files), square or not;
- encoded values are linearised with colour-science's sRGB decoding where the file is sRGB: `encoding="auto"`
  takes 8-bit files as sRGB (as cameras and phones write JPEG and PNG; an EXIF colour space other than sRGB
  is refused in auto mode, since the curve would be unknown) and 16-bit and EXR files as linear, except where the
  file says otherwise (`scenes.folder.photo_tags`): an embedded ICC profile decides before any EXIF colour space
  where its curve is sRGB's (sRGB, a phone's Display P3: linear values in the profile's own primaries, which
  photometric stereo takes as they are) or linear, and is refused in auto mode otherwise (Adobe RGB's gamma 2.2,
  an unreadable profile); else a PNG's own sRGB or gAMA chunk (gAMA 1: linear; 1/2.2 or sRGB: sRGB; another gamma
  is refused); `srgb` or `linear` force one for all files;
- camera RAW files (DNG, CR2, CR3, NEF, ARW, ORF, RW2, RAF) are developed linear by LibRaw (`scenes.folder.raw`:
  linear demosaic, camera white balance, no tone curve, linear sRGB), recorded per image; they are linear, so
  `srgb` is refused for them, and a folder mixing RAW and other files is refused (their scales differ);
- EXIF exposure time and ISO (for RAW files, as LibRaw reads them), where every image has them and they differ,
  normalise the images to the first image's exposure (a photo taken at twice the exposure is halved; divided by
  the f-number squared where every image gives its aperture), recorded
  per image with the fields a file did not give; a value that is there must be a finite number > 0, and the
  exposures (time x ISO) of one capture may differ at most `MAX_EXPOSURE_RATIO` times, or the file is refused
  naming the value;
- a channel at the file's largest code is saturated (a lower bound of the true value), recorded;
- mixed sizes, orientations or bit depths are one ValueError naming the first file that differs.

Everything here is NumPy / OpenCV / Pillow; errors are ValueError / FileNotFoundError with one line naming the
argument (`--input`) and the file.
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scenes.files import shown_name, text_name_problem
from scenes.folder.photo_tags import read_exif as _read_exif
from scenes.folder.raw import RAW_SUFFIXES, is_raw, raw_shape, read_raw
from scenes.images import CODE_SCALES

PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".exr", *RAW_SUFFIXES)
"""File suffixes read as photos (case-insensitive)."""
OTHER_IMAGE_SUFFIXES = (
    ".webp", ".heic", ".heif", ".hif", ".avif", ".gif", ".bmp", ".jp2", ".jxl", ".hdr", ".pfm",
    ".jfif", ".jpe", ".jif", ".tga", ".ppm", ".pgm", ".pbm", ".pnm", ".psd", ".jxr", ".wdp", ".ico", ".qoi", ".dds",
    # camera RAW files LibRaw reads but no test here has: refused rather than developed unchecked
    ".pef", ".srw", ".nrw", ".rwl", ".3fr", ".iiq", ".erf", ".mos", ".x3f", ".kdc", ".mrw", ".sr2", ".srf", ".crw",
)
"""Pictures a capture does not read (a JPEG under the name .jfif too: the suffix says the kind): in a photo folder
they are named, never silently left out of the capture. Hidden files (a name starting with a dot: macOS's ._ copies,
editors' and sync tools' files) are never photos."""
ENCODINGS = ("auto", "srgb", "linear")
"""How encoded values become linear: `auto` (sRGB for 8-bit files, linear otherwise), or one for all files."""
_SRGB_COLOR_SPACE = 1
MAX_EXPOSURE_RATIO = 1024.0
"""The most the EXIF exposures (time x ISO) of one capture may differ, longest over shortest: 10 stops. Between
8-bit photos further apart the darker one holds nothing the brighter does not; such values are a wrong EXIF
field or photos of different captures, and normalising by them would scale a photo out of range."""
_SHOWN = {1: "upright", 2: "mirrored", 3: "turned 180 deg", 4: "mirrored upside down", 5: "transposed",
          6: "turned 90 deg clockwise", 7: "transversed", 8: "turned 90 deg counter-clockwise"}


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
    """8, 16 or 32 (float EXR), the same for every file (16 for RAW files: LibRaw develops them to 16 bits)."""
    exposure: list[dict[str, Any]] = field(default_factory=list)
    """Per image: EXIF `exposure_time_s` and `iso` where present, `not_in_file` (those of the two the file did
    not give, where any), and the `scale` applied (1 when none)."""
    raw: list[dict[str, Any]] = field(default_factory=list)
    """Per image, for a folder of camera RAW files: how LibRaw developed it (`scenes.folder.raw`: white-balance
    multipliers, black and white levels, demosaic, colour space, rawpy / LibRaw versions); empty otherwise."""
    guide: np.ndarray | None = None
    """With `read_photos(guide=True)` and photos larger than `max_side`: (H, W) float32, the mean linear gray of the
    photos at their own size (each at its own exposure), to bring a map made at the smaller size back to theirs."""
    exposure_note: str | None = None
    """Why the photos were not normalised to one exposure although their EXIF exposures differ (one gives none)."""


NEGATIVE_SHARE = 0.01
"""A float photo (EXR) may dip below 0 by this share of its brightest value (sensor noise after a black level was
subtracted); further down it is not linear light."""
MAX_LINEAR = 1e9
"""Values above this are refused: squares of them overflow float32 arithmetic (about 1.8e19) in later steps."""


def object_layout(folder: str | Path) -> str | None:
    """The layout (`scenes.folder.layouts.detect_layout`) --input of a capture is read as, or None for a folder of
    photos: the official UniPS layout only in a folder named *.data (as its loaders find them) or holding its
    mask.png, since cameras name photos L* too (Leica: L1000001.JPG), and those are sRGB photos, not linear images."""
    from scenes.folder.format import MASK_FILE
    from scenes.folder.layouts import detect_layout

    folder = Path(folder)
    layout = detect_layout(folder)
    if layout == "unips" and not folder.name.endswith(".data") and not os.path.lexists(folder / MASK_FILE):
        return None
    return layout


def _loops(path: Path) -> bool:
    import errno

    try:
        os.stat(path)
    except OSError as exc:
        return exc.errno == errno.ELOOP
    return False


def photo_files(folder: str | Path, flag: str = "--input") -> list[Path]:
    """The photo files of `folder` in natural order; FileNotFoundError / ValueError naming `flag`."""
    from natsort import natsorted, ns

    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{flag}: {str(folder)!r} is not a folder")
    shown = [p for p in folder.iterdir() if not p.name.startswith(".")]
    named = [p for p in shown if p.suffix.lower() in PHOTO_SUFFIXES]
    for p in named:  # before any is read: the outputs' writers take names as text only
        if (problem := text_name_problem(p.name)) is not None:
            raise ValueError(f"{flag}: a photo in {shown_name(folder)!r}: {problem}")
    if (mask := next((p for p in named if p.stem.lower() == "mask"), None)) is not None:  # never a photo of a light
        raise ValueError(f"{flag}: {mask.name} in {str(folder)!r} is named as a mask, not a photo; give it as --mask "
                         "(moved out of the folder), or rename it if it is a photo")
    broken = next((p for p in named if not p.is_file()), None)
    if broken is not None:  # a photo that silently went missing would change the capture
        what = ("not a file" if not broken.is_symlink() or broken.exists() else "a link in a loop of links"
                if _loops(broken) else "a link to a missing file")
        raise ValueError(f"{flag}: {broken.name} in {str(folder)!r} is {what}; expected every photo-named entry to be "
                         "a photo (remove it or restore the file)")
    near = next((p for p in shown if (core := p.name.rstrip(" \t.")) != p.name
                 and Path(core).suffix.lower() in PHOTO_SUFFIXES + OTHER_IMAGE_SUFFIXES), None)
    if near is not None:  # 'IMG_7.jpg ' was left out of the capture without a word (sweep 40)
        raise ValueError(f"{flag}: {near.name!r} in {str(folder)!r} is named like a photo but ends in "
                         f"{near.name[len(near.name.rstrip(' ' + chr(9) + '.')):]!r} after its suffix; rename it "
                         "(or move it out of the folder)")
    other = sorted(p.name for p in shown if p.suffix.lower() in OTHER_IMAGE_SUFFIXES)
    if other:
        more = f", and {len(other) - 1} more" if len(other) > 1 else ""
        raise ValueError(f"{flag}: {other[0]} in {str(folder)!r} is a picture of a kind the capture does not read "
                         f"({Path(other[0]).suffix.lower()[1:]}{more}); expected {', '.join(PHOTO_SUFFIXES)}: "
                         "convert it (16-bit PNG or TIFF keep the most), or move it out of the folder")
    files = named
    if not files:
        raise ValueError(f"{flag}: no photos in {str(folder)!r} (expected files ending in {', '.join(PHOTO_SUFFIXES)})")
    files = natsorted(files, key=lambda p: p.name, alg=ns.IGNORECASE)
    raws = [p for p in files if is_raw(p)]
    if raws and len(raws) != len(files):
        other = next(p for p in files if not is_raw(p))
        raise ValueError(
            f"{flag}: {str(folder)!r} mixes camera RAW files ({raws[0].name}) with other photos "
            f"({other.name}): their values are on different scales; expected one kind per capture (move the RAW "
            "or the other files out of the folder)"
        )
    return files


def photo_shape(path: str | Path, flag: str = "--input") -> tuple[int, int]:
    """(height, width) of one photo as `read_photos` reads it (orientation applied)."""
    if is_raw(path):
        return raw_shape(path, flag)
    if Path(path).suffix.lower() == ".exr":
        from scenes.images import read_exr

        try:
            return read_exr(path).shape[:2]
        except ValueError as exc:  # the file is named; the flag that gave it, here
            raise ValueError(f"{flag}: {exc}") from None
    import cv2

    from scenes.images import decode_image

    first = decode_image(Path(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR, f"{flag}: {str(path)!r}")
    if first is None:
        raise ValueError(f"{flag}: cannot read {str(path)!r} as an image")
    return first.shape[:2]


@dataclass
class _File:
    """One photo as read: its codes, what it said about itself and, for RAW files, how it was developed."""

    codes: np.ndarray
    """(H, W, 3): the file's integer codes (uint8 or uint16), or float linear values (EXR; RAW developed linear, in
    [0, 1])."""
    depth: int
    exif: dict[str, Any]
    """The exposure fields (`exposure_time_s`, `iso`) where given, `color_space` and `orientation` (EXIF tag
    0x0112) where the file has them."""
    saturated: np.ndarray | None = None
    """(H, W, 3) bool where the reader knows better than 'at the largest code' (RAW files)."""
    raw: dict[str, Any] | None = None


def _read_file(path: Path, flag: str) -> _File:
    if is_raw(path):
        codes, saturated, exif, record = read_raw(path, flag)
        return _File(codes, 16, exif, saturated, record)
    return _File(*_read_one(path, flag))


def _orientation(f: _File) -> tuple[str, int]:
    """How a file says it is to be shown: its EXIF orientation (1, upright, where it has none; EXR has none), or
    LibRaw's flip for a RAW file."""
    if f.raw is not None:
        return "LibRaw flip", int(f.raw.get("orientation_flip", 0))
    value = f.exif.get("orientation", 1)
    return "EXIF orientation", int(value) if isinstance(value, int) else -1


def _shown(orientation: tuple[str, int]) -> str:
    kind, value = orientation
    return f"{_SHOWN[value]} ({kind} {value})" if kind == "EXIF orientation" and value in _SHOWN else f"{kind} {value}"


def _read_one(path: Path, flag: str) -> tuple[np.ndarray, int, dict[str, Any]]:
    """(H, W, 3) RGB codes as the file holds them (uint8 or uint16; EXR: linear float32), the bit depth, the EXIF
    fields. OpenCV decodes the pixels at their own depth and turns them as the EXIF orientation says."""
    if path.suffix.lower() == ".exr":
        from scenes.images import read_exr

        try:
            data = read_exr(path)  # (H, W, C): R, G, B (of its one layer) when present, else its channels by name
        except ValueError as exc:
            raise ValueError(f"{flag}: {exc}") from None
        if data.shape[2] not in (1, 3):
            raise ValueError(f"{flag}: {str(path)!r} is an EXR of {data.shape[2]} channels, expected one (grey) or "
                             "R, G and B")
        data = np.repeat(data, 3, axis=2) if data.shape[2] == 1 else data
        return data.astype(np.float32), 32, {}
    import cv2

    from scenes.images import decode_image

    raw = decode_image(path, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR, f"{flag}: {str(path)!r}")
    if raw is None:
        raise ValueError(f"{flag}: cannot read {str(path)!r} as an image")
    if raw.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"{flag}: {str(path)!r} holds {raw.dtype} values, expected 8 or 16-bit integers (or an EXR)")
    depth = 8 if raw.dtype == np.uint8 else 16
    try:
        exif = _read_exif(path)
    except ValueError as exc:
        raise ValueError(f"{flag}: {path.name}: {exc}") from None
    return raw[..., ::-1], depth, exif


def _linear(
    codes: np.ndarray, depth: int, encoding: str, exif: dict[str, Any], path: Path, flag: str
) -> tuple[np.ndarray, str]:
    import colour

    declared = exif.get("declared_curve")  # a PNG's sRGB or gAMA chunk says how its codes are encoded
    if encoding == "auto" and declared not in (None, "srgb", "linear"):
        raise ValueError(f"{flag}: {str(path)!r} declares {declared}, not known to be sRGB or linear; give "
                         "--input-encoding srgb or linear to say how its values are encoded")
    kind = encoding if encoding != "auto" else declared or ("srgb" if depth == 8 else "linear")
    if (encoding == "auto" and depth == 8 and "icc" not in exif
            and exif.get("color_space", _SRGB_COLOR_SPACE) != _SRGB_COLOR_SPACE):
        raise ValueError(f"{flag}: {str(path)!r} declares EXIF colour space {exif['color_space']} (not sRGB); give "
                         f"--input-encoding srgb or linear to say how its values are encoded")
    if codes.dtype.kind == "f":  # EXR and RAW: linear values already
        return codes.astype(np.float32, copy=False), "linear"
    # Integer codes through a table of every code's value (the decoding evaluated once per code, in float64): a
    # 24-megapixel photo becomes float32 values directly, without float64 copies of the whole frame.
    top = CODE_SCALES[codes.dtype]
    table = np.arange(int(top) + 1, dtype=np.float64) / top
    if kind == "srgb":
        table = np.asarray(colour.cctf_decoding(table, function="sRGB"), np.float64)
    return table.astype(np.float32)[codes], kind


def exposure_gap(exifs: list[dict[str, Any]], names: list[str]) -> str | None:
    """Why photos whose EXIF exposures differ (a time or an ISO that not every photo shares) cannot be normalised to
    one exposure: a photo that gives no time or ISO (or no f-number, where the others' differ); None when they can,
    or nothing differs."""
    if all("exposure_time_s" in e and "iso" in e for e in exifs):
        stops = {e["f_number"] for e in exifs if "f_number" in e}
        bare = next((n for n, e in zip(names, exifs) if "f_number" not in e), None)
        if len(stops) > 1 and bare is not None:  # the apertures are then left out of every photo's exposure
            return (f"the EXIF f-numbers of the photos differ ({min(stops):.3g} to {max(stops):.3g}), but {bare} "
                    "(and maybe others) gives none: the photos are normalised by time and ISO only, not by aperture "
                    "(give every photo its f-number, or take them at one aperture)")
        return None
    differ = any(len({e[k] for e in exifs if k in e}) > 1 for k in ("exposure_time_s", "iso"))
    lacking = next((n for n, e in zip(names, exifs) if "exposure_time_s" not in e or "iso" not in e), None)
    if not differ or lacking is None:
        return None
    return (f"the EXIF exposures of the photos differ, but {lacking} (and maybe others) gives no exposure time or ISO: "
            "no photo is normalised to one exposure (give every photo its EXIF, or take them at one setting)")


def _exposure_scales(exifs: list[dict[str, Any]], names: list[str], flag: str) -> list[float]:
    """Per image: the factor that brings it to the first image's exposure (1 where EXIF does not tell); exposures
    that are not finite and positive, or further apart than `MAX_EXPOSURE_RATIO`, are one ValueError naming the
    files."""
    if not all("exposure_time_s" in e and "iso" in e for e in exifs):
        return [1.0] * len(exifs)
    # The light a photo gathers grows with the time and the gain, and falls with the square of the f-number (used
    # when every photo gives one: a lens stopped down 4 times lets in 16 times less).
    apertures = all("f_number" in e for e in exifs)
    light = [e["exposure_time_s"] * e["iso"] / (e["f_number"] ** 2 if apertures else 1.0) for e in exifs]

    def said(i: int) -> str:
        stop = f", f/{exifs[i]['f_number']:.3g}" if apertures else ""
        return f"{names[i]} ({exifs[i]['exposure_time_s']:.6g} s at ISO {exifs[i]['iso']:.6g}{stop})"

    bad = next((i for i, v in enumerate(light) if not (np.isfinite(v) and v > 0)), None)
    if bad is not None:
        raise ValueError(f"{flag}: {said(bad)}: EXIF exposure time x ISO / f-number^2 is {light[bad]:.6g}; expected "
                         "a finite value > 0")
    lo, hi = int(np.argmin(light)), int(np.argmax(light))
    if light[hi] / light[lo] > MAX_EXPOSURE_RATIO:
        raise ValueError(f"{flag}: EXIF exposures differ {light[hi] / light[lo]:.3g} times, {said(hi)} against "
                         f"{said(lo)}; expected at most {MAX_EXPOSURE_RATIO:.0f} times (10 stops) between the photos "
                         "of one capture: a wrong EXIF value, or photos of another capture?")
    if len(set(light)) == 1:
        return [1.0] * len(exifs)
    return [light[0] / v for v in light]


def _downscale(image: np.ndarray, max_side: int | None) -> np.ndarray:
    if max_side is None or max(image.shape[:2]) <= max_side:
        return image
    import cv2

    f = max_side / max(image.shape[:2])
    size = (max(1, round(image.shape[1] * f)), max(1, round(image.shape[0] * f)))
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA)


def _check_curves(kinds: list[str], exifs: list[dict[str, Any]], names: list[str], depth: int, encoding: str,
                  flag: str) -> None:
    """One curve for every photo of a capture (PNG chunks or ICC profiles may differ from file to file: refused), and
    a note where the files' own chunks or profiles, not their bit depth, decided it."""
    odd = next((i for i, k in enumerate(kinds) if k != kinds[0]), None)
    if odd is not None:
        raise ValueError(f"{flag}: {names[odd]} is read as {kinds[odd]} and {names[0]} as {kinds[0]} (their PNG "
                         "chunks or ICC profiles differ): every photo of a capture must be encoded one way; give "
                         "--input-encoding srgb or linear to say which")
    default = "srgb" if depth == 8 else "linear"
    if encoding == "auto" and depth != 32 and kinds and kinds[0] != default:
        source = "an ICC profile" if exifs[0].get("icc") else "a PNG chunk"
        print(f"note: {flag}: the files declare their curve ({exifs[0].get('declared_curve')}, {source}): read as "
              f"{kinds[0]}, not as {depth}-bit files are by default; --input-encoding says otherwise", file=sys.stderr)


def _exposure_record(exif: dict[str, Any], scale: float) -> dict[str, Any]:
    """What report.json records of one image's exposure: the EXIF fields read, those the file did not give, the
    scale applied."""
    out = {k: v for k, v in exif.items() if k not in ("color_space", "orientation", "declared_curve", "icc")}
    missing = [k for k in ("exposure_time_s", "iso") if k not in exif]
    return {**out, **({"not_in_file": missing} if missing else {}), "scale": scale}


def read_photos(folder: str | Path, encoding: str = "auto", max_side: int | None = None,
                flag: str = "--input", guide: bool = False) -> Photos:
    """Every photo of `folder`, linear (see the module doc); `max_side` downscales (area average) so that the
    longer side is at most that many pixels; `guide`: also their mean gray at their own size (`Photos.guide`), summed
    photo by photo as they are read."""
    if encoding not in ENCODINGS:
        raise ValueError(f"--input-encoding: got {encoding!r}, expected one of {', '.join(ENCODINGS)}")
    files = photo_files(folder, flag)
    if encoding == "srgb" and files[0].suffix.lower() == ".exr":
        raise ValueError(f"--input-encoding: got 'srgb' for EXR files ({files[0].name}, ...), which hold linear "
                         "floating point values; expected auto or linear")
    if encoding == "srgb" and is_raw(files[0]):
        raise ValueError(f"--input-encoding: got 'srgb' for camera RAW files ({files[0].name}, ...), which hold linear "
                         "sensor values; expected auto or linear")
    images, saturated, kinds, exifs, records = [], [], [], [], []
    first: tuple[tuple[int, ...], int] | None = None
    total: np.ndarray | None = None
    for path in files:
        f = _read_file(path, flag)
        codes, depth, grey = f.codes, f.depth, f.exif.pop("grey", None)
        if first is None:
            first, turned, first_grey = (codes.shape, depth), _orientation(f), grey
        elif None not in (grey, first_grey) and grey != first_grey:  # one camera setting: all colour or all grey
            raise ValueError(f"{flag}: {path.name} is a {'grey' if grey else 'colour'} photo and {files[0].name} a "
                             f"{'grey' if first_grey else 'colour'} one: every photo of a capture must come from one "
                             "camera setting")
        elif _orientation(f) != turned:
            raise ValueError(f"{flag}: {path.name} differs in orientation from {files[0].name} (it is to be shown "
                             f"{_shown(_orientation(f))}, {files[0].name} {_shown(turned)}): every photo of a capture "
                             "must be taken with the camera held one way (where it did not turn, e.g. a phone looking "
                             "straight down, give every file the same EXIF orientation)")
        elif (codes.shape, depth) != first:
            what = ("bit depth" if codes.shape == first[0] else "orientation" if codes.shape[:2] == first[0][1::-1]
                    else "size")
            raise ValueError(f"{flag}: {path.name} differs in {what} from {files[0].name} "
                             f"({codes.shape[1]}x{codes.shape[0]} {depth}-bit, expected {first[0][1]}x{first[0][0]} "
                             f"{first[1]}-bit): every photo of a capture must come from one camera setting")
        lin, kind = _linear(codes, depth, encoding, f.exif, path, flag)
        if not np.all(np.isfinite(lin)):
            raise ValueError(f"{flag}: {path.name} holds NaN or infinite values")
        low, high = (float(lin.min()), float(lin.max())) if codes.dtype.kind == "f" else (0.0, 1.0)
        if low < -NEGATIVE_SHARE * max(high, 0.0) or high <= 0 < -low:
            raise ValueError(f"{flag}: {path.name} holds negative values (down to {low:.3g}, brightest {high:.3g}); "
                             "expected linear light, 0 or more")
        if high > MAX_LINEAR:
            raise ValueError(f"{flag}: {path.name} holds values up to {high:.3g}; expected linear light below "
                             f"{MAX_LINEAR:g} (rescale the file)")
        sat = f.saturated if f.saturated is not None else (
            codes >= 1.0 if codes.dtype.kind == "f" else codes == CODE_SCALES[codes.dtype])
        small = _downscale(lin, max_side)
        saturated.append(_downscale(sat.astype(np.uint8), max_side) > 0 if depth != 32 else np.zeros(small.shape, bool))
        if guide and small.shape != lin.shape:
            gray = lin.mean(axis=-1, dtype=np.float32)
            gray /= len(files)
            if total is None:
                total = gray
            else:
                total += gray
        images.append(small)
        del lin, codes, sat  # one photo at its own size at a time
        kinds.append(kind)
        exifs.append(f.exif)
        if f.raw is not None:
            records.append(f.raw)
    _check_curves(kinds, exifs, [p.name for p in files], first[1], encoding, flag)
    damaged = [i for i, e in enumerate(exifs) if "exif_damaged" in e]
    if damaged:  # one line for the capture, not PIL's warning per file naming none
        print(f"warning: {flag}: the EXIF block of {len(damaged)} photo(s) is damaged ({files[damaged[0]].name}: "
              f"{exifs[damaged[0]]['exif_damaged'].strip()}); what could be read of it is used", file=sys.stderr)
    scales = _exposure_scales(exifs, [p.name for p in files], flag)
    if note := exposure_gap(exifs, [p.name for p in files]):  # said, and recorded with the photos
        print(f"warning: {flag}: {note}", file=sys.stderr)
    stack = np.stack([img * np.float32(s) for img, s in zip(images, scales)])
    return Photos(images=stack, saturated=np.stack(saturated), names=[p.name for p in files], encoding=kinds,
                  bit_depth=first[1], exposure=[_exposure_record(e, s) for e, s in zip(exifs, scales)], raw=records,
                  guide=total, exposure_note=note)
