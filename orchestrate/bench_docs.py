"""Tables of docs/ generated from a benchmark's recorded output (bench/results/*.json) instead of the model card:
`orchestrate.docs` renders them into the blocks named in `BENCH_BLOCKS`, and tests/test_docs.py checks that every
figure of such a table is in its JSON, one table row per JSON row."""
from __future__ import annotations

import json
from pathlib import Path

from scenes.files import read_figures
from scenes.report.tables import markdown_table

REPO = Path(__file__).resolve().parents[1]


class _Record(dict):
    """A JSON object of a benchmark's output: a missing key is named with the file it was looked for in."""

    path: Path

    def __missing__(self, key):
        raise KeyError(f"{self.path.relative_to(REPO) if self.path.is_relative_to(REPO) else self.path}: a record "
                       f"without {key!r} (expected the output of the benchmark that writes it; run it again)")


def read_bench(path: Path) -> dict:
    """The one reader of bench/results/*.json: finite figures only (`scenes.files.read_figures`: NaN or Infinity would
    print as a figure), never through a link, every object a `_Record`; a ValueError naming the file otherwise."""
    def record(d: dict) -> _Record:
        r = _Record(d)
        r.path = path
        return r

    try:
        return read_figures(path, object_hook=record)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc}); expected the benchmark's output (run it again)") from None


SHARDS_BENCH = REPO / "bench" / "results" / "shards.json"
"""The output of `python bench/bench_shards.py --out bench/results/shards.json` (its last run, committed)."""
_READS = {"files": "files (every file's bytes)", "objects": "objects (decoded by the loader)",
          "samples": "training samples (`load_samples`)"}


def shards_throughput(card: dict) -> str:
    """Folders against shards of both encodings, from the benchmark's recorded output (not the model card)."""
    d = read_bench(SHARDS_BENCH)
    st, sz = d["settings"], d["sizes"]
    rows = [[_READS[r["read"]], r["cache"], f"{r['folders_per_s']:.0f}", f"{r['files_per_s']:.0f}",
             f"{r['decoded_per_s']:.0f}", f"{r['ratio_files']:.2f}x", f"**{r['ratio_decoded']:.2f}x**"]
            for r in d["rows"]]

    def mib(b):
        return f"{b / 2**20:.1f} MiB"

    return (f"{st['objects']} synthetic objects of {st['images']} images at {st['res']} x {st['res']} px, shards of "
            f"{st['shard_size']}; on disk: {sz['folder_files']} files of folders {mib(sz['folder_bytes'])}, shards "
            f"of files {mib(sz['shard_bytes_files'])}, decoded shards {mib(sz['shard_bytes_decoded'])}.\n\n"
            + markdown_table(["read", "cache", "folders (objects/s)", "shards, files (objects/s)",
                              "shards, decoded (objects/s)", "files / folders", "decoded / folders"], rows))


CAPTURE_DILIGENT_BENCH = REPO / "bench" / "results" / "capture_diligent.json"
"""The output of `python bench/bench_capture_diligent.py --work WORK` (committed)."""
_DILIGENT_CASES = {"jpeg_true": "JPEG, true mask", "jpeg_auto": "JPEG, `--mask auto`",
                   "png_true": "16-bit PNG, true mask"}


def capture_diligent(card: dict) -> str:
    """Per DiLiGenT object and capture: the final and the model's map's error, which was kept and the residuals
    behind the choice, time and memory."""
    d = read_bench(CAPTURE_DILIGENT_BENCH)
    rows = []
    for r in d["rows"]:
        held = (f"{r['held_before']:.4f} -> {r['held_after']:.4f}" if r.get("held_before") is not None else "-")
        iou = f" (IoU {r['mask_iou']:.3f})" if "mask_iou" in r else ""
        rows.append([r["object"], _DILIGENT_CASES[r["case"]] + iou,
                     f"{r['final_deg']:.2f}", f"{r['model_deg']:.2f}", "refined" if r["refined_kept"] else "model's",
                     f"{r['judged_before']:.4f} -> {r['judged_after']:.4f}", held, f"{r['wall_s']:.0f}",
                     str(r["peak_mib"])])
    return (f"`{d['command']}` (all 96 photos, {d['clip_share']:.1%} of the object's values clipped in the JPEG "
            "files; mean angular error against the ground truth, degrees):\n\n"
            + markdown_table(["object", "photos", "final map", "model's map", "kept", "judged residual",
                              "held-out residual", "time (s)", "peak (MiB)"], rows))


