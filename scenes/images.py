"""The pixel files of an object folder and of predictions: images (16-bit / 8-bit PNG, float EXR), masks,
instance ids and normal maps, each read and written one way (every write through `scenes.files.atomic_write`).

Normal-map files: 16-bit PNG / TIFF `round((n + 1) / 2 * 65535)` (written with OpenCV in BGR order, so
RGB-aware readers get RGB), 8-bit PNG (DiLiGenT's `Normal_gt.png`, visualisations) `(n + 1) / 2 * 255`,
float EXR (channels R, G, B), `.npy` and MATLAB `.mat` holding n itself.

Every integer picture is decoded strictly (`decode_image`): OpenCV returns a truncated JPEG grey-filled and a TIFF
whose compressed data breaks off with the rows it could read; such a file is refused naming it.

Masks (`read_mask`) are binary: 0 outside the object and one other value on it, read from the alpha channel where
the file has one that is not fully opaque, else from the colour channels (their largest); see `read_mask`.
"""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import numpy as np

from scenes.exr import exr_channels, read_exr, write_exr
from scenes.files import atomic_write, caught_stderr, not_a_file
from scenes.tiff import check_tiff, read_planar_tiff

BACKGROUND_16 = 32768
"""Encoded value of n = 0 in a 16-bit normal map."""


def to_uint16(x: np.ndarray) -> np.ndarray:
    """Linear [0, 1] floats to uint16, clipped and rounded."""
    return np.round(np.clip(x, 0.0, 1.0) * 65535.0).astype(np.uint16)


def _imwrite(path: Path, image: np.ndarray, mkdir: bool = False) -> None:
    import cv2

    if mkdir:
        path.parent.mkdir(parents=True, exist_ok=True)

    # Encoded in memory and written by Python: cv2.imwrite reports success on a full disk (0-byte file).
    ok, data = cv2.imencode(path.suffix, image)
    if not ok:
        raise OSError(f"could not encode {str(path)!r} (unsupported extension {path.suffix!r})")
    atomic_write(path, lambda tmp: tmp.write_bytes(data.tobytes()))


def write_picture(path: str | Path, bgr: np.ndarray) -> None:
    """Write a picture for people (figure, contact sheet, error map: 8-bit BGR as OpenCV draws it; the format
    from the extension) atomically, detecting a full disk."""
    _imwrite(Path(path), np.ascontiguousarray(bgr), mkdir=True)


def write_png16(path: str | Path, rgb: np.ndarray) -> None:
    """(H, W, 3) float in [0, 1] or uint16 -> 16-bit RGB PNG (no gamma: linear values)."""
    data = rgb if rgb.dtype == np.uint16 else to_uint16(rgb)
    _imwrite(Path(path), np.ascontiguousarray(data[:, :, ::-1]))


def write_instances(path: str | Path, ids: np.ndarray) -> None:
    """(H, W) integer ids -> one-channel 16-bit PNG (`INSTANCES_FILE`)."""
    ids = np.asarray(ids)
    if ids.min(initial=0) < 0 or ids.max(initial=0) > 65535:
        raise ValueError(f"instance ids: expected values in [0, 65535], got [{ids.min()}, {ids.max()}]")
    _imwrite(Path(path), np.ascontiguousarray(ids.astype(np.uint16)), mkdir=True)


def read_instances(path: str | Path) -> np.ndarray:
    """(H, W) uint16 instance ids of `write_instances`."""
    img = _read_raw(Path(path), "instance-id")
    if img.ndim != 2 or img.dtype != np.uint16:
        raise ValueError(f"{path}: expected a one-channel 16-bit PNG of instance ids, got {img.dtype} {img.shape}")
    return img


