"""Bad input to ``alphaprk run``: a clear one-line refusal (exit status 2) or a message that names the cause.

Tested here: a coordinate file cut short, a file of another format under a reader's
extension (every reader says what it expected), an absurd α, and a ``--temperature`` that
is negative or would be ignored. Files are made in ``tmp_path`` from
the shipped ones (tests/data/files).
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from openmm_alphaprk.cli import build_parser, main
from openmm_alphaprk.systems import DefinitionError, load_definition
from openmm_alphaprk.systems.arguments import system_to_prepare

FILES = Path(__file__).parent / "data" / "files"
PRMTOP = FILES / "peptide.prmtop"
INPCRD = FILES / "peptide.inpcrd"
CHARMM_PARAMS = [str(FILES / "peptide.rtf"), str(FILES / "peptide.prm")]
TIP3P = ["amber14-all.xml", "amber14/tip3p.xml"]


def _run(argv: list[str], tmp_path: Path, capsys) -> tuple[int, str]:
    """``alphaprk run SYSTEM INTEGRATOR ...`` in this process, 2 steps: its exit status and stderr."""
    status = main(["run", *map(str, argv), "-o", str(tmp_path / "out"), "--steps", "2", "--quiet"])
    return status, capsys.readouterr().err


def _refused(argv: list[str], tmp_path: Path, capsys) -> str:
    """Run ``argv``; check it is refused in one line with exit status 2 before the run directory; the line."""
    status, err = _run(argv, tmp_path, capsys)
    assert status == 2, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "out").exists()
    return err


def _cut(source: Path, target: Path, fraction: float = 0.5) -> Path:
    """Write the first ``fraction`` of ``source``'s lines to ``target`` (a file cut short)."""
    lines = source.read_text(encoding="utf-8").splitlines(keepends=True)
    target.write_text("".join(lines[: int(len(lines) * fraction)]), encoding="utf-8")
    return target


def _other_format(target: Path, source: Path = FILES / "peptide.pdb") -> Path:
    """Copy ``source`` (a file of another format) to ``target``, the name a reader takes."""
    shutil.copyfile(source, target)
    return target


def test_a_truncated_inpcrd_beside_its_prmtop_is_refused_naming_the_format_and_the_atoms(tmp_path, capsys):
    """Was a TypeError traceback from OpenMM's reader, exit status 1."""
    shutil.copyfile(PRMTOP, tmp_path / "peptide.prmtop")
    _cut(INPCRD, tmp_path / "peptide.inpcrd")
    err = _refused([tmp_path / "peptide.prmtop", "rattle"], tmp_path, capsys)
    assert (
        "peptide.inpcrd: not an AMBER coordinate file (.inpcrd/.rst7/.ncrst) for the 1,626 atoms of "
        "peptide.prmtop, or cut short (OpenMM's reader: Badly formatted restart file" in err
    )
    assert "give this topology's coordinates, complete, with --coordinates FILE.inpcrd" in err


# (files of the command line, made in tmp_path; the file named; the format it expected)
READER_CASES = {
    "amber topology": (
        lambda d: [_other_format(d / "bad.prmtop"), "--coordinates", INPCRD],
        "bad.prmtop",
        "an AMBER topology file (.prmtop/.parm7)",
    ),
    "amber coordinates": (
        lambda d: [PRMTOP, "--coordinates", _other_format(d / "bad.rst7", FILES / "peptide.gro")],
        "bad.rst7",
        "an AMBER coordinate file (.inpcrd/.rst7/.ncrst) for the 1,626 atoms of peptide.prmtop",
    ),
    "charmm psf": (
        lambda d: [
            _other_format(d / "bad.psf"),
            "--coordinates",
            FILES / "peptide.crd",
            "--params",
            *CHARMM_PARAMS,
            "--box",
            "2.6",
            "2.6",
            "2.6",
        ],  # fmt: skip
        "bad.psf",
        "a CHARMM PSF file (.psf)",
    ),
    "charmm coordinates": (
        lambda d: [
            FILES / "peptide.psf",
            "--coordinates",
            _cut(FILES / "peptide.crd", d / "short.crd"),
            "--params",
            *CHARMM_PARAMS,
            "--box",
            "2.6",
            "2.6",
            "2.6",
        ],  # fmt: skip
        "short.crd",
        "a CHARMM coordinate file (.crd) for the 1,626 atoms of peptide.psf",
    ),
    "charmm parameters": (
        lambda d: [
            FILES / "peptide.psf",
            "--coordinates",
            FILES / "peptide.crd",
            "--params",
            FILES / "peptide.rtf",
            _other_format(d / "bad.txt"),
            "--box",
            "2.6",
            "2.6",
            "2.6",
        ],  # fmt: skip
        "peptide.rtf, bad.txt",
        "CHARMM parameter and topology files",
    ),
    "gromacs topology": (
        lambda d: [_other_format(d / "bad.top"), "--coordinates", FILES / "peptide.gro"],
        "bad.top",
        "a GROMACS topology file (.top)",
    ),
    "gromacs coordinates": (
        lambda d: [FILES / "peptide.top", "--coordinates", _cut(FILES / "peptide.gro", d / "short.gro")],
        "short.gro",
        "a GROMACS coordinate file (.gro) for the 1,626 atoms of peptide.top",
    ),
    "pdb": (
        lambda d: [_other_format(d / "bad.pdb", PRMTOP), "--forcefield", *TIP3P],
        "bad.pdb",
        "a PDB file (.pdb)",
    ),
    "pdbx": (
        lambda d: [_other_format(d / "bad.cif", PRMTOP), "--forcefield", *TIP3P],
        "bad.cif",
        "a PDBx/mmCIF file (.cif/.pdbx)",
    ),
    "openmm system": (
        lambda d: [_other_format(d / "bad.xml"), "--state", FILES / "tip4pew_state.xml"],
        "bad.xml",
        "a serialized OpenMM System (XmlSerializer XML)",
    ),
    "openmm state": (
        lambda d: [FILES / "tip4pew_system.xml", "--state", FILES / "tip4pew_system.xml"],
        "tip4pew_system.xml",
        "a serialized OpenMM State (XmlSerializer XML) for the 1,764 particles of tip4pew_system.xml",
    ),
}


