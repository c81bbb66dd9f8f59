"""The event method (engines/events.py): agreement with DOP853 truth, on-the-fly
observables against its own sampled trace, batch independence, and the force-evaluation
counts of every reference method."""
import math

import numpy as np
import pytest

from granchain.errors import SceneError
from granchain.gaps import members
from granchain.observables import sampled_peaks, summarize
from granchain.simulate import run_scene, trajectories

from conftest import packed, run1

ALL = "[hertz,groove_friction,air_drag,rotation,particle_friction]"
SHORT = {"chain.n": 10, "probes": "[2, 9]"}
CASES = {
    "packed": {},
    "20nm": {"gaps": "{distribution: uniform, mean: 2.0e-8, seed: 3}"},
    "190nm": {"striker.velocity": 0.01, "gaps": "{distribution: uniform, mean: 1.9e-7, seed: 3}"},
    "1um": {"striker.velocity": 0.01, "gaps": "{distribution: uniform, mean: 1.0e-6, seed: 3}"},
    "190nm-all-effects": {"effects": ALL, "striker.velocity": 0.01,
                          "gaps": "{distribution: uniform, mean: 1.9e-7, seed: 3}"},
}
TOL = 1e-8
# The tolerance bounds each step's local error; over the run's 10^2-10^3 steps the
# global error accumulates (the truth, adaptive at 1e-10, closes its own ledger only
# to ~1e-7). Measured at TOL on these cases: v_max <= 2.1e-6, v_g_front <= 1.7e-6 (the
# truth's front times are linear interpolations between samples), v_g <= 5.8e-6 (peak
# times of plateaus), balance error <= 1.6e-6.
BOUND = {"v_max": 1e-5, "v_g": 2e-5, "v_g_front": 1e-5, "balance": 1e-5}


def _event(over, tol=TOL, **kw):
    return packed(**SHORT, **over, **{"integrator.method": "event", "integrator.tolerance": tol})


@pytest.mark.parametrize("case", list(CASES))
def test_event_agrees_with_dop853_truth(case):
    over = CASES[case]
    truth = run1(packed(**SHORT, **over, **{"integrator.method": "adaptive",
                                             "integrator.tolerance": 1e-10}))
    ev = run1(_event(over))
    assert truth.wave_arrived and ev.wave_arrived and ev.status == "passed"
    assert ev.final == truth.final
    for a, b in zip(ev.v_max, truth.v_max):
        assert abs(a / b - 1) < BOUND["v_max"], (a, b)
    assert abs(ev.v_g / truth.v_g - 1) < BOUND["v_g"]
    assert abs(ev.v_g_front / truth.v_g_front - 1) < BOUND["v_g_front"]
    assert ev.energy.balance_error < BOUND["balance"]
    for name in ("work_groove_friction", "work_air_drag", "work_particle_friction"):
        assert getattr(ev.energy, name) == pytest.approx(getattr(truth.energy, name),
                                                        rel=1e-4, abs=1e-6 * truth.energy.initial)
    # probes' peak kinds agree (the last particle's plateau is decided by when each
    # method stops, at the release step end or at the next sample)
    assert ev.plateau[1] == truth.plateau[1] and ev.plateau[8] == truth.plateau[8]
    # the point of the method: far fewer force evaluations than DOP853 on the sample grid
    assert ev.force_evaluations < truth.force_evaluations


