"""A mask that may be wrong is evidence too (`validate.diagnosis.usable.mask_doubts`, the `doubtful_mask` warning of
`orchestrate.capture --mask auto`): Lambertian spheres shaded analytically under eight distant lights on a black
background, with a flat cushion under one that the lamp lights too. The rule stays silent on the true mask and on
the automatic mask that finds it, and speaks on masks that cover the cushion, are grown over the background, are
moved, or leave a second lit object out."""
from __future__ import annotations

import json

import cv2
import numpy as np
from fixtures import shading, sphere

from validate.diagnosis.usable import auto_mask, mask_doubts

SIZE = 96
LIGHTS_POLAR_DEG = [40, 50, 35, 45, 40, 55, 30, 45]
"""Eight lamps 30 to 55 deg off the camera's axis, one every 45 deg around it."""
CUSHION_ALBEDO = 0.5
"""A cushion a little darker than the sphere (albedo 0.6), facing the camera: the lamp moving around the axis hardly
changes its brightness (by cos of the lamp's angle from the axis), it changes the sphere's a lot."""


def _lights() -> np.ndarray:
    p, a = np.radians(LIGHTS_POLAR_DEG), np.radians(np.arange(8) * 45.0)
    return np.stack([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)], -1)


def _photos(shade: np.ndarray) -> np.ndarray:
    return np.repeat(shade[..., None], 3, -1).astype(np.float32)


def sphere_on_cushion() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(images (8, H, W, 3), the sphere's mask, the cushion's): a sphere of radius 20 px in the upper part of the
    frame, in front of a lit flat ellipse (the cushion, 76 x 36 px) under it, facing the camera."""
    n, ball = sphere(SIZE, pad=28, center=(36, 48))
    rows, cols = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    cushion = (((rows - 64) / 18) ** 2 + ((cols - 48) / 38) ** 2 < 1) & ~ball
    lights = _lights()
    shade = shading(n, lights) * 0.6 * ball
    flat = CUSHION_ALBEDO * np.clip(lights @ np.array([0.0, 0.0, 1.0]), 0, None)  # its brightness per photo
    return _photos(np.where(cushion[None], flat[:, None, None], shade)), ball, cushion


def two_spheres() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(images, the larger sphere's mask, the smaller's): two lit spheres apart in one frame."""
    n1, m1 = sphere(SIZE, pad=26, center=(40, 34))  # radius 22
    n2, m2 = sphere(SIZE, pad=34, center=(66, 76))  # radius 14
    n = np.where(m1[..., None], n1, n2)
    return _photos(shading(n, _lights()) * 0.6 * (m1 | m2)), m1, m2


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def test_the_true_mask_and_the_automatic_mask_that_finds_it_are_not_doubted():
    images, big, small = two_spheres()
    warning, facts = mask_doubts(images, big | small)
    assert warning is None and facts["doubtful"] is False, facts
    images, ball, cushion = sphere_on_cushion()
    warning, facts = mask_doubts(images, ball)
    assert warning is None and facts["doubtful"] is False, facts
    tight = cv2.erode(ball.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0  # an outline a pixel inside
    warning, facts = mask_doubts(images, tight)
    assert warning is None and 0 < facts["varying_outside_share"] < 0.1, facts
    found, info = auto_mask(images)
    assert _iou(found, ball) > 0.95 and not (found & cushion).any()  # the cushion hardly varies: left out
    warning, facts = mask_doubts(images, found)
    assert warning is None, facts
    assert facts["seed_agreement_iou"] == info["seed_agreement_iou"]  # the same seed as auto_mask's
    assert facts["varying_outside_share"] < 0.01 and facts["weak_inside_share"] < 0.05


def test_a_mask_over_the_cushion_is_doubted_with_what_to_do():
    images, ball, cushion = sphere_on_cushion()
    warning, facts = mask_doubts(images, ball | cushion)
    assert warning is not None and warning.code == "doubtful_mask" and not warning.fatal
    assert facts["doubtful"] is True and facts["weak_inside_share"] > 0.5 and facts["seed_agreement_iou"] < 0.4
    assert "hardly changes with the light" in warning.message and "--mask FILE" in warning.message
    assert "mask_overlay.png" in warning.message


def test_a_grown_or_moved_mask_is_doubted():
    images, ball, _ = sphere_on_cushion()
    radius = np.sqrt(ball.sum() / np.pi)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * round(0.4 * radius) + 1,) * 2)
    grown = cv2.dilate(ball.astype(np.uint8), kernel) > 0
    warning, facts = mask_doubts(images, grown)
    assert warning is not None and facts["weak_inside_share"] > 0.25 and facts["varying_outside_share"] == 0
    moved = np.roll(ball, round(0.5 * radius), axis=1)
    warning, facts = mask_doubts(images, moved)
    assert warning is not None and facts["varying_outside_share"] > 0.1
    assert "change most with the light lie outside it" in warning.message


