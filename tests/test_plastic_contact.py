"""plastic_contact (effects/plastic_contact.py): Thornton's (1997) elastic-perfectly
plastic normal contact on the reference engine, and against LAMMPS (the plugin's fix
thornton/chain).

The independent solution (tests/independent.py, ``ThorntonContact``: the paper's law
written there, a collision's outcome from its branches' energies by quadrature, no time
stepping) first checks Thornton's closed form e(v/v_y) against the law. Then the engine
(RK4) is run on the two-sphere collision: a chain of three whose third sphere lies 1 mm
away (not reached within the run; tests/test_collisions.py runs two-sphere scenes), so
the striker and particle 2 collide alone. Measured at dt = 1e-10 s over v/v_y = 0.5-30 (ss316 pairs,
equal and unequal spheres, a 440C striker on 316): |e - e_Thornton| <= 3.8e-9 (3e-14
below v_y, where e = 1), the ledger's balance <= 1.9e-9 of E0, its work column the
independent dissipation to <= 1.2e-8 (exactly 0 below v_y); the errors of RK4 and of
the largest overlap read at step ends (O(dt^2)). A contact struck twice: see its test.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from granchain.effects import ENERGY_COLUMNS
from granchain.errors import SceneError
from granchain.gaps import members
from granchain.materials import library
from granchain.observables import energy_ledger
from granchain.scene import scene_from_dict
from granchain.simulate import trajectories

from independent import ThorntonContact, thornton_restitution

LIB = library()
R = 150e-6


def _star(ma, Ra, mb, Rb):
    """(E*, R*, m*) of two spheres, from the handbook numbers."""
    Es = 1.0 / ((1 - ma.nu ** 2) / ma.E + (1 - mb.nu ** 2) / mb.E)
    m1, m2 = (4.0 / 3.0 * math.pi * r ** 3 * m.rho for m, r in ((ma, Ra), (mb, Rb)))
    return Es, Ra * Rb / (Ra + Rb), m1 * m2 / (m1 + m2)


def _scene(v, radii=(R, R, R), mats=("ss316",) * 3, gap=1e-3, t_end=6e-6, **extra):
    d = {"name": "plastic", "chain": {"n": 3, "radius": list(radii), "materials": list(mats)},
         "striker": {"velocity": v}, "effects": ["hertz", "plastic_contact"],
         "gaps": {"distribution": "list", "values": [0.0, gap]}, "probes": [2, 3],
         "integrator": {"method": "rk4", "dt": 1e-10}, "t_end": t_end}
    d.update(extra)
    return scene_from_dict(d)


def _run(sc):
    (_, tr), = list(trajectories(sc, members(sc)))
    assert tr.status in ("done", "passed"), tr.status
    return tr


# ---------------------------------------------------------------------------------------
# the independent solution checks Thornton's closed form
@pytest.mark.parametrize("r", [1.001, 1.5, 2.0, 10.0, 30.0, 300.0])
def test_thornton_closed_form_is_the_law(r):
    """The closed form e(v/v_y) is the law's own restitution (measured 2e-15)."""
    c = ThorntonContact(106e9, 75e-6, 464e6)
    m = 5.6e-8
    e, dm, W = c.collide(m, r * c.yield_speed(m))
    assert abs(e - thornton_restitution(r)) < 1e-12
    assert dm > c.dy and W > 0.0
    assert abs(c.collide(m, 0.999 * c.yield_speed(m))[0] - 1.0) < 1e-14


# ---------------------------------------------------------------------------------------
# the two-sphere collision on the engine
PAIRS = {"equal_316": ((R, R, R), ("ss316",) * 3),
         "189um_striker_316": ((189e-6, R, R), ("ss316",) * 3),
         "440c_striker_on_316": ((R, R, R), ("ss440c", "ss316", "ss316"))}


def _contact(pair):
    radii, mats = PAIRS[pair]
    ma, mb = LIB[mats[0]], LIB[mats[1]]
    Es, Rs, m = _star(ma, radii[0], mb, radii[1])
    py = min(ma.yield_pressure, mb.yield_pressure)    # the softer body's
    return ThorntonContact(Es, Rs, py), m


