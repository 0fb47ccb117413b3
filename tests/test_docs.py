"""What a new user reads: links resolve inside the project, examples show the recommended modes."""

from __future__ import annotations

import ast
import inspect
import re
from pathlib import Path

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    RattleIntegrator,
    RattleRescaleIntegrator,
)
from openmm_alphaprk.runs.integrator_names import parse_integrator
from openmm_alphaprk.workflows.comparison import DEFAULT_INTEGRATORS
from tools.reports import guide, sources
from tools.reports.markdown import stale_blocks

ROOT = Path(__file__).resolve().parents[1]
#: The README and every Markdown page of the documentation (docs/ and its folders; not the built site).
PAGES = [
    ROOT / "README.md",
    *sorted(page for page in (ROOT / "docs").rglob("*.md") if "_build" not in page.relative_to(ROOT).parts),
]
README_MAX_LINES = 150
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


def test_the_pages_include_the_documentation_folders():
    """The research record and the API reference live in subfolders of docs/; their links are checked too."""
    folders = {page.parent.name for page in PAGES}
    assert {"research", "api"} <= folders


def test_the_readme_is_a_front_page():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines; move detail into docs/"


def test_every_data_file_has_its_provenance():
    """Each file of docs/data/ has its day, commit and machine in provenance.toml, and each entry a file."""
    table = sources.provenance()
    entries = {key for key in table if key != "machines"}
    files = set(sources.data_files())
    assert files - entries == set(), "files without provenance"
    assert entries - files == set(), "provenance of files that are not there"
    for path in files:
        entry = sources.source(path)
        assert re.fullmatch(r"\d{4}-\d\d-\d\d", entry.date) and re.fullmatch(r"[0-9a-f]{7,40}", entry.commit)
    assert not [p.name for p in (ROOT / "docs").glob("*.json")], "data belongs under docs/data/<page>/"


#: A tracker reference: "issue 4", "issue-4", "Issue #4", "issues 3", "#4". An upstream
#: project's tracker named with the project ("MDAnalysis GitHub #3889") can be looked up.
TRACKER = re.compile(r"\b[Ii]ssues?[\s-]*#?\d+|(?<![\w&])(?<!GitHub )#\d+\b")
#: The code and its tests: what they do is said in their own words, not by a tracker's number
#: (this module, which spells the pattern's examples, aside).
SOURCES = sorted(
    path
    for folder in ("openmm_alphaprk", "tests", "tools")
    for path in (ROOT / folder).rglob("*")
    if path.suffix in {".py", ".sh", ".md"} and path.name != Path(__file__).name
)
#: How the work was organised rather than what the software does: the tracker's issues ("the issue
#: that asked", "this issue", "the next issue"), sessions, teams, tickets, and a design document
#: that is not in the repository (or its sections, "§4").
ORGANISATION = re.compile(
    r"\b(?:[Tt]h(?:e|is|at) (?:next |same |previous |first )?issue\b(?!s? (?:a|one|its) \w+Warning)"
    r"|[Tt]his session|[Tt]he session|[Tt]he team\b|\bfiled\b|\btickets?\b|[Dd]esign doc(?:ument)?s?\b)"
    r"|§\s?\d"
)


def test_the_tracker_pattern_catches_every_spelling():
    for text in ("issue-4", "issue 4", "Issue #4", "issues 3 and 4", "see #4"):
        assert TRACKER.search(text), text
    for text in ("it issues a warning", "C# 4", "&#8212;", "MDAnalysis GitHub #3889"):
        assert not TRACKER.search(text), text


def test_the_readme_and_the_user_guide_numbers_are_the_datas():
    """The README's "which integrator" table and the user guide's measured blocks are what
    ``python -m tools.reports`` renders from docs/data/ (run it after new measurements)."""
    assert stale_blocks(guide.render(), ROOT) == []
    pages = guide.render()
    assert {page.name for page in pages} >= {
        "README.md",
        "integrators.md",
        "energy_mode.md",
        "platforms.md",
        "smooth_forces.md",
        "own_files.md",
        "driver.md",
    }
    for blocks in pages.values():
        for text in blocks.values():
            assert re.search(r"20\d\d-\d\d-\d\d", text), "every generated block says when it was measured"


