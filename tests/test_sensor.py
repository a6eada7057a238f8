"""The sensor model (scenes.camera_sensor) against its own stated physics, and `python -m wildgen.sensor` on a real
dataset.

The statistics are checked against the recorded parameters analytically (photon transfer, the clipped share of
a ramp and of noisy flat fields, the cos^4 vignetting law, the sRGB and gamma curves written out here), never
against a second run of the code; the files are read back as files (PNG bit depth from the header, levels).
"""
from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from fixtures import use_variant

from scenes.camera_sensor import (
    CFA_PATTERNS,
    DEMOSAIC_METHODS,
    SENSORS,
    Sensor,
    apply_sensor,
    demosaic,
    mosaic,
    read_sensor_record,
    rederive_image,
    write_image,
)


def recorded(sensor: Sensor) -> Sensor:
    """The sensor as a reader of scene.json gets it back (through JSON)."""
    return Sensor.from_dict(json.loads(json.dumps(sensor.to_dict())))


def dn_of(pixels: np.ndarray, sensor: Sensor) -> np.ndarray:
    """The DN of the file pixels (12 bits are stored as DN * 16)."""
    return pixels.astype(np.float64) / (16 if sensor.bits == 12 else 1)


def png_bit_depth(path: Path) -> int:
    """The bit depth written in the PNG header (IHDR, byte 24)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return data[24]


def read_png(path: Path) -> np.ndarray:
    import cv2

    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)[:, :, ::-1]


def srgb_encode(n: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1, written out: 12.92 n below 0.0031308, else 1.055 n^(1/2.4) - 0.055."""
    n = np.clip(n, 0, 1)
    return np.where(n <= 0.0031308, 12.92 * n, 1.055 * n ** (1 / 2.4) - 0.055)


# ------------------------------------------------------------------------------------------ noise


NOISY = [
    recorded(SENSORS["machine-vision"]),
    recorded(Sensor(name="custom", full_well=800.0, read_noise=12.0, black_level=0.1, bits=16,
                    sensitivity=(0.5, 1.0, 1.0), white_balance=(1.6, 1.0, 1.0))),
]


@pytest.mark.parametrize("sensor", NOISY, ids=[s.name for s in NOISY])
def test_variance_follows_gain_and_read_noise(sensor):
    """Flat fields at several levels: per channel, mean = D + K_c full_well y s_c and
    var = K_c (mean - D) + K_c^2 read_noise^2 + 1/12, within sampling error; a line fitted through
    (mean, var) has slope K and gives back the read noise."""
    rng = np.random.default_rng(123)
    levels = [0.0, 0.02, 0.1, 0.3, 0.6, 0.8]
    n = 160 * 160
    for c in range(3):
        K, D = sensor.gain(c), sensor.dark_level
        means, variances = [], []
        for y in levels:
            dn = dn_of(apply_sensor(np.full((160, 160, 3), y, np.float32), sensor, rng), sensor)[..., c].ravel()
            mean_expected = D + K * sensor.full_well * y * sensor.sensitivity[c]
            var_expected = K * (mean_expected - D) + K * K * sensor.read_noise ** 2 + 1 / 12
            assert dn.min() > 0 and dn.max() < sensor.max_code  # neither clipped at 0 nor saturated
            assert abs(dn.mean() - mean_expected) < 5 * math.sqrt(var_expected / n), (c, y)
            assert abs(dn.var() - var_expected) < 5 * var_expected * math.sqrt(2 / (n - 1)) + 0.02, (c, y)
            means.append(dn.mean())
            variances.append(dn.var() - 1 / 12)
        # weighted by 1 / (standard error of each variance): the dark level's point pins the intercept
        slope, intercept = np.polyfit(means, variances, 1, w=1 / np.array(variances))
        assert slope == pytest.approx(K, rel=0.03)
        # the line at the dark level is K^2 read_noise^2
        read_noise = math.sqrt(max(intercept + slope * D, 0)) / K
        assert read_noise == pytest.approx(sensor.read_noise, rel=0.1)


