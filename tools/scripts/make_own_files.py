#!/usr/bin/env python
"""Generate the test input files of tests/data/files/ (a user's own system in every format).

ParmEd writes the AMBER, CHARMM and GROMACS files; it is not a dependency of the package,
so run this with a Python that has both OpenMM and ParmEd, e.g.
    python3 -m venv /tmp/pmd && /tmp/pmd/bin/pip install parmed==4.3.1 openmm==8.6.1 numpy
    /tmp/pmd/bin/python tools/scripts/make_own_files.py [outdir]

Produces:
  peptide.pdb (reference, OpenMM PDBFile), peptide.prmtop/.inpcrd, peptide_vel.rst7,
  peptide.psf/.crd/.prm/.rtf, peptide.top/.gro,
  tip4pew.pdb, tip4pew_system.xml, tip4pew_state.xml
All randomness is seeded (Langevin seed, velocity seed) so reruns on the same platform
give near-identical files (Reference/CPU platform results may still differ in last digits).
"""

import os
import sys

import numpy as np
import openmm
from openmm import app, unit
from openmm.unit import angstrom, femtosecond, kelvin, nanometer, picosecond

OUT = os.path.join(os.path.dirname(__file__), "..", "..", "tests", "data", "files")
#: ParmEd, imported by main(): the geometry and the OpenMM set-up work (and are tested) without it.
parmed = None


def P(name):  # noqa: N802 - the output path of a file
    return os.path.join(OUT, name)


BOX_PEP = 2.6  # nm, cubic
BOX_W4 = 2.4  # nm, cubic (cutoff 0.9 nm < half edge)
SEED = 2024
#: Every system's electrostatics: PME, cutoff 0.9 nm.
NONBONDED = {"nonbondedMethod": app.PME, "nonbondedCutoff": 0.9 * nanometer}


def platform():
    return openmm.Platform.getPlatformByName("CPU")


# ------------------------------------------------------------------ peptide geometry
def place(a, b, c, bond, angle_deg, torsion_deg):
    """NeRF: position of atom d bonded to c, angle b-c-d, torsion a-b-c-d."""
    ang = np.radians(angle_deg)
    tor = np.radians(torsion_deg)
    bc = c - b
    bc /= np.linalg.norm(bc)
    n = np.cross(b - a, bc)
    n /= np.linalg.norm(n)
    m = np.cross(n, bc)
    d2 = np.array([-bond * np.cos(ang), bond * np.sin(ang) * np.cos(tor), bond * np.sin(ang) * np.sin(tor)])
    return c + d2[0] * bc + d2[1] * m + d2[2] * n


#: The heavy-atom bonds inside each residue of the peptide.
RESIDUE_BONDS = {
    "ACE": (("CH3", "C"), ("C", "O")),
    "ALA": (("N", "CA"), ("CA", "C"), ("C", "O"), ("CA", "CB")),
    "NME": (("N", "C"),),
}


def build_peptide_heavy(nala=3, phi=-60.0, psi=-45.0):
    """Heavy atoms of ACE-(ALA)n-NME (Angstrom): a list of (resname, [(atomname, element, xyz)])."""
    # backbone chain: CH3(ACE) C(ACE) N CA C  N CA C ... N(NME) C(NME)
    chain = [(0, "CH3"), (0, "C")] + [(i, name) for i in range(1, nala + 1) for name in ("N", "CA", "C")]
    chain += [(nala + 1, "N"), (nala + 1, "C")]
    angle = np.radians(116.0)
    xyz = [np.array([0.0, 0.0, 0.0]), np.array([1.52, 0.0, 0.0])]
    xyz.append(xyz[1] + 1.33 * np.array([-np.cos(angle), np.sin(angle), 0.0]))  # N of ALA1
    bonds = {("C", "N"): 1.33, ("N", "CA"): 1.46, ("CA", "C"): 1.52, ("N", "C"): 1.46}  # N-C: NME's methyl
    angles = {"N": 116.0, "CA": 122.0, "C": 111.0}
    # the torsion a-b-c-d of the new bond c-d is about b-c: phi, psi, else 180 (omega, the peptide bond)
    torsions = {("N", "CA"): phi, ("CA", "C"): psi}
    for k in range(3, len(chain)):
        b, c, d = chain[k - 2][1], chain[k - 1][1], chain[k][1]
        xyz.append(
            place(xyz[k - 3], xyz[k - 2], xyz[k - 1], bonds[(c, d)], angles[c], torsions.get((b, c), 180.0))
        )
    pos = dict(zip(chain, xyz))

    def carbonyl_O(cpos, prev, nxt):
        u = (cpos - prev) / np.linalg.norm(cpos - prev) + (cpos - nxt) / np.linalg.norm(cpos - nxt)
        return cpos + 1.23 * u / np.linalg.norm(u)

    ace = pos[(0, "C")]
    residues = [
        (
            "ACE",
            [
                ("CH3", "C", pos[(0, "CH3")]),
                ("C", "C", ace),
                ("O", "O", carbonyl_O(ace, pos[(0, "CH3")], pos[(1, "N")])),
            ],
        )
    ]
    for i in range(1, nala + 1):
        n, ca, c = pos[(i, "N")], pos[(i, "CA")], pos[(i, "C")]
        o = carbonyl_O(c, ca, pos[(i + 1, "N")])
        cb = -0.58273431 * np.cross(ca - n, c - ca) + 0.56802827 * (ca - n) - 0.54067466 * (c - ca) + ca
        residues.append(
            ("ALA", [("N", "N", n), ("CA", "C", ca), ("C", "C", c), ("O", "O", o), ("CB", "C", cb)])
        )
    residues.append(("NME", [("N", "N", pos[(nala + 1, "N")]), ("C", "C", pos[(nala + 1, "C")])]))
    return residues


