"""Do the capture's light warnings (`frontal_light`, `one_sided_light`, read from the shading under the model's map
as `orchestrate.capture` reads them) agree with the true lights of rendered captures? (docs/capture.md, "The lights,
read from the shading").

    python bench/bench_light_warnings.py --suite DIR [--suite DIR ...] --out bench/results/light_warnings.json

Each --suite is a `wildgen.make` dataset; objects whose every image has exactly one placed light (directional, point
or area, beside a dim environment at most: the directional, point, near-area, grid, flash and frontal families, and
the odd mixed object drawn with one) count; an environment alone or several lights have no one direction and are
left out. Each image's true direction is its light's (a point or area
light: from the object's centre to it) in the camera frame. Every object gives the captures of `SUBSETS`, made by
choosing photos by their true light (all of them; those lit from one side; those lit from above; those lit from near
the axis), each predicted by the shipped model on its own photos, then warned about with the true mask.

The truth of a capture applies the warnings' own definitions to the true directions: frontal when no light is further
than `FRONTAL_DEG` off the axis; one-sided when it is not frontal and the lights further off the axis than
`ONE_SIDED_DEG` leave a gap of more than 180 deg around it. A capture whose truth changes when one light moves by
`MARGIN_DEG` from the axis or twice that around it is `borderline` and counted apart: there a few degrees of error
in reading the light decide.
"""
from __future__ import annotations

import json
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.cli_common import (  # noqa: E402
    check_suites,
    claim_result,
    machine,
    need_path,
    parse,
    refusals,
    run_main,
    write_result,
)
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import Command, UseAppendAction, arg, check_fields, option  # noqa: E402
from scenes.files import read_text_file  # noqa: E402

SUBSETS = ("all", "one_side", "above", "near_axis")
"""Captures made of each object's photos: all; those whose light's azimuth lies within 75 deg of the first lit
photo's; those lit from above (light y > 0.1); those lit within 20 deg of the axis."""
MARGIN_DEG = 5.0
"""A capture whose truth changes when one light moves this much from the axis (twice as much around it) is
borderline (module doc)."""
MIN_PHOTOS = 4
"""A subset of fewer photos is not made."""
SIDE_FROM_DEG = 10.0
"""The `one_side` subset takes lights further than this from the axis (the subsets' own choice, kept apart from the
warning's constant)."""


def true_directions(folder: Path) -> np.ndarray | None:
    """(K, 3) unit direction to each image's light in the camera frame, or None when an image has no one light."""
    from scenes.folder.format import read_scene
    from scenes.geometry import lights_in_camera_frame

    desc = read_scene(folder)[0]
    out = []
    for lights in lights_in_camera_frame(desc):
        placed = [light for light in lights if light["type"] != "environment"]
        if len(placed) != 1:
            return None
        light = placed[0]
        d = np.asarray(light["direction_to_light"] if light["type"] == "directional" else light["position"], float)
        out.append(d / np.linalg.norm(d))
    return np.array(out)


def _classes(polar: np.ndarray, azimuth: np.ndarray) -> tuple[bool, bool, float]:
    """(frontal, one-sided, the gap in deg) of lights at these angles, by the warnings' own definitions."""
    from validate.diagnosis.usable import FRONTAL_DEG, ONE_SIDED_DEG, ONE_SIDED_GAP_DEG, _largest_gap_deg

    frontal = bool(polar.max() < FRONTAL_DEG)
    off = polar > ONE_SIDED_DEG
    gap = _largest_gap_deg(azimuth[off]) if off.sum() >= 2 else 0.0
    return frontal, bool(not frontal and off.sum() >= 2 and gap > ONE_SIDED_GAP_DEG[0]), gap


