"""The LAMMPS engine (granchain.engines.lammps): cross-validation against the reference
engine's velocity Verlet at the same dt, the per-chain energy ledger, MPI, errors.

Bounds asserted here are the measured agreement with headroom
(docs/explanation/lammps_engine.md): both engines apply the same laws with the same integrator, so they differ by rounding.
"""
from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

from granchain.cli import main as cli_main
from granchain.compare import compare
from granchain.effects import residual_work
from granchain.engines import lammps as lammps_engine
from granchain.engines.lammps import binary as lammps_binary
from granchain.engines import reference
from granchain.errors import GranchainError
from granchain.lammps import deck as lammps_deck
from granchain.observables import summarize
from granchain.simulate import member_gaps, members
from tests.conftest import packed

pytestmark = pytest.mark.lammps

ALL = "[hertz, groove_friction, air_drag, rotation, particle_friction, rolling_friction]"
ALL_BUT_ROLLING = "[hertz, groove_friction, air_drag, rotation, particle_friction]"
LIST_GAPS = [0.0, 20e-9, 5e-9, 0.0, 40e-9, 1e-9, 0.0, 3e-9, 0.0, 10e-9, 7e-9, 0.0, 2e-9, 0.0]

# measured (this LAMMPS, dt = 1 ns, t_end auto): v_max, v_g <= 1.3e-9 relative,
# peak times <= 3e-11 relative, energy terms <= 6e-10 E0, velocities <= 6e-11 m/s
V_BOUND, T_BOUND, E_BOUND, DV_BOUND = 1e-8, 1e-9, 5e-9, 1e-9

SCENES = {
    "hertz-packed": lambda: packed(),
    "list-gaps": lambda: packed(**{"gaps.distribution": "list", "gaps.values": str(LIST_GAPS)}),
    "all-effects": lambda: packed(effects=ALL, **{"rolling.k_roll": 1e3, "gaps.distribution": "uniform",
                                                   "gaps.mean": 20e-9, "ensemble.realisations": 2}),
}


def _members(scene):
    mem = members(scene)
    return member_gaps(scene, mem), np.array([m.v_striker for m in mem])


@pytest.mark.parametrize("name", list(SCENES))
def test_cross_validation_lammps_equals_reference_verlet(name, tmp_path):
    scene = SCENES[name]()
    cmp = compare(scene, workdir=tmp_path / "lmp")
    rows = cmp.rows
    assert cmp.ok, cmp.failures().to_string()
    assert "Fix halt condition" in (tmp_path / "lmp" / "log.lammps").read_text()  # t_end auto
    assert (rows.loc[rows.quantity == "samples", "diff"] == 0).all()
    n_v = rows.quantity.str.match(r"v_max\[\d+\]$").groupby(rows.member).sum()
    assert (n_v == scene.n).all()
    vq = rows[rows.quantity.str.startswith("v_max") | rows.quantity.str.startswith("v_g")]
    assert vq["diff"].max() < V_BOUND
    assert rows[rows.quantity.isin(["dt_peak", "dt_front"])]["diff"].max() < T_BOUND
    energy = rows[(rows.measure == "abs/E0") & rows.ok.notna()]
    assert len(energy) >= 7 * len(members(scene)) and energy["diff"].max() < E_BOUND
    residual = scene.has("particle_friction") or scene.has("rolling_friction")
    assert cmp.meta["balance"] == ("residual" if residual else "independent")
    bal = rows[rows.quantity == "balance_error"]
    if residual:
        assert bal.ok.isna().all() and bal.why.str.contains("not independent").all()
        assert (rows.quantity == "+".join(residual_work(scene.effects))).any()
    else:
        assert bal.ok.all() and bal["diff"].max() < 1e-9
    # and sample by sample
    gaps, vs = _members(cmp.scene)
    ref = list(reference.run(cmp.scene, gaps, vs, method="verlet", trace=True))
    lmp = list(lammps_engine.run(cmp.scene, gaps, vs))
    assert len(ref) == len(lmp) == len(members(scene)) >= 1
    for r, lt in zip(ref, lmp):
        assert lt.info.method == "lammps-verlet" and lt.status == r.status == "passed"
        np.testing.assert_allclose(lt.t, r.t, rtol=1e-12, atol=0)
        assert np.abs(lt.v - r.v).max() < DV_BOUND
        e0 = r.energy[0, :3].sum()
        cols = [0, 1, 2, 3, 4] if residual else list(range(7))
        assert np.abs(lt.energy[:, cols] - r.energy[:, cols]).max() < E_BOUND * e0


