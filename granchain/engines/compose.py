"""The reference kernels' physics, composed from the effect registry.

Each effect module holds its laws and the compiled parts of ``effects.spec.HOOKS`` it
needs (its normal force on a contact, its forces on the spheres, its history projection,
its energy, its event location), as plain functions marked ``effects.spec.compiled``. This
module compiles them with numba and writes, from ``effects.MODULES``, the source of the
few functions that call them in turn:

- ``normal_forces(y, G, P, FL, LO, dy, f) -> shut``: every effect's ``normal``, in registry
  order (the first sets the normal force f, the others act on it);
- ``effect_forces(y, G, P, FL, LO, hist_dt, dy, f, shut)``: every effect's ``forces``, in
  ``EffectSpec.order``;
- ``project_histories(y, G, P, FL, LO)``: every ``project``;
- ``effect_energies(y, G, P, FL, LO, out)``: every ``energies``;
- ``normal_crit(F, d, G, P, FL, n, k, l)``: the normal force of the Coulomb caps
  (LAMMPS's Fncrit) of a contact of net normal force F: |F|, or the ``contact_crit`` of
  the last effect on that has one; the effects' friction laws call it in place of
  ``effects.spec.normal_crit``;
- ``normal_cap(coef, y, G, P, FL, ov, n, k, l, d)``: coef Fncrit of an inner contact, F the
  ``contact_normal`` of every effect in turn (an effect's ``contact_cap`` when it alone
  is on); the effects' return mappings call it in place of ``effects.spec.normal_cap``;
- ``wall_force(d, w, G, P, FL, n, l)``: the end wall's force at overlap d and closing
  speed w, by the same ``contact_normal`` laws;
- ``wall_force_at(y, G, P, FL, LO, n, l)``: the end wall's force in the state y: its
  ``wall_force``, then every ``history_normal`` law (a law whose force depends on its
  history in y) on a closed wall contact;
- ``locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol) -> tau``: the earliest switch any
  effect's ``locate`` finds inside a trial step, -1 if none.

An effect is called only while its switch flag is on (``EffectSpec.switch``). The
per-lane laws are inlined where they are called (numba ``inline="always"``) and the block
hooks compiled once each (:data:`BLOCK_HOOKS`), which the kernels that call these
functions (``engines.kernels``, ``engines.events``) call: their lane loops vectorise as
one hand-written routine's would (the same vector instructions in the machine code), but
each inlined composed function binds its array arguments again, and the reference counts
of those bindings (atomic increments and decrements that numba's pruning leaves between
the calls) cost the every-effect kernels a few per cent against the hand-written routine.

The generated source (:func:`source`) is a file in the JIT cache folder
(``backend.jit_cache_dir``, named by the hash of every source the kernels are made of, the
effect modules and this one included), so numba caches what it compiles like any other
module's functions.
"""
from __future__ import annotations

import os
import sys
import types
from functools import lru_cache

from numba import njit

from ..effects import MODULES, lanes, spec
from . import codes
from .backend import jit_cache_dir, use_jit_cache
from .hermite import hermite_root

use_jit_cache()   # before the first @njit(cache=True)

_DISPATCHERS: dict = {}
_NAMESPACES: dict[str, dict] = {}


def _namespace(module) -> dict:
    """The globals the compiled copies of a module's marked functions see."""
    if module.__name__ not in _NAMESPACES:
        _NAMESPACES[module.__name__] = dict(vars(module))
    return _NAMESPACES[module.__name__]


# The hooks that run over a whole block (their lane loops inside): each compiled once, on
# its own, with the block kernels' options (numpy's error model: no test for a division by
# zero, which would keep the lane loops from vectorising; no bounds checks), and called
# by the kernels (LLVM does not inline them: they are large and linked in once each;
# forcing it, numba's forceinline, measured no faster). Inlining them into each caller
# already in numba (as the per-lane laws are) compiles the same code at a half again the
# time.
BLOCK_HOOKS = ("normal", "forces", "project", "energies")


