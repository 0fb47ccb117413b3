r"""The measured numbers of the README and the user guide, from the JSON that holds them.

Run from the repository root::

    python -m tools.reports.guide          # rewrite the generated blocks
    python -m tools.reports.guide --check  # exit 1 if a page is not what the data renders

It rewrites the generated blocks (between ``<!-- generated: NAME -->`` and ``<!-- end
generated: NAME -->``; the prose around them is written by hand) of ``README.md``
("Which integrator for which job") and of the user guide's pages ``docs/integrators.md``,
``docs/energy_mode.md``, ``docs/platforms.md``, ``docs/smooth_forces.md``,
``docs/own_files.md`` and ``docs/driver.md``. Every number comes from a file of
``docs/data/`` (the accuracy runs of ``docs/data/compositions/``, the MD benchmark of
``docs/data/benchmarks/``, the H100 runs of ``docs/data/*/cuda_h100/``, the research
record's data where a limit was measured there), and each block says which run it is from:
its length, platform, machine and day (``docs/data/provenance.toml``). The blocks of the
Limits sections, of platforms.md, smooth_forces.md, own_files.md and driver.md are rendered
by ``tools.reports.guide_limits``, ``guide_platforms``, ``guide_smooth_forces`` and
``guide_runs``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from tools.reports import guide_limits, guide_platforms, guide_runs, guide_smooth_forces, splitting
from tools.reports.markdown import generator_main, markdown_table, stale_blocks
from tools.reports.numbers import sig, times
from tools.reports.sources import DOCS, ROOT, Source, load

#: The accuracy runs at 2 fs (water boxes, villin) and at 4 fs (water boxes).
ACCURACY_2FS = (
    "compositions/compositions_accuracy_2fs.json",
    "compositions/compositions_accuracy_2fs_villin.json",
)
ACCURACY_4FS = ("compositions/compositions_accuracy_4fs.json",)
SYSTEMS = ("tip3p-2nm", "tip3p-3nm", "villin")
WATER = ("tip3p-2nm", "tip3p-3nm")
#: The horizon (fs) at which the guide compares position errors.
HORIZON_FS = 100.0
MD_BENCHMARK = "benchmarks/benchmarks.json"
#: H100 (CUDA mixed) cost runs of every program at 21k and 72k atoms.
GPU_COST = ("compositions/cuda_h100/cost_6.json", "compositions/cuda_h100/cost_9.json")
GPU_RESCALE_COST = (
    "platforms/cuda_h100/bench_core_rescale_6.json",
    "platforms/cuda_h100/bench_core_rescale_9.json",
)
RESCALE_SYNC_COST = "platforms/cuda_h100/rescale_sync_cost.json"

RATTLE = "RATTLE"
RESCALE = "RATTLE + rescaling"
ALPHA4 = "α-RATTLE-4 α = 0"
RATTLE4_RESCALE = "RATTLE-4 + rescaling"
ENERGY4 = "α-RATTLE-4 energy mode"
ALPHA6 = "α-RATTLE-6 α = 0"
TRIPLE_JUMP = "α-RATTLE-4 (triple-jump) α = 0"


# ------------------------------------------------------------------ numbers as text
def per_system(values: list[float], show=sig) -> str:
    """Write the values of the systems in order, ``a / b / c``."""
    return " / ".join(show(v) for v in values)


def span(values: list[float], show=times) -> str:
    """Return the range of ``values``, ``low–high`` (one value if they agree when shown)."""
    low, high = show(min(values)), show(max(values))
    return low if low == high else f"{low}–{high}"


def percent_span(values: list[float]) -> str:
    low, high = (f"{100 * v:.0f}" for v in (min(values), max(values)))
    return f"{low} %" if low == high else f"{low}–{high} %"


def _days(sources: list[Source]) -> str:
    days = sorted({s.date for s in sources})
    return days[0] if len(days) == 1 else f"{days[0]} to {days[-1]}"


def _files(sources: list[Source]) -> str:
    return ", ".join(f"`docs/data/{s.path}` (commit {s.commit})" for s in sources)


# ------------------------------------------------------------------ the accuracy runs
@dataclass
class Accuracy:
    """The rows of the accuracy runs at one step, by system and row name, and where they come from."""

    timestep_fs: float
    steps: int
    platform: str
    rows: dict[str, dict[str, dict]]
    sources: list[Source]

    @classmethod
    def read(cls, paths: tuple[str, ...]) -> Accuracy:
        rows, sources, settings = {}, [], []
        for path in paths:
            data, source = load(path)
            sources.append(source)
            settings.append(data["settings"])
            for system, result in data["systems"].items():
                rows[system] = {row["name"]: row for row in result["rows"]}
        steps = {max(s["horizons"]) for s in settings}
        timesteps = {s["timestep_fs"] for s in settings}
        platforms = {s["platform"] for s in settings}
        assert len(steps) == len(timesteps) == len(platforms) == 1, (steps, timesteps, platforms)
        return cls(timesteps.pop(), steps.pop(), platforms.pop(), rows, sources)

    def row(self, system: str, name: str) -> dict:
        return self.rows[system][name]

    def rms(self, system: str, name: str) -> float:
        return self.row(system, name)["rms_residual"]

    def evaluations(self, system: str, name: str) -> float:
        return self.row(system, name)["force_evaluations_per_step"]

    def position(self, system: str, name: str, time_fs: float = HORIZON_FS) -> float:
        (error,) = [h["position_rms"] for h in self.row(system, name)["horizons"] if h["time_fs"] == time_fs]
        return error

    def rattle_at(self, system: str, name: str, how: str = "equal evaluations") -> str:
        """Return the RATTLE row at the same cost as ``name`` (``how``: evaluations or wall time)."""
        spec = {
            ALPHA4: "alpha4=0",
            RATTLE4_RESCALE: "rattle4+rescale",
            ENERGY4: "energy4",
            ALPHA6: "alpha6=0",
            TRIPLE_JUMP: "alpha4=0:triple-jump",
        }[name]
        (found,) = [
            row_name
            for row_name, row in self.rows[system].items()
            if row_name.startswith("RATTLE h/") and f"{how} ({spec})" in row["role"]
        ]
        return found

    def gain(self, system: str, name: str, against: str) -> float:
        """How many times ``against``'s position error at the horizon is ``name``'s."""
        return self.position(system, against) / self.position(system, name)

    def caption(self, systems: tuple[str, ...]) -> str:
        machine = {s.machine for s in self.sources}.pop()
        return (
            f"{self.platform} platform, h = {self.timestep_fs:g} fs, {self.steps} steps of h "
            f"({self.steps * self.timestep_fs:g} fs) per row from the system's shipped start, "
            f"every row of a system in one run of `alphaprk bench accuracy`, on {_days(self.sources)} on "
            f"{machine}; values for {' / '.join(systems)}"
        )


# ------------------------------------------------------------------ the explicit family
#: The splitting surveys the guide's row of the minimum-error member is read from (2 fs).
SPLITTING_2FS = ("tip3p-2nm_2fs.json", "villin_2fs.json")


@dataclass(frozen=True)
class SplittingRow:
    """The minimum-error member against RATTLE at h/2 on tip3p-2nm and villin at 2 fs."""

    energy: str
    positions: str
    steps: int
    stable: str
    sources: list[Source]


def splitting_row() -> SplittingRow:
    """Read the 2 fs splitting surveys: energy ratios per system, the span of position-error ratios."""
    found = [splitting.compare(path) for path in SPLITTING_2FS]
    scans = [load(splitting.FOLDER + path) for _, path, _ in splitting.STABILITY]
    ratios = [
        row["ratio_to_rattle"]
        for data, _ in scans
        for row in data["integrators"]
        if row["integrator"] == "split-me"
    ]
    return SplittingRow(
        per_system([c.energy for c in found], lambda v: f"{v:.1f}"),
        span([r for c in found for r in c.positions], lambda v: f"{v:.2f}"),
        found[0].data["steps"],
        span(ratios, lambda v: f"{v:.2f}"),
        [c.source for c in found] + [source for _, source in scans],
    )


# ------------------------------------------------------------------ the blocks
#: The long runs whose drift and ns/day the README's table gives (H100, CUDA mixed).
LONG_RUN = "long_runs/cuda_h100/long_sequential_mixed.json"
LONG_RUN_DHFR = "long_runs/cuda_h100/cost_dhfr_2fs.json"


def long_run_columns() -> tuple[dict[str, list[str]], list[Source]]:
    """Return the README's long-run cells by integrator name: drift per DOF and ns/day, and the sources."""
    data, source = load(LONG_RUN)
    ((_, entry),) = data.items()
    dhfr, dhfr_source = load(LONG_RUN_DHFR)
    dhfr_speed = {row["name"]: row["ns_per_day"] for row in dhfr["rows"]}
    cells = {}
    for row in entry["rows"]:
        drift, error = row["drift_per_dof"], row["drift_per_dof_standard_error"]
        shown = f"{sig(drift)} ± {sig(error)}" if row["drift_resolved"] else f"none (± {sig(error)})"
        speed = dhfr_speed.get(row["label"])
        ns_day = f"{row['ns_per_day']:,.0f}" if row["ns_per_day"] == row["ns_per_day"] else "-"
        cells[row["integrator"]] = [
            f"{shown} ({row['simulated_ps']:.0f} ps)",
            ns_day + (f" / {speed:,.0f}" if speed else " / -"),
        ]
    return cells, [source, dhfr_source]


