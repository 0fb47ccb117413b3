"""What a new user reads: links resolve inside the project, examples show the recommended modes."""

from __future__ import annotations

import re
from pathlib import Path

from openmm_alphaprk.integrators.names import parse_integrator
from openmm_alphaprk.workflows.comparison import DEFAULT_INTEGRATORS

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def test_every_relative_link_resolves_inside_the_project():
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        assert "../shared" not in text, f"{page.name} points at a file users do not have"
        for target in LINK.findall(text):
            if re.match(r"[a-z]+://|mailto:", target):
                continue
            path = (page.parent / target).resolve()
            assert path.is_relative_to(ROOT), f"{page.name}: {target} leaves the project"
            assert path.exists(), f"{page.name}: {target} does not exist"


def test_defaults_and_readme_commands_use_the_recommended_energy_mode():
    """Order 2's energy mode is documented as not for production: no default or example uses it."""
    assert parse_integrator("energy") not in [parse_integrator(name) for name in DEFAULT_INTEGRATORS]
    assert "energy4" in DEFAULT_INTEGRATORS
    commands = re.findall(
        r"^alphaprk (?:run|compare) .*$", (ROOT / "README.md").read_text(encoding="utf-8"), re.M
    )
    assert commands, "the README shows alphaprk run/compare commands"
    for command in commands:
        names = command.split("#")[0].split()
        assert "energy" not in names, command
