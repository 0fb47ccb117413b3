"""docs/long_runs.md's generated blocks from docs/data/long_runs/ (part of ``python -m tools.reports``)."""

from __future__ import annotations

from pathlib import Path

from tools.reports.markdown import Column, markdown_table, table
from tools.reports.numbers import sig, times, two
from tools.reports.sources import DOCS, load, pick, provenance_line

PAGE = DOCS / "long_runs.md"
CUDA = "long_runs/cuda_h100/"
SEQUENTIAL = CUDA + "long_sequential_mixed.json"
CONCURRENT = {"mixed": CUDA + "long_concurrent_mixed.json", "single": CUDA + "long_concurrent_single.json"}
COST = {
    "2,661": CUDA + "cost_tip3p-3nm.json",
    "21,384": CUDA + "cost_tip3p-6nm.json",
    "72,279": CUDA + "cost_tip3p-9nm.json",
    "DHFR 23,558": CUDA + "cost_dhfr_2fs.json",
}
OPENMM_DHFR = CUDA + "dhfr_openmm_settings_4fs.json"
OPENMM_DHFR_SCRIPT = "python -m openmm_alphaprk.benchmarks.dhfr_openmm_settings"
#: The same script on the CPU platform, with OpenMM's forces and with the package's smooth ones.
OPENMM_DHFR_CPU = (
    "long_runs/cpu_dhfr_openmm_settings_4fs.json",
    "long_runs/cpu_dhfr_openmm_settings_4fs_smooth.json",
)
CPU = "long_runs/cpu_tip3p-2nm.json"
#: ``bench long`` on villin at 4 fs with hydrogens of 3 amu, CPU platform.
CPU_VILLIN = "long_runs/cpu_villin-h3_4fs.json"
CPU_BEFORE = "long_runs/cpu_tip3p-2nm_energy4_before.json"
#: Goals of the rescaling's cost on CUDA (mixed): step time against RATTLE's, by atoms.
GOALS = {"21,384": 1.35, "72,279": 1.25}


def _drift(row: dict) -> str:
    """Write a row's drift ± its error, in bold where resolved, and at its rescaling steps."""
    drift, error = row["drift_per_dof"], row["drift_per_dof_standard_error"]
    if drift != drift:  # NaN: too few samples
        return "-"
    text = (
        f"**{sig(drift)} ± {sig(error)}**"
        if row["drift_resolved"]
        else f"{sig(drift)} ± {sig(error)} (not resolved)"
    )
    at_rescaling = row.get("drift_at_rescaling_per_dof", float("nan"))
    if at_rescaling == at_rescaling:
        text += (
            f"; at its rescaling steps {sig(at_rescaling)} ± {sig(row['drift_at_rescaling_standard_error'])}"
        )
    return text


def long_table(path: str, speed: bool = True) -> str:
    """Render one ``bench long`` result: length, drift, RMS, max, worst window, speed of each row."""
    data, source = load(path)
    ((_, entry),) = data.items()
    rattle = next((r["ms_per_step"] for r in entry["rows"] if r["integrator"] == "rattle"), None)

    def timed(show):
        return lambda r: "-" if r["ms_per_step"] != r["ms_per_step"] else show(r)

    columns = [
        Column("integrator", lambda r: f"`{r['integrator']}`" + ("" if r["complete"] else " (stopped)")),
        Column("ps", "{simulated_ps:.0f}"),
        Column("drift kJ/mol/ns/DOF", _drift),
        Column("RMS kJ/mol", lambda r: sig(r["rms_residual"])),
        Column("max", lambda r: sig(r["max_abs_residual"])),
        Column("worst 10 ps RMS", lambda r: sig(r["worst_window_rms"])),
    ]
    if speed:
        columns += [
            Column("ms/step", timed("{ms_per_step:.3f}".format_map)),
            Column("ns/day", timed("{ns_per_day:,.0f}".format_map)),
            Column("× RATTLE", timed(lambda r: times(r["ms_per_step"] / rattle) if rattle else "-")),
        ]
    return table(entry["rows"], columns, provenance_line([source], entry["header"]))


def energy_mode_windows(path: str) -> str:
    """Render the energy mode's windowed RMS against its α = 0 base's and RATTLE's over the same run."""
    data, _ = load(path)
    ((_, entry),) = data.items()
    rows = {row["integrator"]: row for row in entry["rows"]}
    energy, base, rattle = rows["energy4"], rows["alpha4=0"], rows["rattle"]
    e, b, r = (row["windows"]["rms"] for row in (energy, base, rattle))
    n = min(len(e), len(b), len(r))
    to_base = [x / y for x, y in zip(e[:n], b[:n])]
    to_rattle = [y / x for x, y in zip(e[:n], r[:n])]  # how many times below RATTLE's window
    fell = energy.get("controller", {}).get("fraction_fallen_back")
    cells = [
        f"{n} × {energy['windows']['window_ps']:g} ps",
        f"{sum(x > 1 for x in to_base)} (at most {two(max(to_base))}×)",
        f"{sum(x >= 50 for x in to_rattle)} (at worst 1/{times(min(to_rattle))})",
        f"1/{times(rattle['rms_residual'] / energy['rms_residual'])}",
        "–" if not fell else f"{100 * fell:.1f} %",
    ]
    header = (
        "`energy4`'s windows | above `alpha4=0`'s RMS | below 1/50 of RATTLE's | RMS over the run / RATTLE's "
        "| steps fallen back"
    )
    return markdown_table(header, [cells])


