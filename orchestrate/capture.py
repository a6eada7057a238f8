"""`python -m orchestrate.capture`: your own photos in, a checked normal map out.

    python -m orchestrate.capture --input PHOTOS --out OUT [--mask FILE|auto] [--convention opengl|opencv]

1. reads a folder of photos (JPEG, 8/16-bit PNG or TIFF, EXR, camera RAW; any file names, natural order; 8-bit
   files linearised from sRGB, RAW files developed linear by LibRaw, EXIF exposure differences normalised:
   `scenes.folder.photos`), or an object folder
   in one of the toolkit's layouts through the one reader;
2. takes the mask from `--mask FILE`, or finds it from the images alone (`--mask auto`:
   `validate.diagnosis.usable.auto_mask`), or refuses in one line asking for one;
3. says whether the capture is usable before any model runs (`validate.diagnosis.usable.capture_warnings`): too few
   images, too dark, saturated, light from one side only or only near the view axis, camera moved, and an
   automatic mask the light variation does not support (`mask_doubts`); the fatal ones stop, the others are
   recorded in report.json `warnings`;
4. predicts normals with the shipped model (or `--checkpoint`), runs the fitted physical check, and where
   the check can judge the capture refines the map, keeping the refined map only when the check accepts it;
5. writes OUT/normal.png (16-bit, (n + 1) / 2), OUT/normal.exr, OUT/normal_model.png (the model's map, before
   any refinement), OUT/mask.png, OUT/mask_overlay.png (the mask over the photos), OUT/light_variation.png,
   OUT/report.json (every stage, the verdict, the warnings, timings and peak memory) and OUT/report.html (the
   same for a person, one self-contained page); the check's and the refinement's own reports lie in OUT/check/
   and OUT/refine/.

Normals are in the camera frame: `--convention opengl` (the default; Blender, Meshroom): x right, y up, z toward
the camera; `opencv`: x right, y down, z away from the camera (the same vectors with y and z negated).
"""
from __future__ import annotations

import resource
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Literal

import numpy as np

from orchestrate.capture_estimate import check_resources
from orchestrate.capture_full import DEFAULT_MAX_SIDE, guide_image, upsample
from orchestrate.capture_outputs import claim_stages, remove_stale, stage_reports
from orchestrate.capture_verdict import level, mask_first, verdict
from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.limits import check_threads
from scenes.cli.needs import Needs
from scenes.cli.options import REQUIRED, Command, arg, check_fields, option
from scenes.cli.outputs import check_output_folder, claim_outputs, output_lock
from scenes.cli.progress import heartbeat, stage
from scenes.cli.supervise import INTERRUPTED, run_supervised
from scenes.files import to_plain, write_json
from scenes.folder.format import MASK_FILE, write_object_folder
from scenes.images import read_mask, write_mask, write_normal_exr, write_normal_map, write_picture
from unips.expected_error import FILES as EXPECTED_FILES
from unips.expected_error import write_stated
from validate.observations import Capture

OUTPUTS = (
    "normal.png",
    "normal.exr",
    "normal_model.png",
    MASK_FILE,
    "mask_overlay.png",
    "light_variation.png",
    "report.json",
    "report.html",
    *EXPECTED_FILES,
)
"""What the command writes at the top of --out (its working folders: work/, check/, refine/)."""
CONVENTIONS = {"opengl": np.array([1.0, 1.0, 1.0]), "opencv": np.array([1.0, -1.0, -1.0])}
"""Per convention, the signs that turn the camera frame (x right, y up, z toward the camera) into it."""


