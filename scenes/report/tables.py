"""The one Markdown table writer of the project: every table a command or the docs generator writes (the
benchmark's tables, the demo's summary.md, the probe tables, the generated tables of the docs, the bench
scripts' tables) goes through `markdown_table`, so all are written one way: GitHub-flavoured pipe tables,
cells unpadded (a padded column of long help texts would make every line of a flag table as long as the
longest one; the rendered table is the same)."""
from __future__ import annotations

from typing import Any, Iterable, Sequence


def markdown_table(header: Sequence[Any], rows: Iterable[Sequence[Any]]) -> str:
    """`header` and `rows` as one Markdown table (no trailing newline). Cells are written as `str(cell)`: format
    numbers before; a `|` inside a cell must already be escaped as `\\|`. Every row must have one cell per
    header column (ValueError otherwise)."""
    header = [str(h) for h in header]
    body = [[str(c) for c in row] for row in rows]
    for row in body:
        if len(row) != len(header):
            raise ValueError(f"markdown_table: a row has {len(row)} cells, the header {len(header)}: {row}")
    rows = ["| " + " | ".join(cells) + " |" for cells in (header, *body)]
    return "\n".join([rows[0], "|" + "---|" * len(header), *rows[1:]])