def precision_table() -> str:
    """Drift of the concurrent runs, mixed against single precision (no speed: 12 runs shared the GPU)."""
    lines, sources = {}, []
    for precision, path in CONCURRENT.items():
        data, source = load(path)
        sources.append(source)
        ((_, entry),) = data.items()
        for row in entry["rows"]:
            lines.setdefault(row["integrator"], {})[precision] = row
    table = []
    for name, by_precision in lines.items():
        cells = [f"`{name}`"]
        for row in (by_precision.get(precision) for precision in CONCURRENT):
            cells += (
                [f"{row['simulated_ps']:.0f}", _drift(row), sig(row["rms_residual"])] if row else ["-"] * 3
            )
        table.append(cells)
    header = ["integrator"] + [
        f"{p} {what}" for p in CONCURRENT for what in ("ps", "drift kJ/mol/ns/DOF", "RMS kJ/mol")
    ]
    run = (
        "tip3p-3nm, 2 fs, CUDA; twelve runs at once on one GPU, each stopped after 260 s, so the "
        "lengths differ and no speed is given"
    )
    return provenance_line(sources, run) + "\n\n" + markdown_table(header, table)


def cost_table() -> str:
    """Step times of every row against RATTLE's (and α-RATTLE-4's), CUDA mixed, by system."""
    loaded = {atoms: load(path) for atoms, path in COST.items()}
    #: Each row and the row it is timed against.
    wanted = {
        "verlet": "rattle",
        "rattle": "verlet",
        "rattle+rescale": "rattle",
        "rattle+rescale@10": "rattle",
        "alpha4=0": "rattle",
        "rattle4+rescale": "alpha4=0",
        "rattle4+rescale@10": "alpha4=0",
        "energy4": "alpha4=0",
    }

    def cell(atoms: str, rows: list[dict]):
        def text(name: str) -> str:
            try:
                row, base = pick(rows, name), pick(rows, wanted[name])
            except LookupError:
                return "-"
            goal = GOALS.get(atoms) if name == "rattle+rescale" else None
            mark = f" (goal ≤ {goal})" if goal else ""
            return f"{row['ms_per_step'] / base['ms_per_step']:.2f}× · {row['ns_per_day']:,.0f}{mark}"

        return text

    columns = [Column("integrator", lambda n: f"`{n}`"), Column("against", lambda n: f"`{wanted[n]}`")]
    columns += [
        Column(f"{atoms} atoms: step ratio · ns/day", cell(atoms, data["rows"]))
        for atoms, (data, _) in loaded.items()
    ]
    run = (
        "`alphaprk bench cost --platform CUDA --precision mixed --steps 200 --rounds 3` on each system, "
        "2 fs, every row of a system in one run, median of 3 interleaved rounds, each timed between two "
        "device synchronisations; TIP3P boxes of 3, 6 and 9 nm and `dhfr`"
    )
    return table(wanted, columns, provenance_line([source for _, source in loaded.values()], run))


def openmm_dhfr_table(
    path: str = OPENMM_DHFR,
    command: str = f"{OPENMM_DHFR_SCRIPT} --platform CUDA --precision mixed",
) -> str:
    """OpenMM's DHFR benchmark system as OpenMM builds it, 4 fs: ns/day of each integrator."""
    data, source = load(path)
    rattle = next((row["ms_per_step"] for row in data["rows"] if row["integrator"] == "RATTLE"), None)
    columns = [
        Column("integrator", "{integrator}"),
        Column("ms/step", "{ms_per_step:.3f}"),
        Column(
            "ns/day", lambda r: sig(r["ns_per_day"]) if r["ns_per_day"] < 100 else f"{r['ns_per_day']:,.0f}"
        ),
        Column("× LangevinMiddle", "{ratio_to_langevin_middle:.2f}"),
        Column("× Verlet", "{ratio_to_verlet:.2f}"),
        Column("× RATTLE", lambda r: f"{r['ms_per_step'] / rattle:.2f}" if rattle else "-"),
    ]
    return table(data["rows"], columns, provenance_line([source], f"{data['header']}; `{command}`"))


def render() -> dict[Path, dict[str, str]]:
    """Every generated block, by page and block name."""
    command = f"{OPENMM_DHFR_SCRIPT} --platform CPU --steps 30 --rounds 5"
    blocks = {
        "cuda long": long_table(SEQUENTIAL),
        "cuda energy mode": energy_mode_windows(SEQUENTIAL),
        "cuda precision": precision_table(),
        "cuda cost": cost_table(),
        "openmm dhfr": openmm_dhfr_table(),
        "openmm dhfr cpu": "\n\n".join(
            openmm_dhfr_table(path, command + (" --smooth" if "smooth" in path else ""))
            for path in OPENMM_DHFR_CPU
        ),
        "cpu villin long": long_table(CPU_VILLIN),
        "cpu long": long_table(CPU),
        "cpu energy mode": energy_mode_windows(CPU),
        "cpu energy mode before": long_table(CPU_BEFORE) + "\n\n" + energy_mode_windows(CPU_BEFORE),
    }
    return {PAGE: blocks}
