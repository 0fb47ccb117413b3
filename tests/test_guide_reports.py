"""tools.reports.guide's generators: what each block names as its data, how the numbers are written."""

from __future__ import annotations

import re

import pytest

from tools.reports import guide, guide_limits, guide_platforms, long_runs, sources, splitting
from tools.reports.numbers import percent, tolerance, two, whole_percent

#: A data file a block names: `docs/data/PATH` or a link (data/PATH) from a page of docs/.
NAMED = re.compile(r"`docs/data/([^`]+)`|\]\(data/([^)#]+)\)")
#: Blocks that read the run of the block above them on their page ("the run of DAY above").
FOLLOWS = {
    "pme tolerance default": "pme tolerance table",
    "peptide hmr 4fs reading": "peptide hmr 4fs",
    "cuda energy mode": "cuda long",
    "cpu energy mode": "cpu long",
    "survey verdicts": "survey tip3p-2nm 2 fs",
    "per picosecond": "survey tip3p-2nm 4 fs",
}


def test_every_generated_block_names_its_data_and_each_file_has_provenance():
    """A block says which files its numbers come from; each is a data file with its day and machine."""
    files = set(sources.data_files())
    for page, blocks in {**guide.render(), **long_runs.render(), **splitting.render()}.items():
        for name, text in blocks.items():
            named = {a or b for a, b in NAMED.findall(text)}
            where = f"{page.name}: {name}"
            if name in FOLLOWS:  # the run of the block above it, which names the data
                assert FOLLOWS[name] in blocks, where
                continue
            assert named, f"{where} names no data file"
            assert named <= files, f"{where} names {named - files}"
            for path in named:
                entry = sources.source(path)
                assert entry.date in text or entry.date in _all(blocks), f"{where}: {path}'s day is not given"


def _all(blocks: dict[str, str]) -> str:
    return "\n".join(blocks.values())


@pytest.mark.parametrize(
    ("log", "counts"),
    [
        (guide_platforms.LOG_COMMON, {"passed": 26, "deselected": 1}),
        (guide_platforms.LOG_COMPOSITIONS, {"failed": 2, "passed": 53, "skipped": 1}),
        (guide_platforms.LOG_COMPOSITIONS_FIXED, {"passed": 4, "deselected": 39}),
    ],
)
def test_the_test_counts_are_read_from_pytests_summary_line(log, counts):
    assert guide_platforms.pytest_counts(log) == counts


def test_the_order_2_limits_are_the_research_records_runs():
    """87 % / 99.8 % fallbacks, villin 1.5× above RATTLE, two trials 5.6–8.1 evaluations and 3.8× above."""
    o2 = guide_limits.order2()
    text = guide_limits.integrators_order2(o2)
    assert "87 %" in text and "99.8 %" in text and "1.5× *above*" in text
    assert "5.6–8.1 evaluations" in text and "3.8× above" in text
    assert o2["steps"] == 500 and o2["budget_steps"] == {"tip3p-2nm": 1000, "villin": 300}


def test_the_pme_table_names_the_integrators_of_its_day():
    """The run of 2026-11-23 took alpha4=0 (3 evaluations) as the triple jump: the table says so."""
    table = guide.render()[guide.DOCS / "smooth_forces.md"]["pme tolerance table"]
    assert "`alpha4=0` †" in table and "alpha4=0:triple-jump" in table
    assert "| 5e-4 |" in table and "| 1e-5 |" in table


def test_numbers_are_written_as_the_pages_write_them():
    assert [two(v) for v in (91.7, 7.98, 0.802, 0.003, 1.55)] == ["92", "8.0", "0.80", "0.0030", "1.6"]
    assert [tolerance(v) for v in (5e-4, 1e-5, 5e-5)] == ["5e-4", "1e-5", "5e-5"]
    assert (percent(0.87), percent(0.998), whole_percent(0.9925)) == ("87 %", "99.8 %", "99 %")


def test_the_splitting_page_is_what_its_data_renders():
    """docs/splitting.md's blocks are ``python -m tools.reports.splitting``'s (run it after new surveys)."""
    assert splitting.differences() == []
    blocks = splitting.render()[splitting.PAGE]
    assert {"survey tip3p-2nm 2 fs", "survey villin 2 fs", "survey verdicts"} <= set(blocks)
    # the verdicts are the data's: the minimum-error member's ratio to RATTLE at h/2, goal by goal
    found = splitting.compare("villin_2fs.json")
    assert found is not None and f"{found.energy:.2f}× below RATTLE at h/2" in blocks["survey verdicts"]


def test_the_long_runs_page_is_what_its_data_renders():
    """docs/long_runs.md's blocks are ``python -m tools.reports.long_runs``'s (run it after new runs)."""
    assert long_runs.differences() == []
    assert {"cuda long", "cuda cost", "openmm dhfr"} <= set(long_runs.render()[long_runs.PAGE])


def test_the_physics_page_is_what_its_data_renders():
    """docs/physics.md's blocks are ``python -m tools.reports.physics``'s; its provenance names the data."""
    from tools.reports import physics

    assert physics.differences() == []
    blocks = physics.render()[physics.PAGE]
    for name, text in blocks.items():
        if name.endswith("provenance"):
            named = {a or b for a, b in NAMED.findall(text)}
            assert named and named <= set(sources.data_files()), name
            assert all(sources.source(path).date in text for path in named), name