def test_no_page_refers_to_tracker_issues():
    """Pages give dates, not tracker numbers, which a reader of the documentation cannot look up."""
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        found = TRACKER.findall(text)
        assert not found, f"{page.relative_to(ROOT)} names tracker issues: {found}"


def test_no_module_refers_to_tracker_issues():
    """The package, its tests and tools say what they do and test, not which issue asked for it."""
    assert any(path.parent.name == "tests" for path in SOURCES)
    for path in SOURCES:
        found = TRACKER.findall(path.read_text(encoding="utf-8"))
        assert not found, f"{path.relative_to(ROOT)} names tracker issues: {found}"


def test_the_organisation_pattern_catches_what_it_is_for():
    caught = (
        "The tables of the issue that asked for this benchmark",
        "reported for the next issue",
        "the session that closed this issue",
        "as the design doc warned",
        "the design document's measurement",
        "(§4)",
        "a ticket was filed",
    )
    for text in caught:
        assert ORGANISATION.search(text), text
    for text in ("it issues one NonSmoothForcesWarning", "the energy is held", "in this section"):
        assert not ORGANISATION.search(text), text


def test_no_page_tells_how_the_work_was_organised():
    """Pages, research record included, say what the software does and what was measured; not who
    asked for it, in which issue or session, or what a document outside the repository says."""
    for page in PAGES:
        text = " ".join(page.read_text(encoding="utf-8").split())
        found = [m.group(0) for m in ORGANISATION.finditer(text)]
        assert not found, f"{page.relative_to(ROOT)} tells how the work was organised: {found}"


def test_the_default_comparison_uses_the_recommended_energy_mode():
    """Order 2's energy mode is documented as not for production: the main job compares order 4's."""
    assert parse_integrator("energy") not in [parse_integrator(name) for name in DEFAULT_INTEGRATORS]
    assert "energy4" in DEFAULT_INTEGRATORS


def _documented_signature(name: str) -> inspect.Signature:
    """The signature docs/integrators.md ("The integrators") gives for ``name(...)``, parsed as Python."""
    text = (ROOT / "docs" / "integrators.md").read_text(encoding="utf-8")
    match = re.search(rf"`{name}\((timestep[^`]*)\)`", text)
    assert match, f"docs/integrators.md gives {name}'s signature"
    parameters = " ".join(match.group(1).split())
    try:
        (function,) = ast.parse(f"def f({parameters}): pass").body
    except SyntaxError:
        raise AssertionError(f"the documented {name}({parameters}) is not a Python signature") from None
    namespace: dict = {}
    exec(compile(ast.Module([function], []), "README", "exec"), namespace)
    return inspect.signature(namespace["f"])


def test_the_documented_signatures_are_the_real_ones():
    """docs/integrators.md gives each constructor's signature: the one ``inspect.signature`` finds."""
    for cls in (
        AlphaRattleIntegrator,
        AlphaRattleEnergyIntegrator,
        RattleIntegrator,
        RattleRescaleIntegrator,
    ):
        real = inspect.signature(cls)
        assert next(iter(real.parameters)) == "timestep", cls.__name__
        written = _documented_signature(cls.__name__)
        assert [(p.name, p.kind, p.default) for p in written.parameters.values()] == [
            (p.name, p.kind, p.default) for p in real.parameters.values()
        ], cls.__name__


def test_ci_runs_the_readme_commands():
    """What .ci/run runs under ``# README: ...`` (up to its next comment) is README text, word for word."""
    marked, inside = [], False
    for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines():
        if line.startswith("#"):
            inside = line.startswith("# README:")
        elif inside and line.strip():
            marked.append(line.strip())
    assert len(marked) >= 4, marked  # install, test, and the two of the documentation
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```bash\n(.*?)```", readme, re.S)
    readme_commands = {line.strip() for block in blocks for line in block.splitlines()}
    for command in marked:
        assert command in readme_commands, f".ci/run runs {command!r}, which the README does not say"
