"""Clusters (`wildgen.make --cluster A-B`): several objects in one scene, touching or overlapping, recorded as
contiguous triangle ranges of one mesh (scene.json `parts`), with aux/instances.png naming the object seen at
each pixel; checked against the geometry (each part's projected vertices), not against the ray caster."""
from __future__ import annotations

import json

import numpy as np
import pytest
from fixtures import render_dataset


@pytest.fixture(scope="module")
def clusters(tmp_path_factory):
    return render_dataset(tmp_path_factory.mktemp("cluster") / "ds", "--objects", "3", "--images", "2", "--res", "40",
                          "--spp", "4", "--gt-spp", "4", "--cluster", "2-3", "--shapes", "procedural", "--lights",
                          "directional", "--seed", "4")


def test_parts_cover_the_mesh_and_instances_cover_the_mask(clusters):
    from scenes.images import read_instances, read_mask
    from scenes.meshes import load_mesh

    assert len(clusters) == 3
    seen = []
    for folder in clusters:
        scene = json.loads((folder / "scene.json").read_text())
        parts = scene["parts"]
        assert 2 <= len(parts) <= 3
        mesh = load_mesh(folder / scene["shape"]["file"], normalize=False)
        assert sum(p["faces"] for p in parts) == len(mesh.faces)
        ids = read_instances(folder / "aux" / "instances.png")
        mask = read_mask(folder / "mask.png")
        assert ids.dtype == np.uint16 and ids.max() <= len(parts)
        np.testing.assert_array_equal(ids > 0, mask)  # every object pixel has an object, the background none
        seen.append(len(np.unique(ids[mask])))
    assert max(seen) >= 2  # objects side by side in view, not one hidden behind another everywhere


def test_instance_ids_agree_with_each_parts_projected_outline(clusters):
    """Orthographic camera looking down -z: pixel (i, j) of an object point (x, y) is ((x + h) / 2h W, (h - y) / 2h H).
    Part k's pixels must lie inside the outline of part k's own projected vertices (its 2-D bounding box)."""
    from scenes.geometry import transformed_mesh
    from scenes.images import read_instances
    from scenes.meshes import load_mesh

    for folder in clusters:
        scene = json.loads((folder / "scene.json").read_text())
        cam = scene["camera"]
        assert cam["kind"] == "orthographic" and cam["origin"][:2] == [0.0, 0.0]
        mesh = transformed_mesh(load_mesh(folder / scene["shape"]["file"], normalize=False), scene["shape"]["to_world"])
        ids = read_instances(folder / "aux" / "instances.png")
        hs, w, h = cam["half_size"], cam["width"], cam["height"]
        for k, part in enumerate(scene["parts"], start=1):
            faces = mesh.faces[part["first_face"]: part["first_face"] + part["faces"]]
            p = mesh.positions[np.unique(faces)]
            col = (p[:, 0] + hs) / (2 * hs) * w
            row = (hs - p[:, 1]) / (2 * hs) * h
            ii, jj = np.nonzero(ids == k)
            if not len(ii):
                continue  # hidden behind the others
            inside = (
                (jj + 0.5 >= col.min() - 1)
                & (jj + 0.5 <= col.max() + 1)
                & (ii + 0.5 >= row.min() - 1)
                & (ii + 0.5 <= row.max() + 1)
            )
            assert inside.all(), (folder.name, k, (~inside).sum())


def test_one_object_scenes_have_no_parts_and_no_instance_file(tmp_path):
    (folder,) = render_dataset(tmp_path / "one", "--objects", "1", "--images", "1", "--res", "16", "--spp", "1",
                               "--gt-spp", "1", "--shapes", "procedural")
    assert json.loads((folder / "scene.json").read_text())["parts"] == []
    assert not (folder / "aux" / "instances.png").exists()


def test_parts_must_follow_each_other():
    from scenes.description import ImageDesc, PartDesc, SceneDescription, ShapeDesc
    from scenes.lights import DirectionalLight

    d = SceneDescription(shape=ShapeDesc(kind="mesh", file="m.ply"), images=[ImageDesc(lights=[DirectionalLight()])],
                         parts=[PartDesc("a", 0, 10), PartDesc("b", 12, 5)])
    with pytest.raises(ValueError, match=r"parts\[1\]"):
        d.validate()


def test_parts_must_share_out_the_mesh_they_name(clusters, variant_llvm_ad_rgb):
    """Sweep 27: a scene.json whose parts claim 10^9 triangles of a small mesh was re-rendered and scored, exit 0.
    The parts' triangles must be the mesh's: refused when the scene is built, naming the mesh and both counts."""
    import dataclasses

    from scenes.folder.format import read_scene
    from scenes.renderer.build import build_scene

    desc, _ = read_scene(clusters[0])
    build_scene(desc, clusters[0])  # as written: whole
    last = desc.parts[-1]
    desc.parts[-1] = dataclasses.replace(last, faces=last.faces + 10**9)
    with pytest.raises(ValueError, match=r"^parts: \d+ triangles in all, the mesh .* has \d+; expected the parts"):
        build_scene(desc, clusters[0])


def test_dataset_card_counts_objects_per_scene(clusters, tmp_path):
    from collections import Counter

    from wildgen.preview import main

    assert main([str(clusters[0].parent), "--stats", "--out", str(tmp_path / "card")]) == 0
    stats = json.loads((tmp_path / "card" / "stats.json").read_text())
    expect = Counter(str(len(json.loads((f / "scene.json").read_text())["parts"])) for f in clusters)
    assert stats["objects_per_scene"] == dict(expect)