@dataclass
class CaptureOptions:
    """The command line of orchestrate.capture."""

    input: Annotated[str, arg(metavar="DIR")] = REQUIRED
    """Folder of photos (JPEG, PNG, TIFF, EXR, or camera RAW: DNG, CR2, CR3, NEF, ARW, ORF, RW2, RAF; any names)
    of one object under different lights, the camera still (other pictures there, WebP or HEIC, are refused by
    name; hidden files are skipped); or an object folder in one of the toolkit's layouts."""
    out: Annotated[str, arg(metavar="DIR")] = REQUIRED
    """Output folder: normal.png, normal.exr, normal_model.png, mask.png, mask_overlay.png, light_variation.png,
    expected_error_deg.npy / .exr, expected_error.png, report.json, report.html and surface/ (docs/capture.md,
    "Outputs")."""
    mask: Annotated[str, arg(metavar="{FILE,auto,none}")] = "auto"
    """Object mask (white object on black, the size of the photos), or 'auto' to find it from how the light
    changes each pixel (refused in one line where it cannot), or 'none': the whole frame is the scene (a table
    with things on it; a file named none: ./none)."""
    input_encoding: Literal["auto", "srgb", "linear"] = "auto"
    """How the photos' values are encoded: auto (sRGB for 8-bit files, linear for 16-bit, EXR and camera RAW),
    srgb (refused for RAW files) or linear."""
    convention: Literal["opengl", "opencv"] = "opengl"
    """Frame of the written normals: opengl (x right, y up, z toward the camera) or opencv (y down, z away)."""
    max_side: int = option(DEFAULT_MAX_SIDE, minimum=0)
    """Work on copies of the photos whose longer side is at most this many pixels (0: the photos' own size; else at
    least 32); normal.png, normal.exr and mask.png are written at the photos' size (docs/capture.md, "Big photos")."""
    checkpoint: Annotated[str | None, arg(metavar="FILE", help_behavior_hint="(default: the shipped model)")] = None
    """Model weights to predict with: a model file, or a folder of the authors' published weights with --model."""
    model: str | None = None
    """Registered network (unips.models.list_models()) that reads --checkpoint when it is a folder of published
    weights (--model glc-unips or sdm-unips); without --checkpoint, its shipped weights."""
    refine: bool = True
    """Refine the map where the physical check can judge the capture (kept only when the check accepts it)."""
    rotation_search: bool = False
    """Let the refinement search a global tilt of the normals (validate.refine --rotation-search)."""
    rotation_steps: int = option(80, minimum=1, maximum=8000)
    """Adam steps of the light fit at each candidate tilt of --rotation-search (validate.refine --rotation-steps; at
    most 100 times the default)."""
    threads: Annotated[int | None, arg(help_behavior_hint="(default: one per core)")] = option(None, minimum=1)
    """Dr.Jit threads of the check and the refinement (1: byte-identical run to run)."""
    keep_work: bool = False
    """Also write the scaled photos and the mask as an object folder, OUT/work/<name>.data (16-bit PNG), for other
    commands to read; the command itself works on them in memory."""
    overwrite: bool = False
    """Replace the outputs of an earlier capture in --out (its check/, refine/ and work/ folders of another name go
    too, once this capture is written; files it did not write, never)."""

    def validate(self) -> "CaptureOptions":
        from unips.inference import check_model_name

        check_fields(self)
        if 0 < self.max_side < MIN_SIDE:  # smaller copies lose their short side (a resize to 0 px)
            raise UsageError(f"--max-side: got {self.max_side}, expected 0 (the photos' own size) or at least "
                             f"{MIN_SIDE} px")
        check_model_name(self.model)
        check_threads(self.threads, "--threads")  # Dr.Jit would fail later with a traceback
        return self


MIN_SIDE = 32  # the smallest --max-side other than 0
MIN_PHOTO_SIDE = 4  # the smallest side of a photo the capture works on


def of_photos(opts: CaptureOptions) -> bool:
    """Whether --input is a folder of photos, not an object folder (read at its own size and encoding)."""
    from scenes.folder.photos import object_layout

    try:
        return object_layout(opts.input) is None
    except (OSError, ValueError, TypeError):  # its reader says what is wrong with it (TypeError: none given)
        return True


