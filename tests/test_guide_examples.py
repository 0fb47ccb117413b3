"""The Python examples of the README and the user guide run as written.

Each ```python block of these pages is taken from the page and run as a script of its own
(``python -c``), in a fresh folder: what a user who copies it gets.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The pages whose Python blocks are complete scripts, and what each block must print.
PAGES = {
    "README.md": [r"kJ/mol \{'steps': 500"],
    "docs/integrators.md": [r"^5\.0 "],
    "docs/energy_mode.md": [r"kJ/mol \{"],
    "docs/own_files.md": [r"hydrogen"],
    "docs/smooth_forces.md": [r"switching from 0\.8 nm", r"CMMotionRemover .*removed"],
    "docs/splitting.md": [r"update context state", r"constrain positions"],
}
BLOCK = re.compile(r"```python\n(.*?)```", re.S)


def python_blocks(page: str) -> list[str]:
    """Return the ```python blocks of ``page`` (a path from the repository root)."""
    return BLOCK.findall((ROOT / page).read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    return {**os.environ, "ALPHAPRK_CACHE_DIR": str(tmp_path_factory.mktemp("guide-cache"))}


@pytest.mark.parametrize("page", PAGES)
def test_the_pages_python_runs_as_written(page, tmp_path, env):
    blocks = python_blocks(page)
    assert blocks, f"{page} has no python block"
    (tmp_path / "tests").symlink_to(ROOT / "tests")  # the test files a page names from the repository root
    output = ""
    for code in blocks:
        result = subprocess.run(
            [sys.executable, "-c", code],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            encoding="utf-8",
            timeout=240,
        )
        assert result.returncode == 0, f"{page}:\n{code}\n{result.stderr}"
        assert "Warning" not in result.stderr, result.stderr
        output += result.stdout
    for pattern in PAGES[page]:
        assert re.search(pattern, output, re.M), (page, pattern, output)


def test_every_guide_page_with_python_is_run():
    """A page of the README or docs/ (not the research record) with a ```python block is in PAGES."""
    pages = [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]
    with_python = {str(page.relative_to(ROOT)) for page in pages if "```python" in page.read_text("utf-8")}
    assert with_python == set(PAGES)
