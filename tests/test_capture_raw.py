"""Camera RAW files in `orchestrate.capture`: tiny DNG files written here byte by byte (a Bayer RGGB mosaic in
IFD0, the DNG tags LibRaw needs, exposure time and ISO in an EXIF IFD), read by the real rawpy / LibRaw.

Expectations come from the DNG specification and the numbers written into the file, not from the code under test:
the camera is given the colour matrix of linear sRGB (ColorMatrix1 = the inverse of the sRGB-to-XYZ matrix), so the
camera's white-balanced colours are linear sRGB already and each output channel is analytic:
(raw - black) / (white - black) x (white-balance multiplier / the largest multiplier), the multipliers being the
reciprocals of AsShotNeutral."""
from __future__ import annotations

import json

import numpy as np
import pytest
from dng import BLACK, NEUTRAL, WHITE, mosaic_of, write_dng

from scenes.folder.photos import read_photos

MULT = np.array([1 / n for n in NEUTRAL])
GAIN = MULT / MULT.max()
"""What LibRaw's unclipped scaling multiplies each channel by (the largest multiplier reaches 1 at the white level)."""
H, W = 24, 32  # LibRaw refuses a raw image under 22 pixels on a side


def flat(level: float) -> np.ndarray:
    """A grey patch (the camera's white times `level`, in sensor units above black) filling the frame."""
    return mosaic_of(np.broadcast_to(np.array(NEUTRAL) * level, (H, W, 3)))


# ------------------------------------------------------------------------------------------ reading RAW files


def test_a_grey_patch_comes_out_linear_white_balanced_and_recorded(tmp_path):
    import rawpy

    for i, level in enumerate([400, 800, 1600]):
        write_dng(tmp_path / f"IMG_{i + 1}.DNG", flat(level))
    photos = read_photos(tmp_path)
    assert photos.names == ["IMG_1.DNG", "IMG_2.DNG", "IMG_3.DNG"] and photos.encoding == ["linear"] * 3
    assert photos.bit_depth == 16 and photos.images.shape == (3, H, W, 3)
    # black subtracted, white balanced to grey, white level at 1 for the most amplified channel
    expect = [level * min(NEUTRAL) / (WHITE - BLACK) for level in (400, 800, 1600)]
    for img, e in zip(photos.images, expect):
        np.testing.assert_allclose(img, e, atol=1.5 / 65535)
    # doubling the value above black doubles the output
    np.testing.assert_allclose(photos.images[1], 2 * photos.images[0], atol=2 / 65535)
    np.testing.assert_allclose(photos.images[2], 2 * photos.images[1], atol=2 / 65535)
    assert not photos.saturated.any()
    rec = photos.raw[0]
    assert rec["white_balance"][:3] == pytest.approx([1 / n for n in NEUTRAL], rel=1e-4)
    assert rec["white_balance_from"].startswith("camera") and rec["channels"] == "RGBG"
    assert rec["black_level"] == [BLACK] * 4 and rec["white_level"] == WHITE
    assert rec["demosaic"] == "linear" and rec["color_space"].startswith("linear sRGB")
    assert rec["rawpy"] == rawpy.__version__ and rec["libraw"] == ".".join(map(str, rawpy.libraw_version))


def test_each_channel_is_linear_and_a_clipped_sensor_value_is_saturated(tmp_path):
    """A colour ramp: each channel is (raw - black) / (white - black) x its gain; a sensor value at the white level
    marks its pixel and the neighbours the demosaic takes it from."""
    y, x = np.mgrid[0:H, 0:W]
    rgb = np.stack([40 + 60 * x, 30 + 50 * y, 1000 + 0 * x], -1).astype(float)  # sensor units above black
    m = mosaic_of(rgb)
    m[10, 20] = WHITE  # one clipped green sensor value
    write_dng(tmp_path / "a.dng", m)
    write_dng(tmp_path / "b.dng", mosaic_of(rgb))
    photos = read_photos(tmp_path)
    out = photos.images[1]
    # the linear demosaic interpolates a linear ramp exactly away from the border
    expect = rgb / (WHITE - BLACK) * GAIN
    np.testing.assert_allclose(out[2:-2, 2:-2], expect[2:-2, 2:-2], atol=4 / 65535)  # 16-bit steps inside LibRaw
    sat = photos.saturated[0].all(-1)
    assert sat[9:12, 19:22].all() and sat.sum() == 9 and not photos.saturated[1].any()