def _names(record: dict, key: str) -> str:
    """A record's list of names (suites, warning codes) joined for a table cell; anything else is a ValueError (a
    text would be joined letter by letter)."""
    names = record[key]
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        raise ValueError(f"{key} is {names!r}; expected a list of names")
    return ", ".join(names)


LIGHT_WARNINGS_BENCH = REPO / "bench" / "results" / "light_warnings.json"
"""The output of `python bench/bench_light_warnings.py ... --out bench/results/light_warnings.json` (committed)."""


def light_warnings(card: dict) -> str:
    """How often the light warnings agree with the true lights: overall, per material, per kind of capture, per
    rendered suite; and each real capture with measured lights (the bench's rows, in order)."""
    d = read_bench(LIGHT_WARNINGS_BENCH)
    rendered = [[r["captures"], str(r["count"]), str(r["agree"]), "-" if r["share"] is None else f"{r['share']:.1%}"]
                for r in d["rows"] if "captures" in r]
    real = [[r["real"], f"{r['capture']} ({r['photos']})", _names(r, "truth") or "none", _names(r, "said") or "none"]
            for r in d["rows"] if "real" in r]
    return (f"`{d['command']}`:\n\n" + markdown_table(["captures", "count", "agree", "share"], rendered)
            + "\n\nReal captures with measured lights:\n\n"
            + markdown_table(["capture", "photos", "the true lights call for", "said"], real))


DOUBTFUL_MASK_BENCH = REPO / "bench" / "results" / "doubtful_mask.json"
"""The runs `python bench/bench_doubtful_mask.py [--no-cushions] --suite DIR ... --record FILE` added (committed)."""


def doubtful_mask(card: dict) -> str:
    """Per recorded run: how many automatic masks were refused, good, doubted or silent below the IoU of a good one,
    then the silent ones of the runs without painted cushions."""
    d = read_bench(DOUBTFUL_MASK_BENCH)
    rows = [[_names(r, "suites") + (" (painted cushions)" if r["cushions"] else ""), str(r["masks"]),
             str(r["refused"]), str(r["good"]), str(r["good_doubted"]), str(r["below_doubted"]), str(r["below_silent"])]
            for r in d["rows"]]
    silent = [f"{s['object']} ({s['iou']:.2f})" for r in d["rows"] if not r["cushions"] for s in r["silent"]]
    below = f"below {d['good_iou']:g}"
    return (markdown_table(["suites", "automatic masks", "refused", f"good (IoU {d['good_iou']:g} or more)",
                            "good but doubted", f"{below}, doubted", f"{below}, silent"], rows)
            + ("\n\nSilent renders (IoU): " + ", ".join(silent) if silent else ""))


CAPTURE_BENCH = REPO / "bench" / "results" / "capture.json"
"""The output of `python bench/bench_capture.py --out bench/results/capture.json` (its last run, committed)."""


def capture_resources(card: dict) -> str:
    """Time and peak memory of orchestrate.capture by photo count and size, measured against its own estimate."""
    d = read_bench(CAPTURE_BENCH)
    def opt(r: dict, key: str) -> str:  # rows recorded before a column existed show a dash
        return f"{r[key]:.1f}" if key in r else "-"

    def size(r: dict) -> str:  # the photos' size, and the working size where smaller
        work = r.get("working_size", r["size"])
        return f"{r['size'][1]} x {r['size'][0]}" + (f" ({work[1]} x {work[0]})" if work != r["size"] else "")

    rows = [[str(r["images"]), r.get("format", "png").upper(), size(r), f"{r['prepare_s']:.1f}",
             f"{r['predict_s']:.1f}", f"{r['check_and_refine_s']:.1f}", opt(r, "surface_s"), f"{r['wall_s']:.0f}",
             f"{r['estimate_s']:.0f}", str(r["peak_mib"]), str(r["estimate_mib"]), opt(r, "longest_silence_s")]
            for r in d["rows"] if "error" not in r]
    commands = ", ".join(f"`{c}`" for c in d.get("commands", [d.get("command")]))
    return (f"Measured on {d['machine']['cpus']} cores ({commands}), one Dr.Jit thread; the longest silence is "
            "the longest time without a line on stderr:\n\n"
            + markdown_table(["photos", "files", "size (px; worked at)", "read, mask, checks (s)", "model (s)",
                              "check + refine (s)", "surface (s)", "total (s)", "estimated (s)", "peak memory (MiB)",
                              "estimated (MiB)", "longest silence (s)"], rows))


