"""Plain helpers of the tests (no fixtures: those are in tests/conftest.py, and no test module imports another).

Analytic inputs, one factory per concept: the sphere and the ellipsoid on a pixel grid, draws of light directions,
Lambertian shading. Camera frame throughout: x right (columns), y up (-rows), z toward the camera; pixel (i, j) has
its centre at (i + 0.5, j + 0.5). Written from the geometry, not from the code under test.

Then what several test files share: the Mitsuba variants and Dr.Jit's clean-up, rendered datasets, object folders
written without rendering (our layout, DiLiGenT's, UniPS's), the training objects, the fitted check's sphere, and
the command line of the scale tests of `wildgen.make`."""
from __future__ import annotations

import gc
import json
import math
import signal
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest


def dead_pid() -> int:
    """The pid of a process that has ended: the name of a killed writer's temporary (`scenes.files.writer_gone`)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


DEAD_PID = dead_pid()
"""One such pid for the tables of tests (a pid is reused only after the kernel has cycled through all of them)."""


def sphere(size: int = 32, pad: float = 2, center: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (size, size, 3) of a sphere filling a size x size image (radius size / 2 - pad pixels, centre
    (row, column) `center`, default the image centre), zero off it, and its mask."""
    cy, cx = center if center is not None else (size / 2, size / 2)
    rows, cols = np.mgrid[0:size, 0:size]
    r = size / 2 - pad
    x = (cols + 0.5 - cx) / r
    y = -(rows + 0.5 - cy) / r  # image rows grow downward, y grows upward
    mask = x * x + y * y < 1.0
    n = np.zeros((size, size, 3))
    n[..., 0], n[..., 1] = x, y
    n[..., 2] = np.sqrt(np.clip(1.0 - x * x - y * y, 0.0, None))
    n[~mask] = 0.0
    return n, mask


