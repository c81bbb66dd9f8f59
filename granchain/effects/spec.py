"""What every physical effect declares, once (the registry in ``granchain.effects`` adds
these up, as LAMMPS' granular sub-models declare their coefficients and history sizes)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EffectSpec:
    """Declaration of one effect of Eq. 5.1.

    name: the scene's ``effects`` entry.
    state: blocks the effect adds to a chain's state vector, as (kernel layout slot,
        'particle' (n entries) or 'contact' (n-1 entries)), in state order.
    work: the energy-ledger column of the work the effect does on the particles
        (``granchain.trajectory.ENERGY_COLUMNS``), or None if it does none.
    work_slot: the kernel layout slot accumulating that work.
    table_column: the results-table column of that work (J).
    lammps_ledger: the per-atom LAMMPS quantity summed per chain into the ledger for
        this effect (its work, or for rotation the rotational kinetic energy), or None.
    lammps_reports_work: False when LAMMPS has no per-atom output for the work (contact
        friction inside ``pair granular``): the LAMMPS ledger then closes by construction
        and that column is the balance residual.
    params, flags: the slots of the kernels' parameter vector P and flag vector FL that
        the effect's ``kernel(term)`` fills (``P_*``, ``F_*``).
    rows: the per-sphere or per-contact rows of the kernels' per-chain array G that the
        effect's ``rows(term, chain)`` fills (``G_*``).
    ``engines.codes`` numbers every slot, row, state block and ledger column from these
    declarations, in registry order.
    """
    name: str
    state: tuple[tuple[str, str], ...] = ()
    work: str | None = None
    work_slot: str | None = None
    table_column: str | None = None
    lammps_ledger: str | None = None
    lammps_reports_work: bool = True
    params: tuple[str, ...] = ()
    flags: tuple[str, ...] = ()
    rows: tuple[str, ...] = ()

    @property
    def work_code(self) -> str | None:
        """The kernels' name of the effect's ledger column (``E_`` and the work slot's
        suffix: L_WORK_GROOVE -> E_WORK_GROOVE)."""
        return "E_" + self.work_slot[2:] if self.work_slot else None
