"""The kernels' numbering of what the chain and the effects declare, filled in by the
registry (``granchain.effects``) once every effect module is loaded.

numba-free. Indices of the parameter vector P, the flags FL, the layout offsets LO, the
per-chain rows G and the energy columns, numbered from the declarations (``EffectSpec``:
params, flags, rows, state, work_slot) in registry order, the chain first. The generated
names (``P_HERTZ_K``, ``F_GROOVE_FRICTION``, ``G_MASS``, ``L_GROOVE_HIST``,
``E_WORK_GROOVE``, ...) become attributes of this module, so that an effect's compiled
law reads its own slots as ``S.P_...`` (``from . import slots as S``) and numba freezes
them into the kernels like any other constant. Their prefix names the array they index:
P parameters, F flags, G per-chain rows, L layout offsets (state blocks and accumulated
works), E energy columns.
"""
from __future__ import annotations


def _number(names) -> dict[str, int]:
    """Consecutive indices of names in order of first appearance."""
    out: dict[str, int] = {}
    for name in names:
        out.setdefault(name, len(out))
    return out


def number(specs, energy_columns) -> None:
    """Number the slots of ``specs`` (the chain's first, then the effects' in registry
    order) and the ``energy_columns`` into this module's attributes."""
    g = globals()
    g["P_SLOTS"] = _number(p for s in specs for p in s.params)
    g["F_SLOTS"] = _number(f for s in specs for f in s.flags)
    # rows of a chain's per-chain array G (B, G_LEN * n), each block n rows long: row
    # G_X * n + i is entry i of block G_X. A per-contact block holds contacts 0 .. n-2
    # (spheres k, k+1), then the end wall at n-1; a per-sphere block the spheres.
    # G_GAP: kernel gaps (overlap_k = x_k - x_{k+1} - G_GAP_k; the wall's x_n - G_GAP_{n-1})
    g["G_SLOTS"] = _number(r for s in specs for r in s.rows)
    # layout offsets LO (-1: absent): the state blocks (displacements and velocities, then
    # each effect's), then one accumulated-work entry per effect that does work, then
    # L_STATE_SIZE (the state's length)
    g["L_SLOTS"] = _number([b for s in specs for b, _ in s.state]
                           + [s.work_slot for s in specs if s.work_slot] + ["L_STATE_SIZE"])
    # sample columns of the energy array, in energy_columns order: the three mechanical
    # energies (kinetic translational, kinetic rotational, potential), then the works (each
    # effect's, then the dead load's, the chain's)
    chain = specs[0]
    g["E_SLOTS"] = {"E_KIN_TRANS": 0, "E_KIN_ROT": 1, "E_POT": 2,
                    **{s.work_code: energy_columns.index(s.work) for s in specs if s.work_code},
                    "E_WORK_LOAD": energy_columns.index(chain.work)}
    for table in ("P_SLOTS", "F_SLOTS", "G_SLOTS", "L_SLOTS", "E_SLOTS"):
        g.update(g[table])
    g["P_LEN"], g["F_LEN"], g["G_LEN"], g["L_LEN"], g["E_LEN"] = (
        len(g["P_SLOTS"]), len(g["F_SLOTS"]), len(g["G_SLOTS"]), len(g["L_SLOTS"]),
        len(energy_columns))
    # (layout slot, energy column) of every accumulated work, in registry order
    g["WORK_SLOTS"] = tuple((g["L_SLOTS"][s.work_slot], g["E_SLOTS"][s.work_code])
                            for s in specs if s.work_slot)
    # the effects' state blocks integrated as velocities, as the chain's velocities are
    # (their rates start from zero in each force call; the Verlet kicks them)
    g["KICKED"] = tuple(g["L_SLOTS"][b] for s in specs for b in s.kicked)
    g["NAMES"] = {**g["P_SLOTS"], **g["F_SLOTS"], **g["G_SLOTS"], **g["L_SLOTS"],
                  **g["E_SLOTS"]}
