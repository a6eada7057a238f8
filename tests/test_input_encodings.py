"""Sweep 26's faults in what users' files say about themselves: EXIF fields of odd shapes and embedded ICC profiles
of photos (`orchestrate.capture`), DiLiGenT light files a spreadsheet wrote or whose numbers do not survive single
precision (`unips.predict`), float TIFF predictions that are not unit vectors (`unips.evaluate`). Every file is
written here, every command is the real one; a refusal is one line naming the file, and writes nothing."""
from __future__ import annotations

import json
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest
from fixtures import write_predict_diligent, write_predict_ours

from scenes.folder.photos import read_photos

X = np.linspace(0.0, 1.0, 1024)
SRGB_TABLE = np.round(np.where(X <= 0.04045, X / 12.92, ((X + 0.055) / 1.055) ** 2.4) * 65535)
"""The sRGB curve (IEC 61966-2-1, written out) as an ICC 'curv' table."""
D50_COLORANTS = {  # the profiles' rXYZ, gXYZ, bXYZ (adapted to D50, as ICC profiles store them)
    "srgb": ((0.4361, 0.2225, 0.0139), (0.3851, 0.7169, 0.0971), (0.1431, 0.0606, 0.7141)),
    "p3": ((0.5151, 0.2412, -0.0011), (0.2920, 0.6922, 0.0419), (0.1571, 0.0666, 0.7841)),
    "adobe": ((0.6097, 0.3111, 0.0195), (0.2053, 0.6257, 0.0609), (0.1492, 0.0632, 0.7446)),
}


def icc_profile(description: str, colorants: str, curve) -> bytes:
    """An ICC v2 RGB display profile, as the ICC specification lays it out: `curve` a gamma (one number) or a table
    of 16-bit values for all three channels."""
    def s15(v):
        return b"".join(struct.pack(">i", round(x * 65536)) for x in v)

    desc = description.encode() + b"\0"
    trc = b"curv\0\0\0\0" + (struct.pack(">IH", 1, round(curve * 256)) if np.isscalar(curve) else
                             struct.pack(">I", len(curve)) + np.asarray(curve, ">u2").tobytes())
    tags = [(b"desc", b"desc\0\0\0\0" + struct.pack(">I", len(desc)) + desc + b"\0" * 79),
            (b"wtpt", b"XYZ \0\0\0\0" + s15((0.9642, 1.0, 0.8249))),
            *[(t, b"XYZ \0\0\0\0" + s15(c)) for t, c in zip((b"rXYZ", b"gXYZ", b"bXYZ"), D50_COLORANTS[colorants])],
            (b"rTRC", trc), (b"gTRC", trc), (b"bTRC", trc), (b"cprt", b"text\0\0\0\0none\0")]
    offset, table, body = 128 + 4 + 12 * len(tags), struct.pack(">I", len(tags)), b""
    for sig, data in tags:
        table += sig + struct.pack(">II", offset + len(body), len(data))
        body += data + b"\0" * (-len(data) % 4)
    header = (struct.pack(">I", 128 + len(table) + len(body)) + b"none" + bytes([2, 0x10, 0, 0]) + b"mntrRGB XYZ "
              + b"\0" * 12 + b"acsp" + b"\0" * 32 + s15((0.9642, 1.0, 0.8249))).ljust(128, b"\0")
    return header + table + body


def write_jpegs(folder: Path, k: int = 3, exif_tags: dict | None = None, icc: bytes | None = None) -> np.ndarray:
    """k 8-bit JPEGs (quality 100) of a smooth gradient, each with the Exif-IFD `exif_tags` and the ICC profile
    `icc`; their (k, H, W, 3) codes as decoded."""
    from PIL import Image

    folder.mkdir(parents=True)
    yy, xx = np.mgrid[0:16, 0:24]
    for i in range(k):
        codes = np.stack([xx * 8 + 20 + 10 * i, yy * 10 + 30, np.full_like(xx, 90 + 20 * i)], -1).astype(np.uint8)
        img = Image.fromarray(codes)
        exif = img.getexif()
        for tag, value in (exif_tags or {}).items():
            exif.get_ifd(0x8769)[tag] = value
        img.save(folder / f"IMG_{i + 1:04d}.jpg", exif=exif, quality=100, **({"icc_profile": icc} if icc else {}))
    return np.stack([cv2.imread(str(p))[..., ::-1] for p in sorted(folder.glob("*.jpg"))])


