"""The light families added for real rigs and hard cases (verse, flash, frontal, grid96, light_stage, display) and
the capture presets of `wildgen.presets` through `wildgen.make`. Renders are tiny (32 px, 4 spp, 3 images)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from fixtures import render_dataset, use_variant

from scenes.description import CameraDesc
from wildgen.light_families import LIGHT_FAMILIES, Placement
from wildgen.presets import PRESETS

NEW_FAMILIES = ["verse", "flash", "frontal", "grid96", "light_stage", "display"]
SMALL = ["--images", "3", "--res", "32", "--spp", "4", "--gt-spp", "4", "--quiet", "--workers", "0",
         "--variant", "llvm_ad_rgb"]
ORTHO = CameraDesc(origin=[0.0, 0.0, 20.0])
PERSPECTIVE = CameraDesc(kind="perspective", origin=[0.0, 0.0, 4.0], fov=30.0)


def make(out: Path, *extra: str) -> int:
    from wildgen.make import main

    return main(["--out", str(out), *extra])


@pytest.fixture(scope="module")
def families(tmp_path_factory) -> Path:
    use_variant("llvm_ad_rgb")
    out = tmp_path_factory.mktemp("families") / "data"
    assert (
        make(out, "--lights", ",".join(NEW_FAMILIES), "--objects", str(len(NEW_FAMILIES)), "--seed", "5", *SMALL) == 0
    )
    return out


def scene_of(folder: Path) -> dict:
    return json.loads((folder / "scene.json").read_text())


def test_every_new_family_renders_and_is_recorded(families):
    from scenes.description import SceneDescription
    from scenes.images import read_exr
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_image

    expected = {"verse": {"environment", "uniform", "point", "area"}, "flash": {"point", "environment"},
                "frontal": {"point", "uniform"}, "grid96": {"directional"}, "light_stage": {"directional"},
                "display": {"area"}}
    manifest = json.loads((families / "manifest.json").read_text())
    assert [o["light_family"] for o in manifest["objects"]] == NEW_FAMILIES
    for folder, family in zip(sorted(families.glob("*.data")), NEW_FAMILIES):
        scene = scene_of(folder)
        assert scene["light_family"] == family
        types = {l["type"] for im in scene["images"] for l in im["lights"]}
        assert types <= expected[family], (family, types)
        assert len(scene["camera_lights"]) == 3
        desc = SceneDescription.from_dict(
            {k: v for k, v in scene.items() if k not in ("camera_lights", "format_version")}
        )
        built = build_scene(desc.validate(), base_dir=folder)
        for i in range(3):  # re-renderable from scene.json alone, byte for byte
            assert np.array_equal(render_image(built, i), read_exr(folder / "aux" / f"radiance_{i:03d}.exr")), (
                family,
                i,
            )


def test_new_families_pass_the_rerender_check_with_true_normals(families):
    """The known-scene check rebuilds every light of these families (a uniform background included) and reports
    it in its type's camera-frame form; the true normals reproduce the images."""
    from validate.observations import load_known_scene
    from validate.rerender import RerenderConfig, rerender_object

    for folder, family in zip(sorted(families.glob("*.data")), NEW_FAMILIES):
        if family not in ("verse", "frontal", "display"):
            continue
        obj = load_known_scene(folder)
        report = rerender_object(folder, obj.normal_gt, RerenderConfig(seed_mode="same"))
        assert report["reproduce_rel_l1"] == 0.0, family
        assert report["mae_deg"] < 0.01 and report["rel_l1"] < 0.5 * report["noise_floor_rel_l1"], family
        types = {l["type"] for ls in report["lights"] for l in ls}
        assert types == {l["type"] for im in scene_of(folder)["images"] for l in im["lights"]}


def test_verse_draws_its_recipe(np_rng):
    """Per image: exactly one background (environment map or uniform), 0-3 point lights, 0-1 rectangle; over
    many images every count occurs."""
    placement = Placement(np.zeros(3), 1.0, ORTHO, env_scale=0.3)
    points, areas, backgrounds = set(), set(), set()
    for i in range(200):
        lights = LIGHT_FAMILIES["verse"].sample(np_rng, placement, i, 200)
        kinds = [l.type for l in lights]
        assert kinds[0] in ("environment", "uniform") and kinds.count("environment") + kinds.count("uniform") == 1
        assert set(kinds[1:]) <= {"point", "area"}
        points.add(kinds.count("point"))
        areas.add(kinds.count("area"))
        backgrounds.add(kinds[0])
    assert points == {0, 1, 2, 3} and areas == {0, 1} and backgrounds == {"environment", "uniform"}


