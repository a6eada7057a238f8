"""Photos larger than the working size (`orchestrate.capture_full`): the capture works on smaller copies and writes
normal.png, normal.exr and mask.png at the photos' own size; checked against a sphere's analytic normals and mask."""

from __future__ import annotations

import json

import cv2
import numpy as np
from fixtures import shading, sphere

FULL, WORK = 240, 60
"""The photos' side and the working side (a factor 4)."""


def _lights() -> np.ndarray:
    polar, azimuth = np.radians([40, 50, 35, 45, 40, 55, 30, 45]), np.radians(np.arange(8) * 45)
    return np.stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)], -1)


def _angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))


def test_upsampling_follows_the_photos_outline_and_keeps_the_normals():
    """The working map of a sphere (its analytic normals at 60 px) brought to 240 px: the mask guided by the mean
    photo misses far fewer outline pixels than a plain upsampling of the working mask, the normals inside stay within
    a degree of the analytic ones away from the outline, and a user's full-size mask is kept as it is."""
    from orchestrate.capture_full import downscale_mask, guide_image, upsample

    n_full, m_full = sphere(FULL, pad=20)
    n_work, _ = sphere(WORK, pad=5)
    m_work = downscale_mask(m_full, (WORK, WORK))
    photos = shading(n_full, _lights())[..., None] * 0.6 * m_full[..., None] + 0.01  # a grey backdrop
    normals, mask = upsample(n_work, m_work, guide_image(photos.mean(axis=(0, -1))))
    assert normals.shape == (FULL, FULL, 3) and normals.dtype == np.float32 and mask.shape == (FULL, FULL)
    plain = cv2.resize(m_work.astype(np.float32), (FULL, FULL), interpolation=cv2.INTER_LINEAR) > 0.5
    wrong, wrong_plain = int((mask ^ m_full).sum()), int((plain ^ m_full).sum())
    assert wrong < 0.5 * wrong_plain, (wrong, wrong_plain)
    np.testing.assert_allclose(np.linalg.norm(normals[mask], axis=-1), 1.0, atol=1e-5)
    assert not normals[~mask].any()
    from scipy import ndimage

    inner = ndimage.binary_erosion(m_full, iterations=12)  # the sphere's rim turns fast: a working pixel is 4 px
    assert np.median(_angles(normals[inner], n_full[inner])) < 1.0
    kept, kept_mask = upsample(n_work, m_work, guide_image(photos.mean(axis=(0, -1))), full_mask=m_full)
    assert (kept_mask == m_full).all() and np.isfinite(kept).all()


def _write_photos(folder, images: np.ndarray) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for i, img in enumerate(images):
        cv2.imwrite(str(folder / f"IMG_{i + 1:04d}.png"),
                    np.round(np.clip(img, 0, 1) * 65535).astype(np.uint16)[..., ::-1])


def test_the_capture_writes_the_map_at_the_photos_size(tmp_path, capsys, variant_llvm_ad_rgb):
    """--max-side 60 on 240 px photos: the model and the check at 60 px, normal.png, normal.exr and mask.png at
    240 px, the sizes in report.json and on stdout; a mask file of the photos' size is read (brought to the working
    size), one of a third size refused in one line naming both."""
    from orchestrate.capture import main
    from scenes.images import read_mask, read_normals, write_mask

    n, m = sphere(FULL, pad=20)
    images = np.repeat((shading(n, _lights()) * 0.6 * m)[..., None], 3, -1).astype(np.float32)
    _write_photos(tmp_path / "in", images)
    out = tmp_path / "out"
    assert main(["--input", str(tmp_path / "in"), "--out", str(out), "--max-side", str(WORK), "--no-refine",
                 "--threads", "1"]) == 0
    said = capsys.readouterr().out
    assert f"at the photos' size ({FULL} x {FULL} px), the rest at the working size ({WORK} x {WORK} px" in said
    report = json.loads((out / "report.json").read_text())
    assert report["input"]["size"] == [FULL, FULL] and report["input"]["working_size"] == [WORK, WORK]
    assert report["normals"]["size"] == [FULL, FULL]
    normals, mask = read_normals(out / "normal.png"), read_mask(out / "mask.png")
    assert normals.shape == (FULL, FULL, 3) and mask.shape == (FULL, FULL)
    assert read_normals(out / "normal_model.png").shape == (WORK, WORK, 3)
    assert (mask & m).sum() / (mask | m).sum() > 0.97
    both = mask & m
    assert np.mean(_angles(normals[both], n[both])) < 25  # the network's map, brought up: not a blank one
    write_mask(tmp_path / "mask.png", m)
    assert main(["--input", str(tmp_path / "in"), "--out", str(tmp_path / "o2"), "--max-side", str(WORK),
                 "--mask", str(tmp_path / "mask.png"), "--no-refine", "--threads", "1"]) == 0
    assert (read_mask(tmp_path / "o2" / "mask.png") == m).all()  # the user's own, at the photos' size
    capsys.readouterr()
    write_mask(tmp_path / "odd.png", np.ones((100, 100), bool))
    assert main(["--input", str(tmp_path / "in"), "--out", str(tmp_path / "o3"), "--max-side", str(WORK),
                 "--mask", str(tmp_path / "odd.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --mask:") and f"{FULL}x{FULL}" in err[0]
    assert f"{WORK}x{WORK}" in err[0]


def test_the_estimate_counts_the_photos_own_size():
    """Working on smaller copies costs the full-size decoding and the full-size map on top of the working size's."""
    from orchestrate.capture_estimate import estimate

    small, big = estimate(7, 1024, 1536), estimate(7, 1024, 1536, full=(4000, 6000))
    assert big["peak_mib"] > small["peak_mib"] + 1000 and big["seconds"] > small["seconds"]
    assert estimate(7, 1024, 1536, full=(1024, 1536)) == small
