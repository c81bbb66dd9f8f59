"""What every physical effect declares, once (the registry in ``granchain.effects`` adds
these up, as LAMMPS' granular sub-models declare their coefficients and history sizes),
and the compiled parts an effect module may hold, with the signatures the engines'
composer (``granchain.engines.compose``) calls them with."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..units import lmp_float, to_micro


@dataclass(frozen=True)
class EffectSpec:
    """Declaration of one effect of Eq. 5.1.

    name: the scene's ``effects`` entry.
    state: blocks the effect adds to a chain's state vector, as (kernel layout slot,
        'particle' (n entries) or 'contact' (n-1 entries)), in state order.
    kicked: those of its state blocks that are integrated as velocities are (the spins:
        their rates start at zero in each force call and the effects' torques add to
        them; velocity Verlet kicks them); the others are histories, return-mapped by the
        effect's ``project`` after a step.
    work: the energy-ledger column of the work the effect does on the particles
        (``granchain.trajectory.ENERGY_COLUMNS``), or None if it does none.
    work_slot: the kernel layout slot accumulating that work.
    table_column: the results-table column of that work (J).
    work_note: what that work is, for the column's description (``granchain.columns``).
    lammps_ledger: the per-atom LAMMPS quantity summed per chain into the ledger for
        this effect (its work, or for rotation the rotational kinetic energy), or None.
    lammps_reports_work: False when LAMMPS has no per-atom output for the work (contact
        friction inside ``pair granular``): the LAMMPS ledger then closes by construction
        and that column is the balance residual.
    lammps_potential: the per-atom LAMMPS quantity (energy units) of the elastic energy
        the effect's contact law holds beyond the Hertz energy the engine computes from
        the positions, summed per chain into the ledger's potential column; or None.
    lammps_wall_force: the per-atom LAMMPS quantity (force units) of the x force the
        effect adds at the end wall beyond fix wall/gran's, summed per chain into the
        recorded wall force; or None.
    normal_speed: True when its ``contact_normal`` depends on the closing speed (contact
        damping): the LAMMPS engine then records the end wall's force as the reference
        law at each sample's x and v (fix wall/gran's own output takes the half-step
        velocity); otherwise it records fix wall/gran's own output, which holds a contact
        the law keeps closed in tension (JKR) as the law's tensile force.
    lammps_wall_state: the effect's state block (its slot name) whose end-wall entry is
        fix wall/gran's per-atom contact flag (its ``contacts`` output column 1: 1 while
        the fix's touch test holds the sphere, a contact held closed in tension included),
        or None. Where the LAMMPS engine evaluates the wall's law itself (``normal_speed``),
        it dumps that flag and evaluates the law in the state it gives (the
        ``history_normal`` laws included), as the reference engine records the force.
    params, flags: the slots of the kernels' parameter vector P and flag vector FL that
        the effect's ``kernel(term)`` fills (``P_*``, ``F_*``).
    rows: the per-sphere or per-contact rows of the kernels' per-chain array G that the
        effect's ``rows(term, chain)`` fills (``G_*``).
    order: where its forces enter the sums on a sphere: the composer calls the effects'
        ``forces`` in ascending order, ties in registry order (the sums are rounded in
        that order, so a change of order moves trajectories by rounding).
    always: why every scene must have the effect (a scene without it is refused), or None.
    requires: (effect, why) of each effect it cannot act without (the scene refuses it
        while that one is off).
    step_cost: what a particle-step of a chain with the effect on costs the reference
        engine over one of the packaged cost model's chain (every effect of Eq. 5.1),
        measured (``benchmarks/contacts.py --every``); the estimates
        (``costmodel.member_seconds``) take the largest of the effects on. 1 for the
        effects of that chain.
    ``granchain.effects.slots`` numbers every slot, row, state block and ledger column
    from these declarations, in registry order.
    """
    name: str
    state: tuple[tuple[str, str], ...] = ()
    kicked: tuple[str, ...] = ()
    work: str | None = None
    work_slot: str | None = None
    table_column: str | None = None
    work_note: str | None = None
    lammps_ledger: str | None = None
    lammps_reports_work: bool = True
    lammps_potential: str | None = None
    lammps_wall_force: str | None = None
    normal_speed: bool = False
    lammps_wall_state: str | None = None
    params: tuple[str, ...] = ()
    flags: tuple[str, ...] = ()
    rows: tuple[str, ...] = ()
    order: int = 0
    always: str | None = None
    requires: tuple[tuple[str, str], ...] = ()
    step_cost: float = 1.0

    @property
    def work_code(self) -> str | None:
        """The kernels' name of the effect's ledger column (``E_`` and the work slot's
        suffix: L_WORK_GROOVE -> E_WORK_GROOVE)."""
        return "E_" + self.work_slot[2:] if self.work_slot else None

    @property
    def switch(self) -> str | None:
        """The flag that is 1 while the effect is on: ``F_<NAME>``, if it declares it; an
        effect without it (hertz) is always on."""
        flag = "F_" + self.name.upper()
        return flag if flag in self.flags else None

    @property
    def histories(self) -> tuple[str, ...]:
        """Its state blocks that are histories (not kicked)."""
        return tuple(b for b, _ in self.state if b not in self.kicked)


@dataclass(frozen=True)
class DeckPart:
    """What an effect adds to a LAMMPS deck: the value of its one hook, ``lammps(term,
    deck)``, which ``granchain.lammps.deck`` calls for every registered effect in registry
    order (``term`` None while the effect is off) and adds up. ``deck`` holds the deck's
    ``terms`` (its first chain's), ``members`` (each chain's terms under a radius spread,
    else None) and ``n_chains``.

    pair: words of ``pair_style granular``'s sub-models, by sub-model (LAMMPS writes them
        in the order normal, damping, tangential, rolling): "normal" a template of the pair
        of materials' {E} (1e3 Pa), {nu} and the normal model's damping coefficient
        {damp}; "damp" that coefficient; "damping", "tangential", "rolling" the words; a
        later effect's entry replaces an earlier one's.
    unlike: (material a, material b) -> the pair entries of an unlike pair of atom types
        where they are not the one-material words, or None.
    notes: comment lines stating the law in the deck, by sub-model (a later effect's
        replaces an earlier one's), before the pair_coeff lines; unlike_notes: those of a
        deck with unlike pairs; wall_notes: those at the end wall (fix wall/gran takes the
        pairs' normal law and damping).
    contact: how the particle contacts act, in one phrase (a later effect's replaces an
        earlier one's).
    fix: (comment, arguments) of its part of ``fix groove/drag``, the granchain plugin,
        which the deck then loads; fix_option: arguments that fix takes whenever it is
        loaded; fix_energy: (its global output, the work it is) for the global energy
        ledger whenever it is loaded.
    plugin_lines: deck lines of the plugin's other styles (comments and commands, after
        fix groove/drag; the deck then loads the plugin).
    integrator: the deck's time integrator (comment and fix lines).
    energy: (compute line, value, what it is) of the global energy ledger.
    ledger_compute: the compute line of its per-atom ledger quantity
        (``EffectSpec.lammps_ledger``); ledger_note: what that per-chain column is.
    atoms: deck lines before read_data (text added to the atoms comment); read_data: a
        suffix of the read_data command; data: lines it adds to chain.data.
    travel: (v_max, t) -> a bound (m) on how far a sphere can move in a run of length t
        whose fastest striker starts at v_max, when the effect can speed spheres up (the
        deck's box leaves room for it); None: it cannot.
    """
    pair: dict = field(default_factory=dict)
    unlike: object = None
    notes: dict = field(default_factory=dict)
    unlike_notes: tuple[str, ...] = ()
    wall_notes: tuple[str, ...] = ()
    contact: str | None = None
    fix: tuple[str, str] | None = None
    fix_option: str | None = None
    fix_energy: tuple[str, str] | None = None
    plugin_lines: tuple[str, ...] = ()
    integrator: str | None = None
    energy: tuple[str, str, str] | None = None
    ledger_compute: str | None = None
    ledger_note: str | None = None
    atoms: str = ""
    read_data: str = ""
    data: tuple[str, ...] = ()
    travel: object = None


def pair_words(pair: dict, E: float, nu: float) -> list[str]:
    """The pair_coeff sub-model words of a pair of materials of modulus E (Pa) and
    Poisson's ratio nu, from the effects' ``DeckPart.pair`` entries (merged in registry
    order), in LAMMPS's order: the normal model with its damping coefficient, its damping,
    then the tangential and the rolling model where given."""
    normal = pair["normal"].format(E=lmp_float(to_micro(E, "pressure")), nu=lmp_float(nu),
                                   damp=pair["damp"])
    return [f"{normal} {pair['damping']}"] + [pair[k] for k in ("tangential", "rolling")
                                               if k in pair]


def compiled(fn):
    """Mark a function of an effect module as compiled by the engines (numba, inlined
    into the kernels that call it, without reference counting: a marked function other
    than a block hook, ``normal``, ``forces``, ``project`` or ``energies``, allocates no
    array, or it fails to compile). It stays a plain Python function here: the effects
    load no compiler. In compiled code a marked function may call the other marked
    functions of its module and of ``lanes``, the numbered slots (``slots``) and the
    composed contact laws below."""
    fn.granchain_compiled = True
    return fn


# The hooks the composer knows, each optional: its name -> its signature and what it does.
# G: the per-chain rows (G_LEN * n, L), y/dy: a block's state and rates (ny, L), f: the
# normal force of each contact (n, L; row n-1 the end wall's), shut: bit k set when contact
# k is open in every lane. k: a contact (n-1: the end wall), l: a lane.
HOOKS = {
    "normal": ("(y, G, P, FL, LO, dy, f, shut) -> shut",
               "its part of every contact's normal force f (and its work rate), in registry "
               "order, before the spheres' accelerations are summed"),
    "contact_normal": ("(F, d, w, G, P, FL, n, k, l) -> F",
                       "the same law on one contact of overlap d > 0 and closing speed w, "
                       "given the normal force F of the effects before it (the end wall's "
                       "force, the Coulomb caps)"),
    "history_normal": ("(F, d, y, LO, G, P, FL, n, k, l) -> F",
                       "a normal law that reads its history in the state y: the force of "
                       "contact k in lane l at overlap d (of either sign: a contact its "
                       "history holds closed at d <= 0 carries a force there) given the "
                       "force F of the contact_normal laws, where the state is at hand (the "
                       "end wall's recorded force)"),
    "contact_crit": ("(F, d, G, P, FL, n, k, l) -> Fncrit",
                     "the normal force of the Coulomb caps (LAMMPS's Fncrit) of contact k in "
                     "lane l at overlap d, whose net normal force is F, when the law says "
                     "other than |F| (the last effect on that has the hook gives it)"),
    "contact_held": ("(d, y, LO, G, P, FL, n, k, l) -> bool",
                     "whether contact k in lane l at overlap d is closed by its law and its "
                     "history in y (a contact held closed in tension at d <= 0 carries the "
                     "friction laws and the damping there, as LAMMPS's touch does)"),
    "contact_depth": ("(d, G, P, FL, n, k, l) -> depth",
                      "the overlap a^2 / R* of the law's contact radius a at overlap d, when "
                      "it is not d (the Mindlin stiffness 8 G_eff a = 8 G_eff sqrt(R* "
                      "depth))"),
    "contact_cap": ("(coef, d, G, n, k, l) -> cap",
                    "coef times its contact_normal when no other contact_normal is on, in "
                    "its own order of operations"),
    "forces": ("(y, G, P, FL, LO, hist_dt, dy, f, shut)",
              "its forces and torques on the spheres, its history rates (with hist_dt > 0, "
              "velocity Verlet: the histories advanced by hist_dt and return-mapped first) "
              "and its work rate, in ``order``"),
    "project": ("(y, G, P, FL, LO)", "the return mapping of its histories after a step"),
    "energies": ("(y, G, P, FL, LO, out)", "adds its mechanical energy to its column of out "
                 "(E_LEN, L)"),
    "bond": ("(y, G, P, FL, LO, n, k, l) -> state",
             "whether its law holds contact k of lane l closed and whether that is decided: "
             "BOND_NONE (it does not hold it: open, or a law without attraction), "
             "BOND_CAPTURED (held, and the energy of the spheres' relative motion is less "
             "than its law takes from it on the way to the contact's opening: bound), "
             "BOND_UNDECIDED (held, with the energy to part); the t_end auto stop rule "
             "waits while a contact is undecided"),
    "locate": ("(y, ynew, K0, K1, G, P, FL, LO, n, h, rtol, act, tau)",
               "the event method: per lane l with act[l], tau[l] the first tau in (0, 1) "
               "of a switch of its law inside the lane's trial step y -> ynew of length "
               "h[l] (rates K0, K1 at its ends), -1 if none or not act[l]; its test over "
               "the lanes without a branch per lane"),
}


# the states of a contact a ``bond`` hook returns (the composed ``contact_bond`` gives the
# largest of the effects on)
BOND_NONE, BOND_CAPTURED, BOND_UNDECIDED = 0, 1, 2


# The composed contact laws an effect's compiled code may call (the composer puts the
# composed functions in their place; called from Python they are not defined).
def switches(FL):
    """The effects that are on, one bit each (``EffectSpec.switch``), from the flags FL.
    An effect reads it once, before its lane loops, and hands it to :func:`normal_crit`
    and :func:`normal_cap`: a load from FL inside a lane loop (the array may alias the
    state the loop writes, so it is loaded again in every lane) keeps LLVM from
    vectorising the loop."""
    raise NotImplementedError("switches is composed by granchain.engines.compose")


def normal_cap(coef, y, G, P, FL, on, ov, n, k, l, d):
    """coef Fncrit: the Coulomb cap of inner contact k of lane l at overlap d > 0, Fncrit
    the :func:`normal_crit` of F, the net normal force of every effect's
    ``contact_normal`` (registry order); on: :func:`switches`; ov: the offset of the
    velocities in y (``LO[L_VEL]``, read before the lane loop, as ``on`` is)."""
    raise NotImplementedError("normal_cap is composed by granchain.engines.compose")


def normal_crit(F, d, G, P, FL, on, n, k, l):
    """The normal force of the Coulomb caps (LAMMPS's Fncrit) of contact k of lane l at
    overlap d, of net normal force F: |F|, unless an effect on (``on``: :func:`switches`)
    gives it by its ``contact_crit``."""
    raise NotImplementedError("normal_crit is composed by granchain.engines.compose")


def touching(d, y, LO, G, P, FL, on, n, k, l):
    """Is contact k of lane l at overlap d touching (LAMMPS's touch: its friction, rolling
    and damping laws act)? d > 0, or the ``contact_held`` of an effect on (``on``:
    :func:`switches`) says its history holds it closed."""
    raise NotImplementedError("touching is composed by granchain.engines.compose")


def radius_depth(d, G, P, FL, on, n, k, l):
    """The overlap a^2 / R* of contact k's contact radius a at overlap d: d, unless an
    effect on gives it by its ``contact_depth``."""
    raise NotImplementedError("radius_depth is composed by granchain.engines.compose")


def hermite_root(d0, w0, d1, w1, h, level, up):
    """The first tau in (0, 1] at which the cubic Hermite of a value (d0, d1 at the ends
    of a step of length h, rates w0, w1) crosses level (up: from below), -1 if none."""
    raise NotImplementedError("hermite_root is given by granchain.engines.compose")


def hermite3(d0, w0, d1, w1, h, tau):
    """The cubic Hermite of a value (d0, d1 at the ends of a step of length h, rates w0,
    w1) at tau in [0, 1]: the interpolant :func:`hermite_root` searches."""
    raise NotImplementedError("hermite3 is given by granchain.engines.compose")