def capture(folder: Path, out: Path, capsys, *extra: str) -> tuple[int, str]:
    from orchestrate.capture import main

    rc = main(["--input", str(folder), "--out", str(out), "--no-refine", "--threads", "1", *extra])
    return rc, capsys.readouterr().err


def assert_one_line_refusal(rc: int, err: str, *said: str) -> None:
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert all(s in lines[0] for s in said), lines[0]


# ------------------------------------------------------------------------------------------------ EXIF fields
def test_an_exif_colour_space_of_two_values_is_one_line_naming_the_file(tmp_path, capsys):
    """Sweep 26 (a26-photo2-21): ColorSpace written as (1, 2) on every JPEG was int() of a tuple, a TypeError
    traceback; now it is not sRGB as written, refused in auto mode naming the file and the tag, read when the user
    says the encoding."""
    write_jpegs(tmp_path / "photos", exif_tags={0xA001: (1, 2)})
    rc, err = capture(tmp_path / "photos", tmp_path / "o", capsys)
    assert_one_line_refusal(rc, err, "--input", "IMG_0001.jpg", "EXIF colour space (1, 2)", "--input-encoding")
    assert not (tmp_path / "o").exists()
    assert read_photos(tmp_path / "photos", "srgb").encoding == ["srgb"] * 3


@pytest.mark.parametrize("tags, said", [
    ({0x829A: (0.01, 0.02), 0x8827: 100}, "EXIF ExposureTime is (0.01, 0.02)"),  # two exposure times: which one?
    ({0xA001: b"\x01\x02"}, "EXIF colour space b'\\x01\\x02'"),  # bytes where a number belongs
])
def test_exif_fields_of_another_shape_are_refused_naming_the_tag(tmp_path, tags, said):
    """An exposure time of two values was read as its first silently; a colour space of bytes was int() of bytes
    (a ValueError naming no tag); both are now one line naming the file and the field."""
    write_jpegs(tmp_path / "photos", exif_tags=tags)
    with pytest.raises(ValueError, match="IMG_0001.jpg") as caught:
        read_photos(tmp_path / "photos")
    assert said in str(caught.value) and "\n" not in str(caught.value)


# ------------------------------------------------------------------------------------------------ ICC profiles
def test_an_icc_profile_decides_the_curve_it_can_be_read_with(tmp_path):
    """Sweep 26 (a26-photo2-01): JPEGs carrying a linear (gamma 1) profile were decoded with the sRGB curve without
    a word; now read linear. A profile with the sRGB curve keeps them sRGB, whatever its name and primaries: the
    common "sRGB IEC61966-2.1", and a phone's Display P3 with EXIF colour space 65535 (uncalibrated), as iPhones
    write them (refused before as not sRGB)."""
    linear = write_jpegs(tmp_path / "linear", icc=icc_profile("linear RGB", "srgb", 1.0))
    photos = read_photos(tmp_path / "linear")
    assert photos.encoding == ["linear"] * 3
    np.testing.assert_allclose(photos.images, linear / 255.0, atol=1e-6)
    for name, colorants, space in (("sRGB IEC61966-2.1", "srgb", 1), ("Display P3", "p3", 65535)):
        codes = write_jpegs(tmp_path / colorants, exif_tags={0xA001: space}, icc=icc_profile(name, colorants,
                                                                                              SRGB_TABLE))
        photos = read_photos(tmp_path / colorants)
        assert photos.encoding == ["srgb"] * 3, name
        c = codes / 255.0
        np.testing.assert_allclose(photos.images, np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4),
                                   atol=1e-6)


@pytest.mark.parametrize("profile, said", [
    (icc_profile("Adobe RGB (1998)", "adobe", 563 / 256), "the ICC profile 'Adobe RGB (1998)'"),
    (bytes(np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8)), "an ICC profile that LittleCMS cannot"),
])
def test_an_icc_profile_of_another_curve_is_refused_naming_it(tmp_path, capsys, profile, said):
    """A gamma-2.2 profile (Adobe RGB) or one that cannot be read said nothing about the sRGB curve they were decoded
    with; now one line naming the file and the profile, and --input-encoding still decides for all files."""
    write_jpegs(tmp_path / "photos", exif_tags={0xA001: 1}, icc=profile)
    rc, err = capture(tmp_path / "photos", tmp_path / "o", capsys)
    assert_one_line_refusal(rc, err, "--input", "IMG_0001.jpg", said, "--input-encoding")
    assert not (tmp_path / "o").exists()
    assert read_photos(tmp_path / "photos", "srgb").encoding == ["srgb"] * 3


