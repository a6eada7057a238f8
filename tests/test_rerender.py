"""The re-render check (validate/): projection, the normal-swapping BSDF against analytic shading, visibility
against exact ray tests, noise floors, monotonic response to normal errors, bad inputs, and the CLI.

Scenes are tiny (32x32, a few spp, llvm variant); object folders are written here with the scenes API.
"""
from __future__ import annotations

import dataclasses
import gc
import json
import math
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
from fixtures import use_variant

from scenes.description import (
    CameraDesc,
    ImageDesc,
    MaterialDesc,
    RenderDesc,
    SceneDescription,
    ShapeDesc,
    TextureDesc,
)
from scenes.lights import AreaLight, DirectionalLight, EnvironmentLight, PointLight

R = 32


def write_object(desc: SceneDescription, out: Path, extra_files: dict[str, np.ndarray] | None = None) -> Path:
    """A minimal object folder as wildgen writes it (images with exposure, mask, normal.tif, scene.json
    with the extra top-level keys, aux/)."""
    from scenes.images import write_exr, write_mask, write_normal_map, write_png16
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_ground_truth, render_image

    folder = out / f"{desc.name}.data"
    (folder / "aux").mkdir(parents=True)
    for name, arr in (extra_files or {}).items():
        write_exr(folder / name, arr)
    built = build_scene(desc, folder)
    gt = render_ground_truth(built)
    for i, image in enumerate(desc.images):
        rad = render_image(built, i)
        image.exposure = float(0.8 / np.percentile(rad[gt.mask], 95))
        write_png16(folder / f"L{i:03d}.png", rad * image.exposure)
        write_exr(folder / "aux" / f"radiance_{i:03d}.exr", rad)
    normal = shading_normals(built)
    del built
    gc.collect()
    write_mask(folder / "mask.png", gt.mask)
    write_normal_map(folder / "normal.tif", np.where(gt.mask[..., None], normal, 0.0))
    scene = desc.to_dict()
    scene["camera_lights"] = [{"directional": [], "other": 1} for _ in desc.images]
    scene["format_version"] = 1
    (folder / "scene.json").write_text(json.dumps(scene))
    return folder


def shading_normals(built) -> np.ndarray:
    """Camera-frame pixel-mean shading normals straight from Mitsuba's `sh_normal` AOV (box filter).

    In Mitsuba 3.9 this AOV already includes a `normalmap` BSDF's perturbation (checked against
    photometric stereo on a normal-mapped Lambertian sphere: < 0.01 deg), so no normal map is applied on top.
    """
    import mitsuba as mi

    from scenes.geometry import camera_rotation

    built.park_lights()
    aov = mi.load_dict(
        {"type": "aov", "aovs": "nn:sh_normal", "integrator": {"type": "path", "max_depth": 1, "hide_emitters": True}}
    )
    out = np.array(mi.render(built.scene, integrator=aov, spp=64, seed=0), np.float64)
    built.apply_image(0)
    n = out[:, :, 4:7]
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    cam = built.desc.camera
    return (n @ camera_rotation(cam.origin, cam.target, cam.up).T).astype(np.float32)


def sphere_desc(name: str = "sphere", spp: int = 8, normal_map: str | None = None) -> SceneDescription:
    """Textured principled sphere under area lights: a scene whose residual is dominated by noise."""
    return SceneDescription(
        name=name,
        shape=ShapeDesc(kind="sphere"),
        material=MaterialDesc(
            kind="principled",
            base_color=TextureDesc(kind="noise", value=[0.8, 0.3, 0.2], value2=[0.2, 0.6, 0.8], resolution=64),
            roughness=TextureDesc(value=[0.4]),
            normal_map=normal_map,
        ),
        camera=CameraDesc(width=R, height=R, half_size=1.1),
        render=RenderDesc(spp=spp, bounces=2),
        images=[
            ImageDesc(lights=[AreaLight(position=[1.5, 1.0, 2.5], radiance=8.0, width=1.0, height=1.0)], seed=3),
            ImageDesc(
                lights=[
                    AreaLight(position=[-1.5, 0.5, 2.0], radiance=8.0, width=1.0, height=1.0),
                    DirectionalLight(direction=[0.3, -0.4, -1.0], irradiance=0.5),
                ],
                seed=4,
            ),
            ImageDesc(lights=[PointLight(position=[0.0, -2.0, 2.0], intensity=6.0)], seed=5),
        ],
    )