def heavy_topology():
    """Return the peptide's heavy atoms as a Topology (with their bonds) and their positions."""
    top = app.Topology()
    chain = top.addChain()
    positions = []
    previous_c = None
    for resname, atoms in build_peptide_heavy():
        res = top.addResidue(resname, chain)
        amap = {}
        for name, el, xyz in atoms:
            amap[name] = top.addAtom(name, app.Element.getBySymbol(el), res)
            positions.append(openmm.Vec3(*xyz) * 0.1)
        for a, b in RESIDUE_BONDS[resname]:
            top.addBond(amap[a], amap[b])
        if previous_c is not None:
            top.addBond(previous_c, amap["N"])
        previous_c = amap["C"] if resname != "NME" else None
    return top, positions * nanometer


# ------------------------------------------------------------------ helpers
def assign_class_types(ff, topology, struct):
    # private OpenMM API (8.x): the same template matching createSystem() does
    data = app.ForceField._SystemData(topology)
    ff._matchAllResiduesToTemplates(data, topology, {}, False)
    atypes = {}
    for res in topology.residues():
        for atom in res.atoms():
            cls = ff._atomTypes[data.atomType[atom]].atomClass
            cls = {"tip3p-O": "OW", "tip3p-H": "HW"}.get(cls, cls)  # prmtop types are 4 chars
            patom = struct.atoms[atom.index]
            assert patom.name == atom.name
            old = patom.atom_type
            if cls not in atypes:
                at = parmed.AtomType(cls, len(atypes) + 1, patom.mass, patom.atomic_number)
                at.set_lj_params(old.epsilon, old.rmin, old.epsilon_14, old.rmin_14)
                atypes[cls] = at
            at = atypes[cls]
            assert abs(at.epsilon - old.epsilon) < 1e-8 and abs(at.rmin - old.rmin) < 1e-8, cls
            patom.type = cls
            patom.atom_type = at
    print("atom classes:", sorted(atypes))


def energy(system, positions, box=None):
    system = openmm.XmlSerializer.deserialize(openmm.XmlSerializer.serialize(system))
    ctx = openmm.Context(system, openmm.VerletIntegrator(1.0), platform())
    if box is not None:
        ctx.setPeriodicBoxVectors(*box)
    ctx.setPositions(positions)
    e = ctx.getState(getEnergy=True).getPotentialEnergy().value_in_unit(unit.kilojoule_per_mole)
    del ctx
    return e


def relaxed(modeller, system, minimize_iterations: int, steps: int) -> app.Simulation:
    """Minimize, then run seeded Langevin at 300 K (2 fs); return the Simulation."""
    integrator = openmm.LangevinMiddleIntegrator(300 * kelvin, 1.0 / picosecond, 2 * femtosecond)
    integrator.setRandomNumberSeed(SEED)
    simulation = app.Simulation(modeller.topology, system, integrator, platform())
    simulation.context.setPositions(modeller.positions)
    simulation.minimizeEnergy(maxIterations=minimize_iterations)
    simulation.context.setVelocitiesToTemperature(300 * kelvin, SEED)
    simulation.step(steps)
    return simulation


