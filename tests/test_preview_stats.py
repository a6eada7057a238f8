"""The dataset card (`python -m wildgen.preview --stats DIR`) of a small rendered dataset, its numbers checked
against the object folders read here independently (JSON and OpenCV, not the project's readers), and its
picture (matplotlib) checked to plot those numbers."""
from __future__ import annotations

import json
import shutil
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from fixtures import use_variant

FAMILIES = ["directional", "point", "near_area", "mixed"]  # directional, point, area and environment lights
SMALL = ["--objects", str(len(FAMILIES)), "--lights", ",".join(FAMILIES), "--images", "2", "--res", "16",
         "--spp", "4", "--gt-spp", "4", "--bounces", "1", "--camera", "perspective", "--sensor", "webcam",
         "--focal", "15-300", "--detail", "0.5", "--seed", "3", "--variant", "llvm_ad_rgb", "--quiet"]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    from wildgen.make import main

    use_variant("llvm_ad_rgb")
    out = tmp_path_factory.mktemp("card") / "data"
    assert main(["--out", str(out), *SMALL]) == 0
    return out


def card(dataset: Path, *extra: str, capsys) -> tuple[int, dict | None, str, str]:
    """Run the CLI; (exit status, stats.json or None, what it printed on stdout, on stderr)."""
    from wildgen.preview import main

    rc = main([str(dataset), "--stats", *extra])
    printed, err = capsys.readouterr()
    out = Path(extra[extra.index("--out") + 1]) if "--out" in extra else dataset / "preview"
    summary = json.loads((out / "stats.json").read_text()) if rc in (0, 1) else None  # 1: objects failed
    return rc, summary, printed, err


def scenes_of(dataset: Path) -> dict[str, dict]:
    return {f.name[:-5]: json.loads((f / "scene.json").read_text()) for f in sorted(dataset.glob("*.data"))}


def normals_of(folder: Path) -> np.ndarray:
    """Unit camera-frame normals of the mask pixels that have one: mask.png any channel > 0, normal.tif 16-bit
    (n + 1) / 2 in RGB order (OpenCV reads BGR), vectors shorter than 0.5 mean "no normal"."""
    import cv2

    mask = cv2.imread(str(folder / "mask.png"), cv2.IMREAD_UNCHANGED)
    mask = (mask.max(axis=2) if mask.ndim == 3 else mask) > 0
    img = cv2.imread(str(folder / "normal.tif"), cv2.IMREAD_UNCHANGED)
    n = img[..., ::-1].astype(np.float64) / 65535.0 * 2.0 - 1.0
    length = np.linalg.norm(n, axis=2)
    keep = mask & (length >= 0.5)
    return n[keep] / length[keep][:, None], int(mask.sum())


def summary(values) -> dict:
    v = np.asarray(values, np.float64)
    return {"count": len(v), "min": v.min(), "median": float(np.median(v)), "max": v.max()}


def close(got: dict, want: dict) -> bool:
    return got["count"] == want["count"] and all(abs(got[k] - want[k]) < 1e-6 for k in ("min", "median", "max"))


