"""The one check of a normal map to judge (`validate.io.check_normals`; the fitted modes' view of it,
`validate.observations.unit_normals`): hand-made maps at the edges of the rule."""
from __future__ import annotations

import numpy as np
import pytest

from scenes.images import decode_normal_image, encode_normals
from validate.io import UNIT_TOLERANCE, check_normals
from validate.observations import unit_normals


def test_normal_map_rule_is_one_for_both_modes():
    """Finite, unit within UNIT_TOLERANCE (16-bit quantisation is far inside it) and renormalised; a clearly
    non-unit vector is refused by the known-scene check and the fitted modes alike (the fitted mode used to
    renormalise it), with one line naming the source and the count; an exactly-zero vector is refused unless
    missing estimates are allowed, and the fitted modes replace it by (0, 0, 1)."""
    mask = np.array([[True, True, True, False]])
    d = np.array([3.0, 4.0, 12.0]) / 13.0  # a unit vector with exact components
    n = np.zeros((1, 4, 3))
    n[0, :3] = d
    quantised = decode_normal_image(encode_normals(n), "n")  # through 16-bit PNG codes
    assert 0 < np.abs(np.linalg.norm(quantised[0, :3], axis=-1) - 1).max() < 1e-4
    for check in (
        lambda m, what="--normals": check_normals(m, mask, what)[0],
        lambda m, what="--normals": unit_normals(m, mask, what),
    ):
        out = check(quantised)
        np.testing.assert_allclose(np.linalg.norm(out[0, :3], axis=-1), 1, atol=1e-6)
        np.testing.assert_allclose(out[0, :3], np.tile(d, (3, 1)), atol=1e-4)
        assert np.all(out[0, 3] == 0)  # outside the mask

        edge = n.copy()
        edge[0, 0] *= 1 + 0.99 * UNIT_TOLERANCE  # just inside: renormalised
        np.testing.assert_allclose(check(edge)[0, 0], d, atol=1e-6)
        short = n.copy()
        short[0, :2] *= 0.5  # two clearly non-unit vectors
        with pytest.raises(
            ValueError, match=r"^src: 2 normal\(s\) inside the mask are not unit length \(\|n\| from 0.500"
        ):
            check(short, "src")
        bad = n.copy()
        bad[0, 1, 2] = np.nan
        with pytest.raises(ValueError, match=r"1 normal\(s\) inside the mask are NaN or infinite"):
            check(bad)
        outside = n.copy()
        outside[0, 3] = [7.0, 0.0, 0.0]  # outside the mask: not judged
        check(outside)

    zero = n.copy()
    zero[0, 2] = 0
    with pytest.raises(ValueError, match=r"1 normal\(s\) .* 1 of them are exactly 0 .*--allow-missing"):
        check_normals(zero, mask)
    out, valid = check_normals(zero, mask, allow_missing=True)
    assert valid.tolist() == [[True, True, False, False]] and np.all(out[0, 2] == 0)
    np.testing.assert_array_equal(unit_normals(zero, mask)[0, 2], [0, 0, 1])


def test_a_map_facing_away_from_the_camera_is_refused_by_every_check():
    """Sweep 26: a start map whose normals all point away from the camera (z flipped: another convention) was
    refined, and judged, without a word; a poor map's few normals tilted past the silhouette are still judged."""
    mask = np.ones((1, 4), bool)
    d = np.array([3.0, 4.0, 12.0]) / 13.0
    n = np.tile(d, (1, 4, 1))
    flipped = n * [1, 1, -1]
    for check in (lambda m: check_normals(m, mask)[0], lambda m: unit_normals(m, mask)):
        with pytest.raises(ValueError, match=r"^--normals: 100% of the normals inside the mask face away from the "
                                             r"camera \(n_z < 0\)"):
            check(flipped)
        some = n.copy()
        some[0, :2] = flipped[0, :2]  # half of them: a very poor map, judged as one
        np.testing.assert_allclose(check(some)[0, 0], flipped[0, 0], atol=1e-6)