@pytest.mark.parametrize("case", ["20nm", "190nm", "190nm-all-effects"])
def test_on_the_fly_observables_match_its_own_trace(case):
    sc = _event(CASES[case])
    (_, traj), = list(trajectories(sc, members(sc), trace=True))
    assert traj.t.size > 100 and np.allclose(np.diff(traj.t), traj.info.sample_dt)
    r = summarize(traj, sc.probes)
    vm, tp, tf, pl, fi = sampled_peaks(traj)
    sdt = traj.info.sample_dt
    assert list(fi) == list(r.final)
    assert list(pl[:-1]) == list(r.plateau[:-1])
    ok = np.isfinite(vm)
    assert np.all(np.abs(np.array(r.v_max)[ok] / vm[ok] - 1) < 1e-5)
    # front: both the first crossing of v_max / 2, refined below the sample spacing
    assert np.all(np.abs(np.array(r.t_front)[ok] - tf[ok]) < 0.01 * sdt)
    # peak time: within the sample spacing (the sampled rule refines by a parabola)
    assert np.all(np.abs(np.array(r.t_peak)[ok] - tp[ok]) < sdt)
    # without a trace the record holds only the first and last states
    (_, bare), = list(trajectories(sc, members(sc)))
    assert bare.t.size == 2 and bare.t[-1] == pytest.approx(traj.info.t_last)
    rb = summarize(bare, sc.probes)
    assert rb.v_max == r.v_max and rb.t_front == r.t_front
    assert rb.energy.balance_error == r.energy.balance_error


def test_chain_alone_is_bit_identical_to_the_same_chain_in_a_batch():
    sc = _event({"striker.velocity": 0.01, "ensemble.realisations": 3, "effects": ALL,
                 "gaps": "{distribution: uniform, mean: 1.9e-7, seed: 3}"}, tol=1e-6)
    batch = run_scene(sc)
    alone = run_scene(sc, realisations=[1])[0]
    b = batch[1]
    assert b.realisation == alone.realisation == 1
    for key in ("v_max", "t_peak", "t_front", "plateau", "final", "steps", "rejected_steps",
                "force_evaluations", "v_g", "v_g_front"):
        assert getattr(b, key) == getattr(alone, key) or (
            isinstance(getattr(b, key), float) and math.isnan(getattr(b, key))
            and math.isnan(getattr(alone, key))), key
    assert b.energy == alone.energy
    # the three realisations are different chains
    assert batch[0].v_g_front != batch[1].v_g_front


@pytest.mark.parametrize("method, per_step, setup", [("rk4", 4, 0), ("verlet", 1, 1)])
def test_force_evaluations_of_fixed_step_methods(method, per_step, setup):
    dt, t_end = 2e-9, 2e-6
    r = run1(packed(**{"integrator.method": method, "integrator.dt": dt, "t_end": t_end,
                       "output.sample_dt": 2e-8}))
    steps = round(t_end / dt)
    assert r.steps == steps
    assert r.force_evaluations == per_step * steps + setup


def test_force_evaluations_of_adaptive_methods_grow_with_accuracy():
    over = CASES["190nm"]
    loose, tight = (run1(_event(over, tol)) for tol in (1e-5, 1e-8))
    assert loose.force_evaluations < tight.force_evaluations
    # every accepted or rejected trial costs at least the pair's stages
    assert tight.force_evaluations >= 12 * (tight.steps + tight.rejected_steps)
    ad = run1(packed(**SHORT, **over, **{"integrator.method": "adaptive",
                                          "integrator.tolerance": 1e-6}))
    assert ad.force_evaluations >= 12 * (ad.steps + ad.rejected_steps)


# The adaptive method on the packed chain and on 20 nm gaps (Hertz only, 0.1 m/s) against
# the independent solution (scipy's DOP853 at rtol 1e-12, dense output): every sphere's
# velocity at every sample, most of them taken inside a step from DOP853's dense output.
# Measured at 1e-12 (214 and 479 steps for 1213 and 1472 samples): 2.3e-9 and 9.0e-9 of
# v_s; at 1e-10 the run's global error shows (2.3e-8 and 6.1e-7).
DENSE_BOUND = 3e-8