PHOTOS_ONLY = "with --input a folder of photos (an object folder is read at its own size, linear)"
COMMAND = Command(CaptureOptions, prog="python -m orchestrate.capture", description=__doc__.split("\n\n")[0], needs=(
    Needs("rotation_search", lambda c, _: c.refine, "with the refinement on (without --no-refine)"),
    Needs("rotation_steps", lambda c, _: c.refine and c.rotation_search, "with --rotation-search"),
    Needs("input_encoding", lambda c, _: of_photos(c), PHOTOS_ONLY, ("linear",)),  # linear: an object folder's
    Needs("max_side", lambda c, _: of_photos(c), PHOTOS_ONLY, (0,))))  # 0, the own size: an object folder's


def probe_input(opts: CaptureOptions) -> tuple[int, int, int, tuple[int, int]]:
    """(photos, height, width after --max-side, the photos' own (height, width)) of --input, from the file list and
    one image: what the estimate needs before anything large is read. An object folder is worked on at its size."""
    from scenes.folder.layouts import read_folder
    from scenes.folder.photos import object_layout, photo_files, photo_shape

    folder = Path(opts.input)
    if object_layout(folder) is not None:
        fd = read_folder(folder, images=False, arg="--input")
        return fd.num_files, *fd.shape, fd.shape
    files = photo_files(folder)
    k, (h, w) = len(files), photo_shape(files[0])
    if min(h, w) < MIN_PHOTO_SIDE:  # no 2 x 2 block of pixels to build the check's surface from
        raise ValueError(f"--input: the photos are {w}x{h} px ({files[0].name}); expected at least {MIN_PHOTO_SIDE} px "
                         "on each side")
    f = min(1.0, opts.max_side / max(h, w)) if opts.max_side else 1.0
    return k, max(1, round(h * f)), max(1, round(w * f)), (h, w)


def read_input(opts: CaptureOptions) -> Capture:
    """The capture of --input, linear: its photos (mask None until `find_mask`) or an object folder (with its
    mask); `meta["input"]` says what the files said about themselves (report.json `input`)."""
    from scenes.folder.format import object_name  # resolved: a folder reached through '..' is named as itself
    from scenes.folder.layouts import read_folder
    from scenes.folder.photos import object_layout, read_photos
    from validate.observations import capture_from_arrays

    folder = Path(opts.input)
    if object_layout(folder) is not None:  # its mask.png, where it has one (else found as for photos)
        fd = read_folder(folder, arg="--input")
        mask = fd.mask if fd.mask_file is not None else None
        return capture_from_arrays(fd.name, fd.images, mask, [p.name for p in fd.image_paths], fd.saturated,
                                   folder, {"input": {"kind": f"object folder ({fd.layout})"}})
    photos = read_photos(folder, opts.input_encoding, opts.max_side or None, guide=True)
    source = {"kind": "photos", "encoding": photos.encoding, "bit_depth": photos.bit_depth,
              "exposure": photos.exposure, **({"raw": photos.raw} if photos.raw else {}),
              **({"exposure_note": photos.exposure_note} if photos.exposure_note else {})}
    return capture_from_arrays(object_name(folder) or "capture", photos.images, None, photos.names,
                               photos.saturated, folder, {"input": source, "guide": photos.guide})


WHOLE_FRAME = ("every pixel gets a normal, the background's too; the model was trained on single objects on a dark "
               "background, so expect larger errors on a scene; the check fits one light and reflectance model to the "
               "whole frame and judges it where that explains the photos: the edges between things at different "
               "depths (cast shadows, occlusions) are not modelled")  # what report.json says of --mask none