def test_noise_free_and_noise_needs_a_generator():
    x = np.full((8, 8, 3), 0.25, np.float32)
    assert np.all(apply_sensor(x, SENSORS["ideal"]) == round(0.25 * 65535))
    with pytest.raises(ValueError, match="random generator"):
        apply_sensor(x, SENSORS["phone"])


# ------------------------------------------------------------------------------------------ clipping


def test_clipping_fraction_of_a_ramp():
    """A noise-free ramp x in [0, 2) with the sensor's exposure 1.25 and a black level: a pixel is at the
    largest code exactly when b + (1 - b) * 1.25 x > 1 - 0.5 / M (rounding), i.e. for the share
    1 - t / (2 * 1.25) of the ramp, t = 1 - 0.5 / (M (1 - b))."""
    for bits in (8, 12, 16):
        sensor = Sensor(exposure=1.25, black_level=0.02, bits=bits)
        n = 200_000
        x = ((np.arange(n) + 0.5) / n * 2.0).astype(np.float64).reshape(400, 500, 1).repeat(3, 2)
        dn = dn_of(apply_sensor(x, sensor), sensor)
        t = 1 - 0.5 / (sensor.max_code * (1 - sensor.black_level))
        expected = 1 - t / (2 * 1.25)
        assert np.mean(dn == sensor.max_code) == pytest.approx(expected, abs=2 / n)
        assert dn.min() == round(sensor.max_code * sensor.black_level)  # x = 0 sits on the black level


def test_clipping_fraction_of_noisy_flat_fields():
    """Near the full well a pixel saturates with probability P(e >= t * full_well), e ~ Poisson(full_well y) +
    Normal(0, read_noise^2), approximately Normal(full_well y, full_well y + read_noise^2)."""
    sensor = recorded(SENSORS["machine-vision"])
    rng = np.random.default_rng(7)
    t = 1 - 0.5 / (sensor.max_code * (1 - sensor.black_level))
    n = 200 * 200 * 3
    for y in (0.975, 0.99, 0.995, 1.0, 1.01):
        dn = dn_of(apply_sensor(np.full((200, 200, 3), y, np.float32), sensor, rng), sensor)
        fw = sensor.full_well
        z = (t * fw - fw * y) / math.sqrt(fw * y + sensor.read_noise ** 2)
        p = 0.5 * math.erfc(z / math.sqrt(2))
        assert np.mean(dn == sensor.max_code) == pytest.approx(p, abs=5 * math.sqrt(p * (1 - p) / n) + 0.005), y


# ------------------------------------------------------------------------------------------ vignetting


