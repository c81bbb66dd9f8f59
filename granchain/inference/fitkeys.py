"""The scene keys the joint fit infers beside the mean gap (``--fit gap_mean,KEY``): every
scalar scene key declared with a prior range (``granchain.validate.Fit``, on its
:class:`~granchain.validate.Key` in the effect module that holds it), looked up by its path
or its results' name (:func:`fit_key`); the grid axis of one (:class:`FitKey`: its nodes,
the coordinate its prior is uniform in), the checks of a base scene that can vary it
(:func:`check_fit_base`) and of a range given on the command line
(:func:`check_fit_range`)."""
from __future__ import annotations

import difflib
from dataclasses import dataclass

import numpy as np

from ..errors import GranchainError, SceneError
from ..validate import Fit, Key, number_text, short

DEFAULT_KEY = "damping.e"       # the joint fit's key when none is named (today's restitution)


@dataclass(frozen=True)
class FitKey:
    """A fittable scene key: ``path`` (``plasticity.yield_pressure``), its declaration
    ``key`` and the effect whose section holds it."""
    path: str
    key: Key
    effect: str

    @property
    def fit(self) -> Fit:
        return self.key.fit

    @property
    def name(self) -> str:
        """The results' name of the parameter (``Fit.name``)."""
        return self.fit.name

    @property
    def log(self) -> bool:
        return self.fit.log

    def coord(self, x):
        """The coordinate the prior is uniform in, and the grid interpolates in: log x for
        a log-uniform prior, x otherwise."""
        x = np.asarray(x, float)
        return np.log(x) if self.log else x

    def value(self, u):
        """The key's value at coordinate u (the inverse of :meth:`coord`)."""
        u = np.asarray(u, float)
        return np.exp(u) if self.log else u

    def nodes(self, lo: float, hi: float, points: int) -> np.ndarray:
        """The grid's values of the key: ``points`` nodes from lo to hi, evenly spaced in
        :meth:`coord`; the ends exactly lo and hi."""
        x = self.value(np.linspace(float(self.coord(lo)), float(self.coord(hi)), points))
        x[0], x[-1] = lo, hi
        return x


def fittable() -> dict[str, FitKey]:
    """Every fittable scene key by path, in the order of the scene's declarations."""
    from ..scenekeys import declared
    return {path: FitKey(path, key, effect) for path, (key, effect) in declared().items()
            if key.fit is not None}


def fittable_text() -> str:
    """The fittable keys as the refusals list them (each with its results' name)."""
    return ", ".join(f"{p} (or {fk.name})" for p, fk in fittable().items())


def fit_key(name: str) -> FitKey:
    """The fittable key named by its path or its results' name (``restitution``:
    ``damping.e``); any other name is one GranchainError naming ``--fit`` and the fittable
    keys: a scene key that is not declared fittable (a non-scalar one, a choice, a key
    without a prior range) is refused as such."""
    from ..scenekeys import declared
    keys = fittable()
    if name in keys:
        return keys[name]
    by_name = {fk.name: fk for fk in keys.values()}
    if name in by_name:
        return by_name[name]
    hint = (f"fit gap_mean, or gap_mean,KEY with KEY one of {fittable_text()} (e.g. "
            "gap_mean,restitution)")
    if name in declared():
        raise GranchainError(f"--fit: scene key {short(name)} is not declared fittable (a "
                             f"scalar key with a prior range); {hint}")
    close = difflib.get_close_matches(name, list(keys) + list(by_name), n=1)
    raise GranchainError(f"--fit: unknown parameter {short(name)}; " + (
        f"did you mean {close[0]!r}?" if close else hint))


def check_fit_base(base, fk: FitKey) -> None:
    """A base scene whose key ``fk`` the inference can set: the effect holding it on, its
    section's model one the key is declared fittable with (``Fit.models``), and the scene
    valid with the key set (a SceneError naming the key otherwise)."""
    fit = fk.fit
    section = fk.path.rpartition(".")[0]
    fix = (f"add {fk.effect} to effects with {fit.example} (any {fit.symbol}; the inference "
           "sets it)")
    if fk.effect not in base.effects:
        raise SceneError("effects", f"has no {fk.effect}, so the model has no {fit.label} "
                         f"({fk.path}) to fit", fix)
    if fit.models:
        model = base.setting(fk.effect).model
        if model not in fit.models:
            raise SceneError(f"{section}.model", f"is {model}; the inference fits the "
                             f"{fit.label} {fit.symbol} of model {' or '.join(fit.models)}",
                             f"write {fit.example} (any {fit.symbol}; the inference sets it)")


def check_fit_range(fk: FitKey, lo: float, hi: float, points: int,
                    options: tuple[str, str]) -> None:
    """The grid's range of the key: lo < hi, both values the key takes, and >= 2 points;
    ``options`` the command-line options that set (lo, points), named in the refusals."""
    lo_opt, pts_opt = options
    key = fk.key
    floor = 0.0 if (key.positive or key.nonneg) and key.lo is None else key.lo
    for x in (lo, hi):
        try:
            key.number(x)
        except SceneError:
            top = number_text(key.hi) if key.hi is not None else "inf"
            raise GranchainError(f"{lo_opt}: {x:g} is not between {number_text(floor or 0.0)} "
                                 f"and {top}; give the smallest {fk.fit.label} to simulate, "
                                 f"e.g. {number_text(fk.fit.lo)}") from None
    if not lo < hi:
        raise GranchainError(f"{lo_opt}: {lo:g} is not below the range's top {hi:g}; give the "
                             f"smallest {fk.fit.label} to simulate, below {hi:g}")
    if points < 2:
        raise GranchainError(f"{pts_opt}: {points} is too few; give >= 2")