@pytest.mark.parametrize("pair", list(PAIRS))
@pytest.mark.parametrize("r", [0.5, 2.0, 10.0, 30.0])
def test_two_sphere_restitution_is_thorntons(pair, r):
    """e = (v2 - v1)/v after the collision against Thornton's e(v/v_y) (1 below v_y);
    the ledger closes and its work column is the independent dissipation (0 below v_y)."""
    c, m = _contact(pair)
    v = r * c.yield_speed(m)
    radii, mats = PAIRS[pair]
    tr = _run(_scene(v, radii, mats))
    e = (tr.v[-1, 1] - tr.v[-1, 0]) / v
    assert abs(e - thornton_restitution(r)) < 1e-8, (e, thornton_restitution(r))
    led = energy_ledger(tr)
    assert led.balance_error < 5e-9
    _, _, W = c.collide(m, v)
    if r < 1.0:
        assert led.work_plastic_contact == 0.0
    else:
        assert led.work_plastic_contact == pytest.approx(-W, rel=3e-8, abs=0.0)
    # the contact has opened: no elastic energy left, and the work only ever dissipates
    assert led.hertz_potential == 0.0
    col = tr.energy[:, ENERGY_COLUMNS.index("work_plastic_contact")]
    assert np.all(np.diff(col) <= 1e-12 * led.initial)


# ---------------------------------------------------------------------------------------
# a contact struck twice: particle 2 rebounds from a heavy third sphere into the striker
def _segments(v1):
    """(first, last) sample indices of each stretch where particle 1's velocity changes
    (its collisions with particle 2, its only neighbour)."""
    ch = np.nonzero(np.abs(np.diff(v1)) > 1e-12)[0]
    out, start, prev = [], ch[0], ch[0]
    for c in ch[1:]:
        if c > prev + 2:
            out.append((start, prev))
            start = c
        prev = c
    return out + [(start, prev)]


@pytest.mark.parametrize("striker, elastic", [(130e-6, True), (150e-6, False)])
def test_a_contact_struck_twice_reloads_along_its_unloading_curve(striker, elastic):
    """The second collision of particles 1 and 2, at the closing speed u2 the engine
    gives it: within the energy the first left in the contact's unloading curve it is
    elastic (e = 1: a 130 um striker), beyond it reloads elastically to the first
    collision's largest overlap and then plastically (a 150 um striker: e2 = 0.84, where
    a contact without its history would give Thornton's 0.57). Measured: e2 - 1 =
    1.9e-11 (130 um), |e2 - solution| = 2.4e-9 (150 um); the first collision's e to
    <= 3.5e-9."""
    v = 0.1
    radii, mats = (striker, R, 450e-6), ("ss316",) * 3
    tr = _run(_scene(v, radii, mats, gap=2e-7, t_end=2e-5))
    segs = _segments(tr.v[:, 0])
    assert len(segs) == 2, segs
    Es, Rs, m = _star(LIB["ss316"], striker, LIB["ss316"], R)
    c = ThorntonContact(Es, Rs, LIB["ss316"].yield_pressure)
    e1, dm, _ = c.collide(m, v)
    (a1, b1), (a2, b2) = segs
    assert (tr.v[b1 + 2, 1] - tr.v[b1 + 2, 0]) / v == pytest.approx(e1, abs=5e-9)
    before, after = tr.v[a2 - 1], tr.v[b2 + 2]
    assert before[2] == after[2]                 # particle 3 is not touched meanwhile
    u2 = before[0] - before[1]
    got = (after[1] - after[0]) / u2
    e2, _, _ = c.collide(m, u2, dm)
    assert (e2 == 1.0) == elastic
    assert abs(got - e2) < 5e-9, (got, e2)
    fresh = c.collide(m, u2)[0]                  # the same speed on a virgin contact
    assert abs(got - fresh) > 0.05


# ---------------------------------------------------------------------------------------
# the scene
def test_keys_are_refused_while_the_effect_is_off():
    with pytest.raises(SceneError, match="plasticity.yield_pressure"):
        scene_from_dict({"plasticity": {"yield_pressure": 1e9}})


