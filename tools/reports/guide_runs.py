"""The measured blocks of docs/own_files.md (the test peptide) and docs/driver.md (the reporter's cost).

Part of ``python -m tools.reports.guide``. ``docs/data/own_files/*.json`` are the
``comparison.json`` files of ``alphaprk compare`` on the test peptide's files;
``docs/data/driver/reporter_cost.json`` is ``tools/scripts/reporter_cost.py --json``.
"""

from __future__ import annotations

from openmm_alphaprk.observables import drift_text
from tools.reports.guide_limits import files
from tools.reports.markdown import markdown_table
from tools.reports.numbers import sig, times, two
from tools.reports.sources import load

AMBER_2FS = "own_files/amber_2fs.json"
CHARMM_2FS = "own_files/charmm_2fs.json"
AMBER_HMR_4FS = "own_files/amber_hmr_4fs.json"
REPORTER_COST = "driver/reporter_cost.json"

#: How the tables name a row of ``alphaprk compare``.
ROW_NAMES = {"rattle": "RATTLE", "rattle4+rescale": "`rattle4+rescale`", "energy4": "`energy4`"}


# ------------------------------------------------------------------ the test peptide
class Comparison:
    """One ``comparison.json``: its rows' summaries, position errors and equal-cost verdicts."""

    def __init__(self, path: str):
        data, self.source = load(path)
        self.data = data
        self.rows = dict(zip(data["runs"], data["summaries"]))
        self.accuracy = data["accuracy"]["rows"]
        self.equal_cost = {entry["integrator"]: entry for entry in data["equal_cost"]}

    @property
    def first(self) -> dict:
        return next(iter(self.rows.values()))

    def rms(self, name: str) -> float:
        return self.rows[name]["rms_residual"]

    def evaluations(self, name: str) -> float:
        """Force evaluations per step of h (k for RATTLE at h/k)."""
        if " h/" in name:
            return float(name.split("/")[1])
        return self.rows[name]["force_evaluations_per_step"]

    def position(self, name: str) -> float:
        return self.accuracy[name]["position_rms"]

    def horizon_fs(self) -> float:
        return {row["time_fs"] for row in self.accuracy.values()}.pop()

    def caption(self) -> str:
        first = self.first
        return (
            f"{first['platform']} platform, {first['timestep_fs']:g} fs, {first['steps']:,} steps "
            f"({first['simulated_ps']:g} ps) per row from the same start, on {self.source.date} on "
            f"{self.source.machine}; position error after {self.horizon_fs():g} fs"
        )


def _name(row: str) -> str:
    if " h/" in row:
        return f"RATTLE at h/{row.split('/')[1]}"
    return ROW_NAMES.get(row, f"`{row}`")


def peptide_table(comparison: Comparison, drift: bool = False) -> str:
    """Render a comparison's table: evaluations, RMS(H − E_ref), (drift,) position error."""
    lines = []
    for name, summary in comparison.rows.items():
        evaluations = comparison.evaluations(name)
        rms = summary["rms_residual"]
        cells = [
            _name(name),
            f"{evaluations:.2f}".rstrip("0").rstrip("."),
            f"{rms:.3g}" if rms >= 1 else sig(rms),
        ]
        if drift:
            cells.append(drift_text(summary["drift_per_dof"], summary["drift_per_dof_standard_error"]))
        cells.append(sig(comparison.position(name)))
        lines.append(cells)
    header = ["row", "evaluations/step", "RMS(H − E_ref) kJ/mol"]
    header += ["drift kJ/mol/ns/DOF"] if drift else []
    header += ["position error (nm)"]
    caption = f"{comparison.caption()}. Data: {files([comparison.source])}."
    return caption + "\n\n" + markdown_table(header, lines)


def _energy_verdict(c: Comparison) -> dict:
    e4 = c.equal_cost["energy4"]
    return {
        "below_rattle": c.rms("rattle") / c.rms("energy4"),
        "equal_cost": e4["gain"],
        "position_above": 1 / e4["position_gain"],
        "k": e4["k"],
        "evaluations": c.evaluations("energy4"),
    }


def peptide_2fs_reading(amber: Comparison, charmm: Comparison) -> str:
    """Render the paragraph that reads the 2 fs tables (AMBER and CHARMM files)."""
    a, c = _energy_verdict(amber), _energy_verdict(charmm)
    r4 = amber.equal_cost["rattle4+rescale"]
    return (
        f"The energy mode holds H to 1/{times(a['below_rattle'])} of RATTLE's error (CHARMM files: "
        f"{sig(charmm.rms('energy4'))} against {charmm.rms('rattle'):.3g}, 1/{times(c['below_rattle'])}, at "
        f"{c['evaluations']:.2f} evaluations), {two(a['equal_cost'])}× (CHARMM: {two(c['equal_cost'])}×) "
        "below "
        f"RATTLE at equal cost — and its position error is {two(a['position_above'])}× (CHARMM: "
        f"{two(c['position_above'])}×) *above* RATTLE's at h/{a['k']}. `rattle4+rescale` is "
        f"{two(r4['position_gain'])}× below RATTLE at h/{r4['k']} in positions with H at round-off: on this "
        f"system too it is the configuration that earns its cost (CHARMM files: {_rows(charmm)}; "
        f"{charmm.caption()}; data: {files([charmm.source])})."
    )


