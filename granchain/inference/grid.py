"""The simulated grids both fits read.

- The base scene each grid is derived from: completed by :func:`complete_base` (the
  chapter's gap law, the data's striker speeds), checked by :func:`check_base` and, for the
  joint fit, ``fitkeys.check_fit_base`` (the fitted key's effect on).
- What a simulated chain gives a measured column: :func:`timing` and :func:`peak`, the
  one place each.
- The gap-only :class:`Grid` (mean gaps x striker speeds x realisations,
  :func:`simulate_grid`) and the joint :class:`JointGrid` (x the fitted key's values,
  :func:`simulate_joint_grid`): each node one scene derived from the base scene, run
  through ``simulate.run_scene`` with designed gap realisations (``granchain.gapdesign``)
  (the nodes that differ only in their mean gap in one call: ``_run_nodes``) and
  cached per node, keyed by the node's scene, the design and the package's source.

The method is in the module doc of :mod:`granchain.inference`."""
from __future__ import annotations

import dataclasses
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import GranchainError
from ..fileio import atomic_write_bytes
from ..gapdesign import EMPHASIS, GAP_ONLY_KEY_PRIOR, KEY_PRIOR, design, prior_weights
from ..scene import Scene
from .fitkeys import DEFAULT_KEY, FitKey, check_fit_base, check_fit_range, fit_key
from .measurements import TIMING_COLUMNS, Measurements

GAP_LAWS = ("uniform", "exponential")     # laws whose realisations scale with their mean
DEFAULT_GAP_LAW = "uniform"               # the chapter's: uniform on [0, 2 mean], i.i.d.
CACHE_FORMAT = 1                          # bump when the cached arrays change meaning
GAP_MAX, GAP_POINTS, REALISATIONS = 500e-9, 21, 64   # the grid of both fits (and the CLI)
# the restitution's nodes linspace(E_MIN, 1, E_POINTS) (spacing 0.05): damping.e's prior
# range, declared with the key (effects/contact_damping.py)
E_MIN, E_POINTS = fit_key(DEFAULT_KEY).fit.lo, fit_key(DEFAULT_KEY).fit.points
JOINT_OBS = ("dt_peak_s", "dt_front_s", "v_max_1", "v_max_2")
JOINT_CACHE_FORMAT = 1


def timing(result, column: str) -> float:
    """The simulated timing that a measurement's ``column`` is compared with: the chain's
    true peak-to-peak (``dt_peak_s``) or half-peak arrival (``dt_front_s``) delay between
    the probes. This is the one place that chooses between true and instrument timing."""
    return {"dt_peak_s": result.dt_peak, "dt_front_s": result.dt_front}[column]


def complete_base(base: Scene, meas: Measurements) -> tuple[Scene, dict]:
    """The scene the inference simulates, and where its gap law and striker speeds come
    from (``{"gap_law": "scene" | "default", "speeds": "scene" | "data"}``).

    A base scene that does not give ``gaps.distribution`` gets DEFAULT_GAP_LAW, the
    chapter's (its mean is a placeholder: the inference sets it); one that does not give
    ``striker.velocity`` is simulated at the data's own striker speeds. What the scene
    gives is kept as it is, and checked by :func:`check_base` and
    :func:`~granchain.inference.measurements.check_speeds`. The returned scene keeps the
    base scene's ``given``, so completing it again changes nothing and reports the same
    sources. A base scene that cannot take a gap law is refused first
    (:func:`check_gappable`)."""
    check_gappable(base)
    change = {}
    src = {"gap_law": "scene", "speeds": "scene"}
    if "gaps.distribution" not in base.given:
        src["gap_law"] = "default"
        if base.gap_distribution != DEFAULT_GAP_LAW:
            change["gaps"] = {"distribution": DEFAULT_GAP_LAW, "mean": 0.0}
    if "striker.velocity" not in base.given:
        src["speeds"] = "data"
        speeds = sorted({float(v) for v in meas.v})
        if list(base.striker_velocities) != speeds:
            change["striker"] = {"velocity": speeds}
    if change:
        base = dataclasses.replace(base.derive(change), given=base.given)
    return base, src