VERDICT_BENCH = REPO / "bench" / "results" / "verdict_optimised.json"
"""The outputs of `python bench/bench_verdict.py --optimised` on DiLiGenT and a rendered set (committed)."""


def check_resolution(card: dict) -> str:
    """Per trusted capture: the resolution, the truth's score, the lowest-scoring map at least 10 degrees off, the
    lowest-scoring refined map, and whether the truth is first (or not told apart) and the perturbed maps ordered."""
    d = read_bench(VERDICT_BENCH)
    rows, lines = [], []
    for run in d["sets"]:
        s = run["summary"]
        lines.append(f"- {run['set']}: trusted {s['trusted']} of {s['captures']}; truth first or not told apart "
                     f"{s['trusted_gt_first_or_tied']} of {s['trusted']} (first by the score alone: "
                     f"{s['trusted_gt_first']}); GT+10 < GT+25 < constant or not told apart "
                     f"{s['trusted_ordered_or_tied']} (by the score alone: {s['trusted_ordered']}); a map scored below "
                     f"the truth by more than the resolution: {s['trusted_with_a_map_told_apart_below_gt']}")
    for r in d["rows"]:  # the trusted captures
        m, res = r["maps"], r["resolution"]
        far = min((k for k, v in m.items() if k != "gt" and v["mae_deg"] >= 10), key=lambda k: m[k]["judged_rel_l1"])
        opt = min((k for k in m if k.endswith("*")), key=lambda k: m[k]["judged_rel_l1"], default=None)
        cell = (lambda k: f"`{k}` {m[k]['mae_deg']:.1f} deg, {m[k]['judged_rel_l1']:.4f}")  # noqa: E731
        rows.append([r["capture"].removesuffix(".data"), f"{res:.4f}", f"{m['gt']['judged_rel_l1']:.4f}", cell(far),
                     cell(opt) if opt else "-", f"{m['gt*']['mae_deg']:.1f}" if "gt*" in m else "-",
                     "yes" if r["gt_first_or_tied"] else "**no**", "yes" if r["ordered_or_tied"] else "**no**"])
    return (
        "\n".join(lines)
        + "\n\n"
        + markdown_table(
            [
                "capture",
                "resolution",
                "truth",
                "lowest map >= 10 deg off",
                "lowest refined map",
                "truth refined: moved (deg)",
                "truth first or not told apart",
                "GT+10 < GT+25 < constant or not told apart",
            ],
            rows,
        )
    )


VERDICT_SWEEP_BENCH = REPO / "bench" / "results" / "verdict_sweep.json"
"""The output of `python bench/bench_verdict_sweep.py --out bench/results/verdict_sweep.json` (committed)."""


def verdict_sweep(card: dict) -> str:
    """Per value of each verdict constant (one changed at a time): trusted captures, false trust (the truth not
    first among the maps >= 10 deg off), of it beyond the resolution, and needless abstentions."""
    d = read_bench(VERDICT_SWEEP_BENCH)
    st, n = d["settings"], d["settings"]["captures"]
    families = ", ".join(f"{v} {k}" for k, v in st["families"].items())
    every = all(v >= 9.99 for c in d["captures"] for k, v in c["mae_deg"].items() if k != "gt")
    rows = [[f"`{r['constant']}`", f"**{r['value']:g}** (default)" if r["default"] else f"{r['value']:g}",
             f"{r['trusted']}", f"**{r['false_trust']}**" if r["false_trust"] else "0",
             f"{r['false_trust_told_apart']}", f"{r['needless_abstention']}"] for r in d["rows"]]
    return (f"Measured on {n} rendered captures ({families}; `{d['command']}`, {d['seconds']['total']:.0f} s on "
            f"{d['machine']['cpus']} busy cores), each map fitted once ({_names(st, 'maps')}; the wrong maps "
            f"are those at least 10 degrees off{', here all but the truth' if every else ''}), one constant changed at "
            "a time, the others at their defaults:\n\n"
            + markdown_table(["constant", "value", f"trusted (of {n})",
                              "false trust: a wrong map at or below the truth",
                              "of which below it by more than the resolution",
                              "needless abstention: truth first beyond the resolution"], rows))