@pytest.mark.parametrize("window", [None, 64])
@pytest.mark.parametrize("case", ["packed", "20nm"])
def test_adaptive_steps_as_its_tolerance_allows_and_samples_its_dense_output(case, window,
                                                                              monkeypatch):
    """``window``: samples per kernel call (None: the engine's); at 64 a run takes about
    twenty calls, and a step ends at each call's last sample."""
    from granchain.engines import reference
    from granchain.gaps import realise

    if window is not None:
        monkeypatch.setattr(reference, "WINDOW", window)

    from independent import SS440C, hertz_chain_peaks

    over = CASES[case]
    loose = run1(packed(**over, **{"integrator.method": "adaptive", "integrator.tolerance": 1e-3}))
    # its steps follow its tolerance, not the sample grid (about 1200 samples here)
    assert loose.steps < loose.samples / 20, (loose.steps, loose.samples)
    sc = packed(**over, **{"integrator.method": "adaptive", "integrator.tolerance": 1e-12})
    (_, tr), = list(trajectories(sc, members(sc)))
    assert tr.status == "passed" and (window is None or len(tr.t) > 16 * window)
    # most samples lie inside a step
    assert tr.steps < 0.5 * len(tr.t), (tr.steps, len(tr.t))
    E, nu, rho = SS440C
    g = realise(sc, 0) if over else None
    ind = hertz_chain_peaks(E, nu, rho, sc.radius, sc.n, 0.1, gaps=g, probes=(2,),
                            t_end=float(tr.t[-1]), rtol=1e-12)
    err = max(np.abs(tr.v[:, i] - ind.velocity(i + 1, tr.t)).max() for i in range(sc.n))
    assert err / 0.1 < DENSE_BOUND, err / 0.1


def test_event_scene_validation():
    sc = packed(**{"integrator.method": "event"})
    assert sc.tolerance == 1e-6
    with pytest.raises(SceneError, match="integrator.tolerance"):
        packed(**{"integrator.method": "event", "integrator.tolerance": 0.5})


# The event method on a long gapped chain (50 spheres, Hertz only, uniform gaps of mean
# 20 nm, 0.1 m/s, tolerance TOL) against the independent solution (tests/independent.py,
# scipy DOP853 at rtol 1e-10, whose own v_max error here is 1.5e-7 against rtol 1e-12).
# Measured: v_max of every particle within 3.0e-6 (probes: 1.3e-7 and 2.8e-6), peak and
# front times within 0.025 ns (of ~47 us), v_g 5.3e-7, v_g_front 5.0e-7.
LONG = {"chain.n": 50, "probes": "[2, 49]", "gaps": "{distribution: uniform, mean: 2.0e-8, seed: 3}"}
LONG_BOUND = {"v_max": 1e-5, "time": 0.075e-9, "v_g": 1.6e-6, "v_g_front": 1.5e-6}


def test_event_agrees_with_the_independent_solution_on_a_50_sphere_gapped_chain():
    from granchain.gaps import realise
    from granchain.observables import PEAK_TOL

    from independent import SS440C, hertz_chain_peaks

    sc = packed(**LONG, **{"integrator.method": "event", "integrator.tolerance": TOL})
    E, nu, rho = SS440C
    assert (sc.material.E, sc.material.nu, sc.material.rho) == (E, nu, rho)
    n, two_r = sc.n, 2 * sc.radius
    g = realise(sc, 0)
    r = run1(sc)
    assert r.status == "passed" and r.wave_arrived and all(r.final)
    # the independent run lasts 1.3x as long as the event run needed for final peaks
    ind = hertz_chain_peaks(E, nu, rho, sc.radius, n, 0.1, gaps=g, probes=tuple(range(1, n + 1)),
                            t_end=6e-5, rtol=1e-10)
    assert r.t_end < 6e-5 / 1.25
    v_max = np.array(r.v_max)
    assert np.abs(v_max / ind.v_max - 1).max() < LONG_BOUND["v_max"]
    # peak times: sharp peaks at the maximum, plateaus (free flight across a gap) where the
    # velocity first reaches (1 - PEAK_TOL) v_max, as observables.peak defines them
    plateau = np.array(r.plateau)
    t_peak = np.array([ind.crossing(i + 1, (1 - PEAK_TOL) * ind.v_max[i]) if plateau[i]
                       else ind.t_peak[i] for i in range(n)])
    assert np.abs(np.array(r.t_peak) - t_peak)[1:].max() < LONG_BOUND["time"]
    assert np.abs(np.array(r.t_front) - ind.t_front)[1:].max() < LONG_BOUND["time"]
    p1, p2 = sc.probes
    span = (p2 - p1) * (two_r + g[p1 - 1:p2 - 1].mean())
    v_g = span / (t_peak[p2 - 1] - t_peak[p1 - 1])
    v_g_front = span / (ind.t_front[p2 - 1] - ind.t_front[p1 - 1])
    assert abs(r.v_g / v_g - 1) < LONG_BOUND["v_g"], (r.v_g, v_g)
    assert abs(r.v_g_front / v_g_front - 1) < LONG_BOUND["v_g_front"], (r.v_g_front, v_g_front)


