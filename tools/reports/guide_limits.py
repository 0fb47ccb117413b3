"""The measured numbers of the user guide's "Limits": order 2's energy mode, PME's tolerance, the triple jump.

Part of ``python -m tools.reports.guide`` (which writes and checks every generated block):
the blocks of ``docs/integrators.md`` and ``docs/energy_mode.md`` rendered here take their
numbers from the research record's data (the order-2 energy mode, measured 2026-11-23 and
2026-11-26 with the controller of its day), from ``docs/data/smooth_forces/`` (the PME
tolerance) and from the MD benchmark's step scan (``docs/data/benchmarks/``), each with its
run's length, platform, machine and day.
"""

from __future__ import annotations

from tools.reports.numbers import percent, tolerance, two
from tools.reports.sources import Source, load

#: The energy benchmark of both systems at order 2 and 4 (CPU, 500 steps of 2 fs each).
ORDER2_SYSTEMS = "research/controller_robustness/energy_benchmark_systems.json"
#: The order-2 energy mode with its trials capped at 1, 2, 3 (CPU, 2 fs).
ORDER2_BUDGET = {
    "tip3p-2nm": "research/one_trial_per_step/order2_trial_budget_tip3p-2nm.json",
    "villin": "research/one_trial_per_step/order2_trial_budget_villin.json",
}
#: RMS(H − E_ref) and cost against PME's Ewald tolerance (tip3p-3nm), and the cost alone on villin.
PME = "smooth_forces/pme_tolerance.json"
PME_VILLIN = "smooth_forces/pme_tolerance_villin_cost.json"
#: The MD benchmark (its step-size scan).
MD_BENCHMARK = "benchmarks/benchmarks.json"

ORDER2 = "α-RATTLE energy"
RATTLE = "RATTLE"


def files(sources: list[Source]) -> str:
    """Name the data files of a block, with the commit each was added at."""
    return ", ".join(f"`docs/data/{s.path}` (commit {s.commit})" for s in sources)


# ------------------------------------------------------------------ order 2
def _row(rows: list[dict], name: str) -> dict:
    (row,) = [row for row in rows if row["name"] == name]
    return row


def order2() -> dict:
    """Return what the order-2 energy mode did: fallbacks, RMS against RATTLE, and at a budget of trials."""
    systems, systems_source = load(ORDER2_SYSTEMS)
    water, villin = (systems[name]["rows"] for name in ("tip3p-3nm", "villin"))
    budget, budget_sources = {}, []
    for system, path in ORDER2_BUDGET.items():
        data, source = load(path)
        budget[system] = data
        budget_sources.append(source)
    two = [budget[s]["max_trials=2"] for s in ORDER2_BUDGET]
    return {
        "fell_back_water": _row(water, ORDER2)["fraction_fallen_back"],
        "fell_back_villin": _row(villin, ORDER2)["fraction_fallen_back"],
        "villin_rms": _row(villin, ORDER2)["rms_residual"],
        "villin_rattle_rms": _row(villin, RATTLE)["rms_residual"],
        "steps": {_row(rows, RATTLE)["steps"] for rows in (water, villin)}.pop(),
        "two_trials_evaluations": [row["force_evaluations_per_step"] for row in two],
        "two_trials_villin_above": budget["villin"]["max_trials=2"]["rms"]
        / budget["villin"]["rattle"]["rms"],
        "budget_steps": {s: int(budget[s]["max_trials=2"]["totals"]["steps"]) for s in ORDER2_BUDGET},
        "systems_source": systems_source,
        "budget_sources": budget_sources,
    }


def _order2_measured(o2: dict) -> str:
    """Write the fallbacks and villin's RMS, with the run they come from."""
    s = o2["systems_source"]
    return (
        f"sits at its bounds on most steps ({percent(o2['fell_back_water'])} of steps fell back on the 3 nm "
        f"water box, {percent(o2['fell_back_villin'])} on villin), so a run is a random sequence of "
        "different "
        f"symplectic maps; on villin it ended {two(o2['villin_rms'] / o2['villin_rattle_rms'])}× *above* "
        f"RATTLE's RMS error ({o2['villin_rms']:.3g} against {o2['villin_rattle_rms']:.3g} kJ/mol; "
        f"`alphaprk bench energy`, CPU platform, {o2['steps']} steps of 2 fs from each system's start, on "
        f"{s.date} on {s.machine}, the controller of that day: "
        "[controller "
        "robustness](research/controller_robustness.md#why-one-α-at-order-2-cannot-hold-the-energy); "
        f"data: {files([s])})"
    )


def integrators_order2(o2: dict) -> str:
    """Render docs/integrators.md's Limits bullet on the second-order energy mode."""
    evaluations = sorted(o2["two_trials_evaluations"])
    budget = o2["budget_sources"]
    steps = o2["budget_steps"]
    return (
        "- The second-order energy mode cannot hold the energy: α* is O(1) at order 2 and "
        + _order2_measured(o2)
        + ". Its dead-controller failure (a running slope scale blown up, after which H drifted; "
        "[controller robustness](research/controller_robustness.md), 2026-11-23) is fixed and tested. "
        "At ≤ 4 force evaluations per step it is RATTLE: one trial per step never moves α "
        "(`max_trials=1` is refused at both orders), and two trials cost "
        f"{two(evaluations[0])}–{two(evaluations[-1])} evaluations and were "
        f"{two(o2['two_trials_villin_above'])}× above RATTLE's RMS error on villin (CPU platform, 2 fs, "
        f"{steps['tip3p-2nm']:,} steps of tip3p-2nm and {steps['villin']:,} of villin from the shipped "
        f"starts, on {budget[0].date} on {budget[0].machine}: "
        "[order 2 at a budget](research/one_trial_per_step.md#order-2-at-a-budget-of-4-evaluations); "
        f"data: {files(budget)}). Do not use `order=2` for energy; watch `AlphaControllerReporter`'s "
        "H − E_ref column in any energy-mode run."
    )