PROFILE_BENCH = REPO / "bench" / "results" / "profile.json"
"""The output of `python bench/bench_profile.py --baseline REV --out bench/results/profile.json` (committed)."""

_STAGE_COLUMNS = {"sampling": "sampling", "building": "building", "ground_truth": "ground truth",
                  "relighting": "relighting", "tracing": "tracing", "compiling": "compiling",
                  "path_tracing": "path tracing", "reduction": "reduction", "writing": "writing"}


def render_profile(card: dict) -> str:
    """Seconds per object by stage on one core, and objects per hour of wildgen.make, per setting and tree."""
    d = read_bench(PROFILE_BENCH)
    same = {True: "identical", False: "changed", None: "-"}
    rows = [[f"{r['res']} px, {r['images']} images, {r['spp']} spp", f"{r['tree']} (`{r['revision']}`)",
             *[f"{r[k]:.3f}" for k in _STAGE_COLUMNS], f"**{r['total_s']:.2f}**", f"{r['first_object_s']:.2f}",
             f"**{r['objects_per_hour']:.0f}**" if r.get("objects_per_hour") else "-",
             f"{r['run_objects_per_hour']:.0f} ({r['run_objects']})" if r.get("run_objects_per_hour") else "-",
             same[r.get("same_bytes_as_baseline")]] for r in d["rows"]]
    return (f"Measured on {d['machine']['cpus']} cores (`{d['command']}`, light family `{d['lights']}`): seconds per "
            "object and stage on one core (one Dr.Jit thread; the mean over the objects after the first, which also "
            "pays for imports, the asset scan and the first kernels), and objects per hour of the real CLI "
            "(`wildgen.make`, default workers and threads, all cores): in a long run (the difference of a 2-object "
            "and an N-object run, so start-up cancels) and in the N-object run itself:\n\n"
            + markdown_table(["object", "tree", *_STAGE_COLUMNS.values(), "total (s)", "first object (s)",
                              "objects / hour, long run", "objects / hour (N)", "bytes vs baseline"], rows))


CYCLES_BENCH = REPO / "bench" / "results" / "cycles.json"
"""The output of `python bench/bench_cycles.py --out bench/results/cycles.json` (committed)."""


def cycles_speed(card: dict) -> str:
    """Time to the same noise as our renderer at two sample counts, Blender Cycles against ours, one run."""
    d = read_bench(CYCLES_BENCH)
    rows = [
        [
            str(r["noise_of_spp"]),
            f"{r['relative_rmse']:.4f}",
            str(r["cycles_spp"]),
            f"{r['cycles_s']:.2f}",
            str(r["mitsuba_spp"]),
            f"{r['mitsuba_s']:.3f}",
            f"**{r['speedup']:.1f}x**",
            f"{r['speedup_path_tracing']:.1f}x",
        ]
        for r in d["rows"]
    ]
    return (f"Measured side by side on {d['machine']['cpus']} cores (`{d['command']}`; {d['blender']}, "
            f"{d['res']} x {d['res']} px, {d['threads']} threads each; references at {d['reference_spp']} spp):\n\n"
            + markdown_table(["noise of our render at (spp)", "relative RMSE", "Cycles spp", "Cycles (s)", "ours spp",
                              "ours (s)", "ours faster per render", "in path tracing alone"], rows))


EXPECTED_ERROR_BENCH = REPO / "bench" / "results" / "expected_error.json"
"""The output of `python bench/bench_expected_error.py --out bench/results/expected_error.json` (committed)."""