def torus_desc(camera_kind: str = "orthographic", width: int = R, height: int = R) -> SceneDescription:
    return SceneDescription(
        name="torus",
        shape=ShapeDesc(kind="torus", seed=1, resolution=32),
        material=MaterialDesc(kind="principled"),
        camera=CameraDesc(
            kind=camera_kind, width=width, height=height, half_size=1.1, origin=[0.5, 1.5, 4.0], fov=35.0
        ),
        render=RenderDesc(spp=8, bounces=2),
        images=[ImageDesc(lights=[DirectionalLight(direction=[0.3, -0.4, -1.0])], seed=1)],
    )


@pytest.fixture(scope="module")
def sphere_folder(tmp_path_factory) -> Path:
    use_variant("llvm_ad_rgb")  # the wrapper is a Python BSDF: it needs a JIT variant
    return write_object(sphere_desc(), tmp_path_factory.mktemp("data"))


# --- projection and visibility ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind,width,height", [("orthographic", 40, 32), ("perspective", 32, 40)])
def test_projection_matches_mitsuba_sensor(jit, kind, width, height):
    """Ray casts through sub-pixel centres reproduce Mitsuba's own coverage and depth (catches flips,
    half-pixel shifts and aspect errors), and projecting the hits gives back the pixel positions."""
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_ground_truth
    from validate.known.normal_bsdf import depth_map
    from validate.known.projection import CameraProjection

    desc = torus_desc(kind, width, height)
    built = build_scene(desc)
    gt = render_ground_truth(built, spp=64)
    cam = CameraProjection.from_camera(desc.camera)
    ss = 4
    dm = depth_map(built.scene, cam, ss)
    assert dm.shape == (height * ss, width * ss)
    hits = np.isfinite(dm).reshape(height, ss, width, ss)
    coverage = hits.mean(axis=(1, 3))
    assert np.abs(coverage - gt.coverage).mean() < 0.01
    full = hits.all(axis=(1, 3))
    depth = np.where(np.isfinite(dm), dm, 0).reshape(height, ss, width, ss).mean(axis=(1, 3))
    assert np.median(np.abs(depth - gt.depth)[full]) < 2e-3

    u = np.array([0.5, 3.25, width - 0.1])
    v = np.array([0.5, height / 2, 7.75])
    origins, dirs = cam.rays(u, v)
    pu, pv, pz = cam.project(origins + 3.0 * dirs)
    np.testing.assert_allclose(pu, u, atol=1e-9)
    np.testing.assert_allclose(pv, v, atol=1e-9)


def test_visibility_agrees_with_exact_ray_tests(jit, np_rng):
    """Random surface points reached from random directions: the depth-map test agrees with exact ray tests
    toward the camera (shadow ray + facing + inside the frame) on >= 99 % of them."""
    import drjit as dr

    mi = jit
    from scenes.renderer.build import build_scene
    from validate.known.normal_bsdf import NormalSwap, depth_map, wrapper_for
    from validate.known.projection import CameraProjection

    desc = torus_desc()
    cam = CameraProjection.from_camera(desc.camera)
    built = build_scene(desc, bsdf_wrapper=wrapper_for(cam))
    swap = NormalSwap.attach(built.params, cam)
    swap.set_depth(depth_map(built.scene, cam, swap.visibility.supersample))
    bsdf = built.scene.shapes()[0].bsdf()

    n = 40000
    d = np_rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np_rng.uniform(-1, 1, size=(n, 3)) - 5 * d
    ray = mi.Ray3f(mi.Point3f(o.T.astype(np.float32)), mi.Vector3f(d.T.astype(np.float32)))
    si = built.scene.ray_intersect(ray)
    valid = np.array(si.is_valid())
    visible, _, _ = bsdf.lookup(si.p, si.n, -ray.d, si.is_valid())
    to_cam = -mi.Vector3f(*cam.forward)
    facing = np.array(dr.dot(si.n, to_cam) * dr.dot(si.n, -ray.d) > 0)
    occluded = np.array(built.scene.ray_test(si.spawn_ray(to_cam)))
    u, v, _ = cam.project(np.array(si.p).T)
    inside = valid & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
    exact = inside & facing & ~occluded
    got = np.array(visible)
    assert inside.sum() > 10000 and 0.2 < exact[inside].mean() < 0.8  # a real mix of seen and hidden points
    assert (got == exact)[inside].mean() > 0.99