def test_frontal_light_stays_near_the_viewing_direction():
    from wildgen.light_families import FRONTAL_CONE_DEG

    centre = np.array([0.1, -0.2, 0.05])
    placement = Placement(centre, 0.9, ORTHO, env_scale=0.3)
    rng = np.random.default_rng(3)
    angles, ambient = [], []
    for i in range(100):
        lamp, amb = LIGHT_FAMILIES["frontal"].sample(rng, placement, i, 100)
        d = np.asarray(lamp.position) - centre
        angles.append(math.degrees(math.acos(d[2] / np.linalg.norm(d))))
        assert 5 * 0.9 - 1e-9 <= np.linalg.norm(d) <= 10 * 0.9 + 1e-9
        assert amb.type == "uniform"
        ambient.append(amb.radiance * math.pi)
    assert max(angles) <= FRONTAL_CONE_DEG and max(angles) > 0.8 * FRONTAL_CONE_DEG
    assert 0 <= min(ambient) < 0.1 and 0.9 < max(ambient) <= 1.0


def test_fixed_patterns_give_image_i_light_i_whatever_the_rng():
    """grid96, light_stage and display draw nothing: image i gets light i of the pattern."""
    for name in ("grid96", "light_stage", "display"):
        for camera in (ORTHO, PERSPECTIVE):
            p = Placement(np.zeros(3), 1.0, camera, env_scale=0.3)
            a = [LIGHT_FAMILIES[name].sample(np.random.default_rng(1), p, i, 20) for i in range(20)]
            rng = np.random.default_rng(2)
            b = [LIGHT_FAMILIES[name].sample(rng, p, i, 20) for i in range(20)]
            assert a == b, name
            assert rng.random() == np.random.default_rng(2).random()  # nothing drawn


def test_grid96_spans_diligents_lights():
    """96 distinct directions toward the camera side, zenith 0-43.3 degrees, a 12 x 8 grid of (x / z, y / z)."""
    p = Placement(np.zeros(3), 1.0, ORTHO, env_scale=0.3)
    dirs = np.array([-np.asarray(LIGHT_FAMILIES["grid96"].sample(None, p, i, 96)[0].direction) for i in range(96)])
    assert np.allclose(np.linalg.norm(dirs, axis=1), 1)
    zenith = np.degrees(np.arccos(dirs[:, 2]))
    assert zenith.max() == pytest.approx(math.degrees(math.atan(math.hypot(0.8, 0.5))), abs=1e-9) and zenith.min() > 2
    u, v = dirs[:, 0] / dirs[:, 2], dirs[:, 1] / dirs[:, 2]
    assert len(np.unique(u.round(9))) == 12 and len(np.unique(v.round(9))) == 8
    assert len({tuple(d) for d in dirs.round(9)}) == 96
    again = -np.asarray(LIGHT_FAMILIES["grid96"].sample(None, p, 96 + 5, 200)[0].direction)
    np.testing.assert_allclose(again, dirs[5])  # image 101 starts the pattern over
    # The first 10 images already spread over the grid: most columns, every row band, both sides.
    assert len(np.unique(u[:10].round(9))) >= 8 and len(np.unique(v[:10].round(9))) >= 6
    assert u[:10].min() < -0.4 and u[:10].max() > 0.4 and v[:10].min() < -0.2 and v[:10].max() > 0.2


def test_light_stage_spreads_its_lights_evenly():
    from wildgen.light_families import LIGHT_STAGE_MIN_Z

    p = Placement(np.zeros(3), 1.0, ORTHO, env_scale=0.3)
    for count in (8, 64):
        dirs = np.array([-np.asarray(LIGHT_FAMILIES["light_stage"].sample(None, p, i, count)[0].direction)
                         for i in range(count)])
        assert np.allclose(np.linalg.norm(dirs, axis=1), 1)
        assert dirs[:, 2].min() >= LIGHT_STAGE_MIN_Z and dirs[0, 2] > 0.9  # light 0 nearest the view axis
        # Even area: as many lights in each half of the z range (equal-area zones of the sphere).
        mid = (1 + LIGHT_STAGE_MIN_Z) / 2
        assert abs((dirs[:, 2] > mid).sum() - count / 2) <= 1
        cos = dirs @ dirs.T - 2 * np.eye(count)
        assert cos.max() < 0.999  # no two lights coincide


def test_display_patches_are_on_the_screen_and_out_of_view():
    from wildgen.light_families import SCREEN_DISTANCE, SCREEN_GRID, _occludes_view, display_patches

    centre = np.array([0.0, 0.1, 0.0])
    for camera, expected in ((PERSPECTIVE, SCREEN_GRID[0] * SCREEN_GRID[1]), (ORTHO, 6)):
        p = Placement(centre, 1.0, camera, env_scale=0.3)
        patches = display_patches(p)
        assert len(patches) == expected  # the orthographic camera sees through the middle columns
        for i, (pos, w, h) in enumerate(patches):
            (light,) = LIGHT_FAMILIES["display"].sample(None, p, i, len(patches))
            assert light.type == "area" and light.position == pos.tolist()
            assert light.position[2] == pytest.approx(centre[2] + SCREEN_DISTANCE)  # the screen plane
            np.testing.assert_allclose(np.subtract(light.target, light.position), [0, 0, -1])  # faces the object
            assert not _occludes_view(pos, 0.5 * math.hypot(w, h), camera)
            r = np.linalg.norm(pos - centre)
            # Irradiance at the centre (small-source approximation) is the nominal 1.
            assert light.radiance * w * h * (SCREEN_DISTANCE / r) / r**2 == pytest.approx(1.0)