def test_card_numbers_match_the_scene_files(dataset, tmp_path, capsys):
    import cv2

    rc, stats, printed, err = card(dataset, "--out", str(tmp_path / "card"), capsys=capsys)
    assert rc == 0, err
    assert str(tmp_path / "card" / "stats.png") in printed and str(tmp_path / "card" / "stats.json") in printed
    picture = cv2.imread(str(tmp_path / "card" / "stats.png"))
    assert picture is not None and picture.shape[:2] == (1256, 1620) and picture.std() > 10

    scenes = scenes_of(dataset)
    assert stats["objects"] == len(scenes) == len(FAMILIES) and stats["failed"] == {}
    images = [im for s in scenes.values() for im in s["images"]]
    lights = [(s, l) for s in scenes.values() for im in s["images"] for l in im["lights"]]
    assert stats["images"] == len(images)
    assert stats["materials"] == dict(Counter(s["material"]["material_class"] for s in scenes.values()))
    assert stats["objects_per_scene"] == dict(Counter(str(max(1, len(s["parts"]))) for s in scenes.values()))
    assert stats["detail"] == dict(Counter((s["material"].get("detail") or {}).get("kind")
                                           or ("normal-map file" if s["material"]["normal_map"] else "none")
                                           for s in scenes.values()))
    assert stats["light_families"] == dict(Counter(FAMILIES))

    # Light counts by type, and per image.
    by_type = Counter(l["type"] for _, l in lights)
    assert {"directional", "point", "area", "environment"} <= set(by_type)
    assert {t: e["lights"] for t, e in stats["lights"]["per_type"].items() if e["lights"]} == dict(by_type)
    for t, e in stats["lights"]["per_type"].items():
        assert sum(e["per_image"].values()) == len(images)
        assert e["images_with"] == sum(1 for im in images if any(l["type"] == t for l in im["lights"]))
    assert stats["lights"]["per_image"] == {
        str(k): v for k, v in sorted(Counter(len(im["lights"]) for im in images).items())
    }

    # Visible normals: every mask pixel with a normal counted once, in the right bin.
    n = [normals_of(dataset / f"{name}.data") for name in scenes]
    pixels = np.concatenate([v for v, _ in n])
    normals = stats["normals"]
    assert normals["mask_pixels"] == sum(m for _, m in n)
    assert normals["pixels"] == len(pixels) == normals["mask_pixels"] - normals["without_normal"] > 0
    hist = np.asarray(normals["nx_ny_histogram"]["counts"])
    assert hist.sum() == len(pixels) == sum(normals["angle_to_view_axis_deg"]["counts"])
    edges = np.asarray(normals["nx_ny_histogram"]["nx_edges"])
    mine = np.histogram2d(pixels[:, 0], pixels[:, 1], [edges, edges])[0]
    assert np.abs(hist - mine).sum() <= 2  # a pixel on a bin edge may fall either side (float32 in the reader)
    angles = np.degrees(np.arccos(np.clip(pixels[:, 2], -1, 1)))
    assert abs(normals["angle_to_view_axis_deg"]["mean"] - angles.mean()) < 1e-3
    assert abs(normals["angle_to_view_axis_deg"]["max"] - angles.max()) < 1e-3

    # Directions toward the lights and distances of near lights. The generator's camera sits on +z looking at
    # the origin with +y up, so its frame is the world frame.
    elevation, distance = [], []
    for s, l in lights:
        assert (
            s["camera"]["target"] == [0, 0, 0]
            and s["camera"]["up"] == [0, 1, 0]
            and s["camera"]["origin"][:2] == [0, 0]
        )
        to_world = np.asarray(s["shape"]["to_world"])
        if l["type"] == "directional":
            d = -np.asarray(l["direction"])
        elif l["type"] in ("point", "area"):
            d = np.asarray(l["position"]) - to_world[:3, 3]
            distance.append(np.linalg.norm(d) / np.linalg.svd(to_world[:3, :3], compute_uv=False)[0])
        else:
            continue
        elevation.append(np.degrees(np.arcsin(d[2] / np.linalg.norm(d))))
    directions = stats["lights"]["directions"]
    assert directions["lights"] == len(elevation) and directions["without_direction"] == by_type["environment"]
    assert np.asarray(directions["counts"]).sum() == len(elevation)
    assert close(directions["elevation_deg"], summary(elevation))
    distances = stats["lights"]["distances"]
    assert distances["unit"] == "object radii" and close(distances, summary(distance))
    assert sum(distances["counts"]) == len(distance)

    # Strengths, exposures, camera, sensor, levels.
    irradiance = [l["irradiance"] for _, l in lights if l["type"] == "directional"]
    assert stats["lights"]["strength"]["directional"]["field"] == "irradiance"
    assert close(stats["lights"]["strength"]["directional"], summary(irradiance))
    assert stats["lights"]["strength"]["area"]["field"] == "radiance"
    assert close(stats["exposure"], summary([im["exposure"] for im in images]))
    assert sum(stats["exposure"]["counts"]) + stats["exposure"]["zero"] == len(images)
    camera = stats["camera"]
    assert camera["kinds"] == {"perspective": len(scenes)} and camera["resolutions"] == {"16x16": len(scenes)}
    assert close(camera["fov_deg"], summary([s["camera"]["fov"] for s in scenes.values()]))
    focal = [s["camera"]["focal_mm"] for s in scenes.values() if s["camera"].get("focal_mm") is not None]
    assert camera["focal_mm"] == "not recorded" if not focal else close(camera["focal_mm"], summary(focal))
    levels = [s["level"] for s in scenes.values() if s.get("level") is not None]
    assert (
        stats["levels"] == "not recorded"
        if not levels
        else stats["levels"]["counts"] == dict(Counter(map(str, levels)))
    )
    assert stats["sensors"] == {"webcam": len(scenes)}

    # The picture: each panel plots the numbers computed here.
    check_card_figure(stats, pixels, distance, irradiance)