def check_gappable(base: Scene) -> None:
    """Refuse (SceneError naming the key) a base scene whose chain cannot have gaps: a
    preloaded chain (``precompression.force``) is pressed together, so it has no mean gap
    to infer; a two-sphere scene has no probes to time."""
    from ..errors import SceneError
    if base.n == 2:
        raise SceneError("chain.n", "a two-sphere scene has no probes, so no timing between "
                         "them to infer a gap from", "give a chain of chain.n >= 3 with its "
                         "probes")
    if base.precompression > 0.0 or "precompression.force" in base.given:
        raise SceneError("precompression.force", "a preloaded chain is pressed together and "
                         "has no gaps, so the inference cannot give it a gap law",
                         "drop precompression (and walls.end if only the preload needs it) "
                         "from the base scene")


def check_base(base: Scene) -> None:
    """A base scene the inference can use: a chain that can have gaps
    (:func:`check_gappable`), a gap law with a mean that scales its realisations, and a
    fixed set of striker speeds."""
    from ..errors import SceneError
    check_gappable(base)
    if base.gap_distribution not in GAP_LAWS:
        raise SceneError("gaps.distribution", f"'{base.gap_distribution}' has no mean gap to "
                         "infer", f"use one of {', '.join(GAP_LAWS)} (mean: any value; the "
                         "inference sets it), or leave gaps.distribution out for the "
                         f"chapter's {DEFAULT_GAP_LAW} law")


def grid_scene(base: Scene, gap_mean: float, realisations: int) -> Scene:
    """The scene of one grid point: the base scene at mean gap ``gap_mean`` (m) with
    ``realisations`` gap realisations at every striker speed of the base scene."""
    return base.derive({"gaps": {"mean": float(gap_mean)},
                        "ensemble": {"realisations": int(realisations)}})


class WeightedGrid:
    """What a simulated grid (:class:`Grid`, :class:`JointGrid`) says of its realisations'
    weights: ``weights`` are the design's prior / proposal (None for plain draws),
    ``key_prior`` says whether they are used, ``realisations`` how many there are."""

    @property
    def realisation_weights(self) -> np.ndarray:
        """(R,) the realisations' weights in the likelihood (``gapdesign.prior_weights``)."""
        return prior_weights(self.weights, self.realisations, self.key_prior)

    def unmeasured(self, column: str) -> int:
        """How many of the grid's simulated chains (node x speed x realisation) have no
        value of what the fit reads of them (the timing ``column``; in a joint grid also
        a probe's peak): each counts in the likelihood as a realisation that cannot give
        the data (zero density), which is right for a wave that never arrived and a bias
        when a run ended before a peak that would have come."""
        bad = 0
        for a in self.read_by_fit(column):
            bad = bad | ~np.isfinite(a)
        return int(np.sum(bad))


def node_setting(scenes) -> dict:
    """The integrator of a grid's node scenes: ``method``, ``dt_s``, ``tolerance`` (the
    method's own; None for a fixed step) and ``v_g_tolerance`` (what method auto was
    asked; None without auto) when every node has the same; else ``method`` "per node"
    and the others None (a base scene of method auto resolved node by node)."""
    from ..scenekeys import TOLERANCE_METHODS
    got = {(s.method, float(s.dt), s.tolerance if s.method in TOLERANCE_METHODS else None,
            s.auto_tolerance) for s in scenes}
    if len(got) != 1:
        return {"method": "per node", "dt_s": None, "tolerance": None, "v_g_tolerance": None}
    m, dt, tol, auto = got.pop()
    return {"method": m, "dt_s": dt, "tolerance": tol, "v_g_tolerance": auto}


@dataclass(frozen=True)
class Grid(WeightedGrid):
    """Simulated timings: ``timings[column]`` of shape (G, S, R) in s (NaN where the wave
    did not arrive), at mean gaps ``gaps`` (G, m), striker speeds ``speeds`` (S, m/s,
    ascending) and R realisations; ``hashes`` the grid scenes' hashes; ``simulated`` how
    many chains this call ran (the rest came from the cache); ``setting`` the integrator
    of its scenes (:func:`node_setting`; None: not known)."""
    gaps: np.ndarray
    speeds: np.ndarray
    timings: dict
    hashes: tuple[str, ...]
    simulated: int
    weights: np.ndarray | None = None
    key_prior: str = GAP_ONLY_KEY_PRIOR
    setting: dict | None = None

    @property
    def realisations(self) -> int:
        return int(next(iter(self.timings.values())).shape[2])

    @property
    def n_chains(self) -> int:
        return int(self.gaps.size * self.speeds.size * self.realisations)

    def read_by_fit(self, column: str) -> tuple[np.ndarray, ...]:
        return (self.timings[column],)