# ------------------------------------------------------------------------------------------------ presets


def resolve(*argv: str):
    from wildgen.make import _explicit_flags, options_from_args

    args = ["--out", "o", *argv]
    return options_from_args(args, _explicit_flags(args)).gen.validate()


def test_each_preset_sets_its_entry_and_nothing_else():
    """--preset NAME gives the configuration without a preset with the entry's values set, every other field
    at its default; each entry names a light family and a sensor that exist, and says what it imitates."""
    from dataclasses import replace

    from scenes.camera_sensor import sensor_named
    from wildgen.light_families import light_family

    assert list(PRESETS) == ["diligent", "phone-flash", "light-stage", "display"]  # the names of --preset
    plain = resolve()
    for name, preset in PRESETS.items():
        assert resolve("--preset", name) == replace(plain, preset=name, **preset.overrides()), name
        assert sensor_named(preset.config.sensor).name == preset.config.sensor, name
        assert all(light_family(f) for f in preset.config.lights), name
        assert preset.about.strip()


def _dirs_to_light(lights) -> np.ndarray:
    return np.array([-np.asarray(l.direction) for l in lights])


def test_presets_configure_the_rigs_they_imitate(np_rng):
    """What each preset's configuration makes, checked against the rig it names (not against the table):
    phone-flash a point light at the camera of a perspective view, written as a phone writes (8-bit sRGB,
    Bayer mosaic, noise, vignetting); light-stage one distant light per image, all different; display one
    screen patch per image, as many images as a perspective camera leaves patches, written by a webcam
    (8 bits, Bayer, noise, vignetting); diligent and light-stage a linear machine-vision camera
    (orthographic, 12 significant bits: DiLiGenT's 16-bit PNGs)."""
    from scenes.camera_sensor import SENSORS
    from wildgen.light_families import display_patches

    flash = resolve("--preset", "phone-flash")
    assert flash.camera == "perspective"
    p = Placement(np.zeros(3), 1.0, PERSPECTIVE, env_scale=0.3)
    for i in range(flash.images):
        lamp = LIGHT_FAMILIES[flash.lights[0]].sample(np_rng, p, i, flash.images)[0]
        assert lamp.type == "point" and lamp.position == list(PERSPECTIVE.origin)
    for name in ("phone-flash", "display"):
        sensor = SENSORS[resolve("--preset", name).sensor]
        assert sensor.bits == 8 and sensor.cfa != "none" and sensor.full_well and sensor.vignetting > 0, name
        assert sensor.response != "linear", name
    assert SENSORS[flash.sensor].response == "srgb"

    stage = resolve("--preset", "light-stage")
    p = Placement(np.zeros(3), 1.0, ORTHO, env_scale=0.3)
    lights = [LIGHT_FAMILIES[stage.lights[0]].sample(None, p, i, stage.images) for i in range(stage.images)]
    assert all(len(ls) == 1 and ls[0].type == "directional" for ls in lights)
    assert len({tuple(d) for d in _dirs_to_light(l[0] for l in lights).round(6)}) == stage.images

    display = resolve("--preset", "display")
    assert display.camera == "perspective"
    p = Placement(np.zeros(3), 1.0, PERSPECTIVE, env_scale=0.3)
    assert display.images == len(display_patches(p))
    for i in range(display.images):
        (patch,) = LIGHT_FAMILIES[display.lights[0]].sample(None, p, i, display.images)
        assert patch.type == "area" and patch.position == display_patches(p)[i][0].tolist()

    for name in ("diligent", "light-stage"):
        cfg = resolve("--preset", name)
        sensor = SENSORS[cfg.sensor]
        assert cfg.camera == "orthographic" and sensor.response == "linear" and sensor.cfa == "none", name
        assert sensor.bits == 12, name