def find_mask(opts: CaptureOptions, cap: Capture, full: tuple[int, int]) -> tuple[np.ndarray, dict]:
    """The object mask at the working size (from --mask FILE, the object folder's own, or found from the images) and
    how it was made; a mask file may have the photos' own size `full` (kept as `full_mask` in the dict)."""
    from orchestrate.capture_full import downscale_mask
    from validate.diagnosis.usable import auto_mask

    shape = cap.images.shape[1:3]
    if opts.mask == "none":
        return np.ones(shape, bool), {"method": "none: the whole frame is the scene", "note": WHOLE_FRAME}
    if opts.mask != "auto":
        try:
            mask = read_mask(opts.mask, None)
        except (ValueError, FileNotFoundError) as exc:
            raise type(exc)(f"--mask: {exc}") from None
        if mask.shape not in (shape, full):
            at = f" (worked on at {shape[1]}x{shape[0]})" if shape != full else ""
            raise ValueError(f"--mask: {opts.mask!r} is {mask.shape[1]}x{mask.shape[0]}, the photos "
                             f"{full[1]}x{full[0]}{at}")
        if not mask.any():
            raise ValueError(f"--mask: {opts.mask!r} marks no pixel of the object (expected white on black)")
        work = downscale_mask(mask, shape) if mask.shape != shape else mask
        if not (work[:-1, :-1] & work[1:, :-1] & work[:-1, 1:] & work[1:, 1:]).any():  # the check builds a surface
            raise ValueError(f"--mask: {opts.mask!r} holds no 2x2 block of object pixels at the working size "
                             f"{shape[1]}x{shape[0]} (a line or dots); expected the object's area, white on black")
        return work, {"method": "file", "file": opts.mask, **({"full_mask": mask} if mask.shape != shape else {})}
    if cap.mask is not None:  # an object folder brings its own
        return cap.mask, {"method": "the object folder's mask.png"}
    return auto_mask(cap.images)


def _to_convention(n: np.ndarray, convention: str) -> np.ndarray:
    return (n * CONVENTIONS[convention]).astype(np.float32)


def predict(opts: CaptureOptions, cap: Capture, net=None) -> tuple[np.ndarray, object | None, str | None]:
    """The model's map (H, W, 3) of a capture (linear images scaled to 1 at the brightest mask value), its stated
    error (`unips.expected_error.Stated`) and None, or the map, None and why no error is stated. `net`: the network
    run() loaded before reading the photos (loaded here from --checkpoint / --model when None)."""
    from unips.data import PSObject
    from unips.expected_error import for_weights, gather
    from unips.inference import load_network, run_model

    if net is None:
        net = load_network(opts.checkpoint, model=opts.model)
    obj = PSObject(name=cap.name, images=cap.images, mask=cap.mask, normals=None, light_family=None,
                   light_directions=None, light_intensities=None, path=cap.folder, layout=cap.layout,
                   image_names=cap.image_names)
    em, why = for_weights(net.checkpoint)
    if em is None:
        return run_model(net, obj), None, why
    normals, evidence = gather(net, obj, tta=net.contract.views)
    return normals, em.state(evidence), None


def check_and_refine(opts: CaptureOptions, cap: Capture, out: Path, normals: np.ndarray,
                     warnings: list) -> tuple[np.ndarray, dict, dict | None]:
    """The fitted check of the model's map, and the refinement where the check trusts the capture, on one judged
    capture held in memory (read, reduced and explained once; the model map's fit made once for both): (final map,
    float, check report, refine report or None). Their reports and figures go to OUT/check/ and OUT/refine/. A
    refusal of the images names a doubted automatic mask first (`mask_first`, from the capture's `warnings`)."""
    from dataclasses import replace

    from scenes.renderer.variant import choose_variant, set_jit_threads
    from validate.fitted.fit_report import check_judged, judge, write_fitted
    from validate.fitted.fit_scene import FitConfig
    from validate.fitted.refinement import RefineConfig, refine_judged, write_refined
    from validate.judgeable import check_judgeable
    from validate.observations import unit_normals

    choose_variant(None)
    set_jit_threads(opts.threads)
    config = FitConfig().validate()
    model_map = unit_normals(normals, cap.mask, f"{'--checkpoint' if opts.checkpoint else '--model'}: the model's map")
    try:  # a bad map is the weights' fault (above); the images that cannot judge it may be the mask's
        jc = judge(cap, model_map, config, "check", args=("--input", "--mask"))
    except ValueError as exc:
        raise mask_first(exc, warnings) from None
    check, fit = check_judged(jc, config)
    write_fitted(jc, out / "check" / cap.name, fit, check)  # claimed by run(), under report.json
    if not (opts.refine and check["trusted"]):
        return normals, check, None
    try:
        check_judgeable(jc.small, "refine", "--input", "--mask")
    except ValueError as exc:  # the check can judge, the refinement needs more (images with lit pixels)
        return normals, check, {"accepted": False, "why": f"not run: {exc}"}
    refined, final = refine_judged(jc, replace(RefineConfig(), rotation_search=opts.rotation_search,
                                              rotation_steps=opts.rotation_steps).validate())
    write_refined(out / "refine" / cap.name, final, refined)
    return (final if refined["accepted"] else normals), check, refined


