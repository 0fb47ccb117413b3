"""Generated blocks of a Markdown page: render a table, read the blocks, replace them.

A generated block is the text between ``<!-- generated: NAME -->`` and
``<!-- end generated: NAME -->``, each marker on a line of its own. The reports
write what is between the markers; the prose around them is written by hand.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: A generated block: its begin marker, then anything but another marker, then its end marker.
BLOCK_PATTERN = re.compile(
    r"<!-- generated: (?P<name>[^\n]+?) -->\n(?P<body>(?:(?!<!-- ).)*?)<!-- end generated: (?P=name) -->",
    re.S,
)


def markdown_table(header: Sequence[str] | str, rows: list[list[str]], aligns: Sequence[str] = ()) -> str:
    """Render a Markdown table: the header, the alignment line (``---`` by default), one line per row.

    ``header`` is the column titles, or the header line as the page writes it (``"row | ps | RMS"``).
    """

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(cells) + " |"

    header = header.split(" | ") if isinstance(header, str) else header
    aligns = aligns or ["---"] * len(header)
    return "\n".join([line(header), line(aligns), *(line(r) for r in rows)])


@dataclass(frozen=True)
class Column:
    """One column of a generated table: its title, how a row's cell is written, its alignment.

    ``cell`` is a function of the row or a format string filled from the row (a dict):
    ``"{ms_per_step:.3g}"``, ``"{controller[fraction_at_bound]:.1%}"``.
    """

    title: str
    cell: Callable[[Any], str] | str
    align: str = "---"

    def text(self, row: Any) -> str:
        """Return the cell of ``row``."""
        return self.cell.format_map(row) if isinstance(self.cell, str) else self.cell(row)


def series(titles: Iterable[str], key: str, show: Callable[[Any], str]) -> list[Column]:
    """Return a column per title, the i-th showing ``show(row[key][i])``."""
    return [Column(title, lambda r, i=i: show(r[key][i])) for i, title in enumerate(titles)]


def table(rows: Iterable[Any], columns: Sequence[Column], caption: str = "") -> str:
    """Render ``rows`` as the Markdown table ``columns`` describe, under ``caption`` if one is given."""
    lines = [[column.text(row) for column in columns] for row in rows]
    text = markdown_table([c.title for c in columns], lines, [c.align for c in columns])
    return f"{caption}\n\n{text}" if caption else text


def read_blocks(text: str) -> dict[str, str]:
    """Return the generated blocks of a page's text by name, without their trailing newlines."""
    return {m.group("name"): m.group("body").rstrip("\n") for m in BLOCK_PATTERN.finditer(text)}


def page_tables(page: Path) -> dict[str, str]:
    """Return the generated blocks as they stand in the file ``page``."""
    return read_blocks(page.read_text(encoding="utf-8"))


def replace_blocks(text: str, blocks: dict[str, str]) -> tuple[str, list[str]]:
    """Return ``text`` with the generated blocks that ``blocks`` names replaced, and the names it lacks.

    A block's new content is written without its trailing newlines.
    """
    found = set()

    def replace(match: re.Match) -> str:
        name = match.group("name")
        if name not in blocks:
            return match.group(0)
        found.add(name)
        body = blocks[name].rstrip("\n")
        return f"<!-- generated: {name} -->\n{body}\n<!-- end generated: {name} -->"

    return BLOCK_PATTERN.sub(replace, text), sorted(set(blocks) - found)


def update_page(page: Path, blocks: dict[str, str]) -> list[str]:
    """Replace the generated blocks of the file ``page`` that ``blocks`` names; return those it lacks."""
    text, missing = replace_blocks(page.read_text(encoding="utf-8"), blocks)
    page.write_text(text, encoding="utf-8")
    return missing


def stale_blocks(pages: dict[Path, dict[str, str]], root: Path) -> list[str]:
    """Return ``PAGE: BLOCK`` for every block of ``pages`` missing on its page or differing from it."""
    found = []
    for page, blocks in pages.items():
        on_page = page_tables(page)
        found += [
            f"{page.relative_to(root)}: {name}" for name, text in blocks.items() if on_page.get(name) != text
        ]
    return found