def _cache_file(cache_dir: Path, scene: Scene, tag: str) -> Path:
    """One grid point's timings, keyed by its scene, its realisations' design ``tag``
    (``gapdesign.Design.tag``) and the package's source (a grid simulated by other code is
    never reused)."""
    from ..fileio import source_hash
    return Path(cache_dir) / (f"grid-{scene.hash}-{tag}-{source_hash()[:12]}-"
                              f"v{CACHE_FORMAT}.npz")


def _setting_key(scene: Scene) -> tuple:
    return (scene.method, float(scene.dt), scene.tolerance)


def _run_nodes(nodes: list, designed, realisations: int, engine: str, update) -> list:
    """The chains of several grid nodes in one engine call per integrator setting (more
    chains per call keep both threads busy: for the 21 mean gaps of one e of the shipped
    joint example, 27 % less wall time and 13 % less CPU than one call per node, every value
    the same bit for bit). ``nodes``: (mean gap, resolved node scene) pairs, the scenes
    alike but for their mean gap; each node's realisations take the designed gaps of its
    mean gap. Returns, per node in order, (realisation, result) pairs. The callers cache
    each node when its call ends: a run stopped during a call simulates its nodes again
    next time."""
    from ..simulate import run_scene
    out = [[] for _ in nodes]
    groups: dict = {}
    for i, (_, scene) in enumerate(nodes):
        groups.setdefault(_setting_key(scene), []).append(i)
    for idx in groups.values():
        # the call's scene: the nodes' resolved setting at their largest mean gap (the
        # guards and the chunks sized for its longest chains); the gaps are the nodes' own
        first = nodes[idx[0]][1]
        gmax = max(nodes[i][0] for i in idx)
        scene = first.derive({"gaps": {"mean": float(gmax)},
                              "ensemble": {"realisations": realisations * len(idx)}})
        gaps = np.concatenate([designed.gaps(nodes[i][0]) for i in idx])
        for r in run_scene(scene, engine=engine, progress=update, gaps=gaps):
            k, rr = divmod(int(r.realisation), realisations)
            out[idx[k]].append((rr, r))
    return out


def simulate_grid(base: Scene, gap_max: float, gap_points: int, realisations: int,
                  cache_dir=None, engine: str = "reference",
                  progress: bool | None = None, emphasis: float = EMPHASIS) -> Grid:
    """Simulate (or read from ``cache_dir``) the grid of mean gaps
    ``linspace(0, gap_max, gap_points)`` x the base scene's speeds x ``realisations``
    designed realisations (``gapdesign.design`` with ``emphasis``; 0: the gap law's own
    draws, weight 1 each). ``progress``: a bar of the chains still to simulate on stderr
    (``granchain.progress``; None: when stderr is a terminal)."""
    from ..runplan import plan_run
    from ..progress import bar
    check_base(base)
    if gap_points < 3:
        raise GranchainError(f"--gap-points: {gap_points} is too few; give >= 3")
    if not gap_max > 0:
        raise GranchainError(f"--gap-max-nm: {gap_max * 1e9:g} must be > 0")
    if realisations < 2:
        raise GranchainError(f"--realisations: {realisations} is too few; give >= 2")
    speeds = np.array(sorted(set(float(v) for v in base.striker_velocities)))
    if speeds[0] <= 0:
        raise GranchainError("scene field 'striker.velocity': a speed of 0 has no wave; give "
                             "speeds > 0")
    base = base.derive(striker={"velocity": [float(v) for v in speeds]})
    designed = design(base, realisations, emphasis)
    gaps = np.linspace(0.0, gap_max, gap_points)
    out = {c: np.full((gaps.size, speeds.size, realisations), np.nan) for c in TIMING_COLUMNS}
    hashes, simulated, todo, scenes = [], 0, [], []
    for k, g in enumerate(gaps):
        scene = plan_run(grid_scene(base, g, realisations), per_speed=False).scene
        hashes.append(scene.hash)
        scenes.append(scene)
        path = _cache_file(cache_dir, scene, designed.tag) if cache_dir is not None else None
        if path is not None and path.exists():
            with np.load(path) as z:
                for c in TIMING_COLUMNS:
                    out[c][k] = z[c]
        else:
            todo.append((k, scene, path))
    with bar(len(todo) * speeds.size * realisations, f"{base.name}: inference grid",
             enabled=progress) as shown:
        done = _run_nodes([(gaps[k], scene) for k, scene, _ in todo], designed, realisations,
                          engine, shown.update)
        for (k, scene, path), res in zip(todo, done):
            simulated += len(res)
            for rr, r in res:
                j = int(np.searchsorted(speeds, r.v_striker))
                for c in TIMING_COLUMNS:
                    out[c][k, j, rr] = timing(r, c)
            if path is not None:
                path.parent.mkdir(parents=True, exist_ok=True)
                buf = io.BytesIO()
                np.savez(buf, **{c: out[c][k] for c in TIMING_COLUMNS})
                atomic_write_bytes(path, buf.getvalue(), force=True, field="--cache-dir")
    return Grid(gaps, speeds, out, tuple(hashes), simulated, designed.weights,
                setting=node_setting(scenes))