def check_card_figure(stats: dict, pixels: np.ndarray, distance: list, irradiance: list) -> None:
    from matplotlib.collections import LineCollection, QuadMesh

    from wildgen.card_figure import draw_stats

    fig = draw_stats(stats)
    assert fig.get_suptitle().startswith(f"Dataset card: {stats['dataset']}\n{len(FAMILIES)} objects")
    panels = {ax.get_title(loc="left").split("\n")[0]: ax for ax in fig.axes if ax.get_title(loc="left")}
    assert len(panels) == 9

    def heat(title):
        (mesh,) = [c for c in panels[title].collections if isinstance(c, QuadMesh)]
        return mesh

    edges = np.asarray(stats["normals"]["nx_ny_histogram"]["nx_edges"])
    mine = np.histogram2d(pixels[:, 0], pixels[:, 1], [edges, edges])[0]
    mesh = heat("Visible normals (n_x, n_y)")
    shown = mesh.get_array().filled(0).reshape(40, 40).T  # rows of the mesh are n_y bins
    assert np.abs(shown - mine).sum() <= 2 and np.all(mesh.get_array().mask.reshape(40, 40).T == (shown == 0))
    assert mesh.get_clim() == (0.0, float(shown.max()))
    assert panels["Visible normals (n_x, n_y)"].get_xlabel() == "n_x (right)"

    angles = np.degrees(np.arccos(np.clip(pixels[:, 2], -1, 1)))
    bars = panels["Angle between normal and view axis"].patches
    assert len(bars) == 90 and [b.get_x() for b in bars] == pytest.approx(np.arange(0, 180, 2))
    heights = np.array([b.get_height() for b in bars])
    assert np.abs(heights - np.histogram(angles, np.linspace(0, 180, 91))[0]).sum() <= 2

    directions = heat("Directions toward the lights")
    assert directions.get_array().sum() == stats["lights"]["directions"]["lights"]

    near = panels["Distance of near lights from the object centre"]
    assert sum(b.get_height() for b in near.patches) == len(distance) and near.get_xlabel() == "distance (object radii)"
    assert near.patches[0].get_x() == pytest.approx(min(distance))

    strength = panels["Light strengths by type"]
    assert strength.get_xscale() == "log"
    labels = [t.get_text() for t in strength.get_yticklabels()]
    y = strength.get_yticks()[labels.index("directional (irradiance)")]
    segments = [seg for c in strength.collections if isinstance(c, LineCollection) for seg in c.get_segments()]
    (row,) = [seg for seg in segments if np.all(seg[:, 1] == y)]
    assert sorted(row[:, 0]) == pytest.approx([min(irradiance), max(irradiance)])

    exposure = panels["Exposure per image"]
    assert exposure.get_xscale() == "log" and sum(b.get_height() for b in exposure.patches) == stats["images"]

    kinds = panels["Materials, detail and light families"]
    widths = [b.get_width() for b in kinds.patches]
    assert len(widths) == len(stats["materials"]) + len(stats["detail"]) + len(stats["light_families"])
    assert widths[-len(FAMILIES):] == [1.0] * len(FAMILIES)  # one object per family: equal bars, full length
    notes = {t.get_text() for t in kinds.texts}
    assert all(f"{n} ({100 * n / len(FAMILIES):.0f}%)" in notes for n in stats["materials"].values())

    capture = " ".join(t.get_text() for t in panels["Camera, sensor, levels"].texts)
    assert "webcam: 4" in capture and "16x16: 4" in capture