JPEG_DAMAGE = ("Premature end of JPEG file", "Corrupt JPEG data")
"""How libjpeg (OpenCV's JPEG decoder) words its warnings about a file it could not decode whole: a truncated file,
damaged compressed data. OpenCV decodes such a file anyway, the missing part grey. (Its 'Corrupt JPEG data: bad ICC
marker' is about the colour profile, which is not read: not damage.)"""
_JPEG_MAGIC = b"\xff\xd8\xff"
_TIFF_MAGICS = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")
_NAMED_KINDS = {".jpg": ("a JPEG", b"\xff\xd8"), ".jpeg": ("a JPEG", b"\xff\xd8"), ".png": ("a PNG", b"\x89PNG"),
                ".tif": ("a TIFF", b"II", b"MM"), ".tiff": ("a TIFF", b"II", b"MM")}
"""What a file of each suffix must be, and how such a file begins: a file that begins otherwise (a WebP under a
.jpg name) is refused, not decoded; one that begins so but is damaged is the decoder's to refuse."""


def decode_image(path: Path, flags: int, where: str):
    """`cv2.imread(path, flags)` (the file's bytes decoded by `cv2.imdecode`), strictly: a JPEG whose decoder
    reports it truncated or corrupt (`JPEG_DAMAGE`), or a TIFF Pillow cannot decode whole, is a ValueError beginning
    with `where` (the flag and the file); None where OpenCV cannot read the file at all (the caller says so). What
    the decoders print about such a file is caught into the message; what they print about a file that is read is
    shown once, as a note naming it. PNG files are read whole or not at all (libpng fails on damage, and OpenCV
    returns None); other files are read as they are."""
    import cv2

    from scenes.checks import check_read_whole

    try:
        with open(path, "rb") as f:  # read here: OpenCV's own file reading crashes on a name that is not UTF-8
            check_read_whole(path, where, os.fstat(f.fileno()).st_size)
            data = np.frombuffer(f.read(), np.uint8)
    except OSError as exc:  # a folder, a file without read permission
        raise ValueError(f"{where} cannot be opened: {exc.strerror or exc}") from None
    if not data.size:
        raise ValueError(f"{where} is empty (0 bytes); expected an image (copy it again)")
    head = data[:8].tobytes()
    jpeg, tiff, png = head.startswith(_JPEG_MAGIC), head[:4] in _TIFF_MAGICS, head == b"\x89PNG\r\n\x1a\n"
    kind, *starts = _NAMED_KINDS.get(path.suffix.lower(), ("", b""))
    found = "a JPEG" if jpeg else "a TIFF" if tiff else "a PNG" if png else ""
    if kind and found and found != kind:  # what a name says is acted on (a TIFF read as linear, a JPEG's EXIF)
        raise ValueError(f"{where} is named as {kind} but is {found}; expected what its name says: name it as what it "
                         "is")
    if not (jpeg or tiff or png) and not head.startswith(tuple(starts)):  # e.g. WebP bytes in IMG_3.jpg
        raise ValueError(f"{where} is named as {kind} but is not one (its bytes begin {head[:4]!r}); expected what "
                         "its name says: convert it, or name it as what it is")
    actl = data[:data.tobytes().find(b"IDAT")].tobytes().find(b"acTL") if png else -1
    if actl >= 0 and int.from_bytes(data[actl + 4:actl + 8].tobytes(), "big") > 1:  # OpenCV reads frame 1 only
        raise ValueError(f"{where} is an animated PNG (several pictures); expected one picture per file")
    try:
        if not (jpeg or tiff or png):
            return cv2.imdecode(data, flags)
        with caught_stderr() as said:
            img = read_planar_tiff(path, flags) if tiff else None  # (OpenCV scrambles 16-bit and float ones)
            img = cv2.imdecode(data, flags) if img is None else img
            if tiff and img is not None:
                check_tiff(path, where)
    except cv2.error as exc:  # OpenCV's own refusals (a header declaring more pixels than it decodes)
        why = next((line.split("error: ", 1)[-1] for line in str(exc).splitlines() if "error:" in line), str(exc))
        limit = f"; expected an image of at most {2**30} pixels" if "MAX_IMAGE_PIXELS" in why else ""
        raise ValueError(f"{where} cannot be decoded ({why.strip()[:160]}){limit}") from None
    jpeg_damage = [line for line in said if any(d in line for d in JPEG_DAMAGE) and "bad ICC marker" not in line]
    if img is None and jpeg:  # decoded from memory, a JPEG cut short is refused whole (from a file: in part)
        raise ValueError(f"{where} is damaged: the JPEG decoder cannot decode it{' (' + said[0] + ')' if said else ''}"
                         " (a truncated or corrupt file); expected a complete JPEG (copy it again from the camera)")
    if img is not None and jpeg_damage:
        raise ValueError(f"{where} is damaged: the JPEG decoder says {'; '.join(dict.fromkeys(jpeg_damage))!r} (a "
                         "truncated or corrupt file, decoded only in part); expected a complete JPEG (copy it again "
                         "from the camera)")
    if img is None and said:  # not decoded, and the decoder said why (libpng: "PNG input buffer is incomplete")
        why = re.sub(r"^\[[^]]*\]\s*", "", said[0].strip())
        raise ValueError(f"{where} cannot be decoded (the decoder says {why[:160]!r}: a truncated or corrupt file?); "
                         "expected a complete image file")
    for line in dict.fromkeys(said):  # not about damage (libpng on an odd ICC profile): once per file, named
        if (str(path), line) not in _SHOWN:
            _SHOWN.add((str(path), line))
            print(f"note: {where}: {line.strip()}", file=sys.stderr)
    return img