def test_an_automatic_mask_that_keeps_one_of_two_lit_objects_is_doubted():
    images, big, small = two_spheres()
    found, _ = auto_mask(images)  # the largest connected part
    assert _iou(found, big) > 0.9 and not (found & small).any()
    warning, facts = mask_doubts(images, found)
    assert warning is not None and facts["varying_outside_share"] > 0.2


def test_a_dark_belt_is_no_doubt_on_the_true_mask_but_the_automatic_mask_that_stops_at_it_is_doubted():
    """A sphere with a dark belt (albedo 0.1 against 0.6, 16 % of it) across its middle: the belt hardly changes
    with the light, so the true mask holds a little weakly varying area (under WEAK_SHARE_MAX), while auto_mask's
    seed falls in two halves and the largest part kept leaves the other half out."""
    n, ball = sphere(SIZE, pad=16)
    rows = np.arange(SIZE)[:, None] + np.zeros((1, SIZE))
    belt = (rows >= 44) & (rows < 52)
    images = _photos(shading(n, _lights()) * np.where(belt, 0.1, 0.6) * ball)
    warning, facts = mask_doubts(images, ball)
    assert warning is None and 0.1 < facts["weak_inside_share"] < 0.25, facts
    found, _ = auto_mask(images)
    assert _iou(found, ball) < 0.5  # one half
    warning, facts = mask_doubts(images, found)
    assert warning is not None and facts["varying_outside_share"] > 0.3


def test_capture_records_a_doubtful_automatic_mask_and_draws_it_over_the_photos(tmp_path, variant_llvm_ad_rgb, capsys):
    from orchestrate.capture import OUTPUTS, main

    images, big, _ = two_spheres()
    folder = tmp_path / "shoot"
    folder.mkdir()
    for i, img in enumerate(images):  # 16-bit linear PNG (the reader takes 16-bit files as linear)
        cv2.imwrite(str(folder / f"IMG_{i + 1:04d}.png"), np.round(np.clip(img, 0, 1) * 65535).astype(np.uint16))
    out = tmp_path / "out"
    assert main(["--input", str(folder), "--out", str(out), "--no-refine", "--threads", "1"]) == 0
    assert "warning: doubtful_mask: the automatic mask may not be the object" in capsys.readouterr().err
    report = json.loads((out / "report.json").read_text())
    assert "doubtful_mask" in [w["code"] for w in report["warnings"]]
    doubts = report["measurements"]["mask_doubts"]
    assert doubts["doubtful"] is True and doubts["varying_outside_share"] > 0.2
    assert doubts["seed_agreement_iou"] == report["mask"]["seed_agreement_iou"]

    assert "mask_overlay.png" in OUTPUTS
    overlay = cv2.imread(str(out / "mask_overlay.png"))
    assert overlay.shape == (SIZE, SIZE, 3)
    orange = (overlay[..., 2].astype(int) - overlay[..., 0]) > 60  # the tint: red well above blue
    assert orange[big].mean() > 0.9 and not orange[~big].any()  # on the mask, and only there
    assert "Mask over the photos" in (out / "report.html").read_text()