def test_run_json_has_the_reference_keys(repo, capsys):
    scene = str(repo / "granchain/scenes/packed-440c.yaml")
    docs = {}
    for engine in ("reference", "lammps"):
        assert cli_main(["run", scene, "--engine", engine, "--json",
                         "--set", "integrator.method=verlet"]) == 0
        docs[engine] = json.loads(capsys.readouterr().out)
    ref, lmp = docs["reference"], docs["lammps"]
    assert set(lmp) == set(ref)
    assert set(lmp["energy"]) == set(ref["energy"])
    assert lmp["engine"] == "lammps" and lmp["method"] == "lammps-verlet"
    assert lmp["status"] == ref["status"] == "passed" and lmp["samples"] == ref["samples"]
    assert lmp["v_g"] == pytest.approx(ref["v_g"], rel=V_BOUND)


def test_per_chain_ledger_matches_lammps_global_ledger(tmp_path):
    """The per-chain ledger (LAMMPS chunk sums in ledger.txt; kinetic energy from the
    dumped vx) adds up to energy.txt (LAMMPS' global computes, all chains summed)."""
    scene = packed(effects=ALL_BUT_ROLLING, t_end=3e-6,
                   **{"gaps.distribution": "uniform", "gaps.mean": 20e-9, "ensemble.realisations": 3})
    gaps, vs = _members(scene)
    trajs = list(lammps_engine.run(scene, gaps, vs, workdir=tmp_path))
    total = sum(t.energy for t in trajs)
    en = np.loadtxt(tmp_path / lammps_deck.ENERGY_NAME)    # step ke erot groove drag (1e-15 J)
    assert en[:, 0].tolist() == [round(t / scene.dt) for t in trajs[0].t]
    for col, k in ((1, 0), (2, 1), (3, 3), (4, 4)):
        np.testing.assert_allclose(total[:, k], en[:, col] * 1e-15, rtol=1e-12,
                                   atol=1e-12 * abs(en[:, col]).max() * 1e-15)
    assert np.all(total[1:, 3] < 0)                    # the groove takes energy out
    for t in trajs:
        e = t.energy
        assert e[0, 0] == pytest.approx(0.5 * scene.mass * 0.1**2, rel=1e-15)
        assert np.all(e[:, 6] == 0)
        # contact friction: the balance residual, so the ledger balances exactly
        mech = e[:, 0] + e[:, 1] + e[:, 2]
        np.testing.assert_allclose(e[:, 5], mech - mech[0] - e[:, 3] - e[:, 4], rtol=0,
                                   atol=1e-15 * mech[0])
        assert summarize(t).energy.balance_error < 1e-12
        assert t.info.balance == "residual" and t.info.deck == str(tmp_path / "deck.lmp")