def energy_mode_order2(o2: dict) -> str:
    """Render docs/energy_mode.md's Limits bullet on the second-order energy mode."""
    return (
        "- **Order 2 cannot hold the energy.** α* is O(1) at order 2 and "
        + _order2_measured(o2)
        + ". Do not use `order=2` for energy."
    )


# ------------------------------------------------------------------ PME's tolerance
def pme() -> dict:
    """Return the PME-tolerance runs: rows by tolerance and integrator, villin's RATTLE cost, sources."""
    data, source = load(PME)
    villin, villin_source = load(PME_VILLIN)
    by_tolerance = {
        float(key): {row["integrator"]: row for row in value["rows"]} | {"pme": value["pme"]}
        for key, value in data.items()
        if isinstance(value, dict)
    }
    villin_cost = {
        float(key): {"ms": value["rows"][0]["ms_per_step"], "pme": value["pme"]}
        for key, value in villin.items()
        if isinstance(value, dict)
    }
    return {
        "rows": by_tolerance,
        "villin": villin_cost,
        "steps": data["steps"],
        "system": data["system"],
        "load": data["load"],
        "sources": [source, villin_source],
    }


def pme_cost_ratio(runs: dict, tight: float, loose: float, system: str = "water") -> float:
    """How many times a RATTLE step at ``tight`` costs one at ``loose`` (the fastest rounds)."""
    if system == "villin":
        return runs["villin"][tight]["ms"] / runs["villin"][loose]["ms"]
    rows = runs["rows"]
    return rows[tight]["rattle"]["ms_per_step"] / rows[loose]["rattle"]["ms_per_step"]


def energy4_gain(runs: dict, tolerance: float) -> float:
    """RATTLE's RMS(H − E_ref) over energy4's at ``tolerance``."""
    rows = runs["rows"][tolerance]
    return rows["rattle"]["rms_residual"] / rows["energy4"]["rms_residual"]


def gains_text(runs: dict, name: str = "energy4") -> str:
    """RATTLE's RMS over ``name``'s at each tolerance, tightest first: ``92× at 1e-5, ...``."""
    parts = []
    for tol in sorted(runs["rows"]):
        rows = runs["rows"][tol]
        gain = rows["rattle"]["rms_residual"] / rows[name]["rms_residual"]
        parts.append(f"{two(gain)}× at {tolerance(tol)}")
    return ", ".join(parts)


def pme_run_caption(runs: dict) -> str:
    """Which run the PME numbers are from."""
    water, villin = runs["sources"]
    return (
        f"`tools/scripts/pme_tolerance.py`, CPU platform, {runs['steps']} steps of 2 fs per row from the "
        f"shipped {runs['system']} start, on {water.date} on {water.machine}, the energy mode of that day; "
        f"villin: RATTLE's cost alone, {villin.date}"
    )


def integrators_pme(runs: dict) -> str:
    """Render docs/integrators.md's Limits bullet on what PME's tolerance costs and buys."""
    return (
        f"- What the tolerance costs and buys ({pme_run_caption(runs)}): 1e-5 costs "
        f"{pme_cost_ratio(runs, 1e-5, 5e-4):.2f}× a RATTLE step at OpenMM's 5e-4 on the 3 nm water box and "
        f"{pme_cost_ratio(runs, 1e-5, 5e-4, 'villin'):.2f}× on villin, but looser tolerances cost most of "
        f"the energy mode's gain (`energy4`'s RMS(H − E_ref) below RATTLE's {gains_text(runs)}; one run: "
        "[smooth forces](smooth_forces.md#how-tight-a-pme-tolerance-measured)). "
        f"Data: {files(runs['sources'])}."
    )


# ------------------------------------------------------------------ the triple jump's step
def step_scan() -> dict:
    """Return the MD benchmark's step scan on tip3p-2nm: the triple jump (then ``alpha4=0``), RATTLE."""
    data, source = load(MD_BENCHMARK)
    scan = data["scan"]["tip3p-2nm"]
    triple = scan["alpha4=0"]
    failed = sorted(
        float(step) for step, run in triple.items() if isinstance(run, dict) and not run["stable"]
    )
    lengths = {
        run["simulated_ps"] for run in triple.values() if isinstance(run, dict) and "simulated_ps" in run
    }
    return {
        "triple_largest": triple["largest_stable_fs"],
        "triple_failed": failed[0],
        "rattle_largest": scan["rattle"]["largest_stable_fs"],
        "scan_ps": min(lengths),
        "platform": data["environment"]["platform"],
        "source": source,
    }


def integrators_triple_jump(scan: dict) -> str:
    """Render docs/integrators.md's Limits bullet on the triple jump's largest step."""
    s = scan["source"]
    return (
        '- The triple jump (`composition="triple-jump"`) takes sub-steps of 1.35h and −1.70h: on water it '
        f"blows up at a smaller step than RATTLE. In the MD benchmark's step scan (tip3p-2nm, "
        f"{scan['platform']} platform, at least {scan['scan_ps']:g} ps per step size from the shipped start, "
        "on "
        f"{s.date} on {s.machine}, when the triple jump was `alpha4=0`) it ran at "
        f"{scan['triple_largest']:g} fs and blew up at {scan['triple_failed']:g} fs, where RATTLE ran at "
        f"{scan['rattle_largest']:g} fs ([benchmarks](benchmarks.md#largest-stable-step); data: "
        f"{files([s])}); "
        "Suzuki's composition, whose sub-steps are below h, runs as far as RATTLE "
        "([compositions](compositions.md#the-named-compositions))."
    )
