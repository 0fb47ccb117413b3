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


def begin_marker(name: str) -> str:
    """Return the line that opens the generated block ``name``."""
    return f"<!-- generated: {name} -->"


def end_marker(name: str) -> str:
    """Return the line that closes the generated block ``name``."""
    return f"<!-- end generated: {name} -->"


def block(name: str, content: str) -> str:
    """Return the generated block ``name`` holding ``content`` (trailing newlines dropped)."""
    body = content.rstrip("\n")
    return f"{begin_marker(name)}\n{body}\n{end_marker(name)}"


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    """Render a Markdown table: the header, the ``---`` line, one line per row.

    Parameters
    ----------
    header
        The column titles.
    rows
        The cells of each row, as text.

    Returns
    -------
    str
        The table, without a trailing newline.
    """

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(cells) + " |"

    return "\n".join([line(header), line(["---"] * len(header)), *(line(r) for r in rows)])


@dataclass(frozen=True)
class Column:
    """One column of a generated table: its title, how a row's cell is written, its alignment."""

    title: str
    cell: Callable[[Any], str]
    align: str = "---"


def table(rows: Iterable[Any], columns: Sequence[Column], caption: str = "") -> str:
    """Render ``rows`` as the Markdown table ``columns`` describe, under ``caption`` if one is given.

    The one renderer of the generated tables: a page's generator says which rows and which
    columns; every cell is written by its column from the row (a dict of the data's schema).
    """
    lines = [[column.cell(row) for column in columns] for row in rows]
    text = markdown_table([c.title for c in columns], lines)
    aligns = "| " + " | ".join(c.align for c in columns) + " |"
    text = text.replace("| " + " | ".join(["---"] * len(columns)) + " |", aligns, 1)
    return f"{caption}\n\n{text}" if caption else text


def read_blocks(text: str) -> dict[str, str]:
    """Return the generated blocks of a page's text by name, without their trailing newlines."""
    return {m.group("name"): m.group("body").rstrip("\n") for m in BLOCK_PATTERN.finditer(text)}


def page_tables(page: Path) -> dict[str, str]:
    """Return the generated blocks as they stand in the file ``page``."""
    return read_blocks(page.read_text(encoding="utf-8"))


def replace_generated(text: str, name: str, content: str, where: object = "the page") -> str:
    """Replace the content of the generated block ``name`` in ``text``; the markers must exist.

    Parameters
    ----------
    text
        The page's text.
    name
        The block's name.
    content
        Its new content.
    where
        How the page is named in the error.

    Returns
    -------
    str
        The page's new text.

    Raises
    ------
    SystemExit
        If ``text`` has no generated block ``name``.
    """
    pattern = re.compile(
        re.escape(begin_marker(name) + "\n") + r"(?:(?!<!-- ).)*?" + re.escape(end_marker(name)), re.S
    )
    if not pattern.search(text):
        raise SystemExit(f"{where} has no markers for the generated block {name!r}.")
    return pattern.sub(lambda _: block(name, content), text)


def update_page(page: Path, tables: dict[str, str]) -> list[str]:
    """Replace the generated blocks of the file ``page`` that ``tables`` names; leave the others.

    Returns
    -------
    list of str
        The names in ``tables`` that the page has no block for, sorted.
    """
    text = page.read_text(encoding="utf-8")
    found = set()

    def replace(match: re.Match) -> str:
        name = match.group("name")
        if name not in tables:
            return match.group(0)
        found.add(name)
        return block(name, tables[name])

    page.write_text(BLOCK_PATTERN.sub(replace, text), encoding="utf-8")
    return sorted(set(tables) - found)


def stale_blocks(pages: dict[Path, dict[str, str]], root: Path) -> list[str]:
    """Return ``PAGE: BLOCK`` for every block of ``pages`` missing on its page or differing from it."""
    found = []
    for page, blocks in pages.items():
        on_page = read_blocks(page.read_text(encoding="utf-8"))
        found += [
            f"{page.relative_to(root)}: {name}" for name, text in blocks.items() if on_page.get(name) != text
        ]
    return found
