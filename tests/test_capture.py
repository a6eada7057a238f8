"""Users' own photos (`orchestrate.capture`): the photo reader, the capture checks, the automatic mask and the
whole command on real files. Expectations come from the geometry and from the sRGB standard written out here,
not from the code under test."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from fixtures import interruptible, shading, sphere

from scenes.folder.photos import read_photos
from validate.diagnosis.usable import auto_mask, capture_warnings


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1, written out."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def lights(polars, azimuths) -> np.ndarray:
    p, a = np.radians(polars), np.radians(azimuths)
    return np.stack([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)], -1)


def lambertian(n: np.ndarray, mask: np.ndarray, L: np.ndarray, albedo: float = 0.6) -> np.ndarray:
    """(K, H, W, 3) float32 shading of normals under distant lights, black off the object."""
    img = shading(n, L) * albedo * mask
    return np.repeat(img[..., None], 3, -1).astype(np.float32)


SPREAD = lights([40, 50, 35, 45, 40, 55, 30, 45], np.arange(8) * 45)
FRONTAL = lights([5, 10, 15, 12, 8, 15, 3, 14], np.arange(8) * 45)
ONE_SIDE = lights([40, 50, 30, 45, 35, 55], [-50, -20, 0, 20, 40, 60])


def write_jpegs(folder, images: np.ndarray, names=None) -> list:
    folder.mkdir(parents=True, exist_ok=True)
    names = names or [f"IMG_{i + 1:04d}.jpg" for i in range(len(images))]
    for name, img in zip(names, images):
        c = np.where(img <= 0.0031308, img * 12.92, 1.055 * np.clip(img, 0, 1) ** (1 / 2.4) - 0.055)
        cv2.imwrite(str(folder / name), np.round(np.clip(c, 0, 1) * 255).astype(np.uint8)[..., ::-1],
                    [cv2.IMWRITE_JPEG_QUALITY, 98])
    return names


# ------------------------------------------------------------------------------------------ reading photos


def test_eight_bit_files_are_srgb_sixteen_bit_and_exr_linear_in_natural_order(tmp_path, np_rng):
    from scenes.images import write_exr

    codes8 = np_rng.integers(0, 256, (3, 5, 7, 3), dtype=np.uint8)
    for i, name in enumerate(["img_10.png", "IMG_2.png", "img_1.png"]):
        cv2.imwrite(str(tmp_path / name), codes8[i][..., ::-1])
    photos = read_photos(tmp_path)
    assert photos.names == ["img_1.png", "IMG_2.png", "img_10.png"] and photos.encoding == ["srgb"] * 3
    np.testing.assert_allclose(photos.images[0], srgb_to_linear(codes8[2] / 255.0), atol=1e-6)
    assert read_photos(tmp_path, "linear").images[0] == pytest.approx(codes8[2] / 255.0, abs=1e-7)

    d16 = tmp_path / "sixteen"
    d16.mkdir()
    codes16 = np_rng.integers(0, 65536, (2, 5, 7, 3), dtype=np.uint16)
    for i in range(2):
        cv2.imwrite(str(d16 / f"{i}.tif"), codes16[i][..., ::-1])
    photos = read_photos(d16)
    assert photos.bit_depth == 16 and photos.encoding == ["linear"] * 2
    np.testing.assert_array_equal(photos.images, (codes16 / 65535.0).astype(np.float32))
    assert photos.saturated.sum() == (codes16 == 65535).sum()

    dexr = tmp_path / "exr"
    dexr.mkdir()
    values = np_rng.random((2, 5, 7, 3)).astype(np.float32) * 3
    for i in range(2):
        write_exr(dexr / f"{i}.exr", values[i])
    np.testing.assert_array_equal(read_photos(dexr).images, values)


def _png_with_chunk(path, codes: np.ndarray, kind: bytes, data: bytes) -> None:
    """A PNG of `codes` (OpenCV's encoder) with one more chunk after its header (IHDR: 8 + 25 bytes in)."""
    import struct
    import zlib

    ok, buf = cv2.imencode(".png", codes[..., ::-1])
    raw = buf.tobytes()
    chunk = struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    path.write_bytes(raw[:33] + chunk + raw[33:])


def test_what_libpng_says_of_a_png_it_reads_is_one_note_naming_the_file(tmp_path, capfd):
    """libpng's warnings (an ICC profile of the XYZ colour space in a photo) went to the terminal as bare lines, one
    per decode, naming no file (sweep 19); now one note per file and line, naming it."""
    import struct
    import zlib

    from scenes.images import decode_image

    profile = bytearray(128)  # an ICC header whose colour space is 'XYZ ' (an RGB image needs an 'RGB ' profile)
    profile[0:4], profile[12:16], profile[16:20], profile[36:40] = struct.pack(">I", 128), b"mntr", b"XYZ ", b"acsp"
    _png_with_chunk(tmp_path / "a.png", np.full((4, 5, 3), 90, np.uint8), b"iCCP",
                    b"ICC Profile\0\0" + zlib.compress(bytes(profile)))
    for _ in range(2):  # read twice (a capture reads each photo's size first)
        assert decode_image(tmp_path / "a.png", cv2.IMREAD_COLOR, "--input: 'a.png'").shape == (4, 5, 3)
    err = capfd.readouterr().err
    lines = err.strip().splitlines()
    assert lines and all(line.startswith("note: --input: 'a.png': libpng warning: ") for line in lines), err
    assert len(lines) == len(set(lines)), err


def test_a_png_says_its_own_curve(tmp_path, np_rng):
    """A PNG's sRGB or gAMA chunk decides the curve in auto mode (a 16-bit sRGB PNG, an 8-bit linear one); a gamma
    that is neither is refused naming the file; --input-encoding still decides for all files."""
    import struct

    codes16 = np_rng.integers(0, 65536, (2, 5, 7, 3), dtype=np.uint16)
    codes8 = np_rng.integers(0, 256, (2, 5, 7, 3), dtype=np.uint8)
    folders = {name: tmp_path / name for name in ("srgb16", "linear8", "gamma07", "gamma0")}
    for i in range(2):
        for f in folders.values():
            f.mkdir(exist_ok=True)
        _png_with_chunk(folders["srgb16"] / f"{i}.png", codes16[i], b"sRGB", bytes([0]))
        _png_with_chunk(folders["linear8"] / f"{i}.png", codes8[i], b"gAMA", struct.pack(">I", 100000))
        _png_with_chunk(folders["gamma07"] / f"{i}.png", codes8[i], b"gAMA", struct.pack(">I", 70000))
        _png_with_chunk(folders["gamma0"] / f"{i}.png", codes8[i], b"gAMA", struct.pack(">I", 0))  # a damaged chunk
    photos = read_photos(folders["srgb16"])
    assert photos.encoding == ["srgb"] * 2
    np.testing.assert_allclose(photos.images[0], srgb_to_linear(codes16[0] / 65535.0), atol=1e-5)
    photos = read_photos(folders["linear8"])
    assert photos.encoding == ["linear"] * 2 and photos.images[1] == pytest.approx(codes8[1] / 255.0, abs=1e-7)
    with pytest.raises(ValueError, match=r"--input: .*0\.png' declares gamma 0\.7 .*--input-encoding"):
        read_photos(folders["gamma07"])
    assert read_photos(folders["gamma07"], "srgb").encoding == ["srgb"] * 2
    with pytest.raises(ValueError, match=r"--input: .*0\.png' declares gamma 0\.0 \(invalid\)"):
        read_photos(folders["gamma0"])
    mixed = tmp_path / "mixed"  # one file says sRGB, the other nothing (16-bit: linear)
    mixed.mkdir()
    _png_with_chunk(mixed / "0.png", codes16[0], b"sRGB", bytes([0]))
    cv2.imwrite(str(mixed / "1.png"), codes16[1][..., ::-1])
    with pytest.raises(ValueError, match=r"1.png is read as linear and 0.png as srgb .*--input-encoding"):
        read_photos(mixed)


def _jpeg_with_exif(path, a: np.ndarray, orientation: int = 1, exposure_s: float | None = None,
                    iso: int | None = 100) -> None:
    """A JPEG of `a` with EXIF orientation, and exposure time and ISO where given (None: the tag is left out)."""
    from PIL import Image

    img = Image.fromarray(a)
    exif = img.getexif()
    exif[0x0112] = orientation
    if exposure_s is not None:
        ifd = exif.get_ifd(0x8769)
        ifd[0x829A] = exposure_s
        if iso is not None:
            ifd[0x8827] = iso
    img.save(path, exif=exif, quality=100)


def test_exif_orientation_and_exposure_are_applied(tmp_path):
    a = (np.random.default_rng(1).random((6, 9, 3)) * 200 + 20).astype(np.uint8)
    (tmp_path / "upright").mkdir()
    (tmp_path / "turned").mkdir()
    for i in range(2):
        _jpeg_with_exif(tmp_path / "upright" / f"p{i}.jpg", a, 1, exposure_s=0.01 * (i + 1))
        _jpeg_with_exif(tmp_path / "turned" / f"p{i}.jpg", a, 6)  # the camera held turned 90 deg clockwise
    upright, turned = read_photos(tmp_path / "upright"), read_photos(tmp_path / "turned")
    assert turned.images.shape == (2, 9, 6, 3)
    np.testing.assert_array_equal(turned.images[0], np.rot90(upright.images[0], k=-1))
    # the second photo had twice the exposure: brought to the first's
    np.testing.assert_allclose(upright.images[1], upright.images[0] * 0.5, rtol=1e-6)
    assert [e["scale"] for e in upright.exposure] == [1.0, 0.5] and upright.exposure[1]["exposure_time_s"] == 0.02
    assert [e["scale"] for e in turned.exposure] == [1.0, 1.0]


@pytest.mark.parametrize("written", ["ifd0", "apex"])
def test_an_exposure_written_in_ifd0_or_as_apex_values_is_read(tmp_path, written):
    """Sweep 24: ExposureTime and FNumber in IFD0 (TIFF/EP writers put them there), or only as APEX values
    (ShutterSpeedValue Tv: 2^-Tv s; ApertureValue Av: f/2^(Av/2)): they were ignored and photos of different
    exposures went unnormalised. Read now: 0.01 s at f/2 and 0.02 s at f/4 (half the light) give the scale 2."""
    from PIL import Image

    a = (np.random.default_rng(2).random((6, 9, 3)) * 200 + 20).astype(np.uint8)
    for i, (t, n) in enumerate([(0.01, 2.0), (0.02, 4.0)]):
        img = Image.fromarray(a)
        exif = img.getexif()
        if written == "ifd0":
            exif[0x829A], exif[0x829D], exif[0x8827] = t, n, 100
        else:
            ifd = exif.get_ifd(0x8769)
            ifd[0x9201], ifd[0x9202], ifd[0x8827] = -np.log2(t), 2 * np.log2(n), 100
        img.save(tmp_path / f"p{i}.jpg", exif=exif, quality=100)
    photos = read_photos(tmp_path)
    assert photos.exposure[1]["exposure_time_s"] == pytest.approx(0.02, rel=1e-3)
    assert photos.exposure[1]["f_number"] == pytest.approx(4.0, rel=1e-3)
    assert photos.exposure[1]["scale"] == pytest.approx(2.0, rel=1e-3)
    np.testing.assert_allclose(photos.images[1], photos.images[0] * photos.exposure[1]["scale"], rtol=1e-3)


def test_the_f_number_counts_in_the_exposure_when_every_photo_gives_one(tmp_path):
    """Light gathered ~ time x ISO / N^2: 0.01 s at f/2 and 0.04 s at f/4 gather the same light (scale 1), 0.01 s at
    f/4 a quarter of it (scale 4); without an f-number in every photo, time and ISO alone."""
    from PIL import Image

    a = (np.random.default_rng(2).random((6, 9, 3)) * 200 + 20).astype(np.uint8)
    for folder, stops in (("all", [(0.01, 2.0), (0.04, 4.0), (0.01, 4.0)]), ("some", [(0.01, 2.0), (0.01, None)])):
        (tmp_path / folder).mkdir()
        for i, (t, n) in enumerate(stops):
            img = Image.fromarray(a)
            exif = img.getexif()
            ifd = exif.get_ifd(0x8769)
            ifd[0x829A], ifd[0x8827] = t, 100
            if n is not None:
                ifd[0x829D] = n
            img.save(tmp_path / folder / f"p{i}.jpg", exif=exif, quality=100)
    assert [e["scale"] for e in read_photos(tmp_path / "all").exposure] == pytest.approx([1.0, 1.0, 4.0])
    assert [e["scale"] for e in read_photos(tmp_path / "some").exposure] == [1.0, 1.0]


def test_exposures_that_differ_where_one_photo_gives_none_are_said(tmp_path, capsys):
    """Two photos at 0.01 s and one at 0.02 s, but one of them without ISO: none can be normalised, and the
    command says so instead of leaving the doubled exposure silently (sweep 6)."""
    a = (np.random.default_rng(2).random((6, 9, 3)) * 200 + 20).astype(np.uint8)
    for i, (t, iso) in enumerate([(0.01, 100), (0.02, 100), (0.01, None)]):
        _jpeg_with_exif(tmp_path / f"p{i}.jpg", a, exposure_s=t, iso=iso)
    photos = read_photos(tmp_path)
    assert [e["scale"] for e in photos.exposure] == [1.0, 1.0, 1.0] and "p2.jpg" in photos.exposure_note
    err = capsys.readouterr().err
    assert err.startswith("warning: --input: the EXIF exposures of the photos differ, but p2.jpg") and \
        err.count("\n") == 1, err
    # The photo without ISO is the one whose time differs (sweep 6's case): said the same way.
    for i, (t, iso) in enumerate([(0.01, 100), (0.01, 100), (0.02, None)]):
        _jpeg_with_exif(tmp_path / f"p{i}.jpg", a, exposure_s=t, iso=iso)
    assert "p2.jpg" in read_photos(tmp_path).exposure_note


def test_apertures_that_differ_where_one_photo_gives_none_are_said(tmp_path, capsys):
    """f/2 and f/8 (16 times less light) and a third photo without an f-number: the apertures are left out of every
    photo's scale, and the command says so naming that photo (sweep 23's drafts: silent, scale 1 for the f/8 one)."""
    from PIL import Image

    a = (np.random.default_rng(2).random((6, 9, 3)) * 200 + 20).astype(np.uint8)
    for i, n in enumerate((2.0, 8.0, None)):
        img = Image.fromarray(a)
        exif = img.getexif()
        ifd = exif.get_ifd(0x8769)
        ifd[0x829A], ifd[0x8827] = 0.01, 100
        if n is not None:
            ifd[0x829D] = n
        img.save(tmp_path / f"p{i}.jpg", exif=exif, quality=100)
    photos = read_photos(tmp_path)
    assert [e["scale"] for e in photos.exposure] == [1.0, 1.0, 1.0]
    assert "f-numbers of the photos differ (2 to 8), but p2.jpg" in photos.exposure_note
    assert "p2.jpg" in capsys.readouterr().err


def test_exif_exposures_must_be_finite_positive_and_at_most_ten_stops_apart(tmp_path):
    """The longest exposure over the shortest (time x ISO) may be MAX_EXPOSURE_RATIO (1024, 10 stops), not more; a
    value that is not a positive number is refused naming the file and the value as written (issue 50)."""
    from PIL.TiffImagePlugin import IFDRational

    a = (np.random.default_rng(2).random((6, 9, 3)) * 200 + 20).astype(np.uint8)
    for i, seconds in enumerate([0.001, 1.024]):
        _jpeg_with_exif(tmp_path / f"p{i}.jpg", a, exposure_s=seconds)
    photos = read_photos(tmp_path)
    assert [e["scale"] for e in photos.exposure] == [1.0, pytest.approx(1 / 1024)]
    _jpeg_with_exif(tmp_path / "p1.jpg", a, exposure_s=1.025)
    with pytest.raises(ValueError, match=r"^--input: EXIF exposures differ 1.02e\+03 times, p1.jpg \(1.025 s at ISO "
                                         r"100\) against p0.jpg \(0.001 s at ISO 100\); expected at most 1024 times"):
        read_photos(tmp_path)
    for value, shown in ((IFDRational(1, 0), "1/0"), (IFDRational(-1, 100), "-1/100")):
        _jpeg_with_exif(tmp_path / "p1.jpg", a, exposure_s=value)
        with pytest.raises(ValueError, match=rf"^--input: p1.jpg: EXIF ExposureTime is {shown}; expected a finite "):
            read_photos(tmp_path)


def test_a_damaged_jpeg_is_one_line_naming_it_and_the_decoder_says_nothing_else(tmp_path, capfd):
    """A JPEG cut short (OpenCV reading the file would decode its missing part grey, libjpeg's complaint on the
    terminal): refused naming the file in one line (issue 50), nothing else printed; the size probe refuses it too."""
    from scenes.folder.photos import photo_shape

    a = (np.random.default_rng(3).random((48, 64, 3)) * 200 + 20).astype(np.uint8)
    for name in ("a.jpg", "b.jpg"):
        cv2.imwrite(str(tmp_path / name), a)
    whole = (tmp_path / "b.jpg").read_bytes()
    (tmp_path / "b.jpg").write_bytes(whole[: len(whole) * 3 // 4])
    capfd.readouterr()
    with pytest.raises(ValueError, match=r"^--input: '.*b.jpg' is damaged: the JPEG decoder cannot decode it .*"
                                         r"truncated or corrupt") as err:
        read_photos(tmp_path)
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match=r"b.jpg' is damaged"):
        photo_shape(tmp_path / "b.jpg")
    assert capfd.readouterr().err == ""


def test_mixed_photos_are_one_line_naming_the_file(tmp_path):
    cv2.imwrite(str(tmp_path / "a.png"), np.zeros((4, 6, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "b.png"), np.zeros((4, 5, 3), np.uint8))
    with pytest.raises(ValueError, match=r"^--input: b.png differs in size from a.png"):
        read_photos(tmp_path)
    cv2.imwrite(str(tmp_path / "b.png"), np.zeros((6, 4, 3), np.uint8))
    with pytest.raises(ValueError, match=r"^--input: b.png differs in orientation"):
        read_photos(tmp_path)
    cv2.imwrite(str(tmp_path / "b.png"), np.zeros((4, 6, 3), np.uint16))
    with pytest.raises(ValueError, match=r"^--input: b.png differs in bit depth"):
        read_photos(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"^--input: .*missing' is not a folder"):
        read_photos(tmp_path / "missing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=r"^--input: no photos in"):
        read_photos(tmp_path / "empty")


def test_the_size_probe_before_reading_takes_exr_and_turned_photos_as_the_reader_does(tmp_path):
    """orchestrate.capture sizes its memory estimate from one file before reading: OpenCV alone does not
    decode EXR, so the probe goes through the reader's own decoders."""
    from orchestrate.capture import CaptureOptions, probe_input
    from scenes.images import write_exr

    for i in range(2):
        write_exr(tmp_path / f"{i}.exr", np.ones((5, 7, 3), np.float32))
    assert probe_input(CaptureOptions(input=str(tmp_path), out=str(tmp_path / "o"))) == (2, 5, 7, (5, 7))
    (tmp_path / "jpg").mkdir()
    _jpeg_with_exif(tmp_path / "jpg" / "p.jpg", np.zeros((6, 9, 3), np.uint8), 6)
    turned = CaptureOptions(input=str(tmp_path / "jpg"), out=str(tmp_path / "o"))
    assert probe_input(turned) == (1, 9, 6, (9, 6))  # the reader's orientation: 9 rows of 6


# ------------------------------------------------------------------------------------------ capture checks

N96, M96 = sphere(96, pad=8)


def codes(images) -> list[str]:
    return [w.code for w in capture_warnings(images, M96)[0]]


def test_a_good_capture_gets_no_warning_and_each_fault_its_own():
    good = lambertian(N96, M96, SPREAD)
    assert codes(good) == []
    assert codes(lambertian(N96, M96, FRONTAL)) == ["frontal_light"]
    assert codes(lambertian(N96, M96, ONE_SIDE)) == ["one_sided_light"]
    assert codes(good * 0.02) == ["too_dark"]
    assert codes(good[::2]) == ["too_few_images"]  # 4 images, lit from all four sides
    (fatal,), _ = capture_warnings(good[:2], M96)
    assert fatal.code == "too_few_images" and fatal.fatal
    (black,), _ = capture_warnings(good * 0.0, M96)
    assert black.code == "too_dark" and black.fatal
    clipped = np.clip(good * 3.0, 0, 1)
    warnings, facts = capture_warnings(clipped, M96, saturated=clipped >= 1.0)
    assert [w.code for w in warnings] == ["saturated"] and max(facts["saturated_share"]) > 0.1


def test_a_camera_moved_by_a_few_pixels_in_half_the_images_is_flagged():
    good = lambertian(N96, M96, SPREAD)
    moved = good.copy()
    moved[4:] = np.roll(moved[4:], (2, 3), axis=(1, 2))
    warnings, facts = capture_warnings(moved, M96)
    assert [w.code for w in warnings] == ["camera_moved"]
    assert np.abs(np.abs(facts["camera_shift_px"]) - [3, 2]).max() <= 1  # 3 px right, 2 down (y up), or back
    assert codes(good) == []


def test_auto_mask_finds_the_object_or_refuses(np_rng):
    mask, info = auto_mask(lambertian(N96, M96, SPREAD))
    assert (mask & M96).sum() / (mask | M96).sum() >= 0.95 and info["separability"] > 0.6
    backdrop = (0.3 + 0.5 * np_rng.random(8))[:, None, None, None] * np.ones((1, 96, 96, 3))
    lit_backdrop = np.where(M96[None, ..., None], lambertian(N96, M96, SPREAD), backdrop).astype(np.float32)
    with pytest.raises(
        ValueError, match=r"^--mask: auto cannot separate the object from the background: .*; give a mask"
    ):
        auto_mask(lit_backdrop)


# ------------------------------------------------------------------------------------------ the command


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    """A sphere under 8 distant lights as 8-bit sRGB JPEG photos with camera names, no mask."""
    folder = tmp_path_factory.mktemp("photos") / "shoot"
    write_jpegs(folder, lambertian(N96, M96, SPREAD))
    return folder


def test_photos_in_a_normal_map_out_in_both_conventions(photos, tmp_path, variant_llvm_ad_rgb):
    from orchestrate.capture import main
    from scenes.images import read_mask, read_normals

    outs = {}
    for convention in ("opengl", "opencv"):
        out = tmp_path / convention
        assert main(["--input", str(photos), "--out", str(out), "--convention", convention, "--no-refine",
                     "--threads", "1"]) == 0
        outs[convention] = read_normals(out / "normal.png")
        report = json.loads((out / "report.json").read_text())
        assert report["warnings"] == [] and report["mask"]["method"].startswith("otsu")
        assert report["normals"]["convention"] == convention and report["input"]["encoding"] == ["srgb"] * 8
        assert set(report["verdict"]) >= {"images_can_judge", "summary", "residual_in_noise_units", "level", "headline"}
        e = report["expected_error_deg"]
        assert e["interval_80"][0] < e["mean"] < e["interval_80"][1] and report["verdict"]["level"] == "usable"
        assert report["verdict"]["headline"].startswith(f"usable: expected error about {e['mean']:.0f} deg")
        per = np.load(out / "expected_error_deg.npy")
        assert np.isfinite(per[read_mask(out / "mask.png")]).all() and np.isnan(per[~read_mask(out / "mask.png")]).all()
        assert report["estimate"]["peak_mib"] > 0 and report["peak_memory_mib"] > 0
        assert read_normals(out / "normal_model.png").shape == (96, 96, 3)  # the model's map, kept beside
        depth = np.load(out / "surface" / "depth.npy")  # the final map's surface, orthographic (no EXIF focal)
        assert np.isfinite(depth[read_mask(out / "mask.png")]).all() and report["surface"]["camera"].startswith("ortho")
        assert (out / "surface" / "mesh.ply").is_file() and (out / "surface" / "shaded.png").is_file()
        mask = read_mask(out / "mask.png")
        assert (mask & M96).sum() / (mask | M96).sum() >= 0.95
    gl, cv = outs["opengl"], outs["opencv"]
    m = mask & M96
    np.testing.assert_allclose(cv[m] * [1, -1, -1], gl[m], atol=1e-4)  # the same map, y and z negated
    upper, right = m & (np.arange(96)[:, None] < 40), m & (np.arange(96)[None, :] > 56)
    assert gl[upper][:, 1].mean() > 0.3 and gl[right][:, 0].mean() > 0.3 and gl[m][:, 2].mean() > 0.5  # y up
    assert np.degrees(np.arccos(np.clip((gl[m] * N96[m]).sum(-1), -1, 1))).mean() < 25


def _chromium() -> str:
    import shutil

    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        pytest.skip("headless Chromium is not installed (scripts/setup.sh installs Debian's chromium as root)")
    return found


def test_report_html_is_a_page_in_a_real_browser(photos, tmp_path, variant_llvm_ad_rgb, capsys):
    """The page opens in headless Chromium: its DOM holds the verdict and every picture, and the screenshot shows
    the page's own title band (not a browser error page). The verdict's headline is the CLI's first line."""
    import subprocess

    from orchestrate.capture import main
    from orchestrate.capture_page import HEADER_RGB

    browser = _chromium()
    out = tmp_path / "page"
    capsys.readouterr()
    assert main(["--input", str(photos), "--out", str(out), "--no-refine", "--threads", "1"]) == 0
    page = (out / "report.html").resolve()
    report = json.loads((out / "report.json").read_text())
    assert capsys.readouterr().out.splitlines()[0] == report["verdict"]["headline"]
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        f"--user-data-dir={tmp_path / 'profile'}",
    ]
    dom = subprocess.run(
        [browser, *flags, "--dump-dom", page.as_uri()], capture_output=True, text=True, timeout=120
    ).stdout
    assert report["verdict"]["summary"][:20] in dom and report["verdict"]["summary"].startswith("The images can")
    assert report["verdict"]["headline"] in dom and 'alt="Expected error"' in dom and 'alt="The surface"' in dom
    assert dom.count('src="data:image/png;base64,') >= 6 and "What to improve in the capture" in dom
    shot = tmp_path / "shot.png"
    subprocess.run([browser, *flags, "--window-size=1000,1400", f"--screenshot={shot}", page.as_uri()],
                   capture_output=True, timeout=120)
    picture = cv2.imread(str(shot))[..., ::-1]
    assert picture.shape[:2] == (1400, 1000)
    band = picture[5:40, 5:500].reshape(-1, 3)  # the title band's background
    assert (np.abs(band.astype(int) - HEADER_RGB).max(axis=1) <= 3).mean() > 0.8
    assert len(np.unique(picture.reshape(-1, 3), axis=0)) > 200  # pictures drawn, not a blank page


def test_three_photos_give_the_models_map_and_say_the_images_cannot_judge_it(photos, tmp_path, variant_llvm_ad_rgb):
    """Three photos determine a normal but not a judgement: the check abstains (its rank-4 test needs 5
    observations a pixel) instead of failing inside."""
    import shutil

    from orchestrate.capture import main

    three = tmp_path / "three"
    three.mkdir()
    for f in sorted(photos.iterdir())[::3]:
        shutil.copy(f, three / f.name)
    assert main(["--input", str(three), "--out", str(tmp_path / "o"), "--threads", "1"]) == 0
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["verdict"]["images_can_judge"] is False and "only 3 images" in report["verdict"]["why"]
    assert report["verdict"]["level"] == "not checked" and report["verdict"]["headline"].startswith("not checked: ")
    assert report["normals"]["source"] == "model" and "too_few_images" in [w["code"] for w in report["warnings"]]


def test_a_capture_too_large_for_the_memory_is_refused_before_any_work(photos, tmp_path, capsys, monkeypatch):
    """The estimate is checked against the memory this machine has (here made small), in one line. Sweep 39: where
    even the smallest --max-side would not fit (96 px photos cost little more than 32 px ones), it names --input and
    fewer photos, not a smaller --max-side."""
    from orchestrate.capture import main
    from orchestrate.capture_estimate import estimate

    need = estimate(8, 96, 96)["peak_mib"]
    monkeypatch.setattr("scenes.cli.limits.available_memory", lambda: int(need * 2**20 * 0.5))
    assert main(["--input", str(photos), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --input: 8 photos of 96 x 96 px needs about") and "fewer photos" in err, err
    assert not (tmp_path / "o" / "normal.png").exists()
    assert estimate(96, 512, 612)["peak_mib"] > estimate(16, 512, 612)["peak_mib"] > estimate(16, 256, 306)["peak_mib"]


def test_the_estimate_bounds_every_measured_run():
    """The recorded measurements (bench_capture's sizes and formats; bench_capture_diligent's whole DiLiGenT
    captures, 96 photos of 612 x 512, with the run that peaked 13 % above its repeats): the peak never above the
    current estimate, the time within a factor 1.5 of it."""
    import json

    from orchestrate.capture_estimate import estimate

    root = Path(__file__).resolve().parents[1] / "bench" / "results"
    for r in json.loads((root / "capture.json").read_text())["rows"]:
        (h, w), (hw, ww) = r["size"], r.get("working_size", r["size"])
        e = estimate(r["images"], hw, ww, (h, w) if (h, w) != (hw, ww) else None)
        assert r["peak_mib"] <= e["peak_mib"], (r, e)
        assert 1 / 1.5 <= r["wall_s"] / e["seconds"] <= 1.5, (r, e)
    e = estimate(96, 512, 612)
    for r in json.loads((root / "capture_diligent.json").read_text())["rows"]:
        assert r["peak_mib"] <= e["peak_mib"], (r, e)


def test_bad_captures_stop_in_one_line(photos, tmp_path, capsys):
    import shutil

    from orchestrate.capture import main

    two = tmp_path / "two"
    two.mkdir()
    for f in sorted(photos.iterdir())[:2]:
        shutil.copy(f, two / f.name)
    assert main(["--input", str(two), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "only 2 image(s)" in err[0] and "Traceback" not in err[0]
    cv2.imwrite(str(tmp_path / "small_mask.png"), np.full((10, 10), 255, np.uint8))
    assert main(["--input", str(photos), "--out", str(tmp_path / "o"), "--mask", str(tmp_path / "small_mask.png")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --mask: ") and "is 10x10, the photos 96x96" in err
    assert main(["--input", str(photos), "--out", str(tmp_path / "o"), "--mask", str(tmp_path / "none.png")]) == 2
    assert capsys.readouterr().err.startswith("error: --mask: ")
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "report.json").write_text("{}")
    assert main(["--input", str(photos), "--out", str(tmp_path / "taken")]) == 2
    assert "--overwrite" in capsys.readouterr().err and (tmp_path / "taken" / "report.json").read_text() == "{}"
    assert main(["--input", str(photos), "--out", str(tmp_path / "m"), "--model", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --model: 'nope' is not registered") and not (tmp_path / "m").exists()


def test_the_verdict_level_follows_its_rule():
    """usable only when checked, under USABLE_DEG and with no warning that the error model never saw; a doubtful
    mask or a moved camera never reads usable, whatever the stated figure."""
    from orchestrate.capture_verdict import USABLE_DEG, level
    from unips.expected_error import Stated
    from validate.diagnosis.usable import CaptureWarning

    mask = np.ones((4, 4), bool)

    def stated(deg: float) -> Stated:
        return Stated(per_pixel=np.where(mask, deg, np.nan).astype(np.float32), mean=deg, interval_80=(deg * .8,
                                                                                                       deg * 1.3))

    trusted, untrusted = {"trusted": True}, {"trusted": False, "why": "near light"}
    assert level(trusted, stated(9.0), None, [])[0] == "usable"
    assert level(trusted, stated(USABLE_DEG + 1), None, [])[0] == "use with care"
    for code in ("doubtful_mask", "camera_moved"):
        lv, line = level(trusted, stated(5.0), None, [CaptureWarning(code, "...")])
        assert lv == "use with care" and line.startswith("use with care: expected error about 5 deg")
    assert level(trusted, stated(5.0), None, [CaptureWarning("too_dark", "...")])[0] == "usable"
    lv, line = level(untrusted, stated(5.0), None, [])
    assert lv == "not checked" and "near light" in line and "5 deg" in line
    lv, line = level(trusted, None, "no error model was fitted for x.safetensors", [])
    assert lv == "not checked" and "no error model" in line


def test_mask_none_makes_the_whole_frame_the_scene(photos, tmp_path, variant_llvm_ad_rgb):
    """--mask none: no mask is found or doubted, every pixel gets a normal, and report.json says what that means."""
    from orchestrate.capture import WHOLE_FRAME, main
    from scenes.images import read_mask, read_normals

    out = tmp_path / "scene"
    assert main(["--input", str(photos), "--out", str(out), "--mask", "none", "--no-refine", "--threads", "1"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["mask"]["method"].startswith("none") and report["mask"]["note"] == WHOLE_FRAME
    assert read_mask(out / "mask.png").all() and "mask_doubts" not in report["measurements"]
    n = read_normals(out / "normal.exr")
    assert (np.linalg.norm(n, axis=-1) > 0.5).mean() > 0.99
    assert np.isfinite(np.load(out / "expected_error_deg.npy")).all()


def test_exr_photos_of_one_channel_are_grey_and_of_two_are_refused_naming_the_file(tmp_path):
    """A grey (Y) EXR is read as three equal channels (it used to reach the capture as one channel and fail
    there); an EXR of two channels is refused naming the file (it was a message about array shapes)."""
    import OpenEXR

    from scenes.images import write_exr

    grey, two = tmp_path / "grey", tmp_path / "two"
    grey.mkdir()
    two.mkdir()
    rng = np.random.default_rng(0)
    for i in range(3):
        write_exr(grey / f"IMG_{i}.exr", rng.uniform(0.1, 1, (6, 8)).astype(np.float32))
        channels = {c: rng.uniform(0.1, 1, (6, 8)).astype(np.float32) for c in "RG"}
        with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels) as f:
            f.write(str(two / f"IMG_{i}.exr"))
    photos = read_photos(grey)
    assert photos.images.shape == (3, 6, 8, 3) and np.array_equal(photos.images[..., 0], photos.images[..., 2])
    with pytest.raises(ValueError, match=r"IMG_0\.exr' is an EXR of 2 channels"):
        read_photos(two)


@pytest.mark.slow
def test_ctrl_c_during_a_capture_is_one_line_and_status_130(photos, tmp_path):
    """Ctrl-C (SIGINT) in the middle of a capture: one line saying what is left, exit 130, no traceback."""
    import signal
    import subprocess
    import sys
    import time

    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen([sys.executable, "-m", "orchestrate.capture", "--input", str(photos), "--out",
                             str(tmp_path / "o"), "--threads", "1"], cwd=root, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=interruptible)
    time.sleep(8)  # past the imports, inside the model or the check
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, (proc.returncode, err[-2000:])
    lines = [line for line in err.splitlines() if not line.startswith("capture: ")]  # progress lines aside
    assert lines == [lines[-1]] and lines[-1].startswith("interrupted: ") and "Traceback" not in err, err


def test_an_image_whose_name_is_not_utf8_is_read_not_crashed_on(tmp_path):
    """OpenCV's own file reading dies with SIGSEGV on a name whose bytes are not UTF-8 (a Latin-1 'é', which Python
    holds as a lone surrogate): `decode_image` reads the bytes itself and decodes them (sweep 8)."""
    import os

    from scenes.images import decode_image

    a = (np.random.default_rng(3).random((5, 7, 3)) * 255).astype(np.uint8)
    path = Path(os.fsdecode(os.fsencode(tmp_path) + b"/caf\xe9.png"))
    path.write_bytes(cv2.imencode(".png", a)[1].tobytes())
    np.testing.assert_array_equal(decode_image(path, cv2.IMREAD_UNCHANGED, "--input"), a)


def test_one_grey_photo_among_colour_ones_is_named(tmp_path):
    """OpenCV reads a grey JPEG as colour (three equal channels): among colour photos it would be a photo of another
    camera setting, used silently (sweep 9). All grey photos are one setting and read."""
    from PIL import Image

    a = (np.random.default_rng(4).random((6, 9, 3)) * 200 + 20).astype(np.uint8)
    for i in range(3):
        Image.fromarray(a).save(tmp_path / f"p{i}.jpg", quality=95)
    Image.fromarray(a[..., 0]).save(tmp_path / "p1.jpg", quality=95)
    with pytest.raises(ValueError, match=r"^--input: p1.jpg is a grey photo and p0.jpg a colour one"):
        read_photos(tmp_path)
    for i in range(3):
        Image.fromarray(a[..., i]).save(tmp_path / f"p{i}.jpg", quality=95)
    assert read_photos(tmp_path).images.shape == (3, 6, 9, 3)


def test_too_many_photos_are_refused_naming_the_count_not_the_size(monkeypatch):
    """Sweep 39: 4000 photos of 32 x 32 px were refused with the advice to give a smaller --max-side (e.g. 1024),
    which cannot help: each photo's fixed cost is what fills the memory. That case names --input and fewer photos;
    large photos still get the --max-side advice."""
    from orchestrate import capture_estimate
    from scenes.cli import limits
    from scenes.cli.errors import UsageError

    monkeypatch.setattr(limits, "available_memory", lambda: 8 * 2**30)
    with pytest.raises(UsageError, match=r"^--input: 4000 photos of 32 x 32 px needs about .*fewer photos") as exc:
        capture_estimate.check_resources(4000, 32, 32)
    assert "smaller --max-side" not in str(exc.value) and "even at --max-side 32" in str(exc.value)
    with pytest.raises(UsageError, match=r"^--max-side: 20 photos of 20000 x 20000 px .*smaller --max-side"):
        capture_estimate.check_resources(20, 20000, 20000)


def test_an_overwrite_by_a_capture_of_another_name_removes_the_earlier_ones_stage_folders(photos, tmp_path,
                                                                                           variant_llvm_ad_rgb):
    """Sweep 40: with --overwrite, a capture of folder q into the --out of a capture of p left check/p/ and
    work/p.data/ beside a report that describes q only. They go once q's capture is written; a user's file in
    check/p/ stays, and keeps its folder."""
    import shutil

    from orchestrate.capture import main

    out, p, q = tmp_path / "o", tmp_path / "p", tmp_path / "q"
    shutil.copytree(photos, p)
    args = ["--out", str(out), "--no-refine", "--threads", "1", "--max-side", "48", "--keep-work"]
    assert main(["--input", str(p), *args]) == 0
    assert (out / "check" / "p" / "report.json").is_file() and (out / "work" / "p.data" / "mask.png").is_file()
    (out / "check" / "p" / "notes.txt").write_text("mine\n")
    p.rename(q)
    assert main(["--input", str(q), *args, "--overwrite"]) == 0
    assert sorted(f.name for f in (out / "check" / "p").iterdir()) == ["notes.txt"]
    assert not (out / "work" / "p.data").exists() and (out / "work" / "q.data" / "mask.png").is_file()
    assert (out / "check" / "q" / "report.json").is_file()