_SHOWN: set[tuple[str, str]] = set()
"""(file, line) of what a decoder printed about a file it read, already shown (a photo is decoded more than once)."""


def _read_raw(path: Path, what: str = "image"):
    import cv2

    if path.is_dir():
        raise ValueError(f"{what} file {path} is a folder; expected an image file")
    if why := not_a_file(path):
        raise FileNotFoundError(f"{what} file {path} {why}")
    img = decode_image(path, cv2.IMREAD_UNCHANGED, f"{what} file {path}")
    if img is None:
        suffix = path.suffix.lower()
        if suffix in (".npy", ".npz", ".mat", ".exr", ".txt", ".json", ".csv"):  # not damaged: another kind of file
            raise ValueError(f"{what} file {path}: a {suffix} file, which is not read as an image here; expected "
                             "an image file (a PNG or TIFF)")
        raise ValueError(f"{what} file {path}: cannot be read (corrupt or unsupported format)")
    return img


def _check_float_image(img: np.ndarray, path: Path) -> np.ndarray:
    """A float image is radiance: finite and non-negative, or it is refused by name."""
    if not np.all(np.isfinite(img)):
        raise ValueError(f"image file {path}: contains NaN or infinite values")
    if np.any(img < 0):
        raise ValueError(f"image file {path}: has negative values (min {float(img.min()):.3g}); expected radiance >= 0")
    return img


def read_image(path: str | Path) -> np.ndarray:
    """Read one image as (H, W, 3) float32 linear RGB (uint16 / 65535, uint8 / 255, float EXR as is; gray
    repeated to RGB, alpha dropped). Float images must be finite and non-negative."""
    path = Path(path)
    if path.suffix.lower() == ".exr":
        if why := not_a_file(path):
            raise FileNotFoundError(f"image file {path} {why}")
        img = read_exr(path)
        img = np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img[:, :, :3]
        if img.shape[2] != 3:
            raise ValueError(f"image file {path}: expected a gray or RGB EXR, got {img.shape[2]} channels")
        return _check_float_image(np.ascontiguousarray(img, dtype=np.float32), path)
    img = _read_raw(path)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3]  # drop alpha
    elif img.ndim == 3 and img.shape[2] == 1:
        img = np.repeat(img, 3, axis=2)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"image file {path}: expected a gray, RGB or RGBA image, got shape {img.shape}")
    img = np.ascontiguousarray(img[..., ::-1])  # BGR -> RGB
    if img.dtype in (np.float32, np.float64):
        return _check_float_image(img.astype(np.float32), path)
    if img.dtype not in CODE_SCALES:
        raise ValueError(f"image file {path}: unsupported pixel type {img.dtype} (expected 8 or 16 bit)")
    return codes_to_linear(img)

