"""Gap realisations between neighbouring spheres, and the members of a scene (striker
speed x gap realisation, ``members``) that they are drawn for.

Gap k (0-based) separates particles k+1 and k+2 (1-based): there are n-1 of them.
Realisation r of a scene draws from ``numpy.random.default_rng([seed, r])``, so any
member of an ensemble can be re-run alone and reproduces bit for bit, whatever the
ensemble size or the batching.

Distributions (``gaps.distribution``):
- ``none``: a packed chain, all gaps 0.
- ``fixed``: every gap equals ``mean``.
- ``uniform``: i.i.d. uniform on [0, 2 mean] (mean ``mean``).
- ``exponential``: i.i.d. exponential with mean ``mean``.
- ``list``: the n-1 ``values`` as given (the same for every realisation).
- ``from_length``: a chain whose length exceeds the packed length by ``extra_length``
  (chapter Fig. 5.4): the extra length is split at random over the n-1 contacts,
  uniformly on the simplex (flat Dirichlet), so every realisation has total gap
  ``extra_length`` and mean gap ``extra_length/(n-1)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import Scene


def realise(scene: Scene, realisation: int) -> np.ndarray:
    """The n-1 gaps (m) of one realisation."""
    m = scene.n - 1
    dist = scene.gap_distribution
    if dist == "none":
        return np.zeros(m)
    if dist == "fixed":
        return np.full(m, scene.gap_mean)
    if dist == "list":
        return np.asarray(scene.gap_values, dtype=float)
    rng = np.random.default_rng([scene.gap_seed, int(realisation)])
    if dist == "uniform":
        return rng.uniform(0.0, 2.0 * scene.gap_mean, size=m)
    if dist == "exponential":
        return rng.exponential(scene.gap_mean, size=m)
    if dist == "from_length":
        return scene.gap_extra_length * rng.dirichlet(np.ones(m))
    raise AssertionError(dist)  # validated in scene.py


def realise_many(scene: Scene, realisations) -> np.ndarray:
    return np.stack([realise(scene, r) for r in realisations]) if len(realisations) else \
        np.zeros((0, scene.n - 1))


# the key that sets the radius draws' stream apart from the gap draws' (rng([seed, r]))
RADIUS_STREAM = 0x52414449


def member_radii(scene: Scene, mem: list[Member]) -> np.ndarray | None:
    """(len(mem), n) radii (m) of the members under ``chain.radius_spread``: realisation r
    draws e_i from numpy default_rng([spread.seed, r, RADIUS_STREAM]) (normal: i.i.d.
    N(0, sd^2), each draw beyond NORMAL_TRUNCATION sd drawn again; uniform: on
    +-sqrt(3) sd) and adds it to the nominal radius R_i. None without a spread."""
    spread = scene.radius_spread
    if spread is None:
        return None
    from .scenekeys import NORMAL_TRUNCATION
    nominal = np.asarray(scene.radii, dtype=float)
    out = np.empty((len(mem), scene.n))
    for j, m in enumerate(mem):
        rng = np.random.default_rng([spread.seed, int(m.realisation), RADIUS_STREAM])
        if spread.distribution == "uniform":
            e = rng.uniform(-1.0, 1.0, size=scene.n) * (np.sqrt(3.0) * spread.sd)
        else:
            e = rng.standard_normal(scene.n)
            bad = np.abs(e) > NORMAL_TRUNCATION
            while np.any(bad):
                e[bad] = rng.standard_normal(int(bad.sum()))
                bad = np.abs(e) > NORMAL_TRUNCATION
            e = e * spread.sd
        out[j] = nominal + e
    return out


def mean_gap_between(gaps: np.ndarray, p1: int, p2: int) -> np.ndarray:
    """Mean gap over the contacts between 1-based particles p1 < p2 (last axis = contacts)."""
    return np.asarray(gaps)[..., p1 - 1:p2 - 1].mean(axis=-1)


@dataclass(frozen=True)
class Member:
    """One chain of a scene: a striker speed and a gap realisation index; ``gaps``: its n-1
    gaps (m) when they are given (a designed ensemble, ``members(..., gaps=)``) instead of
    drawn from the scene's gap law."""
    index: int
    v_striker: float
    realisation: int
    gaps: tuple[float, ...] | None = None


def members(scene: Scene, realisations=None, gaps=None) -> list[Member]:
    """The chains of a scene: every striker speed x every realisation, in table order.
    ``gaps``: (R, n-1) gaps (m) of realisations 0..R-1 that the members take instead of
    the scene's gap law (the inference's designed realisations, ``granchain.gapdesign``)."""
    reals = range(scene.realisations) if realisations is None else realisations
    out = []
    for v in scene.striker_velocities:
        for r in reals:
            row = None if gaps is None else tuple(float(x) for x in gaps[int(r)])
            out.append(Member(len(out), float(v), int(r), row))
    return out


def member_gaps(scene: Scene, mem: list[Member]) -> np.ndarray:
    """(len(mem), n-1) gaps (m) of the members, one realisation each (a member's own
    ``gaps`` where given)."""
    out = realise_many(scene, [m.realisation for m in mem]).reshape(len(mem), scene.n - 1)
    for j, m in enumerate(mem):
        if m.gaps is not None:
            out[j] = m.gaps
    return out
