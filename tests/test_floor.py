"""`wildgen.make --floor`: the object stands on a flat textured surface seen around it. The surface is in the images
only: the mask, normals and depth are the object's alone (those of the same object rendered without it), lights are
never under it, and the images are re-rendered byte for byte from scene.json."""
from __future__ import annotations

import json

import numpy as np
import pytest
from fixtures import render_dataset, use_variant

FLAGS = ("--objects", "3", "--images", "3", "--res", "48", "--spp", "4", "--gt-spp", "4", "--shapes", "procedural",
         "--seed", "3", "--margin", "0.6", "--lights", "directional,point,directional")


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    use_variant("llvm_ad_rgb")
    root = tmp_path_factory.mktemp("floor")
    return render_dataset(root / "with", *FLAGS, "--floor", "1"), render_dataset(root / "without", *FLAGS)


def test_the_floor_is_in_the_images_and_not_in_the_truth(pair):
    from scipy.ndimage import binary_dilation

    from scenes.images import read_exr, read_mask, read_normals

    with_floor, without = pair
    assert len(with_floor) == len(without) == 3  # (no environment light: without a floor the background is black)
    seen_around = 0
    for a, b in zip(with_floor, without):
        scene_a, scene_b = (json.loads((f / "scene.json").read_text()) for f in (a, b))
        assert "floor" not in scene_b and scene_a["floor"]["size"] > 0  # older scenes read the same
        # the same object, pose and material with and without the floor (its own random stream)
        assert scene_a["shape"] == scene_b["shape"] and scene_a["material"] == scene_b["material"]
        mask = read_mask(a / "mask.png")
        assert np.array_equal(mask, read_mask(b / "mask.png"))
        assert np.array_equal(read_normals(a / "normal.tif"), read_normals(b / "normal.tif"))
        assert np.array_equal(read_exr(a / "aux" / "depth.exr"), read_exr(b / "aux" / "depth.exr"))
        # away from the object the frame is black without a floor and lit where the floor shows
        away = ~binary_dilation(mask, iterations=2)
        outside_a = np.mean([read_exr(a / "aux" / f"radiance_{i:03d}.exr")[away].mean() for i in range(3)])
        outside_b = np.mean([read_exr(b / "aux" / f"radiance_{i:03d}.exr")[away].mean() for i in range(3)])
        assert outside_b == 0.0
        seen_around += outside_a > 0.01
    assert seen_around == 3


def test_no_light_is_under_the_floor(pair):
    with_floor, _ = pair
    for folder in with_floor:
        scene = json.loads((folder / "scene.json").read_text())
        n, o = np.array(scene["floor"]["normal"]), np.array(scene["floor"]["point"])
        for image in scene["images"]:
            for light in image["lights"]:
                if light["type"] == "directional":  # it travels down onto the floor, from above it
                    assert np.dot(light["direction"], n) <= 1e-9
                elif light["type"] in ("point", "area"):
                    assert np.dot(np.array(light["position"]) - o, n) >= -1e-9


def test_a_scene_with_a_floor_renders_again_from_its_scene_json(pair):
    from scenes.description import SceneDescription
    from scenes.images import read_exr
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_image

    folder = pair[0][0]
    scene = json.loads((folder / "scene.json").read_text())
    desc = SceneDescription.from_dict({k: v for k, v in scene.items() if k not in ("camera_lights", "format_version")})
    assert desc.floor is not None and SceneDescription.from_json(desc.to_json()) == desc
    built = build_scene(desc, base_dir=folder)
    for i in range(len(desc.images)):
        assert np.array_equal(render_image(built, i), read_exr(folder / "aux" / f"radiance_{i:03d}.exr"))


def test_a_bad_floor_is_one_line_naming_the_field():
    from scenes.description import FloorDesc, SceneDescription

    with pytest.raises(ValueError, match=r"floor\.normal: got \[0, 0, 0\], expected a non-zero vector"):
        FloorDesc(normal=[0, 0, 0]).validate()
    with pytest.raises(ValueError, match=r"floor: unknown field\(s\) colour"):
        SceneDescription.from_dict({"floor": {"colour": 1}})


def test_lights_under_the_floor_are_mirrored_above_it():
    """Directional, point and area lights below the floor's plane move to their mirror image above it; those above
    stay as they are."""
    from scenes.description import FloorDesc
    from scenes.lights import AreaLight, DirectionalLight, PointLight
    from wildgen.sampling import above_floor

    floor = FloorDesc(point=[0.0, -1.0, 0.0], normal=[0.0, 1.0, 0.0])
    below = [DirectionalLight(direction=[0.0, 0.6, -0.8]), PointLight(position=[1.0, -3.0, 2.0]),
             AreaLight(position=[0.0, -2.0, 3.0], target=[0.0, -1.5, 0.0])]
    up = above_floor(below, floor)
    assert np.allclose(up[0].direction, [0.0, -0.6, -0.8]) and np.allclose(up[1].position, [1.0, 1.0, 2.0])
    assert np.allclose(up[2].position, [0.0, 0.0, 3.0]) and np.allclose(up[2].target, [0.0, -0.5, 0.0])
    above = [DirectionalLight(direction=[0.0, -0.6, -0.8]), PointLight(position=[0.0, 2.0, 3.0])]
    assert above_floor(above, floor) == above and above_floor(below, None) == below
