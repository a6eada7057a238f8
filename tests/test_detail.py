"""Surface detail (`wildgen.make --detail P`, `scenes.detail`): the ground truth of a normal-mapped surface is the
analytically perturbed normal (a plane with a known bump function), the detail-free normals are written beside
it (normal_base.tif), and the procedural maps have the tilt they are asked for."""
from __future__ import annotations

import numpy as np
import pytest
from fixtures import render_dataset, use_variant

A, F = 0.05, 2  # height field h(u, v) = A sin(2 pi F u) sin(2 pi F v) over the UV square


def _analytic_normal(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Tangent-space normal of the bump h: normalize(-dh/du, -dh/dv, 1) with dp/du = dp/dv = 2 (plane [-1, 1]^2)."""
    w = 2 * np.pi * F
    hu = A * w * np.cos(w * u) * np.sin(w * v) / 2.0  # dh/dx: u spans 2 scene units
    hv = A * w * np.sin(w * u) * np.cos(w * v) / 2.0
    n = np.stack([-hu, -hv, np.ones_like(u)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


@pytest.fixture(scope="module")
def variant():
    from scenes.renderer.variant import choose_variant

    use_variant()
    return choose_variant("auto")


def test_plane_with_a_known_bump_has_the_analytic_ground_truth(variant, tmp_path):
    from scenes.description import CameraDesc, ImageDesc, MaterialDesc, SceneDescription, ShapeDesc
    from scenes.geometry import write_mesh_ply
    from scenes.images import write_normal_map
    from scenes.lights import DirectionalLight
    from scenes.procedural import MeshData
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_ground_truth

    # A camera-facing plane [-1, 1]^2 with u along x and v along y: tangent space = camera frame.
    pos = np.float32([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    mesh = MeshData(pos, np.int32([[0, 1, 2], [0, 2, 3]]), np.float32([[0, 0, 1]] * 4), (pos[:, :2] + 1) / 2)
    write_mesh_ply(tmp_path / "plane.ply", mesh)
    res = 256  # the normal-map file, written as any normal map: row 0 at the top (v = 1)
    vv, uu = np.meshgrid(1 - (np.arange(res) + 0.5) / res, (np.arange(res) + 0.5) / res, indexing="ij")
    write_normal_map(tmp_path / "bump.png", _analytic_normal(uu, vv))
    h = w = 48
    desc = SceneDescription(
        shape=ShapeDesc(kind="mesh", file="plane.ply", normalize=False),
        material=MaterialDesc(kind="lambertian", normal_map="bump.png"),
        camera=CameraDesc(kind="orthographic", origin=[0, 0, 5], half_size=0.9, width=w, height=h),
        images=[ImageDesc(lights=[DirectionalLight(direction=[0, 0, -1])])],
    ).validate()
    gt = render_ground_truth(build_scene(desc, base_dir=tmp_path), spp=16)
    # pixel centres -> plane points -> UV
    x = (2 * (np.arange(w) + 0.5) / w - 1) * 0.9
    y = (1 - 2 * (np.arange(h) + 0.5) / h) * 0.9
    X, Y = np.meshgrid(x, y)
    expect = _analytic_normal((X + 1) / 2, (Y + 1) / 2)
    assert gt.mask.all()
    ang = np.degrees(np.arccos(np.clip((gt.normal * expect).sum(-1), -1, 1)))
    tilt = np.degrees(np.arccos(expect[..., 2]))
    assert tilt.max() > 15  # a real bump: up to 17 deg
    assert np.median(ang) < 0.5 and ang.max() < 2.0, (np.median(ang), ang.max())
    # without the normal map the same plane is flat
    desc.material.normal_map = None
    base = render_ground_truth(build_scene(desc, base_dir=tmp_path), spp=4)
    assert np.abs(base.normal - np.float32([0, 0, 1])).max() < 1e-4


@pytest.mark.parametrize("kind", ["bumps", "scratches", "fabric", "stone"])
def test_procedural_detail_has_the_requested_tilt_and_is_seamless(kind):
    from scenes.description import DetailDesc
    from scenes.detail import realize_detail

    d = DetailDesc(kind=kind, strength_deg=12.0, scale=4.0, seed=3, resolution=128)
    d.validate()
    n = realize_detail(d) * 2 - 1
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1, atol=1e-5)
    tilt = np.degrees(np.arccos(np.clip(n[..., 2], -1, 1)))
    assert np.percentile(tilt, 95) == pytest.approx(12.0, abs=0.5)
    # periodic: the step across the seam is like any other step between neighbouring texels
    seam = np.abs(n[:, 0] - n[:, -1]).mean()
    inner = np.abs(np.diff(n, axis=1)).mean()
    assert seam < 3 * inner + 1e-6
    np.testing.assert_array_equal(realize_detail(d), realize_detail(d))  # seeded


def test_tangent_normals_follow_the_height_gradient():
    from scenes.detail import tangent_normals_from_height

    res = 64
    v, u = np.meshgrid((np.arange(res) + 0.5) / res, (np.arange(res) + 0.5) / res, indexing="ij")
    h = np.sin(2 * np.pi * u)  # rises along u where cos > 0: the normal tilts toward -u there
    n = tangent_normals_from_height(h, 20.0)
    assert (n[:, 5, 0] < 0).all() and np.abs(n[..., 1]).max() < 1e-9
    assert (n[:, 40, 0] > 0).all()


def test_generator_writes_detail_and_base_normals(variant, tmp_path):
    import json

    from scenes.images import read_normals

    folders = render_dataset(tmp_path / "ds", "--objects", "2", "--images", "2", "--res", "48", "--spp", "4",
                             "--gt-spp", "4", "--detail", "1", "--shapes", "procedural", "--seed", "2")
    assert len(folders) == 2
    for folder in folders:
        scene = json.loads((folder / "scene.json").read_text())
        assert scene["material"]["detail"] is not None and scene["material"]["normal_map"]
        n = read_normals(folder / "normal.tif")
        b = read_normals(folder / "normal_base.tif")
        from scenes.images import read_mask

        m = read_mask(folder / "mask.png")
        ang = np.degrees(np.arccos(np.clip((n[m] * b[m]).sum(-1), -1, 1)))
        # the detail is there (sparse scratches touch few pixels: the 90th percentile), not more than its strength
        assert np.percentile(ang, 90) > 3 and np.median(ang) < scene["material"]["detail"]["strength_deg"]