def _jit(fn):
    """The numba dispatcher of a marked function: a copy of it over its module's
    namespace, in which every marked function is its dispatcher (compiled lazily, at the
    first call that reaches it). A block hook (:data:`BLOCK_HOOKS`) is compiled on its
    own, every other marked function inlined where it is called."""
    if fn not in _DISPATCHERS:
        module = sys.modules[fn.__module__]
        ns = _namespace(module)
        copy = types.FunctionType(fn.__code__, ns, fn.__name__, fn.__defaults__, fn.__closure__)
        copy.__qualname__, copy.__doc__ = fn.__qualname__, fn.__doc__
        copy.__module__ = fn.__module__
        if any(getattr(module, h, None) is fn for h in BLOCK_HOOKS):
            opts = {"error_model": "numpy", "boundscheck": False}
        else:
            opts = {"inline": "always"}
        _DISPATCHERS[fn] = njit(cache=True, **opts)(copy)
    return _DISPATCHERS[fn]


def _bind(module) -> None:
    """Every marked function in the module's namespace becomes its dispatcher."""
    ns = _namespace(module)
    for k, v in list(ns.items()):
        if _marked(v):
            ns[k] = _jit(v)


def compiled(fn):
    """The compiled form of a marked function of any module (``effects.spec.compiled``),
    inlined where it is called: what the kernels call the effects' lanes and laws and
    ``granchain.obsrules`` by."""
    _bind(sys.modules[fn.__module__])
    return _jit(fn)


def _marked(v) -> bool:
    return isinstance(v, types.FunctionType) and getattr(v, "granchain_compiled", False)


def _hooks(module) -> dict[str, object]:
    """The hooks of ``spec.HOOKS`` a module defines, by name."""
    return {h: getattr(module, h) for h in spec.HOOKS if _marked(getattr(module, h, None))}


def _switch(module) -> str | None:
    """'FL[i] != 0' of the module's switch flag, or None (always on)."""
    flag = module.SPEC.switch
    return None if flag is None else f"FL[{getattr(codes, flag)}] != 0"


def _call(module, hook: str, args: str, assign: str = "", indent: str = "    ",
          guard: bool = True) -> list[str]:
    """Source lines calling a module's hook (under its switch, if ``guard``)."""
    name = f"{module.SPEC.name}__{hook}"
    line = f"{assign}{name}({args})"
    cond = _switch(module)
    if cond is None or not guard:
        return [indent + line]
    return [f"{indent}if {cond}:", f"{indent}    {line}"]


