"""One reader for every folder layout: the model's loader (`unips.data`), the fitted check (`validate.observations`)
and the known-scene check (`validate.io`) see the same images, mask, ground truth and lights, and refuse the
same bad folders with the same one-line errors.

Each test below was a divergence between three hand-written readers: it fails on a tree where they differ.
The folders are written here with OpenCV / OpenEXR / SciPy (an analytic sphere), not by the code under test.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fixtures import write_diligent, write_ours, write_png16, write_unips

from scenes.folder.layouts import LAYOUT_TABLE, LAYOUTS, MIN_NORMAL_LENGTH, detect_layout, read_folder
from scenes.images import write_exr
from unips.data import load_ground_truth, load_object
from validate.observations import load_capture


def _readers():
    return {"unips.data": load_object, "validate.observations": load_capture}


def _edit_camera_lights(folder: Path, edit) -> None:
    scene = json.loads((folder / "scene.json").read_text())
    edit(scene["camera_lights"])
    (folder / "scene.json").write_text(json.dumps(scene))


def test_table_names_and_detection(tmp_path):
    assert LAYOUTS == tuple(entry.name for entry in LAYOUT_TABLE) == ("ours", "diligent", "unips")
    write_ours(tmp_path / "a.data")
    write_diligent(tmp_path / "bPNG")
    write_unips(tmp_path / "c")
    assert [detect_layout(tmp_path / p) for p in ("a.data", "bPNG", "c")] == ["ours", "diligent", "unips"]
    (tmp_path / "a.data" / "scene.json").unlink()
    assert detect_layout(tmp_path / "a.data") == "unips"  # our folder without its scene file


@pytest.mark.parametrize("layout", ["ours", "diligent", "unips"])
def test_every_view_sees_the_same_folder(tmp_path, layout):
    folder = tmp_path / "obj"
    if layout == "ours":
        n, mask, L, irr, imgs = write_ours(folder)
    elif layout == "diligent":
        n, mask, L, irr, imgs = write_diligent(folder)
    else:
        n, mask, imgs = write_unips(folder, gt="mat")
    obj, cap, gt = load_object(folder), load_capture(folder), load_ground_truth(folder)
    assert obj.layout == cap.layout == gt.layout == layout
    assert obj.image_names == cap.image_names
    assert np.array_equal(obj.mask, cap.mask) and np.array_equal(obj.mask, gt.mask) and np.array_equal(obj.mask, mask)
    assert np.array_equal(obj.normals, cap.normal_gt) and np.array_equal(obj.normals, gt.normals)
    assert np.degrees(np.arccos(np.clip(np.sum(obj.normals[mask] * n[mask], -1), -1, 1))).max() < 0.1
    assert np.abs(obj.images - imgs).max() < 1e-4  # raw images, as written
    if layout == "diligent":  # the check sees them divided by the intensity file, with unit irradiance
        assert np.allclose(cap.images * irr[:, None, None, :], obj.images, atol=1e-5)
        assert np.allclose(cap.light_irradiance, 1.0)
    else:
        assert np.array_equal(cap.images, obj.images)
    if layout == "unips":
        assert obj.light_directions is None and cap.light_directions is None
    else:
        assert np.allclose(obj.light_directions, L, atol=1e-5) and np.array_equal(
            obj.light_directions, cap.light_directions
        )


def test_malformed_camera_light_is_a_clean_error_in_every_reader(tmp_path):
    folder = tmp_path / "o.data"
    write_ours(folder)
    _edit_camera_lights(folder, lambda cam: cam[2]["directional"][0].pop("irradiance"))
    for name, reader in _readers().items():
        with pytest.raises(ValueError, match=r"camera_lights\[2\].directional\[0\]: irradiance"):
            reader(folder)


def test_zero_camera_light_direction_is_refused_in_every_reader(tmp_path):
    folder = tmp_path / "o.data"
    write_ours(folder)
    _edit_camera_lights(folder, lambda cam: cam[1]["directional"][0].__setitem__("direction_to_light", [0, 0, 0]))
    for name, reader in _readers().items():
        with pytest.raises(ValueError, match=r"camera_lights\[1\].*zero vector"):
            reader(folder)


def test_a_huge_camera_light_direction_keeps_its_direction(tmp_path):
    """A direction whose squared length overflows (1e308 per axis) is still a direction: read as (1, 1, 1) / sqrt 3,
    where it became (0, 0, 0) with a numpy overflow warning and was used as a light."""
    import warnings

    folder = tmp_path / "o.data"
    write_ours(folder)
    _edit_camera_lights(folder, lambda cam: cam[1]["directional"][0].__setitem__("direction_to_light", [1e308] * 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for name, reader in _readers().items():
            assert np.allclose(reader(folder).light_directions[1], 1 / np.sqrt(3)), name


def test_camera_light_count_mismatch_is_refused_in_every_reader(tmp_path):
    folder = tmp_path / "o.data"
    write_ours(folder)
    _edit_camera_lights(folder, lambda cam: cam.pop())
    for name, reader in _readers().items():
        with pytest.raises(ValueError, match="camera_lights has 5 entries, expected a list of 6"):
            reader(folder)


def test_exr_only_unips_folder_is_read_by_every_reader(tmp_path):
    folder = tmp_path / "exr"
    n, mask, imgs = write_unips(folder, exr=True)
    assert detect_layout(folder) == "unips"
    obj, cap = load_object(folder), load_capture(folder)
    assert np.allclose(obj.images, imgs * 3.0, atol=1e-6) and np.array_equal(obj.images, cap.images)
    assert cap.saturated is None  # float radiance is never clipped


def test_float_images_must_be_finite_non_negative_and_not_mixed(tmp_path):
    folder = tmp_path / "exr"
    write_unips(folder, exr=True)
    img = np.full((24, 24, 3), 0.5, np.float32)
    img[3, 4, 1] = np.nan
    write_exr(folder / "L02.exr", img)
    for reader in _readers().values():
        with pytest.raises(ValueError, match=r"L02.exr: contains NaN"):
            reader(folder)
    img[3, 4, 1] = -0.25
    write_exr(folder / "L02.exr", img)
    for reader in _readers().values():
        with pytest.raises(ValueError, match=r"L02.exr: has negative values"):
            reader(folder)
    write_exr(folder / "L02.exr", np.abs(img))
    write_png16(folder / "L05.png", np.zeros((24, 24, 3)))
    for reader in _readers().values():
        with pytest.raises(ValueError, match="mixes float EXR .* and integer .*L05.png"):
            reader(folder)


def test_ground_truth_names_and_short_normals_are_one_rule(tmp_path):
    folder = tmp_path / "u"
    n, mask, _ = write_unips(folder, gt="mat")
    ys, xs = np.nonzero(mask)
    short = n.copy()
    short[ys[0], xs[0]] *= 0.3  # shorter than MIN_NORMAL_LENGTH: "no normal", in every reader
    short[ys[1], xs[1]] *= 0.7  # long enough: renormalised, in every reader
    import scipy.io

    scipy.io.savemat(folder / "Normal_gt.mat", {"Normal_gt": short})
    assert 0.3 < MIN_NORMAL_LENGTH < 0.7
    obj, cap, gt = load_object(folder), load_capture(folder), load_ground_truth(folder)
    for normals in (obj.normals, cap.normal_gt, gt.normals):
        assert normals is not None  # Normal_gt.mat in a UniPS folder: read by all
        assert np.array_equal(normals[ys[0], xs[0]], [0, 0, 0])
        assert np.allclose(normals[ys[1], xs[1]], n[ys[1], xs[1]], atol=1e-6)
    assert np.array_equal(obj.normals, cap.normal_gt)


def test_huge_ground_truth_values_do_not_overflow(tmp_path):
    folder = tmp_path / "u"
    n, mask, _ = write_unips(folder, gt=None)
    np.save(folder / "big.npy", n * 1e30)
    from scenes.folder.layouts import finish_normals
    from scenes.images import read_normals

    out = finish_normals(read_normals(folder / "big.npy"), mask, folder / "big.npy")
    assert np.allclose(out[mask], n[mask], atol=1e-6)


def test_folder_errors_name_the_callers_argument(tmp_path):
    with pytest.raises(FileNotFoundError, match="^--data: "):
        load_capture(tmp_path / "missing")
    with pytest.raises(FileNotFoundError, match="^--data: .* is not an object folder"):
        load_capture(tmp_path)
    with pytest.raises(FileNotFoundError, match="^path: "):
        load_object(tmp_path / "missing")
    ours = tmp_path / "o.data"
    write_ours(ours)
    (ours / "mask.png").unlink()
    with pytest.raises(FileNotFoundError, match="mask file .*mask.png does not exist"):
        read_folder(ours)


def test_max_images_cuts_lights_after_checking_all(tmp_path):
    folder = tmp_path / "d"
    n, mask, L, inten, imgs = write_diligent(folder, k=6)
    fd = read_folder(folder, max_images=4)
    assert fd.num_files == 6 and len(fd.image_paths) == 4 and fd.images.shape[0] == 4
    assert np.allclose(fd.lights.directions, L[:4], atol=1e-5)
    assert np.allclose(fd.lights.intensities, inten[:4], atol=1e-5)
    for bad in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="max_images"):
            read_folder(folder, max_images=bad)


def test_captures_without_information_are_refused_by_every_reader(tmp_path):
    black = tmp_path / "black"
    write_unips(black)
    for f in black.glob("L*.png"):
        write_png16(f, np.zeros((24, 24, 3)))
    white = tmp_path / "white"
    write_unips(white)
    for f in white.glob("L*.png"):
        write_png16(f, np.ones((24, 24, 3)))
    for reader in _readers().values():
        with pytest.raises(ValueError, match="every image .* is black inside the object mask"):
            reader(black)
        with pytest.raises(ValueError, match="every image .* is one flat value|saturated"):
            reader(white)
    one_dark = tmp_path / "one_dark"  # a single dark image among lit ones is a capture, not an error
    write_unips(one_dark)
    write_png16(one_dark / "L00.png", np.zeros((24, 24, 3)))
    assert load_object(one_dark).num_images == 5


def test_masks_are_binary_after_the_alpha_rule(tmp_path):
    """A mask is 0 outside the object and one other value on it, read from its alpha where that is not fully opaque,
    else from its colour (issue 50). Today's files of every kind still read; a soft alpha, a cut-out whose colour
    fills the frame, a JPEG, a grey level everywhere are each one line saying what was found."""
    import cv2
    from PIL import Image

    from scenes.images import read_mask

    yy, xx = np.mgrid[:20, :24]
    m = (yy - 10) ** 2 + (xx - 12) ** 2 < 49
    v8 = np.where(m, 255, 0).astype(np.uint8)
    white = np.full_like(v8, 255)

    def read(name: str, data: np.ndarray) -> np.ndarray:
        assert cv2.imwrite(str(tmp_path / name), data)
        return read_mask(tmp_path / name)

    # a cut-out: colour white everywhere, the object in the alpha (by the "any channel > 0" rule: the whole frame)
    assert np.array_equal(read("cutout.png", np.stack([white, white, white, v8], -1)), m)
    Image.fromarray(np.stack([white, v8], -1), "LA").save(tmp_path / "la.png")  # grey + alpha
    assert np.array_equal(read_mask(tmp_path / "la.png"), m)
    # opaque alpha: the colour is the mask; a colour mask counts its largest channel
    assert np.array_equal(read("opaque.png", np.stack([v8, v8, v8, white], -1)), m)
    assert np.array_equal(read("red.png", np.stack([0 * v8, 0 * v8, v8], -1)), m)
    for name, data in (("one.png", m.astype(np.uint8)), ("sixteen.png", m.astype(np.uint16) * 65535),
                       ("sixteen_low.png", m.astype(np.uint16) * 300), ("bits.tif", v8)):
        assert np.array_equal(read(name, data), m), name
    assert read("white.png", white).all()  # all white: the whole frame is the object
    for name, data, words in (
        ("soft.png", np.stack([white, white, white, cv2.GaussianBlur(v8, (5, 5), 0)], -1),
         "(read from its alpha channel, which is not fully opaque): is not binary"),
        ("grey.png", np.full_like(v8, 7), ": is 7 everywhere; expected 0 outside the object"),
        ("code3.png", np.where(m, 255, 3).astype(np.uint8), ": holds two values, 3 and 255, and no 0"),
        ("labels.png", np.where(m, np.where(xx < 12, 100, 200), 0).astype(np.uint8), "3 distinct values (0, 100, 200)"),
        ("empty.png", 0 * v8, ": is empty"),
    ):
        with pytest.raises(ValueError, match=r"^mask file .*" + name.replace(".", r"\.")) as err:
            read(name, data)
        assert words in str(err.value) and "\n" not in str(err.value), (name, str(err.value))
    Image.fromarray(v8).save(tmp_path / "saved.jpg", quality=75)
    with pytest.raises(ValueError, match=r"saved.jpg: is not binary: .* a JPEG: .* save the mask as PNG"):
        read_mask(tmp_path / "saved.jpg")
    # our own object folders (scenes.images.write_mask, what wildgen.make writes) read back as written
    from scenes.images import write_mask

    write_mask(tmp_path / "ours.png", m)
    assert np.array_equal(read_mask(tmp_path / "ours.png"), m)


def test_a_diligent_listing_from_a_windows_editor_reads_the_same(tmp_path):
    """filenames.txt with a byte-order mark, CRLF line ends and trailing blanks names the same images (sweep 9)."""
    from scenes.folder.layouts import diligent_images

    (tmp_path / "filenames.txt").write_bytes(b"\xef\xbb\xbf001.png\r\n002.png  \r\n\r\n")
    assert diligent_images(tmp_path) == [tmp_path / "001.png", tmp_path / "002.png"]