def _rows(c: Comparison) -> str:
    return ", ".join(_name(name) for name in c.rows)


def peptide_hmr_reading(hmr: Comparison) -> str:
    """Render the paragraph that reads the 4 fs table."""
    e = _energy_verdict(hmr)
    r4 = hmr.equal_cost["rattle4+rescale"]
    return (
        f"At {hmr.first['timestep_fs']:g} fs the energy mode holds H to 1/{times(e['below_rattle'])} of "
        f"RATTLE's error but only {two(e['equal_cost'])}× below RATTLE at equal cost, and its position error "
        f"is {two(e['position_above'])}× above RATTLE's at h/{e['k']}; `rattle4+rescale` is "
        f"{two(r4['position_gain'])}× below RATTLE at h/{r4['k']} in positions with H at round-off (the run "
        "of "
        f"{hmr.source.date} above)."
    )


def own_files_blocks() -> dict[str, str]:
    """Every generated block of docs/own_files.md, by name."""
    amber, charmm, hmr = (Comparison(path) for path in (AMBER_2FS, CHARMM_2FS, AMBER_HMR_4FS))
    return {
        "peptide 2fs": peptide_table(amber),
        "peptide 2fs reading": peptide_2fs_reading(amber, charmm),
        "peptide hmr 4fs": peptide_table(hmr, drift=True),
        "peptide hmr 4fs reading": peptide_hmr_reading(hmr),
    }


# ------------------------------------------------------------------ the reporter's cost
def reporter_cost() -> str:
    """Render docs/driver.md's table of what reporting the controller costs, and what it says."""
    data, source = load(REPORTER_COST)
    settings, rows = data["settings"], data["rows"]
    lines = [
        [
            row["integrator"],
            row["reporting"],
            f"{row['steps_per_s']:.1f}",
            f"{row['ratio_to_no_reporter']:.3f}",
            "–" if row["report_us"] is None else two(row["report_us"]),
        ]
        for row in rows
    ]
    spread = max(abs(row["ratio_to_no_reporter"] - 1) for row in rows)
    step_ms = {row["integrator"]: 1000 / row["steps_per_s"] for row in rows if row["report_us"] is None}
    report = {
        row["integrator"]: max(
            r["report_us"] for r in rows if r["integrator"] == row["integrator"] and r["report_us"]
        )
        for row in rows
    }
    threads = f", {settings['threads']} thread" if settings["threads"] else ""
    caption = (
        f"`python tools/scripts/reporter_cost.py --threads {settings['threads']} --rounds "
        f"{settings['rounds']}` "
        f"({settings['platform']} platform{threads}, `{settings['system']}`, {settings['atoms']:,} atoms, "
        f"{settings['timestep_fs']:g} fs; {settings['rounds']} interleaved rounds of "
        f"{settings['energy4_steps']} "
        f"energy4 / {settings['rattle_steps']} RATTLE steps per row, one process; on {source.date} on "
        f"{source.machine}, shared with other jobs: load average {settings['load'][0]:.1f}). Data: "
        f"{files([source])}."
    )
    header = ["integrator", "reporting", "steps/s (median)", "× no reporter", "one report (µs)"]
    table = markdown_table(header, lines).replace(
        "| --- | --- | --- | --- | --- |", "| --- | --- | ---: | ---: | ---: |"
    )
    reading = (
        "On the CPU platform the reporter's cost is below what steps/s can resolve here: the rows differ by "
        "up "
        f"to ±{100 * spread:.0f} % in either direction, which is the load of the shared machine, not the "
        f"reporter. Timed by itself (median of {settings['repeats']:,}), one report — OpenMM's `getState` "
        "and "
        f"the row read and written — takes {two(report['energy4'])} µs, "
        f"{_share(report['energy4'], step_ms['energy4'])} of an energy4 step ({step_ms['energy4']:.0f} ms) "
        "at "
        f"every step; an empty reporter's `getState` alone takes {two(report['rattle'])} µs, "
        f"{_share(report['rattle'], step_ms['rattle'])} of a RATTLE step ({step_ms['rattle']:.1f} ms). The "
        "cost "
        "the default avoids is the GPU's host synchronization per step, which this measurement does not "
        "cover."
    )
    return caption + "\n\n" + table + "\n\n" + reading


def _share(report_us: float, step_ms: float) -> str:
    return f"{report_us / (10 * step_ms):.2g} %"


def driver_blocks() -> dict[str, str]:
    """Every generated block of docs/driver.md, by name."""
    return {"reporter cost": reporter_cost()}