def truth(directions: np.ndarray) -> dict:
    """The warnings the true directions call for, and whether the capture is borderline: the truth changes when one
    light moves by MARGIN_DEG from the axis or twice that around it (module doc)."""
    polar = np.degrees(np.arccos(np.clip(directions[:, 2], -1, 1)))
    azimuth = np.degrees(np.arctan2(directions[:, 1], directions[:, 0]))
    frontal, one_sided, gap = _classes(polar, azimuth)
    border = False
    for i in range(len(polar)):
        for dp in (-MARGIN_DEG, 0.0, MARGIN_DEG):
            for da in (-2 * MARGIN_DEG, 0.0, 2 * MARGIN_DEG):
                p, a = polar.copy(), azimuth.copy()
                p[i], a[i] = max(p[i] + dp, 0.0), a[i] + da
                border = border or _classes(p, a)[:2] != (frontal, one_sided)
    return {"frontal_light": frontal, "one_sided_light": one_sided, "borderline": border,
            "max_polar_deg": round(float(polar.max()), 1), "gap_deg": round(float(gap), 1)}


def subsets(directions: np.ndarray) -> dict[str, np.ndarray]:
    """Image indices of each capture of `SUBSETS` with at least MIN_PHOTOS photos."""
    polar = np.degrees(np.arccos(np.clip(directions[:, 2], -1, 1)))
    azimuth = np.degrees(np.arctan2(directions[:, 1], directions[:, 0]))
    lit = np.nonzero(polar > SIDE_FROM_DEG)[0]
    picks = {"all": np.arange(len(directions)), "above": np.nonzero(directions[:, 1] > 0.1)[0],
             "near_axis": np.nonzero(polar < 20.0)[0]}
    if len(lit):
        turn = np.abs((azimuth - azimuth[lit[0]] + 180.0) % 360.0 - 180.0)
        picks["one_side"] = np.nonzero((turn < 75.0) & (polar > SIDE_FROM_DEG))[0]
    return {name: idx for name, idx in picks.items() if len(idx) >= MIN_PHOTOS}


def capture_rows(name: str, family: str, material: str, images: np.ndarray, mask: np.ndarray,
                 directions: np.ndarray, net, picks: dict[str, np.ndarray]) -> list[dict]:
    """One row per capture of `picks` (name -> photo indices): the model's map of those photos alone, the light
    warnings under it with `mask`, and the truth of their true `directions`."""
    from unips.data import PSObject
    from unips.inference import run_model
    from validate.diagnosis.usable import light_warnings

    rows = []
    seen: set[tuple[int, ...]] = set()
    for capture, idx in picks.items():
        if tuple(idx) in seen:  # (one object's "above" may be all of it)
            continue
        seen.add(tuple(idx))
        chosen = images[idx]
        scaled = np.clip(chosen / max(float(chosen[:, mask].max()), 1e-12), 0, 1).astype(np.float32)  # as the capture
        obj = PSObject(name=name, images=scaled, mask=mask, normals=None, light_family=None, light_directions=None,
                       light_intensities=None, path=None, layout="photos")
        normals = run_model(net, obj, tta=net.contract.views)
        warnings, facts = light_warnings(chosen, mask, normals)
        said = {w.code for w in warnings}
        want = truth(directions[idx])
        agree = all((code in said) == want[code] for code in ("frontal_light", "one_sided_light"))
        rows.append({"object": name, "suite": name.split("/")[0], "family": family, "material": material,
                     "capture": capture,
                     "photos": len(idx), **want, "said": sorted(said), "agree": agree,
                     "read_polar_deg": facts.get("light_polar_deg"),
                     "read_azimuth_deg": facts.get("light_azimuth_deg")})
    return rows


def object_rows(folder: Path, net) -> list[dict]:
    """The rows of one rendered object: one per capture of `subsets`."""
    from scenes.folder.format import read_scene_dict
    from unips.data import load_object

    directions = true_directions(folder)
    if directions is None:
        return []
    obj = load_object(folder, arg="--suite")
    material = read_scene_dict(folder)["material"]["material_class"]
    return capture_rows(f"{folder.parent.name}/{folder.name}", obj.light_family, material, obj.images, obj.mask,
                        directions, net, subsets(directions))


LIGHTS = "lights.txt: the number of lights on its first line, then one line x y z per photo"