def readme_table(a2: Accuracy, a4: Accuracy) -> str:
    """Render the README's "which integrator for which job" from the accuracy and long runs."""
    rattle_rms = per_system([a2.rms(s, RATTLE) for s in SYSTEMS])
    rattle_x = per_system([a2.position(s, RATTLE) for s in SYSTEMS])
    rescale_rms = max(a2.rms(s, RESCALE) for s in SYSTEMS)
    r4 = [a2.gain(s, RATTLE4_RESCALE, a2.rattle_at(s, RATTLE4_RESCALE)) for s in SYSTEMS]
    e4_k = sorted({a2.rattle_at(s, ENERGY4).split("/")[1] for s in SYSTEMS})
    e4 = [a2.gain(s, ENERGY4, a2.rattle_at(s, ENERGY4)) for s in SYSTEMS]
    a6 = [a4.gain(s, ALPHA6, a4.rattle_at(s, ALPHA6)) for s in WATER]
    split = splitting_row()
    lines = [
        [
            "ordinary dynamics, any ensemble",
            "`RattleIntegrator` (`rattle`) or `VerletIntegrator`",
            "1",
            f"error {rattle_rms}; positions {rattle_x} nm",
        ],
        [
            "hold the energy, RATTLE's trajectory",
            "`RattleRescaleIntegrator(h)` (`rattle+rescale`)",
            "1",
            f"error at round-off (≤ {sig(rescale_rms, 1)}); RATTLE's positions",
        ],
        [
            "remove the drift at nearly RATTLE's speed",
            "`RattleRescaleIntegrator(h, rescale_interval=10)` (`rattle+rescale@10`)",
            "1",
            "H = E_ref at every 10th step, RATTLE's steps between; RATTLE's positions",
        ],
        [
            "a lower energy error at two evaluations, symplectic",
            "`SplittingRattleIntegrator(h)` (`split-me`)",
            "2",
            f"error {split.energy}× below RATTLE at h/2 (tip3p-2nm / villin, {split.steps} steps); "
            f"positions {split.positions}× RATTLE at h/2's",
        ],
        [
            "**hold the energy and track the dynamics**",
            "`RattleRescaleIntegrator(h, order=4)` (`rattle4+rescale`)",
            f"{a2.evaluations(SYSTEMS[0], RATTLE4_RESCALE):g}",
            f"error {per_system([a2.rms(s, RATTLE4_RESCALE) for s in SYSTEMS])}; positions "
            f"**{per_system(r4, times)}× below h/5**",
        ],
        [
            "accurate symplectic dynamics",
            "`AlphaRattleIntegrator(h, 0.0, order=4)` (`alpha4=0`)",
            f"{a2.evaluations(SYSTEMS[0], ALPHA4):g}",
            "the same positions; error "
            + per_system([a2.rms(s, ALPHA4) for s in SYSTEMS], lambda v: sig(v, 3)),
        ],
        [
            f"larger steps ({a4.timestep_fs:g} fs)",
            "`order=6` (`alpha6=0`, `rattle6+rescale`)",
            f"{a4.evaluations(WATER[0], ALPHA6):g}",
            f"positions {per_system(a6, times)}× below RATTLE at {a4.timestep_fs:g}/9 fs (water; "
            f"{a4.steps} steps of {a4.timestep_fs:g} fs, {_days(a4.sources)})",
        ],
        [
            "studying the method",
            "`AlphaRattleEnergyIntegrator(h, order=4)` (`energy4`)",
            span([a2.evaluations(s, ENERGY4) for s in SYSTEMS], lambda v: f"{v:.1f}"),
            f"error {per_system([a2.rms(s, ENERGY4) for s in SYSTEMS])}, but positions "
            f"{per_system(e4, lambda v: times(1 / v))}× *above* h/{'/'.join(e4_k)}",
        ],
    ]
    long_cells, long_sources = long_run_columns()
    names = (
        "rattle",
        "rattle+rescale",
        "rattle+rescale@10",
        "split-me",
        "rattle4+rescale",
        "alpha4=0",
        None,
        "energy4",
    )
    for line, name in zip(lines, names, strict=True):
        line += long_cells.get(name, ["-", "-"])
    caption = (
        f"{a2.caption(SYSTEMS)}. Error = RMS(H − E_ref) over the run (kJ/mol); positions = RMS "
        f'distance per atom to RATTLE at h/64 after {HORIZON_FS:g} fs; "h/k" = RATTLE at the same '
        f"force evaluations. Long runs ([long runs](docs/long_runs.md)): drift of H − E_ref in kJ/mol/ns "
        f"per degree of freedom and ns/day on an H100 (CUDA mixed, 2 fs, {long_sources[0].date}): "
        f"tip3p-3nm (2,661 atoms) in one `alphaprk bench long` run / dhfr (23,558 atoms) in "
        f"`alphaprk bench cost`. `split-me`: {split.steps} steps of 2 fs from the same starts, "
        f"{_days(split.sources)} "
        f"([splitting](docs/splitting.md)). Data: "
        f"{_files(a2.sources + a4.sources + long_sources + split.sources)}."
    )
    header = ["job", "use", "evaluations per step", "measured", "long-run drift", "ns/day (H100)"]
    return caption + "\n\n" + markdown_table(header, lines)


