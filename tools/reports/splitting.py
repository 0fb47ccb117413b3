"""docs/splitting.md's generated blocks from docs/data/splitting/ (written by tools/scripts)."""

from __future__ import annotations

import re
from pathlib import Path

from openmm_alphaprk.runs.integrator_names import label
from tools.reports.long_runs import long_table
from tools.reports.markdown import Column, markdown_table, table
from tools.reports.numbers import sig, times, tolerance
from tools.reports.sources import DOCS, load, provenance_line

PAGE = DOCS / "splitting.md"
FOLDER = "splitting/"

#: The systems as the page names them.
SYSTEMS = {
    "tip3p-2nm": "tip3p-2nm (rigid TIP3P, 774 atoms, PME)",
    "tip3p-3nm": "tip3p-3nm (rigid TIP3P, 2,661 atoms, PME)",
    "villin": "villin (8,867 atoms, Amber14, HBonds, PME)",
    "dhfr": "dhfr (23,558 atoms, amber99sb, HBonds, PME)",
}

#: A survey row that is no name of the registry: Suzuki's composition of the minimum-error splitting.
COMPOSED = {"me2 x suzuki5": "Suzuki's composition of `split-me` (`composed(me2, SUZUKI5)`) at h"}


def _named(name: str) -> str:
    """Name an integrator as the page does: the registry's label and the name (``rattle``: RATTLE)."""
    return "RATTLE (`rattle`)" if name == "rattle" else f"{label(name)} (`{name}`)"


#: The surveys on the page, in its order: (block name, data file).
SURVEYS = (
    ("survey tip3p-2nm 2 fs", "tip3p-2nm_2fs.json"),
    ("survey tip3p-3nm 2 fs", "tip3p-3nm_2fs.json"),
    ("survey villin 2 fs", "villin_2fs.json"),
    ("survey villin 2 fs second", "villin_2fs_second.json"),
    ("survey dhfr 2 fs", "dhfr_2fs.json"),
    ("survey tip3p-2nm 2 fs order 4", "tip3p-2nm_2fs_order4.json"),
    ("energy mode tip3p-2nm", "energy_mode_tip3p-2nm_2fs.json"),
    ("energy mode villin", "energy_mode_villin_2fs.json"),
    ("survey tip3p-2nm 4 fs", "tip3p-2nm_4fs.json"),
    ("survey villin 4 fs", "villin_4fs_hmr3.json"),
    ("survey dhfr 4 fs", "dhfr_4fs_hmr3.json"),
)

#: Goals set for the family: energy error below RATTLE at h/2's by this factor (2 fs; 4 fs with
#: hydrogens of 3 amu), position error at most this multiple of RATTLE at h/2's, the rescaled
#: member's RMS at most this fraction of RATTLE's.
ENERGY_GOAL = {2.0: 3.0, 4.0: 2.5}
#: The systems each step's energy goal was set for (the others are shown without a verdict).
GOAL_SYSTEMS = {2.0: ("tip3p-2nm", "villin"), 4.0: ("villin", "dhfr")}
POSITION_GOAL = 1.2
RESCALED_GOAL = 1e-3


def _rows(data: dict) -> dict[str, dict]:
    """Return a survey's rows by label."""
    return {row["row"]: row for row in data["rows"]}


def _title(data: dict, path: str = "") -> str:
    """Return a survey's title in bold: the system, the step, the hydrogens' mass and how they were set."""
    name = SYSTEMS.get(data["system"], data["system"])
    title = f"**{name}, {data['timestep_fs']:g} fs"
    if path.endswith("_second.json"):
        title += " (the second run)"
    if data.get("hydrogen_mass_amu"):
        again = "-h" in data.get("start", "")
        how = "start equilibrated with them" if again else "repartitioned in the start, not re-equilibrated"
        title += f", hydrogens {data['hydrogen_mass_amu']:g} amu ({how})"
    return title + "**"


