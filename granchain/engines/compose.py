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
- ``switches(FL) -> on``: one bit per effect with a switch, set while it is on; the
  effects read it before their lane loops and hand it to the two laws below, which test
  its bits, not FL (a load from FL inside a lane loop keeps LLVM from vectorising it);
- ``normal_crit(F, d, G, P, FL, on, n, k, l)``: the normal force of the Coulomb caps
  (LAMMPS's Fncrit) of a contact of net normal force F: |F|, or the ``contact_crit`` of
  the last effect on that has one; the effects' friction laws call it in place of
  ``effects.spec.normal_crit``;
- ``normal_cap(coef, y, G, P, FL, on, ov, n, k, l, d)``: coef Fncrit of an inner contact,
  F the ``contact_normal`` of every effect in turn (an effect's ``contact_cap`` when it
  alone is on); the effects' return mappings call it in place of
  ``effects.spec.normal_cap``;
- ``touching(d, y, LO, G, P, FL, on, n, k, l)``: whether a contact at overlap d touches:
  d > 0, or the ``contact_held`` of an effect on (a contact its law holds closed in
  tension); the effects' friction laws call it in place of ``effects.spec.touching``;
- ``radius_depth(d, G, P, FL, on, n, k, l)``: the overlap a^2 / R* of the contact radius
  a: d, or the ``contact_depth`` of the last effect on that has one (``effects.spec
  .radius_depth``);
- ``wall_force(d, w, G, P, FL, n, l)``: the end wall's force at overlap d and closing
  speed w, by the same ``contact_normal`` laws;
- ``wall_force_at(y, G, P, FL, LO, n, l)``: the end wall's force in the state y: its
  ``wall_force``, then every ``history_normal`` law (a law whose force depends on its
  history in y: a plastic contact's largest overlap, a JKR contact held closed in
  tension at an overlap <= 0);
- ``contact_bond(y, G, P, FL, LO, n, k, l)``: the largest ``bond`` state
  (``effects.spec.BOND_*``) of contact k of lane l by the effects on (BOND_NONE without
  one): held closed by a law, and then bound or with the energy to part;
- ``locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, best)``: per lane l with
  act[l], best[l] the earliest switch any effect's ``locate`` finds inside the lane's
  trial step of length h[l], -1 if none.