CODE_SCALES = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}
"""Largest code of each integer pixel type: a file value v is the linear value v / scale."""


def codes_to_linear(codes: np.ndarray) -> np.ndarray:
    """Integer file values (uint8 / uint16, any shape) -> float32 in [0, 1]: the one conversion every reader of
    integer images uses (`read_image`, and decoded shards, `scenes.folder.shard_format`), so both give the same bits."""
    return codes.astype(np.float32) / CODE_SCALES[codes.dtype]


def write_mask(path: str | Path, mask: np.ndarray) -> None:
    """(H, W) bool -> 8-bit gray PNG, 255 inside, 0 outside."""
    _imwrite(Path(path), np.where(mask, 255, 0).astype(np.uint8))


MASK_ALPHA_RULE = ("a mask with an alpha channel is read from its alpha where the alpha is not fully opaque (some "
                   "pixel below the largest code), else from its colour; a colour mask from the largest of its "
                   "channels")
"""Which values of a mask file are its mask (docs/capture.md)."""
MASK_FAR_SHARE = 0.1
"""A mask with this share of its pixels or more in the middle half of its range (far from both 0 and its largest
value) is called a photo, a gradient or a blurred mask in the refusal; with fewer, soft edges (or, for a JPEG, the
values its compression adds along the edges)."""


def _mask_values(img: np.ndarray) -> tuple[np.ndarray, str]:
    """(H, W) values of a mask file as `MASK_ALPHA_RULE` says, and which of its channels they are (for messages)."""
    if img.ndim == 2:
        return img, ""
    channels = img.shape[2]
    if channels in (2, 4):
        alpha = img[..., channels - 1]
        top = np.iinfo(img.dtype).max if np.issubdtype(img.dtype, np.integer) else 1.0
        if np.any(alpha < top):
            return alpha, " (read from its alpha channel, which is not fully opaque)"
        img = img[..., : channels - 1]
        where = " (read from its colour: its alpha is fully opaque)"
    else:
        where = "" if channels == 1 else " (the largest of its colour channels)"
    return img.max(axis=2), where