def _label(row: str) -> str:
    """Return how the page names a row of a survey or of the energy-mode measurement."""
    if row in COMPOSED:
        return COMPOSED[row]
    if row.startswith("RATTLE at h"):
        return row
    energy = re.fullmatch(r"split-energy tol ([0-9.e+-]+), <= (\d+) trials", row)
    if energy:
        return f"energy mode, tol {tolerance(float(energy.group(1)))}·\\|E_ref\\|, ≤ {energy.group(2)} trials"
    named = re.fullmatch(r"([a-z0-9+=/-]+)( at h/\d+)?", row)
    if named and named.group(2):
        base = "RATTLE" if named.group(1) == "rattle" else f"`{named.group(1)}`"
        return base + named.group(2)
    return _named(row)


def survey_table(path: str) -> str:
    """Render one survey: evaluations per step, RMS(H − E_ref), position errors at the horizons, per row."""
    data, source = load(FOLDER + path)

    def errors(row: dict) -> str:
        text = " / ".join(sig(e) for e in row["position_rms"])
        return text + (f" (blew up at step {row['blew_up_at_step']})" if row.get("blew_up_at_step") else "")

    columns = [
        Column("row", lambda r: _label(r["row"])),
        Column("evaluations / step", "{evaluations:g}"),
        Column("RMS(H − E_ref) kJ/mol", lambda r: sig(r["rms_residual"], 3)),
        Column(f"position error nm after {' / '.join(str(h) for h in data['horizons'])} steps", errors),
    ]
    run = (
        f"{_title(data, path)} — {data['steps']} steps from the start `{data.get('start', data['system'])}`, "
        f"reference {data['reference'].split(',')[0]}"
    )
    return table(data["rows"], columns, provenance_line([source], run))


def compare(path: str) -> dict | None:
    """Return `split-me` against RATTLE at h/2 in the survey ``path`` (None without both rows).

    Its ``energy`` and ``positions``: RATTLE at h/2's errors over the member's (above 1: the
    member better); ``rescaled_rms`` and ``rescaled_fraction``: `split-me+rescale`'s RMS(H − E_ref)
    and that over RATTLE's at h (None without those rows).
    """
    data, _ = load(FOLDER + path)
    rows = _rows(data)
    me, half = rows.get("split-me"), rows.get("RATTLE at h/2")
    if me is None or half is None:
        return None
    rescaled, rattle = rows.get("split-me+rescale"), rows.get("RATTLE at h")
    return {
        "data": data,
        "energy": half["rms_residual"] / me["rms_residual"],
        "positions": [a / b for a, b in zip(me["position_rms"], half["position_rms"])],
        "rescaled_rms": None if rescaled is None else rescaled["rms_residual"],
        "rescaled_fraction": None
        if rescaled is None or rattle is None
        else rescaled["rms_residual"] / rattle["rms_residual"],
    }


def _verdict(met: bool) -> str:
    return f" **{'met' if met else 'missed'}**"


def survey_verdicts() -> str:
    """Render the table of each survey's minimum-error member against RATTLE at h/2, with its goals."""
    rows = []
    for _, path in SURVEYS:
        if (found := compare(path)) is not None:
            h = found["data"]["timestep_fs"]
            goal = ENERGY_GOAL.get(h) if found["data"]["system"] in GOAL_SYSTEMS.get(h, ()) else None
            rows.append({**found, "path": path, "goal": goal})

    def energy(r: dict) -> str:
        goal = r["goal"]
        return f"{r['energy']:.2f}" + (
            "" if goal is None else f" (≥ {goal:g}:{_verdict(r['energy'] >= goal)})"
        )

    def rescaled(r: dict) -> str:
        if r["rescaled_fraction"] is None:
            return "–"
        verdict = _verdict(r["rescaled_fraction"] <= RESCALED_GOAL)
        return f"{sig(r['rescaled_rms'])}, {sig(r['rescaled_fraction'])}{verdict}"

    columns = [
        Column("survey", lambda r: _title(r["data"], r["path"]).replace("**", "")),
        Column("`split-me`: × below RATTLE at h/2 in RMS(H − E_ref)", energy),
        Column(
            f"position error / RATTLE at h/2's (≤ {POSITION_GOAL:g})",
            lambda r: (
                " / ".join(f"{v:.2f}" for v in r["positions"])
                + _verdict(max(r["positions"]) <= POSITION_GOAL)
            ),
        ),
        Column(f"`split-me+rescale` RMS kJ/mol, and / RATTLE's (≤ {RESCALED_GOAL:g})", rescaled),
    ]
    return table(rows, columns)