def _variation_picture(images: np.ndarray, path: Path) -> None:
    from validate.diagnosis.mask_seed import variation_map

    v = variation_map(images)
    import cv2

    v8 = (np.clip(v / max(float(np.percentile(v, 99.5)), 1e-6), 0, 1) * 255).astype(np.uint8)
    write_picture(path, cv2.applyColorMap(v8, cv2.COLORMAP_VIRIDIS))


def load_network_first(opts: CaptureOptions) -> tuple[object, float]:
    """The network of --checkpoint / --model, loaded (its weights checked: `unips.models.tensors`) before the photos
    are read, so that a bad one costs no reading; and the seconds it took. A refusal names the flag."""
    from unips.expected_error import for_weights
    from unips.inference import load_network

    t0 = time.perf_counter()
    try:
        net = load_network(opts.checkpoint, model=opts.model)
        for_weights(net.checkpoint)  # its error model read and checked now too, not after the model's map
    except (ValueError, FileNotFoundError) as exc:  # its message names the file, or the registry: the flag too
        flag = "--checkpoint" if opts.checkpoint is not None else "--model"
        if str(exc).startswith(flag):
            raise
        raise type(exc)(f"{flag}: {exc}") from None
    return net, time.perf_counter() - t0


REPORT_KEYS = ("input", "verdict", "timings")
"""Keys every capture report.json holds (the provisional one too): one without them is never replaced."""


