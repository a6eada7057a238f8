"""What OpenCV gets wrong about TIFF files, for `scenes.images.decode_image` (every TIFF the toolkit reads: photos,
normal maps, textures, environment maps): a file it reads only in part, or the first of several pictures
(`check_tiff`, by Pillow), and a 16-bit or float file whose channels are stored one plane after another
(planar configuration 2), whose pixels it scrambles (`read_planar_tiff`, by tifffile)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def read_planar_tiff(path: Path, flags: int) -> np.ndarray | None:
    """The picture of a TIFF whose several channels are stored as separate planes, or of grey and alpha (OpenCV
    drops that alpha and makes 16 bits 8), laid out as `cv2.imdecode` gives a picture (H, W, C in BGR(A) order, grey
    repeated, the file's type; the alpha dropped unless `flags` is IMREAD_UNCHANGED); None for any other TIFF
    (OpenCV reads those right) or one tifffile cannot read (OpenCV's reading stands)."""
    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            grey_alpha = page.samplesperpixel == 2
            if not grey_alpha and (page.planarconfig != tifffile.PLANARCONFIG.SEPARATE or page.samplesperpixel < 3):
                return None
            pixels = page.asarray()  # (C, H, W) planar, (H, W, C) contiguous
            separate = page.planarconfig == tifffile.PLANARCONFIG.SEPARATE
    except (tifffile.TiffFileError, OSError, ValueError, IndexError, RuntimeError):
        return None
    if pixels.ndim != 3:
        return None
    img = np.moveaxis(pixels, 0, -1) if separate else pixels  # (H, W, C) RGB(A), or grey and alpha
    if grey_alpha:
        img = img[..., [0, 0, 0, 1]]
    img = img[..., [2, 1, 0, *range(3, img.shape[-1])]]  # OpenCV's BGR(A)
    return np.ascontiguousarray(img if flags < 0 else img[..., :3])


def check_tiff(path: Path, where: str) -> None:
    """A ValueError beginning with `where` when Pillow cannot decode the TIFF `path` whole (OpenCV returns the rows
    it could read) or finds several pictures in it; nothing where it decodes, or is of a kind Pillow does not read
    (OpenCV's reading stands)."""
    from PIL import Image, UnidentifiedImageError

    try:
        img = Image.open(path)
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError):
        return
    with img:
        if getattr(img, "n_frames", 1) > 1:  # OpenCV reads page 1 only (a camera's smaller preview page is no picture)
            sizes = [img.seek(i) or img.size for i in range(img.n_frames)]
            img.seek(0)
            big = max(sizes, key=lambda size: size[0] * size[1])
            if sizes.count(sizes[0]) > 1 or big != sizes[0]:
                raise ValueError(f"{where} holds {len(sizes)} pages, the first {sizes[0][0]}x{sizes[0][1]} px and the "
                                 f"largest {big[0]}x{big[1]} px; expected one picture per file (a smaller preview page "
                                 "after it)")
        try:
            img.load()
        except OSError as exc:
            if "not available" not in str(exc):
                said = str(exc) or type(exc).__name__
                raise ValueError(f"{where} is damaged: the TIFF decoder says {said!r} (a truncated or corrupt file, "
                                 "readable only in part); expected a complete TIFF") from None
        except (SyntaxError, ValueError):  # a layout Pillow does not support
            return


