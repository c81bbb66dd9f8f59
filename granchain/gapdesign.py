"""The gap realisations of an inference grid: the base scene's gap law, with the gaps next
to the probes importance-sampled toward small values, and each realisation's weight.

Why: a probe's peak, and with it the time of that peak, is set mostly by the contacts on
either side of the probe. A gap there of a few nanometres, a few percent of the mean, puts
the probe into a packed pair: its peak drops from a gapped chain's ~0.95 v_s toward a packed
one's ~0.7 v_s. Under the uniform law a given gap is below 0.05 of the mean in 2.5 % of
chains, so a grid of R = 64 plain draws holds one or two such patterns, or none; data from
such a chain (about 5 % of all chains, counting the three contacts next to the two probes)
lie in the tail of the kernel density and the posterior is narrow and biased. Drawing those
contacts from a proposal with more weight near zero makes the grid hold several such
patterns. The likelihood then takes that proposal as the key contacts' prior
(``prior_weights``, "robust"), or weights each realisation by prior / proposal back to the
law ("law").

The design, for a law whose realisations scale with their mean (uniform on [0, 2 mean],
exponential): realisation r draws its normalised pattern (mean 1) from the scene's own
stream, ``numpy.random.default_rng([gaps.seed, r])`` as ``granchain.gaps.realise``; at each
key contact its quantile q under the law is mapped to q' = H^-1(q) with the proposal

    H(q) = (1 - a) q + a q^(1/3),      h(q) = (1 - a) + (a / 3) q^(-2/3),

a mixture of the law itself and a Beta(1/3, 1) on the quantile, and the realisation's weight
is the product over its key contacts of 1 / h(q') (the prior density of q is 1). With
a = ``EMPHASIS`` = 0.5, P(q < 0.025) is 0.16 instead of 0.025, each key contact's factor
lies in (0, 2] and the weights' mean is 1; the effective sample size over three key contacts is about 0.6 R
(``modelcheck.effective_size``). Key contacts: those on either side of each probe, but the striker's
own contact (its gap only delays the whole wave: it sets no peak).

The same quantile map and weights hold for any mean gap, so a realisation's gaps are
``mean x pattern_r`` at every node (common random numbers, as with plain draws).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gaps import realise
from .scene import Scene

EMPHASIS = 0.5          # the proposal's share of Beta(1/3, 1) on a key contact's quantile
SCALED_LAWS = ("uniform", "exponential")
KEY_PRIORS = ("robust", "law")
KEY_PRIOR = "robust"    # the joint fit's key-contact prior in the likelihood (prior_weights)
GAP_ONLY_KEY_PRIOR = "law"   # the gap-only fit's (prior_weights says why they differ)


def prior_weights(weights: np.ndarray | None, realisations: int,
                  key_prior: str = KEY_PRIOR) -> np.ndarray:
    """(R,) the realisations' weights in the likelihood and the model check.

    ``"robust"`` (the fits' default): every realisation weighs 1, so the key contacts'
    prior is the proposal itself, half the law and half a Beta(1/3, 1) toward contact.
    ``"law"``: the design's weights prior / proposal, an unbiased average over the law.

    Why robust: a peak is set by the two contacts beside its probe, so the law's chance of
    a near-contact there (2.5 % per contact under the uniform law) decides whether a low
    peak reads as a near-contact or as a lower restitution. Weighted back to the law, the
    joint fit read the stress set's low peaks as a lower e: e covered in 0.86-0.875 of it,
    with intervals of width 0.019 (``benchmarks/inference_outside.py --key-prior law``).
    With the heavier prior e is covered in 0.975 of the stress set and in every natural
    experiment; the natural intervals of e widen from 0.019 to 0.033 and the mean gap's
    coverage rises from 0.925 to 0.975 (docs/explanation/inference.md gives the table).
    The law still governs every other gap, and its mean is what the fits report.

    The gap-only fit reads the timing alone, which the key contacts barely move: both
    priors cover 0.95-0.99 of the natural and the stress sets (150 experiments each), the
    law's intervals narrower (45 against 51 nm), so that fit keeps the law
    (``GAP_ONLY_KEY_PRIOR``)."""
    if key_prior not in KEY_PRIORS:
        raise AssertionError(f"unknown key-contact prior {key_prior!r}")
    if weights is None or key_prior == "robust":
        return np.ones(int(realisations))
    return np.asarray(weights, float)


@dataclass(frozen=True)
class Design:
    """(R, n-1) normalised gap patterns (mean 1 under the law), their weights (R,; mean 1
    over the proposal), the key contacts (0-based gap indices) and the emphasis a."""
    patterns: np.ndarray
    weights: np.ndarray
    contacts: tuple[int, ...]
    emphasis: float

    def gaps(self, mean: float) -> np.ndarray:
        """(R, n-1) gaps (m) at mean gap ``mean`` (m)."""
        return float(mean) * self.patterns

    @property
    def tag(self) -> str:
        """What the design adds to a grid's cache key."""
        return "w" + "-".join(str(c) for c in self.contacts) + f"a{self.emphasis:g}"


def key_contacts(scene: Scene) -> tuple[int, ...]:
    """0-based indices of the gaps on either side of each probe (gap k separates particles
    k + 1 and k + 2), without the striker's gap 0."""
    keys = set()
    for p in scene.probes:
        for k in (p - 2, p - 1):
            if 1 <= k <= scene.n - 2:
                keys.add(k)
    return tuple(sorted(keys))


def proposal_cdf(q: np.ndarray, a: float = EMPHASIS) -> np.ndarray:
    return (1.0 - a) * q + a * np.cbrt(q)


def proposal_pdf(q: np.ndarray, a: float = EMPHASIS) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return (1.0 - a) + (a / 3.0) * np.power(q, -2.0 / 3.0)


def proposal_quantile(x: np.ndarray, a: float = EMPHASIS) -> np.ndarray:
    """H^-1(x): the q with (1 - a) q + a q^(1/3) = x, by bisection on s = q^(1/3) (the
    left side is increasing in s on [0, 1])."""
    x = np.asarray(x, float)
    lo, hi = np.zeros_like(x), np.ones_like(x)
    for _ in range(60):
        s = 0.5 * (lo + hi)
        below = (1.0 - a) * s ** 3 + a * s < x
        lo, hi = np.where(below, s, lo), np.where(below, hi, s)
    return (0.5 * (lo + hi)) ** 3


def _quantile(u: np.ndarray, law: str) -> np.ndarray:
    """The quantile of normalised gaps u (mean 1) under the law."""
    if law == "uniform":
        return np.clip(u / 2.0, 0.0, 1.0)
    return -np.expm1(-u)


def _value(q: np.ndarray, law: str) -> np.ndarray:
    if law == "uniform":
        return 2.0 * q
    return -np.log1p(-np.minimum(q, 1.0 - 1e-16))


def design(scene: Scene, realisations: int, emphasis: float = EMPHASIS) -> Design:
    """The designed realisations 0..R-1 of the scene's gap law (module doc); emphasis 0
    gives the law's own draws with weight 1 each."""
    law = scene.gap_distribution
    if law not in SCALED_LAWS:
        raise AssertionError(f"no designed realisations for gap law {law!r}")
    unit = scene.derive({"gaps": {"mean": 1.0}})
    patterns = np.stack([realise(unit, r) for r in range(int(realisations))])
    weights = np.ones(int(realisations))
    contacts = key_contacts(scene) if emphasis > 0 else ()
    for k in contacts:
        q = proposal_quantile(_quantile(patterns[:, k], law), emphasis)
        patterns[:, k] = _value(q, law)
        weights = weights / proposal_pdf(q, emphasis)
    return Design(patterns, weights, contacts, float(emphasis))