# --- the BSDF against analytic shading ------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["orthographic", "perspective"])
def test_swapped_normals_give_analytic_lambertian_shading(jit, kind):
    """Lambertian plane facing the camera, directional light: with a predicted map whose left half is tilted
    one way and right half another, each pixel is albedo / pi * E * max(0, n' . l) for its own half."""
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_ground_truth, render_image
    from validate.known.normal_bsdf import MODE_PREDICTED, NormalSwap, depth_map, wrapper_for
    from validate.known.projection import CameraProjection

    albedo, irradiance = 0.5, 2.0
    l = np.array([0.3, 0.2, 1.0])
    l /= np.linalg.norm(l)
    width, height = 40, 32  # non-square: aspect handled in the BSDF's projection too
    desc = SceneDescription(
        shape=ShapeDesc(kind="plane", resolution=8),
        material=MaterialDesc(kind="lambertian", base_color=TextureDesc(value=[albedo] * 3)),
        camera=CameraDesc(kind=kind, width=width, height=height, half_size=0.9, fov=28.0),
        render=RenderDesc(spp=4, bounces=1),
        images=[ImageDesc(lights=[DirectionalLight(direction=(-l).tolist(), irradiance=irradiance)])],
    )
    cam = CameraProjection.from_camera(desc.camera)
    built = build_scene(desc, bsdf_wrapper=wrapper_for(cam))
    gt = render_ground_truth(built)
    swap = NormalSwap.attach(built.params, cam)
    swap.set_depth(depth_map(built.scene, cam, swap.visibility.supersample))
    built.apply_image(0)

    a, b = math.radians(30), math.radians(50)
    n_left = np.array([-math.sin(a), 0.0, math.cos(a)])  # tilted away from the light in x
    n_right = np.array([0.0, -math.sin(b), math.cos(b)])  # tilted away from the light in y
    pred = np.zeros((height, width, 3))
    pred[:, : width // 2] = n_left
    pred[:, width // 2 :] = n_right
    swap.set_normals(pred, gt.mask)
    swap.set_mode(MODE_PREDICTED)
    img = render_image(built, 0)

    interior = gt.coverage == 1.0
    interior[1:-1] &= gt.coverage[:-2] == 1.0
    interior[1:-1] &= gt.coverage[2:] == 1.0
    interior[:, 1:-1] &= (gt.coverage[:, :-2] == 1.0) & (gt.coverage[:, 2:] == 1.0)
    cols = np.arange(width)
    left = interior & (cols < width // 2 - 1)[None, :]
    right = interior & (cols > width // 2)[None, :]
    assert left.sum() > 50 and right.sum() > 50
    for region, nrm in ((left, n_left), (right, n_right)):
        expected = albedo / math.pi * irradiance * max(0.0, float(nrm @ l))
        np.testing.assert_allclose(img[region], expected, rtol=2e-3)
    # The unchanged plane would be much brighter on both sides: the swap really happened.
    unchanged = albedo / math.pi * irradiance * l[2]
    assert img[left].mean() < 0.8 * unchanged and img[right].mean() < 0.8 * unchanged


def test_passthrough_mode_is_bit_identical_to_the_original(jit, sphere_folder):
    from scenes.folder.format import read_scene
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_image
    from validate.known.normal_bsdf import NormalSwap, depth_map, wrapper_for
    from validate.known.projection import CameraProjection

    desc, _ = read_scene(sphere_folder / "scene.json")
    built = build_scene(desc, sphere_folder)
    original = [render_image(built, i) for i in range(len(desc.images))]
    del built
    gc.collect()
    cam = CameraProjection.from_camera(desc.camera)
    built = build_scene(desc, sphere_folder, bsdf_wrapper=wrapper_for(cam))
    swap = NormalSwap.attach(built.params, cam)
    swap.set_depth(depth_map(built.scene, cam, swap.visibility.supersample))
    for i, ref in enumerate(original):
        assert np.array_equal(render_image(built, i), ref)


# --- floors and response to errors ----------------------------------------------------------------------


def test_ground_truth_normals_reach_the_noise_floor(jit, sphere_folder):
    from validate.observations import load_known_scene
    from validate.rerender import RerenderConfig, rerender_object

    obj = load_known_scene(sphere_folder)
    same = rerender_object(sphere_folder, obj.normal_gt, RerenderConfig(seed_mode="same"))
    indep = rerender_object(sphere_folder, obj.normal_gt, RerenderConfig(seed_mode="independent", floors=False))
    floor = same["noise_floor_rel_l1"]
    assert same["reproduce_rel_l1"] == 0.0  # scene.json + this Mitsuba reproduce the stored images exactly
    assert same["mae_deg"] < 0.01
    assert 0.01 < floor < 0.2
    assert indep["gt_rel_l1"] < 1.3 * floor  # within a small factor of pure noise
    assert same["gt_rel_l1"] < 0.25 * floor  # common random numbers cancel most of the noise
    assert same["rel_l1"] == pytest.approx(same["gt_rel_l1"], rel=1e-3)
    assert same["frac_above_threshold"] < 0.01
    assert same["timings"]["rerender_s"] > 0 and same["timings"]["original_render_s"] > 0


@pytest.mark.parametrize("kind", ["random", "smooth", "bias"])
def test_residual_grows_with_the_normal_error(jit, sphere_folder, kind):
    from validate.observations import load_known_scene
    from validate.perturb import perturb_normals
    from validate.rerender import RerenderConfig, rerender_object

    obj = load_known_scene(sphere_folder)
    floor = rerender_object(sphere_folder, obj.normal_gt, RerenderConfig(floors=False))["rel_l1"]
    scores, maes = [], []
    for angle in (5, 20, 40):
        pred = perturb_normals(obj.normal_gt, obj.mask, kind, angle, seed=7)
        r = rerender_object(sphere_folder, pred, RerenderConfig(floors=False))
        scores.append(r["rel_l1"])
        maes.append(r["mae_deg"])
    assert floor < scores[0] < scores[1] < scores[2]
    assert maes[0] < maes[1] < maes[2]
    if kind != "bias":
        np.testing.assert_allclose(maes, [5, 20, 40], atol=0.5)
    assert scores[0] > 3 * floor  # 5 degrees is well above the ground-truth floor


def test_normal_mapped_material_wraps_the_inner_bsdf(jit, tmp_path):
    """With a `normalmap` material, hidden points keep the normal-mapped normal (the normalmap BSDF is kept)
    and visible ones feed the prediction to a second instance of the inner BSDF; ground-truth normals
    (which include the normal map) still explain the images."""
    from validate.known.normal_bsdf import PLUGIN_NAME, wrapper_for
    from validate.known.projection import CameraProjection
    from validate.observations import load_known_scene
    from validate.rerender import RerenderConfig, rerender_object

    yy, xx = np.mgrid[0:64, 0:64] / 64.0
    tangent = np.stack([0.25 * np.sin(2 * np.pi * 2 * xx), 0.25 * np.cos(2 * np.pi * 2 * yy), np.ones_like(xx)], -1)
    tangent /= np.linalg.norm(tangent, axis=-1, keepdims=True)
    desc = sphere_desc(name="mapped", normal_map="nmap.exr")
    folder = write_object(desc, tmp_path, {"nmap.exr": ((tangent + 1) / 2).astype(np.float32)})

    wrapped = wrapper_for(CameraProjection.from_camera(desc.camera))(
        {"type": "normalmap", "normalmap": {}, "bsdf": {"type": "principled"}}
    )
    assert (
        wrapped["type"] == PLUGIN_NAME
        and wrapped["bsdf"]["type"] == "normalmap"
        and wrapped["inner"]["type"] == "principled"
    )

    obj = load_known_scene(folder)
    r = rerender_object(folder, obj.normal_gt, RerenderConfig())
    assert r["reproduce_rel_l1"] == 0.0
    assert r["gt_rel_l1"] < 0.5 * r["noise_floor_rel_l1"]
    from validate.perturb import perturb_normals

    bad = rerender_object(
        folder, perturb_normals(obj.normal_gt, obj.mask, "smooth", 15, seed=1), RerenderConfig(floors=False)
    )
    assert bad["rel_l1"] > 3 * r["gt_rel_l1"]


# --- files, bad inputs, CLI -----------------------------------------------------------------------------


def test_normal_map_files_round_trip(tmp_path, np_rng):
    import cv2

    from scenes.images import encode_normals, write_exr
    from validate.io import read_normal_map

    n = np_rng.normal(size=(6, 5, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n[0, 0] = 0.0  # background
    cv2.imwrite(str(tmp_path / "n.png"), encode_normals(n)[:, :, ::-1])
    write_exr(tmp_path / "n.exr", n.astype(np.float32))
    np.save(tmp_path / "n.npy", n.astype(np.float32))
    for name, tol in (("n.png", 4e-5), ("n.exr", 1e-7), ("n.npy", 0)):
        got = read_normal_map(tmp_path / name)
        np.testing.assert_allclose(got, n, atol=tol, err_msg=name)  # also catches BGR/RGB swaps
        assert np.all(got[0, 0] == 0)


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    return err[0]


def test_bad_inputs_are_named(jit, sphere_folder, tmp_path, capsys):
    import shutil

    from validate.observations import load_known_scene
    from validate.rerender import RerenderConfig, main, rerender_object

    obj = load_known_scene(sphere_folder)
    out = str(tmp_path / "out")

    np.save(tmp_path / "small.npy", np.zeros((R - 1, R, 3), np.float32))
    with pytest.raises(ValueError, match="shape"):
        rerender_object(sphere_folder, np.load(tmp_path / "small.npy"))
    assert main(["--data", str(sphere_folder), "--normals", str(tmp_path / "small.npy"), "--out", out]) == 2
    assert "shape" in _one_line_error(capsys)

    nan = obj.normal_gt.copy()
    nan[obj.mask.nonzero()[0][0], obj.mask.nonzero()[1][0]] = np.nan
    np.save(tmp_path / "nan.npy", nan)
    with pytest.raises(ValueError, match="NaN"):
        rerender_object(sphere_folder, nan)
    assert main(["--data", str(sphere_folder), "--normals", str(tmp_path / "nan.npy"), "--out", out]) == 2
    assert "NaN" in _one_line_error(capsys)

    with pytest.raises(ValueError, match="unit length"):
        rerender_object(sphere_folder, obj.normal_gt * 0.5)
    np.save(tmp_path / "gt.npy", obj.normal_gt)

    holes = obj.normal_gt.copy()
    ys, xs = obj.mask.nonzero()
    holes[ys[:5], xs[:5]] = 0.0  # "no estimate" from a predictor
    with pytest.raises(ValueError, match="--allow-missing"):
        rerender_object(sphere_folder, holes)
    r = rerender_object(sphere_folder, holes, RerenderConfig(allow_missing=True, floors=False))
    assert r["missing_pixels"] == 5
    assert r["mae_deg"] == pytest.approx(90 * 5 / obj.mask.sum(), abs=0.01)  # missing counts as 90 deg

    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match="scene.json"):
        rerender_object(empty, obj.normal_gt)
    assert main(["--data", str(empty), "--normals", str(tmp_path / "gt.npy"), "--out", out]) == 2
    assert "scene.json" in _one_line_error(capsys)

    short = tmp_path / "short.data"
    shutil.copytree(sphere_folder, short)
    (short / "L002.png").unlink()
    with pytest.raises(ValueError, match="2 L\\*.png files but scene.json describes 3"):
        rerender_object(short, obj.normal_gt)
    assert main(["--data", str(short), "--normals", str(tmp_path / "gt.npy"), "--out", out]) == 2
    assert "L*.png" in _one_line_error(capsys)

    assert main(["--data", str(sphere_folder), "--normals", str(tmp_path / "missing.png"), "--out", out]) == 2
    assert "missing.png" in _one_line_error(capsys)
    assert main(["--data", str(sphere_folder), "--normals", str(tmp_path / "gt.npy"), "--spp", "0", "--out", out]) == 2
    assert "--spp" in _one_line_error(capsys)
    assert not (tmp_path / "out").exists()


def test_scalar_variant_is_refused_clearly():
    import mitsuba as mi

    from validate.known.normal_bsdf import register

    if "scalar_rgb" not in mi.variants():
        pytest.skip("scalar_rgb is not built in")
    previous = mi.variant()
    mi.set_variant("scalar_rgb")
    try:
        with pytest.raises(ValueError, match="scalar"):
            register()
    finally:
        if previous is not None:
            mi.set_variant(previous)


def test_cli_dataset_end_to_end(jit, sphere_folder, tmp_path, capsys):
    """Dataset mode: PRED/<object>/normal.png as unips.predict writes it; report.json, figure.png and
    summary.csv come out, and the printed table names every object."""
    import csv
    import shutil

    import cv2

    from scenes.images import encode_normals
    from validate.observations import load_known_scene
    from validate.perturb import perturb_normals
    from validate.rerender import main

    data = tmp_path / "dataset"
    data.mkdir()
    shutil.copytree(sphere_folder, data / "a.data")
    shutil.copytree(sphere_folder, data / "b.data")
    obj = load_known_scene(sphere_folder)
    preds = {"a": obj.normal_gt, "b": perturb_normals(obj.normal_gt, obj.mask, "smooth", 20, seed=3)}
    for name, n in preds.items():
        (tmp_path / "pred" / name).mkdir(parents=True)
        cv2.imwrite(str(tmp_path / "pred" / name / "normal.png"), encode_normals(n)[:, :, ::-1])
    out = tmp_path / "out"
    rc = main(["--data", str(data), "--normals", str(tmp_path / "pred"), "--out", str(out), "--save-renders"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "a " in printed and "b " in printed and "rel_l1" in printed
    reports = {}
    for name in ("a", "b"):
        report = json.loads((out / name / "report.json").read_text())
        for key in (
            "rel_l1",
            "psnr",
            "gt_rel_l1",
            "noise_floor_rel_l1",
            "mae_deg",
            "frac_above_threshold",
            "images",
            "timings",
        ):
            assert key in report, key
        assert len(report["images"]) == 3
        fig = cv2.imread(str(out / name / "figure.png"))
        assert fig is not None and fig.shape[0] > 4 * 64
        assert (out / name / "R002.png").is_file()
        reports[name] = report
    assert reports["b"]["mae_deg"] == pytest.approx(20, abs=0.1)
    assert reports["b"]["rel_l1"] > 3 * reports["a"]["rel_l1"]
    assert reports["b"]["frac_above_threshold"] > reports["a"]["frac_above_threshold"]
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["object"] for r in rows] == ["a", "b"]


def test_known_scene_report_refuses_an_unknown_light_type():
    """The known-scene report lists each light in its type's camera-frame form (`scenes.lights`); a type the
    table does not know is a ValueError naming it, never reported as an environment light."""
    from scenes.geometry import lights_in_camera_frame as known_scene_lights

    env = np.eye(4).tolist()
    desc = SceneDescription(
        camera=CameraDesc(width=8, height=8),
        images=[ImageDesc(lights=[PointLight(position=[0.0, 1.0, 2.0], intensity=3.0),
                                  AreaLight(position=[0.0, 0.0, 2.0], target=[0.0, 0.0, 0.0]),
                                  EnvironmentLight(to_world=env, scale=0.5)])],
    )
    (lights,) = known_scene_lights(desc, [2.0])
    assert [l["type"] for l in lights] == ["point", "area", "environment"]
    assert lights[0]["intensity"] == [6.0, 6.0, 6.0] and lights[2]["scale"] == 1.0
    np.testing.assert_allclose(lights[1]["normal"], [0, 0, -1], atol=1e-12)
    @dataclasses.dataclass(kw_only=True)
    class SkyDome(EnvironmentLight):
        type: ClassVar[str] = "sky_dome"

    desc.images[0].lights[2] = SkyDome(to_world=env, scale=0.5)
    with pytest.raises(
        ValueError, match="unknown light type 'sky_dome', expected one of directional, point, area, environment"
    ):
        known_scene_lights(desc, [2.0])