def read_lights(folder: Path) -> np.ndarray:
    """The unit light directions (N, 3) of `folder`/lights.txt (a real capture of the course's kind, --real); a
    UsageError naming --real and the file when there is none or it is not `LIGHTS`."""
    path = folder / "lights.txt"
    if not path.is_file():
        raise UsageError(f"--real: {str(folder)!r} holds no lights.txt and is no DiLiGenT object folder (NAMEPNG); "
                         f"expected real captures with measured lights ({LIGHTS})")
    try:
        lines = [line for line in read_text_file(path).splitlines() if line.strip()]
        count = int(lines[0].split()[0]) if lines else 0
        d = np.array([[float(v) for v in line.split()] for line in lines[1:]])
    except (OSError, ValueError) as exc:
        raise UsageError(f"--real: {str(path)!r} is not readable ({type(exc).__name__}: {exc}); expected {LIGHTS}"
                         ) from None
    norms = np.linalg.norm(d, axis=1, keepdims=True) if d.ndim == 2 and d.shape[1:] == (3,) else None
    if norms is None or len(d) != count or count < 1 or not np.isfinite(d).all() or not (norms > 0).all():
        shape = "x".join(map(str, d.shape)) if d.size else "no values"
        raise UsageError(f"--real: {str(path)!r} says {count} lights and holds {shape} values after it; expected "
                         f"{LIGHTS}, each finite and not zero")
    return d / norms


def real_objects(folder: Path) -> list[Path]:
    """The object folders of photos of a real capture folder (--real); a UsageError when there is none (nothing
    measured would pass for a measurement)."""
    subs = sorted(p for p in folder.iterdir() if p.is_dir())
    if not subs:
        raise UsageError(f"--real: {str(folder)!r} holds lights.txt but no object folder of photos; expected one "
                         "folder of photos per object beside <object>.mask.png")
    return subs


