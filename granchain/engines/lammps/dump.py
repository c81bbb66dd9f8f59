"""Reading a LAMMPS deck's output back into per-chain arrays: the binary dumps
(:func:`read_binary`, with :mod:`granchain.engines.lammps.binary`) or the text dump and
ledger (:func:`read_dump` with MDAnalysis, :func:`read_ledger`), each sample's energies
from :mod:`granchain.engines.lammps.ledger`; one-line errors for a missing, truncated or
foreign file."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ...effects import holds_contacts, physics_terms
from ...errors import GranchainError
from ...lammps import deck as deckmod
from ...scene import Scene
from .binary import read_binary_dump
from .ledger import (UM, _fill_ledger, _fill_mechanical, _fill_residual, _kinetic,
                     _new_energies, _potential, _zeros, geometry)

DUMP_READ = ("x", "vx")   # the dump columns read as MDAnalysis additional (float64) columns



def read_dump(path: Path, scene: Scene, pl: "deckmod.DeckPlan", *, velocities: str = "float64",
              readers: int = 1):
    """Read a deck's output into per-chain arrays: the dump with MDAnalysis, and the
    per-chain ledger (``ledger.txt`` next to the dump, if the deck writes one).

    Returns a dict: ``step`` (S,), ``v`` (S, B, n) m/s, ``energy`` (S, B, 7) J and
    ``last_overlap`` (S, B) m, the Hertz overlap of each chain's last contact.
    ``readers`` > 1 splits the dump's frames between that many processes (each opens the
    dump with MDAnalysis, scans it for the frame offsets and parses its share): it only
    pays with idle cores (on the shared 2-core test machine, 2 readers read a 200-chain
    dump 1.8x faster at load ~1, and no faster at load ~4).
    Raises GranchainError (one line, naming the file) if the dump or the ledger is
    missing, truncated or does not match the plan.
    """
    if velocities not in ("float64", "float32"):
        raise GranchainError(f"read_dump: velocities must be 'float64' or 'float32' (got {velocities!r})")
    path = Path(path)
    B, n = pl.n_chains, pl.n
    if not path.is_file() or path.stat().st_size == 0:
        raise GranchainError(f"LAMMPS dump {path} is missing or empty: the run wrote no "
                             "trajectory (see log.lammps next to it)")
    missing = [c for c in DUMP_READ if c not in pl.dump_columns]
    if missing:
        raise GranchainError(f"LAMMPS dump {path}: the deck does not dump {', '.join(missing)}")
    job = {"path": str(path), "B": B, "n": n, "velocities": velocities,
           "geometry": geometry(scene, pl),
           "overlaps": holds_contacts(physics_terms(scene))}  # every contact's (stop rule)
    readers = max(1, int(readers))
    if readers == 1:
        parts = [_read_part(job, 0, 1)]
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor
        # fork: the workers run only numpy and MDAnalysis; spawn would re-import the
        # caller's __main__ (and fail in scripts without a __main__ guard)
        with ProcessPoolExecutor(readers, mp_context=mp.get_context("fork")) as ex:
            parts = list(ex.map(_read_part, [job] * readers, range(readers), [readers] * readers))
    step = np.concatenate([p[1] for p in parts])
    _check_steps(f"LAMMPS dump {path}", pl, step, path.parent)
    V = _chain_major(np.concatenate([p[2] for p in parts]).reshape(len(step), B * n), B, n)
    EH = np.concatenate([p[3] for p in parts])
    last_overlap = np.concatenate([p[4] for p in parts])
    KE = np.concatenate([p[5] for p in parts])
    WL = None if parts[0][6] is None else np.concatenate([p[6] for p in parts])
    ledger = read_ledger(path.with_name(deckmod.LEDGER_NAME), pl, step) if pl.ledger_columns else None
    E = _new_energies(*EH.shape)
    _fill_mechanical(E, KE, EH, WL)
    walled = deckmod.WALL_FORCE_COLUMN in pl.ledger_columns
    # the wall force from x and v (geometry.wall_law): the last sphere's x (um) and vx
    sampled = (np.concatenate([p[8][0] for p in parts]), np.concatenate([p[8][1] for p in parts]),
               job["geometry"]) if walled and parts[0][8] is not None else None
    WF = np.empty(EH.shape) if walled else None
    XL = np.concatenate([p[7] for p in parts]) if walled else None
    if ledger is not None:
        _fill_ledger(E, WF, pl, ledger, sampled)
    _fill_residual(scene, E)
    OV = np.concatenate([p[9] for p in parts]) if job["overlaps"] else None
    return {"step": step, "v": V, "energy": E, "last_overlap": last_overlap, "wall_force": WF,
            "last_disp": XL, "overlaps": OV}


def read_binary(path: Path, scene: Scene, pl: "deckmod.DeckPlan"):
    """Read a deck's binary output (``output="binary"``) into per-chain arrays: the
    trajectory ``traj.bin`` and the per-chain ledger ``ledger.bin`` next to it (if the
    deck writes one), both LAMMPS binary ``dump custom`` files sorted by id.

    Returns the dict of :func:`read_dump`, from the same doubles: ``step`` (S,), ``v``
    (S, B, n) m/s, ``energy`` (S, B, 7) J and ``last_overlap`` (S, B) m. Raises
    GranchainError (one line, naming the file) if a file is missing, truncated or does
    not match the plan.
    """
    path = Path(path)
    B, n = pl.n_chains, pl.n
    what = f"LAMMPS binary dump {path}"
    missing = [c for c in DUMP_READ if c not in pl.dump_columns]
    if pl.output != "binary" or missing:
        raise GranchainError(f"{what}: the deck does not write the binary trajectory "
                             f"(output {pl.output!r}, columns {' '.join(pl.dump_columns)})")
    geo = geometry(scene, pl)
    walled = deckmod.WALL_FORCE_COLUMN in pl.ledger_columns
    sampled = walled and geo.wall_law is not None     # the wall force from x and v
    every = holds_contacts(physics_terms(scene))     # every contact's overlap (stop rule)
    out = {}

    def consume(lo, block, frames):
        """A block of samples: each chain's velocities into its contiguous record, the
        Hertz energy, last overlap, kinetic energy and load work straight into the result
        arrays (sized for ``frames`` samples at the first block)."""
        if not out:
            out.update(V=_zeros((B, frames, n)), E=_new_energies(frames, B),
                       OL=np.empty((frames, B)), WF=np.empty((frames, B)) if walled else None,
                       XL=np.empty((frames, B)) if walled else None,
                       WX=np.empty((frames, B)) if sampled else None,
                       WV=np.empty((frames, B)) if sampled else None,
                       OV=np.empty((frames, B, n - 1)) if every else None)
        hi = lo + len(block["x"])
        x = block["x"].reshape(-1, B, n)
        EH, ov, WL = _potential(x, geo)
        out["OL"][lo:hi] = ov[..., -1]
        if every:
            out["OV"][lo:hi] = ov
        if walled:
            out["XL"][lo:hi] = (x[..., -1] - geo.x_last0) * UM
        v = block["vx"].reshape(-1, B, n)
        if sampled:
            out["WX"][lo:hi] = x[..., -1]
            out["WV"][lo:hi] = v[..., -1]
        _fill_mechanical(out["E"][lo:hi], _kinetic(v, geo), EH, WL)
        out["V"][:, lo:hi] = v.transpose(1, 0, 2)

    step, _ = read_binary_dump(path, pl.dump_columns, B * n, pl.nsamples, what, consume=consume)
    _check_steps(what, pl, step, path.parent)
    S = len(step)
    V = out["V"][:, :S].transpose(1, 0, 2)           # (S, B, n) view, each chain contiguous
    E, OL = out["E"][:S], out["OL"][:S]
    WF = out["WF"][:S] if walled else None
    XL = out["XL"][:S] if walled else None
    if pl.ledger_columns:
        lpath = path.with_name(deckmod.LEDGER_BINARY_NAME)
        lwhat = f"LAMMPS ledger {lpath}"
        lcols = deckmod.ledger_binary_columns(pl)

        def ledger(lo, block, frames):
            hi = lo + len(block[lcols[0]])
            if hi > S:
                raise GranchainError(f"{lwhat} does not match the trajectory: more than {S} "
                                     f"samples; {path.name} has {S}")
            _fill_ledger(E[lo:hi], None if WF is None else WF[lo:hi], pl,
                         np.stack([block[c] for c in lcols], axis=2),
                         (out["WX"][lo:hi], out["WV"][lo:hi], geo) if sampled else None)

        lstep, _ = read_binary_dump(lpath, lcols, B, pl.nsamples, lwhat, consume=ledger)
        if not np.array_equal(lstep, step):
            raise GranchainError(f"{lwhat} does not match the trajectory: {len(lstep)} samples; "
                                 f"{path.name} has {S}")
    _fill_residual(scene, E)
    return {"step": step, "v": V, "energy": E, "last_overlap": OL, "wall_force": WF,
            "last_disp": XL, "overlaps": out["OV"][:S] if every else None}


def _chain_major(a, B: int, n: int):
    """(S, B*n) sample-major values -> the same values as an (S, B, n) view of a
    chain-major (B, S, n) array, so that each chain's record is contiguous. Transposed in
    blocks of samples (cache-friendly)."""
    S = a.shape[0]
    out = np.empty((B, S, n))
    for lo in range(0, S, 64):
        out[:, lo:lo + 64] = a[lo:lo + 64].reshape(-1, B, n).transpose(1, 0, 2)
    return out.transpose(1, 0, 2)


def _check_steps(what: str, pl: "deckmod.DeckPlan", step, rundir: Path) -> None:
    """The samples of a run: 0, every, 2 every, ... up to the plan's, or fewer if the run
    was halted by its stop rule (log.lammps in ``rundir``)."""
    S = len(step)
    if S > pl.nsamples or (not pl.auto and S != pl.nsamples) or (
            pl.auto and S < pl.nsamples and not _halted(rundir / "log.lammps")):
        raise GranchainError(f"{what} is truncated: {S} of {pl.nsamples} "
                             "samples and the run was not halted by its stop rule")
    expected = np.arange(S, dtype=np.int64) * pl.every
    if S == 0 or not np.array_equal(step, expected):
        raise GranchainError(f"{what}: its steps are not 0, {pl.every}, "
                             f"{2 * pl.every}, ... (was it written by this deck?)")


def read_ledger(path: Path, pl: "deckmod.DeckPlan", step) -> np.ndarray:
    """The per-chain ledger ``ledger.txt`` (``fix ave/time ... mode vector``) at the dump's
    samples ``step``: (S, B, k) in LAMMPS energy units (1e-15 J), columns
    ``pl.ledger_columns``. One-line GranchainError if missing, truncated or not this deck's.
    """
    path = Path(path)
    B, k = pl.n_chains, len(pl.ledger_columns)
    try:
        text = path.read_text()
    except OSError:
        text = ""
    if not text:
        raise GranchainError(f"LAMMPS ledger {path} is missing or empty: the run wrote no "
                             "per-chain energies (see log.lammps next to it)")
    # header: three '#' lines; then per sample 'step B' and B rows 'row value*k'
    body = 0
    for _ in range(3):
        if text.startswith("#", body):
            body = text.find("\n", body) + 1 or len(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")        # numpy warns (not raises) at unparsable text
        try:
            vals = np.fromstring(text[body:], sep=" ")
        except (ValueError, DeprecationWarning):
            vals = None
    per = 2 + B * (1 + k)
    S = len(step)
    if vals is None or vals.size % per or not text.endswith("\n"):
        raise GranchainError(f"LAMMPS ledger {path} is truncated or unreadable")
    a = vals.reshape(-1, per)
    rows = a[:, 2:].reshape(-1, B, 1 + k)
    if (len(a) != S or not np.array_equal(a[:, 0], step) or np.any(a[:, 1] != B)
            or np.any(rows[:, :, 0] != np.arange(1, B + 1))):
        raise GranchainError(f"LAMMPS ledger {path} does not match the dump: {len(a)} samples "
                             f"of {B} rows; the dump has {S} samples of {B} chains")
    return rows[:, :, 1:]


def _halted(log: Path) -> bool:
    """Did the run that wrote ``log`` (its log.lammps) stop by its fix halt?"""
    try:
        return "Fix halt condition" in Path(log).read_text(errors="replace")
    except OSError:
        return False


def _read_part(job: dict, part: int, nparts: int):
    """Frames [part*S/nparts, (part+1)*S/nparts) of a dump: (S, step, V, E_potential,
    overlap of the last contact in m, kinetic energy, work of the dead load (None
    without), displacement of the last sphere in m (NaN without an end wall), the last
    sphere's x (um) and vx at the samples (None unless ``geometry.wall_law``: the wall
    force is the law at those), every contact's
    overlap in m (None unless ``job["overlaps"]``)), per chain."""
    import MDAnalysis as mda

    path, B, n, geo = job["path"], job["B"], job["n"], job["geometry"]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")       # no masses/types in a dump: MDAnalysis warns
            u = mda.Universe(path, topology_format="LAMMPSDUMP", format="LAMMPSDUMP",
                             additional_columns=list(DUMP_READ))
            traj = u.trajectory
            S = traj.n_frames
            if u.atoms.n_atoms != B * n:
                raise GranchainError(f"LAMMPS dump {path} holds {u.atoms.n_atoms} atoms; the "
                                     f"deck has {B} chain(s) x {n} = {B * n}")
            lo, hi = part * S // nparts, (part + 1) * S // nparts
            step = np.empty(hi - lo, dtype=np.int64)
            V = np.empty((hi - lo, B, n))
            EH = np.empty((hi - lo, B))
            OL = np.empty((hi - lo, B))
            KE = np.empty((hi - lo, B))
            WL = np.zeros((hi - lo, B))
            XL = np.empty((hi - lo, B))
            WD = (np.empty((hi - lo, B)), np.empty((hi - lo, B))) \
                if geo.wall_law is not None else None
            OV = np.empty((hi - lo, B, n - 1)) if job["overlaps"] else None
            for s, ts in enumerate(traj[lo:hi]):
                data = ts.data
                step[s] = data["step"]
                v = data["vx"].reshape(B, n)
                if job["velocities"] == "float32":
                    v = v.astype(np.float32).astype(np.float64)
                V[s] = v
                KE[s] = _kinetic(v, geo)
                x = data["x"].reshape(B, n)
                EH[s], ov, wl = _potential(x, geo)
                OL[s] = ov[..., -1]
                if OV is not None:
                    OV[s] = ov
                XL[s] = (x[:, -1] - geo.x_last0) * UM
                if WD is not None:
                    WD[0][s], WD[1][s] = x[:, -1], v[:, -1]
                if wl is not None:
                    WL[s] = wl
    except GranchainError:
        raise
    except (ValueError, IndexError, EOFError, OSError, KeyError, TypeError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise GranchainError(f"LAMMPS dump {path} is truncated or unreadable: {msg}") from None
    return S, step, V, EH, OL, KE, WL if geo.load > 0 else None, XL, WD, OV