def integrators_table(a2: Accuracy, a4: Accuracy, md: dict, md_source: Source, gpu: dict) -> str:
    """Render docs/integrators.md's "which integrator for which job" (with the triple jump and a fixed α)."""
    rattle_rms = per_system([a2.rms(s, RATTLE) for s in SYSTEMS], lambda v: sig(v, 3))
    rattle_x = per_system([a2.position(s, RATTLE) for s in SYSTEMS])
    rescale_time = [a2.row(s, RESCALE)["time_ratio"] for s in SYSTEMS]
    rescale_rms = max(a2.rms(s, RESCALE) for s in SYSTEMS)
    r4_rms = per_system([a2.rms(s, RATTLE4_RESCALE) for s in SYSTEMS])
    r4_x = per_system([a2.position(s, RATTLE4_RESCALE) for s in SYSTEMS])
    r4_cost = [a2.gain(s, RATTLE4_RESCALE, a2.rattle_at(s, RATTLE4_RESCALE)) for s in SYSTEMS]
    r4_wall = [
        a2.gain(s, RATTLE4_RESCALE, a2.rattle_at(s, RATTLE4_RESCALE, "equal wall time")) for s in SYSTEMS
    ]
    a4_rms = per_system([a2.rms(s, ALPHA4) for s in SYSTEMS], lambda v: sig(v, 3))
    a6_x = per_system([a4.position(s, ALPHA6) for s in WATER])
    a6_cost = per_system([a4.gain(s, ALPHA6, a4.rattle_at(s, ALPHA6)) for s in WATER], times)
    a6_rattle2 = per_system([a2.position(s, RATTLE) / a4.position(s, ALPHA6) for s in WATER], times)
    a6_2fs = per_system([a2.gain(s, ALPHA6, a2.rattle_at(s, ALPHA6)) for s in SYSTEMS], times)
    e4_evals = per_system([a2.evaluations(s, ENERGY4) for s in SYSTEMS], lambda v: f"{v:.2f}")
    e4_rms = per_system([a2.rms(s, ENERGY4) for s in SYSTEMS])
    e4_k = per_system([float(a2.rattle_at(s, ENERGY4).split("/")[1]) for s in SYSTEMS], lambda v: f"h/{v:g}")
    e4_above = per_system([1 / a2.gain(s, ENERGY4, a2.rattle_at(s, ENERGY4)) for s in SYSTEMS], times)
    e4_vs_r4 = span([a2.gain(s, RATTLE4_RESCALE, ENERGY4) for s in SYSTEMS])
    r4_holds = span([a2.rms(s, ENERGY4) / a2.rms(s, RATTLE4_RESCALE) for s in SYSTEMS])
    r4_share = percent_span(
        [a2.evaluations(s, RATTLE4_RESCALE) / a2.evaluations(s, ENERGY4) for s in SYSTEMS]
    )
    tj = per_system([1 / a2.gain(s, TRIPLE_JUMP, a2.rattle_at(s, TRIPLE_JUMP)) for s in SYSTEMS], times)
    split = splitting_row()
    fixed = [e for system in md["energy"].values() for e in system if e["label"] == "α-RATTLE α = 1/6 2 fs"]
    rattles = {
        system: next(e for e in entries if e["label"] == "RATTLE 2 fs")
        for system, entries in md["energy"].items()
    }
    fixed_rms = [
        e["rms_residual"] / rattles[system]["rms_residual"]
        for system, entries in md["energy"].items()
        for e in entries
        if e["label"] == "α-RATTLE α = 1/6 2 fs"
    ]
    fixed_evals = span([e["force_evaluations_per_step"] for e in fixed], lambda v: f"{v:.1f}")
    fixed_time = span([e["timing"]["time_per_step_ratio"] for e in fixed], lambda v: f"{v:.1f}")
    lines = [
        [
            "ordinary dynamics, any ensemble",
            "`RattleIntegrator` (or OpenMM's `VerletIntegrator`)",
            f"the baseline: 1 force evaluation; RMS(H − E_ref) {rattle_rms} kJ/mol; position error "
            f"{rattle_x} nm",
        ],
        [
            "hold the total energy at E_ref, RATTLE's trajectory",
            "`RattleRescaleIntegrator` (`rattle+rescale`)",
            f"1 evaluation, {span(rescale_time, lambda v: f'{v:.1f}')}× RATTLE's step on the CPU "
            f"({times(gpu['rescale_21k'])}× at 21k atoms on an H100); RMS(H − E_ref) at the energy's "
            f"round-off (≤ {sig(rescale_rms, 1)} kJ/mol); positions RATTLE's",
        ],
        [
            "symplectic dynamics with a lower energy error at two evaluations",
            "`SplittingRattleIntegrator(h)` (`split-me`): α-RATTLE's quadrature as a kick-drift splitting "
            "with constraints, the minimum-error α",
            f"2 evaluations; RMS(H − E_ref) {split.energy}× below RATTLE at h/2 (tip3p-2nm / villin, "
            f"{split.steps} steps); position error {split.positions}× RATTLE at h/2's; stable to "
            f"{split.stable}× RATTLE's largest step, where RATTLE at h/2 reaches 2×. With `+rescale` "
            "H is held at round-off on the same trajectory, which `rattle+rescale` at h/2 also gives "
            "([the explicit family](splitting.md))",
        ],
        [
            "**hold the energy *and* track the dynamics**",
            "`RattleRescaleIntegrator(h, order=4)` (`rattle4+rescale`): Suzuki's five-stage composition "
            "of RATTLE steps, then the rescaling",
            f"{a2.evaluations(SYSTEMS[0], RATTLE4_RESCALE):g} evaluations; RMS(H − E_ref) {r4_rms} kJ/mol; "
            f"position error {r4_x} nm, **{per_system(r4_cost, times)}× below RATTLE's and RATTLE + "
            f"rescaling's at h/5** ({per_system(r4_wall, times)}× below RATTLE at equal CPU wall time)",
        ],
        [
            "accurate symplectic dynamics",
            "`AlphaRattleIntegrator(h, 0.0, order=4)` (`alpha4=0`)",
            f"the same positions; its energy fluctuates ({a4_rms} kJ/mol)",
        ],
        [
            "larger steps",
            f"`order=6` (`alpha6=0`, `rattle6+rescale`: McLachlan's nine stages) at {a4.timestep_fs:g} fs",
            f"9 evaluations per {a4.timestep_fs:g} fs; position error after {HORIZON_FS:g} fs {a6_x} nm "
            f"(water boxes), {a6_cost}× below RATTLE at {a4.timestep_fs:g}/9 fs and {a6_rattle2}× below "
            f"RATTLE at {a2.timestep_fs:g} fs; at {a2.timestep_fs:g} fs {a6_2fs}× below RATTLE at h/9",
        ],
        [
            "the energy-preserving α (`energy4`)",
            "for studying the method, not for production",
            f"{e4_evals} evaluations, RMS(H − E_ref) {e4_rms} kJ/mol, but its position error after "
            f"{HORIZON_FS:g} fs is {e4_above}× *above* RATTLE's at equal evaluations ({e4_k}) and "
            f"{e4_vs_r4}× above `rattle4+rescale`'s, which holds H {r4_holds}× better at {r4_share} of "
            "the force evaluations: α* perturbs each step as much as the composition's own error "
            "([compositions](compositions.md))",
        ],
        [
            'the triple jump (`composition="triple-jump"`, the order-4 default before)',
            "for comparison",
            f"3 evaluations; after {HORIZON_FS:g} fs {tj}× above RATTLE at h/3; it blows up at a smaller "
            "step than RATTLE ([compositions](compositions.md#the-named-compositions))",
        ],
        [
            "a fixed α ≠ 0",
            "`AlphaRattleIntegrator(h, alpha)`, for studying the family",
            "symplectic, order 2 (on a composition: order 2 with α on one stage, the composition's "
            'order with α on every stage, `alpha_stages="all"`); α = 1/6 cuts a harmonic oscillator\'s '
            f"phase error to O(h⁴), but on the water boxes and villin it costs {fixed_evals} evaluations "
            f"({fixed_time}× RATTLE's time) for {span(fixed_rms, lambda v: f'{v:.2f}')}× RATTLE's "
            f"RMS(H − E_ref) (10 ps and 4 ps runs, {md_source.date}: [benchmarks](benchmarks.md))",
        ],
    ]
    caption = (
        f"{a2.caption(SYSTEMS)}; position error = RMS distance per atom to RATTLE at h/64 after "
        f'{HORIZON_FS:g} fs; "at equal cost" = k RATTLE steps of h/k, k the row\'s force evaluations '
        f"per step; order 6 at {a4.timestep_fs:g} fs: {a4.steps} steps, {_days(a4.sources)}. Data: "
        f"{_files(a2.sources + a4.sources)}; `split-me` ({_days(split.sources)}): "
        f"{_files(split.sources)}; H100: {_files(gpu['sources'])}."
    )
    header = ["job", "use", f"measured at {a2.timestep_fs:g} fs ({' / '.join(SYSTEMS)})"]
    return caption + "\n\n" + markdown_table(header, lines)