def _distinct(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct values of a mask and how many pixels hold each (bincount for 8 and 16-bit files: np.unique
    sorts every pixel)."""
    if values.dtype in (np.uint8, np.uint16):
        counts = np.bincount(values.ravel(), minlength=1)
        found = np.flatnonzero(counts)
        return found.astype(values.dtype), counts[found]
    return np.unique(values, return_counts=True)


def read_mask(path: str | Path, shape: tuple[int, int] | None = None) -> np.ndarray:
    """(H, W) bool mask, True on the object; its size must be `shape` when given.

    Which values are read: `MASK_ALPHA_RULE`. They must be binary: 0 outside the object and one other value on it
    (any: 1, 255, 65535); one value everywhere is allowed only where it is the file's largest code (all white: the
    whole frame is the object). Anything else is a ValueError saying what was found: a background code other than
    0, a gradient or a photo, soft edges, the edge values a JPEG's compression adds (save masks as PNG), an empty
    mask.
    """
    path = Path(path)
    img = _read_raw(path, "mask")
    values, channel = _mask_values(img)
    where = f"mask file {path}{channel}"
    if shape is not None and values.shape != tuple(shape):
        raise ValueError(f"mask file {path}: size {values.shape[1]}x{values.shape[0]} (WxH) differs from the "
                         f"images' {shape[1]}x{shape[0]}")
    if np.issubdtype(values.dtype, np.floating) and not np.all(np.isfinite(values)):
        raise ValueError(f"{where}: holds NaN or infinite values; expected 0 outside the object and one other value "
                         "on it")
    found, counts = _distinct(values)
    top = np.iinfo(values.dtype).max if np.issubdtype(values.dtype, np.integer) else 1.0

    def shown(v) -> str:
        return f"{v:.6g}" if np.issubdtype(found.dtype, np.floating) else str(int(v))

    has_zero = bool(np.any(found == 0))
    if len(found) <= 2 and "colour" in channel and img.shape[2] >= 3:  # binary by the rule, yet colours that differ
        colours = img[..., :3].reshape(-1, 3)[values.ravel() > 0]
        other = colours[(colours != colours[0]).any(axis=1)] if len(colours) else colours
        if len(other):  # red on blue, or red and green on black: a label image, its meaning lost by the rule
            raise ValueError(f"{where}: holds colours {tuple(map(int, colours[0][::-1]))} and "
                             f"{tuple(map(int, other[0][::-1]))} (RGB), whose largest channel is the same; expected "
                             "the object white (or one colour) on black, not a label image of several parts")
    if len(found) == 2 and has_zero and found[-1] > 0:
        return values > 0
    if len(found) == 1 and has_zero:
        raise ValueError(f"{where}: is empty (0 everywhere, no pixel > 0)")
    if len(found) == 1 and found[0] == top:
        return np.ones(values.shape, dtype=bool)  # all white: the whole frame is the object
    expected = "expected 0 outside the object and one other value on it"
    if len(found) == 1:
        raise ValueError(f"{where}: is {shown(found[0])} everywhere; {expected} (all white, {shown(top)}, where the "
                         "object fills the frame)")
    if len(found) == 2 and not has_zero:
        raise ValueError(f"{where}: holds two values, {shown(found[0])} and {shown(found[1])}, and no 0: a background "
                         f"code of {shown(found[0])}?; {expected}")
    if len(found) == 2:
        raise ValueError(f"{where}: holds 0 and {shown(found[0])}; {expected}, above 0")
    lo, hi = float(found[0]), float(found[-1])
    far = float(counts[(found > lo + (hi - lo) / 4) & (found < hi - (hi - lo) / 4)].sum()) / values.size
    listed = ", ".join(shown(v) for v in found[:4]) + (f", ..., {shown(found[-1])}" if len(found) > 4 else "")
    with open(path, "rb") as f:
        jpeg = f.read(3) == _JPEG_MAGIC
    why = ("a photo, a gradient or a blurred mask?" if far >= MASK_FAR_SHARE else
           "a JPEG: its lossy compression adds values along the mask's edges; save the mask as PNG" if jpeg else
           "soft (blurred or anti-aliased) edges, or several labels?")
    raise ValueError(f"{where}: is not binary: {len(found)} distinct values ({listed}), {far:.0%} of the pixels in "
                     f"the middle half of their range: {why}; {expected}")


def check_normal_array(n: np.ndarray, what: str = "n") -> np.ndarray:
    """n as float32 (H, W, 3) after checking its shape and that it is finite."""
    n = np.asarray(n)
    if n.ndim != 3 or n.shape[2] != 3:
        raise ValueError(f"{what}: expected a normal map of shape (H, W, 3), got shape {n.shape}")
    if not np.issubdtype(n.dtype, np.number):
        raise ValueError(f"{what}: expected a numeric array, got dtype {n.dtype}")
    n = n.astype(np.float32)
    if not np.all(np.isfinite(n)):
        raise ValueError(f"{what}: normal map contains NaN or infinite values")
    return n


def _background(n: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels whose normal is exactly zero."""
    return ~np.any(n != 0, axis=2)


def encode_normals(n: np.ndarray) -> np.ndarray:
    """(H, W, 3) normals -> (H, W, 3) uint16 RGB, round((n + 1) / 2 * 65535), background (n = 0) 32768."""
    check_normal_array(n)
    n = np.asarray(n)
    n = n if np.issubdtype(n.dtype, np.floating) else n.astype(np.float32)  # float64 input stays float64
    enc = np.round((np.clip(n, -1.0, 1.0) + 1.0) * 0.5 * 65535.0).astype(np.uint16)
    enc[_background(n)] = BACKGROUND_16
    return enc