def ortho_sphere(res: int, half: float = 1.1, samples: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The unit sphere at the origin as an orthographic camera on the z axis with half size `half` sees it on a
    res x res grid (the scenes' default camera: camera frame = world frame): per pixel the front-surface point
    (x, y, sqrt(1 - x^2 - y^2)), which is also its normal (z = 0 off the sphere), and x^2 + y^2 (< 1 on it);
    shapes (res, res, 3) and (res, res). With `samples`: at samples x samples sub-pixel centres per pixel,
    shapes (res, res, samples^2, 3) and (res, res, samples^2)."""
    s = samples or 1
    n = res * s
    c = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(c * half, -c * half)
    r2 = x * x + y * y
    points = np.stack([x, y, np.sqrt(np.clip(1 - x * x - y * y, 0, None))], -1)
    if samples is None:
        return points, r2
    points = points.reshape(res, s, res, s, 3).transpose(0, 2, 1, 3, 4).reshape(res, res, s * s, 3)
    return points, r2.reshape(res, s, res, s).transpose(0, 2, 1, 3).reshape(res, res, s * s)


def ellipsoid_normals(h: int, w: int, ci: float, cj: float, ri: float, rj: float) -> tuple[np.ndarray, np.ndarray]:
    """Normals (H, W, 3) and mask of an ellipsoid seen orthographically, from image-space parameters.

    Centre (row ci, column cj) in continuous pixel units, semi-axes ri along the rows and rj along the columns,
    depth semi-axis 0.7 min(ri, rj).
    """
    i, j = np.mgrid[0:h, 0:w] + 0.5
    x, y = j - cj, -(i - ci)
    c = 0.7 * min(ri, rj)
    q = 1.0 - (x / rj) ** 2 - (y / ri) ** 2
    mask = q > 0.02
    z = c * np.sqrt(np.clip(q, 0.0, None))
    n = np.stack([x / rj ** 2, y / ri ** 2, z / c ** 2], axis=-1)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(mask[..., None], n, 0.0), mask


def cone_lights(k: int, seed: int = 0, max_deg: float = 40.0, min_deg: float = 5.0) -> np.ndarray:
    """k unit directions toward the light, zenith uniform in [min_deg, max_deg] degrees, azimuth uniform."""
    rng = np.random.default_rng(seed)
    th = np.radians(rng.uniform(min_deg, max_deg, k))
    ph = rng.uniform(0.0, 2.0 * np.pi, k)
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=1)


def random_lights(rng: np.random.Generator, k: int) -> np.ndarray:
    """k unit directions toward the light in the upper hemisphere (z >= 0.5 before normalising: none grazing)."""
    v = rng.normal(size=(k, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.5
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def shading(normals: np.ndarray, lights: np.ndarray) -> np.ndarray:
    """max(0, n . l_k), shape (K, ...) for normals (..., 3) and lights (K, 3): Lambertian shading with attached
    shadows (times albedo and irradiance, an image). Rows of normals (P, 3) are a matrix product, the normals of an
    image (H, W, 3) or of sub-pixel samples one sum per entry."""
    if normals.ndim == 2:
        return np.clip(normals @ lights.T, 0.0, None).T
    return np.clip(np.einsum("...c,kc->k...", normals, lights), 0.0, None)


def lambertian(normals: np.ndarray, mask: np.ndarray, lights: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """Images (K, 3, H, W): albedo[k] * max(0, n . l_k) inside the mask."""
    return (shading(normals, lights) * mask)[:, None] * albedo[:, :, None, None]


# -- Mitsuba variants and Dr.Jit -------------------------------------------------------------------------------

SHARED = Path(__file__).resolve().parents[2] / "shared"
REPO = Path(__file__).resolve().parents[1]

VARIANTS = ("llvm_ad_rgb", "scalar_rgb")
"""The Mitsuba variants the tests run on, fastest first: each gets a fixture `variant_<name>` in tests/conftest.py,
`any_variant` runs a test on each, and `use_variant` is the one place that decides whether one is usable here."""


def use_variant(*variants: str) -> str:
    """Set the first of `variants` (default: any of `VARIANTS`) this machine can run and return its name; skip
    the calling test when it can run none. For module-scoped fixtures (a test takes a `variant_*` fixture). The only
    caller of `scenes.renderer.variant._usable` in the tests (the module has no public check that does not raise:
    `choose_variant` raises instead of skipping)."""
    from scenes.renderer.variant import _usable

    for variant in variants or VARIANTS:
        if _usable(variant):  # sets it
            return variant
    pytest.skip(f"Mitsuba variant {' / '.join(variants or VARIANTS)} is not usable on this machine")


def release_drjit() -> None:
    """What Mitsuba's own test fixtures do around a test: collect the garbage (Python plugins and scenes sit in
    reference cycles), wait for running kernels, free Dr.Jit's kernel history, memory and kernel caches, forget
    the instances left in its registry and reset its flags. Nothing outlives a test that holds Mitsuba objects
    (module-scoped fixtures return paths only). A no-op before Dr.Jit is imported."""
    gc.collect()
    gc.collect()
    if "drjit" not in sys.modules:
        return
    import drjit as dr

    dr.sync_thread()
    dr.kernel_history_clear()
    dr.flush_malloc_cache()
    dr.flush_kernel_cache()
    dr.detail.clear_registry()
    dr.set_flag(dr.JitFlag.Default, True)


def render_dataset(out: Path, *flags: str, variant: str | None = None) -> list[Path]:
    """Render a small dataset with `wildgen.make` in this process (`flags` as on its command line, plus --workers 0
    --quiet) and return its object folders, sorted; the test is skipped when `variant` (default: any of
    `VARIANTS`) is not usable. `variant` is only checked: pass --variant in `flags` to render with it."""
    use_variant(*([variant] if variant else []))
    from wildgen.make import main

    assert main([*flags, "--workers", "0", "--quiet", "--out", str(out)]) == 0
    return sorted(Path(out).glob("*.data"))


# -- object folders written without rendering ------------------------------------------------------------------


def write_synthetic_object(folder: Path, images: np.ndarray, mask: np.ndarray, normals: np.ndarray | None,
                           light_family: str | None = "directional", directions: np.ndarray | None = None,
                           irradiance: np.ndarray | None = None, other: int = 0) -> Path:
    """An object folder in our layout written through `scenes.folder.format` (no rendering): L*.png, mask.png,
    normal.tif and a partial scene.json (light family, camera-frame directional lights when given)."""
    from scenes.folder.format import write_object_folder

    scene: dict = {"light_family": light_family}
    if directions is not None:
        irr = np.ones((len(directions), 3)) if irradiance is None else np.asarray(irradiance)
        scene["camera_lights"] = [{"directional": [{"direction_to_light": np.asarray(d).tolist(),
                                                    "irradiance": np.asarray(e).tolist()}], "other": other}
                                  for d, e in zip(directions, irr)]
    return write_object_folder(folder, images, mask, normals, scene=scene)


def write_png16(path: Path, rgb: np.ndarray) -> None:
    """A 16-bit RGB PNG written with OpenCV (not the code under test)."""
    assert cv2.imwrite(str(path), np.round(np.clip(rgb, 0, 1) * 65535).astype(np.uint16)[..., ::-1])


def write_mask(path: Path, mask: np.ndarray) -> None:
    assert cv2.imwrite(str(path), mask.astype(np.uint8) * 255)


SPHERE_ALBEDO = np.array([0.9, 0.6, 0.3])
"""The albedo of `sphere_images` (times 0.9)."""


def sphere_images(n: np.ndarray, mask: np.ndarray, L: np.ndarray, intensities: np.ndarray | None = None) -> np.ndarray:
    """(K, H, W, 3) Lambertian images in [0, 1): albedo * intensity * max(0, n . l)."""
    shade = shading(n, L)
    inten = np.ones((len(L), 3)) if intensities is None else intensities
    img = 0.9 * shade[..., None] * SPHERE_ALBEDO * inten[:, None, None, :]
    img[:, ~mask] = 0.0
    return img


def write_ours(folder: Path, k: int = 6, size: int = 32, other: int = 0, seed: int = 0):
    """The loaders' sphere in our layout (coloured irradiance per light); (normals, mask, lights, irradiance,
    images)."""
    n, mask = sphere(size)
    L = cone_lights(k, seed)
    irr = np.linspace(0.8, 1.1, k)[:, None] * np.array([1.0, 0.95, 0.9])
    imgs = sphere_images(n, mask, L, irr)
    write_synthetic_object(folder, imgs, mask, n, directions=L, irradiance=irr, other=other)
    return n, mask, L, irr, imgs


def write_diligent(folder: Path, k: int = 6, size: int = 32, seed: int = 1, gt: str = "mat"):
    """The loaders' sphere in DiLiGenT's layout (light intensities per image, RGB mask, Normal_gt.mat or
    Normal_gt.png); (normals, mask, lights, intensities, images)."""
    import scipy.io

    folder.mkdir(parents=True)
    n, mask = sphere(size)
    L = cone_lights(k, seed)
    inten = np.linspace(0.5, 0.9, k)[:, None] * np.array([1.0, 0.8, 0.6])
    imgs = sphere_images(n, mask, L, inten)
    names = [f"{i + 1:03d}.png" for i in range(k)]
    for name, im in zip(names, imgs):
        write_png16(folder / name, im)
    (folder / "filenames.txt").write_text("\n".join(names) + "\n")
    np.savetxt(folder / "light_directions.txt", L, fmt="%.6f")
    np.savetxt(folder / "light_intensities.txt", inten, fmt="%.6f")
    write_mask(folder / "mask.png", np.repeat(mask[..., None], 3, axis=2))  # DiLiGenT ball's mask is RGB
    if gt == "mat":
        scipy.io.savemat(folder / "Normal_gt.mat", {"Normal_gt": n})
    else:
        enc = np.round((n + 1) / 2 * 255).astype(np.uint8)
        enc[~mask] = 0  # DiLiGenT's PNG background is black
        assert cv2.imwrite(str(folder / "Normal_gt.png"), enc[..., ::-1])
    return n, mask, L, inten, imgs


def write_unips(folder: Path, k: int = 5, size: int = 24, exr: bool = False, gt: str | None = None) -> tuple:
    """The loaders' sphere in UniPS's layout (L*.png or radiance L*.exr, mask.png, optional Normal_gt.mat);
    (normals, mask, images)."""
    from scenes.images import write_exr

    folder.mkdir(parents=True)
    n, mask = sphere(size)
    imgs = sphere_images(n, mask, cone_lights(k, 3))
    for i, im in enumerate(imgs):
        if exr:
            write_exr(folder / f"L{i:02d}.exr", (im * 3.0).astype(np.float32))  # radiance, beyond 1 is fine
        else:
            write_png16(folder / f"L{i:02d}.png", im)
    write_mask(folder / "mask.png", mask)
    if gt == "mat":
        import scipy.io

        scipy.io.savemat(folder / "Normal_gt.mat", {"Normal_gt": n})
    return n, mask, imgs


def write_predict_ours(folder: Path, size: int = 32, k: int = 8, seed: int = 0, family: str = "directional"):
    """The predict and evaluate CLIs' sphere in our layout: L*.png, mask.png, normal.tif, scene.json with
    camera-frame directional lights; (normals, mask)."""
    n, mask = sphere(size)
    L = cone_lights(k, seed, max_deg=30.0)
    shade = shading(n, L)
    imgs = 0.8 * shade[..., None] * np.array([0.9, 0.7, 0.5])
    imgs[:, ~mask] = 0
    write_synthetic_object(folder, imgs, mask, n, light_family=family, directions=L)
    return n, mask


def write_predict_diligent(folder: Path, size: int = 28, k: int = 8, seed: int = 5):
    """The predict and evaluate CLIs' grey sphere in DiLiGenT's layout; (normals, mask)."""
    import scipy.io

    folder.mkdir(parents=True)
    n, mask = sphere(size)
    L = cone_lights(k, seed, max_deg=30.0)
    shade = shading(n, L)
    names = [f"{i + 1:03d}.png" for i in range(k)]
    for i, name in enumerate(names):
        img = 0.5 * shade[i][..., None] * np.ones(3)
        img[~mask] = 0
        write_png16(folder / name, img)
    (folder / "filenames.txt").write_text("\n".join(names))
    np.savetxt(folder / "light_directions.txt", L)
    np.savetxt(folder / "light_intensities.txt", np.ones((k, 3)))
    assert cv2.imwrite(str(folder / "mask.png"), mask.astype(np.uint8) * 255)
    scipy.io.savemat(folder / "Normal_gt.mat", {"Normal_gt": n})
    return n, mask


# -- training objects ------------------------------------------------------------------------------------------


def write_object(folder: Path, rng: np.random.Generator, size: int, k: int, family: str) -> None:
    """A training object folder in the project layout (16-bit PNGs, mask.png, normal.tif, scene.json): a Lambertian
    ellipsoid drawn from `rng` under k random directional lights."""
    import tifffile

    folder.mkdir(parents=True)
    ri, rj = rng.uniform(0.25, 0.42, 2) * size
    ci, cj = size / 2 + rng.uniform(-3, 3, 2)
    normals, mask = ellipsoid_normals(size, size, ci, cj, ri, rj)
    lights = random_lights(rng, k)
    albedo = np.tile(rng.uniform(0.3, 0.9, 3), (k, 1))
    irradiance = rng.uniform(0.6, 1.0, (k, 1)) * np.ones((1, 3))
    images = lambertian(normals, mask, lights, albedo * irradiance)
    for i in range(k):
        rgb16 = np.round(np.clip(images[i].transpose(1, 2, 0), 0, 1) * 65535).astype(np.uint16)
        cv2.imwrite(str(folder / f"L{i:03d}.png"), rgb16[..., ::-1])  # OpenCV writes BGR
    cv2.imwrite(str(folder / "mask.png"), (mask * 255).astype(np.uint8))
    tifffile.imwrite(folder / "normal.tif", np.round((normals + 1) / 2 * 65535).astype(np.uint16))
    cams = [{"directional": [{"direction_to_light": lights[i].tolist(), "irradiance": irradiance[i].tolist()}],
             "other": 0} for i in range(k)]
    (folder / "scene.json").write_text(json.dumps({"light_family": family, "camera_lights": cams}))


def train(dataset: dict[str, Path], out: Path, *extra: str) -> int:
    """`unips.train` of the tiny test model on `dataset["train"]` (the `train_dataset` fixture) into `out`."""
    from unips.train import main

    args = ["--data", str(dataset["train"]), "--model", "glc-test", "--out", str(out), "--batch", "2",
            "--res", "32", "--pixels", "200", "--max-images", "4", "--threads", "1", "--no-progress",
            "--log-every", "1", *extra]
    return main(args)


# -- the fitted check's sphere ---------------------------------------------------------------------------------

FIT_RES = 32
"""The size of the fitted check's sphere images."""