def gpu_cost(paths: tuple[str, ...] = GPU_COST) -> dict:
    """Return the time per force evaluation against RATTLE's on an H100 (CUDA mixed) at 21k and 72k atoms."""
    per_eval: dict[str, list[float]] = {}
    sources = []
    for path in paths:
        data, source = load(path)
        sources.append(source)
        for row in data["rows"]:
            per_eval.setdefault(row["name"], []).append(row["ratio_per_evaluation"])
    rescale = {}
    for path, atoms in zip(GPU_RESCALE_COST, ("21k", "72k")):
        data, source = load(path)
        sources.append(source)
        (row,) = [row for row in data["rows"] if row["name"] == RESCALE]
        rescale[atoms] = row
    return {
        "per_eval": per_eval,
        "rescale_21k": rescale["21k"]["ratio_per_evaluation"],
        "rescale_rows": rescale,
        "sources": sources,
    }


def gpu_in_short(gpu: dict) -> str:
    """Render docs/integrators.md's sentence on the compositions' cost on an H100."""
    per_eval = gpu["per_eval"]
    fixed = span(per_eval[ALPHA4] + per_eval[ALPHA6], lambda v: f"{v:.2f}")
    rescale4 = span(per_eval[RATTLE4_RESCALE], lambda v: f"{v:.2f}")
    energy = span(per_eval[ENERGY4], lambda v: f"{v:.2f}")
    return (
        f"On an H100 (CUDA mixed; 21k- and 72k-atom TIP3P boxes, {_days(gpu['sources'][:2])}) the "
        f"compositions cost what their RATTLE stages cost from 21k atoms on ({fixed}× RATTLE's time per "
        f"force evaluation for `alpha4=0` and `alpha6=0`, {rescale4}× for `rattle4+rescale`, {energy}× "
        "for `energy4`), and the `energy4` of that day blew up on villin at 4 fs where `alpha4=0` and "
        "`rattle4+rescale` ran (today's takes the α = 0 step where it cannot hold one: "
        "[the energy mode](energy_mode.md)) ([compositions](compositions.md#on-a-gpu-cuda-on-an-h100); data: "
        f"{_files(gpu['sources'][:2])})."
    )


