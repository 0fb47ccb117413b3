"""docs/smooth_forces.md's measured blocks: PME's tolerance against cost and energy, and the diagnosis.

Part of ``python -m tools.reports.guide``. The PME-tolerance run is
``docs/data/smooth_forces/pme_tolerance.json`` (tip3p-3nm; villin's cost alone beside it),
made by ``tools/scripts/pme_tolerance.py`` on 2026-11-23, when ``alpha4=0`` was the triple
jump; the diagnosis run is an ``alphaprk bench energy`` run of tip3p-2nm.
"""

from __future__ import annotations

from tools.reports.guide_limits import energy4_gain, files, pme, pme_cost_ratio
from tools.reports.markdown import markdown_table
from tools.reports.numbers import tolerance, two, whole_percent
from tools.reports.sources import load

#: 300 steps of tip3p-2nm with both energy modes (CPU, from the shipped start): the diagnosis.
DIAGNOSIS = "smooth_forces/energy_tip3p-2nm_300.json"
#: The integrators of the PME run as the table names them (order 4 was the triple jump that day).
THEN = {"rattle": "`rattle`", "energy4": "`energy4` †", "alpha4=0": "`alpha4=0` †"}


def pme_table(runs: dict) -> str:
    """Render the table of RMS(H − E_ref), evaluations and cost per tolerance and integrator."""
    water, _ = runs["sources"]
    rows = runs["rows"]
    tightest = min(rows)
    lines = []
    for tol in sorted(rows, reverse=True):
        rattle = rows[tol]["rattle"]
        for name, row in rows[tol].items():
            if name == "pme":
                continue
            fallen = row.get("fraction_fallen_back", float("nan"))
            rms, ms = row["rms_residual"], row["ms_per_step"]
            lines.append(
                [
                    tolerance(tol),
                    rows[tol]["pme"],
                    THEN[name],
                    f"{rms:.3g}",
                    f"{rattle['rms_residual'] / rms:.3g}",
                    f"{row['force_evaluations_per_step']:.2f}",
                    "–" if fallen != fallen else whole_percent(fallen),
                    f"{ms:.1f}",
                    f"{ms / rattle['ms_per_step']:.2f}",
                    f"{ms / rows[tightest][name]['ms_per_step']:.2f}",
                ]
            )
    rounds = {len(row["ms_per_step_rounds"]) for tol in rows for n, row in rows[tol].items() if n != "pme"}
    load_text = " / ".join(f"{v:.1f}" for v in runs["load"])
    caption = (
        f"{runs['steps']} steps of 2 fs per row from the shipped {runs['system']} start, CPU platform, on "
        f"{water.date} on {water.machine} (load average {load_text} at its start); ms/step: the fastest of "
        f"{rounds.pop()} interleaved rounds (every round is in the JSON). † On that day the order-4 "
        "composition was the triple jump: `alpha4=0` is what is now `alpha4=0:triple-jump`, and `energy4` "
        f"the energy mode of that day on it. Data: {files([water])}."
    )
    header = [
        "Ewald tolerance",
        "PME",
        "integrator",
        "RMS(H − E_ref) kJ/mol",
        "RATTLE's RMS / this",
        "evaluations/step",
        "fallen back",
        "ms/step",
        "time / RATTLE's",
        f"time / at {tolerance(tightest)}",
    ]
    return caption + "\n\n" + markdown_table(header, lines)


