"""Focal range of the generator (`wildgen.make --camera perspective --focal A-B`): the recorded focal length and
field of view agree with the 35 mm-equivalent definition, and aux/view.exr holds, per pixel, the reverse of the
ray Mitsuba's own perspective sensor traces through the pixel centre (an independent camera model)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from fixtures import render_dataset


def test_fov_from_focal_matches_the_35mm_definition():
    from scenes.description import fov_from_focal

    # A 36 mm wide frame: 50 mm gives 39.6 deg, 15 mm 100.4 deg, 300 mm 6.87 deg (textbook values).
    assert fov_from_focal(50) == pytest.approx(39.60, abs=0.01)
    assert fov_from_focal(15) == pytest.approx(100.39, abs=0.01)
    assert fov_from_focal(300) == pytest.approx(6.87, abs=0.01)


def test_camera_record_refuses_a_focal_length_that_does_not_match_its_fov():
    from scenes.description import CameraDesc

    with pytest.raises(ValueError, match="camera.fov"):
        CameraDesc(kind="perspective", fov=30.0, focal_mm=50.0).validate()
    with pytest.raises(ValueError, match="camera.focal_mm"):
        CameraDesc(kind="orthographic", focal_mm=50.0).validate()


@pytest.fixture(scope="module")
def perspective_set(tmp_path_factory):
    return render_dataset(tmp_path_factory.mktemp("focal") / "ds", "--objects", "3", "--images", "2", "--res", "24",
                          "--spp", "4", "--gt-spp", "4", "--camera", "perspective", "--focal", "15-300", "--lights",
                          "point", "--seed", "5")


def test_focal_lengths_are_drawn_in_range_and_recorded(perspective_set):
    from scenes.description import fov_from_focal
    from scenes.images import read_mask

    focals = []
    for folder in perspective_set:
        cam = json.loads((folder / "scene.json").read_text())["camera"]
        assert cam["kind"] == "perspective" and 15 <= cam["focal_mm"] <= 300
        assert cam["fov"] == pytest.approx(fov_from_focal(cam["focal_mm"]), abs=1e-9)
        # distance follows the field of view: the object fills the frame at every focal length
        assert cam["origin"][2] * math.tan(math.radians(cam["fov"] / 2)) == pytest.approx(
            4.0 * math.tan(math.radians(15))
        )
        mask = read_mask(folder / "mask.png")
        ys, xs = np.nonzero(mask)
        assert max(np.ptp(xs), np.ptp(ys)) + 1 >= 0.8 * mask.shape[1]
        focals.append(cam["focal_mm"])
    assert len(set(focals)) == len(focals)  # drawn per object


def test_view_directions_are_the_reverse_of_mitsubas_pixel_rays(perspective_set):
    import mitsuba as mi

    from scenes.folder.format import read_scene
    from scenes.geometry import camera_rotation
    from scenes.images import read_exr
    from scenes.renderer.build import sensor_dict
    from scenes.renderer.variant import choose_variant

    choose_variant("auto")
    for folder in perspective_set:
        desc, _ = read_scene(folder)
        cam = desc.camera
        view = read_exr(folder / "aux" / "view.exr")[..., :3]
        assert view.shape == (cam.height, cam.width, 3)
        np.testing.assert_allclose(np.linalg.norm(view, axis=-1), 1.0, atol=1e-5)
        sensor = mi.load_dict(sensor_dict(desc, 1))
        ii, jj = np.meshgrid(np.arange(cam.height), np.arange(cam.width), indexing="ij")
        uv = mi.Point2f(
            ((jj.ravel() + 0.5) / cam.width).astype(np.float32), ((ii.ravel() + 0.5) / cam.height).astype(np.float32)
        )
        ray, _ = sensor.sample_ray(0.0, 0.5, uv, mi.Point2f(0.5, 0.5))
        d_world = np.array(ray.d).reshape(3, -1).T if np.array(ray.d).shape[0] == 3 else np.array(ray.d).reshape(-1, 3)
        d_cam = d_world @ camera_rotation(cam.origin, cam.target, cam.up).T
        np.testing.assert_allclose(view.reshape(-1, 3), -d_cam, atol=2e-5)
        # the centre pixel looks almost straight along the axis, a corner at the half field of view's angle
        edge = view[cam.height // 2, 0]
        half_px = math.atan(math.tan(math.radians(cam.fov / 2)) * (1 - 1 / cam.width))
        assert math.degrees(math.acos(edge[2] / np.hypot(edge[0], edge[2]))) == pytest.approx(
            math.degrees(half_px), abs=1e-3
        )


def test_orthographic_view_is_the_axis(tmp_path):
    from scenes.description import CameraDesc
    from scenes.geometry import view_directions

    v = view_directions(CameraDesc(kind="orthographic", width=5, height=3))
    assert v.shape == (3, 5, 3) and np.all(v == np.float32([0, 0, 1]))