def test_a_chain_longer_than_the_record_buffer_keeps_its_observables():
    """More spheres than record steps kept per particle (``codes.RB_SIZE``): each
    particle's buffer is its own, merged only when it is full, and the on-the-fly
    observables still match the chain's own trace (60 spheres, 20 nm gaps)."""
    from granchain.engines.codes import RB_SIZE
    n = 60
    assert n > RB_SIZE
    sc = packed(**{"chain.n": n, "probes": f"[2, {n - 1}]", "integrator.method": "event",
                   "integrator.tolerance": TOL,
                   "gaps": "{distribution: uniform, mean: 2.0e-8, seed: 3}"})
    (_, traj), = list(trajectories(sc, members(sc), trace=True))
    r = summarize(traj, sc.probes)
    vm, tp, tf, pl, fi = sampled_peaks(traj)
    sdt = traj.info.sample_dt
    ok = np.isfinite(vm)
    assert ok.sum() > RB_SIZE
    assert np.all(np.abs(np.array(r.v_max)[ok] / vm[ok] - 1) < 1e-5)
    assert np.all(np.abs(np.array(r.t_front)[ok] - tf[ok]) < 0.01 * sdt)
    assert np.all(np.abs(np.array(r.t_peak)[ok] - tp[ok]) < sdt)


def test_plateau_rule_counts_the_grid_samples_of_a_continuous_run():
    """One plateau rule for sampled records and continuous runs (``obsrules``): a flat top
    of 5 to 6.2 sample intervals, sampled at many phases of the grid, is a plateau to the
    sampled rule (``observables.peak``: more than PLATEAU_SAMPLES samples near the top)
    exactly when its continuous near-peak run holds more than PLATEAU_SAMPLES grid
    instants (``obsrules.grid_samples``, the event method's rule). Its length alone
    (> PLATEAU_SAMPLES intervals, the event method's earlier rule) classes some of these
    runs as plateaus that the sampled rule does not."""
    from granchain import obsrules
    from granchain.observables import peak
    dt = 1e-8
    t = np.arange(200) * dt
    by_length = 0
    for span in (5.05, 5.3, 5.5, 5.8, 5.95, 6.2):
        for phase in np.linspace(0.0, 1.0, 17)[:-1]:
            t_in = (50.0 + phase) * dt
            t_out = t_in + span * dt
            # rises to 1 over 20 intervals, flat on [t_in, t_out], falls over 20
            v = np.interp(t, [0.0, t_in - 20 * dt, t_in, t_out, t_out + 20 * dt, t[-1]],
                          [0.0, 0.0, 1.0, 1.0, 0.0, 0.0])
            # the exact run above the near level (the slopes are 1 / (20 dt))
            lo = obsrules.near_level(1.0)
            a = t_in - (1.0 - lo) * 20 * dt
            b = t_out + (1.0 - lo) * 20 * dt
            sampled = peak(t, v)[3]
            assert sampled == obsrules.plateau(obsrules.grid_samples(a, b, dt)), (span, phase)
            by_length += sampled != ((b - a) > obsrules.PLATEAU_SAMPLES * dt)
    assert by_length > 0


