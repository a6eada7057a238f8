"""`python -m wildgen.preview DIR`: contact sheets (images, normal map, mask) per object and an overview;
with `--stats`, the dataset card instead.

Writes DIR/preview/<object>.png (every image, the normal map and the mask, labelled), DIR/preview/overview.png
(per object its first image and normal map) and DIR/preview/preview.json (the sheets it wrote: a PNG carries no
mark of its writer, so --overwrite replaces only the sheets listed there; and the objects that could not be read,
`failed`, one line each: the others are drawn, and the command exits 1). Images are linear; they are shown with
the sRGB curve (`scenes.colors.linear_to_srgb`) so that dark regions stay visible. The dataset's numbers are
`wildgen.card`, its picture `wildgen.card_figure`.

The dataset card (`--stats`) is what to look at before training on a dataset: DIR/preview/stats.png plots the
distributions of the visible normals, the light directions, distances and strengths, the exposures, the
materials, light families, camera and sensor of all objects; DIR/preview/stats.json holds the numbers behind
every panel (counts, histograms with their bin edges, min / median / max) and the objects that could not be
read (`failed`, one line each), which are left out of everything else (the card is written, and the command
exits 1 naming the first).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

from scenes.cli.errors import UsageError
from scenes.cli.options import Command, Positional, arg
from scenes.cli.outputs import check_listed, check_output_folder, make_output_folder
from scenes.files import is_within
from scenes.folder.format import check_dataset_complete

TILE = 128
"""Pixels of one tile of a contact sheet."""
SHEET_COLUMNS, OVERVIEW_COLUMNS = 6, 4
SHEETS_RECORD = "preview.json"
"""The list of sheets a preview wrote into its output folder: the only PNGs a later --overwrite replaces."""


def _to_display(rgb: np.ndarray) -> np.ndarray:
    """Linear float RGB -> 8-bit sRGB-encoded RGB (`scenes.colors.linear_to_srgb`)."""
    from scenes.colors import linear_to_srgb

    return np.round(linear_to_srgb(rgb) * 255).astype(np.uint8)


def _tile(img: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.resize(img, (TILE, TILE), interpolation=cv2.INTER_NEAREST if img.shape[0] < TILE else cv2.INTER_AREA)


def object_tiles(folder: Path) -> list[tuple[np.ndarray, str]]:
    """The tiles of one object folder's contact sheet, (TILE, TILE, 3) uint8 RGB each with its label: every
    image, then the normal map and the mask."""
    from scenes.files import check_text_name
    from scenes.folder.format import MASK_FILE, NORMAL_FILE, check_listed_done, image_files
    from scenes.folder.layouts import check_own_files
    from scenes.images import normal_visual, read_image, read_mask, read_normals

    check_text_name(folder, "DIR")  # its sheet is written under this name
    check_listed_done(folder, "DIR")  # a folder where a failed render's would be is not the render's
    check_own_files(folder, "DIR")  # not another object's files (a link)
    images = image_files(folder)
    if not images:
        raise FileNotFoundError(f"DIR: object folder {str(folder)!r} has no L*.png images")
    try:
        pictures = [read_image(p) for p in images]
        odd = next((p for p, im in zip(images, pictures) if im.shape[:2] != pictures[0].shape[:2]), None)
        if odd is not None:  # every reader refuses such an object: the sheet would hide it
            raise ValueError(f"{odd.name} differs in size from {images[0].name} (every image of an object has one "
                             "size)")
        tiles = [(_tile(_to_display(im)), p.stem) for p, im in zip(images, pictures)]
        n = read_normals(folder / NORMAL_FILE, "DIR")
        mask = read_mask(folder / MASK_FILE).astype(np.uint8) * 255
    except (OSError, ValueError) as exc:
        raise ValueError(f"DIR: object folder {str(folder)!r}: {exc}") from exc
    tiles.append((_tile(np.ascontiguousarray(normal_visual(n))), "normal"))
    tiles.append((_tile(np.repeat(mask[:, :, None], 3, axis=2)), "mask"))
    return tiles


def contact_sheet(cells: list[tuple[np.ndarray, str]], cols: int):
    """A matplotlib Figure of picture cells (equal-sized uint8 RGB arrays, each with a label written in white at
    its top left), `cols` to a row, one screen pixel per picture pixel; black where a row is short."""
    from scenes.report.charts import add_axes_px, new_figure

    h, w = cells[0][0].shape[:2]
    rows = -(-len(cells) // cols)
    fig = new_figure(cols * w, rows * h)
    fig.set_facecolor("black")
    for k, (picture, label) in enumerate(cells):
        ax = add_axes_px(fig, (k % cols) * w, (k // cols) * h, w, h)
        ax.imshow(picture, interpolation="nearest", aspect="auto")
        ax.text(3, 3, label, color="white", fontsize=7, ha="left", va="top")
    return fig


def _object_folders(dataset: Path) -> list[Path]:
    """The object folders of DIR (or DIR itself when it is one); the one-line error when there are none."""
    folders = sorted(p for p in dataset.glob("*.data") if p.is_dir()) if dataset.is_dir() else []
    if dataset.name.endswith(".data") and dataset.is_dir():
        folders = [dataset]
    elif folders:  # a run still writing it, or stopped: not drawn (nor counted) as a dataset
        check_dataset_complete(dataset, "DIR")
    if not folders:
        raise FileNotFoundError(f"DIR: no <object>.data folders in {str(dataset)!r}")
    return folders


def _output_folder(dataset: Path, out: str | Path | None) -> Path:
    """--out, or DIR/preview (beside a single object folder: its parent's preview/), checked writable."""
    folders = dataset if not dataset.name.endswith(".data") else dataset.parent  # where the object folders lie
    out_dir = Path(out) if out else folders / "preview"
    check_output_folder(out_dir)
    if is_within(out_dir, folders) and is_within(folders, out_dir):  # that folder by any name (a mount too)
        raise UsageError(f"--out: {str(out_dir)!r} is the folder of the object folders ({str(folders)!r}); the "
                         f"sheets would lie among them: expected a folder of its own (the default is "
                         f"{str(folders / 'preview')!r})")
    return out_dir


def _check_sheet_names(folders: list[Path], out_dir: Path) -> None:
    """Refuse sheets that would land inside an object folder (over its own images) or share a name: an object
    named 'overview' (the overview's file) or '' (a folder named '.data')."""
    inside = next((f for f in folders if is_within(out_dir, f)), None)
    if inside is not None:
        raise UsageError(f"--out: {str(out_dir)!r} lies in the object folder {str(inside)!r}; the sheets would mix "
                         "with its files: expected a folder outside every object folder")
    clash = next((f for f in folders if f.name[:-5] in ("", "overview")), None)
    if clash is not None:
        raise UsageError(f"DIR: the object folder {clash.name!r} would give its sheet the name "
                         f"{clash.name[:-5] + '.png'!r}, which is {'the overview' if clash.name[:-5] else 'no name'}; "
                         "rename the folder")


def preview(dataset: str | Path, out: str | Path | None = None,
            overwrite: bool = False) -> tuple[list[Path], dict[str, str]]:
    """Write contact sheets and the overview; returns the written paths (the overview last) and the objects that
    could not be read ({name: reason}, also in preview.json's `failed`: one bad object does not stop the others).
    Every object is read and every sheet drawn before anything is written; existing sheets are replaced only
    with `overwrite` (`scenes.cli.outputs.claim_outputs`)."""
    from scenes.cli.outputs import claim_outputs
    from scenes.files import shown_name, write_json
    from scenes.images import write_picture
    from scenes.report.charts import to_bgr

    dataset = Path(dataset)
    folders = _object_folders(dataset)
    out_dir = _output_folder(dataset, out)
    _check_sheet_names(folders, out_dir)
    targets = [out_dir / f"{folder.name[:-5]}.png" for folder in folders] + [out_dir / "overview.png"]
    record = out_dir / SHEETS_RECORD
    claim_outputs([*targets, record], overwrite, owner="wildgen.preview", signed={record: ("dataset", "sheets")})
    listed = check_listed(targets, record, "sheets", "wildgen.preview")  # a sheet it never drew: the user's
    print(f"drawing contact sheets of {len(folders)} object(s) into {out_dir}", flush=True)
    drawn, failed = [], {}
    for folder, target in zip(folders, targets):
        try:
            tiles = object_tiles(folder)
        except (OSError, ValueError) as exc:  # one bad object is recorded and the rest goes on
            failed[shown_name(folder.name[:-5])] = shown_name(str(exc))
            print(f"  {shown_name(folder.name)}: not drawn ({shown_name(str(exc))})", flush=True)
            continue
        (first, name), (normal, _) = tiles[0], tiles[-2]  # the first image and the normal map
        summary = (np.concatenate([first, normal], 1), f"{folder.name[:-5]}: {name} | normal")
        drawn.append((target, to_bgr(contact_sheet(tiles, SHEET_COLUMNS)), summary))
    if not drawn:  # one object (DIR itself): its own message; several: which failed first
        raise ValueError(next(iter(failed.values())) if len(folders) == 1 else
                         f"DIR: none of the {len(folders)} object folders of {str(dataset)!r} can be drawn (first, "
                         f"{next(iter(failed))}: {next(iter(failed.values()))})")
    written = [target for target, _, _ in drawn] + [targets[-1]]
    make_output_folder(out_dir)
    sheets = sorted(listed | {p.name for p in written})  # recorded before the first sheet: a killed run's are its own
    write_json(record, {"dataset": str(dataset), "sheets": sheets, "failed": failed})
    for target, sheet, _ in drawn:
        write_picture(target, sheet)
    write_picture(targets[-1], to_bgr(contact_sheet([s for _, _, s in drawn], OVERVIEW_COLUMNS)))
    return written, failed


# ---------------------------------------------------------------------------------- the dataset card

def write_stats(dataset: str | Path, out: str | Path | None = None,
                overwrite: bool = False) -> tuple[list[Path], dict[str, str]]:
    """Write the dataset card (stats.png) and its numbers (stats.json); returns their paths and the objects that
    could not be read ({name: reason}). Outputs are checked before any folder is read; existing ones are replaced
    only with `overwrite`."""
    from scenes.cli.outputs import claim_outputs
    from scenes.files import atomic_write_text
    from scenes.images import write_picture
    from scenes.report.charts import to_bgr
    from wildgen.card import STATS_PICTURE, STATS_SUMMARY, dataset_stats, json_text
    from wildgen.card_figure import draw_stats

    dataset = Path(dataset)
    folders = _object_folders(dataset)
    out_dir = _output_folder(dataset, out)
    targets = [out_dir / STATS_PICTURE, out_dir / STATS_SUMMARY]
    claim_outputs(targets, overwrite, owner="wildgen.preview --stats",
                  signed={out_dir / STATS_SUMMARY: ("dataset", "objects", "normals", "lights")})
    print(f"reading {len(folders)} object(s) for the dataset card", flush=True)
    stats = dataset_stats(dataset, folders)
    picture = to_bgr(draw_stats(stats))
    make_output_folder(out_dir)
    write_picture(targets[0], picture)
    atomic_write_text(targets[1], json_text(stats))
    return targets, stats["failed"]


@dataclass
class PreviewOptions:
    """The command line of wildgen.preview."""

    dataset: Annotated[str, Positional, arg(metavar="DIR")] = ""
    """Dataset directory (or one <object>.data folder)."""
    out: Annotated[str | None, arg(help_behavior_hint="(default: DIR/preview)")] = None
    """Output folder: one <object>.png per object, overview.png and preview.json, the list of sheets written
    (with --stats: stats.png and stats.json)."""
    stats: bool = False
    """Instead of the contact sheets, write the dataset card: stats.png plots the distributions to check before
    training (visible normals, light directions, distances and strengths, exposures, materials, light
    families, camera, sensor) and stats.json holds the numbers behind it, with the object folders that could
    not be read under `failed`."""
    overwrite: bool = False
    """Replace the contact sheets listed in an earlier run's preview.json (or the dataset card) in the output
    folder (other files are never touched)."""


COMMAND = Command(
    PreviewOptions,
    prog="python -m wildgen.preview",
    description="Contact sheet PNG per object and one overview PNG of a dataset; with --stats, "
    "the dataset card (stats.png, stats.json) instead.",
)


def main(argv: list[str] | None = None) -> int:
    from scenes.cli.errors import UsageError, report_error

    try:
        args = COMMAND.parse(argv)
        if not args.dataset.strip():  # '' (or no DIR at all) would be the current folder: never meant
            raise UsageError(f"DIR: got {args.dataset!r}, expected a dataset folder (wildgen.make's --out) or one "
                             "<object>.data folder")
        from contextlib import ExitStack

        from scenes.cli.outputs import check_not_being_written, output_lock

        check_not_being_written(args.dataset, "DIR")
        held = ExitStack()
        if Path(args.dataset).is_dir():  # a missing dataset is refused by the reader, naming it
            held.enter_context(output_lock(_output_folder(Path(args.dataset), args.out)))  # one writer per folder
    except (UsageError, ValueError, OSError) as exc:
        return report_error(exc)
    with held:
        return _write(args)


def _write(args) -> int:
    from scenes.cli.errors import UsageError, report_error

    try:
        if args.stats:
            written, failed = write_stats(args.dataset, args.out, args.overwrite)  # outputs checked before any read
            print(f"wrote the dataset card {written[0]} and its numbers {written[1]}")
            if failed:  # counted on the card, said here too (as the sheets)
                name, reason = next(iter(failed.items()))
                print(f"error: {len(failed)} object(s) could not be read for the card (first, {name}: {reason}); "
                      f"they are listed under 'failed' in {written[1]}", file=sys.stderr)
                return 1
            return 0
        written, failed = preview(args.dataset, args.out, args.overwrite)  # outputs checked before any drawing
    except (UsageError, ValueError, OSError) as exc:
        return report_error(exc)
    print(f"wrote {len(written) - 1} contact sheets and {written[-1]}")
    if failed:
        name, reason = next(iter(failed.items()))
        print(f"error: {len(failed)} of {len(failed) + len(written) - 1} object(s) could not be drawn (first, {name}: "
              f"{reason}); they are listed under 'failed' in {written[-1].parent / SHEETS_RECORD}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    sys.exit(run_supervised("wildgen.preview", main))
