"""The one JSON writer (`scenes.files.write_json`): plain values out of NumPy ones, null for a non-finite number
(a file is always valid JSON), written atomically, each file in its own layout (indent, sorted keys, newline)."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from scenes.files import json_text, to_plain, write_json


def strict_loads(text: str):
    """json.loads that refuses NaN / Infinity literals (Python's json accepts them; other readers do not)."""

    def refuse(name: str):
        raise ValueError(f"invalid JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def test_non_finite_numbers_become_null_and_the_file_is_valid_json(tmp_path):
    path = tmp_path / "report.json"
    value = {"nan": float("nan"), "inf": float("inf"), "-inf": -np.inf, "np_nan": np.float32("nan"),
             "list": [1.0, float("nan"), (2, np.inf)], "ok": 0.25}
    write_json(path, value)
    assert strict_loads(path.read_text()) == {"nan": None, "inf": None, "-inf": None, "np_nan": None,
                                              "list": [1.0, None, [2, None]], "ok": 0.25}


def test_numpy_and_other_values_come_out_plain():
    @dataclasses.dataclass
    class Point:
        x: float
        where: Path

    out = to_plain({"f64": np.float64(0.1), "f32": np.float32(0.5), "i": np.int64(3), "u8": np.uint8(255),
                    "b": np.bool_(True), "arr": np.arange(3, dtype=np.int32), "grid": np.eye(2),
                    "tuple": (1, "a"), "path": Path("/a/b"), "point": Point(np.float64(2.0), Path("c")),
                    np.int64(7): "numpy key", "none": None})
    assert out == {"f64": 0.1, "f32": 0.5, "i": 3, "u8": 255, "b": True, "arr": [0, 1, 2],
                   "grid": [[1.0, 0.0], [0.0, 1.0]], "tuple": [1, "a"], "path": "/a/b",
                   "point": {"x": 2.0, "where": "c"}, 7: "numpy key", "none": None}
    types = {k: type(v) for k, v in out.items()}
    assert types["f64"] is float and types["f32"] is float and types["i"] is int and types["b"] is bool
    assert all(type(v) is int for v in out["arr"]) and type(out["grid"][0][0]) is float
    assert to_plain(np.float64("nan")) is None and to_plain(float("-inf")) is None


def test_unknown_types_and_strict_mode_name_where(tmp_path):
    with pytest.raises(TypeError, match=r"^a\.b\[1\]: object is not JSON serializable$"):
        to_plain({"a": {"b": [1, object()]}})
    with pytest.raises(ValueError, match=r"^scene\.images\[0\]\.exposure: got nan"):
        to_plain({"images": [{"exposure": float("nan")}]}, strict=True, where="scene")
    with pytest.raises(ValueError, match="non-finite"):
        write_json(tmp_path / "scene.json", {"x": np.inf}, strict=True)
    assert not (tmp_path / "scene.json").exists()


def test_the_layout_is_the_callers(tmp_path):
    obj = {"b": 1, "a": [1, 2]}
    assert json_text(obj) == json.dumps(obj, indent=1)
    assert json_text(obj, indent=None, sort_keys=True, newline=True) == json.dumps(obj, sort_keys=True) + "\n"
    assert json_text(obj, indent=2, sort_keys=True) == json.dumps(obj, indent=2, sort_keys=True)
    write_json(tmp_path / "index.json", obj, indent=1, sort_keys=True, newline=True)
    assert (tmp_path / "index.json").read_text() == json.dumps(obj, indent=1, sort_keys=True) + "\n"
    # Floats print as Python prints them (the same bytes as json.dumps of the float or NumPy float).
    for x in (0.1, 1 / 3, 1e-300, 123456789.123, np.float64(2) ** 0.5):
        assert json_text([x]) == json.dumps([float(x)], indent=1)


def test_a_failed_write_leaves_the_old_file_intact(tmp_path, monkeypatch):
    path = tmp_path / "manifest.json"
    write_json(path, {"old": 1})
    old = path.read_bytes()
    with pytest.raises(TypeError):
        write_json(path, {"new": object()})  # fails before anything is written
    assert path.read_bytes() == old

    def full_disk(self, text, *args, **kwargs):
        self.write_bytes(text[: len(text) // 2].encode())
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_text", full_disk)
    with pytest.raises(OSError, match="No space left"):
        write_json(path, {"new": list(range(100))})
    assert path.read_bytes() == old
    assert [p.name for p in tmp_path.iterdir()] == ["manifest.json"]  # no temporary left behind


def test_a_dataset_manifest_with_nan_is_valid_json(tmp_path):
    from wildgen.config import GenConfig
    from wildgen.dataset import MANIFEST, write_manifest

    cfg = GenConfig(lights=["directional"], objects=1, images=1, width=8, height=8, spp=1, gt_spp=1)
    write_manifest(tmp_path, cfg, "scalar_rgb", {0: {"name": "object_0000", "mean_radiance": float("nan"),
                                                     "pixels": np.int64(12)}}, extra={"ratio": np.float32(0.5)})
    text = (tmp_path / MANIFEST).read_text()
    manifest = strict_loads(text)
    assert manifest["objects"] == [{"name": "object_0000", "mean_radiance": None, "pixels": 12}]
    assert manifest["ratio"] == 0.5
    assert text == json.dumps(manifest, indent=1, sort_keys=True)  # the layout of a dataset's manifest.json


def test_a_model_card_with_nan_is_valid_json(tmp_path):
    from orchestrate.train_recipe import install_weights
    from unips.models.builder import sidecar_path

    weights = tmp_path / "run" / "final.safetensors"
    weights.parent.mkdir()
    weights.write_bytes(b"weights")
    sidecar_path(weights).write_text("{}")
    entry = SimpleNamespace(weights_path=tmp_path / "registry" / "glc-tiny.safetensors",
                            card_path=tmp_path / "registry" / "model_card.json")
    card = {"final_loss": float("nan"), "lr": np.float32(0.25), "steps": np.int64(10),
            "lineage": [{"mae_deg": np.float64("inf")}]}
    install_weights(weights, entry, card)
    assert strict_loads(entry.card_path.read_text()) == {"final_loss": None, "lr": 0.25, "steps": 10,
                                                         "lineage": [{"mae_deg": None}]}


def test_scene_json_refuses_a_non_finite_number(tmp_path):
    """A NaN in a scene description is a bug (its reader would refuse the null): scene.json is written strictly."""
    from scenes.folder.format import SCENE_FILE, scene_json_text, write_object_folder

    with pytest.raises(ValueError, match=r"^extra: got nan"):
        scene_json_text(SimpleNamespace(to_dict=lambda: {"camera": {}}), {"extra": float("nan")})
    images, mask = np.zeros((1, 4, 4, 3), np.float32), np.ones((4, 4), bool)
    write_object_folder(tmp_path / "o.data", images, mask, None, scene={"b": np.float64(1.5), "a": (1, 2)})
    text = (tmp_path / "o.data" / SCENE_FILE).read_text()
    assert text == '{"b": 1.5, "a": [1, 2]}'  # the plain dict as given, as json.dumps(scene) wrote it


def test_a_json_record_holding_half_a_character_is_refused_naming_the_file(tmp_path):
    """JSON's escape \\udce9 is valid syntax but a lone surrogate, which no file, page, figure or terminal can write:
    read_json refuses it naming the file (sweep 21: a scene.json light_family so escaped ended in a traceback in
    the benchmark's tables and the preview's figures). A whole escape pair is one character and is read."""
    from scenes.files import read_figures, read_json

    (tmp_path / "half.json").write_text('{"light_family": "caf\\udce9"}')
    for reader in (read_json, read_figures):
        with pytest.raises(ValueError, match=r"half.json.*escape \\udce9 is half of a character"):
            reader(tmp_path / "half.json")
    (tmp_path / "pair.json").write_text('{"name": "\\ud83d\\ude00"}')
    assert read_json(tmp_path / "pair.json") == {"name": "\U0001f600"}


def test_a_json_record_holding_a_key_twice_is_refused_naming_the_file_and_the_key(tmp_path):
    """Sweep 23's drafts: a manifest entry with "status": "failed", then "status": "done" (an edit merged by hand):
    Python keeps the last value, other readers the first. The one reader refuses it, naming the file and the key;
    figures' readers too (their object_hook still applies to records that pass)."""
    from scenes.files import read_figures, read_json

    (tmp_path / "twice.json").write_text('{"objects": [{"status": "failed", "error": "e", "status": "done"}]}')
    for reader in (read_json, read_figures):
        with pytest.raises(ValueError, match=r"twice.json.*holds the key 'status' twice"):
            reader(tmp_path / "twice.json")
    (tmp_path / "once.json").write_text('{"a": {"b": 1}}')
    assert read_figures(tmp_path / "once.json", object_hook=lambda d: {**d, "seen": True}) == \
        {"a": {"b": 1, "seen": True}, "seen": True}
