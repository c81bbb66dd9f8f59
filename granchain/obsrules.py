"""The observable rules, once: how a peak is measured, when a particle has seen the wave,
when a peak is final, when the wave has left a chain.

Plain arithmetic on scalars, marked ``effects.spec.compiled``: the engines compile them
into their kernels (the fixed-step blocks' on-the-fly observables, the event method's
continuous-time peaks, the stop rules), and ``granchain.observables`` and
``granchain.stoprule`` call them from Python, on numbers or elementwise on numpy arrays
(the comparisons combine with ``&``). The same operations in the same order everywhere,
so that the kernels' on-the-fly results equal the summariser's on the sampled record, bit
for bit. ``granchain.stoprule`` states what they mean for a run and re-exports the
constants.
"""
from __future__ import annotations

import math

from .effects.spec import compiled

ARRIVAL_FRACTION = 1e-3    # a particle has seen the wave once v > ARRIVAL_FRACTION * v_s
PASS_FRACTION = 0.5        # the wave has passed an inner particle once v < this * its peak
PEAK_TOL = 1e-4            # a peak: samples within PEAK_TOL of the maximum (observables.peak)
PLATEAU_SAMPLES = 5        # a plateau: a near-peak run longer than this many samples


@compiled
def near_level(top):
    """The level within PEAK_TOL of a maximum: samples at or above it are near the peak."""
    return (1.0 - PEAK_TOL) * top


@compiled
def pass_level(top):
    """The level below which the wave has passed a particle (or the wall's force its
    peak): PASS_FRACTION of the peak."""
    return PASS_FRACTION * top


@compiled
def front_level(v_max):
    """The level whose first crossing on the rising edge is the arrival (front) time:
    half the peak."""
    return 0.5 * v_max


@compiled
def arrival(v_striker):
    """The speed above which a particle has seen the wave: ARRIVAL_FRACTION * v_s."""
    return ARRIVAL_FRACTION * v_striker


@compiled
def near(v, top):
    """Is v near the peak top (within PEAK_TOL)?"""
    return v >= near_level(top)


@compiled
def passed(v, top):
    """Has a value v after the peak top fallen below the pass level?"""
    return v < pass_level(top)


@compiled
def plateau(run):
    """Is a run of ``run`` contiguous near-peak samples a plateau (longer than
    PLATEAU_SAMPLES)? A plateau's maximum is ill-defined: its peak time is the start of
    the run."""
    return run > PLATEAU_SAMPLES


@compiled
def grid_samples(t_in, t_out, dt):
    """How many instants k dt (k = 0, 1, ...) of a sample grid of interval dt lie in
    [t_in, t_out] (0 if none, or if a time is NaN): the samples a record on that grid
    holds of a run of the velocity from t_in to t_out. A run known in continuous time
    (the event method's near-peak run) is a :func:`plateau` by this count, as a sampled
    record's run is by the count of its samples; its length alone (more than
    PLATEAU_SAMPLES intervals) classes a run of 5 to 6 intervals, which holds 5 or 6
    samples by where the grid falls, apart from the sampled rule."""
    if not t_out >= t_in:
        return 0
    return int(math.floor(t_out / dt)) - int(math.ceil(t_in / dt)) + 1


@compiled
def pymax(a, b):
    """Python's max(a, b): a unless b > a."""
    return b if b > a else a


@compiled
def pymin(a, b):
    """Python's min(a, b): a unless b < a."""
    return b if b < a else a


@compiled
def vertex(y0, y1, y2):
    """(off, top): the vertex of the parabola through three equally spaced samples around
    a maximum y1: its offset in sample intervals from the middle one (in [-1/2, 1/2]; 0
    when the samples do not curve down) and its height."""
    den = y0 - 2.0 * y1 + y2
    off = 0.5 * (y0 - y2) / den if den < 0.0 else 0.0
    off = pymin(pymax(off, -0.5), 0.5)
    return off, y1 - 0.25 * (y0 - y2) * off


@compiled
def crossing(ta, tb, y0, y1, level):
    """The time at which the line through (ta, y0) and (tb, y1) reaches level."""
    return ta + (level - y0) / (y1 - y0) * (tb - ta)


@compiled
def detached(v_last, overlap_last, vthr):
    """Has the last particle of a free chain taken the wave and left? It moves faster
    than the arrival speed vthr and its contact with its neighbour is open (overlap <= 0)."""
    return (v_last > vthr) & (overlap_last <= 0.0)


@compiled
def wall_left(v_last, x_last, vthr):
    """Has the wave left a chain that ends on a wall? Its last particle moves back from
    the wall faster than the arrival speed vthr and is back at or behind its start
    (displacement x_last <= 0): the wave has reflected and the wall force is back at or
    below its static value, so the wall's dynamic peak is behind."""
    return (v_last < -vthr) & (x_last <= 0.0)