# ------------------------------------------------------------------------------------------------ light files
def predict(folder: Path, out: Path, capsys) -> tuple[int, str]:
    from unips.predict import main

    rc = main(["--method", "least-squares", "--input", str(folder), "--out", str(out)])
    return rc, capsys.readouterr().err


def test_light_files_a_spreadsheet_saved_are_read(tmp_path, capsys):
    """Sweep 26 (a26-pred2-12): light_directions.txt with a UTF-8 BOM, commas and CRLF (what a Windows spreadsheet
    saves) was refused at its BOM; both light files are now read by the one reader, to the same normals."""
    for name in ("plain", "excel"):
        write_predict_diligent(tmp_path / name)
    for light_file in ("light_directions.txt", "light_intensities.txt"):
        rows = np.loadtxt(tmp_path / "plain" / light_file) * (1.0 if "dir" in light_file else 0.5)
        np.savetxt(tmp_path / "plain" / light_file, rows, fmt="%.9f")
        text = "\r\n".join(",".join(f"{v:.9f}" for v in row) for row in rows) + "\r\n"
        (tmp_path / "excel" / light_file).write_bytes(b"\xef\xbb\xbf" + text.encode())
    for name in ("plain", "excel"):
        rc, err = predict(tmp_path / name, tmp_path / f"o_{name}", capsys)
        assert rc == 0, err
    maps = [cv2.imread(str(next((tmp_path / f"o_{n}").rglob("normal.png"))), cv2.IMREAD_UNCHANGED)
            for n in ("plain", "excel")]
    np.testing.assert_array_equal(maps[0], maps[1])


@pytest.mark.parametrize("light_file, row, said", [
    ("light_directions.txt", "1e308 1e308 1e308", "row 2 is 1e+308 1e+308 1e+308, whose length is inf"),
    ("light_intensities.txt", "1e-40 1e-40 1e-40", "row 2 holds 1e-40 1e-40 1e-40"),
    ("light_intensities.txt", "1 1e-39 1", "row 2 holds 1 1e-39 1"),
])
def test_light_rows_that_do_not_survive_single_precision_are_refused(tmp_path, capsys, light_file, row, said):
    """Sweep 26 (a26-pred2-13, -14): a direction whose length overflows became a zero light and the prediction
    went on (exit 0); an intensity below float32's normal range made the division overflow, refused as 'n: normal
    map contains NaN' naming no file, after the output folder was made. Now one line naming the file and the row,
    before anything is written."""
    write_predict_diligent(tmp_path / "dil")
    lines = (tmp_path / "dil" / light_file).read_text().splitlines()
    (tmp_path / "dil" / light_file).write_text("\n".join([lines[0], row, *lines[2:]]) + "\n")
    rc, err = predict(tmp_path / "dil", tmp_path / "o", capsys)
    assert_one_line_refusal(rc, err, "--input", light_file, said)
    assert not (tmp_path / "o").exists()


def test_a_scene_irradiance_below_single_precision_is_refused_naming_the_scene_file(tmp_path, capsys):
    """The same overflow through our own layout: a scene.json irradiance of 1e-40 is refused naming the file and
    the entry, not as 'n: normal map contains NaN'."""
    write_predict_ours(tmp_path / "obj.data")
    scene = json.loads((tmp_path / "obj.data" / "scene.json").read_text())
    scene["camera_lights"][1]["directional"][0]["irradiance"] = [1e-40] * 3
    (tmp_path / "obj.data" / "scene.json").write_text(json.dumps(scene))
    rc, err = predict(tmp_path / "obj.data", tmp_path / "o", capsys)
    assert_one_line_refusal(rc, err, "--input", "scene.json", "camera_lights[1].directional[0]: irradiance is 1e-40")
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------------------------------------ float TIFF
def test_a_float_tiff_prediction_must_hold_unit_vectors(tmp_path, capsys):
    """Sweep 26 (a26-eval2-01): a float32 normal.tif holding (n + 1) / 2 was scored as directions (the unit-length
    check covered .exr, .npy and .mat only); now refused naming it, and a float TIFF of unit vectors is scored."""
    import tifffile

    from unips.evaluate import main

    n, mask = write_predict_diligent(tmp_path / "gt" / "ballPNG")
    n = (n * mask[..., None]).astype(np.float32)
    for name, values in (("encoded", np.where(mask[..., None], (n + 1) / 2, 0)), ("unit", n)):
        (tmp_path / name / "ballPNG").mkdir(parents=True)
        tifffile.imwrite(tmp_path / name / "ballPNG" / "normal.tif", values.astype(np.float32), photometric="rgb")
    assert main(["--pred", str(tmp_path / "unit"), "--gt", str(tmp_path / "gt")]) == 0
    metrics = json.loads((tmp_path / "unit" / "metrics.json").read_text())
    assert metrics["objects"]["ballPNG"]["mae_deg"] < 0.01
    capsys.readouterr()
    rc = main(["--pred", str(tmp_path / "encoded"), "--gt", str(tmp_path / "gt")])
    err = capsys.readouterr().err
    assert_one_line_refusal(rc, err, "normal.tif", "not of unit length")
    assert sorted(p.name for p in (tmp_path / "encoded").rglob("*")) == ["ballPNG", "normal.tif"]