def test_float64_columns_are_the_dumped_values(tmp_path):
    """Observables use the dump's %.17g text at float64; velocities="float32" rounds them
    as MDAnalysis' own float32 parsing would (relative rounding <= 2^-24)."""
    scene = packed(t_end=2e-6)
    gaps, vs = _members(scene)
    pl = lammps_deck.plan(scene, gaps=gaps, v_striker=vs)
    next(lammps_engine.run(scene, gaps, vs, workdir=tmp_path, output="dump"))
    lines = (tmp_path / lammps_deck.DUMP_NAME).read_text().splitlines()
    cols = lines[8].split()[2:]
    last = np.array([[float(x) for x in ln.split()] for ln in lines[-scene.n:]])
    d64 = lammps_engine.read_dump(tmp_path / lammps_deck.DUMP_NAME, scene, pl)
    d32 = lammps_engine.read_dump(tmp_path / lammps_deck.DUMP_NAME, scene, pl, velocities="float32")
    vx = last[:, cols.index("vx")]
    assert d64["v"][-1, 0].tolist() == vx.tolist()                 # bit for bit
    assert d32["v"][-1, 0].tolist() == vx.astype(np.float32).astype(float).tolist()
    assert np.any(d32["v"][-1, 0] != vx)
    np.testing.assert_allclose(d32["v"], d64["v"], rtol=2.0**-24, atol=0)
    # frames split in two
    two = lammps_engine.read_dump(tmp_path / lammps_deck.DUMP_NAME, scene, pl, readers=2)
    for k in ("step", "v", "energy"):
        assert np.array_equal(two[k], d64[k])


def test_two_mpi_ranks_give_the_same_observables(tmp_path):
    """50 chains (two striker speeds x 25 gap realisations) on 1 and on 2 ranks."""
    scene = packed(effects=ALL_BUT_ROLLING, probes="[2, 6]",
                   **{"gaps.distribution": "uniform", "gaps.mean": 20e-9, "ensemble.realisations": 25,
                      "striker.velocity": "[0.07, 0.1]", "output.sample_dt": 36e-9})
    gaps, vs = _members(scene)
    assert len(vs) == 50
    one = list(lammps_engine.run(scene, gaps, vs, nprocs=1))
    two = list(lammps_engine.run(scene, gaps, vs, nprocs=2, workdir=tmp_path))
    assert "1 by 2 by 1 MPI processor grid" in (tmp_path / "log.lammps").read_text()
    assert two[0].info.nprocs == 2
    for a, b in zip(one, two):
        sa, sb = summarize(a, scene.probes), summarize(b, scene.probes)
        assert sa.wave_arrived and sa.status == sb.status == "passed"
        assert sa.samples == sb.samples
        np.testing.assert_allclose(sb.v_max, sa.v_max, rtol=1e-12, atol=0)
        for k in ("v_max_1", "v_max_2", "dt_peak", "v_g", "v_g_front"):
            assert getattr(sb, k) == pytest.approx(getattr(sa, k), rel=1e-12, abs=0)
        np.testing.assert_allclose(b.energy, a.energy, rtol=1e-12, atol=1e-12 * a.energy[0, 0])


@pytest.mark.parametrize("nprocs", [1, 2])
def test_binary_and_text_dump_paths_give_identical_trajectories(nprocs, tmp_path):
    """output="binary" (LAMMPS binary dumps read with numpy, the default) and "dump" (the
    text dump read with MDAnalysis): the same doubles, so the same Trajectory objects."""
    scene = packed(effects=ALL, **{"rolling.k_roll": 1e3, "gaps.distribution": "uniform",
                                   "gaps.mean": 20e-9, "ensemble.realisations": 3,
                                   "striker.velocity": "[0.07, 0.1]", "output.sample_dt": 36e-9,
                                   "integrator.method": "verlet"})
    gaps, vs = _members(scene)
    runs = {out: list(lammps_engine.run(scene, gaps, vs, nprocs=nprocs, output=out,
                                        workdir=tmp_path / out))
            for out in ("binary", "dump")}
    assert (tmp_path / "binary" / lammps_deck.BINARY_NAME).is_file()
    assert not (tmp_path / "binary" / lammps_deck.DUMP_NAME).exists()
    assert (tmp_path / "binary" / lammps_deck.LEDGER_BINARY_NAME).is_file()
    assert not (tmp_path / "binary" / lammps_deck.LEDGER_NAME).exists()
    assert len(runs["binary"]) == len(runs["dump"]) == 6
    for a, b in zip(runs["binary"], runs["dump"]):
        assert a.info.output == "binary" and b.info.output == "dump"
        assert a.info.nprocs == nprocs and a.status == b.status == "passed"
        assert a.t.tolist() == b.t.tolist() and a.steps == b.steps
        assert a.v.tobytes() == b.v.tobytes()                     # bit for bit
        assert a.last_overlap == b.last_overlap
        e0 = b.energy[0, :3].sum()
        assert np.abs(a.energy - b.energy).max() <= 1e-12 * e0
        assert np.any(b.energy[-1, [1, 3, 4]] != 0)               # the ledger columns are there


