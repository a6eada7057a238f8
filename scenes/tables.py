"""The one Markdown table writer of the project: every table a command or the docs generator writes (the
benchmark's tables, the demo's summary.md, the probe tables, the generated tables of the docs, the bench
scripts' tables) goes through `markdown_table`, so all are written one way: GitHub-flavoured pipe tables by
`tabulate` (tablefmt "github"), each column padded to its widest cell."""
from __future__ import annotations

from typing import Any, Iterable, Sequence

from tabulate import tabulate


def markdown_table(header: Sequence[Any], rows: Iterable[Sequence[Any]]) -> str:
    """`header` and `rows` as one Markdown table (no trailing newline). Cells are written as `str(cell)`: format
    numbers before (tabulate's own number parsing is off, so "12.0" stays "12.0"); a `|` inside a cell must
    already be escaped as `\\|`. Every row must have one cell per header column (ValueError otherwise)."""
    header = [str(h) for h in header]
    body = [[str(c) for c in row] for row in rows]
    for row in body:
        if len(row) != len(header):
            raise ValueError(f"markdown_table: a row has {len(row)} cells, the header {len(header)}: {row}")
    return tabulate(body, headers=header, tablefmt="github", disable_numparse=True)