def test_a_blank_prediction_is_not_scored_as_ninety_degrees(tmp_path, capsys):
    """Sweep 27 (a27-eval3-08): a predicted normal.exr of zeros everywhere was scored 90 deg on every pixel, exit 0,
    pulling the mean up with no word. No normal where the truth is known is no estimate: that object fails."""
    from scenes.images import write_normal_exr
    from unips.evaluate import main

    n, mask = write_predict_diligent(tmp_path / "gt" / "ballPNG")
    write_normal_exr(tmp_path / "p" / "ballPNG" / "normal.exr", np.zeros_like(n, np.float32))
    assert main(["--pred", str(tmp_path / "p"), "--gt", str(tmp_path / "gt")]) == 2  # (its one object: none scored)
    err = capsys.readouterr().err
    assert "normal.exr holds no normal where the ground truth is known" in err, err
    assert not (tmp_path / "p" / "metrics.json").exists()


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_a_tiff_of_separate_planes_reads_as_the_same_picture(tmp_path, dtype):
    """Sweep 26: OpenCV scrambles a 16-bit or float TIFF whose channels are stored as separate planes (planar
    configuration 2, what some scanners and raw converters write): a capture of such photos found no object, and a
    float normal.tif of that layout would be judged as another map. Every reader (decode_image) reads it as the
    same picture as the interleaved file."""
    import tifffile

    from scenes.images import decode_image, read_normals

    rng = np.random.default_rng(0)
    rgba = (rng.random((20, 30, 4)) * 60000).astype(dtype)
    for planar, name in (("separate", "p.tif"), ("contig", "c.tif")):
        tifffile.imwrite(tmp_path / name, rgba[..., :3] if planar == "contig" else
                         np.ascontiguousarray(rgba[..., :3].transpose(2, 0, 1)), photometric="rgb",
                         planarconfig=planar)
    for flags in (cv2.IMREAD_UNCHANGED, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR):
        got = decode_image(tmp_path / "p.tif", flags, "t")
        assert got.dtype == dtype and np.array_equal(got, decode_image(tmp_path / "c.tif", flags, "t"))
        assert np.array_equal(got[..., ::-1], rgba[..., :3])
    if dtype == np.float32:  # a normal map of unit vectors, both layouts
        n = rng.normal(size=(20, 30, 3)).astype(np.float32)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        tifffile.imwrite(tmp_path / "normal.tif", np.ascontiguousarray(n.transpose(2, 0, 1)), photometric="rgb",
                         planarconfig="separate")
        assert np.allclose(read_normals(tmp_path / "normal.tif"), n, atol=1e-6)


@pytest.mark.parametrize("suffix", [".tif", ".jpg"])
def test_cmyk_photos_are_refused_naming_the_file(tmp_path, capsys, suffix):
    """Sweep 26: 8-bit CMYK TIFFs (a print export) were turned into RGB by OpenCV without a word, and the capture
    ended on "auto cannot separate the object". Ink amounts are not light: refused naming the file."""
    from PIL import Image

    from orchestrate.capture import main as capture

    photos = tmp_path / "photos"
    photos.mkdir()
    rng = np.random.default_rng(1)
    for i in range(4):
        Image.fromarray((rng.random((24, 24, 3)) * 255).astype(np.uint8)).convert("CMYK").save(
            photos / f"IMG_{i}{suffix}")
    assert capture(["--input", str(photos), "--out", str(tmp_path / "o"), "--no-refine", "--threads", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: --input: IMG_0") and "holds CMYK values (a print separation)" in err[-1], err
    assert not (tmp_path / "o").exists()