def decode_normal_image(img: np.ndarray, what: str) -> np.ndarray:
    """Decode an RGB integer normal image (uint8 or uint16) to float normals.

    Pixels whose decoded vector is shorter than 0.5 (the encoded zero vector, 32768 or 128) become 0.
    Float images are taken as n itself.
    """
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"{what}: expected a 3-channel normal image, got shape {img.shape}")
    if img.dtype == np.uint16:
        n = img.astype(np.float32) / 65535.0 * 2.0 - 1.0
    elif img.dtype == np.uint8:
        n = img.astype(np.float32) / 255.0 * 2.0 - 1.0
    elif np.issubdtype(img.dtype, np.floating):
        n = img.astype(np.float32)
    else:
        raise ValueError(f"{what}: unsupported normal image dtype {img.dtype} (expected uint8, uint16 or float)")
    if np.issubdtype(img.dtype, np.integer):
        n[np.linalg.norm(n, axis=2) < 0.5] = 0.0
    return n


def write_normal_map(path: str | Path, n: np.ndarray) -> None:
    """Write a 16-bit RGB normal map (PNG or TIFF, chosen by the extension; `normal.tif` of the folder)."""
    _imwrite(Path(path), np.ascontiguousarray(encode_normals(n)[..., ::-1]), mkdir=True)  # OpenCV writes BGR


def write_normal_exr(path: str | Path, n: np.ndarray) -> None:
    """Write normals as a float32 OpenEXR file with channels R, G, B."""
    n = check_normal_array(n)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_exr(path, n)