def test_diligent_preset_renders_diligents_96_lights(tmp_path, variant_llvm_ad_rgb):
    """A dataset made with --preset diligent (only the resolution and samples made small) has DiLiGenT's
    612 x 512 frame in its configuration and 96 images per object, each lit by one distant light of DiLiGenT's
    12 x 8 LED grid: directions toward (x / z, y / z) on 12 evenly spaced columns over +-0.8 and 8 rows over
    +-0.5 (zenith up to 43.3 deg), computed here; every light once."""
    cfg = resolve("--preset", "diligent")
    assert (cfg.width, cfg.height, cfg.images) == (612, 512, 96)
    (folder,) = render_dataset(tmp_path / "d", "--preset", "diligent", "--objects", "1", "--res", "8", "--spp", "1",
                               "--gt-spp", "1", "--variant", "llvm_ad_rgb")
    assert len(list(folder.glob("L*.png"))) == 96
    scene = scene_of(folder)
    assert scene["camera"]["kind"] == "orthographic" and scene["sensor"]["model"]["name"] == "machine-vision"
    cams = scene["camera_lights"]
    assert len(cams) == 96 and all(len(c["directional"]) == 1 and c["other"] == 0 for c in cams)
    got = np.array([c["directional"][0]["direction_to_light"] for c in cams])
    grid = np.array([[u, v, 1.0] for u in np.linspace(-0.8, 0.8, 12) for v in np.linspace(-0.5, 0.5, 8)])
    grid /= np.linalg.norm(grid, axis=1, keepdims=True)
    nearest = np.linalg.norm(got[:, None] - grid[None], axis=-1).argmin(1)
    assert np.allclose(got, grid[nearest], atol=1e-9) and sorted(nearest) == list(range(96))
    assert math.degrees(math.acos(grid[:, 2].min())) == pytest.approx(43.3, abs=0.05)


def test_explicit_flags_override_the_preset():
    cfg = resolve("--preset", "diligent", "--images", "4", "--res", "32", "--sensor", "ideal")
    assert (cfg.lights, cfg.images, cfg.width, cfg.height, cfg.sensor, cfg.camera) == \
        (["grid96"], 4, 32, 32, "ideal", "orthographic")
    cfg = resolve("--lights", "verse", "--preset", "phone-flash", "--height", "100")
    assert (cfg.lights, cfg.width, cfg.height, cfg.camera) == (["verse"], 256, 100, "perspective")
    assert resolve().preset is None and resolve().lights == ["near_area"]  # no preset: today's defaults


def test_unknown_preset_is_a_one_line_error(tmp_path, capsys):
    rc = make(tmp_path / "o", "--preset", "studio", "--quiet")
    err = capsys.readouterr().err.strip()
    assert (
        rc == 2 and err.startswith("error: --preset:") and "'studio'" in err and "diligent" in err and "\n" not in err
    )
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_preset_is_recorded_in_the_manifest_and_resumes(tmp_path, variant_llvm_ad_rgb):
    out = tmp_path / "d"
    args = ["--preset", "diligent", "--objects", "1", "--images", "2", "--width", "24", "--height", "20", "--spp", "1",
            "--gt-spp", "1", "--quiet", "--workers", "0"]
    assert make(out, *args) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["preset"] == "diligent" and manifest["config"]["lights"] == ["grid96"]
    assert manifest["config"]["sensor"] == "machine-vision" and manifest["config"]["images"] == 2
    scene = scene_of(out / "00000.data")
    assert (
        scene["camera"]["width"] == 24
        and scene["camera"]["height"] == 20
        and scene["sensor"]["model"]["name"] == "machine-vision"
    )
    assert make(out, *args) == 0  # the same command again: the same configuration, nothing re-rendered
    assert make(out, "--resume", "--quiet", "--workers", "0") == 0


def test_sixty_four_images_per_object(tmp_path, variant_llvm_ad_rgb):
    """64 images of an object (16 px): every image written and read back; the busiest images of verse need
    slots of every light type it uses."""
    from scenes.folder.layouts import read_folder

    out = tmp_path / "k64"
    assert make(out, "--lights", "light_stage,verse", "--objects", "2", "--images", "64", "--res", "16", "--spp", "1",
                "--gt-spp", "1", "--quiet", "--workers", "0", "--variant", "llvm_ad_rgb") == 0
    for folder in sorted(out.glob("*.data")):
        data = read_folder(folder)
        assert data.images.shape[0] == 64 and len(data.image_paths) == 64
        assert len(scene_of(folder)["images"]) == 64


def test_the_families_lit_by_the_environment_map_are_those_named(np_rng):
    """`ENVIRONMENT_FAMILIES` is what wildgen.make's --env-width rule reads (a flag that shapes a map no image uses
    is refused): over many draws a family lights some image with the environment map exactly when it is named."""
    from wildgen.light_families import ENVIRONMENT_FAMILIES

    placement = Placement(np.zeros(3), 1.0, ORTHO, env_scale=0.3)
    for name, family in LIGHT_FAMILIES.items():
        used = any(light.environment_map for i in range(60) for light in family.sample(np_rng, placement, i, 60))
        assert used == (name in ENVIRONMENT_FAMILIES), name
