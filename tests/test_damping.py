"""Contact damping (effects/contact_damping.py), LAMMPS ``pair granular`` damping laws on
Hertz contacts: a two-sphere collision gives the requested coefficient of restitution at
any speed (coeff_restitution), the viscoelastic law's documented velocity dependence, a
closed ledger, and one-line refusals."""
from __future__ import annotations

import math

import numpy as np
import pytest

from granchain.effects import contact_damping as cd
from granchain.engines import reference
from granchain.errors import SceneError
from granchain.gaps import member_gaps, members
from granchain.scene import scene_from_dict


def collision(v, damping, method="adaptive", t_end=2e-5, tol=1e-12, **over):
    """Striker at v onto particle 2 of a 3-sphere chain whose third sphere is 1 mm away (it
    never takes part): (trajectory, e = (v2' - v1')/v); ``tol``: the adaptive method's."""
    integ = ({"method": "adaptive", "tolerance": tol} if method == "adaptive"
             else {"method": method, "dt": 2e-10})
    sc = scene_from_dict({"name": "pair", "chain": {"n": 3}, "probes": [2, 3],
                          "effects": ["hertz", "contact_damping"], "damping": damping,
                          "striker": {"velocity": v}, "t_end": t_end, "integrator": integ,
                          "gaps": {"distribution": "list", "values": [0.0, 1e-3]}, **over})
    tr = next(reference.run(sc, member_gaps(sc, members(sc)), np.array([v])))
    return tr, (tr.v[-1, 1] - tr.v[-1, 0]) / v


@pytest.mark.parametrize("e", [0.5, 0.8, 0.95])
def test_coeff_restitution_gives_e_at_every_speed(e):
    """Measured |e_sim - e| over 0.01 to 1 m/s (adaptive, tolerance 1e-12): 3.4e-10."""
    for v in (0.01, 0.1, 1.0):
        _, got = collision(v, {"model": "coeff_restitution", "e": e})
        assert abs(got - e) < 1e-9, (v, got)


def test_undamped_law_is_elastic_and_e_below_one_is_not():
    # measured 2.8e-11 at 1e-13 (2.0e-10 at 1e-12: the adaptive method's steps follow its
    # tolerance alone)
    _, one = collision(0.1, {"model": "coeff_restitution", "e": 1.0}, tol=1e-13)
    assert abs(one - 1.0) < 6e-11
    _, nine = collision(0.1, {"model": "coeff_restitution", "e": 0.9})
    assert abs(nine - 0.9) < 1e-9 and abs(nine - 1.0) > 0.09


def test_viscoelastic_loss_grows_as_the_fifth_root_of_speed():
    """LAMMPS's viscoelastic law eta = eta_n0 m_eff a on Hertz contacts: for weak damping
    1 - e grows as v^(1/5) (Kuwabara-Kono); per decade of speed by 10^(1/5) = 1.585
    (measured 1.585 and 1.586 with RK4 at 0.2 ns)."""
    loss = [1.0 - collision(v, {"model": "viscoelastic", "eta": 1e5}, method="rk4")[1]
            for v in (0.01, 0.1, 1.0)]
    for a, b in zip(loss, loss[1:]):
        assert b / a == pytest.approx(10 ** 0.2, rel=3e-3)


def test_the_peak_lies_above_the_final_speed_and_the_ledger_closes():
    """The net force turns attractive before the contact opens: particle 2 peaks above
    the speed it leaves with (0.9510 against 0.9500 v_s at e = 0.9). The damping work
    closes the balance (RK4: measured 2.7e-11 of E0)."""
    tr, e = collision(0.1, {"model": "coeff_restitution", "e": 0.9}, method="rk4")
    assert tr.v[:, 1].max() / 0.1 == pytest.approx(0.95100, abs=2e-5)
    assert tr.v[-1, 1] / 0.1 == pytest.approx(0.95, abs=2e-6)
    E = tr.energy
    mech = E[:, 0] + E[:, 1] + E[:, 2]
    from granchain.effects import ENERGY_COLUMNS
    wc = ENERGY_COLUMNS.index("work_contact_damping")
    assert E[-1, wc] == pytest.approx(mech[-1] - mech[0], rel=1e-9)
    assert E[-1, wc] < 0
    assert np.max(np.abs(mech - mech[0] - E[:, 3:].sum(axis=1))) / mech[0] < 1e-10


