"""docs/energy_program.md: each variable of the energy mode's programs has a meaning; the page is current.

The meanings are hand-written (tools/reports/energy_globals.py); who writes each variable
and the outlines are read from the programs (tools/reports/energy_program.py). A
variable added to a program without a meaning, a meaning left after its variable went,
or a page not regenerated after the program changed fails here.
"""

import re

import pytest

from openmm_alphaprk.integrators.energy_mode import AlphaRattleEnergyIntegrator
from tools.reports import energy_program, markdown
from tools.reports.energy_globals import MEANINGS, PER_DOF_MEANINGS, PLACEHOLDERS, STAGES

ORDERS = energy_program.ORDERS


@pytest.fixture(scope="module")
def programs():
    return {order: energy_program.record_program(order) for order in ORDERS}


def _matched(variables, meanings):
    rows = energy_program.rows_of(variables, meanings)
    counts = {v: sum(v in names for names in rows.values()) for v in variables}
    return rows, counts


@pytest.mark.parametrize("order", ORDERS)
def test_every_global_has_one_meaning(programs, order):
    meanings = {row: text for stage in MEANINGS.values() for row, text in stage.items()}
    _, counts = _matched(programs[order].globals(), meanings)
    assert not [v for v, n in counts.items() if n == 0], "globals without a meaning in energy_globals.py"
    assert not [v for v, n in counts.items() if n > 1], "globals with more than one meaning"


@pytest.mark.parametrize("order", ORDERS)
def test_every_per_dof_variable_has_a_meaning(programs, order):
    _, counts = _matched(programs[order].per_dof(), PER_DOF_MEANINGS)
    assert [v for v, n in counts.items() if n != 1] == []


def test_no_meaning_is_left_over(programs):
    every = {v for p in programs.values() for v in p.globals()}
    every_dof = {v for p in programs.values() for v in p.per_dof()}
    meanings = {row: text for stage in MEANINGS.values() for row, text in stage.items()}
    rows = energy_program.rows_of(sorted(every), meanings) | energy_program.rows_of(
        sorted(every_dof), PER_DOF_MEANINGS
    )
    assert [row for row, names in rows.items() if not names] == []
    assert list(STAGES) == list(MEANINGS)
    assert all(re.fullmatch(r"<\w+>", p) for p in PLACEHOLDERS)


def test_the_recording_sees_every_computation_and_its_piece(programs):
    for program in programs.values():
        assert len(program.pieces) == program.integrator.getNumComputations()
        assert all(program.pieces)  # every computation was added inside an _add_* or _build_* method
    for helper in energy_program.HELPERS:
        assert callable(getattr(AlphaRattleEnergyIntegrator, helper))


def test_the_python_side_is_read_from_the_source():
    writers = energy_program.python_writers()
    assert writers["reference_set"] == ["`reset_reference_energy()`"]
    assert writers["alpha_min"] == ["setter `alpha_bounds`"]
    assert any(w.startswith("`check_context()`") for w in writers["energy_tolerance"])


def test_the_page_is_what_the_programs_give_now(programs):
    page = energy_program.PAGE
    rendered = energy_program.render_blocks(programs)
    on_page = markdown.page_tables(page)
    assert set(on_page) == set(rendered)
    for name, block in rendered.items():
        assert on_page[name] == block, f"{page.name}, block {name!r}: run python -m tools.reports"


def test_the_pages_prose_names_what_exists(programs):
    """A variable or method the hand-written prose names in backticks is one the programs have."""
    text = energy_program.PAGE.read_text(encoding="utf-8")
    prose = markdown.BLOCK_PATTERN.sub("", text)
    known = {v for p in programs.values() for v in (*p.globals(), *p.per_dof())}
    known |= {"x", "v", "f", "while", *PLACEHOLDERS["<series>"].split("|")}
    known |= set(dir(AlphaRattleEnergyIntegrator))
    named = re.findall(r"`([a-z_][a-z0-9_]*)(?:\(\))?`", prose)
    assert named
    assert [name for name in named if name not in known] == []