@lru_cache(maxsize=1)
def source() -> str:
    """The composed functions' source, from ``effects.MODULES`` (module docstring)."""
    hooked = [(m, _hooks(m)) for m in MODULES]
    by = {h: [m for m, hs in hooked if h in hs] for h in spec.HOOKS}
    forces = sorted(by["forces"], key=lambda m: m.SPEC.order)   # stable: registry order
    out = ["# The composed physics of the reference kernels, written by",
           "# granchain.engines.compose from granchain.effects.MODULES.", ""]

    out += ["def normal_forces(y, G, P, FL, LO, dy, f):", "    shut = 0"]
    for m in by["normal"]:
        out += _call(m, "normal", "y, G, P, FL, LO, dy, f, shut", "shut = ")
    out += ["    return shut", "", ""]

    out += ["def effect_forces(y, G, P, FL, LO, hist_dt, dy, f, shut):"]
    for m in forces:
        out += _call(m, "forces", "y, G, P, FL, LO, hist_dt, dy, f, shut")
    out += ["    return", "", ""]

    out += ["def project_histories(y, G, P, FL, LO):"]
    for m in by["project"]:
        out += _call(m, "project", "y, G, P, FL, LO")
    out += ["    return", "", ""]

    out += ["def effect_energies(y, G, P, FL, LO, out):"]
    for m in by["energies"]:
        out += _call(m, "energies", "y, G, P, FL, LO, out")
    out += ["    return", "", ""]

    # the caps' normal force: |F| unless an effect on says otherwise (the last one on)
    crits = by["contact_crit"]
    out += ["def normal_crit(F, d, G, P, FL, n, k, l):"]
    for m in reversed(crits):
        out += _call(m, "contact_crit", "F, d, G, P, FL, n, k, l", "return ")
    out += ["    return abs(F)", "", ""]

    normals = by["contact_normal"]
    out += ["def normal_cap(coef, y, G, P, FL, ov, n, k, l, d):"]
    capper = next(iter(by["contact_cap"]), None)
    others = [m for m in normals if m is not capper]
    others += [m for m in crits if m is not capper and m not in others]
    shortcut = capper is not None and all(_switch(m) for m in others)
    if shortcut:
        alone = " and ".join(f"not ({_switch(m)})" for m in others) or "True"
        out += [f"    if {alone}:",
                f"        return {capper.SPEC.name}__contact_cap(coef, d, G, n, k, l)"]
    out += ["    w = y[ov + k, l] - y[ov + k + 1, l]",
            "    F = 0.0"]
    for m in normals:
        # past the shortcut the one other law is on: checking its switch again inside
        # the return mappings' lane loops keeps LLVM from vectorising them
        unguarded = shortcut and len(others) == 1
        out += _call(m, "contact_normal", "F, d, w, G, P, FL, n, k, l", "F = ",
                     guard=not unguarded)
    out += ["    return coef * " + ("normal_crit(F, d, G, P, FL, n, k, l)" if crits else "abs(F)"),
            "", ""]

    # the first normal law gives the force of any overlap (zero when open), the others
    # act on a closed contact
    out += ["def wall_force(d, w, G, P, FL, n, l):", "    F = 0.0"]
    for j, m in enumerate(normals):
        if j == 0:
            out += _call(m, "contact_normal", "F, d, w, G, P, FL, n, n - 1, l", "F = ")
        else:
            out += ["    if d > 0.0:"] + _call(m, "contact_normal",
                                                 "F, d, w, G, P, FL, n, n - 1, l", "F = ",
                                                 indent="        ")
    out += ["    return F", "", ""]

    # the wall's force in a state: the laws above, then those reading their history in y
    out += ["def wall_force_at(y, G, P, FL, LO, n, l):",
            "    d = y[LO[%d] + n - 1, l] - G[n - 1, l]" % codes.L_DISP,
            "    F = wall_force(d, y[LO[%d] + n - 1, l], G, P, FL, n, l)" % codes.L_VEL]
    for m in by["history_normal"]:
        out += ["    if d > 0.0:"] + _call(m, "history_normal",
                                             "F, d, y, LO, G, P, FL, n, n - 1, l", "F = ",
                                             indent="        ")
    out += ["    return F", "", ""]

    out += ["def locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol):", "    best = -1.0"]
    for m in by["locate"]:
        out += _call(m, "locate", "y, ynew, K0, K1, G, P, FL, LO, n, h, rtol", "tau = ")
        body = ["if tau > 0.0 and (best < 0.0 or tau < best):", "    best = tau"]
        pad = "        " if _switch(m) else "    "
        out += [pad + b for b in body]
    out += ["    return best", ""]
    return "\n".join(out)


COMPOSED = ("normal_forces", "effect_forces", "project_histories", "effect_energies",
            "normal_crit", "normal_cap", "wall_force", "wall_force_at", "locate")


def _file(text: str) -> str:
    """Path of the generated source in the JIT cache folder, written if it differs (an
    unchanged file keeps its time stamp, which numba's cache checks)."""
    path = jit_cache_dir() / "composed.py"
    try:
        if not path.is_file() or path.read_text() != text:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f".composed-{os.getpid()}.py")
            tmp.write_text(text)
            os.replace(tmp, path)
    except OSError:
        pass
    return str(path)


def _compose() -> dict:
    """Compile the effects' marked functions and the composed ones; returns the composed
    dispatchers by name."""
    for m in (lanes,) + tuple(MODULES):
        _bind(m)
    text = source()
    ns = {"__name__": "granchain_composed", "__builtins__": __builtins__}
    for m in MODULES:
        for h, fn in _hooks(m).items():
            ns[f"{m.SPEC.name}__{h}"] = _jit(fn)
    exec(compile(text, _file(text), "exec"), ns)
    out = {}
    for name in COMPOSED:
        fn = ns[name]
        fn.__module__ = "granchain_composed"
        out[name] = njit(cache=True, inline="always")(fn)
    # the composed functions call each other (wall_force_at calls wall_force, normal_cap
    # normal_crit) compiled
    ns.update(out)
    # the effects' compiled code calls these in place of the stubs of effects.spec
    services = ((spec.normal_cap, out["normal_cap"]), (spec.normal_crit, out["normal_crit"]),
                (spec.hermite_root, hermite_root))
    for ns in _NAMESPACES.values():
        for k, v in list(ns.items()):
            for stub, real in services:
                if v is stub:
                    ns[k] = real
    return out


globals().update(_compose())
# the lane helpers, compiled, for the kernels' own loops
bit, overlap = compiled(lanes.bit), compiled(lanes.overlap)