def test_vignetting_profile_follows_cos4():
    """Relative illumination cos^4(theta), tan(theta) = r tan(theta_c), cos^4(theta_c) = 1 - vignetting at the
    corners (r = 1 at half the diagonal)."""
    sensor = Sensor(vignetting=0.3)
    h, w = 60, 90
    img = dn_of(apply_sensor(np.full((h, w, 3), 0.5, np.float64), sensor), sensor) / sensor.max_code
    theta_c = math.acos(0.7 ** 0.25)
    yy, xx = np.mgrid[0:h, 0:w]
    r = np.hypot(yy + 0.5 - h / 2, xx + 0.5 - w / 2) / math.hypot(h / 2, w / 2)
    expected = 0.5 * np.cos(np.arctan(r * math.tan(theta_c))) ** 4
    assert np.abs(img - expected[..., None]).max() <= 0.5 / sensor.max_code + 1e-9
    assert img[h // 2, w // 2, 0] == pytest.approx(0.5, abs=1e-3)  # centre: all the light
    assert img[0, 0, 0] == pytest.approx(0.5 * 0.7, abs=5e-3)  # corner pixel (its centre is just inside the corner)


# ------------------------------------------------------------------------------------------ files


def test_bit_depths_of_the_files(tmp_path, np_rng):
    """8-bit files are 8-bit PNGs that use all 256 levels; 12-bit files are 16-bit PNGs holding only multiples
    of 16 and reaching 4095 * 16; 16-bit files are 16-bit PNGs."""
    ramp = np.linspace(0.0, 1.2, 256 * 512, dtype=np.float32).reshape(256, 512, 1).repeat(3, 2)
    for name in ("phone", "webcam"):
        write_image(tmp_path / f"{name}.png", apply_sensor(ramp, SENSORS[name], np_rng))
        back = read_png(tmp_path / f"{name}.png")
        assert png_bit_depth(tmp_path / f"{name}.png") == 8 and back.dtype == np.uint8
        assert set(np.unique(back).tolist()) == set(range(256)), name
    write_image(tmp_path / "mv.png", apply_sensor(ramp, SENSORS["machine-vision"], np_rng))
    back = read_png(tmp_path / "mv.png")
    assert png_bit_depth(tmp_path / "mv.png") == 16 and back.dtype == np.uint16
    assert np.all(back % 16 == 0) and back.max() == 4095 * 16
    assert len(np.unique(back)) > 3900  # the 12-bit levels above the black level are used
    write_image(tmp_path / "ideal.png", apply_sensor(ramp, SENSORS["ideal"]))
    assert png_bit_depth(tmp_path / "ideal.png") == 16 and len(np.unique(read_png(tmp_path / "ideal.png"))) > 60000


def test_ideal_gives_the_bytes_of_write_png16(tmp_path):
    from scenes.images import write_png16

    rng = np.random.default_rng(3)
    x = (rng.random((40, 50, 3)) * 1.3).astype(np.float32)
    # values on the rounding boundaries (k + 0.5) / 65535, zero, and above 1
    x[0, :, :] = ((np.arange(50 * 3).reshape(50, 3) + 0.5) / 65535).astype(np.float32)
    x[1, :5] = [[0, 0, 0], [1, 1, 1], [2, 2, 2], [1e-9, 1e-9, 1e-9], [0.9999999, 0.5, 0.25]]
    exposure = 0.8374
    write_png16(tmp_path / "old.png", x * exposure)
    write_image(tmp_path / "new.png", apply_sensor(x * exposure, SENSORS["ideal"]))
    assert (tmp_path / "old.png").read_bytes() == (tmp_path / "new.png").read_bytes()


# ------------------------------------------------------------------------------------------ colour


@pytest.mark.parametrize("pattern", [p for p in CFA_PATTERNS if p != "none"])
def test_mosaic_then_demosaic_returns_a_flat_colour(pattern):
    colour = np.array([0.2, 0.55, 0.9])
    rgb = np.ones((17, 24, 3)) * colour  # odd height: a partial Bayer block at the bottom
    cfa = mosaic(rgb, pattern)
    assert cfa.shape == (17, 24)
    first = {"R": 0, "G": 1, "B": 2}[pattern[0]]
    assert cfa[0, 0] == colour[first]
    for method in DEMOSAIC_METHODS:
        out = demosaic(cfa, pattern, method)
        assert out.shape == rgb.shape
        np.testing.assert_allclose(out, rgb, atol=1e-12, err_msg=method)  # borders included


def test_white_balance_and_responses_of_a_flat_colour():
    """Noise-free, with a Bayer filter: the sensitivity is undone by the white balance, the file holds the
    response of the colour (sRGB and gamma written out here), a wrong white balance gives the colour cast it
    should."""
    colour = np.array([0.05, 0.4, 0.8])
    x = np.ones((12, 16, 3), np.float64) * colour
    base = Sensor(cfa="GRBG", sensitivity=(0.5, 1.0, 0.8), white_balance=(2.0, 1.0, 1.25), bits=8)
    out = apply_sensor(x, replace(base, response="srgb"))
    np.testing.assert_array_equal(out, np.broadcast_to(np.round(srgb_encode(colour) * 255), x.shape))
    out = apply_sensor(x, replace(base, response="gamma", gamma=1.8))
    np.testing.assert_array_equal(out, np.broadcast_to(np.round(colour ** (1 / 1.8) * 255), x.shape))
    out = apply_sensor(x, replace(base, white_balance=(1.0, 1.0, 1.0), bits=16))
    np.testing.assert_array_equal(out, np.broadcast_to(np.round(colour * [0.5, 1.0, 0.8] * 65535), x.shape))
    # beyond the full well a pixel holds no more electrons: a white balance gain below 1 leaves saturated
    # highlights at that gain (the tinted highlights of real cameras), not at the largest code
    out = apply_sensor(np.full((4, 4, 3), 1.6), Sensor(white_balance=(0.5, 1.0, 0.8), bits=16))
    np.testing.assert_array_equal(out[0, 0], np.round(np.array([0.5, 1.0, 0.8]) * 65535))


# ------------------------------------------------------------------------------------------ plain data


def test_sensor_plain_data_and_one_line_errors():
    for name, sensor in SENSORS.items():
        assert sensor.name == name and sensor.about
        assert recorded(sensor) == sensor
    bad = [
        ({"bits": 10}, "sensor.bits: got 10, expected one of 8, 12, 16"),
        ({"read_noise": 2.0}, "sensor.read_noise: got 2.0"),
        ({"cfa": "RGB"}, "sensor.cfa: got 'RGB'"),
        ({"response": "log"}, "sensor.response: got 'log'"),
        ({"white_balance": [1, 0, 1]}, "sensor.white_balance: got (1, 0, 1), expected three numbers > 0"),
        ({"vignetting": 1.0}, "sensor.vignetting: got 1.0, expected a number >= 0 and < 1"),
        ({"full_well": -3.0}, "sensor.full_well: got -3.0, expected a number > 0"),
        ({"colour": 1}, "sensor: unknown field(s) colour, expected"),
    ]
    for change, message in bad:
        with pytest.raises(ValueError) as err:
            Sensor.from_dict({**SENSORS["ideal"].to_dict(), **change})
        assert str(err.value).startswith(message) and "\n" not in str(err.value)
    # a folder written before the sensor model was made by the ideal sensor
    assert read_sensor_record({}, 3).sensor == SENSORS["ideal"]
    with pytest.raises(ValueError, match="noise_seeds: expected 3"):
        read_sensor_record({"sensor": {"model": SENSORS["ideal"].to_dict(), "seed": 0, "noise_seeds": [1]}}, 3)


# ------------------------------------------------------------------------------------------ wildgen.sensor


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    use_variant("llvm_ad_rgb")
    from wildgen.make import main

    out = tmp_path_factory.mktemp("sensor") / "DS"
    assert main(["--objects", "2", "--images", "3", "--res", "32", "--spp", "4", "--lights", "directional",
                 "--variant", "llvm_ad_rgb", "--quiet", "--out", str(out)]) == 0
    return out


def resensor(data: Path, out: Path, sensor: str, *extra: str) -> int:
    from wildgen.sensor import main

    return main(["--data", str(data), "--sensor", sensor, "--out", str(out), "--quiet", *extra])


def tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_ideal_reapplied_gives_the_rendered_images(dataset, tmp_path):
    assert resensor(dataset, tmp_path / "ideal", "ideal") == 0
    src, new = tree(dataset), tree(tmp_path / "ideal")
    images = [k for k in src if Path(k).name.startswith("L") and k.endswith(".png")]
    assert len(images) == 6
    for key in src:
        if not key.endswith("scene.json") and key != "manifest.json":
            assert new[key] == src[key], key  # the images and every other file, byte for byte
    scene = json.loads(new["00000.data/scene.json"])
    assert scene["sensor"]["model"] == SENSORS["ideal"].to_dict()


def test_reapply_records_rederives_and_is_deterministic(dataset, tmp_path, capsys):
    from scenes.folder.format import image_name, read_scene
    from scenes.images import read_exr
    from wildgen.dataset import verify_object

    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    assert resensor(dataset, a, "webcam") == 0
    assert resensor(dataset, b, "webcam") == 0
    assert tree(a) == tree(b)  # byte-identical reruns, manifest included
    assert resensor(dataset, c, "webcam", "--seed", "5") == 0
    manifest = json.loads((a / "manifest.json").read_text())
    assert manifest["sensor"]["name"] == "webcam" and manifest["config"]["sensor"] == "webcam"
    source = json.loads((dataset / "manifest.json").read_text())
    for entry, old in zip(manifest["objects"], source["objects"]):
        assert verify_object(a, entry) is None  # the manifest's checksums are the files'
        assert entry["light_family"] == old["light_family"]
        folder = a / entry["folder"]
        desc, extras = read_scene(folder)
        rec = read_sensor_record(extras, len(desc.images))
        assert rec.sensor == SENSORS["webcam"] and len(set(rec.noise_seeds)) == len(desc.images)
        for i, image in enumerate(desc.images):
            name = image_name(i)
            pixels = read_png(folder / name)
            assert pixels.dtype == np.uint8 and png_bit_depth(folder / name) == 8
            radiance = read_exr(folder / "aux" / f"radiance_{i:03d}.exr")
            # any image is re-derived from what the folder records
            np.testing.assert_array_equal(
                rederive_image(radiance, image.exposure, rec.sensor, rec.noise_seeds[i]), pixels
            )
            assert (c / entry["folder"] / name).read_bytes() != (folder / name).read_bytes()  # another seed
        # camera_lights irradiance includes the exposure: scaled by the sensor's 1.15
        _, old_extras = read_scene(dataset / entry["folder"])
        old_irr = [l["irradiance"] for im in old_extras["camera_lights"] for l in im["directional"]]
        new_irr = [l["irradiance"] for im in extras["camera_lights"] for l in im["directional"]]
        assert old_irr and np.allclose(np.array(new_irr), 1.15 * np.array(old_irr))
    # refusals: one line, exit 2, nothing written
    capsys.readouterr()
    assert resensor(dataset, a, "phone") == 2
    assert resensor(dataset, tmp_path / "d", "nikon") == 2
    assert resensor(tmp_path / "missing", tmp_path / "e", "phone") == 2
    assert resensor(dataset, dataset / "inside", "phone") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all(line.startswith("error: ") for line in err)
    assert "--overwrite" in err[0] and "--sensor: got 'nikon'" in err[1] and "--data" in err[2] and "--out" in err[3]
    assert not (tmp_path / "d").exists() and not (dataset / "inside").exists()
    # --overwrite replaces the dataset
    assert resensor(dataset, a, "phone", "--overwrite") == 0
    assert json.loads((a / "manifest.json").read_text())["sensor"]["name"] == "phone"
    assert read_png(a / "00000.data" / "L000.png").dtype == np.uint8


def test_make_with_a_sensor_writes_what_wildgen_sensor_writes(dataset, tmp_path):
    """`wildgen.make --sensor NAME` and re-applying NAME to the ideal dataset give the same images and record
    (same scenes, same seeds): the sensor is a pure function of the recorded radiance, exposure and seed."""
    from wildgen.make import main

    made = tmp_path / "made"
    assert main(["--objects", "2", "--images", "3", "--res", "32", "--spp", "4", "--lights", "directional",
                 "--variant", "llvm_ad_rgb", "--quiet", "--sensor", "phone", "--out", str(made)]) == 0
    assert resensor(dataset, tmp_path / "re", "phone") == 0
    a, b = tree(made), tree(tmp_path / "re")
    pngs = [k for k in a if Path(k).name.startswith("L") and k.endswith(".png")]
    assert len(pngs) == 6
    for key in pngs:
        assert a[key] == b[key], key
    scene_a = json.loads(a["00000.data/scene.json"])
    scene_b = json.loads(b["00000.data/scene.json"])
    assert scene_a["sensor"] == scene_b["sensor"] and scene_a["camera_lights"] == scene_b["camera_lights"]
    assert scene_a["sensor"]["model"]["bits"] == 8


@pytest.fixture(scope="module")
def sensor_datasets(dataset, tmp_path_factory):
    """The ideal dataset re-applied through a 12-bit linear and an 8-bit sRGB Bayer sensor."""
    root = tmp_path_factory.mktemp("sensors")
    for name in ("machine-vision", "phone"):
        assert resensor(dataset, root / name, name) == 0
    return root


@pytest.mark.parametrize("name,tolerance", [("machine-vision", None), ("phone", 0.15)])
def test_readers_undo_a_recorded_sensor_for_the_check(dataset, sensor_datasets, name, tolerance):
    """The check compares light: the one reader linearises a recorded sensor (response, black level, white
    balance, vignetting); the model's view keeps the file values, as a camera wrote them."""
    from scenes.folder.format import read_scene
    from scenes.folder.layouts import read_folder
    from scenes.images import read_exr
    from unips.data import load_object
    from validate.observations import load_capture

    folder = sensor_datasets / name / "00000.data"
    fd = read_folder(folder)
    assert fd.sensor is not None and fd.sensor.name == name
    desc, _ = read_scene(folder)
    truth = np.stack([read_exr(folder / "aux" / f"radiance_{i:03d}.exr") * im.exposure
                      for i, im in enumerate(desc.images)])  # (K, H, W, 3) light, before the sensor
    lin = load_capture(folder).images
    m = fd.mask & (truth.mean(axis=(0, 3)) > 0.05) & (truth.max(axis=(0, 3)) < 0.95)  # lit, never clipped
    t = truth[:, m]
    rel = np.abs(lin[:, m] - t).mean() / t.mean()
    assert abs((lin[:, m] - t).mean()) / t.mean() < 0.05  # no bias left by the response or the black level
    if tolerance is None:  # linear, no mosaic: what is left is the noise, E|N(0, s)| = s sqrt(2 / pi)
        sigma = np.sqrt(t * fd.sensor.full_well + fd.sensor.read_noise ** 2) / fd.sensor.full_well
        expected = np.sqrt(2 / np.pi) * sigma.mean() / t.mean()
        assert 0.8 * expected < rel < 1.25 * expected, (rel, expected)
    else:
        assert rel < tolerance, rel  # noise, 8-bit codes and demosaicing at 32 px
    raw = load_object(folder).images
    raw_rel = np.abs(raw[:, m] - t).mean() / t.mean()
    assert raw_rel > 2 * rel  # the file values are not light: linearising matters
    ideal = read_folder(dataset / "00000.data")
    assert ideal.sensor is None and np.array_equal(ideal.linear(), ideal.images)


def test_twelve_bit_saturation_is_detected(sensor_datasets, tmp_path):
    """A 12-bit file in a 16-bit PNG tops out at 65520: that is its clipped value, not 65535."""
    import shutil

    import cv2

    from scenes.folder.layouts import read_folder

    folder = tmp_path / "o.data"
    shutil.copytree(sensor_datasets / "machine-vision" / "00000.data", folder)
    img = cv2.imread(str(folder / "L000.png"), cv2.IMREAD_UNCHANGED)
    img[:4, :4] = 65520
    assert cv2.imwrite(str(folder / "L000.png"), img)
    fd = read_folder(folder)
    assert fd.saturated is not None and fd.saturated[0, :4, :4].all()
    assert np.array_equal(fd.saturated[0], img[..., ::-1] == 65520)  # exactly the channels at the largest code
