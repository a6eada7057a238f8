"""Loaders (three layouts), preprocessing and normal-map files, on real files written here.

The objects are an analytic Lambertian sphere rendered with numpy under known directional lights,
written as 16-bit PNGs with OpenCV, so every value the loaders return has an independent answer.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from fixtures import (
    SHARED,
    SPHERE_ALBEDO,
    cone_lights,
    shading,
    sphere,
    sphere_images,
    write_diligent,
    write_mask,
    write_ours,
    write_png16,
)

from scenes.images import read_normals, write_normal_exr, write_normal_map, write_normal_visual
from scenes.metrics import angular_error_deg, mean_angular_error
from unips.data import PSObject, find_objects, load_ground_truth, load_object
from unips.preprocess import prepare, resize_prepared, uncrop

# ------------------------------------------------------------------------------------------ loaders


def test_load_ours_layout(tmp_path):
    n, mask, L, irr, imgs = write_ours(tmp_path / "ball.data")
    obj = load_object(tmp_path / "ball.data")
    assert obj.layout == "ours" and obj.name == "ball" and obj.light_family == "directional"
    assert obj.images.shape == (6, 32, 32, 3) and obj.images.dtype == np.float32
    # RGB order and 16-bit scaling: the written values come back within half a quantum.
    assert np.abs(obj.images - imgs).max() <= 0.5 / 65535 + 1e-7
    assert obj.images[..., 0].sum() > obj.images[..., 2].sum()  # albedo red > blue survives BGR->RGB
    assert np.array_equal(obj.mask, mask)
    assert np.abs(obj.normals[mask] - n[mask]).max() < 2e-4
    assert np.all(obj.normals[~mask] == 0)
    assert np.allclose(obj.light_directions, L, atol=1e-6)
    assert np.allclose(obj.light_intensities, irr, atol=1e-6)
    assert obj.image_names == [f"L{i:03d}.png" for i in range(6)]


def test_ours_with_upper_case_suffixes_reads_the_same(tmp_path):
    """A copy from a case-blind disk names the images L000.PNG: the same object; two files for one image refused."""
    n, mask, L, irr, imgs = write_ours(tmp_path / "ball.data")
    for p in sorted((tmp_path / "ball.data").glob("L*.png")):
        p.rename(p.with_suffix(".PNG"))
    obj = load_object(tmp_path / "ball.data")
    assert obj.layout == "ours" and obj.images.shape == (6, 32, 32, 3)
    assert np.abs(obj.images - imgs).max() <= 0.5 / 65535 + 1e-7
    assert np.allclose(obj.light_directions, L, atol=1e-6)
    (tmp_path / "ball.data" / "L2.png").write_bytes((tmp_path / "ball.data" / "L002.PNG").read_bytes())
    with pytest.raises(ValueError, match="two files for image 2"):
        load_object(tmp_path / "ball.data")


def test_ours_with_other_lights_has_no_directions(tmp_path):
    write_ours(tmp_path / "o.data", other=1)
    obj = load_object(tmp_path / "o.data")
    assert obj.light_directions is None and obj.light_intensities is None


def test_load_diligent_layout_keeps_raw_images(tmp_path):
    """Uncalibrated protocol: images exactly as recorded; the intensities only in light_intensities."""
    n, mask, L, inten, imgs = write_diligent(tmp_path / "sphPNG")
    obj = load_object(tmp_path / "sphPNG")
    assert obj.layout == "diligent" and obj.name == "sphPNG" and obj.light_family == "directional"
    shade = shading(n, L)
    expected = 0.9 * shade[..., None] * SPHERE_ALBEDO * inten[:, None, None, :]  # not divided by the intensities
    assert np.abs(obj.images - expected).max() < 2e-4
    assert np.allclose(obj.light_directions, L / np.linalg.norm(L, axis=1, keepdims=True), atol=1e-5)
    assert np.allclose(obj.light_intensities, inten, atol=1e-6)
    assert np.allclose(obj.meta["light_intensities_file"], inten, atol=1e-6)
    assert np.array_equal(obj.mask, mask)
    assert np.abs(obj.normals - n).max() < 1e-6


def test_diligent_normal_png_fallback(tmp_path):
    n, mask, *_ = write_diligent(tmp_path / "x", gt="png")
    obj = load_object(tmp_path / "x")
    assert mean_angular_error(obj.normals, n, mask) < 0.5  # 8-bit quantisation
    assert np.all(obj.normals[~mask] == 0)


def test_load_unips_layout_8bit_no_mask(tmp_path):
    folder = tmp_path / "u.data"
    folder.mkdir()
    n, mask = sphere(24)
    imgs = sphere_images(n, mask, cone_lights(4))
    for i, im in enumerate(imgs):
        assert cv2.imwrite(str(folder / f"L{i + 1}.png"), np.round(im * 255).astype(np.uint8)[..., ::-1])
    (folder / "L_notes.txt").write_text("not an image")
    enc = np.round((n + 1) / 2 * 255).astype(np.uint8)
    assert cv2.imwrite(str(folder / "Normal_gt.png"), enc[..., ::-1])
    obj = load_object(folder)
    assert obj.layout == "unips" and obj.name == "u" and obj.light_directions is None
    assert obj.images.shape == (4, 24, 24, 3)
    assert np.abs(obj.images - imgs).max() <= 0.5 / 255 + 1e-6
    assert obj.mask.all()  # no mask.png: the whole image
    assert mean_angular_error(obj.normals, n, mask) < 0.5


def test_max_images_natural_order(tmp_path):
    folder = tmp_path / "nat"
    folder.mkdir()
    for i in (1, 2, 10, 11):
        img = (
            np.full((8, 8, 3), i / 20.0) + np.linspace(0, 0.01, 8)[None, :, None]
        )  # not flat: flat captures are refused
        write_png16(folder / f"L{i}.png", img)
    obj = load_object(folder, max_images=3)
    assert obj.image_names == ["L1.png", "L2.png", "L10.png"]
    assert np.allclose(obj.images[:, 0, 0, 0], [0.05, 0.1, 0.5], atol=1e-4)


def test_find_objects(tmp_path):
    write_ours(tmp_path / "b.data")
    write_diligent(tmp_path / "a")
    (tmp_path / "junk").mkdir()
    assert [p.name for p in find_objects(tmp_path)] == ["a", "b.data"]
    assert find_objects(tmp_path / "a") == [tmp_path / "a"]
    with pytest.raises(FileNotFoundError, match="junk"):
        find_objects(tmp_path / "junk")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        find_objects(tmp_path / "nope")


def test_load_ground_truth(tmp_path):
    n, mask, *_ = write_ours(tmp_path / "g.data")
    gt = load_ground_truth(tmp_path / "g.data")
    assert gt.name == "g" and gt.light_family == "directional" and np.array_equal(gt.mask, mask)
    assert np.abs(gt.normals - n).max() < 2e-4


# ------------------------------------------------------------------------------------- bad input


def test_bad_inputs(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match="not an object folder"):
        load_object(empty)
    with pytest.raises(ValueError, match="layout"):
        load_object(empty, layout="weird")
    with pytest.raises(FileNotFoundError, match="no images"):
        load_object(empty, layout="unips")

    sizes = tmp_path / "sizes"
    sizes.mkdir()
    write_png16(sizes / "L0.png", np.zeros((8, 8, 3)))
    write_png16(sizes / "L1.png", np.zeros((8, 9, 3)))
    with pytest.raises(ValueError, match="L1.png.*differs"):
        load_object(sizes)

    badmask = tmp_path / "badmask"
    badmask.mkdir()
    write_png16(badmask / "L0.png", np.zeros((8, 8, 3)))
    write_mask(badmask / "mask.png", np.ones((9, 8), bool))
    with pytest.raises(ValueError, match="mask.png.*differs"):
        load_object(badmask)

    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / "L0.png").write_bytes(b"\x89PNG not really")
    with pytest.raises(ValueError, match="L0.png.*cannot be read"):
        load_object(corrupt)

    nan = tmp_path / "nan"
    write_diligent(nan)
    text = (nan / "light_directions.txt").read_text().splitlines()
    text[2] = "nan 0 1"
    (nan / "light_directions.txt").write_text("\n".join(text))
    with pytest.raises(ValueError, match="light_directions.*NaN"):
        load_object(nan)

    rows = tmp_path / "rows"
    write_diligent(rows)
    (rows / "light_intensities.txt").write_text("1 1 1\n" * 5)
    with pytest.raises(ValueError, match="light_intensities.*5 rows, expected 6"):
        load_object(rows)

    with pytest.raises(ValueError, match="max_images"):
        load_object(rows, max_images=0)

    # Both readers share scenes.folder.layouts: the fitted check refuses the same bad light files the model's
    # loader does (a zero direction used to become NaN lights there).
    from validate.observations import load_capture

    zero = tmp_path / "zero"
    write_diligent(zero)
    text = (zero / "light_directions.txt").read_text().splitlines()
    text[1] = "0 0 0"
    (zero / "light_directions.txt").write_text("\n".join(text))
    for reader in (load_object, load_capture):
        with pytest.raises(ValueError, match="light_directions.*row 2 is a zero vector"):
            reader(zero)
        with pytest.raises(ValueError, match="light_intensities.*5 rows, expected 6"):
            reader(rows)

    scene = tmp_path / "scene.data"
    write_ours(scene)
    (scene / "scene.json").write_text("{not json")
    with pytest.raises(ValueError, match="scene.json"):
        load_object(scene)


# ---------------------------------------------------------------------------------- real DiLiGenT


def test_real_diligent_ball_frame():
    folder = SHARED / "data" / "diligent" / "ballPNG"
    if not folder.is_dir():
        pytest.skip("../shared/data/diligent is not present")
    obj = load_object(folder, max_images=8)
    assert obj.images.shape == (8, 512, 612, 3) and obj.name == "ballPNG"
    assert obj.normals is not None and obj.mask.sum() > 10000
    # Same frame for lights and normals: gray intensity must follow max(0, n . l) (a flipped axis
    # would decorrelate it).
    gray = obj.images[:, obj.mask] @ np.array([0.2989, 0.587, 0.114], np.float32)
    shade = shading(obj.normals[obj.mask], obj.light_directions)
    corr = [np.corrcoef(gray[k], shade[k])[0, 1] for k in range(8)]
    assert min(corr) > 0.9, corr
    # The top of the ball faces up (+y), its left side faces left (-x).
    rows, cols = np.nonzero(obj.mask)
    top = obj.normals[rows.min() + 5, int(np.median(cols))]
    left = obj.normals[int(np.median(rows)), cols.min() + 5]
    assert top[1] > 0.8 and left[0] < -0.8


# ------------------------------------------------------------------------------------- preprocess


def _object(n, mask, k=3) -> PSObject:
    imgs = sphere_images(n, mask, cone_lights(k)).astype(np.float32)
    return PSObject(name="t", images=imgs, mask=mask, normals=n.astype(np.float32), light_family=None,
                    light_directions=None, light_intensities=None, path=Path("."), layout="test")


def test_prepare_crop_uncrop_round_trip():
    # Sphere near the top-left corner of a 40x52 frame: the crop must run past the image border.
    n_full = np.zeros((40, 52, 3))
    m_full = np.zeros((40, 52), bool)
    n_s, m_s = sphere(20, pad=0)
    n_full[:20, 1:21], m_full[:20, 1:21] = n_s, m_s
    obj = _object(n_full, m_full)
    obj.images[1] = 0.0  # a black image: the zero-mean guard must keep it finite
    p = prepare(obj, margin=4)
    rows, cols = np.nonzero(m_full)
    h, w = np.ptp(rows) + 1 + 8, np.ptp(cols) + 1 + 8
    assert p.crop.size == max(h, w) and p.images.shape == (3, p.crop.size, p.crop.size, 3)
    assert p.crop.y0 < 0 and p.crop.x0 < 0  # extends beyond the image
    assert p.mask.sum() == m_full.sum()
    assert np.all(np.isfinite(p.images))
    for k in (0, 2):
        assert np.isclose(p.images[k][p.mask].mean(), 1.0, atol=1e-5)
    assert np.all(p.images[1] == 0)
    back = uncrop(p.normals, p, full_shape=(40, 52))
    assert np.array_equal(back, obj.normals)  # exact


def test_resize_prepared():
    n, mask = sphere(40)
    p = prepare(_object(n, mask), margin=4)
    r = resize_prepared(p, 16)
    assert r.images.shape == (3, 16, 16, 3) and r.mask.shape == (16, 16) and r.normals.shape == (16, 16, 3)
    norms = np.linalg.norm(r.normals[r.mask], axis=1)
    assert np.allclose(norms, 1.0, atol=1e-5) and np.all(r.normals[~r.mask] == 0)
    # Back to the crop size and into the frame: close to the truth except at the silhouette.
    back = uncrop(r.normals, r, mask=mask)
    assert back.shape == (40, 40, 3)
    assert mean_angular_error(back, n, mask) < 6.0
    with pytest.raises(ValueError, match="size"):
        resize_prepared(p, 0)


# ------------------------------------------------------------------------------------- normal io


def test_normal_png_round_trip(tmp_path):
    n, mask = sphere(32)
    write_normal_map(tmp_path / "n.png", n)
    raw = cv2.imread(str(tmp_path / "n.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16 and np.all(raw[~mask] == 32768)
    back = read_normals(tmp_path / "n.png")
    assert np.abs(back - n).max() <= 1.0 / 65535 + 1e-6
    assert np.all(back[~mask] == 0)
    # RGB order on disk: x (right) is the first channel; a point on the right has red high.
    assert raw[16, 28, 2] > 60000


def test_normal_exr_npy_mat_round_trip(tmp_path):
    import scipy.io

    n, mask = sphere(16)
    n = n.astype(np.float32)
    write_normal_exr(tmp_path / "n.exr", n)
    assert np.array_equal(read_normals(tmp_path / "n.exr"), n)
    np.save(tmp_path / "n.npy", n)
    assert np.array_equal(read_normals(tmp_path / "n.npy"), n)
    scipy.io.savemat(tmp_path / "n.mat", {"Normal_gt": n})
    assert np.array_equal(read_normals(tmp_path / "n.mat"), n)
    write_normal_visual(tmp_path / "v.png", n)
    vis = cv2.imread(str(tmp_path / "v.png"), cv2.IMREAD_UNCHANGED)
    assert vis.dtype == np.uint8 and np.all(vis[~mask] == 0)


def test_exr_layers_windows_and_mat_kinds_are_read_as_what_they_hold(tmp_path):
    """Sweep 19: an EXR of one layer (beauty.R/G/B, as multilayer renderers write) was read by sorted channel name
    (blue as red); a data window shifted inside its display window was taken as the frame (the map 4 px off its
    mask); a complex .mat lost its imaginary part with a ComplexWarning. Now the layer is R, G, B; the shifted
    window and the complex map are refused naming the file."""
    import OpenEXR
    import scipy.io

    from scenes.images import read_exr

    n, _ = sphere(16)
    n = n.astype(np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    layer = {f"beauty.{c}": np.ascontiguousarray(n[..., i]) for i, c in enumerate("RGB")}
    with OpenEXR.File(header, dict(layer)) as f:
        f.write(str(tmp_path / "layer.exr"))
    assert np.array_equal(read_normals(tmp_path / "layer.exr"), n)
    assert np.array_equal(read_exr(tmp_path / "layer.exr"), n)
    two = {**layer, "diffuse.R": layer["beauty.R"]}
    with OpenEXR.File(header, dict(two)) as f:
        f.write(str(tmp_path / "two.exr"))
    with pytest.raises(ValueError, match=r"two.exr' holds several layers \(beauty, diffuse\)"):
        read_exr(tmp_path / "two.exr")
    shifted = {**header, "dataWindow": ((4, 4), (19, 19)), "displayWindow": ((0, 0), (15, 15))}
    with OpenEXR.File(shifted, {c: np.ascontiguousarray(n[..., i]) for i, c in enumerate("RGB")}) as f:
        f.write(str(tmp_path / "shifted.exr"))
    with pytest.raises(ValueError, match=r"shifted.exr.*data window \(\(4, 4\), \(19, 19\)\) is not its display"):
        read_normals(tmp_path / "shifted.exr", "--normals")
    scipy.io.savemat(tmp_path / "c.mat", {"Normal_gt": n.astype(np.complex128)})
    with pytest.raises(ValueError, match=r"^--normals: MAT file .*c.mat: 'Normal_gt' is complex128 \(complex\) values"):
        read_normals(tmp_path / "c.mat", "--normals")


def test_normal_io_bad_input(tmp_path):
    with pytest.raises(ValueError, match="shape"):
        write_normal_map(tmp_path / "a.png", np.zeros((4, 4)))
    bad = np.zeros((4, 4, 3))
    bad[1, 1, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        write_normal_exr(tmp_path / "a.exr", bad)
    np.save(tmp_path / "b.npy", np.zeros((4, 4, 2)))
    with pytest.raises(ValueError, match="shape"):
        read_normals(tmp_path / "b.npy")
    np.save(tmp_path / "c.npy", bad)
    with pytest.raises(ValueError, match="NaN"):
        read_normals(tmp_path / "c.npy")
    with pytest.raises(FileNotFoundError):
        read_normals(tmp_path / "missing.png")
    with pytest.raises(ValueError, match="extension"):
        (tmp_path / "x.jpg2").write_bytes(b"0")
        read_normals(tmp_path / "x.jpg2")


def test_angular_error_known_angle():
    n, mask = sphere(16)
    # Rotate every normal by exactly 20 degrees about an axis perpendicular to it.
    axis = np.cross(n, np.array([0.3, 0.5, 0.8]))
    axis /= np.maximum(np.linalg.norm(axis, axis=2, keepdims=True), 1e-12)
    t = np.radians(20.0)
    rot = n * np.cos(t) + np.cross(axis, n) * np.sin(t)
    rot[~mask] = 0
    err = angular_error_deg(rot, n, mask)
    assert np.allclose(err[mask], 20.0, atol=1e-4) and np.all(err[~mask] == 0)
    assert abs(mean_angular_error(2.5 * rot, n, mask) - 20.0) < 1e-4  # scale does not matter
    with pytest.raises(ValueError, match="empty"):
        mean_angular_error(rot, n, np.zeros_like(mask))


def test_object_folder_fixture_and_one_lookup_order(synthetic_object):
    """The shared fixture's folder loads as our layout; predictions are found in one order for everyone."""
    from scenes.folder.format import PREDICTION_FILES, find_prediction, object_name, prediction_file
    from scenes.images import read_mask

    obj = load_object(synthetic_object)
    assert obj.layout == "ours" and obj.name == object_name(synthetic_object) == "ball"
    assert np.array_equal(obj.mask, read_mask(synthetic_object / "mask.png"))
    assert obj.light_directions is not None and obj.num_images == 6
    pred = synthetic_object.parent / "pred" / "ball"
    write_normal_map(pred / "normal.png", obj.normals)
    assert prediction_file(pred).name == "normal.png"
    write_normal_exr(pred / "normal.exr", obj.normals)
    assert PREDICTION_FILES[0] == "normal.exr"
    assert prediction_file(pred).name == "normal.exr" == find_prediction(pred.parent, "ball").name