def energy_mode_cost(a2: Accuracy) -> str:
    """Render docs/integrators.md's Limits bullet on what the energy mode costs."""
    evals = span([a2.evaluations(s, ENERGY4) for s in SYSTEMS], lambda v: f"{v:.1f}")
    return (
        f"- The energy mode costs {evals} force evaluations per step on the shipped systems "
        f"({a2.platform}, {a2.timestep_fs:g} fs, {_days(a2.sources)}) and tracks the dynamics worse than "
        f"RATTLE at equal cost ([the energy mode](energy_mode.md); data: {_files(a2.sources)})."
    )


def not_for_production(a2: Accuracy) -> str:
    """Render docs/energy_mode.md's paragraph that says what to use instead."""
    holds = span([a2.rms(s, ENERGY4) / a2.rms(s, RATTLE4_RESCALE) for s in SYSTEMS])
    share = percent_span([a2.evaluations(s, RATTLE4_RESCALE) / a2.evaluations(s, ENERGY4) for s in SYSTEMS])
    tracks = span([a2.gain(s, RATTLE4_RESCALE, ENERGY4) for s in SYSTEMS])
    return (
        "**It is not the integrator to use for production.** On every system measured "
        f"({', '.join(SYSTEMS)}; "
        f"{a2.platform}, {a2.timestep_fs:g} fs, {a2.steps} steps from the shipped start, "
        f"{_days(a2.sources)}; data: {_files(a2.sources)}), `RattleRescaleIntegrator(h, order=4)` "
        "(`rattle4+rescale`) holds the energy "
        f"{holds}× better at {share} of the force evaluations and tracks the dynamics {tracks}× better "
        "([compositions](compositions.md#what-each-buys-in-short)); see "
        "[which integrator for which job](integrators.md#which-integrator-for-which-job). The energy "
        "mode is kept for studying the method. This page says how it works now; how it got there, "
        "and what was tried and not kept, is in the [research record](research/index.md)."
    )


