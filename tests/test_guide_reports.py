"""``python -m tools.reports``: every generated block is its data's, names its data, and is a table.

The pages' sentences are written by hand and cite the generated tables; the blocks of the
README and the user guide (``tools.reports.guide``) hold tables and one line of provenance,
no prose with numbers spliced in.
"""

from __future__ import annotations

import re

import pytest

from tools.reports import __main__ as reports
from tools.reports import accuracy, guide, long_runs, physics, sources, splitting
from tools.reports.markdown import Column, stale_blocks, table
from tools.reports.numbers import percent, tolerance, two, whole_percent

#: A data file a block names: `docs/data/PATH` or a link (data/PATH) from a page of docs/ or the README.
NAMED = re.compile(r"`docs/data/([^`]+)`|\]\((?:docs/)?data/([^)#]+)\)")
#: Blocks that read the run of the block above them on their page ("the run of DAY above").
FOLLOWS = {
    "cuda energy mode": "cuda long",
    "cpu energy mode": "cpu long",
    "survey verdicts": "survey tip3p-2nm 2 fs",
    "per picosecond": "survey tip3p-2nm 4 fs",
}


def test_every_generated_block_is_what_its_data_renders():
    """``python -m tools.reports --check``: every page's blocks (and docs/step_programs.md)."""
    assert reports.stale() == [], "run python -m tools.reports"
    assert reports.main(["--check"]) == 0


def test_every_generated_block_names_its_data_and_each_file_has_provenance():
    """A block says which files its numbers come from; each is a data file with its day and machine."""
    files = set(sources.data_files())
    for page, blocks in {**guide.render(), **long_runs.render(), **splitting.render()}.items():
        for name, text in blocks.items():
            named = {a or b for a, b in NAMED.findall(text)} - {"README.md"}
            where = f"{page.name}: {name}"
            if name in FOLLOWS:  # the run of the block above it, which names the data
                assert FOLLOWS[name] in blocks, where
                continue
            if page.name == "README.md":  # the front page: one line, the days, a link to the data
                assert "](docs/data/README.md)" in text and re.search(r"20\d\d-\d\d-\d\d", text), where
                continue
            assert named, f"{where} names no data file"
            assert named <= files, f"{where} names {named - files}"
            for path in named:
                assert sources.source(path).date in text, f"{where}: {path}'s day is not given"


def test_the_user_guide_blocks_are_tables_under_one_line():
    """No sentence of the guide's blocks is generated: a provenance line, then a table (and nothing after)."""
    for page, blocks in guide.render().items():
        for name, text in blocks.items():
            caption, _, rest = text.partition("\n\n")
            assert "\n" not in caption, f"{page.name}: {name}"
            assert all(line.startswith("|") for line in rest.splitlines()), f"{page.name}: {name}"


def test_the_readme_provenance_is_one_line_a_person_reads():
    text = guide.readme_block()
    caption = text.split("\n\n")[0]
    assert len(caption) < 400 and "commit" not in caption


def test_the_renderer_writes_a_column_spec():
    columns = [Column("name", lambda r: r["n"]), Column("value", lambda r: f"{r['v']:.1f}", "---:")]
    assert table([{"n": "a", "v": 1}], columns, "Caption.") == (
        "Caption.\n\n| name | value |\n| --- | ---: |\n| a | 1.0 |"
    )


def test_rows_are_found_by_the_registrys_name():
    rows = [
        {"name": "RATTLE", "integrator": "rattle", "divisor": 1},
        {"name": "x", "integrator": "rattle", "divisor": 5},
    ]
    assert sources.pick(rows, "rattle", 5)["name"] == "x"
    assert sources.pick([{"name": "RATTLE"}], "rattle")["name"] == "RATTLE"  # a file from before specs
    with pytest.raises(LookupError):
        sources.pick(rows, "energy4")


@pytest.mark.parametrize(
    ("log", "counts"),
    [
        ("platforms/cuda_h100/common_platform_tests.log", {"passed": 26, "deselected": 1}),
        ("compositions/cuda_h100/cuda_tests.log", {"failed": 2, "passed": 53, "skipped": 1}),
        ("compositions/cuda_h100/single_tests.log", {"passed": 4, "deselected": 39}),
    ],
)
def test_the_test_counts_are_read_from_pytests_summary_line(log, counts):
    assert guide.pytest_counts(log) == counts


def test_the_order_2_limits_are_the_research_records_runs():
    """87 % / 99.8 % fallbacks, villin 5.62 against RATTLE's 3.75; two trials 5.6–8.1 evaluations."""
    text = guide.order2_table()
    assert "| 87 % |" in text and "| 99.8 % |" in text and "| 5.62 | 3.75 |" in text
    assert "| 5.6 |" in text and "| 8.1 |" in text


def test_the_pme_table_names_the_integrators_of_its_day():
    """The run of 2026-11-23 took alpha4=0 (3 evaluations) as the triple jump: the table says so."""
    text = guide.pme_table()
    assert "`alpha4=0` †" in text and "alpha4=0:triple-jump" in text
    assert "| 5e-4 |" in text and "| 1e-5 |" in text


def test_numbers_are_written_as_the_pages_write_them():
    assert [two(v) for v in (91.7, 7.98, 0.802, 0.003, 1.55)] == ["92", "8.0", "0.80", "0.0030", "1.6"]
    assert [tolerance(v) for v in (5e-4, 1e-5, 5e-5)] == ["5e-4", "1e-5", "5e-5"]
    assert (percent(0.87), percent(0.998), whole_percent(0.9925)) == ("87 %", "99.8 %", "99 %")


def test_the_splitting_page_blocks():
    blocks = splitting.render()[splitting.PAGE]
    assert {"survey tip3p-2nm 2 fs", "survey villin 2 fs", "survey verdicts"} <= set(blocks)
    # the verdicts are the data's: the minimum-error member's ratio to RATTLE at h/2, goal by goal
    found = splitting.compare("villin_2fs.json")
    assert found is not None and f"| {found['energy']:.2f} (≥ 3: **met**) |" in blocks["survey verdicts"]


def test_the_long_runs_and_physics_pages_blocks():
    assert {"cuda long", "cuda cost", "openmm dhfr"} <= set(long_runs.render()[long_runs.PAGE])
    assert stale_blocks(physics.render(), sources.ROOT) == []
    for name, text in physics.render()[physics.PAGE].items():
        if name.endswith("provenance"):
            named = {a or b for a, b in NAMED.findall(text)}
            assert named and named <= set(sources.data_files()), name
            assert all(sources.source(path).date in text for path in named), name


def test_the_accuracy_pages_name_each_systems_data_and_its_day():
    """Each system's header block on accuracy.md and compositions.md links its data file and gives its day."""
    files = set(sources.data_files())
    for page, blocks in accuracy.render().items():
        headers = {name: text for name, text in blocks.items() if name.endswith("header")}
        assert headers, page.name
        for name, text in headers.items():
            (path,) = {a or b for a, b in NAMED.findall(text)}
            assert path in files and sources.source(path).date in text, f"{page.name}: {name}"