def run(opts: CaptureOptions) -> dict:
    """The whole command (main without the error handling); returns report.json's content. Each stage says when it
    starts, that it is alive at least every 10 s, and when it ends (`scenes.cli.progress.stage`, on stderr)."""
    from orchestrate.capture_surface import write_capture_surface
    from scenes.surface.write import SURFACE_DIR
    from validate.diagnosis.usable import as_dicts, capture_warnings, light_warnings, mask_doubts, unusable_photos

    t0, times, out = time.perf_counter(), {}, Path(opts.out)
    check_output_folder(out)
    claim_outputs([out / n for n in OUTPUTS], opts.overwrite, owner="orchestrate.capture", marker=out / "report.json",
                  signed={out / "report.json": REPORT_KEYS})  # an earlier capture's files: beside its report
    k, h, w, full = probe_input(opts)
    need = check_resources(k, h, w, full)
    net, times["load_model_s"] = load_network_first(opts)
    into = f" into {w} x {h} px" if full != (h, w) else ""
    stale = claim_stages(opts, out)  # before the photos are read: a refusal comes at once
    with stage("capture", f"reading {k} photos of {full[1]} x {full[0]} px{into} (the whole run: about "
               f"{need['seconds']:.0f} s, {need['peak_mib']} MiB at most)"):
        read = read_input(opts)
    guide = read.meta.pop("guide", None)  # the photos' mean at their own size, when worked on smaller copies
    times["read_s"] = time.perf_counter() - t0 - times["load_model_s"]
    if fatal := unusable_photos(read.images):  # before the mask: two photos (or one photo twice) say nothing
        raise UsageError(f"--input: {fatal.message}")
    with stage("capture", "the mask and the capture checks"):
        mask, mask_info = find_mask(opts, read, full)
        full_mask = mask_info.pop("full_mask", None)
        automatic = opts.mask == "auto" and read.mask is None  # found from the images: it may be wrong (mask_doubts)
        read = replace(read, mask=mask)
        # the light warnings wait for the model's map: the lights are read from the shading under it
        warnings, facts = capture_warnings(read.images, mask, read.saturated, read.image_names, lights=False)
        if automatic:  # measured before a fatal warning: a doubted mask is named first (mask_first)
            doubt, facts["mask_doubts"] = mask_doubts(read.images, mask)
            warnings += [doubt] if doubt else []
        if warnings and warnings[0].fatal:
            raise mask_first(UsageError(f"--input: {warnings[0].message}"), warnings)
    say(warnings)
    times["mask_and_checks_s"] = time.perf_counter() - t0 - times["read_s"] - times["load_model_s"]
    # One scale for every photo (their relative exposures are kept): the brightest mask value becomes 1, as the
    # model expects; the clipped channels stay those the files said (read.saturated), not re-derived from values.
    scale = 1.0 / max(float(read.images[:, mask].max()), 1e-12)
    cap = replace(read, images=np.clip(read.images * scale, 0, 1).astype(np.float32))
    write_json(out / "report.json", {"complete": False, "input": {}, "verdict": None, "timings": {}})  # ours if stopped
    work = write_object_folder(out / "work" / f"{cap.name}.data", cap.images, mask, None) if opts.keep_work else None
    t1 = time.perf_counter()
    with stage("capture", "the model's map and its expected error"):
        model_map, stated, why_unstated = predict(opts, cap, net)
    more, light_facts = light_warnings(read.images, mask, model_map)
    facts.update(light_facts)
    say(more)
    warnings += more
    times["predict_s"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    with stage("capture", "the physical check" + (" and the refinement" if opts.refine else ""),
               need["check_s"]):
        final, check, refined = check_and_refine(opts, cap, out, model_map, warnings)
    times["check_and_refine_s"] = time.perf_counter() - t1
    final = np.where(mask[..., None], final, 0.0)
    size = write_maps(opts, out, read.images, mask, final, model_map, stated, guide, full_mask)
    t1 = time.perf_counter()
    with stage("capture", "the surface from the final map"):
        surface = write_capture_surface(out / SURFACE_DIR, final, mask, read.meta["input"])
    times.update(surface_s=time.perf_counter() - t1, total_s=time.perf_counter() - t0)
    report = {"complete": True,
              "input": {"folder": str(opts.input), "images": len(read.image_names), "names": read.image_names,
                        "size": list(full), "working_size": list(read.images.shape[1:3]), **read.meta["input"]},
              "mask": {**mask_info, "pixels": int(mask.sum())},
              "warnings": as_dicts(warnings), "measurements": facts, "surface": surface,
              **outcome(opts, check, refined, stated, why_unstated, warnings),
              "stages": stage_reports(cap.name, refined, work.relative_to(out) if work else None),
              "timings": times, "estimate": need,
              "peak_memory_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    report["normals"]["size"] = size  # normal.png's and mask.png's
    from orchestrate.capture_page import pictures, write_page

    refined_used = report["normals"]["source"] == "refined"
    write_page(out / "report.html", to_plain(report), pictures(out, cap.name, read.images, read.image_names, mask,
                                                             final, model_map, refined_used))
    write_json(out / "report.json", report, indent=1, newline=True)  # last: complete only once all is written
    remove_stale(stale)
    return report


def say(warnings: list) -> None:  # each warning as one line on stderr
    for w in warnings:
        print(f"warning: {w.code}: {w.message}", file=sys.stderr)


def write_maps(opts: CaptureOptions, out: Path, images: np.ndarray, mask: np.ndarray, final: np.ndarray,
               model_map: np.ndarray, stated, guide: np.ndarray | None = None,
               full_mask: np.ndarray | None = None) -> list[int]:
    """The maps and pictures of OUTPUTS (report.json and report.html aside); with `guide` (the photos' mean at
    their own size, when the work was on smaller copies) normal.png, normal.exr and mask.png at the photos' size
    (`orchestrate.capture_full.upsample`; `full_mask`: the user's mask file at that size). Returns their size."""
    from orchestrate.capture_page import mask_overlay

    normals, outline = (final, mask) if guide is None else upsample(final, mask, guide_image(guide), full_mask)
    write_normal_map(out / "normal.png", _to_convention(normals, opts.convention))
    write_normal_exr(out / "normal.exr", _to_convention(normals, opts.convention))
    write_normal_map(out / "normal_model.png", _to_convention(model_map, opts.convention))
    write_mask(out / MASK_FILE, outline)
    if stated is not None:
        write_stated(out, stated)
    write_picture(out / "mask_overlay.png", mask_overlay(images, mask))
    _variation_picture(images, out / "light_variation.png")
    return list(outline.shape)


def outcome(opts: CaptureOptions, check: dict, refined: dict | None, stated, why_unstated: str | None,
            warnings: list) -> dict:
    """report.json's `normals`, `expected_error_deg` (or `expected_error_note`) and `verdict`."""
    lv, headline = level(check, stated, why_unstated, warnings)
    kept_refined = bool(refined and refined.get("accepted"))
    return {"normals": {"convention": opts.convention,
                        "frame": "x right, y up, z toward the camera" if opts.convention == "opengl"
                        else "x right, y down, z away from the camera",
                        "encoding": "normal.png: 16-bit (n + 1) / 2; normal.exr: float32 n; 0 outside the mask",
                        "source": "refined" if kept_refined else "model"},
            "expected_error_deg": None if stated is None else {
                **stated.summary(), "map": "the model's map" + (
                    " (the refined map was kept: the check accepted it, its own error is not stated)"
                    if kept_refined else ""),
                "files": list(EXPECTED_FILES)},
            **({"expected_error_note": why_unstated} if stated is None else {}),
            "verdict": {"level": lv, "headline": headline, **verdict(check, refined)}}


def main(argv: list[str] | None = None) -> int:
    try:
        opts = COMMAND.parse(argv).validate()
        mask_file = None if opts.mask in ("auto", "none") else opts.mask  # read too: never written over
        # one writer, never into what it reads
        with output_lock(opts.out, inputs={"--input": opts.input, "--mask": mask_file}), heartbeat("capture"):
            report = run(opts)
    except INPUT_ERRORS as exc:
        return report_error(exc)
    except OSError as exc:
        return report_error(exc, 1)
    except KeyboardInterrupt:  # Ctrl-C: the user's, not a fault; every file is written whole or not at all
        print(INTERRUPTED, file=sys.stderr)
        return 130
    print(report["verdict"]["headline"])
    print(report["verdict"]["summary"])
    print(
        f"wrote {Path(opts.out) / 'normal.png'}, normal.exr, mask.png, mask_overlay.png, light_variation.png, "
        + ("expected_error_deg.npy, .exr, expected_error.png, " if report["expected_error_deg"] else "")
        + f"report.json, report.html and surface/ ({len(report['warnings'])} warning(s))"
    )
    (h, w), (hw, ww) = report["input"]["size"], report["input"]["working_size"]
    if (h, w) != (hw, ww):
        print(f"normal.png, normal.exr and mask.png at the photos' size ({w} x {h} px), the rest at the working size "
              f"({ww} x {hw} px, --max-side {opts.max_side})")
    return 0


if __name__ == "__main__":  # Ctrl-C kills the work whole (scenes.cli.supervise: Mitsuba's own handler aside)
    sys.exit(run_supervised("orchestrate.capture", main, INTERRUPTED))