@pytest.mark.parametrize("extra, field", [
    ({"effects": ["hertz", "rotation", "particle_friction", "plastic_contact"]}, "effects"),
    ({"effects": ["hertz", "adhesion", "plastic_contact"],
      "adhesion": {"model": "dmt", "surface_energy": 0.1}}, "effects"),
    ({"effects": ["hertz", "contact_damping", "plastic_contact"],
      "damping": {"e": 0.9, "limit_damping": True}}, "damping.limit_damping"),
    ({"material": "brass"}, "plasticity.yield_pressure"),
    ({"plasticity": {"yield_pressure": 1.0}}, "plasticity.yield_pressure"),
    ({"walls": {"end": "rigid"}, "precompression": {"force": 1.0}}, "precompression.force"),
])
def test_what_it_cannot_act_with_is_refused_in_one_line(extra, field):
    d = {"effects": ["hertz", "plastic_contact"], **extra}
    with pytest.raises(SceneError) as err:
        scene_from_dict(d)
    assert err.value.field == field
    assert "\n" not in str(err.value)


def test_a_scene_yield_pressure_replaces_the_materials():
    """brass has no sourced yield pressure: the scene's is taken, at every contact."""
    sc = scene_from_dict({"effects": ["hertz", "plastic_contact"], "material": "brass",
                          "plasticity": {"yield_pressure": 5e8}})
    from granchain.effects import physics_terms
    assert set(physics_terms(sc).plastic_contact.pressures[:-1]) == {5e8}


# ---------------------------------------------------------------------------------------
# against LAMMPS (the plugin's fix thornton/chain): granchain compare, velocity Verlet at
# 1 ns. The plastic work is LAMMPS's own output (not its balance residual), the potential
# column and the wall force carry the fix's parts.
LAMMPS_CHAINS = {
    # 440C above its yield onset (v_y = 0.44 m/s at these contacts), beside the groove/drag
    # fix (rotation, groove friction, air drag)
    "440c-fast": {"material": "ss440c", "striker": {"velocity": [0.5, 1.0]}, "t_end": 1.2e-5,
                  "effects": ["hertz", "rotation", "groove_friction", "air_drag",
                              "plastic_contact"]},
    # annealed 316 at 14 v_y on a rigid wall
    "316-wall": {"material": "ss316", "striker": {"velocity": 0.05}, "walls": {"end": "rigid"},
                 "t_end": 3e-5},
    # a dead load below F_y on a 316 wall, with contact damping (its dashpot as without
    # plasticity, LAMMPS's balance residual)
    "316-preload-damped": {"material": "ss316", "striker": {"velocity": 0.05},
                           "walls": {"end": "ss316"}, "precompression": {"force": 1e-4},
                           "effects": ["hertz", "contact_damping", "plastic_contact"],
                           "damping": {"e": 0.9}, "t_end": 3e-5},
    # unequal spheres and materials (each contact's E*, R*, p_y), on a 440C wall
    "unequal": {"chain": {"n": 6, "radius": [150e-6, 120e-6, 150e-6, 100e-6, 150e-6, 130e-6],
                          "materials": ["ss440c", "ss316", "ss440c", "ss316", "ss316",
                                        "ss440c"]},
                "probes": [2, 5], "walls": {"end": "ss440c"}, "striker": {"velocity": 0.2},
                "t_end": 2e-5},
}


