"""What a pip install gets: the package data, one version string, messages that point at installed text."""

from __future__ import annotations

import ast
import importlib.metadata
import shutil
import subprocess
import sys
from pathlib import Path

import openmm_alphaprk
from openmm_alphaprk.systems.shipped import STATES_DIR

PACKAGE = Path(openmm_alphaprk.__file__).parent
ROOT = PACKAGE.parent


def test_built_package_holds_the_shipped_states_and_the_package_version(tmp_path):
    """Setuptools (the build backend; in the ``test`` extra) builds the package as pip would."""
    source = tmp_path / "source"
    shutil.copytree(PACKAGE, source / PACKAGE.name, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source)
    built = tmp_path / "built"
    subprocess.run(
        [sys.executable, "-c", "from setuptools import setup; setup()", "-q", "egg_info", "build_py"]
        + ["--build-lib", str(built)],
        cwd=source,
        check=True,
        capture_output=True,
    )
    files = {path.relative_to(built / PACKAGE.name).as_posix() for path in built.rglob("*") if path.is_file()}
    shipped = {f"systems/states/{path.name}" for path in STATES_DIR.iterdir()}
    for name in ("tip3p-3nm", "tip3p-2nm", "water-cluster"):
        assert f"systems/states/{name}.xml.gz" in shipped
    assert shipped <= files
    assert {f"systems/{path.name}" for path in (PACKAGE / "systems").glob("*.toml")} <= files
    # the generators of the project's own docs/ live in tools/, outside what pip installs
    assert not any(name.startswith("reports/") for name in files)
    pkg_info = (source / "openmm_alphaprk.egg-info" / "PKG-INFO").read_text(encoding="utf-8")
    assert f"\nVersion: {openmm_alphaprk.__version__}\n" in pkg_info


def test_one_version_string():
    """pyproject.toml reads the version from the package; the installed metadata agrees."""
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert 'dynamic = ["version"]' in text and "\nversion =" not in text.split("[tool.")[0]
    assert 'version = { attr = "openmm_alphaprk.__version__" }' in text
    assert importlib.metadata.version("openmm-alphaprk") == openmm_alphaprk.__version__


def _message_strings(path: Path):
    """The string constants inside ``raise`` statements and ``warnings.warn`` calls of a module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        is_warn = isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "warn"
        if isinstance(node, ast.Raise) or is_warn:
            for inner in ast.walk(node):
                if isinstance(inner, ast.Constant) and isinstance(inner.value, str):
                    yield inner.lineno, inner.value


#: Messages known to name a docs/ file or a .md page (module: count); adding or removing one fails the test.
KNOWN_DOCS_POINTERS: dict[str, int] = {}


def test_errors_and_warnings_point_at_nothing_a_pip_install_lacks():
    """A pip user has the README and the docstrings, not the docs/ folder of the repository."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        relative = path.relative_to(PACKAGE)
        hits = [line for line, text in _message_strings(path) if "docs/" in text or ".md" in text]
        if hits:
            found[relative.as_posix()] = len(hits)
    assert found == KNOWN_DOCS_POINTERS