def per_picosecond() -> str:
    """Render `split-me` at 4 fs (hydrogens 3 amu) against RATTLE at 2 fs (1 amu): equal cost per ps."""
    rows = []
    for system in ("tip3p-2nm", "villin", "dhfr"):
        four = next(p for _, p in SURVEYS if p.startswith(f"{system}_4fs"))
        me = _rows(load(FOLDER + four)[0])["split-me"]
        rattle = _rows(load(FOLDER + f"{system}_2fs.json")[0])["RATTLE at h"]
        rows.append((system, me["rms_residual"], rattle["rms_residual"]))
    columns = [
        Column("system", lambda r: r[0]),
        Column("`split-me` at 4 fs, kJ/mol", lambda r: sig(r[1], 3)),
        Column("RATTLE at 2 fs (1 amu), kJ/mol", lambda r: sig(r[2], 3)),
        Column(
            "RATTLE's / `split-me`'s",
            lambda r: f"{times(r[2] / r[1])} **{'met' if r[2] > r[1] else 'missed'}**",
        ),
    ]
    return table(rows, columns)


#: Surveys run twice from the same start: (the first run's file, the second's).
REPEATED = (
    ("tip3p-2nm_2fs_first.json", "tip3p-2nm_2fs.json"),
    ("tip3p-2nm_4fs_first.json", "tip3p-2nm_4fs.json"),
    ("villin_2fs.json", "villin_2fs_second.json"),
)


def repeats() -> str:
    """Render the surveys run twice: RMS(H − E_ref) of RATTLE at h/2 and of `split-me`, each run."""
    lines = []
    for paths in REPEATED:
        for which, path in zip(("first", "second"), paths):
            data, source = load(FOLDER + path)
            rows = _rows(data)
            half, quarter, me = (rows[r]["rms_residual"] for r in ("RATTLE at h/2", "split=1/4", "split-me"))
            survey = f"{data['system']}, {data['timestep_fs']:g} fs"
            run = f"{which} ({source.date}, commit {source.commit})"
            lines.append(
                [
                    survey,
                    run,
                    *(sig(v, 3) for v in (half, quarter, me)),
                    f"{half / me:.2f}",
                    f"`docs/data/{source.path}`",
                ]
            )
    return markdown_table(
        "survey | run | RATTLE at h/2 kJ/mol | `split=1/4` | `split-me` | ratio | data", lines
    )


#: The stability scans on the page: (block name, data file, how the page names the system).
STABILITY = (
    ("stability tip3p-2nm", "stability_tip3p-2nm.json", "tip3p-2nm (rigid TIP3P, 774 atoms, PME)"),
    (
        "stability villin",
        "stability_villin.json",
        "villin (8,867 atoms, Amber14, HBonds, hydrogens 1 amu, PME)",
    ),
    (
        "stability villin-h3",
        "stability_villin-h3.json",
        "villin-h3 (villin with hydrogens of 3 amu, its own equilibrated start)",
    ),
)


