"""The engine-neutral trajectory: what every engine produces and observables read."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .effects import ENERGY_COLUMNS  # noqa: F401  (the energy-ledger columns, in engine order)


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
    meta: dict = field(default_factory=dict)
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

    @property
    def n(self) -> int:
        return self.v.shape[1]