TO_LIGHT = np.array(
    [[math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)]
     for e, a in zip(np.radians([40, 55, 70, 35, 50, 65, 45, 60]), np.radians([0, 45, 90, 135, 180, 225, 270, 315]))]
)
"""Directions toward the light (camera frame) of the fitted check's sphere, elevations 35-70 deg all around."""


def analytic_sphere(mask_radius: float = 1.0 / 1.1) -> tuple[np.ndarray, np.ndarray]:
    """Normals (FIT_RES, FIT_RES, 3) and mask of a unit sphere seen by the default orthographic camera (half size
    1.1)."""
    n, r2 = ortho_sphere(FIT_RES, 1.1)
    mask = r2 < 0.97
    return np.where(mask[..., None], n, 0).astype(np.float32), mask


def small_config(**kw):
    """A `validate.fitted.fit.FitConfig` small enough for the tests (40 steps), with `kw` changed."""
    from validate.fitted.fit import FitConfig

    base = dict(steps=40, batch_images=8, refresh_every=10, ao_rays=4, max_pixels=100000, seed=0)
    base.update(kw)
    return FitConfig(**base)


def render_lambertian_sphere_folder(parent: Path, name: str, lights: list) -> Path:
    """Render a Lambertian sphere (albedo 0.7), 32x32, one image per entry of `lights` (lists of
    `scenes.lights.LightDesc`), into parent/NAME.data: images, mask and ground-truth normals, no scene.json. Needs
    a JIT variant set (`use_variant("llvm_ad_rgb")`)."""
    from scenes import images
    from scenes.description import (
        CameraDesc,
        ImageDesc,
        MaterialDesc,
        RenderDesc,
        SceneDescription,
        ShapeDesc,
        TextureDesc,
    )
    from scenes.renderer.build import build_scene
    from scenes.renderer.render import render_ground_truth, render_image

    desc = SceneDescription(
        name=name,
        shape=ShapeDesc(kind="sphere"),
        material=MaterialDesc(kind="lambertian", base_color=TextureDesc(value=[0.7, 0.7, 0.7])),
        camera=CameraDesc(width=FIT_RES, height=FIT_RES, half_size=1.1),
        render=RenderDesc(spp=64, bounces=1),
        images=[ImageDesc(lights=l, seed=i) for i, l in enumerate(lights)],
    )
    folder = parent / f"{name}.data"
    folder.mkdir()
    built = build_scene(desc)
    gt = render_ground_truth(built, spp=64)
    for i in range(len(desc.images)):
        images.write_png16(folder / f"L{i:03d}.png", render_image(built, i))
    mask = gt.coverage > 0.999
    images.write_mask(folder / "mask.png", mask)
    images.write_normal_map(folder / "normal.tif", np.where(mask[..., None], gt.normal, 0.0))
    return folder


