"""The dataset generator end to end through its CLI, and the layout contract of an object folder."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
from fixtures import use_variant

from wildgen.light_families import LIGHT_FAMILIES

FAMILIES = list(LIGHT_FAMILIES)
SMALL = ["--objects", str(len(FAMILIES)), "--images", "3", "--res", "32", "--spp", "4", "--gt-spp", "4", "--quiet"]


def make(out: Path, *extra: str) -> int:
    from wildgen.make import main

    return main(["--out", str(out), *SMALL, *extra])


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    use_variant("llvm_ad_rgb")
    out = tmp_path_factory.mktemp("ds") / "data"
    assert make(out, "--lights", ",".join(FAMILIES), "--seed", "7", "--variant", "llvm_ad_rgb") == 0
    return out


def test_every_family_end_to_end(dataset):
    manifest = json.loads((dataset / "manifest.json").read_text())
    assert manifest["config"]["lights"] == FAMILIES and manifest["seed"] == 7 and manifest["variant"] == "llvm_ad_rgb"
    assert {"mitsuba", "drjit", "unips-toolkit"} <= set(manifest["versions"])
    families = [o["light_family"] for o in manifest["objects"] if o["status"] == "done"]
    assert families == FAMILIES
    for entry in manifest["objects"]:
        folder = dataset / entry["folder"]
        for rel, digest in entry["files"].items():
            from wildgen.writer import sha256_file

            assert sha256_file(folder / rel) == digest
        scene = json.loads((folder / "scene.json").read_text())
        types = {l["type"] for im in scene["images"] for l in im["lights"]}
        expected = {"directional": {"directional"}, "point": {"point"}, "near_area": {"area"}, "hdri": {"environment"}}
        if entry["light_family"] in expected:
            assert expected[entry["light_family"]] <= types
    assert not list(dataset.glob(".tmp-*"))


def test_layout_contract(dataset):
    import cv2

    from scenes.images import read_exr

    for folder in sorted(dataset.glob("*.data")):
        names = sorted(p.name for p in folder.iterdir())
        assert names == ["L000.png", "L001.png", "L002.png", "aux", "mask.png", "normal.tif", "scene.json"]
        for i in range(3):
            img = cv2.imread(str(folder / f"L{i:03d}.png"), cv2.IMREAD_UNCHANGED)
            assert img.dtype == np.uint16 and img.shape == (32, 32, 3)
        mask = cv2.imread(str(folder / "mask.png"), cv2.IMREAD_UNCHANGED)
        assert mask.dtype == np.uint8 and mask.ndim == 2 and set(np.unique(mask)) <= {0, 255} and (mask > 0).sum() > 50
        enc = cv2.imread(str(folder / "normal.tif"), cv2.IMREAD_UNCHANGED)[:, :, ::-1]
        assert enc.dtype == np.uint16 and enc.shape == (32, 32, 3)
        n = enc.astype(np.float64) / 65535 * 2 - 1
        inside = mask > 0
        assert np.allclose(np.linalg.norm(n[inside], axis=-1), 1, atol=2e-3)
        assert np.all(enc[~inside] == 32768)
        assert (n[inside][:, 2] > -0.05).mean() > 0.99  # visible normals face the camera (+z)
        scene = json.loads((folder / "scene.json").read_text())
        for key in ("shape", "material", "camera", "render", "images", "light_family", "camera_lights"):
            assert key in scene
        for i, im in enumerate(scene["images"]):
            assert im["exposure"] > 0 and isinstance(im["seed"], int)
            rad = read_exr(folder / "aux" / f"radiance_{i:03d}.exr")
            png = cv2.imread(str(folder / f"L{i:03d}.png"), cv2.IMREAD_UNCHANGED)[:, :, ::-1]
            expect = np.round(np.clip(rad * im["exposure"], 0, 1) * 65535)
            assert np.array_equal(png, expect.astype(np.uint16))
        for aux in ("normal.exr", "depth.exr", "base_color.exr", "roughness.exr", "metallic.exr", "mesh.ply"):
            assert (folder / "aux" / aux).is_file()
        # Nothing the official UniPS training loader would delete sits at the top.
        for forbidden in ("baseColor.tif", "roughness.tif", "metal.tif", "depth.exr"):
            assert not (folder / forbidden).exists()


def test_scene_json_reproduces_the_images(dataset):
    """Re-rendering from scene.json alone: same seed gives the same radiance, another seed agrees within noise."""
    from scenes.description import SceneDescription
    from scenes.images import read_exr
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_image

    folder = dataset / "00002.data"
    scene = json.loads((folder / "scene.json").read_text())
    desc = SceneDescription.from_dict({k: v for k, v in scene.items() if k not in ("camera_lights", "format_version")})
    built = build_scene(desc, base_dir=folder)
    mask = read_exr(folder / "aux" / "coverage.exr")[:, :, 0] > 0.999
    for i in range(len(desc.images)):
        original = read_exr(folder / "aux" / f"radiance_{i:03d}.exr")
        assert np.array_equal(render_image(built, i), original)
        again = render_image(built, i, spp=64, seed=12345)
        rel = np.abs(again[mask] - original[mask]).mean() / original[mask].mean()
        assert rel < 0.35, rel  # 4 spp originals are noisy; a wrong scene is off by far more


def test_same_seed_gives_byte_identical_folders(dataset, tmp_path):
    out = tmp_path / "again"
    assert make(out, "--lights", ",".join(FAMILIES), "--seed", "7", "--variant", "llvm_ad_rgb") == 0
    for folder in sorted(dataset.glob("*.data")):
        files = sorted(p.relative_to(folder) for p in folder.rglob("*") if p.is_file())
        other = sorted(p.relative_to(out / folder.name) for p in (out / folder.name).rglob("*") if p.is_file())
        assert files == other
        for rel in files:
            assert (folder / rel).read_bytes() == (out / folder.name / rel).read_bytes(), rel


def test_entropy_rule_rejects_a_flat_plane(np_rng):
    from scenes.procedural import generate
    from wildgen.sampling import random_rotation, visible_normal_entropy

    plane = generate("plane", 0, 8)
    sphere = generate("blob", 0, 32, {"amplitude": 0.0})
    for _ in range(5):
        R = random_rotation(np_rng)
        assert visible_normal_entropy(plane, R) < 0.5
        assert visible_normal_entropy(sphere, R) > 6.0


def test_preview_writes_sheets(dataset, tmp_path):
    import cv2

    from wildgen.preview import main

    assert main([str(dataset), "--out", str(tmp_path / "pv")]) == 0
    overview = cv2.imread(str(tmp_path / "pv" / "overview.png"))
    assert overview is not None and overview.std() > 5
    assert len(list((tmp_path / "pv").glob("0*.png"))) == len(FAMILIES)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--lights", "laser"], "--lights"),
        (["--res", "0"], "--res"),
        (["--spp", "-1"], "--spp"),
        (["--assets", "/no/such/folder"], "--assets"),
    ],
)
def test_bad_flags_one_line_error(tmp_path, capsys, args, needle):
    from wildgen.make import main

    rc = main(["--out", str(tmp_path / "o"), "--objects", "1", "--quiet", *args])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.startswith("error:") and needle in err and "\n" not in err
    assert not list((tmp_path / "o").glob("*.data")) if (tmp_path / "o").exists() else True


def test_a_relative_assets_folder_is_found_again_by_a_resume_from_another_folder(tmp_path, monkeypatch, capsys):
    """Sweep 33 (b33-mk-01): `--out o --assets assets` typed in one folder, then `--resume --objects 2` from another:
    the manifest had recorded 'assets' as typed, and the resume was refused ("folder 'assets' does not exist")."""
    import trimesh

    from wildgen.make import main

    (tmp_path / "assets" / "meshes").mkdir(parents=True)
    trimesh.creation.icosphere(subdivisions=2).export(tmp_path / "assets" / "meshes" / "ball.ply")
    tiny = ["--images", "3", "--res", "16", "--spp", "1", "--gt-spp", "1", "--workers", "0", "--quiet",
            "--lights", "directional"]
    monkeypatch.chdir(tmp_path)
    assert main(["--out", "o", "--assets", "assets", "--shapes", "mesh", "--objects", "1", *tiny]) == 0
    manifest = json.loads((tmp_path / "o" / "manifest.json").read_text())
    assert manifest["config"]["assets"] == str(tmp_path / "assets")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    assert main(["--out", str(tmp_path / "o"), "--objects", "2", "--resume", *tiny]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "o").glob("*.data")) == ["00000.data", "00001.data"]
    scene = json.loads((tmp_path / "o" / "00001.data" / "scene.json").read_text())
    assert scene["shape"]["kind"] == "mesh", scene["shape"]


def test_texture_sets_named_as_poly_haven_and_ambientcg_name_them(tmp_path):
    """Map names as the two CC0 libraries write them: colour, roughness and OpenGL normal maps found; a DirectX normal
    map (green axis flipped) is never taken for an OpenGL one (the set keeps none)."""
    import cv2

    from wildgen.assets import AssetLibrary

    tex = tmp_path / "textures"
    tex.mkdir()
    names = ["wood_diff_1k", "wood_rough_1k", "wood_nor_gl_1k", "wood_nor_dx_1k", "Bricks076_1K-PNG_Color",
             "Bricks076_1K-PNG_Roughness", "Bricks076_1K-PNG_NormalDX", "Bricks076_1K-PNG_Displacement"]
    for n in names:
        assert cv2.imwrite(str(tex / f"{n}.png"), np.full((4, 4, 3), 128, np.uint8))
    sets = {ts.name: ts for ts in AssetLibrary.scan(tmp_path).textures}
    wood, bricks = sets["textures/wood"], sets["textures/bricks076_1k-png"]
    assert (wood.base_color.name, wood.roughness.name, wood.normal.name) == (
        "wood_diff_1k.png", "wood_rough_1k.png", "wood_nor_gl_1k.png")
    assert (bricks.base_color.name, bricks.roughness.name, bricks.normal) == (
        "Bricks076_1K-PNG_Color.png", "Bricks076_1K-PNG_Roughness.png", None)


def test_an_obj_of_relative_indices_reads_as_the_same_mesh_written_absolute(tmp_path):
    """Faces that count back from the vertices defined before them (`f -3 -1 -2`, as streaming exporters write) are
    the faces of the absolute file (trimesh alone resolves them against the end of the file)."""
    from scenes.meshes import load_mesh

    rel = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -1 -2\nv 0 0 1\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n"
    ab = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 3 2\nv 0 0 1\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    (tmp_path / "rel.obj").write_text(rel)
    (tmp_path / "abs.obj").write_text(ab)
    a, b = load_mesh(tmp_path / "rel.obj"), load_mesh(tmp_path / "abs.obj")
    assert np.array_equal(a.faces, b.faces) and np.array_equal(a.positions, b.positions) and len(a.faces) == 4


def test_bad_asset_folder_leaves_no_partial_object(tmp_path, capsys, variant_llvm_ad_rgb):
    assets = tmp_path / "assets"
    (assets / "meshes").mkdir(parents=True)
    (assets / "meshes" / "broken.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    out = tmp_path / "o"
    rc = make(out, "--assets", str(assets), "--shapes", "mesh", "--objects", "1")
    err = capsys.readouterr().err.strip().splitlines()
    assert rc != 0 and err and "broken.obj" in err[-1]
    assert not list(out.glob("*.data")) and not list(out.glob(".tmp-*"))


def test_with_shared_assets(shared, tmp_path, variant_llvm_ad_rgb):
    out = tmp_path / "a"
    assert (
        make(
            out,
            "--assets",
            str(shared / "assets"),
            "--lights",
            "hdri",
            "--shapes",
            "mesh",
            "--objects",
            "2",
            "--seed",
            "3",
        )
        == 0
    )
    for folder in sorted(out.glob("*.data")):
        scene = json.loads((folder / "scene.json").read_text())
        assert scene["environment"]["file"].startswith("aux/environment.hdr")
        assert (folder / "aux" / "environment.hdr").is_file()


def test_light_family_table_is_the_one_list():
    """Every family of the table has a description and a sampler whose lights make a valid scene; the
    configuration check, `wildgen.make --help` and the demo's subset read the same table."""
    import wildgen.config
    from orchestrate.demo import FAMILIES as DEMO_FAMILIES
    from scenes.description import CameraDesc, EnvironmentDesc, ImageDesc, SceneDescription
    from wildgen.light_families import Placement, sample_lighting
    from wildgen.make import COMMAND

    assert wildgen.config.LIGHT_FAMILIES is LIGHT_FAMILIES
    helptext = "".join(COMMAND.help().split())
    assert "{" + ",".join(LIGHT_FAMILIES) + "}" in helptext
    assert set(DEMO_FAMILIES.split(",")) <= set(LIGHT_FAMILIES)
    placement = Placement(np.zeros(3), 0.8, CameraDesc(origin=[0.0, 0.0, 20.0]), 0.3)
    for name, family in LIGHT_FAMILIES.items():
        assert family.description.strip(), name
        lights = sample_lighting(np.random.default_rng(0), name, 4, placement)
        desc = SceneDescription(images=[ImageDesc(lights=ls) for ls in lights], environment=EnvironmentDesc(),
                                light_family=name)
        desc.validate()
    with pytest.raises(ValueError, match="--lights: unknown family 'laser', expected one of directional, point"):
        sample_lighting(np.random.default_rng(0), "laser", 1, placement)
    with pytest.raises(ValueError, match="--lights.*laser.*" + ", ".join(LIGHT_FAMILIES)):
        wildgen.config.GenConfig(lights=["laser"]).validate()