def pme_reading(runs: dict) -> str:
    """Render the bullets that read the table (RATTLE, the triple jump, the energy mode, the cost)."""
    rows = runs["rows"]
    tols = sorted(rows)
    loosest, tightest = tols[-1], tols[0]
    tight_rattle = [rows[t]["rattle"]["rms_residual"] for t in tols[:-1]]
    alpha_gain = {t: rows[t]["rattle"]["rms_residual"] / rows[t]["alpha4=0"]["rms_residual"] for t in tols}
    energy = {t: rows[t]["energy4"] for t in tols}
    villin = runs["villin"]
    villin_source = runs["sources"][1]
    energy_ms = [row["ms_per_step"] for row in energy.values()]
    looser = ", ".join(f"{two(alpha_gain[t])}× at {tolerance(t)}" for t in tols[1:])
    energy_looser = ", ".join(f"{two(energy4_gain(runs, t))}× at {tolerance(t)}" for t in tols[1:-1])
    return "\n".join(
        [
            f"- **RATTLE** does not care below {tolerance(tols[-2])} (RMS {min(tight_rattle):.3g}–"
            f"{max(tight_rattle):.3g} kJ/mol): its own O(h²) error dominates. At {tolerance(loosest)} the "
            "PME "
            f"error raises it to {rows[loosest]['rattle']['rms_residual']:.3g}.",
            f"- **The triple jump** (`alpha4=0` †, fourth order, its error {two(alpha_gain[tightest])}× "
            "below "
            f"RATTLE's at {tolerance(tightest)}) is limited by PME: its gain over RATTLE falls to {looser}.",
            f"- **The energy mode** (`energy4` †) loses most: {two(energy4_gain(runs, tightest))}× below "
            "RATTLE "
            f"at {tolerance(tightest)}, {energy_looser}, and at {tolerance(loosest)} it is *worse* than "
            "RATTLE "
            f"({two(energy4_gain(runs, loosest))}×) while falling back on "
            f"{whole_percent(energy[loosest]['fraction_fallen_back'])} of the steps at "
            f"{energy[loosest]['force_evaluations_per_step']:.1f} evaluations each: it steers by an energy "
            "whose "
            "PME error it cannot follow. Its RMS varies between runs (CPU force sums are not bitwise "
            "reproducible and the controller amplifies that). These numbers are for the energy mode of "
            f"{runs['sources'][0].date}; RATTLE's and the triple jump's do not depend on it.",
            f"- **Cost**: {tolerance(tightest)} costs {pme_cost_ratio(runs, tightest, loosest):.2f}× a "
            f"{tolerance(loosest)} RATTLE step on this box, {pme_cost_ratio(runs, tightest, tols[-2]):.2f}× "
            "a "
            f"{tolerance(tols[-2])} step and {pme_cost_ratio(runs, tightest, tols[1]):.2f}× a "
            f"{tolerance(tols[1])} step. On villin in water (a larger box: `python "
            "tools/scripts/pme_tolerance.py --system villin --integrators rattle --cost-only`, "
            f"{villin_source.date}, [its JSON](data/smooth_forces/pme_tolerance_villin_cost.json)) the grid "
            f"grows from {_grid(villin[loosest]['pme'])} to {_grid(villin[tightest]['pme'])} and a RATTLE "
            "step "
            f"from {villin[loosest]['ms']:.1f} to {villin[tightest]['ms']:.1f} ms: {tolerance(tightest)} "
            "costs "
            f"{pme_cost_ratio(runs, tightest, loosest, 'villin'):.2f}× a {tolerance(loosest)} step, "
            f"{pme_cost_ratio(runs, tightest, tols[1], 'villin'):.2f}× a {tolerance(tols[1])} step and "
            f"{pme_cost_ratio(runs, tightest, tols[-2], 'villin'):.2f}× a {tolerance(tols[-2])} step. The "
            f"energy mode's time per step hardly changes with the tolerance on the water box "
            f"({min(energy_ms):.0f}–{max(energy_ms):.0f} ms), because it needs more evaluations per step the "
            f"looser the tolerance ({energy[tightest]['force_evaluations_per_step']:.1f} at "
            f"{tolerance(tightest)}, {energy[loosest]['force_evaluations_per_step']:.1f} at "
            f"{tolerance(loosest)}).",
            "- The timings come from a machine shared with other jobs (the load average is in the JSON): "
            "each is the fastest of the interleaved rounds; read the ratios as ±20 %.",
        ]
    )


def _grid(pme_text: str) -> str:
    """``alpha 2.920/nm, grid 44x41x35`` → ``44×41×35``."""
    return pme_text.split("grid ")[1].replace("x", "×")


def pme_default(runs: dict) -> str:
    """Render the paragraph on the default tolerance and when a looser one pays."""
    rows = runs["rows"]
    tols = sorted(rows)
    tightest, second = tols[0], tols[1]
    third = tols[2]
    saves_water = 1 - pme_cost_ratio(runs, second, tightest)
    saves_villin = 1 - 1 / pme_cost_ratio(runs, tightest, second, "villin")
    energy_factor = rows[second]["energy4"]["rms_residual"] / rows[tightest]["energy4"]["rms_residual"]
    alpha_factor = rows[second]["alpha4=0"]["rms_residual"] / rows[tightest]["alpha4=0"]["rms_residual"]
    return (
        f"**Default: {tolerance(tightest)}** (`make_smooth`, `prepare_for_nve`, `build_water_box` and the "
        f"`systems/` definitions). No looser tolerance keeps the energy mode's gain: {tolerance(second)} "
        "saves "
        f"{whole_percent(saves_water)} of a RATTLE step on the 3 nm box ({whole_percent(saves_villin)} on "
        "villin) and costs a factor "
        f"of {two(energy_factor)} in `energy4`'s RMS and {two(alpha_factor)} in the triple jump's (the run "
        "of "
        f"{runs['sources'][0].date} above). The "
        "tradeoff is worth taking only where just RATTLE's (or Verlet's) energy is compared: there "
        f"{tolerance(third)} gives the same RMS at {1 / pme_cost_ratio(runs, tightest, third):.2f}× the time "
        "on "
        f"the water box and {1 / pme_cost_ratio(runs, tightest, third, 'villin'):.2f}× on villin "
        f"(`prepare_for_nve(system, ewald_error_tolerance={tolerance(third)})`; the energy mode then warns, "
        "since it is not smooth enough for it)."
    )


def diagnosis() -> str:
    """Render the sentence on how many steps end outside the tolerance with smooth forces."""
    data, source = load(DIAGNOSIS)
    (system,) = data
    rows = {row["name"]: row for row in data[system]["rows"]}
    order4, order2 = rows["α-RATTLE-4 energy mode"], rows["α-RATTLE energy mode"]
    steps = order4["steps"]
    return (
        f"Measured on {system} (CPU platform, smooth forces, {steps} steps of 2 fs from the shipped start, "
        f"`alphaprk bench energy`, on {source.date} on {source.machine}): "
        f"{whole_percent(1 - order4['fraction_within_tolerance'])} of `energy4`'s steps end outside the "
        "tolerance; the "
        "second-order energy mode is not diagnosed this way: with smooth forces it already ends "
        f"{whole_percent(1 - order2['fraction_within_tolerance'])} of its steps outside it. Data: "
        f"{files([source])}."
    )


def blocks() -> dict[str, str]:
    """Every generated block of docs/smooth_forces.md, by name."""
    runs = pme()
    return {
        "pme tolerance table": pme_table(runs),
        "pme tolerance reading": pme_reading(runs),
        "pme tolerance default": pme_default(runs),
        "diagnosis": diagnosis(),
    }