def expected_error(card: dict) -> str:
    """Per light family of the held-out renders (and DiLiGenT as JPEG photos): the true and the stated mean error, how
    often the stated mean hits and the 80 % interval covers the true one, and the pixel ranking's sparsification."""
    d = read_bench(EXPECTED_ERROR_BENCH)
    o = d["overall"]
    rows = [[r["set"], str(r["objects"]), f"{r['true_mean']:.2f}", f"{r['stated_mean']:.2f}",
             f"**{r['hit_share']:.2f}**", f"**{r['coverage']:.2f}**",
             "-" if r["ause_ratio"] is None else f"{r['ause_ratio']:.3f}"] for r in d["rows"]]
    rises = ", ".join(f"{k.replace('_', ' ')} {v:.0%}" for k, v in o["stated_rises_share"].items())
    return (f"Measured on {o['objects']} held-out renders ({_names(d, 'suite')}; {d['objects_per_row']} objects "
            f"each, {d['assets']} assets, seed {d['seed']}; `{d['command']}`), the error model fitted on "
            f"{d['error_model']['calibration']['objects']} renders of the training assets. Hit: {d['hit_rule']}. "
            "Coverage: the 80 % interval holds the true mean (target 0.70-0.90). Sparsification ratio: the area "
            "between our curve and the oracle's over the area between random and the oracle, pixels pooled per "
            f"family (0: the oracle's ranking, 1: no better than random). The stated error rose on {rises} of the "
            "objects (half the images, 3 images, every second photo shifted by 3 px, the mask grown by 4 px):\n\n"
            + markdown_table(["objects", "count", "true mean (deg)", "stated mean (deg)", "hit", "coverage",
                              "sparsification ratio"], rows))


FULL_SIZE_BENCH = REPO / "bench" / "results" / "full_size.json"
"""The output of `python bench/bench_full_size.py --out bench/results/full_size.json` (committed)."""


def full_size(card: dict) -> str:
    """Per working side: the mean angular error of the map brought back to the rendered size, and the outline's wrong
    pixels guided by the photos against a plain upsampling."""
    d = read_bench(FULL_SIZE_BENCH)

    def share(r: dict, key: str) -> str:
        return f"{r[key]:.2%}" if key in r else "-"

    rows = [[f"{r['working_side']} px" + (" (the photos' own)" if r["working_side"] == d["side"] else ""),
             f"{r['mean_error_deg']:.2f}", share(r, "outline_wrong_guided"), share(r, "outline_wrong_linear")]
            for r in d["rows"]]
    return (f"{d['objects']} held-out objects rendered at {d['side']} x {d['side']} px (`{d['command']}`); the map "
            "made at the working side and brought back to the rendered size, its mean angular error against the exact "
            "normals; the outline brought back from the working mask, its wrong pixels as a share of the object:\n\n"
            + markdown_table(["working side", "mean error at the photos' size (deg)", "outline wrong, guided",
                              "outline wrong, plain upsampling"], rows))


REFINE_RULE_BENCH = REPO / "bench" / "results" / "refine_rule.json"
"""The output of `python bench/bench_refine_rule.py --out bench/results/refine_rule.json` (committed)."""


def refine_rule(card: dict) -> str:
    """Per rule of keeping the refined map, on each independently rendered held-out set: how many refined maps it
    kept, the mean true error of the kept maps, the refined maps it kept that were worse and declined that were
    better."""
    d = read_bench(REFINE_RULE_BENCH)
    seeds = [str(x["seed"]) for x in d["sets"]]
    header = ["rule"] + [h for seed in seeds for h in (f"seed {seed}: kept", "mean error (deg)", "hurt", "missed")]
    rows = [[r["rule"]] + [c for seed in seeds for c in (str(r["by_seed"][seed]["kept_refined"]),
                                                         f"{r['by_seed'][seed]['mean_error_deg']:.2f}",
                                                         str(r["by_seed"][seed]["hurt"]),
                                                         str(r["by_seed"][seed]["missed"]))] for r in d["rows"]]
    return (f"`{d['command']}`: {' and '.join(str(x['judged']) for x in d['sets'])} captures judged of "
            f"{' and '.join(str(x['objects']) for x in d['sets'])} rendered; hurt: a kept refined map more than "
            f"{d['hurt_deg']} deg worse than the model's, missed: a declined one as much better:\n\n"
            + markdown_table(header, rows))