def peak(result, probe: int) -> float:
    """The simulated peak (m/s) that a measured ``vmax_1_m_s`` (probe 0) or ``vmax_2_m_s``
    (probe 1) is compared with: the chain's true peak, as :func:`timing` takes the true
    timing."""
    return result.v_max_1 if probe == 0 else result.v_max_2


def gap_nodes(gap_max: float, points: int) -> np.ndarray:
    """Mean gaps of the joint grid: gap_max (k/(points-1))^2, dense where the peaks change
    fastest (the packed-to-gapped change at gaps of the order of the contact overlap,
    ~10-30 nm; module doc)."""
    return gap_max * np.linspace(0.0, 1.0, points) ** 2


def joint_scene(base: Scene, gap_mean: float, value: float, realisations: int,
                key: str = DEFAULT_KEY) -> Scene:
    """The scene of one node of the joint grid: the base scene at mean gap ``gap_mean``
    (m) and the fitted scene key ``key`` at ``value``, ``realisations`` gap
    realisations."""
    return base.derive({"gaps": {"mean": float(gap_mean)}, fit_key(key).path: float(value),
                        "ensemble": {"realisations": int(realisations)}})


@dataclass(frozen=True)
class JointGrid(WeightedGrid):
    """Simulated observables ``values[name]`` (``JOINT_OBS``: the two timings in s, the
    probes' peaks in m/s) of shape (G, P, S, R), NaN where not measured, at mean gaps
    ``gaps`` (G), values ``params`` (P, ascending) of the fitted scene key ``key``
    (``damping.e``: restitutions, the last 1), striker speeds ``speeds`` (S) and R
    realisations (the same gap patterns at every node); ``setting`` as :class:`Grid`."""
    gaps: np.ndarray
    params: np.ndarray
    speeds: np.ndarray
    values: dict
    hashes: tuple[str, ...]
    simulated: int
    wall_s: float = 0.0
    weights: np.ndarray | None = None
    key_prior: str = KEY_PRIOR
    key: str = DEFAULT_KEY
    setting: dict | None = None

    @property
    def fit_key(self) -> FitKey:
        return fit_key(self.key)

    @property
    def coords(self) -> np.ndarray:
        """The nodes in the coordinate the grid interpolates in (``FitKey.coord``)."""
        return self.fit_key.coord(self.params)

    @property
    def realisations(self) -> int:
        return int(next(iter(self.values.values())).shape[3])

    @property
    def n_chains(self) -> int:
        return int(self.gaps.size * self.params.size * self.speeds.size
                   * self.realisations)

    def read_by_fit(self, column: str) -> tuple[np.ndarray, ...]:
        return tuple(self.values[c] for c in (column, "v_max_1", "v_max_2"))


def _joint_cache_file(cache_dir: Path, scene: Scene, tag: str) -> Path:
    from ..fileio import source_hash
    return Path(cache_dir) / (f"joint-{scene.hash}-{tag}-{source_hash()[:12]}-"
                              f"v{JOINT_CACHE_FORMAT}.npz")