def _first_unstable(row: dict) -> str:
    """Return the first unstable step of a row and how its run ended."""
    failed = [run for run in row["runs"] if not run["stable"]]
    if not failed:
        return "-"
    first = min(failed, key=lambda run: run["h_fs"])
    reason = first["reason"]
    if reason.startswith("blew up"):
        how = "NaN coordinates" if "NaN" in reason else "an OpenMM exception"
    elif reason.startswith("|H"):
        how = f"H over the threshold ({reason.split()[3]} kJ/mol/DOF)"
    else:
        how = reason
    found = re.search(r"at step (\d+)", reason)
    step = found.group(1) if found else first["steps_done"]
    return f"{first['h_fs']:g}: {how} at step {step} of {first['steps']}"


def stability_table(path: str, title: str) -> str:
    """Render one stability scan: largest stable step per row, per evaluation, against RATTLE and theory."""
    data, source = load(FOLDER + path)

    def there(row: dict) -> str:
        runs = [run for run in row["runs"] if run["stable"] and run["h_fs"] == row["largest_stable_fs"]]
        return sig(runs[0]["max_per_dof"]) if runs else "-"

    columns = [
        Column("integrator", lambda r: _named(r["integrator"])),
        Column("evaluations / step", "{evaluations:g}"),
        Column("largest stable h (fs)", "**{largest_stable_fs:g}**"),
        Column("per evaluation h/k (fs)", lambda r: f"{r['largest_stable_fs'] / r['evaluations']:.3g}"),
        Column("× RATTLE's h", "{ratio_to_rattle:.2f}"),
        Column("linear prediction (fs)", "{predicted_fs:.3g}"),
        Column("max \\|H − E_ref\\|/DOF there (kJ/mol)", there),
        Column("the first unstable h (fs)", _first_unstable),
    ]
    run = (
        f"**{title}** ({data['dof']:,} degrees of freedom; T = {data['time_ps']:g} ps, H every "
        f"{data['every']} steps, threshold {data['threshold_kt']:g} kT = "
        f"{data['threshold_kj_per_mol_per_dof']:.3f} kJ/mol per degree of freedom, edge to "
        f"{data['resolution_fs']:g} fs)"
    )
    return table(data["integrators"], columns, provenance_line([source], run))


#: The long runs on the page: (block name, data file of ``alphaprk bench long``).
LONG = (("long 2 fs", "long_tip3p-2nm_2fs.json"), ("long 1 fs", "long_tip3p-2nm_1fs.json"))
#: The step-time measurements on the page: (block name, data file).
COST = (
    ("cost cpu", "cost_cpu_tip3p-2nm.json"),
    ("cost opencl", "cost_opencl_tip3p-2nm.json"),
)


def cost_table(path: str) -> str:
    """Render one ``bench cost`` run: step time against RATTLE's, per force evaluation, ns/day."""
    data, source = load(FOLDER + path)
    columns = [
        Column("integrator", "{name}"),
        Column("evaluations / step", "{force_evaluations_per_step:g}"),
        Column("ms/step", "{ms_per_step:.3g}"),
        Column("× RATTLE's step", "{time_ratio:.2f}"),
        Column("per evaluation", "{ratio_per_evaluation:.2f}"),
        Column("ns/day", "{ns_per_day:.3g}"),
    ]
    precision = data.get("precision") or "the platform's"
    run = (
        f"**{data['system']} ({data['atoms']:,} atoms), {data['timestep_fs']:g} fs, {data['platform']} "
        f"platform, precision {precision}** — `alphaprk bench cost`, every row in one run, rounds "
        "interleaved, with other runs on the machine's two cores"
    )
    return table(data["rows"], columns, provenance_line([source], run))


def render() -> dict[Path, dict[str, str]]:
    """Every generated block of the page, by page and block name."""
    blocks = {name: survey_table(path) for name, path in SURVEYS}
    blocks.update(
        {"survey verdicts": survey_verdicts(), "per picosecond": per_picosecond(), "repeats": repeats()}
    )
    blocks.update({name: cost_table(path) for name, path in COST})
    blocks.update({name: long_table(FOLDER + path, speed=False) for name, path in LONG})
    blocks.update({name: stability_table(path, title) for name, path, title in STABILITY})
    return {PAGE: blocks}