def test_camera_lights_refuse_an_unknown_light_type():
    """scene.json's camera_lights goes through the light-type table: a type it does not know is an error naming
    it, not an 'other' light."""
    from scenes.description import ImageDesc, SceneDescription
    from scenes.lights import DirectionalLight, PointLight
    from wildgen.writer import camera_lights

    @dataclasses.dataclass(kw_only=True)
    class Spot(PointLight):
        type: ClassVar[str] = "spot"

    desc = SceneDescription(images=[ImageDesc(lights=[DirectionalLight(direction=[0.0, 0.0, -1.0]),
                                                      PointLight()], exposure=2.0)])
    (entry,) = camera_lights(desc)
    assert entry["other"] == 1 and len(entry["directional"]) == 1
    np.testing.assert_allclose(entry["directional"][0]["direction_to_light"], [0, 0, 1])
    assert entry["directional"][0]["irradiance"] == [2.0, 2.0, 2.0]
    desc.images[0].lights[1] = Spot()
    with pytest.raises(
        ValueError, match="unknown light type 'spot', expected one of directional, point, area, environment"
    ):
        camera_lights(desc)


def test_a_stopped_make_is_no_dataset_until_it_is_finished(tmp_path):
    """Sweep 26: a make stopped (SIGTERM) after 8 of 40 objects was predicted as an 8-object dataset, exit 0: its
    manifest said nothing of being unfinished. It says complete: false until the run's end, and every reader
    refuses it; the same command finishes it, and then it reads."""
    from scenes.folder.layouts import find_object_folders
    from wildgen.config import GenConfig
    from wildgen.dataset import make_dataset

    use_variant("llvm_ad_rgb")
    cfg = GenConfig(lights=["directional"], objects=2, images=2, width=16, height=16, spp=1, gt_spp=1)

    def stop(entry: dict) -> None:  # Ctrl-C once the first object is recorded
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        make_dataset(cfg, tmp_path / "ds", "llvm_ad_rgb", stop)
    manifest = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert manifest["complete"] is False and [e["status"] for e in manifest["objects"]] == ["done"]
    with pytest.raises(ValueError, match="is an incomplete dataset"):
        find_object_folders(tmp_path / "ds", "--data")
    make_dataset(cfg, tmp_path / "ds", "llvm_ad_rgb")
    assert json.loads((tmp_path / "ds" / "manifest.json").read_text())["complete"] is True
    assert len(find_object_folders(tmp_path / "ds", "--data")) == 2