def normal_visual(n: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 RGB picture of the normals, (n + 1) / 2, background black."""
    n = check_normal_array(n)
    vis = np.round((np.clip(n, -1.0, 1.0) + 1.0) * 0.5 * 255.0).astype(np.uint8)
    vis[_background(n)] = 0
    return vis


def write_normal_visual(path: str | Path, n: np.ndarray) -> None:
    """Write an 8-bit RGB picture of the normals, (n + 1) / 2, background black."""
    _imwrite(Path(path), np.ascontiguousarray(normal_visual(n)[..., ::-1]), mkdir=True)


def _read_mat(path: Path, arg: str = "normal map") -> np.ndarray:
    import scipy.io

    try:
        data = scipy.io.loadmat(str(path))
    except Exception as exc:
        raise ValueError(f"{arg}: cannot read MAT file {path}: {exc}") from exc
    arrays = {k: v for k, v in data.items() if not k.startswith("__")}
    key = next((k for k in ("Normal_gt", "normal", "normals", "Normal_est", "N") if k in arrays),
               next(iter(arrays)) if len(arrays) == 1 else None)
    if key is None:
        raise ValueError(f"{arg}: MAT file {path} has no 'Normal_gt' key and several arrays "
                         f"{', '.join(sorted(arrays))}")
    n = np.asarray(arrays[key])
    if n.dtype.kind not in "fiu":  # complex, logical, a cell or a struct: no real vectors to take
        kind = {"c": f"{n.dtype} (complex) values", "O": "a cell array", "V": "a struct", "b": "logical values"}.get(
            n.dtype.kind, f"{n.dtype} values")
        raise ValueError(f"{arg}: MAT file {path}: {key!r} is {kind}; expected real numbers (the x, y, z of each "
                         "pixel)")
    return n.astype(np.float32)


def read_normals(path: str | Path, arg: str = "normal map") -> np.ndarray:
    """Read a normal map: .png/.tif/.tiff (8 or 16 bit), .exr, .npy, .mat.

    Returns (H, W, 3) float32; background pixels are 0. Raises FileNotFoundError for a missing file,
    ValueError for unreadable files, wrong shapes or non-finite values; each message starts with `arg`, the flag
    the file came from (a CLI passes its own, e.g. --pred).
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{arg}: normal map {path} is a folder; expected a normal map file")
    if why := not_a_file(path):
        raise FileNotFoundError(f"{arg}: normal map {path} {why}")
    suffix = path.suffix.lower()
    if suffix in (".png", ".tif", ".tiff"):
        import cv2

        img = decode_image(path, cv2.IMREAD_UNCHANGED, f"{arg}: image file {path}")
        if img is None:
            raise ValueError(f"{arg}: cannot read image file {path} (corrupt or unsupported)")
        if img.ndim != 3 or img.shape[2] not in (3, 4):
            raise ValueError(f"{arg}: normal image {path} must be RGB, got shape {'x'.join(map(str, img.shape))}")
        n = decode_normal_image(np.ascontiguousarray(img[..., 2::-1]), f"{arg} {path}")
    elif suffix == ".exr":
        try:
            ch = exr_channels(path)
        except ValueError as exc:
            raise ValueError(f"{arg}: cannot read EXR file {path}: {exc}") from exc
        missing = [c for c in "RGB" if c not in ch]
        if missing:
            raise ValueError(
                f"{arg}: EXR file {path} lacks channels {', '.join(missing)} (has {', '.join(sorted(ch))})"
            )
        n = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float32)
    elif suffix == ".npy":
        from scenes.checks import check_read_whole

        check_read_whole(path, f"{arg}: NPY file {path}")
        try:
            n = np.load(path, allow_pickle=False)
        except Exception as exc:
            raise ValueError(f"{arg}: cannot read NPY file {path}: {exc}") from exc
        if n.dtype.kind != "f":  # integer codes are an encoded map's (a PNG's), not vectors
            raise ValueError(f"{arg}: NPY file {path} holds {n.dtype} values; expected float unit vectors (x, y, z) "
                             "(an 8 or 16-bit encoded map belongs in a PNG)")
    elif suffix == ".mat":
        n = _read_mat(path, arg)
    else:
        raise ValueError(f"{arg}: unsupported normal-map extension {suffix!r} for {path} "
                         "(expected .png, .tif, .tiff, .exr, .npy or .mat)")
    return check_normal_array(n, f"{arg}: normal map {path}" if arg != "normal map" else f"normal map {path}")


UNIT_TOLERANCE = 0.02
"""The one bound on | |n| - 1 | for the vectors of a normal map given as floats, wherever one is read (scored:
`check_unit_length`; judged: `validate.io.check_normals`; integrated: `scenes.surface.inputs.check_normals`).
16-bit PNG rounding stays below 1e-4 and 8-bit below 0.01; a map scaled by mistake (by 5 %: sweep 33), (n + 1) / 2
saved as floats or an unnormalised output lies beyond it, and would be scored, judged or integrated as if its
vectors were directions. (Ground-truth files of any scale are normalised by their readers.)"""


def check_unit_length(n: np.ndarray, what: str, encoded: bool = False) -> None:
    """Refuse a normal map (H, W, 3) to score whose nonzero vectors are not of unit length (their median
    further than `UNIT_TOLERANCE` from 1); `encoded`: decoded from an 8 or 16-bit image (n + 1) / 2."""
    lengths = np.linalg.norm(n.astype(np.float64), axis=-1)
    lengths = lengths[lengths > 0]
    if lengths.size and abs(float(np.median(lengths)) - 1.0) > UNIT_TOLERANCE:
        hint = ("codes (n + 1) / 2 over the file's whole range: 8-bit codes in a 16-bit file decode near (-1, -1, -1)"
                if encoded else "unit normals x, y, z in [-1, 1] (an encoded map (n + 1) / 2 belongs in a PNG)")
        raise ValueError(f"{what}: its vectors are not of unit length (median {float(np.median(lengths)):.3g}); "
                         f"expected {hint}")
