"""The capture checks' camera motion and frontal light (`validate.diagnosis.usable`,
`validate.diagnosis.camera_motion`) on analytic
captures whose truth is known: a textured ellipsoid seen by a camera that moved between two groups of photos, and
lights whose angle from the viewing direction is drawn. Written from the geometry, not from the code under test."""
from __future__ import annotations

import numpy as np
import pytest
from fixtures import ellipsoid_normals, shading, sphere

from validate.diagnosis.usable import capture_warnings, light_spread_deg

H, W, PAD = 104, 120, 8


def ring(polar_deg: float, k: int = 8, turn: float = 0.0) -> np.ndarray:
    a = np.radians(np.arange(k) * 360.0 / k + turn)
    t = np.radians(polar_deg)
    return np.stack([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.full(k, np.cos(t))], -1)


def scene(lights: np.ndarray, texture: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(K, H + 2 PAD, W + 2 PAD, 3) Lambertian shading of an ellipsoid with a spotted albedo, and its mask."""
    n, mask = ellipsoid_normals(H + 2 * PAD, W + 2 * PAD, (H + 2 * PAD) / 2, (W + 2 * PAD) / 2, 40, 50)
    i, j = np.mgrid[0:H + 2 * PAD, 0:W + 2 * PAD]
    albedo = 0.5 + (0.25 * np.sign(np.sin(i / 3.1) * np.sin(j / 4.3)) if texture else 0.0)
    img = shading(n, lights) * albedo * mask
    return np.repeat(img[..., None], 3, -1).astype(np.float32), mask


def cut(images: np.ndarray, dx: int = 0, dy: int = 0) -> np.ndarray:
    """The frame less PAD on each side, its content moved by dx columns right and dy rows down (no wrap-around)."""
    return images[:, PAD - dy:PAD - dy + H, PAD - dx:PAD - dx + W]


def codes(images: np.ndarray, mask: np.ndarray) -> list[str]:
    return [w.code for w in capture_warnings(images, mask)[0]]


LIGHTS = np.concatenate([ring(35, 8), ring(50, 8, 22.5)])


@pytest.mark.parametrize("shift", [(2, 0), (0, 3), (3, 3)])
@pytest.mark.parametrize("moved", ["alternate", "second half"])
def test_a_camera_moved_by_two_or_three_pixels_in_half_the_photos_is_flagged(shift, moved):
    images, mask = scene(LIGHTS)
    mask = cut(mask[None])[0]
    still, shifted = cut(images), cut(images, *shift)
    take = np.arange(1, 16, 2) if moved == "alternate" else np.arange(8, 16)
    capture = still.copy()
    capture[take] = shifted[take]
    warnings, facts = capture_warnings(capture, mask)
    assert [w.code for w in warnings] == ["camera_moved"]
    dx, dy = shift
    assert np.abs(np.abs(facts["camera_shift_px"]) - [dx, dy]).max() <= 1  # x right, y up: seen from either side
    assert codes(still, mask) == []


def test_a_still_camera_without_texture_is_not_flagged_as_moved():
    images, mask = scene(LIGHTS, texture=False)
    assert codes(cut(images), cut(mask[None])[0]) == []


def test_light_spread_reads_the_ring_of_lights_on_a_sphere_whatever_the_albedo():
    n, mask = sphere(96, pad=6)
    albedo = 0.3 + 0.6 * (np.arange(96)[None, :] // 12 % 2)
    for polar in (10, 25, 40):
        img = shading(n, ring(polar, 12, 10)) * albedo * mask
        assert light_spread_deg(np.repeat(img[..., None], 3, -1), mask) == pytest.approx(polar, abs=3)


def test_frontal_light_is_told_apart_from_light_all_around_and_from_one_side():
    rng = np.random.default_rng(3)
    tilt, turn = np.radians(rng.uniform(3, 15, 12)), rng.uniform(0, 2 * np.pi, 12)
    near = np.stack([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)], -1)
    images, mask = scene(near)
    assert codes(images, mask) == ["frontal_light"]  # all within 15 deg, on a shape less round than a sphere
    images, mask = scene(LIGHTS)
    assert codes(images, mask) == []
    side = np.radians(np.linspace(-40, 40, 8))  # 45 deg off the axis, all from the right: varies little
    one_side = np.stack([np.sin(np.radians(45)) * np.cos(side), np.sin(np.radians(45)) * np.sin(side),
                         np.full(8, np.cos(np.radians(45)))], -1)
    images, mask = scene(one_side)
    assert codes(images, mask) == ["one_sided_light"]


def test_lights_read_from_the_shading_under_a_map_are_the_true_ones():
    """Under the object's normals, each photo's light is read from the shading of the whole object (a textured
    ellipsoid here): its angle from the axis within 3 deg of the truth, where the outline reads 20-45 deg lights
    several times too close to the axis on real objects; and the warnings follow the true directions: lights 20-40
    deg off the axis all around are not frontal, all from above is one-sided naming the missing bottom."""
    from validate.diagnosis.light_reading import shading_light_angles
    from validate.diagnosis.usable import light_warnings

    n, _ = ellipsoid_normals(H + 2 * PAD, W + 2 * PAD, (H + 2 * PAD) / 2, (W + 2 * PAD) / 2, 40, 50)
    around = np.concatenate([ring(20, 6), ring(40, 6, 30.0)])
    images, mask = scene(around)
    polar, azimuth = shading_light_angles(images, mask, n)
    true_polar = np.degrees(np.arccos(around[:, 2]))
    assert np.abs(polar - true_polar).max() < 3.0, (polar, true_polar)
    assert light_warnings(images, mask, n)[0] == []
    above = np.radians(np.linspace(30, 150, 7))  # 40 deg off the axis, every lamp in the upper half
    top = np.stack([np.sin(np.radians(40)) * np.cos(above), np.sin(np.radians(40)) * np.sin(above),
                    np.full(7, np.cos(np.radians(40)))], -1)
    images, mask = scene(top)
    warned, facts = light_warnings(images, mask, n)
    assert [w.code for w in warned] == ["one_sided_light"] and "(the top; no photo is lit from the bottom)" in \
        warned[0].message and facts["light_angles"].startswith("from the shading")
    near = ring(12, 8)
    images, mask = scene(near)
    assert [w.code for w in light_warnings(images, mask, n)[0]] == ["frontal_light"]


def test_the_lights_of_a_glossy_metal_object_are_read_from_its_highlights():
    """A metal-like ellipsoid (a faint diffuse term, a Blinn-Phong highlight of exponent 50): each photo is mostly a
    highlight on a dark surface. The reader's lobe finds every light within 6 deg of the truth; lights all from above
    read as one-sided, lights all around as neither warning."""
    from validate.diagnosis.light_reading import shading_light_angles
    from validate.diagnosis.usable import light_warnings

    n, mask = ellipsoid_normals(H + 2 * PAD, W + 2 * PAD, (H + 2 * PAD) / 2, (W + 2 * PAD) / 2, 40, 50)

    def photos(lights: np.ndarray) -> np.ndarray:
        half = lights + np.array([0.0, 0.0, 1.0])
        half /= np.linalg.norm(half, axis=1, keepdims=True)
        lobe = np.clip(np.einsum("hwc,kc->khw", n, half), 0, None) ** 50
        img = (0.03 * shading(n, lights) + lobe) * mask
        return np.repeat(img[..., None], 3, -1).astype(np.float32)

    around = np.concatenate([ring(30, 6), ring(45, 6, 30.0)])
    polar, azimuth = shading_light_angles(photos(around), mask, n)
    read = np.stack([np.sin(np.radians(polar)) * np.cos(np.radians(azimuth)),
                     np.sin(np.radians(polar)) * np.sin(np.radians(azimuth)), np.cos(np.radians(polar))], -1)
    off = np.degrees(np.arccos(np.clip((read * around).sum(-1), -1, 1)))
    assert off.max() < 6.0, off
    assert light_warnings(photos(around), mask, n)[0] == []
    top = around[around[:, 1] > 0.1]
    assert [w.code for w in light_warnings(photos(top), mask, n)[0]] == ["one_sided_light"]


def test_photos_that_differ_only_in_brightness_are_one_light_and_fatal():
    """The same photo under other EXIF exposures (each scaled by its own factor) tells the light once (sweep 7);
    a sphere under four lights is not refused, even with one of them dimmed."""
    from fixtures import sphere_images

    from validate.diagnosis.usable import unusable_photos

    n, mask = sphere(32)
    lights = np.array([[0.3, 0.2, 0.93], [-0.4, 0.1, 0.9], [0.1, -0.5, 0.86], [0.5, 0.5, 0.7]])
    lights /= np.linalg.norm(lights, axis=1, keepdims=True)
    images = sphere_images(n, mask, lights).astype(np.float32)
    scaled = np.stack([images[0] * f for f in (1.0, 0.5, 0.25, 2.0)])
    same = unusable_photos(scaled)
    assert same is not None and same.fatal and "differ only in brightness" in same.message
    images[1] *= 0.5
    assert unusable_photos(images) is None


def test_photos_too_small_to_search_for_motion_are_passed_quietly():
    """8 x 8 photos leave no pixels to search a shift in: no pair is compared, and nothing is printed (sweep 9)."""
    import warnings

    from validate.diagnosis.camera_motion import camera_shifts

    images = np.random.default_rng(0).random((6, 8, 8, 3)).astype(np.float32)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pairs, shifts = camera_shifts(images)
    assert pairs == [] and shifts.shape == (0, 2)
