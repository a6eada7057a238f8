"""Training from simple to complex (`unips.train --curriculum`): the objects a step may draw follow the
complexity levels recorded in scene.json (`wildgen.make --level`), stage by stage, and a real run trains on them."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fixtures import render_dataset, write_object


def test_pool_adds_the_levels_one_stage_at_a_time():
    from unips.train_data import curriculum_pool

    levels = [3, 1, 2, 1, 3]
    # 60 steps, the first half in 3 stages of 10 steps: levels <= 1, <= 2, <= 3; then everything
    assert curriculum_pool(levels, 0, 60, 0.5) == [1, 3]
    assert curriculum_pool(levels, 9, 60, 0.5) == [1, 3]
    assert curriculum_pool(levels, 10, 60, 0.5) == [1, 2, 3]
    assert curriculum_pool(levels, 25, 60, 0.5) == [0, 1, 2, 3, 4]
    assert curriculum_pool(levels, 59, 60, 0.5) == [0, 1, 2, 3, 4]
    with pytest.raises(ValueError, match="--curriculum"):
        curriculum_pool([1, None, 2], 0, 10, 0.5)


@pytest.fixture(scope="module")
def levelled(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("levels")
    rng = np.random.default_rng(7)
    for level in (1, 3):
        for i in range(3):
            folder = root / f"L{level}" / f"obj{i}.data"
            write_object(folder, rng, 40, 6, "directional")
            scene = json.loads((folder / "scene.json").read_text())
            scene["level"] = level
            (folder / "scene.json").write_text(json.dumps(scene))
    write_object(root / "nolevel" / "obj.data", rng, 40, 6, "directional")
    return {"L1": root / "L1", "L3": root / "L3", "none": root / "nolevel"}


def test_early_batches_hold_only_the_simplest_level(levelled):
    from unips.train_data import curriculum_pool, load_samples, make_batch

    samples = load_samples(f"{levelled['L1']},{levelled['L3']}", 32)
    levels = [s.level for s in samples]
    assert sorted(levels) == [1, 1, 1, 3, 3, 3]  # read from scene.json through the one reader
    # Tag each object's images with its level, so the batch itself shows which objects were drawn.
    for s in samples:
        s.images = s.images * 0 + float(s.level)
    settings = dict(seed=0, batch=2, min_images=2, max_images=4, pixels=50, canonical=8, augment=False)
    drawn = {}
    for step in range(16):
        batch = make_batch(samples, step, pool=curriculum_pool(levels, step, 16, 1.0), **settings)
        drawn[step] = {round(float(v)) for v in batch.images.amax(dim=(1, 2, 3, 4))}
    assert all(drawn[step] == {1} for step in range(8))  # first stage: the simplest level only
    assert any(3 in drawn[step] for step in range(8, 16))  # then the complex level comes in


def test_a_curriculum_run_trains_and_refuses_unlevelled_data(levelled, tmp_path):
    from unips.train import main

    base = [
        "--model",
        "glc-test",
        "--batch",
        "2",
        "--res",
        "32",
        "--pixels",
        "200",
        "--max-images",
        "4",
        "--threads",
        "1",
        "--no-progress",
        "--steps",
        "6",
        "--curriculum",
        "--curriculum-fraction",
        "0.5",
    ]
    assert main(["--data", f"{levelled['L1']},{levelled['L3']}", "--out", str(tmp_path / "run"), *base]) == 0
    log = [json.loads(line) for line in (tmp_path / "run" / "log.jsonl").read_text().splitlines()]
    assert log and all(np.isfinite(r["loss"]) for r in log if "loss" in r)
    assert main(["--data", str(levelled["none"]), "--out", str(tmp_path / "bad"), *base]) == 2


def test_level_fills_the_configuration_and_is_recorded(tmp_path):
    from wildgen.levels import LEVELS

    tiny = ["--objects", "2", "--images", "1", "--res", "16", "--spp", "1", "--gt-spp", "1"]
    level1 = render_dataset(tmp_path / "l1", *tiny, "--level", "1")
    level5 = render_dataset(tmp_path / "l5", *tiny, "--level", "5", "--lights", "point")
    for folder in level1:
        scene = json.loads((folder / "scene.json").read_text())
        assert scene["level"] == 1 and scene["light_family"] in LEVELS[1].config.lights
        assert scene["material"]["material_class"] == "diffuse" and scene["parts"] == []
    for folder in level5:
        scene = json.loads((folder / "scene.json").read_text())
        assert scene["level"] == 5 and scene["light_family"] == "point"  # the explicit flag keeps its value
        assert 2 <= len(scene["parts"]) <= 4  # the level's clusters
    config = json.loads((tmp_path / "l1" / "manifest.json").read_text())["config"]
    assert config["shape_kinds"] == ["superquadric"] and config["shapes"] == "procedural"


def test_a_level_outside_the_generators_is_refused_naming_scene_json(levelled, tmp_path):
    """scene.json's level is one of wildgen.make's (1 to 5): level 99 would become a curriculum stage of its own."""
    import shutil

    from scenes.folder.calibration import LEVEL_RANGE
    from unips.train_data import load_samples
    from wildgen.levels import LEVELS

    assert LEVEL_RANGE == (min(LEVELS), max(LEVELS)) and sorted(LEVELS) == list(range(LEVEL_RANGE[0],
                                                                                     LEVEL_RANGE[1] + 1))
    for bad in (0, 99):
        data = tmp_path / f"L{bad}"
        shutil.copytree(levelled["L1"], data)
        scene_file = data / "obj1.data" / "scene.json"
        scene = json.loads(scene_file.read_text())
        scene["level"] = bad
        scene_file.write_text(json.dumps(scene))
        with pytest.raises(ValueError, match=rf"obj1.data.*level must be a whole number from 1 to 5 .*got {bad}"):
            load_samples(str(data), 32)
