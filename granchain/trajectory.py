"""The engine-neutral trajectory: what every engine produces and observables read."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .effects import ENERGY_COLUMNS  # noqa: F401  (the energy-ledger columns, in engine order)

if TYPE_CHECKING:
    from .guards import Limits


@dataclass(frozen=True)
class OnTheFly:
    """Observables an engine measured while integrating (per particle, NaN where not
    final, as ``granchain.observables.peaks``): v_max (m/s), t_peak, t_front (s),
    plateau, final; balance_error: the largest |energy balance| / E(0) over the run.
    samples: the number of samples the run took on its sample grid (None: the
    trajectory's own t). A walled chain's end-wall peak (``observables.wall_peak``):
    wall_force_max (N), t_wall_peak (s), wall_peak_final (None: read from the
    trajectory's wall_force)."""
    v_max: np.ndarray
    t_peak: np.ndarray
    t_front: np.ndarray
    plateau: np.ndarray
    final: np.ndarray
    balance_error: float
    samples: int | None = None
    wall_force_max: float = float("nan")
    t_wall_peak: float = float("nan")
    wall_peak_final: bool | None = None


@dataclass(frozen=True)
class RunInfo:
    """How an engine produced a trajectory.

    method: the integrator (rk4, verlet, adaptive, event, or LAMMPS' lammps-verlet);
    dt: its step (s; the tolerance methods' first step); sample_dt: the sample interval
    (s); rtol: the tolerance methods' relative tolerance (None for a fixed step); trace:
    whether the sampled record was kept (False: observables measured on the fly, only
    the first and last states kept); pair: the event method's Runge-Kutta pair; t_last:
    the event method's time of its last state (s).

    LAMMPS runs only (None otherwise): nprocs (MPI ranks), lammps_version, lammps_wall_s
    (the LAMMPS process), batch_wall_s (deck, run and read-back of the whole batch),
    read_wall_s, readers and velocities (the text dump's reader options), output (binary
    or dump), balance ("independent": LAMMPS reports every work of the ledger;
    "residual": some work has no per-atom output and is the balance's residual), deck
    (the deck's path when its directory is kept)."""
    method: str
    dt: float
    sample_dt: float | None = None
    rtol: float | None = None
    trace: bool = True
    pair: str | None = None
    t_last: float | None = None
    nprocs: int | None = None
    lammps_version: str | None = None
    lammps_wall_s: float | None = None
    batch_wall_s: float | None = None
    read_wall_s: float | None = None
    readers: int | None = None
    velocities: str | None = None
    output: str | None = None
    balance: str | None = None
    deck: str | None = None


@dataclass
class Trajectory:
    """Sampled history of one chain.

    t: (S,) s; v: (S, n) velocity along the chain, m/s; energy: (S, len(ENERGY_COLUMNS)) J in the order of
    ENERGY_COLUMNS (work = work done ON the particles by that effect, accumulated from
    t = 0); gaps: (n-1,) m; radius: m; v_striker: m/s.
    """
    t: np.ndarray
    v: np.ndarray
    energy: np.ndarray
    gaps: np.ndarray
    radius: float
    v_striker: float
    effects: tuple[str, ...] = ()
    steps: int = 0
    rejected: int = 0
    status: str = "done"
    wall_s: float = 0.0
    # how the engine produced it (method, step, sampling; LAMMPS' run)
    info: RunInfo | None = None
    # Hertz overlap (m, > 0 in contact) of the last contact (particles n-1, n) at the last
    # sample: tells whether the last particle has left (granchain.stoprule). NaN: unknown.
    last_overlap: float = float("nan")
    # right-hand-side (force routine) evaluations of the integration
    force_evaluations: int = 0
    # observables measured on the fly (the event method, the fixed-step methods without a
    # trace); when set, t, v, energy and wall_force may hold only the initial and final
    # states (no trace asked for), and
    # ``observables.summarize`` reads the peaks and the balance error from here
    observed: OnTheFly | None = None
    # each sphere's radius (m), particle 1 first, when they differ (None: all ``radius``)
    radii: np.ndarray | None = None
    # force (N) of the end wall on the last sphere at each sample (None: free end), and
    # its static part (the preload at t = 0)
    wall_force: np.ndarray | None = None
    wall_static: float = 0.0
    # the physical bounds of this chain's results (``guards.result_limits`` of the scene
    # that ran; the engines set them), checked by ``observables.summarize``; None: only
    # the bounds that need no scene (positive delays, finite values)
    limits: "Limits | None" = None

    @property
    def n(self) -> int:
        return self.v.shape[1]