def what_it_achieves(a2: Accuracy, gpu: dict) -> str:
    """Render docs/energy_mode.md's list of what it achieves."""
    evals = span([a2.evaluations(s, ENERGY4) for s in SYSTEMS], lambda v: f"{v:.1f}")
    rms = per_system([a2.rms(s, ENERGY4) for s in SYSTEMS])
    below = per_system([a2.rms(s, RATTLE) / a2.rms(s, ENERGY4) for s in SYSTEMS], lambda v: f"1/{times(v)}")
    above = per_system([1 / a2.gain(s, ENERGY4, a2.rattle_at(s, ENERGY4)) for s in SYSTEMS], times)
    k = sorted({a2.rattle_at(s, ENERGY4).split(" ")[1] for s in SYSTEMS})
    tracks = span([a2.gain(s, RATTLE4_RESCALE, ENERGY4) for s in SYSTEMS])
    energy_gpu = span(gpu["per_eval"][ENERGY4], lambda v: f"{v:.2f}")
    return "\n".join(
        [
            f"{a2.caption(SYSTEMS)} ([compositions](compositions.md), [accuracy](accuracy.md); data: "
            f"{_files(a2.sources)}):",
            "",
            f"- **Energy**: `energy4` takes {evals} force evaluations per step and holds RMS(H − E_ref) to "
            f"{rms} kJ/mol, {below} of RATTLE's. The main job compares it with RATTLE at equal cost over "
            "1000 steps of the 3 nm box ([getting started](getting_started.md#the-main-job)).",
            f"- **Dynamics**: its position error after {HORIZON_FS:g} fs is {above}× *above* RATTLE's at "
            f"equal force evaluations ({', '.join(k)}), and {tracks}× above `rattle4+rescale`'s. α* perturbs "
            "each step by about as much as the composition's own error.",
            f"- **Cost on a GPU**: on an H100 (CUDA mixed, {_days(gpu['sources'][:2])}) `energy4` costs "
            f"{energy_gpu}× RATTLE's time per force evaluation from 21k atoms on, and the program of that "
            "day blew up on villin at 4 fs where `alpha4=0` and `rattle4+rescale` ran "
            "([compositions](compositions.md#on-a-gpu-cuda-on-an-h100)); today's takes the α = 0 step where "
            "it cannot hold one (below), not yet run on a GPU at 4 fs.",
        ]
    )


