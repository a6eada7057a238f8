"""A minimal camera RAW writer for tests and benches: uncompressed Bayer (RGGB) DNG files written byte by byte (the
DNG tags LibRaw needs, exposure time and ISO in an EXIF IFD), read back by the real rawpy / LibRaw.

The camera is given the colour matrix of linear sRGB (ColorMatrix1 = the inverse of the sRGB-to-XYZ matrix), so the
camera's white-balanced colours are linear sRGB already."""
from __future__ import annotations

import struct

import numpy as np

BLACK, WHITE = 256, 4095
NEUTRAL = (0.5, 1.0, 0.8)
"""AsShotNeutral: the camera's R, G, B response to white; the white-balance multipliers are 2, 1, 1.25."""
SRGB_TO_XYZ = np.array([[0.412453, 0.357580, 0.180423], [0.212671, 0.715160, 0.072169],
                        [0.019334, 0.119193, 0.950227]])
"""Linear sRGB (D65) to CIE XYZ, the matrix LibRaw converts to sRGB with."""
_FORMATS = {1: "B", 3: "H", 4: "I", 5: "I", 10: "i"}
"""struct formats of the TIFF types used: BYTE, SHORT, LONG, RATIONAL and SRATIONAL (two numbers each)."""


def _rationals(values, den: int = 1_000_000) -> list[int]:
    return [x for v in values for x in (int(round(v * den)), den)]


def _ifd(entries: dict[int, tuple[int, list]], at: int) -> bytes:
    """One little-endian TIFF IFD at file offset `at`, its out-of-line values right after it; no next IFD."""
    head = struct.pack("<H", len(entries))
    data_at = at + 2 + 12 * len(entries) + 4
    data = b""
    for tag in sorted(entries):
        typ, values = entries[tag]
        if typ == 2:
            payload, count = values.encode() + b"\0", len(values) + 1
        else:
            count = len(values) // (2 if typ in (5, 10) else 1)
            payload = struct.pack("<" + _FORMATS[typ] * len(values), *values)
        if len(payload) <= 4:
            head += struct.pack("<HHI", tag, typ, count) + payload.ljust(4, b"\0")
        else:
            data += b"\0" * (len(data) % 2)
            head += struct.pack("<HHII", tag, typ, count, data_at + len(data))
            data += payload
    return head + b"\0\0\0\0" + data


def write_dng(path, mosaic: np.ndarray, orientation: int = 1, exposure_s: float | None = None,
              iso: int | None = None, neutral=NEUTRAL, white: int = WHITE) -> None:
    """A minimal uncompressed Bayer (RGGB) DNG 1.4 of `mosaic` (H, W) uint16 sensor values."""
    h, w = mosaic.shape
    ifd0 = {254: (4, [0]), 256: (4, [w]), 257: (4, [h]), 258: (3, [16]), 259: (3, [1]), 262: (3, [32803]),
            271: (2, "Test"), 272: (2, "Test Camera"), 273: (4, [0]), 274: (3, [orientation]), 277: (3, [1]),
            278: (4, [h]), 279: (4, [mosaic.size * 2]), 284: (3, [1]), 33421: (3, [2, 2]),
            33422: (1, [0, 1, 1, 2]), 34665: (4, [0]), 50706: (1, [1, 4, 0, 0]), 50707: (1, [1, 1, 0, 0]),
            50708: (2, "Test Camera"), 50714: (4, [BLACK]), 50717: (4, [white]),
            50721: (10, _rationals(np.linalg.inv(SRGB_TO_XYZ).ravel())), 50778: (3, [21])}
    if neutral is not None:
        ifd0[50728] = (5, _rationals(neutral))
    exif = {}
    if exposure_s is not None:
        exif[33434] = (5, [1, int(round(1 / exposure_s))])
    if iso is not None:
        exif[34855] = (3, [iso])
    exif = exif or {37510: (2, "none")}  # an EXIF IFD with neither (a UserComment), as a camera might write
    size0 = len(_ifd(ifd0, 8))
    exif_at = 8 + size0 + size0 % 2
    size_exif = len(_ifd(exif, exif_at))
    pixels_at = exif_at + size_exif + size_exif % 2
    ifd0[273], ifd0[34665] = (4, [pixels_at]), (4, [exif_at])
    blob = b"II*\0" + struct.pack("<I", 8) + _ifd(ifd0, 8)
    blob = blob.ljust(exif_at, b"\0") + _ifd(exif, exif_at)
    blob = blob.ljust(pixels_at, b"\0") + mosaic.astype("<u2").tobytes()
    path.write_bytes(blob)


def mosaic_of(rgb_above_black: np.ndarray) -> np.ndarray:
    """(H, W) RGGB sensor values of an (H, W, 3) image of values above black (sensor units)."""
    m = np.empty(rgb_above_black.shape[:2])
    m[0::2, 0::2] = rgb_above_black[0::2, 0::2, 0]
    m[0::2, 1::2] = rgb_above_black[0::2, 1::2, 1]
    m[1::2, 0::2] = rgb_above_black[1::2, 0::2, 1]
    m[1::2, 1::2] = rgb_above_black[1::2, 1::2, 2]
    return np.clip(np.round(m + BLACK), 0, WHITE).astype(np.uint16)