# -- the scale tests of wildgen.make ---------------------------------------------------------------------------

SCALE_N = 6
"""Objects of the scale tests' dataset."""
SCALE_FLAGS = ["--lights", "directional,near_area,hdri,point", "--objects", str(SCALE_N), "--images", "3",
               "--res", "32", "--spp", "4", "--gt-spp", "4", "--seed", "11", "--variant", "llvm_ad_rgb", "--quiet"]
"""`wildgen.make`'s flags of the scale tests' dataset (tiny objects: 32x32, 4 spp, llvm)."""


def interruptible() -> None:
    """Child set-up: take SIGINT as a terminal's Ctrl-C would deliver it, even when the test runner itself was
    started in the background (where the shell leaves SIGINT ignored, and children inherit that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def make_command(out: Path, *extra: str) -> list[str]:
    """`python -m wildgen.make` of the scale tests' dataset into `out`."""
    return [sys.executable, "-m", "wildgen.make", "--out", str(out), *SCALE_FLAGS, *extra]


def make_cli(out: Path, *extra: str, timeout: float = 300) -> subprocess.CompletedProcess:
    """Run `make_command` in a subprocess from the repository root."""
    return subprocess.run(make_command(out, *extra), cwd=REPO, capture_output=True, text=True, timeout=timeout)


def object_bytes(root: Path) -> dict[str, bytes]:
    """Every file under the object folders, by path relative to the dataset."""
    return {
        str(p.relative_to(root)): p.read_bytes()
        for folder in sorted(root.glob("*.data"))
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def manifest_entries(root: Path) -> list[dict]:
    """Manifest objects without their timings and Ray node (the per-run fields of an entry)."""
    objects = json.loads((root / "manifest.json").read_text())["objects"]
    return [{k: v for k, v in e.items() if k not in ("timings", "node")} for e in objects]


def assert_same_dataset(a: Path, b: Path) -> None:
    """Datasets `a` and `b` hold the same bytes in every object folder and the same manifest entries, and `b` no
    temporary folder."""
    fa, fb = object_bytes(a), object_bytes(b)
    assert sorted(fa) == sorted(fb)
    different = [rel for rel in fa if fa[rel] != fb[rel]]
    assert not different, different[:5]
    assert manifest_entries(a) == manifest_entries(b)
    assert not list(b.glob(".tmp-*"))