An effect is called only while its switch flag is on (``EffectSpec.switch``). The
per-lane laws are inlined where they are called by LLVM (numba's ``forceinline``: LLVM's
``alwaysinline``, so that numba types and lowers each law once, where its own
``inline="always"`` inlined the law's typed IR again at every call and compiled it there)
and the block hooks compiled once each (:data:`BLOCK_HOOKS`), which the kernels that call
these functions (``engines.kernels``, ``engines.events``) call: their lane loops vectorise
as one hand-written routine's would. The per-lane laws and the block routines that inline
them (``engines.integrators``) allocate nothing and are compiled without numba's reference
counting (``_nrt=False``), so the bindings of their array arguments count no references.
The composed functions the drivers call per lane at a sample or stop test, and ``locate``
once per trial step (:data:`CALLED`), are compiled once each and called.

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

import numpy as np
from numba import njit

from ..effects import MODULES, lanes, spec
from . import codes
from .backend import jit_cache_dir, use_jit_cache
from .hermite import hermite3, hermite_root

use_jit_cache()   # before the first @njit(cache=True)

_DISPATCHERS: dict = {}
_NAMESPACES: dict[tuple[str, str], dict] = {}


def _namespace(module, variant: str = "") -> dict:
    """The globals the compiled copies of a module's marked functions see (a
    :data:`PLAIN` variant: its own copy, in which the composed contact laws are the
    plain ones)."""
    key = (module.__name__, variant)
    if key not in _NAMESPACES:
        _NAMESPACES[key] = dict(vars(module))
    return _NAMESPACES[key]


# The hooks that run over a whole block (their lane loops inside): each compiled once, on
# its own, with the block kernels' options (numpy's error model: no test for a division by
# zero, which would keep the lane loops from vectorising; no bounds checks), and called
# by the kernels (LLVM does not inline them: they are large and linked in once each;
# forcing it, numba's forceinline, measured no faster). Inlining them into each caller
# already in numba (as the per-lane laws are) compiles the same code at a half again the
# time.
BLOCK_HOOKS = ("normal", "forces", "project", "energies")

# The variant of a block hook that calls the composed contact laws (``normal_crit``,
# ``normal_cap``) compiled again with the plain ones in their place (Fncrit = |F|, the cap
# of the first normal law alone), which the composed functions call while no other
# normal law and no ``contact_crit`` is on: a law that may be switched on inside a lane
# loop keeps LLVM from vectorising it (its loads run only in the lanes that take the
# branch), and the friction laws' loops are the kernels' longest.
PLAIN = "plain"

# how a per-lane law is compiled: inlined by LLVM where it is called, without numba's
# reference counting (a law allocates nothing; an allocation fails to compile)
INLINED = {"forceinline": True, "_nrt": False}


def _jit(fn, variant: str = ""):
    """The numba dispatcher of a marked function: a copy of it over its module's
    namespace, in which every marked function is its dispatcher (compiled lazily, at the
    first call that reaches it). A block hook (:data:`BLOCK_HOOKS`) is compiled on its
    own, every other marked function inlined where it is called (by LLVM, without
    reference counting)."""
    if (fn, variant) not in _DISPATCHERS:
        module = sys.modules[fn.__module__]
        ns = _namespace(module, variant)
        copy = types.FunctionType(fn.__code__, ns, fn.__name__, fn.__defaults__, fn.__closure__)
        # numba's cache tells compiled functions apart by their qualified names
        copy.__qualname__ = fn.__qualname__ + (f"__{variant}" if variant else "")
        copy.__doc__, copy.__module__ = fn.__doc__, fn.__module__
        if any(getattr(module, h, None) is fn for h in BLOCK_HOOKS):
            opts = {"error_model": "numpy", "boundscheck": False}
        else:
            opts = INLINED
        _DISPATCHERS[fn, variant] = njit(cache=True, **opts)(copy)
    return _DISPATCHERS[fn, variant]


def _bind(module, variant: str = "") -> None:
    """Every marked function in the module's namespace becomes its dispatcher (the
    module's own in the variant)."""
    ns = _namespace(module, variant)
    for k, v in list(ns.items()):
        if _marked(v):
            ns[k] = _jit(v, variant if v.__module__ == module.__name__ else "")


def _composes(module) -> bool:
    """Does the module's compiled code call the composed contact laws?"""
    return any(v is spec.normal_crit or v is spec.normal_cap or v is spec.touching
               or v is spec.radius_depth for v in vars(module).values())


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


def _bit(module) -> int | None:
    """The module's bit in ``switches(FL)`` (its place among the effects with a switch,
    in registry order), or None (always on)."""
    switched = [m for m in MODULES if m.SPEC.switch is not None]
    return switched.index(module) if module in switched else None


def _on(module) -> str | None:
    """'on & (1 << j) != 0' of the module's bit j in ``switches(FL)``, or None."""
    j = _bit(module)
    return None if j is None else f"on & {1 << j} != 0"


def _call(module, hook: str, args: str, assign: str = "", indent: str = "    ",
          guard: bool = True, switch=_switch) -> list[str]:
    """Source lines calling a module's hook (under its switch, if ``guard``: ``switch``
    gives the test, on FL (:func:`_switch`) or on ``switches(FL)`` (:func:`_on`))."""
    name = f"{module.SPEC.name}__{hook}"
    line = f"{assign}{name}({args})"
    cond = switch(module)
    if cond is None or not guard:
        return [indent + line]
    return [f"{indent}if {cond}:", f"{indent}    {line}"]


def _plain(by) -> tuple[object, list, str | None]:
    """(capper, others, when): the effect whose ``contact_cap`` is the cap while it
    alone is on, the other normal and ``contact_crit`` laws, and the test on FL that
    none of them is on (the :data:`PLAIN` hooks may run), None if one of them is always
    on or no effect has a ``contact_cap``."""
    capper = next(iter(by["contact_cap"]), None)
    others = [m for m in by["contact_normal"] if m is not capper]
    for hook in ("contact_crit", "contact_held", "contact_depth"):
        others += [m for m in by[hook] if m is not capper and m not in others]
    if capper is None or not all(_switch(m) for m in others):
        return capper, others, None
    return capper, others, " and ".join(f"not ({_switch(m)})" for m in others) or "True"


def _block_call(module, hook: str, args: str, when: str | None) -> list[str]:
    """Source lines calling a module's block hook under its switch, its :data:`PLAIN`
    variant while ``plain`` (the composed function's local: ``when`` held) if it calls
    the composed contact laws."""
    if when is None or not _composes(module):
        return _call(module, hook, args)
    name = f"{module.SPEC.name}__{hook}"
    lines = ["if plain:", f"    {name}__{PLAIN}({args})", "else:", f"    {name}({args})"]
    cond = _switch(module)
    if cond is None:
        return ["    " + x for x in lines]
    return [f"    if {cond}:"] + ["        " + x for x in lines]


@lru_cache(maxsize=1)
def source() -> str:
    """The composed functions' source, from ``effects.MODULES`` (module docstring)."""
    hooked = [(m, _hooks(m)) for m in MODULES]
    by = {h: [m for m, hs in hooked if h in hs] for h in spec.HOOKS}
    forces = sorted(by["forces"], key=lambda m: m.SPEC.order)   # stable: registry order
    capper, others, when = _plain(by)
    out = ["# The composed physics of the reference kernels, written by",
           "# granchain.engines.compose from granchain.effects.MODULES.", ""]

    out += ["def normal_forces(y, G, P, FL, LO, dy, f):", "    shut = 0"]
    for m in by["normal"]:
        out += _call(m, "normal", "y, G, P, FL, LO, dy, f, shut", "shut = ")
    out += ["    return shut", "", ""]

    # the block hooks that call the composed contact laws: their plain variant while no
    # other normal law and no contact_crit is on
    plain = [] if when is None else [f"    plain = {when}"]
    out += ["def effect_forces(y, G, P, FL, LO, hist_dt, dy, f, shut):"] + plain
    for m in forces:
        out += _block_call(m, "forces", "y, G, P, FL, LO, hist_dt, dy, f, shut", when)
    out += ["    return", "", ""]

    out += ["def project_histories(y, G, P, FL, LO):"] + plain
    for m in by["project"]:
        out += _block_call(m, "project", "y, G, P, FL, LO", when)
    out += ["    return", "", ""]

    out += ["def effect_energies(y, G, P, FL, LO, out):"]
    for m in by["energies"]:
        out += _call(m, "energies", "y, G, P, FL, LO, out")
    out += ["    return", "", ""]

    # the effects on, one bit each: read once per lane loop by the laws below, which
    # run inside the lane loops and test these bits, not FL
    out += ["def switches(FL):", "    on = 0"]
    for m in MODULES:
        if _bit(m) is not None:
            out += [f"    if {_switch(m)}:", f"        on |= {1 << _bit(m)}"]
    out += ["    return on", "", ""]

    # the caps' normal force: |F| unless an effect on says otherwise (the last one on)
    crits = by["contact_crit"]
    out += ["def normal_crit(F, d, G, P, FL, on, n, k, l):"]
    for m in reversed(crits):
        out += _call(m, "contact_crit", "F, d, G, P, FL, n, k, l", "return ", switch=_on)
    out += ["    return abs(F)", "", ""]

    # touching: d > 0, or a law on holds the contact closed at d <= 0
    out += ["def touching(d, y, LO, G, P, FL, on, n, k, l):",
            "    if d > 0.0:",
            "        return True"]
    for m in by["contact_held"]:
        call = f"{m.SPEC.name}__contact_held(d, y, LO, G, P, FL, n, k, l)"
        test = f"{_on(m)} and {call}" if _on(m) else call
        out += [f"    if {test}:", "        return True"]
    out += ["    return False", "", ""]
    # the contact radius's overlap a^2 / R*: d unless a law on says otherwise
    out += ["def radius_depth(d, G, P, FL, on, n, k, l):"]
    for m in reversed(by["contact_depth"]):
        out += _call(m, "contact_depth", "d, G, P, FL, n, k, l", "return ", switch=_on)
    out += ["    return d", "", ""]

    normals = by["contact_normal"]
    out += ["def normal_cap(coef, y, G, P, FL, on, ov, n, k, l, d):"]
    shortcut = when is not None
    if shortcut:
        alone = " and ".join(f"not ({_on(m)})" for m in others) or "True"
        out += [f"    if {alone}:",
                f"        return {capper.SPEC.name}__contact_cap(coef, d, G, n, k, l)"]
    out += ["    w = y[ov + k, l] - y[ov + k + 1, l]",
            "    F = 0.0"]
    for m in normals:
        # past the shortcut the one other law is on: its switch need not be tested again
        unguarded = shortcut and len(others) == 1
        out += _call(m, "contact_normal", "F, d, w, G, P, FL, n, k, l", "F = ",
                     guard=not unguarded, switch=_on)
    out += ["    return coef * " + ("normal_crit(F, d, G, P, FL, on, n, k, l)" if crits
                                    else "abs(F)"), "", ""]

    # the plain laws (no other normal law, no contact_crit on)
    if when is not None:
        out += [f"def normal_crit__{PLAIN}(F, d, G, P, FL, on, n, k, l):",
                "    return abs(F)", "", "",
                f"def normal_cap__{PLAIN}(coef, y, G, P, FL, on, ov, n, k, l, d):",
                f"    return {capper.SPEC.name}__contact_cap(coef, d, G, n, k, l)", "", "",
                f"def touching__{PLAIN}(d, y, LO, G, P, FL, on, n, k, l):",
                "    return d > 0.0", "", "",
                f"def radius_depth__{PLAIN}(d, G, P, FL, on, n, k, l):",
                "    return d", "", ""]

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
        out += _call(m, "history_normal", "F, d, y, LO, G, P, FL, n, n - 1, l", "F = ")
    out += ["    return F", "", ""]

    # a contact held closed by a law: the largest state of the effects on
    out += ["def contact_bond(y, G, P, FL, LO, n, k, l):", "    s = 0"]
    for m in by["bond"]:
        lines = _call(m, "bond", "y, G, P, FL, LO, n, k, l", "b = ")
        pad = " " * (len(lines[-1]) - len(lines[-1].lstrip()))
        out += lines + [pad + "if b > s:", pad + "    s = b"]
    out += ["    return s", "", ""]

    # every lane's earliest switch: each effect's into tau, then the earliest per lane
    out += ["def locate(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, best):",
            "    L = y.shape[1]",
            "    for l in range(L):",
            "        best[l] = -1.0"]
    if by["locate"]:
        out += ["    tau = np.empty(L)"]
    for m in by["locate"]:
        out += _call(m, "locate", "y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, tau")
        body = ["for l in range(L):",
                "    if tau[l] > 0.0 and (best[l] < 0.0 or tau[l] < best[l]):",
                "        best[l] = tau[l]"]
        pad = "        " if _switch(m) else "    "
        out += [pad + b for b in body]
    out += ["    return", ""]
    return "\n".join(out)


# the composed functions compiled once each and called (not inlined): the drivers call
# them per lane at a sample or a stop test, and locate once per trial step (its lane
# loops inside), never inside a step's lane loops
CALLED = ("wall_force", "wall_force_at", "contact_bond", "locate")

# the composed contact laws the PLAIN hooks call in their plain form
PLAIN_LAWS = ("normal_crit", "normal_cap", "touching", "radius_depth")
COMPOSED = ("normal_forces", "effect_forces", "project_histories", "effect_energies",
            "switches", "normal_crit", "normal_cap", "touching", "radius_depth", "wall_force",
            "wall_force_at", "contact_bond", "locate")


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
    # a module numba's cache imports by name to rebuild a called function's environment
    mod = types.ModuleType("granchain_composed")
    sys.modules[mod.__name__] = mod
    ns = mod.__dict__
    ns.update({"__builtins__": __builtins__, "np": np})
    for m in MODULES:
        if _composes(m):
            _bind(m, PLAIN)
        for h, fn in _hooks(m).items():
            ns[f"{m.SPEC.name}__{h}"] = _jit(fn)
            if _composes(m) and h in BLOCK_HOOKS:
                ns[f"{m.SPEC.name}__{h}__{PLAIN}"] = _jit(fn, PLAIN)
    exec(compile(text, _file(text), "exec"), ns)
    out = {}
    for name in COMPOSED + tuple(f"{c}__{PLAIN}" for c in PLAIN_LAWS if f"{c}__{PLAIN}" in ns):
        fn = ns[name]
        fn.__module__ = "granchain_composed"
        out[name] = njit(cache=True, **({} if name in CALLED else INLINED))(fn)
    # the composed functions call each other (wall_force_at calls wall_force, normal_cap
    # normal_crit) compiled
    ns.update(out)
    # the effects' compiled code calls these in place of the stubs of effects.spec (the
    # plain laws in the PLAIN variants, where there are plain laws)
    for (_, variant), ns in _NAMESPACES.items():
        laws = {c: out.get(f"{c}__{variant}" if variant else c, out[c]) for c in PLAIN_LAWS}
        services = ((spec.normal_cap, laws["normal_cap"]),
                    (spec.normal_crit, laws["normal_crit"]),
                    (spec.touching, laws["touching"]),
                    (spec.radius_depth, laws["radius_depth"]),
                    (spec.switches, out["switches"]), (spec.hermite_root, hermite_root),
                    (spec.hermite3, hermite3))
        for k, v in list(ns.items()):
            for stub, real in services:
                if v is stub:
                    ns[k] = real
    return {c: out[c] for c in COMPOSED}


globals().update(_compose())
# the lane helpers, compiled, for the kernels' own loops
bit, overlap = compiled(lanes.bit), compiled(lanes.overlap)
