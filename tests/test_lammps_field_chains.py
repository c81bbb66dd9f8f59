"""LAMMPS for the field's chains: spheres of their own size and material, an end wall and
a dead load (``granchain.lammps.field``, docs/explanation/lammps_laws.md section 12).

Closed forms where the physics has one (binary Hertz collisions of unlike spheres, a
sphere bouncing off a wall, a preloaded chain at rest), written here from the handbook
values without the package's Hertz code; the reference engine's velocity Verlet
elsewhere. (That the chapter's chains keep their decks byte for byte is a regression
pin: tests/test_regression_pins.py.)
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from granchain.compare import comparison_scene, member_rows
from granchain.engines import lammps as lammps_engine
from granchain.engines import reference
from granchain.lammps import deck as lammps_deck
from granchain.lammps import run_lammps
from granchain.lammps.deckplan import ledger_binary_columns
from granchain.materials import library
from granchain.observables import summarize
from granchain.scene import load_scene
from granchain.gaps import member_radii
from granchain.simulate import member_gaps, members
from tests.conftest import packed

pytestmark = pytest.mark.lammps

ALL = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"
ALL_BUT_ROLLING = "[hertz, groove_friction, air_drag, rotation, particle_friction]"
PLUGIN = "/PLUGIN/groove_drag.so"
MAT = library()

# ---------------------------------------------------------------------------------------
# closed forms, written out here
def e_star(a, b):
    """1/E* = (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b (b None: a rigid wall)."""
    return 1.0 / ((1 - a.nu ** 2) / a.E + (0.0 if b is None else (1 - b.nu ** 2) / b.E))


def k_hertz(a, Ra, b, Rb):
    """(4/3) E* sqrt(R*); Rb None: a flat wall (R* = Ra)."""
    Rs = Ra if Rb is None else Ra * Rb / (Ra + Rb)
    return 4.0 / 3.0 * e_star(a, b) * math.sqrt(Rs)


def mass(m, R):
    return 4.0 / 3.0 * math.pi * R ** 3 * m.rho


def max_overlap(mu, K, v):
    """Peak overlap of a head-on Hertz collision: (5 mu v^2 / (4 K))^(2/5)."""
    return (5.0 * mu * v * v / (4.0 * K)) ** 0.4


def peak(y):
    """Largest value of a sampled smooth maximum, refined by the parabola through it and
    its neighbours."""
    j = int(np.argmax(y))
    a, b, c = y[j - 1], y[j], y[j + 1]
    den = a - 2 * b + c
    return b - 0.125 * (a - c) ** 2 / den


def run_deck(sc, tmp_path, edit_data=None):
    """Write the scene's deck (binary output, every step sampled), optionally edit its
    chain.data, run it; return (plan, step, {x, vx} (S, natoms) in um and m/s)."""
    deck = lammps_deck.write_deck(sc, tmp_path, output="binary")
    if edit_data:
        data = tmp_path / lammps_deck.DATA_NAME
        data.write_text(edit_data(data.read_text()))
    run_lammps(deck, tmp_path, timeout=600)
    pl = lammps_deck.plan(sc, output="binary")
    step, cols = lammps_engine.read_binary_dump(tmp_path / lammps_deck.BINARY_NAME, pl.dump_columns,
                                                pl.n_chains * sc.n, pl.nsamples, "traj")
    return pl, step, cols


def set_velocities(text, v):
    """chain.data with the Velocities section's vx of atom i+1 set to v[i]."""
    head, rest = text.split("Velocities\n\n", 1)
    rows, tail = rest.split("\n\n", 1) if "\n\n" in rest else (rest.rstrip("\n"), "")
    out = []
    for ln in rows.splitlines():
        f = ln.split()
        f[1] = repr(float(v[int(f[0]) - 1]))
        out.append(" ".join(f))
    return head + "Velocities\n\n" + "\n".join(out) + "\n" + ("\n" + tail if tail else "")


def test_binary_collisions_of_unlike_spheres_follow_hertz(tmp_path):
    """Striker (brass, R 189 um) hits sphere 2 (440C, 150 um) at 0.1 m/s; sphere 2 then
    crosses a 0.5 um gap and hits sphere 3 (PTFE, 120 um) alone. Each collision is a
    two-body Hertz collision with the pair's own E* and R*: peak overlap
    (5 mu v^2/(4K))^(2/5), elastic exchange of momentum. Tests the per-type pair_coeff
    (E = 2 E*_IJ, nu = 0) and the per-atom masses. Measured (Verlet, 1 ns, every step
    sampled): peak overlaps 1.4e-7 and 2.6e-8 off, velocities after 6.5e-10."""
    mats = [MAT["brass"], MAT["ss440c"], MAT["ptfe"]]
    R = [189e-6, 150e-6, 120e-6]
    v = 0.1
    sc = packed(t_end=12e-6, **{"chain.n": 3, "probes": "[2, 3]",
                                "chain.materials": "[brass, ss440c, ptfe]",
                                "chain.radius": str(R), "gaps.distribution": "list",
                                "gaps.values": "[0.0, 0.5e-6]", "output.sample_dt": 1e-9})
    deck = lammps_deck.render(sc, plugin=PLUGIN)[0]
    assert "3 atom types" in lammps_deck.render(sc, plugin=PLUGIN)[1]
    assert re.search(r"pair_coeff +1 2 hertz/material \S+ 0\.0 0\.0 ", deck)
    _, step, c = run_deck(sc, tmp_path)
    x, vx = c["x"], c["vx"]
    m = [mass(a, r) for a, r in zip(mats, R)]
    Rum = [r * 1e6 for r in R]
    d12 = (Rum[0] + Rum[1] - (x[:, 1] - x[:, 0])) * 1e-6
    d23 = (Rum[1] + Rum[2] - (x[:, 2] - x[:, 1])) * 1e-6
    mu12 = m[0] * m[1] / (m[0] + m[1])
    assert peak(d12) == pytest.approx(max_overlap(mu12, k_hertz(mats[0], R[0], mats[1], R[1]), v),
                                      rel=3e-6)
    # after the first collision (before the second): elastic exchange
    j = int(np.flatnonzero(d12 > 0)[-1]) + 1
    assert np.all(d23[:j + 1] <= 0)
    v1, v2 = (m[0] - m[1]) / (m[0] + m[1]) * v, 2 * m[0] / (m[0] + m[1]) * v
    assert vx[j, 0] == pytest.approx(v1, rel=1e-8) and vx[j, 1] == pytest.approx(v2, rel=1e-8)
    mu23 = m[1] * m[2] / (m[1] + m[2])
    assert peak(d23) == pytest.approx(max_overlap(mu23, k_hertz(mats[1], R[1], mats[2], R[2]), v2),
                                      rel=3e-6)
    k = int(np.flatnonzero(d23 > 0)[-1]) + 1
    assert k < len(step) - 1 and np.all(d12[j:] <= 0)
    assert vx[k, 2] == pytest.approx(2 * m[1] / (m[1] + m[2]) * v2, rel=1e-8)


@pytest.mark.parametrize("wall", ["rigid", "ss316", "ptfe"])
def test_sphere_bouncing_off_the_end_wall(wall, tmp_path):
    """The last sphere (440C, R 150 um) of a 3-sphere chain starts at the wall at 0.1 m/s
    towards it, the others at rest far behind: a sphere on a flat wall, K_w =
    (4/3) E*_w sqrt(R), peak overlap (5 m v^2/(4 K_w))^(2/5), peak wall force
    K_w delta_m^1.5, rebound at -v. The force is the one fix wall/gran applied (its
    'contacts' output, summed per chain into ledger.bin). Measured: peak overlap <= 2.9e-7
    off, peak force <= 4.3e-7 (Verlet at 1 ns), the force K_w delta^1.5 of the dumped
    positions to 7e-16, rebound <= 9.3e-9."""
    v = 0.1
    sc = packed(t_end=12e-6, **{"chain.n": 3, "probes": "[2, 3]", "walls.end": wall,
                               "gaps.distribution": "list", "gaps.values": "[5e-6, 5e-6]",
                               "output.sample_dt": 1e-9})
    pl, step, c = run_deck(sc, tmp_path, lambda t: set_velocities(t, [0.0, 0.0, v]))
    x, vx = c["x"], c["vx"]
    s440 = MAT["ss440c"]
    Kw = k_hertz(s440, 150e-6, None if wall == "rigid" else MAT[wall], None)
    m = mass(s440, 150e-6)
    dm = max_overlap(m, Kw, v)
    dw = (x[:, 2] + 150.0) * 1e-6                  # the wall plane is x = 0
    assert x[0, 2] == -150.0 and peak(dw) == pytest.approx(dm, rel=3e-6)
    cols = ledger_binary_columns(pl)
    lstep, led = lammps_engine.read_binary_dump(tmp_path / lammps_deck.LEDGER_BINARY_NAME, cols, 1,
                                                pl.nsamples, "ledger")
    assert np.array_equal(lstep, step)
    F = -led[cols[-1]][:, 0] * 1e-9                 # N, compression > 0
    assert peak(F) == pytest.approx(Kw * dm ** 1.5, rel=3e-6)
    # the force LAMMPS applied is K_w delta^1.5 of the dumped positions
    np.testing.assert_allclose(F, Kw * np.maximum(dw, 0) ** 1.5, rtol=1e-9, atol=1e-12 * F.max())
    assert vx[-1, 2] == pytest.approx(-v, rel=1e-7) and np.all(vx[:, :2] == 0)


@pytest.mark.parametrize("wall", ["rigid", "al6061"])
def test_preloaded_chain_at_rest_stays_static(wall, tmp_path):
    """A dead load F0 = 1 N on particle 2 of a chain of four materials and three radii
    pressed onto the wall, striker at rest: every contact from particle 2 to the wall
    carries F0 at its static overlap (F0/K)^(2/3) (each contact's own K), so nothing
    moves, if LAMMPS applies exactly our K to every contact and to the wall. Measured:
    |v| <= 3.4e-11 m/s, wall force F0 to 2e-14; the same deck with the E of one unlike
    pair_coeff 2e-4 too large (about what mixing E and nu separately would give): |v| up
    to 4.7e-4 m/s, wall force off by 1.8e-4."""
    F0 = 1.0
    sc = packed(t_end=20e-6, **{"chain.n": 6, "probes": "[2, 5]", "striker.velocity": 0.0,
                                "chain.materials": "[ss440c, brass, ss440c, tungsten_carbide, "
                                                   "ss316, al6061]",
                                "chain.radius": "[150e-6, 189e-6, 150e-6, 120e-6, 150e-6, 200e-6]",
                                "walls.end": wall, "precompression.force": F0})
    gaps, vs = member_gaps(sc, members(sc)), np.zeros(1)
    (t,) = lammps_engine.run(sc, gaps, vs, workdir=tmp_path)
    assert t.t[-1] >= 20e-6 and np.abs(t.v).max() < 1e-9
    np.testing.assert_allclose(t.wall_force, F0, rtol=1e-11)
    assert t.wall_static == pytest.approx(F0, rel=1e-14)
    E = t.energy
    e_h = E[0, 2]
    assert e_h > 0 and np.abs(E[:, 2] - e_h).max() < 1e-10 * e_h
    assert np.abs(E[:, -1]).max() < 1e-10 * e_h          # the load does no work
    data = (tmp_path / lammps_deck.DATA_NAME).read_text()
    assert "fix             load second addforce 1000000000.0 0.0 0.0" in (
        tmp_path / lammps_deck.DECK_NAME).read_text()
    assert "5 atom types" in data


# ---------------------------------------------------------------------------------------
# against the reference engine (granchain.compare's rows, and the wall's observables)
FIELD = {
    # a dimer chain: 440C (150 um) and brass (189 um) alternating
    "dimer": lambda: packed(**{"chain.n": 10, "probes": "[2, 9]",
                               "chain.materials": "[" + ", ".join(["ss440c", "brass"] * 5) + "]",
                               "chain.radius": "[" + ", ".join(["150e-6", "189e-6"] * 5) + "]"}),
    # every effect on spheres of three materials and sizes (groove springs per sphere)
    "mixed-all-effects": lambda: packed(effects=ALL, **{
        "chain.n": 8, "probes": "[2, 7]", "rolling.k_roll": 1e3,
        "chain.materials": "[brass, ss440c, ss440c, ptfe, ss440c, ss316, ss440c, ss440c]",
        "chain.radius": "[189e-6, 150e-6, 150e-6, 120e-6, 150e-6, 150e-6, 150e-6, 150e-6]"}),
    # gapped chains against a wall: each realisation ends at the same wall plane
    "wall-gaps": lambda: packed(effects=ALL_BUT_ROLLING, **{
        "chain.n": 8, "probes": "[2, 7]", "walls.end": "ss316", "gaps.distribution": "uniform",
        "gaps.mean": 20e-9, "ensemble.realisations": 3}),
    # preloaded, mixed, rigid wall, every effect
    "preloaded": lambda: packed(effects=ALL, **{
        "chain.n": 8, "probes": "[2, 7]", "rolling.k_roll": 1e3, "walls.end": "rigid",
        "precompression.force": 0.5, "striker.material": "tungsten_carbide",
        "striker.radius": 120e-6}),
}


@pytest.mark.parametrize("name", list(FIELD))
def test_field_chains_match_the_reference_engine(name, tmp_path):
    scene = FIELD[name]()
    cs = comparison_scene(scene)
    mem = members(cs)
    gaps, vs = member_gaps(cs, mem), np.array([m.v_striker for m in mem])
    ref = list(reference.run(cs, gaps, vs, method="verlet", dt=cs.dt, trace=True))
    lmp = list(lammps_engine.run(cs, gaps, vs, workdir=tmp_path))
    if cs.wall is not None:
        x_last = [ln for ln in (tmp_path / lammps_deck.DATA_NAME).read_text().splitlines()
                  if re.match(rf"\d+ \d+ ", ln) and int(ln.split()[0]) % cs.n == 0]
        assert len({ln.split()[4] for ln in x_last}) == 1     # one wall plane for all
    assert len(ref) == len(lmp) == len(mem) >= 1
    for r, lt in zip(ref, lmp):
        rows = member_rows(cs, r, lt)
        bad = [row for row in rows if row["ok"] is False]
        assert not bad, bad
        assert lt.status == r.status == "passed" and lt.t.size == r.t.size
        assert np.abs(lt.v - r.v).max() < 1e-9 * r.v_striker
        if cs.heterogeneous:
            np.testing.assert_array_equal(lt.radii, r.radii)
        if cs.wall is None:
            assert lt.wall_force is None
            continue
        F = r.wall_force.max()
        assert np.abs(lt.wall_force - r.wall_force).max() < 1e-9 * F
        assert lt.wall_static == r.wall_static
        a, b = summarize(r, cs.probes), summarize(lt, cs.probes)
        assert a.wall_peak_final and b.wall_peak_final
        assert b.wall_force_max == pytest.approx(a.wall_force_max, rel=1e-8)
        assert b.t_wall_peak == pytest.approx(a.t_wall_peak, rel=1e-9)


def test_wall_and_load_give_the_same_record_on_every_output_path_and_rank_count():
    """Text dump (MDAnalysis, ledger.txt) and binary dumps, 1 and 2 MPI ranks: the same
    velocities and wall force bit for bit; the same energies (bit for bit on one rank; on
    two, the per-chain sums over ranks differ in order: measured 5e-29 J)."""
    cs = comparison_scene(FIELD["preloaded"]())
    mem = members(cs)
    gaps, vs = member_gaps(cs, mem), np.array([m.v_striker for m in mem])
    (a,) = lammps_engine.run(cs, gaps, vs)
    for kw in ({"output": "dump"}, {"nprocs": 2}):
        (b,) = lammps_engine.run(cs, gaps, vs, **kw)
        for f in ("v", "wall_force"):
            np.testing.assert_array_equal(getattr(b, f), getattr(a, f))
        e0 = a.energy[0, :3].sum()
        assert np.abs(b.energy - a.energy).max() <= (0.0 if "output" in kw else 1e-14 * e0)


# ---------------------------------------------------------------------------------------
# chain.radius_spread: every chain of the deck has its own radii
SPREAD = {
    # every effect, three materials, gapped chains; normal draws, sd 2 um
    "spread-all-effects": lambda: packed(effects=ALL, **{
        "chain.n": 8, "probes": "[2, 7]", "rolling.k_roll": 1e3, "ensemble.realisations": 3,
        "chain.radius_spread": "{sd: 2e-6, seed: 3}",
        "chain.materials": "[brass, ss440c, ss440c, ptfe, ss440c, ss316, ss440c, ss440c]",
        "gaps.distribution": "uniform", "gaps.mean": 10e-9}),
    # a 316 end wall and a dead load, every effect; uniform draws, sd 3 um
    "spread-wall-preload": lambda: packed(effects=ALL, **{
        "chain.n": 8, "probes": "[2, 7]", "rolling.k_roll": 1e3, "ensemble.realisations": 3,
        "chain.radius_spread": "{distribution: uniform, sd: 3e-6, seed: 5}",
        "walls.end": "ss316", "precompression.force": 0.5}),
}


def spread_members(cs):
    mem = members(cs)
    return (member_gaps(cs, mem), np.array([m.v_striker for m in mem]),
            member_radii(cs, mem))


def data_atoms(path):
    """The Atoms rows of a chain.data: (id, type, diameter, density, x) per atom."""
    text = path.read_text()
    body = text.split("Atoms # sphere\n\n", 1)[1].split("\n\n", 1)[0]
    return np.array([[float(f) for f in ln.split()[:5]] for ln in body.splitlines()])


def data_groove(path):
    """The Groove rows of a chain.data: (id, kt, gamma) per atom."""
    body = path.read_text().split("\nGroove\n\n", 1)[1]
    return np.array([[float(f) for f in ln.split()] for ln in body.strip().splitlines()])


@pytest.mark.parametrize("name", list(SPREAD))
def test_radius_spread_ensembles_match_the_reference_engine(name, tmp_path):
    """One deck, each chain its own radii: its diameters and masses (chain.data), its
    contacts (R* from the atoms; no pair_coeff holds a radius), its groove springs (the
    Groove section), its static overlaps and wall overlap (its positions; the stop rule
    compares each last sphere with its own initial x, fix store/state). Against the
    reference engine's Verlet with the same radii. Measured: velocities <= 1.2e-10 v_s,
    v_max 1.8e-10, v_g 1.6e-11 (every effect); 2.8e-10 v_s, v_max 4.4e-10, v_g 2.0e-10,
    wall force 1.3e-11 (wall and preload). LAMMPS with the nominal radii: v_max 2-4e-2
    off and other sample counts."""
    cs = comparison_scene(SPREAD[name]())
    gaps, vs, radii = spread_members(cs)
    B, n = radii.shape
    ref = list(reference.run(cs, gaps, vs, method="verlet", dt=cs.dt, trace=True, radii=radii))
    lmp = list(lammps_engine.run(cs, gaps, vs, radii=radii, workdir=tmp_path))
    atoms = data_atoms(tmp_path / lammps_deck.DATA_NAME)
    np.testing.assert_allclose(atoms[:, 2].reshape(B, n) * 0.5e-6, radii, rtol=1e-15)
    groove = data_groove(tmp_path / lammps_deck.DATA_NAME)[:, 1:].reshape(B, n, 2)
    assert np.all(groove[0] != groove[1]) and np.all(groove[1] != groove[2])
    deck = (tmp_path / lammps_deck.DECK_NAME).read_text()
    assert "kt d_groove_kt gamma d_groove_gamma" in deck
    if cs.wall is not None:
        x_last = atoms[n - 1::n, 4]
        assert len(set(x_last)) == B                      # each chain's last sphere its own x
        assert np.all(x_last + atoms[n - 1::n, 2] / 2 > 0)    # each at its own wall overlap
        assert "fix             x0 lasts store/state 0 x" in deck and "x<=f_x0" in deck
    assert len(ref) == len(lmp) == B >= 1
    for b, (r, lt) in enumerate(zip(ref, lmp)):
        rows = member_rows(cs, r, lt)
        bad = [row for row in rows if row["ok"] is False]
        assert not bad, bad
        assert lt.status == r.status == "passed" and lt.t.size == r.t.size
        assert np.abs(lt.v - r.v).max() < 3e-9 * r.v_striker
        np.testing.assert_array_equal(lt.radii, radii[b])
        np.testing.assert_array_equal(r.radii, radii[b])
        if cs.wall is None:
            continue
        F = r.wall_force.max()
        assert np.abs(lt.wall_force - r.wall_force).max() < 1e-9 * F
        # each member's own K_w w_0^1.5 (= F0); the reference states the nominal chain's
        assert lt.wall_static == pytest.approx(r.wall_static, rel=1e-14)
        a, c = summarize(r, cs.probes), summarize(lt, cs.probes)
        assert a.wall_peak_final and c.wall_peak_final
        assert c.wall_force_max == pytest.approx(a.wall_force_max, rel=1e-8)
        assert c.t_wall_peak == pytest.approx(a.t_wall_peak, rel=1e-9)


@pytest.mark.parametrize("wall", ["rigid", "al6061"])
def test_preloaded_spread_chains_at_rest_stay_static(wall, tmp_path):
    """A dead load F0 = 1 N on chains of four materials whose radii are each member's own
    draw (uniform, sd 3 um), striker at rest: every chain holds its own static overlaps
    (F0/K)^(2/3), each contact's K from its own radii, so nothing moves. Measured |v| <=
    4.8e-11 m/s, wall force F0 to 1.1e-13; the same decks with each chain's positions
    built from the nominal chain's static overlaps: |v| up to 5.8e-2 m/s, wall force
    1.6e-2 off."""
    F0 = 1.0
    sc = packed(t_end=20e-6, **{"chain.n": 6, "probes": "[2, 5]", "striker.velocity": 0.0,
                                "chain.materials": "[ss440c, brass, ss440c, tungsten_carbide, "
                                                   "ss316, al6061]",
                                "chain.radius_spread": "{distribution: uniform, sd: 3e-6}",
                                "ensemble.realisations": 3,
                                "walls.end": wall, "precompression.force": F0})
    gaps, vs, radii = spread_members(sc)
    trajs = list(lammps_engine.run(sc, gaps, vs, radii=radii, workdir=tmp_path))
    assert len(trajs) == 3
    for b, t in enumerate(trajs):
        assert t.t[-1] >= 20e-6 and np.abs(t.v).max() < 1e-9
        np.testing.assert_allclose(t.wall_force, F0, rtol=1e-11)
        assert t.wall_static == pytest.approx(F0, rel=1e-14)
        np.testing.assert_array_equal(t.radii, radii[b])
        e_h = t.energy[0, 2]
        assert e_h > 0 and np.abs(t.energy[:, 2] - e_h).max() < 1e-10 * e_h


def test_deck_of_a_spread_scene_holds_each_members_radii(tmp_path):
    """granchain deck on a radius-spread scene writes every member with its own radii
    (gaps.member_radii), and the chapter scenes' decks are unchanged (above); the same
    member re-drawn alone gives the same row."""
    from granchain.cli import main as cli_main
    scene_file = tmp_path / "spread.yaml"
    scene_file.write_text("name: spread\nchain: {n: 15, radius_spread: {sd: 0.5e-6, seed: 7}}\n"
                          "integrator: {method: verlet, dt: 1.0e-9}\n"
                          "ensemble: {realisations: 4}\n")
    assert cli_main(["deck", str(scene_file), "-o", str(tmp_path / "d")]) == 0
    sc = load_scene(scene_file)
    radii = member_radii(sc, members(sc))
    atoms = data_atoms(tmp_path / "d" / lammps_deck.DATA_NAME)
    np.testing.assert_allclose(atoms[:, 2].reshape(4, 15) * 0.5e-6, radii, rtol=1e-15)
    assert len(set(atoms[:, 2])) == 60
    one = data_atoms_text(lammps_deck.render(sc, gaps=member_gaps(sc, members(sc, [2])),
                                             radii=member_radii(sc, members(sc, [2])))[1])
    np.testing.assert_array_equal(one[:, 2], atoms[30:45, 2])


def data_atoms_text(text):
    body = text.split("Atoms # sphere\n\n", 1)[1].split("\n\n", 1)[0]
    return np.array([[float(f) for f in ln.split()[:5]] for ln in body.splitlines()])


@pytest.mark.parametrize("props,word", [
    ("", "names d_gkt, which is not a per-atom floating-point vector"),
    ("fix p all property/atom d_gkt d_gg", "out of range"),          # kt = 0 on atom 1
    ("fix p all property/atom d_gkt d_gg\nset atom 1 d_gkt 5.0\nset atom 1 d_gg -1.0",
     "out of range"),
    ("fix p all property/atom d_gkt d_gg\nset atom 1 d_gkt 5.0", None),
])
def test_per_atom_groove_springs_are_checked(props, word, tmp_path):
    """fix groove/drag kt d_NAME gamma d_NAME: the properties must exist, kt > 0 and
    gamma >= 0 on every atom (one-line LAMMPS error at the run's setup)."""
    from granchain.lammps import LammpsError, build_plugin
    deck = tmp_path / "in.gd"
    deck.write_text(f"""units micro
atom_style sphere
region box block -1000 1000 -1000 1000 -1000 1000
create_box 1 box
create_atoms 1 single 0 0 0
set atom 1 diameter 300 density 7.8
{props}
plugin load {build_plugin()}
fix g all groove/drag groove s 0.7 mu 0.3 g 9.81e-6 kt d_gkt gamma d_gg
run 0
""")
    if word is None:
        run_lammps(deck, tmp_path, timeout=120)
        return
    with pytest.raises(LammpsError) as exc:
        run_lammps(deck, tmp_path, timeout=120)
    msg = str(exc.value)
    assert "\n" not in msg and "ERROR: Fix groove/drag:" in msg and word in msg
