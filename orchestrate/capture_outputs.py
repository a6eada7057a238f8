"""What orchestrate.capture writes below --out besides its top-level files: each stage's folder, claimed before the
first write (`claim_stages`), listed in report.json (`stage_reports`), and an earlier capture's stage folders of
another name removed once this capture is written (`stale_stages`, with --overwrite)."""
from __future__ import annotations

from pathlib import Path

from scenes.cli.outputs import claim_outputs


def stage_reports(name: str, refined: dict | None, work: Path | None) -> dict:
    """report.json `stages`: where the check's and the refinement's own reports and --keep-work's folder lie."""
    return {"check": f"check/{name}/report.json",
            "refine": f"refine/{name}/refine_report.json" if refined and "mode" in refined else None,
            "work_folder": str(work) if work else None}


def claim_stages(opts, out: Path) -> list[Path]:
    """Claim every file the stages write below --out (surface/, check/<name>/, refine/<name>/, --keep-work's folder)
    before the first write (`scenes.cli.outputs.claim_outputs`); <name> as `read_input` names the capture. Returns
    the files of an earlier capture of another name that this one replaces (`stale_stages`: with --overwrite)."""
    from orchestrate.capture_surface import SHADED_PICTURE
    from scenes.folder.format import object_name
    from scenes.surface.write import REPORT_KEYS as SURFACE_REPORT_KEYS
    from scenes.surface.write import SURFACE_DIR, surface_outputs
    from validate.fitted.fit_report import CHECK_OUTPUTS
    from validate.fitted.refinement import REFINE_OUTPUTS

    name = object_name(Path(opts.input)) or "capture"
    stages = {"surface": surface_outputs(out / SURFACE_DIR, ("ply",)) + [out / SURFACE_DIR / SHADED_PICTURE],
              "check": [out / "check" / name / n for n in CHECK_OUTPUTS],
              "refine": [out / "refine" / name / n for n in REFINE_OUTPUTS]}
    claim_outputs([p for paths in stages.values() for p in paths], opts.overwrite, owner="orchestrate.capture",
                  marker=out / "report.json", signed={out / SURFACE_DIR / "report.json": SURFACE_REPORT_KEYS})
    claim_outputs([out / "work" / f"{name}.data"] if opts.keep_work else [], opts.overwrite,
                  owner="orchestrate.capture", folders=True)  # --keep-work's folder too (no link on the way)
    return stale_stages(out, name) if opts.overwrite else []


def stale_stages(out: Path, name: str) -> list[Path]:
    """The files of the earlier capture in --out (its report.json's `stages`) below check/<old>/, refine/<old>/ and
    work/<old>.data/ when <old> is not this capture's <name>: with --overwrite they go once this capture is written
    (they would lie beside a report that no longer describes them). Only the names those stages write are taken,
    and a name read from the report only as a plain folder name."""
    from scenes.files import read_json
    from scenes.folder.format import MASK_FILE, image_name
    from validate.fitted.fit_report import CHECK_OUTPUTS
    from validate.fitted.refinement import REFINE_OUTPUTS

    try:
        stages = read_json(out / "report.json").get("stages") or {}
        where, old = Path(str(stages.get("check") or "")).parts[:2]
    except (OSError, ValueError, AttributeError):  # no record of a capture: nothing of it is known
        return []
    if where != "check" or old == name or old in (".", "..") or "\\" in old:  # read from a file: a plain name only
        return []
    folders = {out / "check" / old: CHECK_OUTPUTS, out / "refine" / old: REFINE_OUTPUTS}
    work = out / "work" / f"{old}.data"
    if stages.get("work_folder") == str(work.relative_to(out)) and work.is_dir() and not work.is_symlink():
        folders[work] = (MASK_FILE, *(image_name(i) for i in range(len(list(work.iterdir())))))
    return [folder / n for folder, names in folders.items()
            if folder.is_dir() and not folder.is_symlink() and not folder.parent.is_symlink()
            for n in names if (folder / n).is_file() and not (folder / n).is_symlink()]


def remove_stale(files: list[Path]) -> None:
    """Remove the earlier capture's files `stale_stages` found, and their folders once empty (a user's file
    there keeps its folder)."""
    for f in files:
        f.unlink(missing_ok=True)
    for folder in sorted({f.parent for f in files}):
        try:
            folder.rmdir()
        except OSError:  # not empty: something of the user's
            pass