SYNC_VARIANTS = (
    ("energy", "the potential energy read once per step"),
    ("K", "and the kinetic energy summed, the velocities scaled uniformly"),
    ("K+moved", "and the start-of-step check of a state set by the user"),
    ("K+P", "and the momentum (3 sums) instead of that check"),
    ("K+P+moved", "all of it (what `rattle+rescale` does)"),
)


def rescale_sync_table() -> str:
    """Render docs/platforms.md's table of what a rescaling step could cost on an H100."""
    data, source = load(RESCALE_SYNC_COST)
    atoms = sorted(data, key=int)
    header = [
        "added to RATTLE",
        *(f"{int(n):,} atoms" if i == 0 else f"{int(n):,}" for i, n in enumerate(atoms)),
    ]
    lines = [
        [title, *(f"{data[n][key] / data[n]['rattle']:.2f}" for n in atoms)] for key, title in SYNC_VARIANTS
    ]
    caption = (
        f"Time per step against a RATTLE `CustomIntegrator` (H100, CUDA mixed, {source.date}; "
        f"{_files([source])}):"
    )
    return caption + "\n\n" + markdown_table(header, lines)


#: bench cost on an H100 of the program that sums K alone per step (2026-11-27), by atoms.
GPU_RESCALE_NOW = {
    "2,661": "long_runs/cuda_h100/cost_tip3p-3nm.json",
    "21,384": "long_runs/cuda_h100/cost_tip3p-6nm.json",
    "72,279": "long_runs/cuda_h100/cost_tip3p-9nm.json",
    "23,558 (dhfr)": "long_runs/cuda_h100/cost_dhfr_2fs.json",
}