def test_binary_reader_reads_what_lammps_holds(tmp_path, monkeypatch):
    """traj.bin holds x and vx of every atom, sorted by id; ledger.bin the per-chain sums
    (the values of ledger.txt of the same deck, bit for bit)."""
    scene = packed(effects="[hertz, groove_friction, air_drag]", t_end=2e-6,
                   **{"gaps.distribution": "uniform", "gaps.mean": 20e-9, "ensemble.realisations": 2})
    gaps, vs = _members(scene)
    pl = lammps_deck.plan(scene, gaps=gaps, v_striker=vs, output="binary")
    next(lammps_engine.run(scene, gaps, vs, workdir=tmp_path / "b"))
    next(lammps_engine.run(scene, gaps, vs, workdir=tmp_path / "d", output="dump"))
    step, cols = lammps_engine.read_binary_dump(tmp_path / "b" / lammps_deck.BINARY_NAME,
                                                ("x", "vx"), 2 * scene.n, pl.nsamples, "traj")
    assert step.tolist() == list(range(0, pl.nsteps + 1, pl.every))
    assert cols["x"][0].tolist() == np.concatenate(
        [lammps_deck.chain_positions(scene, g) for g in gaps]).tolist()
    assert cols["vx"][0].tolist() == [0.1 if i % scene.n == 0 else 0.0 for i in range(2 * scene.n)]
    pld = lammps_deck.plan(scene, gaps=gaps, v_striker=vs)
    ledger_txt = lammps_engine.read_ledger(tmp_path / "d" / lammps_deck.LEDGER_NAME, pld, step)
    lstep, lcols = lammps_engine.read_binary_dump(tmp_path / "b" / lammps_deck.LEDGER_BINARY_NAME,
                                                  lammps_deck.ledger_binary_columns(pl), 2,
                                                  pl.nsamples, "ledger")
    assert lstep.tolist() == step.tolist()
    assert np.stack([lcols[c] for c in lammps_deck.ledger_binary_columns(pl)],
                    axis=2).tobytes() == ledger_txt.tobytes()
    # frames read one by one (the reader's path for files whose frames differ in layout)
    # and in blocks of strided views (the regular layout LAMMPS writes): the same arrays
    whole = lammps_engine.read_binary(tmp_path / "b" / lammps_deck.BINARY_NAME, scene, pl)
    monkeypatch.setattr(lammps_binary, "_frame_layout", lambda *a: None)
    frames = lammps_engine.read_binary(tmp_path / "b" / lammps_deck.BINARY_NAME, scene, pl)
    for k in ("step", "v", "energy", "last_overlap"):
        assert frames[k].tobytes() == whole[k].tobytes()
    step2, cols2 = lammps_engine.read_binary_dump(tmp_path / "b" / lammps_deck.BINARY_NAME,
                                                  ("x", "vx"), 2 * scene.n, pl.nsamples, "traj")
    assert step2.tolist() == step.tolist() and cols2["x"].tobytes() == cols["x"].tobytes()


