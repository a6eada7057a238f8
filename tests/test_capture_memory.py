"""`orchestrate.capture` works on the photos in memory: the channels the files say are clipped reach the fit as
clipped (lower bounds), even where the exposure normalisation and the command's scaling moved them far below the
largest value, where a clip can no longer be told from the values."""

from __future__ import annotations

import json

import numpy as np
from fixtures import sphere

from scenes.images import write_mask

SIZE = 64
EXPOSURES_S = (0.01, 0.01, 0.01, 0.01, 0.02, 0.02, 0.02, 0.02)
"""The last four photos were taken at twice the exposure time: their lit half clips in the file."""


def _to_light(polar_deg: float, azimuth_deg: float) -> np.ndarray:
    p, a = np.radians(polar_deg), np.radians(azimuth_deg)
    return np.array([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)])


def _write_photo(path, linear: np.ndarray, exposure_s: float) -> None:
    """An 8-bit sRGB JPEG (IEC 61966-2-1 written out) carrying its exposure time and ISO in EXIF."""
    from PIL import Image

    c = np.where(linear <= 0.0031308, linear * 12.92, 1.055 * np.clip(linear, 0, 1) ** (1 / 2.4) - 0.055)
    img = Image.fromarray(np.round(np.clip(c, 0, 1) * 255).astype(np.uint8))
    exif = img.getexif()
    ifd = exif.get_ifd(0x8769)
    ifd[0x829A], ifd[0x8827] = exposure_s, 100
    img.save(path, exif=exif, quality=100)


def test_a_clipped_channel_of_an_exposure_rescaled_photo_stays_a_lower_bound(tmp_path, variant_llvm_ad_rgb):
    from orchestrate.capture import main
    from scenes.folder.photos import read_photos

    n, mask = sphere(SIZE)
    folder = tmp_path / "shoot"
    folder.mkdir()
    for i, t in enumerate(EXPOSURES_S):
        shading = np.clip(n @ _to_light(45, 45 * i), 0, None) * 0.6 * mask
        radiance = np.repeat(shading[..., None], 3, -1) * (t / EXPOSURES_S[0])  # what the sensor collected
        _write_photo(folder / f"IMG_{i + 1:04d}.jpg", radiance, t)
    write_mask(tmp_path / "mask.png", mask)

    photos = read_photos(folder)
    clipped = photos.saturated[:, mask]
    assert [e["scale"] for e in photos.exposure] == [1.0] * 4 + [0.5] * 4
    assert not clipped[:4].any() and clipped[4:].mean() > 0.1  # only the long exposures clip
    # After the exposure normalisation and the command's scaling (brightest mask value -> 1), the clipped
    # channels sit near 0.5, nowhere near the largest value: values alone would take them as measurements.
    scaled = photos.images[:, mask] / photos.images[:, mask].max()
    assert scaled[clipped].max() < 0.9

    out = tmp_path / "out"
    assert main(["--input", str(folder), "--out", str(out), "--mask", str(tmp_path / "mask.png"), "--no-refine",
                 "--threads", "1"]) == 0
    check = json.loads((out / "check" / "shoot" / "report.json").read_text())
    assert check["fit_downsample"] == 1
    # The fit's censored observations are exactly the files' clipped channels.
    assert check["saturated_fraction"] == np.float64(clipped.mean()).item()
    assert not (out / "work").exists()  # the photos are not written back to disk unless asked (--keep-work)