@pytest.mark.parametrize("orientation, turn", [(3, 2), (6, -1), (8, 1)])
def test_the_recorded_orientation_is_applied(tmp_path, orientation, turn):
    """TIFF orientation 6: the camera was turned 90 degrees clockwise, so the picture is turned back (np.rot90 k=-1);
    8 the other way, 3 upside down. Left half bright, one clipped block at the top left: both follow the turn."""
    rgb = np.broadcast_to(np.array(NEUTRAL) * 300, (H, W, 3)).copy()
    rgb[:, : W // 2] *= 4
    m = mosaic_of(rgb)
    m[2:4, 2:4] = WHITE
    for name, o in [("upright.dng", 1), ("turned.dng", orientation)]:
        (tmp_path / name[:-4]).mkdir()
        write_dng(tmp_path / name[:-4] / name, m, orientation=o)
    upright, turned = read_photos(tmp_path / "upright"), read_photos(tmp_path / "turned")
    np.testing.assert_array_equal(turned.images[0], np.rot90(upright.images[0], k=turn))
    np.testing.assert_array_equal(turned.saturated[0], np.rot90(upright.saturated[0], k=turn))
    assert upright.saturated[0, 1:5, 1:5].all() and upright.saturated[0].all(-1).sum() == 16
    assert upright.images[0, H // 2, 4] == pytest.approx(4 * upright.images[0, H // 2, W - 4], rel=1e-3)


def test_exposure_and_iso_normalise_raw_files_and_are_recorded(tmp_path):
    write_dng(tmp_path / "p1.dng", flat(500), exposure_s=1 / 100, iso=100)
    write_dng(tmp_path / "p2.dng", flat(1000), exposure_s=1 / 50, iso=100)  # twice the light, twice the value
    write_dng(tmp_path / "p3.dng", flat(2000), exposure_s=1 / 50, iso=200)
    photos = read_photos(tmp_path)
    assert [e["scale"] for e in photos.exposure] == [1.0, 0.5, 0.25]
    assert photos.exposure[1]["exposure_time_s"] == 0.02 and photos.exposure[2]["iso"] == 200
    np.testing.assert_allclose(photos.images[1], photos.images[0], atol=2 / 65535)
    np.testing.assert_allclose(photos.images[2], photos.images[0], atol=2 / 65535)
    (tmp_path / "no_exif").mkdir()
    for i in range(2):
        write_dng(tmp_path / "no_exif" / f"{i}.dng", flat(500), exposure_s=1 / 100 if i else None)
    exposure = read_photos(tmp_path / "no_exif").exposure
    assert exposure[0] == {"not_in_file": ["exposure_time_s", "iso"], "scale": 1.0}
    assert exposure[1] == {"exposure_time_s": 0.01, "not_in_file": ["iso"], "scale": 1.0}


def test_a_file_without_white_balance_says_what_was_used(tmp_path):
    write_dng(tmp_path / "a.dng", flat(500), neutral=None)
    rec = read_photos(tmp_path).raw[0]
    assert rec["white_balance_from"].startswith("LibRaw's daylight") and len(rec["white_balance"]) == 4


def test_bad_raw_folders_are_one_line_naming_the_flag_and_the_file(tmp_path, capfd):
    def refused(folder, pattern, encoding="auto"):
        with pytest.raises(ValueError, match=pattern) as err:
            read_photos(folder, encoding)
        assert "\n" not in str(err.value)

    write_dng(tmp_path / "a.dng", flat(500))
    write_dng(tmp_path / "b.dng", mosaic_of(np.full((H + 2, W, 3), 500.0)))
    refused(tmp_path, r"^--input: b.dng differs in size from a.dng \(32x26 16-bit, expected 32x24 16-bit\)")
    write_dng(tmp_path / "b.dng", flat(500), orientation=6)
    refused(tmp_path, r"^--input: b.dng differs in orientation from a.dng")
    (tmp_path / "b.dng").write_bytes(b"not a raw file at all" * 10)
    refused(tmp_path, r"^--input: cannot read '.*b.dng' as a camera RAW file \(.+\); expected a RAW file LibRaw")
    blob = (tmp_path / "a.dng").read_bytes()
    (tmp_path / "b.dng").write_bytes(blob[: len(blob) - 600])  # the pixels cut short
    refused(tmp_path, r"^--input: cannot read '.*b.dng' as a camera RAW file \(.*Unexpected end of file")
    assert capfd.readouterr().err == ""  # LibRaw's own complaint went into the one line, not to the terminal
    write_dng(tmp_path / "b.dng", flat(500), white=200)  # no range above the black level (256): all would be 0
    refused(tmp_path, r"^--input: '.*b.dng' says its white level 200 is at or below its black level 256")
    write_dng(tmp_path / "b.dng", flat(500))
    refused(tmp_path, r"^--input-encoding: got 'srgb' for camera RAW files \(a.dng, ...\)", "srgb")
    assert read_photos(tmp_path, "linear").images.shape == (2, H, W, 3)
    (tmp_path / "c.JPG").write_bytes(b"")
    refused(tmp_path, r"^--input: .* mixes camera RAW files \(a.dng\) with other photos \(c.JPG\)")


def test_raw_photos_reach_the_report_and_bad_ones_stop_the_command_in_one_line(tmp_path, capsys):
    """The whole command up to its first check: report.json is not written for three images, so the reading
    is checked through `read_input` (what main records) and main's one-line refusals."""
    from orchestrate.capture import CaptureOptions, main, probe_input, read_input

    (tmp_path / "in").mkdir()
    for i in range(3):
        write_dng(tmp_path / "in" / f"{i}.dng", flat(400 + 100 * i), exposure_s=1 / 100, iso=100, orientation=6)
    opts = CaptureOptions(input=str(tmp_path / "in"), out=str(tmp_path / "o"))
    assert probe_input(opts) == (3, W, H, (W, H))
    source = read_input(opts).meta["input"]
    json.dumps(source)  # report.json takes it as it is
    assert source["bit_depth"] == 16 and len(source["raw"]) == 3 and source["raw"][0]["orientation_flip"] == 6
    (tmp_path / "in" / "2.dng").write_bytes(b"\0" * 100)
    assert main(["--input", str(tmp_path / "in"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --input: cannot read") and "2.dng" in err[0]
    assert main(["--input", str(tmp_path / "in"), "--out", str(tmp_path / "o"), "--input-encoding", "srgb"]) == 2
    assert capsys.readouterr().err.startswith("error: --input-encoding: got 'srgb' for camera RAW files")


def test_square_raw_files_turned_differently_are_refused(tmp_path):
    """The camera turned for one photo of a square frame: the shapes agree, LibRaw's flips do not (issue 50)."""
    square = mosaic_of(np.broadcast_to(np.array(NEUTRAL) * 500, (W, W, 3)))
    write_dng(tmp_path / "a.dng", square)
    write_dng(tmp_path / "b.dng", square, orientation=6)
    with pytest.raises(ValueError, match=r"^--input: b.dng differs in orientation from a.dng \(it is to be shown "
                                         r"LibRaw flip 6, a.dng LibRaw flip 0\)"):
        read_photos(tmp_path)
    write_dng(tmp_path / "a.dng", square, orientation=6)
    assert read_photos(tmp_path).images.shape == (2, W, W, 3)  # turned alike: read, both turned back