@pytest.mark.parametrize("case", list(READER_CASES))
def test_every_reader_says_what_kind_of_file_it_expected(case, tmp_path, capsys):
    """Was "reading bad.prmtop failed: list index out of range", or a traceback."""
    files, named, expected = READER_CASES[case]
    argv = files(tmp_path)
    err = _refused([argv[0], "verlet", *argv[1:]], tmp_path, capsys)
    assert f": {named}: not {expected}" in err
    assert "(OpenMM's reader: " in err and "; give " in err


def test_an_absurd_alpha_is_named_as_the_cause_of_the_blow_up(tmp_path, capsys):
    """alpha=1e9 stopped with "... which points at the start"; it points at the α."""
    status, err = _run(["water-cluster", "alpha=1e9"], tmp_path, capsys)
    assert status == 1 and "Traceback" not in err
    assert "blew up in its first 100 steps with alpha=1e+09 at a 2 fs step, outside |alpha| <= 1" in err
    assert "Likely causes: (1) the α:" in err and "use alpha between -1 and 1" in err
    assert "points at the start" not in err


@pytest.mark.parametrize("kelvin", ["-300", "0"])
def test_a_temperature_not_above_zero_kelvin_is_refused(kelvin, tmp_path, capsys):
    err = _refused([PRMTOP, "rattle", "--temperature", kelvin], tmp_path, capsys)
    assert f"--temperature {kelvin} K: a temperature must be above 0 K" in err


def test_a_temperature_below_zero_in_a_definition_file_is_refused(tmp_path):
    toml = tmp_path / "mine.toml"
    toml.write_text(
        f'[build]\nkind = "amber"\nfiles = {{ system = "{PRMTOP}", coordinates = "{INPCRD}" }}\n'
        "[equilibration]\nseed = 1\ntemperature_K = -300.0\nminimize_tolerance_kJ_per_mol_nm = 10.0\n"
        "minimize_max_iterations = 0\nlangevin_steps = 0\nlangevin_timestep_fs = 2.0\n"
        'langevin_friction_per_ps = 1.0\nplatform = "CPU"\n',
        encoding="utf-8",
    )
    with pytest.raises(DefinitionError, match="equilibration.temperature_K must be positive"):
        load_definition(str(toml))


def test_a_temperature_the_start_would_ignore_is_refused_saying_how_to_get_new_velocities(tmp_path, capsys):
    """The restart's velocities are kept: --temperature would change nothing, silently."""
    restart = ["--coordinates", FILES / "peptide_vel.rst7"]
    err = _refused([PRMTOP, "rattle", *restart, "--temperature", "350"], tmp_path, capsys)
    assert "--temperature 350 K would be ignored: peptide_vel.rst7 carries velocities" in err
    assert "add --equilibrate TIME" in err and "--coordinates FILE.inpcrd without velocities" in err
    err = _refused(
        [
            FILES / "tip4pew_system.xml",
            "verlet",
            "--state",
            FILES / "tip4pew_state.xml",
            "--temperature",
            "350",
        ],
        tmp_path,
        capsys,
    )
    assert "tip4pew_state.xml carries velocities" in err and "--state STATE.xml without velocities" in err
    # a named system starts from its definition's state, velocities included
    err = _refused(["tip3p-2nm", "rattle", "--temperature", "300"], tmp_path, capsys)
    assert "--temperature 300 K does not apply to 'tip3p-2nm'" in err
    assert re.search(r"run a copy of .*tip3p-2nm\.toml with another equilibration\.temperature_K", err)


def test_a_temperature_is_used_where_velocities_are_drawn_at_it():
    parser = build_parser()

    def definition(*argv):
        args = parser.parse_args(["run", str(argv[0]), "rattle", *map(str, argv[1:])])
        return system_to_prepare(args.system, args)

    assert (
        definition(PRMTOP, "--temperature", "350").equilibration["temperature_K"] == 350
    )  # none in the file
    drawn = definition(PRMTOP, "--coordinates", FILES / "peptide_vel.rst7", "--temperature", "350",
                       "--equilibrate", "10fs")  # fmt: skip
    assert drawn.equilibration["temperature_K"] == 350 and drawn.equilibration["langevin_steps"] == 5
    assert (
        definition(PRMTOP, "--coordinates", FILES / "peptide_vel.rst7").equilibration["temperature_K"] == 300
    )