def test_limit_damping_keeps_the_force_repulsive():
    """With limit_damping the net force is held at >= 0: the particle no longer peaks
    above its final speed, and the loss is smaller than without the limit."""
    tr, e_lim = collision(0.1, {"model": "coeff_restitution", "e": 0.5, "limit_damping": True},
                          method="rk4")
    _, e_free = collision(0.1, {"model": "coeff_restitution", "e": 0.5}, method="rk4")
    assert tr.v[:, 1].max() <= tr.v[-1, 1] * (1 + 1e-12)
    assert e_lim > e_free + 0.01


def test_c_of_e_is_lammps_setup():
    """c(e) = -sqrt(3/2) 2 sqrt(5/6) ln e / sqrt(pi^2 + ln^2 e) (LAMMPS's setup), 0 at e = 1."""
    for e in (0.3, 0.8, 0.99):
        lg = math.log(e)
        assert cd.restitution_damp(e) == pytest.approx(
            -math.sqrt(1.5) * 2 * math.sqrt(5 / 6) * lg / math.sqrt(math.pi**2 + lg**2), rel=1e-15)
    assert cd.restitution_damp(1.0) == 0.0


@pytest.mark.parametrize("damping, field, words", [
    ({"model": "coeff_restitution"}, "damping.e", "missing"),
    ({"model": "coeff_restitution", "e": 1.2}, "damping.e", "above 1"),
    ({"model": "coeff_restitution", "e": 0.0}, "damping.e", "must be > 0"),
    ({"model": "viscoelastic"}, "damping.eta", "missing"),
    ({"model": "viscoelastic", "eta": 1.0, "e": 0.9}, "damping.e", "no effect"),
    ({"model": "coeff_restitution", "e": 0.9, "eta": 1.0}, "damping.eta", "no effect"),
    ({"model": "restitution", "e": 0.9}, "damping.model", "did you mean 'coeff_restitution'"),
    ({"model": "tsuji", "e": 0.9, "limit_damping": "yes"}, "damping.limit_damping",
     "true or false"),
])
def test_bad_damping_is_refused_in_one_line(damping, field, words):
    with pytest.raises(SceneError) as info:
        scene_from_dict({"name": "bad", "effects": ["hertz", "contact_damping"],
                         "damping": damping})
    assert info.value.field == field and words in str(info.value), str(info.value)
    assert "\n" not in str(info.value)


def test_a_damped_chain_on_a_wall_ends_at_its_tighter_cap_with_final_peaks():
    """A damped chain against a rigid wall whose last sphere does not come back behind its
    start runs to its (tighter) time cap, flagged timeout, with every peak and the wall's
    peak final."""
    from granchain import stoprule
    from granchain.simulate import run_scene
    sc = scene_from_dict({"name": "w", "walls": {"end": "rigid"},
                          "effects": ["hertz", "contact_damping"], "damping": {"e": 0.5}})
    r = run_scene(sc)[0]
    cap = stoprule.auto_t_max(sc, np.zeros(14), 0.1)
    undamped = stoprule.auto_t_max(scene_from_dict({"name": "u", "walls": {"end": "rigid"}}),
                                   np.zeros(14), 0.1)
    assert cap < undamped / 3            # measured 6.9e-5 s against 2.5e-4 s
    assert r.wall_peak_final and not r.not_final and r.t_end <= cap * (1 + 1e-9)
    assert r.status in ("passed", "timeout")


def test_damping_keys_without_the_effect_are_refused():
    with pytest.raises(SceneError, match="contact_damping is off"):
        scene_from_dict({"name": "bad", "damping": {"e": 0.9}})