def _event_observables(v, x, a, t_end, h, sample_dt):
    """The event method's on-the-fly observables (``eventobs._observe``, then
    ``finalize``) of one particle whose velocity is v(t) (displacement x(t), acceleration
    a(t)), fed in steps of h as the engine feeds its accepted steps."""
    from granchain.engines import codes, eventobs
    LO = np.full(codes.L_LEN, -1, dtype=np.int64)
    LO[codes.L_DISP], LO[codes.L_VEL] = 0, 1
    VMAX, TPK, VINIT = np.full((1, 1), v(0.0)), np.zeros((1, 1)), np.full((1, 1), v(0.0))
    PASSED = np.zeros((1, 1), dtype=np.int64)
    RUNEND = np.full((1, 1), -1.0)
    CLIMB = np.full((1, 1, 2, codes.RB_LEN), -1.0)
    RB = np.zeros((1, 1, codes.RB_SIZE, codes.RB_LEN))
    RBN = np.zeros((1, 1), dtype=np.int64)
    DROP = np.full((1, 1), -np.inf)
    c = np.empty(5)
    y0, y1, k0, k1 = (np.zeros((2, 1)) for _ in range(4))
    steps = int(round(t_end / h))
    for k in range(steps):
        t0, t1 = k * h, (k + 1) * h
        y0[:, 0], y1[:, 0] = (x(t0), v(t0)), (x(t1), v(t1))
        k0[:, 0], k1[:, 0] = (v(t0), a(t0)), (v(t1), a(t1))
        eventobs._observe(t0, h, y0, y1, k0, k1, LO, 1, 0, 0, VMAX, TPK, PASSED, RUNEND,
                          CLIMB, RB, RBN, DROP, c)
    vmax, tpk, _, plat = eventobs.finalize(VMAX[0], TPK[0], RUNEND[0], CLIMB[0], RB[0], RBN[0],
                                           DROP[0], VINIT[0], steps * h, sample_dt)
    return float(vmax[0]), float(tpk[0]), bool(plat[0])


@pytest.mark.parametrize("first, w2, plateau", [
    (1.0 - 0.3e-4, 1.5e-6, False),   # first maximum near the second's: runs apart
    (1.0 - 0.3e-4, 1.2e-5, True),    # ... and the second's own run long
    (1.0 - 2.0e-4, 1.5e-6, False),   # first maximum below the near level
])
def test_event_plateau_is_the_near_run_that_holds_the_maximum(first, w2, plateau):
    """Two maxima within PEAK_TOL of each other with a dip below the near level between
    them: the event method classes the peak by the near-peak run that holds the maximum,
    as the sampled rule (``observables.peak``) does: a short run at the second maximum is
    no plateau, however long the first maximum's run was. The climb back through the near
    level after the dip lies in steps that set no record (the velocity still below the
    first maximum), which the method keeps for this. A plateau's t_peak is the first
    crossing of the near level in both rules."""
    import math as m
    from granchain.observables import peak
    w1, sdt = 1.2e-5, 1e-8
    t1, t2 = 4 * w1, 9 * w1
    g = [(first, t1, w1), (1.0, t2, w2)]
    v = lambda t: sum(A * m.exp(-((t - tc) / w) ** 2) for A, tc, w in g)  # noqa: E731
    a = lambda t: sum(-2 * (t - tc) / w ** 2 * A * m.exp(-((t - tc) / w) ** 2)  # noqa: E731
                      for A, tc, w in g)
    x = lambda t: sum(A * w * m.sqrt(m.pi) / 2 * (m.erf((t - tc) / w) + m.erf(tc / w))  # noqa: E731
                      for A, tc, w in g)
    t_end = t2 + 4 * w2
    ts = np.arange(int(round(t_end / sdt)) + 1) * sdt
    vs, ts_peak, _, sampled = peak(ts, np.array([v(t) for t in ts]))
    assert sampled == plateau
    ev_max, ev_peak, ev_plateau = _event_observables(v, x, a, t_end, sdt / 3, sdt)
    assert ev_plateau == plateau
    assert abs(ev_max / vs - 1.0) < 1e-9
    if plateau:
        assert abs(ev_peak - ts_peak) < 0.01 * sdt
    else:
        assert abs(ev_peak - t2) < 1e-3 * sdt and abs(ts_peak - t2) < 0.05 * sdt