def test_capture_with_a_given_mask_does_not_doubt_it(tmp_path, variant_llvm_ad_rgb):
    """A mask the user gives is taken as it is: the rule is asked only of automatic masks."""
    from orchestrate.capture import main
    from scenes.images import write_mask

    images, big, _ = two_spheres()
    folder = tmp_path / "shoot"
    folder.mkdir()
    for i, img in enumerate(images):
        cv2.imwrite(str(folder / f"IMG_{i + 1:04d}.png"), np.round(np.clip(img, 0, 1) * 65535).astype(np.uint16))
    write_mask(tmp_path / "mask.png", big)
    out = tmp_path / "out"
    assert main(["--input", str(folder), "--out", str(out), "--mask", str(tmp_path / "mask.png"), "--no-refine",
                 "--threads", "1"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert "doubtful_mask" not in [w["code"] for w in report["warnings"]]
    assert "mask_doubts" not in report["measurements"] and (out / "mask_overlay.png").is_file()


def sphere_on_a_tilted_floor() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(images, the sphere's mask, the floor's): the sphere standing on a textured flat floor leaning toward the
    camera (its normal 37 deg up from the viewing axis), which the lamps light as strongly as the sphere and on which
    the sphere casts its shadow away from each lamp."""
    n, ball = sphere(SIZE, pad=28, center=(36, 48))
    rows, cols = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    floor = (rows > 40) & (rows < 88) & (cols > 8) & (cols < 88) & ~ball
    texture = 1 + 0.2 * np.sin(cols / 3.0) * np.cos(rows / 5.0)
    lights = _lights()
    normal = np.array([0.0, 0.6, 0.8])
    shade = shading(n, lights) * 0.6 * ball
    photos = []
    for k, light in enumerate(lights):
        lit = 0.7 * max(float(light @ normal), 0.0) * texture
        dy, dx = int(round(12 * light[1])), int(round(-12 * light[0]))  # the shadow falls away from the lamp
        lit = np.where(np.roll(ball, (dy, dx), axis=(0, 1)), 0.1 * lit, lit)
        photos.append(np.where(floor, lit, shade[k]))
    return _photos(np.stack(photos)), ball, floor


def test_a_mask_that_took_a_lit_floor_with_the_object_is_doubted_as_one_flat_surface():
    """A floor the lamps light as much as the object varies like it, so the light variation puts it with the object
    (the blind spot of the first three measurements); but every pixel of it follows one profile across the photos
    (times its texture, left out where the sphere's shadow falls): one flat surface, which the fourth sees."""
    images, ball, floor = sphere_on_a_tilted_floor()
    warning, facts = mask_doubts(images, ball)
    assert facts["flat_share"] < 0.2, facts
    warning, facts = mask_doubts(images, ball | floor)
    assert facts["weak_inside_share"] < 0.25 and facts["varying_outside_share"] < 0.1, facts  # the blind spot:
    assert facts["seed_agreement_iou"] > 0.9, facts  # the floor is in the seed too
    assert warning is not None and facts["flat_share"] > 0.5, facts
    assert "one flat surface lit alike in every photo" in warning.message


def test_a_shiny_objects_highlights_taken_for_all_of_it_are_doubted():
    """A dim sphere with a strong highlight under each lamp: the highlights vary far more than the body, so the
    first reading of the variation keeps them only (a third of the sphere); the second reading (its logarithm)
    finds the whole sphere, and the mask is doubted."""
    lights = _lights()
    n, ball = sphere(SIZE, pad=20)
    half = lights + np.array([0.0, 0.0, 1.0])
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    highlight = np.clip(np.einsum("...c,kc->k...", n, half), 0, None) ** 60
    images = _photos((0.03 * shading(n, lights) + 2.0 * highlight) * ball)
    mask, _ = auto_mask(images)
    assert _iou(mask, ball) < 0.5  # the fragment
    warning, facts = mask_doubts(images, mask)
    assert warning is not None and facts["second_reading_iou"] < 0.5, facts
    assert "logarithm" in warning.message


def test_a_hole_the_background_shows_through_stays_open():
    """A ring (a torus seen from above, the black background through its hole): the automatic mask keeps the
    hole open; a pocket of the object that varies (it is lit from some side) would be filled."""
    rows, cols = np.mgrid[0:SIZE, 0:SIZE] + 0.5
    r = np.hypot(rows - 48, cols - 48)
    ring = (r < 36) & (r > 14)
    d = np.clip((r - 25.0) / 11.0, -1, 1)  # across the tube of radius 11 around the circle of radius 25
    n = np.stack([d * (cols - 48) / r, -d * (rows - 48) / r, np.sqrt(np.clip(1 - d * d, 0, None))], -1)
    images = _photos(0.6 * shading(n * ring[..., None], _lights()) * ring)
    mask, _ = auto_mask(images)
    assert not mask[48, 48] and _iou(mask, ring) > 0.95
    assert mask_doubts(images, mask)[0] is None


def test_a_flat_surface_reaching_out_beside_the_object_is_measured():
    """The cushion taken with the sphere reaches out on both sides of it: most of it lies outside the convex hull
    of the rest of the mask (`flat_outside_share`); the sphere alone has none."""
    images, ball, cushion = sphere_on_cushion()
    _, union = mask_doubts(images, ball | cushion)
    _, alone = mask_doubts(images, ball)
    assert union["flat_outside_share"] > 0.1 and alone["flat_outside_share"] == 0.0, (union, alone)


def sphere_beside_a_chrome_ball(albedo: float, ball_value: float) -> np.ndarray:
    """Images (8, H, W, 3) of a dim sphere (`albedo`, radius 22 px, low right) and a chrome ball at the top left: a
    10 px disc of `ball_value` whose 4 x 4 px highlight, at white, moves around it with the lamp. The highlight
    changes more with the light than the dim sphere does, so the automatic mask takes the ball."""
    n, ball = sphere(SIZE, pad=26, center=(58, 58))
    shade = shading(n, _lights()) * albedo * ball
    rows, cols = np.mgrid[0:SIZE, 0:SIZE]
    chrome = (rows - 16) ** 2 + (cols - 16) ** 2 <= 100
    images = []
    for k, im in enumerate(shade):
        im = np.where(chrome, ball_value, im)
        y, x = int(16 + 6 * np.sin(np.pi * k / 4)), int(16 + 6 * np.cos(np.pi * k / 4))
        im[y - 2:y + 2, x - 2:x + 2] = 1.0
        images.append(im)
    return _photos(np.stack(images))


def _shoot(folder, images: np.ndarray) -> None:
    folder.mkdir()
    for i, img in enumerate(images):  # 16-bit linear PNG: white is the file's largest code, read as clipped
        cv2.imwrite(str(folder / f"IMG_{i + 1:04d}.png"), np.round(np.clip(img, 0, 1) * 65535).astype(np.uint16))


def test_a_refusal_on_a_doubted_automatic_mask_names_the_mask_not_the_exposure(tmp_path, variant_llvm_ad_rgb, capsys):
    """Sweep 32: a chrome ball beside the object, the automatic mask on the ball: the only lit pixels in it are the
    clipped highlight, and the refusal said to expose shorter, though the mask is what is wrong."""
    from orchestrate.capture import main

    _shoot(tmp_path / "shoot", sphere_beside_a_chrome_ball(albedo=0.05, ball_value=0.0))
    out = tmp_path / "out"
    assert main(["--input", str(tmp_path / "shoot"), "--out", str(out), "--no-refine", "--threads", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-2].startswith("warning: doubtful_mask: ")
    assert err[-1].startswith("error: --mask: the automatic mask may not be the object")
    assert "every lit mask pixel is saturated" in err[-1] and "give it (--mask FILE" in err[-1]
    assert not (out / "normal.png").exists()


def test_a_capture_not_checked_on_a_doubted_automatic_mask_says_so_first(tmp_path, variant_llvm_ad_rgb, capsys):
    """The same ball, dark grey (lit, not clipped): the check runs on the ball and cannot judge (its pixels hardly
    vary); the headline names the doubted mask before the check's reason (the lights)."""
    from orchestrate.capture import main

    _shoot(tmp_path / "shoot", sphere_beside_a_chrome_ball(albedo=0.02, ball_value=0.05))
    out = tmp_path / "out"
    assert main(["--input", str(tmp_path / "shoot"), "--out", str(out), "--no-refine", "--threads", "1"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert "doubtful_mask" in [w["code"] for w in report["warnings"]] and report["mask"]["pixels"] < 200
    assert report["verdict"]["level"] == "not checked"
    assert report["verdict"]["headline"].startswith("not checked on an automatic mask that may not be the object "
                                                    "(doubtful_mask: give --mask FILE): ")
    assert capsys.readouterr().out.startswith("not checked on an automatic mask")