def test_a_damped_chain_with_every_effect_closes_its_ledger():
    """A 15-sphere gapped chain with every effect and e = 0.9: balance 2.1e-9 of E0
    (RK4 at 1 ns); damping takes 69 % of the energy (14 inelastic collisions and more)."""
    from granchain.simulate import run_scene
    sc = scene_from_dict({"name": "all", "effects": ["hertz", "rotation", "groove_friction",
                                                     "air_drag", "particle_friction",
                                                     "contact_damping"],
                          "damping": {"e": 0.9},
                          "gaps": {"distribution": "uniform", "mean": 2e-8, "seed": 3}})
    r = run_scene(sc)[0]
    assert r.status == "passed" and r.energy.balance_error < 6e-9
    assert -0.75 < r.energy.work_contact_damping / r.energy.initial < -0.6


def test_a_step_that_cannot_resolve_the_dashpot_is_refused():
    """A stiff viscoelastic dashpot (eta_n0 = 3e13 1/(m s): m_eff/eta ~ 2e-8 s at 0.1 m/s,
    within cd.MAX_DAMPING_RATIO of the collision time) bounds the fixed step as the
    collision does; the same scene at a fine step runs."""
    raw = {"name": "stiff", "effects": ["hertz", "contact_damping"],
           "damping": {"model": "viscoelastic", "eta": 3e13}}
    with pytest.raises(SceneError) as info:
        scene_from_dict(raw)
    assert info.value.field == "integrator.dt" and "dashpot" in str(info.value)
    tau, _ = cd.time_scale(scene_from_dict(dict(raw, integrator={"method": "adaptive"})), 0.1)
    assert 1e-9 < tau < 1e-7
    scene_from_dict(dict(raw, integrator={"method": "rk4", "dt": tau / 25}))


def test_the_wall_force_record_is_the_net_damped_force():
    """With contact damping the recorded wall force is F_el + eta w (the force the wall
    puts on the last sphere): it turns attractive before the contact opens (the elastic
    part never does), held at >= 0 by limit_damping; its impulse equals the chain's
    momentum change (a 3-sphere chain struck onto a rigid wall, e = 0.6, RK4 at 0.1 ns
    sampled every step); and e = 1 gives the Hertz record exactly."""
    from granchain.simulate import run_scene
    plain = run_scene(scene_from_dict({"name": "w", "walls": {"end": "rigid"}, "t_end": 2e-5}))[0]
    one = run_scene(scene_from_dict({"name": "w", "walls": {"end": "rigid"}, "t_end": 2e-5,
                                     "effects": ["hertz", "contact_damping"],
                                     "damping": {"e": 1.0}}))[0]
    assert one.wall_force_max == plain.wall_force_max
    sc = scene_from_dict({"name": "bounce", "chain": {"n": 3}, "probes": [2, 3],
                          "walls": {"end": "rigid"}, "effects": ["hertz", "contact_damping"],
                          "damping": {"e": 0.6}, "t_end": 6e-6,      # the last contact opens at 4.0 us
                          "output": {"sample_dt": 1e-10},
                          "integrator": {"method": "rk4", "dt": 1e-10}})
    tr = next(reference.run(sc, np.zeros((1, 2)), np.array([0.1])))
    impulse = np.trapezoid(tr.wall_force, tr.t)
    p0, p1 = 0.1 * sc.masses[0], float(np.dot(sc.masses, tr.v[-1]))
    assert tr.wall_force[-1] == 0.0 and p1 < 0           # the chain bounced off the wall
    assert impulse == pytest.approx(p0 - p1, rel=1e-6)
    assert tr.wall_force.min() < -1e-3 * tr.wall_force.max()
    lim = scene_from_dict(dict(sc.spec, name="lim", damping={"e": 0.6, "limit_damping": True},
                               measurement=None), check_unused=False)
    tl = next(reference.run(lim, np.zeros((1, 2)), np.array([0.1])))
    assert tl.wall_force.min() == 0.0 and tl.wall_force.max() > 0