def real_rows(folder: Path, net) -> list[dict]:
    """The rows of real captures with measured lights: a folder of object folders of photos with `<object>.mask.png`
    beside them and `lights.txt` (the count, then x y z per photo; the course objects of ../shared/data/real/psm),
    all photos; or a DiLiGenT folder (`*PNG`: its calibrated lights), every 6th photo (16) and all 96."""
    from scenes.folder.photos import read_photos
    from scenes.images import read_mask
    from unips.data import load_object

    if folder.name.endswith("PNG"):
        obj = load_object(folder, arg="--real")
        d = obj.light_directions / np.linalg.norm(obj.light_directions, axis=1, keepdims=True)
        k = len(d)
        spaced = {"16 evenly spaced": np.arange(0, k, k // 16)[:16]} if k > 16 else {}  # a folder of fewer: all
        return capture_rows(f"diligent/{folder.name}", "diligent (real)", "real", obj.images, obj.mask, d, net,
                            {**spaced, "all": np.arange(k)})
    d = read_lights(folder)
    rows = []
    for sub in real_objects(folder):
        try:
            photos = read_photos(sub, "auto")
        except (ValueError, FileNotFoundError) as exc:  # said as the flag that named the capture
            raise UsageError(f"--real: {str(exc).removeprefix('--input: ')}") from None
        if len(photos.images) != len(d):
            raise UsageError(f"--real: {str(sub)!r} holds {len(photos.images)} photos and {str(folder)!r}/lights.txt "
                             f"{len(d)} lights; expected one light per photo")
        mask = read_mask(folder / f"{sub.name}.mask.png")
        rows += capture_rows(f"{folder.name}/{sub.name}", f"{folder.name} (real)", "real", photos.images, mask, d,
                             net, {"all": np.arange(len(d))})
    return rows


def summary(rows: list[dict]) -> dict:
    """Agreement overall, apart from the borderline captures, and per family and capture kind."""
    def share(rs):
        return {"captures": len(rs), "agree": sum(r["agree"] for r in rs),
                "share": round(sum(r["agree"] for r in rs) / len(rs), 3) if rs else None}
    clear = [r for r in rows if not r["borderline"]]
    out = {"all": share(rows), "clear": share(clear), "borderline": share([r for r in rows if r["borderline"]])}
    for key in ("suite", "family", "material", "capture"):
        out[f"by_{key}"] = {v: share([r for r in clear if r[key] == v]) for v in sorted({r[key] for r in rows})}
    truths = Counter((r["frontal_light"], r["one_sided_light"]) for r in clear)
    out["clear_truths"] = {f"frontal={f}, one_sided={o}": n for (f, o), n in sorted(truths.items())}
    return out


@dataclass
class Options:
    """The command line of bench/bench_light_warnings.py."""

    suite: Annotated[list[Path], arg(metavar="DIR"), UseAppendAction] = field(default_factory=list)
    """a wildgen.make dataset (repeatable)"""
    real: Annotated[list[Path], arg(metavar="DIR"), UseAppendAction] = field(default_factory=list)
    """real captures with measured lights (repeatable): ../shared/data/real/psm, or a DiLiGenT object folder
    (ballPNG, catPNG)"""
    out: Annotated[Path | None, arg(metavar="FILE")] = None
    """write the rows and the summary as JSON here"""
    threads: int = option(2, minimum=1)
    """torch threads"""

    def validate(self) -> "Options":
        check_fields(self)
        if not self.suite and not self.real:
            raise UsageError("--suite: nothing to measure: expected --suite DIR (a wildgen.make dataset) or --real DIR")
        return self


COMMAND = Command(Options, prog="python bench/bench_light_warnings.py", description=__doc__.split("\n\n")[0])
RESULT_KEYS = ("command", "summary", "rows", "captures")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def table_rows(result: dict) -> list[dict]:
    """The rows of the docs' tables, in their order: the rendered captures' agreement (overall, borderline, per
    material, kind of capture and suite), then each real capture."""
    def row(name: str, x: dict) -> dict:
        return {"captures": name, "count": x["captures"], "agree": x["agree"], "share": x["share"]}

    rows = [row("all rendered captures, borderline apart", result["clear"]), row("borderline", result["borderline"])]
    for key, label in (("by_material", "material"), ("by_capture", "photos chosen"), ("by_suite", "suite")):
        rows += [row(f"{label}: {k}", v) for k, v in result[key].items()]
    return rows + [{"real": r["object"], "capture": r["capture"], "photos": r["photos"],
                    "truth": [k for k in ("frontal_light", "one_sided_light") if r[k]], "said": r["said"]}
                   for r in result["real"]]


def main(argv: list[str] | None = None) -> int:
    import torch

    from unips.inference import load_network

    args = parse(COMMAND, argv)
    check_suites(args.suite)
    for folder in args.real:
        need_path(folder, "--real", "real captures with measured lights, or a DiLiGenT object folder")
        if not folder.name.endswith("PNG"):
            with refusals():
                read_lights(folder)  # before the network is loaded
                real_objects(folder)
    claim_result(args.out, RESULT_KEYS, COMMAND,
                 inputs={f"--suite {d}": d for d in args.suite} | {f"--real {d}": d for d in args.real})
    torch.set_num_threads(args.threads)
    net = load_network(None)
    rows: list[dict] = []
    sources = [(f, object_rows) for suite in args.suite for f in sorted(Path(suite).glob("*.data"))]
    for folder, rows_of in sources + [(f, real_rows) for f in args.real]:
        new = rows_of(folder, net)
        for r in new:
            if not r["agree"]:
                print(f"disagrees: {r['object']} {r['family']} {r['capture']}: truth frontal={r['frontal_light']} "
                      f"one_sided={r['one_sided_light']} (max {r['max_polar_deg']} deg, gap {r['gap_deg']}), "
                      f"said {r['said']}{' (borderline)' if r['borderline'] else ''}", flush=True)
        rows += new
    real = [r for r in rows if r["material"] == "real"]
    result = {**summary([r for r in rows if r["material"] != "real"]), "real": real} if rows else {}
    print(json.dumps(result, indent=1))
    if args.out:

        args.out.parent.mkdir(parents=True, exist_ok=True)
        flags = [f"--suite {s}" for s in args.suite] + [f"--real {s}" for s in args.real]
        write_result(args.out, {"command": "python bench/bench_light_warnings.py " + " ".join(flags), "summary": result,
                              "rows": table_rows(result) if rows else [], "captures": rows, "machine": machine()},
                   indent=1, newline=True)
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