ERROR_EVIDENCE_BENCH = REPO / "bench" / "results" / "error_evidence.json"
"""The output of `python bench/bench_error_evidence.py --out bench/results/error_evidence.json` (committed)."""


def error_evidence(card: dict) -> str:
    """Per kind of evidence: how much of the object-level error it predicts out of fold (the spread of log(true /
    predicted) and the hit share)."""
    d = read_bench(ERROR_EVIDENCE_BENCH)
    rows = [[r["evidence"], str(r["added_features"]), f"{r['spread']:.3f}", f"{r['hit_share']:.2f}"] for r in d["rows"]]
    return (f"Measured on the {d['samples']} calibration samples ({d['objects']} objects and their faulted copies; "
            f"`{d['command']}`), {d['folds']} folds grouped by object, ridge {d['ridge']:g}; a hit share of 0.8 needs "
            f"a spread of about {d['needed_spread']}:\n\n"
            + markdown_table(["evidence added to the stated error's inputs", "features", "spread of log(true / "
                              "predicted)", "hit share"], rows))


SURFACE_BENCH = REPO / "bench" / "results" / "surface.json"
"""The output of `python bench/bench_surface.py --work WORK` (committed)."""


def surface_integration(card: dict) -> str:
    """Per case family: MADE of ours, the reference BiNI and least squares (all pixels and near true depth jumps),
    and the whole-process times side by side."""
    d = read_bench(SURFACE_BENCH)
    methods = [m for m in ("ours", "reference", "reference_converged", "least_squares") if m in d["rows"][0]]
    names = {"ours": "ours", "reference": "reference BiNI", "reference_converged": "BiNI converged",
             "least_squares": "least squares"}

    def cell(v):
        return "-" if v is None else f"{v:.4f}"

    rows = [[r["cases"], str(r["count"])] + [cell(r[m]) for m in methods]
            + [cell(r[f"{m}_near_jumps"]) if not r["cases"].endswith("(mm)") else "-" for m in methods]
            for r in d["rows"]]
    w = d["whole_process_seconds"]
    return (f"`{d['command']}` ({d['machine']}; renders: {d['objects']} objects a family, seed {d['seed']}, "
            f"assets {d['assets']}). MADE after one global scale (perspective) or the known pixel size and one offset "
            "(orthographic); near jumps: pixels within 3 px of a true depth jump. Whole processes over all "
            f"{len(d['cases'])} cases: ours {w['ours']:.1f} s, the reference {w['reference']:.1f} s "
            f"(ratio {w['ours'] / w['reference']:.2f}), least squares {w['least_squares']:.1f} s.\n\n"
            + markdown_table(["cases", "count", *(names[m] for m in methods),
                              *(f"{names[m]} near jumps" for m in methods)], rows))


BENCH_TABLES = {
    "model:shards-throughput": (SHARDS_BENCH, shards_throughput),
    "surface:bench": (SURFACE_BENCH, surface_integration),
    "capture:resources": (CAPTURE_BENCH, capture_resources),
    "capture:full-size": (FULL_SIZE_BENCH, full_size),
    "capture:diligent": (CAPTURE_DILIGENT_BENCH, capture_diligent),
    "capture:light-warnings": (LIGHT_WARNINGS_BENCH, light_warnings),
    "capture:doubtful-mask": (DOUBTFUL_MASK_BENCH, doubtful_mask),
    "check:resolution": (VERDICT_BENCH, check_resolution),
    "check:verdict-sweep": (VERDICT_SWEEP_BENCH, verdict_sweep),
    "check:refine-rule": (REFINE_RULE_BENCH, refine_rule),
    "generator:profile": (PROFILE_BENCH, render_profile),
    "generator:cycles": (CYCLES_BENCH, cycles_speed),
    "model:expected-error": (EXPECTED_ERROR_BENCH, expected_error),
    "model:error-evidence": (ERROR_EVIDENCE_BENCH, error_evidence),
}
"""Blocks generated from a benchmark's recorded output instead of the model card: name -> (the output, its table)."""
BENCH_BLOCKS = {name: path for name, (path, _) in BENCH_TABLES.items()}