def check_joint_options(gap_max: float, gap_points: int, lo: float, points: int,
                        realisations: int, key: str = DEFAULT_KEY, hi: float | None = None,
                        options: tuple[str, str] = ("--e-min", "--e-points")) -> None:
    """The joint grid's options: mean gaps, realisations and the fitted key's range
    [lo, hi] (hi None: its declared top) in ``points`` nodes, set by ``options``."""
    if gap_points < 3:
        raise GranchainError(f"--gap-points: {gap_points} is too few; give >= 3")
    if not gap_max > 0:
        raise GranchainError(f"--gap-max-nm: {gap_max * 1e9:g} must be > 0")
    if realisations < 2:
        raise GranchainError(f"--realisations: {realisations} is too few; give >= 2")
    fk = fit_key(key)
    check_fit_range(fk, lo, fk.fit.hi if hi is None else hi, points, options)


def simulate_joint_grid(base: Scene, gap_max: float, gap_points: int, lo: float,
                        points: int, realisations: int, cache_dir=None,
                        engine: str = "reference", progress: bool | None = None,
                        emphasis: float = EMPHASIS, key: str = DEFAULT_KEY,
                        hi: float | None = None) -> JointGrid:
    """Simulate (or read from ``cache_dir``) the joint grid: mean gaps
    ``gap_nodes(gap_max, gap_points)`` x the fitted scene key ``key``'s values
    ``FitKey.nodes(lo, hi, points)`` (hi None: its declared top; damping.e: restitutions
    from lo to 1) x the base scene's speeds x ``realisations`` designed realisations
    (module doc). ``progress`` and ``emphasis`` as :func:`simulate_grid`."""
    import time
    from ..runplan import plan_run
    from ..progress import bar
    fk = fit_key(key)
    hi = fk.fit.hi if hi is None else float(hi)
    check_base(base)
    check_fit_base(base, fk)
    check_joint_options(gap_max, gap_points, lo, points, realisations, key, hi)
    speeds = np.array(sorted(set(float(v) for v in base.striker_velocities)))
    if speeds[0] <= 0:
        raise GranchainError("scene field 'striker.velocity': a speed of 0 has no wave; give "
                             "speeds > 0")
    base = base.derive(striker={"velocity": [float(v) for v in speeds]})
    designed = design(base, realisations, emphasis)
    gaps, ps = gap_nodes(gap_max, gap_points), fk.nodes(lo, hi, points)
    shape = (gaps.size, ps.size, speeds.size, realisations)
    out = {c: np.full(shape, np.nan) for c in JOINT_OBS}
    hashes, simulated, todo, scenes = [], 0, [], []
    t0 = time.perf_counter()
    for k, g in enumerate(gaps):
        for j, p in enumerate(ps):
            scene = plan_run(joint_scene(base, g, p, realisations, key),
                             per_speed=False).scene
            hashes.append(scene.hash)
            scenes.append(scene)
            path = (_joint_cache_file(cache_dir, scene, designed.tag) if cache_dir is not None
                    else None)
            if path is not None and path.exists():
                with np.load(path) as z:
                    for c in JOINT_OBS:
                        out[c][k, j] = z[c]
            else:
                todo.append((k, j, scene, path))
    with bar(len(todo) * speeds.size * realisations, f"{base.name}: inference grid",
             enabled=progress) as shown:
        # the nodes of one value of the key in one engine call (_run_nodes), value by value
        for j in dict.fromkeys(j for _, j, _, _ in todo):
            nodes = [t for t in todo if t[1] == j]
            done = _run_nodes([(gaps[k], scene) for k, _, scene, _ in nodes], designed,
                              realisations, engine, shown.update)
            for (k, j, scene, path), res in zip(nodes, done):
                simulated += len(res)
                for rr, r in res:
                    s = int(np.searchsorted(speeds, r.v_striker))
                    for c in TIMING_COLUMNS:
                        out[c][k, j, s, rr] = timing(r, c)
                    out["v_max_1"][k, j, s, rr] = peak(r, 0)
                    out["v_max_2"][k, j, s, rr] = peak(r, 1)
                if path is not None:
                    path.parent.mkdir(parents=True, exist_ok=True)
                    buf = io.BytesIO()
                    np.savez(buf, **{c: out[c][k, j] for c in JOINT_OBS})
                    atomic_write_bytes(path, buf.getvalue(), force=True,
                                       field="--cache-dir")
    return JointGrid(gaps, ps, speeds, out, tuple(hashes), simulated,
                     time.perf_counter() - t0, designed.weights, key=key,
                     setting=node_setting(scenes))