def test_unreadable_objects_are_recorded_and_the_rest_summarised(dataset, tmp_path, capsys):
    data = tmp_path / "data"
    shutil.copytree(dataset, data)
    names = sorted(scenes_of(data))
    (data / f"{names[1]}.data" / "normal.tif").write_bytes(b"not a TIFF file")
    (data / f"{names[2]}.data" / "scene.json").write_text("{broken")
    scene = json.loads((data / f"{names[3]}.data" / "scene.json").read_text())
    scene["images"][0]["lights"][0]["type"] = "laser"
    (data / f"{names[3]}.data" / "scene.json").write_text(json.dumps(scene))

    rc, stats, printed, err = card(data, capsys=capsys)  # no --out: DIR/preview/
    # sweep 37: the card was written and the command said nothing of the 3 objects left out (exit 0); as the
    # contact sheets, it exits 1 naming the first and where the rest are listed
    assert rc == 1 and err.count("\n") == 1 and err.startswith("error: 3 object(s) could not be read"), err
    assert f"first, {names[1]}" in err and str(data / "preview" / "stats.json") in err
    assert (data / "preview" / "stats.png").is_file() and str(data / "preview" / "stats.json") in printed
    failed = stats["failed"]
    assert sorted(failed) == names[1:]
    assert all("\n" not in why for why in failed.values())
    assert "normal.tif" in failed[names[1]] and "scene.json" in failed[names[2]] and "laser" in failed[names[3]]
    kept = scenes_of(dataset)[names[0]]
    assert stats["objects"] == 1 and stats["images"] == len(kept["images"])
    assert stats["materials"] == {kept["material"]["material_class"]: 1}
    assert stats["light_families"] == {kept["light_family"]: 1}
    assert stats["normals"]["pixels"] == len(normals_of(dataset / f"{names[0]}.data")[0])


def test_bad_input_is_one_line(dataset, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    junk = tmp_path / "junk" / "x.data"
    junk.mkdir(parents=True)
    (junk / "scene.json").write_text("[]")
    for folder, needles in ((tmp_path / "nowhere", ("DIR", "nowhere")), (tmp_path / "empty", ("DIR", "empty")),
                            (tmp_path / "junk", ("DIR", "none of the 1", "x"))):
        rc, _, _, err = card(folder, "--out", str(tmp_path / "o"), capsys=capsys)
        err = err.strip()
        assert rc == 2 and err.startswith("error:") and "\n" not in err and all(n in err for n in needles), err
    assert not (tmp_path / "o").exists()

    out = ["--out", str(tmp_path / "card")]
    assert card(dataset, *out, capsys=capsys)[0] == 0
    rc, _, _, err = card(dataset, *out, capsys=capsys)  # an earlier card is replaced only with --overwrite
    assert rc == 2 and "--overwrite" in err and "stats.png" in err
    assert card(dataset, *out, "--overwrite", capsys=capsys)[0] == 0


def test_stats_flag_is_documented():
    from wildgen.preview import COMMAND

    text = " ".join(COMMAND.help().split())
    assert "--stats" in text and "dataset card" in text
