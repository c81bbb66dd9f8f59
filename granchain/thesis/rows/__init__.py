"""Rows of the thesis comparison table, one builder per group of the chapter's numbers,
each group in its own module.

Each builder takes :class:`PackedChain` (the packed 440C chain's reductions that every
group quotes) and the tables it needs (``None`` when not given: its values are then NaN
and its reasons say which table is missing) and returns a list of row dicts with the
keys of ``granchain.thesis.COLUMNS``, in table order:

- :func:`packed_chain_rows`     v_max slopes and v_max,2 / v_max,1 (Fig. 5.1b);
- :func:`group_velocity_rows`   v_g against Nesterenko's speed (Fig. 5.1c);
- :func:`experiment_rows`       the chapter's measurements against the model (Fig. 5.2);
- :func:`gap_rows`              20 nm gaps and the chapter's fitted gaps (Fig. 5.3b, 5.3c);
- :func:`bound_rows`            Eq. 5.4 as a bound of random and loose chains (5.3c, 5.4b);
- :func:`energy_rows`           groove-friction and air-drag work, pulse width (Fig. 5.1a);
- :func:`instrument_rows`       how much of the measured peak deficit the chapter's 2.5 MHz
                                vibrometers explain (vibrometer study, Fig. 5.2a);
- :func:`field_rows`            beyond the chapter, against theory: a precompressed chain's
                                v_g against Nesterenko's V_s(f_r) and c0, and the wall
                                force's v_s exponent against a Hertz solitary wave's 6/5;
- :func:`tolerance_rows`        beyond the chapter: can a sphere-size tolerance alone make
                                Fig. 5.3b's ~20% oscillation (radius_spread study)?
- :func:`dissipation_rows`      beyond the chapter: which contact damping e gives the measured
                                v_max,2/v_max,1, and does it give the measured peaks or leave
                                a loss at the striker (dissipation study)?
- :func:`plasticity_rows`       beyond the chapter: which limiting pressure of Thornton's
                                yielding contacts gives the measured v_max,1, and is v_max,1(v_s)
                                then linear, as measured (plasticity study)?
- :func:`adhesion_rows`         beyond the chapter: which surface energy of adhesive contacts,
                                alone or with the groove's flats, gives the measured v_max,1 at
                                the lowest speeds (adhesion study)?
- :func:`capture_rows`          beyond the chapter, against theory: two adhesive spheres'
                                capture velocity and its JKR scaling with gamma (capture
                                study).

Every number comes from granchain.reductions; reasons quote the numbers that support them.
"""
from __future__ import annotations

from .common import PackedChain, packed_chain
from .packed import group_velocity_rows, packed_chain_rows
from .experiment import experiment_rows
from .gapped import gap_rows
from .bounds import bound_rows
from .energy import energy_rows
from .instrument import instrument_rows
from .field import field_rows
from .tolerance import tolerance_rows
from .dissipation import dissipation_rows
from .plasticity import plasticity_rows
from .adhesion import adhesion_rows, capture_rows

__all__ = ["PackedChain", "packed_chain", "packed_chain_rows", "group_velocity_rows",
           "experiment_rows", "gap_rows", "bound_rows", "energy_rows", "instrument_rows",
           "field_rows", "tolerance_rows", "dissipation_rows",
           "plasticity_rows", "adhesion_rows", "capture_rows"]