def rescale_gpu_cost(gpu: dict) -> str:
    """Render docs/platforms.md's sentences on the package's RattleRescaleIntegrator on an H100."""
    now, now_sources = [], []
    for atoms, path in GPU_RESCALE_NOW.items():
        data, source = load(path)
        now_sources.append(source)
        rows = {row["name"]: row for row in data["rows"]}
        rattle = rows[RATTLE]["ms_per_step"]
        every = rows[RESCALE]["ms_per_step"] / rattle
        tenth = rows["RATTLE + rescaling every 10 steps"]["ms_per_step"] / rattle
        now.append(f"{every:.2f}× ({tenth:.2f}× every 10th step) at {atoms} atoms")
    rows = gpu["rescale_rows"]
    sources = gpu["sources"][-2:]
    cells = []
    for atoms, row in rows.items():
        rattle_ms = row["ms_per_step"] / row["ratio_per_evaluation"]
        ratio, ms = row["ratio_per_evaluation"], row["ms_per_step"]
        cells.append(f"{ratio:.2f}× at {atoms} atoms ({ms:.3f} against {rattle_ms:.3f} ms)")
    return (
        f"The package's `RattleRescaleIntegrator` that sums the kinetic energy alone per step measured "
        f"{', '.join(now)} RATTLE's step in `alphaprk bench cost --platform CUDA --precision mixed` "
        f"({_days(now_sources)}; {_files(now_sources)}; [long runs](long_runs.md#cost-on-a-gpu)). The "
        f"program before it (5 sums and the energy per step) measured {cells[0]} and {cells[1]} "
        f"({_days(sources)}; {_files(sources)})."
    )


# ------------------------------------------------------------------ the pages
def render() -> dict[Path, dict[str, str]]:
    """Return every generated block of the README and the user guide, by page and block name."""
    a2, a4 = Accuracy.read(ACCURACY_2FS), Accuracy.read(ACCURACY_4FS)
    md, md_source = load(MD_BENCHMARK)
    gpu = gpu_cost()
    order2, pme = guide_limits.order2(), guide_limits.pme()
    return {
        ROOT / "README.md": {"which integrator": readme_table(a2, a4)},
        DOCS / "integrators.md": {
            "which integrator": integrators_table(a2, a4, md, md_source, gpu),
            "gpu in short": gpu_in_short(gpu),
            "pme tolerance": guide_limits.integrators_pme(pme),
            "order 2": guide_limits.integrators_order2(order2),
            "energy mode cost": energy_mode_cost(a2),
            "triple jump step": guide_limits.integrators_triple_jump(guide_limits.step_scan()),
        },
        DOCS / "energy_mode.md": {
            "not for production": not_for_production(a2),
            "what it achieves": what_it_achieves(a2, gpu),
            "order 2": guide_limits.energy_mode_order2(order2),
        },
        DOCS / "platforms.md": {
            "rescale sync cost": rescale_sync_table(),
            "rescale gpu cost": rescale_gpu_cost(gpu),
            **guide_platforms.blocks(a2),
        },
        DOCS / "smooth_forces.md": guide_smooth_forces.blocks(),
        DOCS / "own_files.md": guide_runs.own_files_blocks(),
        DOCS / "driver.md": guide_runs.driver_blocks(),
    }


def differences() -> list[str]:
    """Return ``PAGE: BLOCK`` for every block that is missing or differs from what the data renders."""
    return stale_blocks(render(), ROOT)


def main(argv: list[str] | None = None) -> int:
    return generator_main(render, __doc__.split("\n\n")[0], ROOT, argv)


if __name__ == "__main__":
    sys.exit(main())