def test_missing_and_truncated_binary_output(tmp_path):
    scene = packed(t_end=2e-6, effects="[hertz, groove_friction, air_drag]")
    gaps, vs = _members(scene)
    pl = lammps_deck.plan(scene, gaps=gaps, v_striker=vs, output="binary")
    traj, ledger = tmp_path / lammps_deck.BINARY_NAME, tmp_path / lammps_deck.LEDGER_BINARY_NAME
    with pytest.raises(GranchainError, match=f"LAMMPS binary dump {traj} is missing") as exc:
        lammps_engine.read_binary(traj, scene, pl)
    _one_line(exc.value)
    next(lammps_engine.run(scene, gaps, vs, workdir=tmp_path))
    assert lammps_engine.read_binary(traj, scene, pl)["energy"][-1, 0, 3] < 0
    data = traj.read_bytes()
    frame = len(data) // pl.nsamples
    traj.write_bytes(data[:-frame])                                # last frame missing
    with pytest.raises(GranchainError, match=r"is truncated: \d+ of \d+ samples") as exc:
        lammps_engine.read_binary(traj, scene, pl)
    _one_line(exc.value)
    traj.write_bytes(data[:-20])                                   # cut inside a frame
    with pytest.raises(GranchainError, match=f"LAMMPS binary dump {traj} is truncated or unreadable") as exc:
        lammps_engine.read_binary(traj, scene, pl)
    _one_line(exc.value)
    traj.write_bytes(data)
    ldata = ledger.read_bytes()
    ledger.write_bytes(ldata[:-len(ldata) // pl.nsamples])
    with pytest.raises(GranchainError, match=f"LAMMPS ledger {ledger} does not match the trajectory") as exc:
        lammps_engine.read_binary(traj, scene, pl)
    _one_line(exc.value)
    ledger.unlink()
    with pytest.raises(GranchainError, match=f"LAMMPS ledger {ledger} is missing") as exc:
        lammps_engine.read_binary(traj, scene, pl)
    _one_line(exc.value)
    with pytest.raises(GranchainError, match="does not match the deck") as exc:
        lammps_engine.read_binary_dump(traj, ("x", "vx"), 2 * scene.n, pl.nsamples, "traj")
    _one_line(exc.value)


# --------------------------------------------------------------------------------------
# errors: one line, naming the deck or dump and the cause
def _one_line(exc):
    assert "\n" not in str(exc)
    return str(exc)


def test_bad_plugin_parameter_names_the_deck(tmp_path):
    sc = packed(t_end=1e-6, effects="[hertz, groove_friction]")
    bad = dataclasses.replace(sc.setting("groove_friction"), mu=-0.1)    # past the scene check
    scene = dataclasses.replace(sc, settings=tuple((k, bad if k == "groove_friction" else v)
                                                   for k, v in sc.settings))
    with pytest.raises(GranchainError) as exc:
        list(lammps_engine.run(scene, np.zeros((1, 14)), [0.1], workdir=tmp_path))
    msg = _one_line(exc.value)
    assert f"LAMMPS deck {tmp_path / 'deck.lmp'}:" in msg
    assert "Fix groove/drag: value of 'mu' must be >= 0 (got '-0.1')" in msg


def test_failing_run_lost_atoms_names_the_deck_and_keeps_it():
    # a step far above the scene check (20 steps per contact) blows the chain apart
    scene = dataclasses.replace(packed(t_end=200e-6, **{"output.sample_dt": 1e-7}), dt=1e-6)
    with pytest.raises(GranchainError) as exc:
        list(lammps_engine.run(scene, np.zeros((1, 14)), [1.0]))
    msg = _one_line(exc.value)
    m = re.match(r"LAMMPS deck (\S+deck\.lmp): ERROR: Lost atoms", msg)
    assert m, msg
    from pathlib import Path
    deck = Path(m.group(1))
    assert deck.is_file()                       # a failed run keeps its directory
    import shutil
    shutil.rmtree(deck.parent)


def test_missing_and_truncated_dump(tmp_path):
    scene = packed(t_end=2e-6)
    gaps, vs = _members(scene)
    pl = lammps_deck.plan(scene, gaps=gaps, v_striker=vs)
    dump = tmp_path / lammps_deck.DUMP_NAME
    with pytest.raises(GranchainError, match=f"LAMMPS dump {dump} is missing") as exc:
        lammps_engine.read_dump(dump, scene, pl)
    _one_line(exc.value)
    next(lammps_engine.run(scene, gaps, vs, workdir=tmp_path, output="dump"))
    text = dump.read_text()
    lines = text.splitlines(keepends=True)
    frame = 9 + scene.n
    dump.write_text("".join(lines[:-frame]))                    # last frame missing
    with pytest.raises(GranchainError, match=r"is truncated: \d+ of \d+ samples") as exc:
        lammps_engine.read_dump(dump, scene, pl)
    _one_line(exc.value)
    dump.write_text("".join(lines[:-3]))                        # cut inside a frame
    with pytest.raises(GranchainError, match=f"LAMMPS dump {dump} is truncated") as exc:
        lammps_engine.read_dump(dump, scene, pl)
    _one_line(exc.value)


def test_missing_and_truncated_ledger(tmp_path):
    scene = packed(t_end=2e-6, effects="[hertz, groove_friction, air_drag]")
    gaps, vs = _members(scene)
    pl = lammps_deck.plan(scene, gaps=gaps, v_striker=vs)
    assert pl.ledger_columns == ("work_groove_friction", "work_air_drag")
    next(lammps_engine.run(scene, gaps, vs, workdir=tmp_path, output="dump"))
    dump, ledger = tmp_path / lammps_deck.DUMP_NAME, tmp_path / lammps_deck.LEDGER_NAME
    assert lammps_engine.read_dump(dump, scene, pl)["energy"][-1, 0, 3] < 0
    text = ledger.read_text()
    ledger.write_text(text[:-40])                               # cut inside a row
    with pytest.raises(GranchainError, match=f"LAMMPS ledger {ledger} is truncated") as exc:
        lammps_engine.read_dump(dump, scene, pl)
    _one_line(exc.value)
    lines = text.splitlines(keepends=True)
    ledger.write_text("".join(lines[:-2]))                      # last sample missing
    with pytest.raises(GranchainError, match=f"LAMMPS ledger {ledger} does not match the dump") as exc:
        lammps_engine.read_dump(dump, scene, pl)
    _one_line(exc.value)
    ledger.unlink()
    with pytest.raises(GranchainError, match=f"LAMMPS ledger {ledger} is missing") as exc:
        lammps_engine.read_dump(dump, scene, pl)
    _one_line(exc.value)


def test_cli_prints_lammps_errors_in_one_line(repo, tmp_path, monkeypatch, capsys):
    scene = str(repo / "granchain/scenes/packed-440c.yaml")
    real = lammps_deck.write_deck

    def broken(*a, **k):                                        # a deck LAMMPS rejects
        path = real(*a, **k)
        path.write_text(path.read_text().replace("run             ", "fix bad all nonsense\nrun "))
        return path
    monkeypatch.setattr(lammps_deck, "write_deck", broken)
    assert cli_main(["run", scene, "--engine", "lammps", "--workdir", str(tmp_path / "w"),
                     "--set", "t_end=1e-6"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"granchain: error: LAMMPS deck {tmp_path / 'w' / 'deck.lmp'}: ERROR:")


def test_workdir_and_options(repo, tmp_path, capsys):
    scene = packed(t_end=1e-6)
    (tmp_path / "junk").write_text("x")
    with pytest.raises(GranchainError, match="not empty") as exc:
        list(lammps_engine.run(scene, np.zeros((1, 14)), [0.1], workdir=tmp_path))
    _one_line(exc.value)
    t = next(lammps_engine.run(scene, np.zeros((1, 14)), [0.1], workdir=tmp_path, force=True))
    assert t.status == "done" and (tmp_path / "junk").exists() and (tmp_path / "traj.bin").exists()
    assert t.info.output == "binary" and not (tmp_path / "traj.dump").exists()
    with pytest.raises(GranchainError, match="output must be one of") as exc:
        list(lammps_engine.run(scene, np.zeros((1, 14)), [0.1], output="none"))
    _one_line(exc.value)
    t = next(lammps_engine.run(scene, np.zeros((1, 14)), [0.1]))     # temporary dir: removed
    assert t.info.deck is None
    y = str(repo / "granchain/scenes/packed-440c.yaml")
    assert cli_main(["run", y, "--np", "2"]) == 2
    assert "--engine lammps" in capsys.readouterr().err


def test_cli_lammps_output_selects_the_path(repo, tmp_path, capsys):
    """--lammps-output dump keeps the text dump in --workdir; the default reads the binary
    dumps; the results are the same."""
    y = str(repo / "granchain/scenes/packed-440c.yaml")
    docs = {}
    for out, name in (("dump", lammps_deck.DUMP_NAME), (None, lammps_deck.BINARY_NAME)):
        wd = tmp_path / str(out)
        extra = ["--lammps-output", out] if out else []
        assert cli_main(["run", y, "--engine", "lammps", "--json", "--set", "t_end=3e-6",
                         "--workdir", str(wd), *extra]) == 0
        docs[out] = json.loads(capsys.readouterr().out)
        assert (wd / name).is_file() and len(list(wd.glob("traj.*"))) == 1
    assert docs["dump"]["v_max"] == docs[None]["v_max"]
    assert docs["dump"]["energy"] == docs[None]["energy"]
    assert cli_main(["run", y, "--lammps-output", "dump"]) == 2
    assert "--engine lammps" in capsys.readouterr().err


def test_human_summary_says_the_balance_is_a_residual(repo, capsys):
    y = str(repo / "granchain/scenes/packed-440c.yaml")
    assert cli_main(["run", y, "--engine", "lammps"]) == 0
    assert "balance residual, not an independent check" in capsys.readouterr().out
    assert cli_main(["run", y, "--engine", "lammps", "--set", "effects=[hertz, air_drag]",
                     "--set", "groove=null", "--set", "contact=null"]) == 0
    assert "residual" not in capsys.readouterr().out


def test_lammps_check_sizes_its_step_by_steps_per_contact():
    """lammps_check with steps_per_contact N: each scene (own and field chains, one
    striker speed each) steps at t_c(v_s) / N on its sample grid, so the slowest striker
    takes the largest step; the reference side runs the scene's dt (compare). dt and
    steps_per_contact together, or N below the accuracy study's 20, are one-line errors."""
    import copy
    from pathlib import Path

    from snakemake.common.configfile import load_configfile

    from granchain.costmodel import fixed_step
    from granchain.workflow.config import ConfigError, select_preset, validate_config
    from granchain.workflow.studies import check_chain_scenes, study_scenes

    raw = load_configfile(str(Path(__file__).resolve().parents[1] / "config/config.yaml"))
    raw["preset"] = "default"

    def preset(**lc):
        cfg = copy.deepcopy(raw)
        spec = cfg["presets"]["default"]["studies"]["lammps_check"]
        spec.pop("steps_per_contact", None)
        spec.update(lc)
        return select_preset(validate_config(cfg))[1]

    p = preset(steps_per_contact=320)
    scenes = study_scenes(p, "lammps_check") + check_chain_scenes(p)
    assert scenes
    by_speed = {}
    for ss in scenes:
        sc = ss.scene
        (v,) = sc.striker_velocities
        assert sc.dt == fixed_step(sc, 320) and sc.dt > 1e-9
        assert sc.contact_time(v) / sc.dt >= 320
        if not ss.chain:
            by_speed.setdefault(float(v), set()).add(sc.dt)
    speeds = sorted(by_speed)
    assert all(len(by_speed[v]) == 1 for v in speeds)
    assert [by_speed[v].pop() for v in speeds] == sorted(
        (fixed_step(ss.scene, 320) for ss in scenes if not ss.chain
         and ss.gap_mean_nm == 0), reverse=True)
    plain = preset()                                 # no key: the base dt
    assert {ss.scene.dt for ss in study_scenes(plain, "lammps_check")} == {1e-9}
    with pytest.raises(ConfigError) as exc:
        study_scenes(preset(steps_per_contact=320, dt=1e-9), "lammps_check")
    assert "\n" not in str(exc.value) and "steps_per_contact" in str(exc.value)
    with pytest.raises(ConfigError) as exc:
        preset(steps_per_contact=10)
    msg = str(exc.value)
    assert "\n" not in msg and "lammps_check.steps_per_contact" in msg and "20" in msg