@pytest.mark.lammps
@pytest.mark.parametrize("name, nprocs", [(k, 1) for k in LAMMPS_CHAINS] + [("316-wall", 2)])
def test_chains_agree_with_lammps(name, nprocs, tmp_path):
    """Both engines yield the contacts alike: v_max, v_g, the ledger (the plastic work,
    the balance), and with a wall its force, to rounding (measured <= 6.1e-10 on v_max and
    v_g; the tolerances of granchain.compare elsewhere). On two ranks the chain is cut
    along x, so contacts join atoms of different ranks (the fix's ghost history)."""
    from granchain.compare import compare
    spec = {"name": name, "chain": {"n": 8}, "probes": [2, 7],
            "integrator": {"method": "verlet", "dt": 1e-9},
            "effects": ["hertz", "plastic_contact"], **LAMMPS_CHAINS[name]}
    cmp = compare(scene_from_dict(spec), workdir=tmp_path / "lmp", nprocs=nprocs)
    assert cmp.ok, cmp.failures().to_string()
    rows = cmp.rows
    v = rows[rows.quantity.str.startswith("v_max") | rows.quantity.str.startswith("v_g")]
    assert len(v) > 0 and v["diff"].max() < 2e-9
    # the law yielded and LAMMPS reported its work itself (an independent row)
    work = rows[rows.quantity == "work_plastic_contact"]
    initial = rows[rows.quantity == "initial"]
    assert len(work) == len(initial) > 0
    assert np.all(work.lammps.to_numpy() < -1e-4 * initial.lammps.to_numpy())
    assert np.all(work.tolerance.to_numpy() > 0)
    if "walls" in LAMMPS_CHAINS[name]:
        wall = rows[rows.quantity == "wall_force_max"]
        assert len(wall) > 0 and np.all(wall.lammps.to_numpy() > 0)


# ---------------------------------------------------------------------------------------
# a packed chain on an end wall: the ledger closes with the plastic work of every contact
# and of the wall (measured at dt = 1e-10 s: <= 1.6e-9 of E0; the plastic work 70-88 % of
# E0 at 0.05 m/s, 14 v_y)
WALLED = {"wall": ("rk4", {}), "wall_verlet": ("verlet", {}),
          "preload": ("rk4", {"precompression": {"force": 1e-4}}),
          "damped": ("rk4", {"effects": ["hertz", "contact_damping", "plastic_contact"],
                             "damping": {"e": 0.9}})}


@pytest.mark.parametrize("case", list(WALLED))
def test_the_ledger_closes_on_a_walled_chain(case):
    method, extra = WALLED[case]
    d = {"name": "walled", "chain": {"n": 5}, "material": "ss316",
         "striker": {"velocity": 0.05}, "effects": ["hertz", "plastic_contact"],
         "walls": {"end": "rigid"}, "probes": [2, 5],
         "integrator": {"method": method, "dt": 1e-10}, "t_end": 1.5e-5, **extra}
    tr = _run(scene_from_dict(d))
    led = energy_ledger(tr)
    assert led.balance_error < 5e-9
    assert -0.9 < led.work_plastic_contact / led.initial < -0.6
    assert np.max(tr.wall_force) > 0.0


def test_method_auto_plans_a_plastic_chain_the_law_accepts():
    """Method auto on a gapped plastic chain (a 316 chain at 500 nm gaps and 0.03-0.1 m/s,
    as the grid of ``infer --fit gap_mean,plasticity.yield_pressure`` plans at its
    default largest mean gap) plans a setting the law accepts: its check passes on the
    planned scene."""
    from granchain.effects import plastic_contact
    from granchain.runplan import plan_run
    sc = scene_from_dict({"name": "p", "material": "ss316", "striker": {"velocity": [0.03, 0.1]},
                          "gaps": {"distribution": "uniform", "mean": 500e-9},
                          "effects": ["hertz", "plastic_contact"],
                          "plasticity": {"model": "thornton", "yield_pressure": 1e9},
                          "integrator": {"method": "auto", "tolerance": 1e-3}})
    planned = plan_run(sc, per_speed=False).scene
    assert planned.method != "auto"
    plastic_contact.check(planned)


# ---------------------------------------------------------------------------------------
# the event method: its steps end on the law's switches (plastic_contact.locate: yield, the
# largest overlap, delta_p), so its error bound holds across them
EVENT_TOLS = (1e-5, 1e-8)
# |e - e_Thornton| and the ledger's balance at each tolerance, bound EVENT_BOUND x the
# tolerance. Measured on the equal 316 pair over the speeds below: 4.3e-8 at 1e-8, 2.7e-6
# at 1e-6; with the switches left to the error control (no locate): up to 2.6e-2 (2.4e-3
# to 8.9e-3 at 1e-8)
EVENT_BOUND = 10.0


