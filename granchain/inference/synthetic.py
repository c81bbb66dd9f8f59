"""Synthetic measurements: chains of a base scene simulated outside any grid, at a given
mean gap (and restitution), as the tests, the calibration benchmarks and the shipped
examples use them (:func:`simulate_rows`, :func:`simulate_joint_rows`), and the
viscoelastic damping whose head-on collision has a given coefficient of restitution
(:func:`matching_eta`), for truths from a law the likelihood does not use."""
from __future__ import annotations

import numpy as np

from ..errors import GranchainError
from ..gaps import Member
from ..scene import Scene
from .fitkeys import DEFAULT_KEY, fit_key
from .grid import peak, timing


def simulate_rows(base: Scene, gap_mean: float, speeds, realisations,
                  column: str, engine: str = "reference") -> np.ndarray:
    """Simulated timings (s) of chains of the base scene at mean gap ``gap_mean`` (m), one
    per (speed, realisation) pair: synthetic measurements (realisations drawn with the
    base scene's ``gaps.seed``; give another seed for chains the grid never saw)."""
    from ..runplan import plan_run
    from ..observables import summarize
    from ..simulate import trajectories
    speeds = [float(v) for v in speeds]
    scene = plan_run(base.derive({"gaps": {"mean": float(gap_mean)},
                                  "striker": {"velocity": sorted(set(speeds))}}),
                     per_speed=False).scene
    mem = [Member(i, v, int(r)) for i, (v, r) in enumerate(zip(speeds, realisations))]
    out = np.empty(len(mem))
    for m, traj in trajectories(scene, mem, engine):
        out[m.index] = timing(summarize(traj, scene.probes), column)
    return out


def simulate_joint_rows(base: Scene, gap_mean: float, value: float | None, speeds,
                        realisations, column: str, engine: str = "reference",
                        key: str = DEFAULT_KEY) -> np.ndarray:
    """(rows, 3) simulated (timing in s, vmax_1, vmax_2 in m/s) of chains of the base scene
    at mean gap ``gap_mean`` (m) and the scene key ``key`` at ``value`` (default: the
    restitution e; None: the base scene as it is, e.g. another damping law), one per
    (speed, realisation) pair: synthetic measurements (give the base scene another
    ``gaps.seed`` for chains the grid never saw)."""
    from ..runplan import plan_run
    from ..observables import summarize
    from ..simulate import trajectories
    speeds = [float(v) for v in speeds]
    change = {"gaps": {"mean": float(gap_mean)}, "striker": {"velocity": sorted(set(speeds))}}
    if value is not None:
        change[fit_key(key).path] = float(value)
    scene = plan_run(base.derive(change), per_speed=False).scene
    mem = [Member(i, v, int(r)) for i, (v, r) in enumerate(zip(speeds, realisations))]
    out = np.empty((len(mem), 3))
    for m, traj in trajectories(scene, mem, engine):
        res = summarize(traj, scene.probes)
        out[m.index] = (timing(res, column), peak(res, 0), peak(res, 1))
    return out


def collision_restitution(base: Scene, v: float, damping: dict) -> float:
    """The coefficient of restitution of one head-on collision of the base scene's striker
    with particle 2 at closing speed v (m/s), Hertz contact with ``damping`` (a scene
    ``damping`` section) and nothing else: (v_2' - v_1') / v."""
    from ..simulate import trajectories
    sc = base.derive({"chain": {"n": 3}, "probes": [2, 3], "t_end": 40 * base.contact_time(v),
                      "effects": ["hertz", "contact_damping"], "damping": damping,
                      "gaps": {"distribution": "list", "values": [0.0, 1e-3]},
                      "striker": {"velocity": float(v)},
                      "integrator": {"method": "adaptive", "tolerance": 1e-9}})
    _, traj = next(trajectories(sc, [Member(0, float(v), 0)]))
    return float((traj.v[-1, 1] - traj.v[-1, 0]) / v)


def matching_eta(base: Scene, e: float, v: float, tol: float = 1e-5) -> float:
    """The viscoelastic eta_n0 (1/(m s)) whose head-on collision at closing speed v gives
    the coefficient of restitution e (secant on 1 - e, which is nearly proportional to
    eta for weak damping); at other speeds its e differs (1 - e ~ v^(1/5))."""
    if e >= 1.0:
        return 0.0
    loss = lambda eta: 1.0 - collision_restitution(   # noqa: E731
        base, v, {"model": "viscoelastic", "eta": eta, "e": None})
    a = 1e12 * (1.0 - e)          # 1 - e ~ 1e-12 eta for 150 um steel at 0.05 m/s
    la = loss(a)
    b = a * (1.0 - e) / la
    lb = loss(b)
    for _ in range(30):
        if abs(lb - (1.0 - e)) < tol:
            return b
        a, la, b = b, lb, b + (1.0 - e - lb) * (b - a) / (lb - la)
        lb = loss(b)
    raise GranchainError(f"no viscoelastic eta found for e = {e:g} at {v:g} m/s")