def main(argv: list[str] | None = None) -> None:
    global OUT, parmed  # the output folder of P() and the ParmEd module, set once
    import parmed

    args = sys.argv[1:] if argv is None else argv
    if args:
        OUT = args[0]
        os.makedirs(OUT, exist_ok=True)
    # some hosts have a broken OpenCL driver; addHydrogens/addSolvent use the default platform
    os.environ.setdefault("OPENMM_DEFAULT_PLATFORM", "CPU")
    ff = app.ForceField("amber14-all.xml", "amber14/tip3p.xml")

    # ---------------- 1. peptide: build, hydrogens, solvate, minimize, short Langevin
    top, pos = heavy_topology()
    mod = app.Modeller(top, pos)
    mod.addHydrogens(ff)
    mod.addSolvent(
        ff, model="tip3p", boxSize=openmm.Vec3(BOX_PEP, BOX_PEP, BOX_PEP) * nanometer, neutralize=False
    )
    print("peptide system atoms:", mod.topology.getNumAtoms(), "residues:", mod.topology.getNumResidues())

    sys_md = ff.createSystem(mod.topology, constraints=app.HBonds, rigidWater=True, **NONBONDED)
    sim = relaxed(mod, sys_md, minimize_iterations=2000, steps=2000)  # 4 ps
    st = sim.context.getState(getPositions=True, getVelocities=True, getEnergy=True, enforcePeriodicBox=True)
    positions = st.getPositions(asNumpy=True)
    velocities = st.getVelocities(asNumpy=True)
    box = st.getPeriodicBoxVectors()
    print("after 4 ps Langevin: PE", st.getPotentialEnergy(), "KE", st.getKineticEnergy())
    topology = mod.topology
    topology.setPeriodicBoxVectors(box)
    with open(P("peptide.pdb"), "w") as f:
        app.PDBFile.writeFile(topology, positions, f, keepIds=False)

    e_ff = energy(sys_md, positions, box)
    print(f"ForceField(HBonds) energy at final positions: {e_ff:.3f} kJ/mol")

    # ---------------- 2. AMBER
    sys_flex = ff.createSystem(topology, constraints=None, rigidWater=False, **NONBONDED)
    struct = parmed.openmm.load_topology(topology, sys_flex, xyz=positions)
    # load_topology names atom types after unique LJ parameters (C1, H1, ...), which merges
    # Amber atom classes with equal LJ but different bonded parameters.  Rename them to the
    # ForceField atom classes (CT, XC, 2C, N, H, HW, OW, ...) so type-based formats
    # (CHARMM prm) can reproduce the per-interaction parameters.
    assign_class_types(ff, topology, struct)
    # tleap-style TIP3P: an H-H "bond" in each water.  OpenMM's AmberPrmtopFile makes water
    # rigid (rigidWater=True) only by constraining the prmtop's bonds-with-H of residues named
    # WAT/HOH, so without it the H-O-H angle stays flexible.  req = the H-H distance of the
    # OpenMM tip3p.xml geometry (0.9572 A, 104.52 deg); k as in tleap (553 kcal/mol/A^2).
    hh = parmed.BondType(553.0, 1.5139007, list=struct.bond_types)
    struct.bond_types.append(hh)
    for res in struct.residues:
        if res.name == "HOH":
            hs = [a for a in res.atoms if a.element == 1]
            struct.bonds.append(parmed.Bond(hs[0], hs[1], type=hh))
    bv = np.array([[v.x, v.y, v.z] for v in box.value_in_unit(angstrom)])
    struct.box = [bv[0, 0], bv[1, 1], bv[2, 2], 90.0, 90.0, 90.0]
    struct.save(P("peptide.prmtop"), overwrite=True)
    struct.save(P("peptide.inpcrd"), overwrite=True)

    # restart with velocities (ParmEd Rst7.vels is in Angstrom/ps; it writes /20.455)
    rst = parmed.amber.Rst7(
        natom=len(struct.atoms), title="ACE-ALA3-NME in TIP3P, 300 K, after 4 ps Langevin"
    )
    rst.coordinates = positions.value_in_unit(angstrom)
    rst.vels = velocities.value_in_unit(angstrom / picosecond).reshape(-1)
    rst.box = struct.box
    rst.write(P("peptide_vel.rst7"))  # velocities checked by tests/test_own_formats.py

    # ---------------- 3. CHARMM (from the Amber-parameterized structure)
    amb = parmed.load_file(P("peptide.prmtop"), P("peptide.inpcrd"))
    # (a) CHARMM prm supports one global 1-4 scaling (e14fac) and 1-4 LJ per type.  The
    #     Amber dihedrals whose 1-4 pair is not computed (ignore_end: extra terms, impropers)
    #     carry scee=scnb=1.0, which ParmEd refuses to mix; they do not matter, so set all to
    #     the Amber values 1.2 / 2.0 (-> e14fac 0.8333 and epsilon_14 = epsilon/2).
    # (b) Amber impropers are periodic torsions.  ParmEd writes periodic impropers into the
    #     prm IMPROPERS section in the form "k n phase", which OpenMM's CharmmParameterSet reads
    #     as a *harmonic* improper (k, theta0=n).  Flag them as ordinary dihedrals so they are
    #     written to the psf PHI section and the prm DIHEDRALS section (exact same energy;
    #     OpenMM builds 1-4 pairs from bond connectivity, so no spurious 1-4 pairs appear).
    #     Type keys must then be unique between propers and impropers: e.g. the improper
    #     CA(i)-N(i+1)-C(i)-O(i) and the proper CA(i+1)-N(i+1)-C(i)-O(i) share the class key
    #     CX-N-C-O with different parameters.  So every peptide atom gets its own CHARMM type
    #     (atom name + "_" + residue number, e.g. CA_2, HB1_3; LJ/mass copied from its class);
    #     water keeps OW/HW.  Then every parameter in the prm is exactly the Amber one.
    for d in amb.dihedrals:
        d.improper = False
    for a in amb.atoms:
        if a.residue.name in ("HOH", "WAT"):
            continue
        old = a.atom_type
        tname = f"{a.name}_{a.residue.idx + 1}"
        at = parmed.AtomType(tname, 100 + a.idx, old.mass, old.atomic_number)
        at.set_lj_params(old.epsilon, old.rmin, old.epsilon_14, old.rmin_14)
        a.type, a.atom_type = tname, at
    assert len({a.type for a in amb.atoms if a.residue.name not in ("HOH", "WAT")}) == sum(
        1 for a in amb.atoms if a.residue.name not in ("HOH", "WAT")
    )
    amb.save(P("peptide.psf"), overwrite=True)
    amb.save(P("peptide.crd"), format="charmmcrd", overwrite=True)
    pset = parmed.charmm.CharmmParameterSet.from_structure(amb)  # raises on unequal duplicates
    for typs in pset.dihedral_types.values():
        for t in typs:
            t.scee, t.scnb = 1.2, 2.0
    pset.write(par=P("peptide.prm"), top=P("peptide.rtf"))

    # ---------------- 4. GROMACS
    gmx = parmed.load_file(P("peptide.prmtop"), P("peptide.inpcrd"))
    # Drop the tleap-style water H-H bond again: GROMACS tip3p.itp has only O-H bonds + angle
    # under FLEXIBLE (else settles), and OpenMM's GromacsTopFile defines FLEXIBLE and builds
    # the rigid-water H-H constraint from the angle, so an H-H bond would duplicate it.
    for b in [
        b
        for b in gmx.bonds
        if b.atom1.residue.name == "HOH" and b.atom1.element == 1 and b.atom2.element == 1
    ]:
        b.delete()
        gmx.bonds.remove(b)
    for dt in gmx.dihedral_types:
        if dt.scee == 1.0 and dt.scnb == 1.0:
            dt.scee, dt.scnb = 1.2, 2.0
    gmx.save(P("peptide.top"), format="gromacs", overwrite=True)
    # Standard 3 decimals (nm): OpenMM 8.6's GromacsGroFile recognises coordinate lines only
    # with the fixed 8-character fields (a precision=6 .gro is rejected: "Unexpected line").
    gmx.save(P("peptide.gro"), overwrite=True)

    # ---------------- 5. TIP4P-Ew box
    ff4 = app.ForceField("amber14/tip4pew.xml")
    m4 = app.Modeller(app.Topology(), [])
    m4.addSolvent(ff4, model="tip4pew", boxSize=openmm.Vec3(BOX_W4, BOX_W4, BOX_W4) * nanometer)
    s4 = ff4.createSystem(m4.topology, removeCMMotion=False, **NONBONDED)
    sim4 = relaxed(m4, s4, minimize_iterations=1000, steps=500)  # 1 ps
    st4 = sim4.context.getState(
        getPositions=True, getVelocities=True, getEnergy=True, enforcePeriodicBox=True
    )
    print("tip4pew: particles", s4.getNumParticles(), "PE", st4.getPotentialEnergy())
    m4.topology.setPeriodicBoxVectors(st4.getPeriodicBoxVectors())
    with open(P("tip4pew.pdb"), "w") as f:
        app.PDBFile.writeFile(m4.topology, st4.getPositions(), f)
    with open(P("tip4pew_system.xml"), "w") as f:
        f.write(openmm.XmlSerializer.serialize(s4))
    # state with positions, velocities, box only (no forces/energies/parameters)
    st4b = sim4.context.getState(getPositions=True, getVelocities=True, enforcePeriodicBox=True)
    with open(P("tip4pew_state.xml"), "w") as f:
        f.write(openmm.XmlSerializer.serialize(st4b))


if __name__ == "__main__":
    main()