def _event(tol):
    return {"integrator": {"method": "event", "tolerance": tol}}


@pytest.mark.parametrize("pair", list(PAIRS))
@pytest.mark.parametrize("r", [0.5, 2.0, 10.0, 30.0])
def test_event_two_sphere_collision_is_thorntons(pair, r):
    """The event method's e against Thornton's e(v/v_y) and against RK4 at 0.1 ns (itself
    within 3.8e-9 of it), within EVENT_BOUND times the tolerance, the error falling with
    it; the ledger closes as tightly and its work is the independent dissipation (to
    EVENT_BOUND times the tolerance of E0)."""
    c, m = _contact(pair)
    v = r * c.yield_speed(m)
    radii, mats = PAIRS[pair]
    want = thornton_restitution(r)
    rk4 = _run(_scene(v, radii, mats))
    e_rk4 = (rk4.v[-1, 1] - rk4.v[-1, 0]) / v
    errs = []
    for tol in EVENT_TOLS:
        tr = _run(_scene(v, radii, mats, **_event(tol)))
        e = (tr.v[-1, 1] - tr.v[-1, 0]) / v
        assert abs(e - want) < EVENT_BOUND * tol, (tol, e, want)
        assert abs(e - e_rk4) < EVENT_BOUND * tol + 4e-9, (tol, e, e_rk4)
        led = energy_ledger(tr)
        assert led.balance_error < EVENT_BOUND * tol
        _, _, W = c.collide(m, v)
        if r < 1.0:
            assert led.work_plastic_contact == 0.0
        else:
            assert abs(led.work_plastic_contact + W) < EVENT_BOUND * tol * led.initial
        errs.append(abs(e - want))
    assert errs[1] < errs[0]


def _chain(method):
    """15 annealed 316 spheres (v_y about 1 mm/s), 20 nm gaps, struck at 0.02 m/s."""
    d = {"name": "plastic-chain", "material": "ss316", "chain": {"n": 15}, "probes": [2, 14],
         "effects": ["hertz", "plastic_contact"], "striker": {"velocity": 0.02},
         "gaps": {"distribution": "uniform", "mean": 2e-8, "seed": 3}, "t_end": 4e-5,
         "integrator": method}
    sc = scene_from_dict(d)
    from granchain.engines import reference
    from granchain.gaps import member_gaps
    mem = members(sc)
    (tr,) = reference.run(sc, member_gaps(sc, mem), np.array([m.v_striker for m in mem]),
                          progress=False, trace=False)
    return tr


def test_event_chain_agrees_with_fine_rk4():
    """A 15-sphere plastic chain by the event method against RK4 at 0.1 ns (within 9e-10
    of RK4 at 0.02 ns): every sphere's v_max and final velocity and the ledger's plastic
    work. Measured at tolerance 1e-8: v_max 1.0e-6, v_final 3.6e-7 of v_s, balance
    1.5e-6 (the global error of some 300 steps); at 1e-5: 2.9e-5, 1.0e-5, 1.0e-5."""
    rk4 = _chain({"method": "rk4", "dt": 1e-10})
    vm = np.array(rk4.observed.v_max)
    errs = []
    for tol, bound in ((1e-5, 1e-4), (1e-8, 5e-6)):
        ev = _chain({"method": "event", "tolerance": tol})
        assert ev.status == "done"
        err = np.abs(np.array(ev.observed.v_max) / vm - 1).max()
        assert err < bound, (tol, err)
        assert np.abs(ev.v[-1] - rk4.v[-1]).max() < bound * 0.02
        assert ev.observed.balance_error < bound
        led, led_rk4 = energy_ledger(ev), energy_ledger(rk4)
        assert led_rk4.work_plastic_contact < -0.1 * led_rk4.initial
        assert abs(led.work_plastic_contact - led_rk4.work_plastic_contact) < bound * led.initial
        errs.append(err)
    assert errs[1] < errs[0]
