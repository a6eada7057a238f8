"""`python -m wildgen.preview DIR`: contact sheets (images, normal map, mask) per object and an overview.

Writes DIR/preview/<object>.png and DIR/preview/overview.png. Images are linear; they are shown with a
display gamma of 2.2 so that dark regions stay visible.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from scenes.cli import check_output_folder, make_output_folder
from scenes.config import config_from_args as parse_config
from scenes.config import config_parser, option

TILE = 128


def _to_display(rgb: np.ndarray) -> np.ndarray:
    """Linear float RGB -> 8-bit BGR for OpenCV, gamma 2.2."""
    return np.round(np.clip(rgb, 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)[:, :, ::-1]


def _tile(img: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.resize(img, (TILE, TILE), interpolation=cv2.INTER_NEAREST if img.shape[0] < TILE else cv2.INTER_AREA)


def _label(img: np.ndarray, text: str) -> np.ndarray:
    import cv2

    out = img.copy()
    cv2.putText(out, text, (3, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def object_sheet(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """Contact sheet of one object folder, and a 2-tile summary (first image, normal map) for the overview."""
    import cv2

    from scenes.objfolder import MASK_FILE, NORMAL_FILE, image_files, normal_visual, read_image, read_mask, read_normals

    images = image_files(folder)
    if not images:
        raise FileNotFoundError(f"DIR: object folder {str(folder)!r} has no L*.png images")
    try:
        tiles = [_label(_tile(_to_display(read_image(p))), p.stem) for p in images]
        n = read_normals(folder / NORMAL_FILE)
        mask = read_mask(folder / MASK_FILE).astype(np.uint8) * 255
    except (OSError, ValueError) as exc:
        raise ValueError(f"DIR: object folder {str(folder)!r}: {exc}") from exc
    tiles.append(_label(_tile(np.ascontiguousarray(normal_visual(n)[:, :, ::-1])), "normal"))
    tiles.append(_label(_tile(cv2.cvtColor(mask, cv2.COLOR_GRAY2BGR)), "mask"))
    cols = 6
    while len(tiles) % cols:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.concatenate(tiles[i : i + cols], 1) for i in range(0, len(tiles), cols)]
    return np.concatenate(rows, 0), np.concatenate([tiles[0], tiles[len(images)]], 1)


def preview(dataset: str | Path, out: str | Path | None = None, overwrite: bool = False) -> list[Path]:
    """Write contact sheets and the overview; returns the written paths. Every object is read and every sheet
    drawn before anything is written; existing sheets are replaced only with `overwrite`
    (`scenes.cli.claim_outputs`)."""
    from scenes.cli import claim_outputs
    from scenes.objfolder import write_picture

    dataset = Path(dataset)
    folders = sorted(p for p in dataset.glob("*.data") if p.is_dir()) if dataset.is_dir() else []
    if dataset.name.endswith(".data") and dataset.is_dir():
        folders = [dataset]
    if not folders:
        raise FileNotFoundError(f"DIR: no <object>.data folders in {str(dataset)!r}")
    out_dir = Path(out) if out else (dataset if not dataset.name.endswith(".data") else dataset.parent) / "preview"
    check_output_folder(out_dir)
    targets = [out_dir / f"{folder.name[:-5]}.png" for folder in folders] + [out_dir / "overview.png"]
    claim_outputs(targets, overwrite, owner="wildgen.preview")
    print(f"drawing contact sheets of {len(folders)} object(s) into {out_dir}", flush=True)
    sheets, summaries = [], []
    for folder in folders:
        sheet, summary = object_sheet(folder)
        sheets.append(sheet)
        summaries.append(_label(summary, folder.name[:-5]))
    cols = 4
    while len(summaries) % cols:
        summaries.append(np.zeros_like(summaries[0]))
    overview = np.concatenate([np.concatenate(summaries[i : i + cols], 1) for i in range(0, len(summaries), cols)], 0)
    make_output_folder(out_dir)
    for path, image in zip(targets, [*sheets, overview]):
        write_picture(path, image)
    return targets


@dataclass
class PreviewOptions:
    """The command line of wildgen.preview."""

    dataset: str = option("", positional=True, metavar="DIR")
    """Dataset directory (or one <object>.data folder)."""
    out: str | None = option(None, default_text="DIR/preview")
    """Output folder: one <object>.png per object and overview.png."""
    overwrite: bool = False
    """Replace the contact sheets of an earlier run in the output folder (other files are never touched)."""


def build_parser():
    return config_parser(PreviewOptions, prog="python -m wildgen.preview",
                         description="Contact sheet PNG per object and one overview PNG of a dataset.")


def main(argv: list[str] | None = None) -> int:
    from scenes.cli import UsageError, report_error

    try:
        args = parse_config(PreviewOptions, build_parser().parse_args(argv))
        written = preview(args.dataset, args.out, args.overwrite)  # outputs checked before any sheet is drawn
    except (UsageError, ValueError, OSError) as exc:
        return report_error(exc)
    print(f"wrote {len(written) - 1} contact sheets and {written[-1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
