"""The LAMMPS deck generator ``granchain.lammps.deck`` and the decks it writes.

Every run uses the plain wheel, ``lmp -in deck.lmp`` in the deck directory (through
``granchain.lammps.runner.run_lammps``). Dumps are read with numpy.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from granchain.cli import main as cli_main
from granchain.errors import GranchainError
from granchain.lammps import run_lammps
from granchain.lammps.deck import DATA_NAME, chain_positions, to_micro, write_deck
from tests.conftest import packed

pytestmark = pytest.mark.lammps

T_SHORT = 2e-6
ALL_BUT_ROLLING = "[hertz, groove_friction, air_drag, rotation, particle_friction]"
LIST_GAPS = [0.0, 20e-9, 5e-9, 0.0, 40e-9, 1e-9, 0.0, 3e-9, 0.0, 10e-9, 7e-9, 0.0, 2e-9, 0.0]


def hertz_scene(**over):
    return packed(t_end=T_SHORT, **over)


def list_scene():
    return packed(t_end=T_SHORT, **{"gaps.distribution": "list", "gaps.values": str(LIST_GAPS)})


def effects_scene(**over):
    return packed(t_end=T_SHORT, effects=ALL_BUT_ROLLING, **over)


def read_dump(path: Path) -> dict[int, dict[str, np.ndarray]]:
    """Text ``dump custom`` -> {step: {column: values}} (rows as written: sorted by id)."""
    out: dict[int, dict[str, np.ndarray]] = {}
    lines = path.read_text().splitlines()
    i = 0
    while i < len(lines):
        step = int(lines[i + 1])
        nat = int(lines[i + 3])
        cols = lines[i + 8].split()[2:]
        rows = np.array([[float(v) for v in ln.split()] for ln in lines[i + 9:i + 9 + nat]])
        out[step] = {c: rows[:, k] for k, c in enumerate(cols)}
        i += 9 + nat
    return out


def read_atoms(data: Path) -> np.ndarray:
    """Atoms section of chain.data: rows of id type diameter density x y z."""
    text = data.read_text()
    block = text.split("Atoms # sphere\n\n", 1)[1].split("\n\n", 1)[0]
    return np.array([[float(v) for v in ln.split()] for ln in block.splitlines()])


def run_deck(deck: Path):
    return run_lammps(deck, deck.parent, timeout=600)


# ---------------------------------------------------------------------------------------
def test_to_micro_is_the_decimal_shift():
    assert to_micro(150e-6, "length") == 150.0
    assert to_micro(1e-9, "time") == 0.001
    assert to_micro(200e9, "pressure") == 2e8
    assert to_micro(7800.0, "density") == 7.8
    assert to_micro(9.81, "acceleration") == 9.81e-6
    assert to_micro(1e7, "stiffness") == 1e10
    assert to_micro(2.0, "damping") == 2e9
    for g in (1.234567890123e-8, 3.3e-9, 0.0):
        assert to_micro(g, "length") == pytest.approx(g * 1e6, rel=2e-16, abs=0)


@pytest.mark.parametrize("make", [hertz_scene, list_scene, effects_scene])
def test_same_scene_same_bytes(make, tmp_path):
    scene = make()
    a = write_deck(scene, tmp_path / "a")
    b = write_deck(scene, tmp_path / "b")
    for name in ("deck.lmp", DATA_NAME):
        assert (a.parent / name).read_bytes() == (b.parent / name).read_bytes()
    text = a.read_text()
    assert str(tmp_path) not in text


def test_refuses_to_overwrite_unless_forced(tmp_path):
    scene = hertz_scene()
    write_deck(scene, tmp_path)
    with pytest.raises(GranchainError, match="exists.*--force") as exc:
        write_deck(scene, tmp_path)
    assert "\n" not in str(exc.value)
    assert write_deck(scene, tmp_path, force=True) == tmp_path / "deck.lmp"


def test_cli_deck(tmp_path, capsys, repo):
    out = tmp_path / "d"
    hertz = ["--set", "effects=[hertz]", "--set", "groove=null", "--set", "drag=null",
             "--set", "contact=null"]
    assert cli_main(["deck", str(repo / "granchain/scenes/packed-440c.yaml"), "-o", str(out),
                     *hertz]) == 0
    assert (out / "deck.lmp").is_file() and (out / DATA_NAME).is_file()
    assert cli_main(["deck", str(repo / "granchain/scenes/packed-440c.yaml"), "-o", str(out),
                     *hertz]) == 2
    assert "exists" in capsys.readouterr().err
    assert cli_main(["deck", str(repo / "granchain/scenes/packed-440c.yaml"), "-o", str(out),
                     *hertz, "--write", "binary", "--force"]) == 0
    assert "traj.bin x vx" in (out / "deck.lmp").read_text()


def test_cli_deck_writes_a_deck_per_sample_cadence(tmp_path, capsys, repo):
    """Two striker speeds at auto sampling are sampled on two grids: granchain deck writes
    the two decks the engine runs, each sampling its chains on its own grid (the steps of
    ``runplan.step_grid`` of its speed's interval) and holding only its speed's chains."""
    from granchain.runplan import plan_run, step_grid
    from granchain.scene import load_scene
    path = repo / "granchain/scenes/packed-440c.yaml"
    sets = ["striker.velocity=[0.02, 0.1]", "effects=[hertz]", "groove=null", "drag=null",
            "contact=null"]
    out = tmp_path / "d"
    assert cli_main(["deck", str(path), "-o", str(out),
                     *[a for kv in sets for a in ("--set", kv)]]) == 0
    printed = capsys.readouterr().out.split()
    sc = load_scene(path, sets)
    plan = plan_run(sc)
    every = [step_grid(plan.at(v).sample_dt, sc.dt)[0] for v in (0.02, 0.1)]
    assert every[0] != every[1]
    assert printed == [str(out / f"cadence-{e}" / "deck.lmp") for e in every]
    assert not (out / "deck.lmp").exists()
    for e, v in zip(every, (0.02, 0.1)):
        d = out / f"cadence-{e}"
        assert f"dump            d all custom {e} traj.dump" in (d / "deck.lmp").read_text()
        vel = (d / DATA_NAME).read_text().split("Velocities\n\n", 1)[1].splitlines()
        assert len(vel) == sc.n and float(vel[0].split()[1]) == to_micro(v, "velocity")


def test_only_enabled_effects_appear(tmp_path):
    h = write_deck(hertz_scene(), tmp_path / "h").read_text()
    assert "groove/drag" not in h and "plugin load" not in h and not re.search(r"^variable", h, re.M)
    assert "rolling" not in h and "erotate" not in h and "chunk" not in h and "ledger.txt" not in h
    assert "tangential linear_history 0.0 0.0 0.0" in h
    assert re.search(r"^fix\s+nve all nve$", h, re.M)
    assert "hertz/material 200000000.0 0.0 0.28 damping viscoelastic" in h

    e = write_deck(effects_scene(), tmp_path / "e").read_text()
    assert "fix             gd all groove/drag groove s" in e and "drag T0 52000.0 L 2500.0" in e
    assert "rotation yes" in e and "tangential mindlin NULL 0.0 1.4" in e
    assert "rolling" not in e and re.search(r"^fix\s+nve all nve/sphere$", e, re.M)
    assert "reduce/chunk chain sum c_erot_atom f_gd[2] f_gd[3]\n" in e
    assert "ave/time 9 1 9 c_ledger[*] mode vector file ledger.txt" in e

    d = write_deck(hertz_scene(effects="[hertz, air_drag]", **{"drag.form": "odd"}),
                   tmp_path / "d").read_text()
    assert "groove s" not in d and "form odd" in d and "rotation no" in d
    assert "reduce/chunk chain sum f_gd[3]\n" in d and " c_ledger mode vector" in d

    r = write_deck(hertz_scene(effects="[hertz, rotation, particle_friction, rolling_friction]",
                                 **{"rolling.k_roll": 1e3, "contact.tangential": "linear_history",
                                    "contact.kt": 2e4}), tmp_path / "r").read_text()
    assert "rolling sds 1000000.0 0.0 0.01" in r
    assert "tangential linear_history 20000000.0 0.0 1.4" in r
    assert "groove/drag" not in r


@pytest.mark.parametrize("make", [hertz_scene, list_scene])
def test_positions_are_the_realisation_exactly(make, tmp_path):
    scene = make()
    write_deck(scene, tmp_path)
    atoms = read_atoms(tmp_path / DATA_NAME)
    g = np.zeros(scene.n - 1) if scene.gap_values is None else np.array(scene.gap_values)
    x = [0.0]
    for gi in g:
        x.append(x[-1] + 2.0 * 150.0 + to_micro(gi, "length"))
    assert atoms[:, 0].tolist() == list(range(1, scene.n + 1))
    assert atoms[:, 4].tolist() == x                      # bit for bit
    assert np.all(atoms[:, 2] == 300.0) and np.all(atoms[:, 3] == 7.8)
    assert np.all(atoms[:, 5:] == 0.0)


def test_ensemble_layout(tmp_path):
    scene = packed(t_end=T_SHORT, **{"gaps.distribution": "uniform", "gaps.mean": 20e-9,
                                     "ensemble.realisations": 3, "striker.velocity": "[0.05, 0.1]"})
    from granchain.simulate import member_gaps, members
    mem = members(scene)
    gaps = member_gaps(scene, mem)
    deck = write_deck(scene, tmp_path)
    atoms = read_atoms(tmp_path / DATA_NAME)
    n = scene.n
    assert len(atoms) == len(mem) * n
    assert atoms[:, 0].tolist() == list(range(1, len(mem) * n + 1))
    for b in range(len(mem)):
        rows = atoms[b * n:(b + 1) * n]
        assert rows[:, 4].tolist() == chain_positions(scene, gaps[b]).tolist()
        assert np.all(rows[:, 5] == b * 600.0)
    vel = (tmp_path / DATA_NAME).read_text().split("Velocities\n\n", 1)[1].splitlines()
    vx = np.array([float(ln.split()[1]) for ln in vel])
    assert vx[::n].tolist() == [m.v_striker for m in mem]
    assert np.count_nonzero(vx) == len(mem)
    assert "6 chain(s) of 15 spheres" in deck.read_text()


@pytest.mark.parametrize("make", [hertz_scene, list_scene, effects_scene])
def test_deck_runs_standalone(make, tmp_path):
    scene = make()
    deck = write_deck(scene, tmp_path)
    run = run_deck(deck)
    m = re.search(r"^granchain: mass\[1\] = (\S+) pg", run.log.read_text(), re.M)
    assert float(m.group(1)) == pytest.approx(scene.mass * 1e15, rel=1e-12)
    d = read_dump(tmp_path / "traj.dump")
    steps = sorted(d)
    every = steps[1] - steps[0]
    assert steps[-1] * 1e-9 >= T_SHORT and steps[-1] * 1e-9 < T_SHORT + every * 1e-9
    last = d[steps[-1]]
    assert list(last) == ["id", "x", "y", "z", "vx"]           # only what the engine reads
    assert last["id"].tolist() == list(range(1, scene.n + 1))
    assert np.all(last["y"] == 0) and np.all(last["z"] == 0)
    en = np.loadtxt(tmp_path / "energy.txt")
    assert en[:, 0].tolist() == steps
    ke0 = 0.5 * scene.mass * 0.1**2 * 1e15
    assert en[0, 1] == pytest.approx(ke0, rel=1e-12)
    ledger = tmp_path / "ledger.txt"
    if scene.has("groove_friction"):
        assert en[-1, 3] < 0          # the groove takes energy out
        # per-chain ledger: 'step 1' then '1 erot groove drag' per sample (one chain)
        rows = np.loadtxt(ledger, comments="#", usecols=(0, 1))
        assert rows[0::2, 0].tolist() == steps and np.all(rows[0::2, 1] == 1)
        vals = np.array([ln.split() for ln in ledger.read_text().splitlines()
                         if not ln.startswith("#")][1::2], dtype=float)
        np.testing.assert_allclose(vals[:, 1:], en[:, 2:], rtol=1e-13, atol=0)
    else:
        assert not ledger.exists()


def test_zero_tangential_force_without_particle_friction(tmp_path):
    """linear_history 0 0 0 leaves no torque: with nve/sphere omega stays exactly 0."""
    deck = write_deck(hertz_scene(), tmp_path)
    text = deck.read_text().replace("fix             nve all nve\n",
                                    "fix             nve all nve/sphere\n")
    text = text.replace("traj.dump id x y z vx", "traj.dump id x y z vx omegay tqy fx")
    deck.write_text(text)
    run_deck(deck)
    d = read_dump(tmp_path / "traj.dump")
    for frame in d.values():
        assert np.all(frame["omegay"] == 0) and np.all(frame["tqy"] == 0)
    assert np.any(d[max(d)]["fx"] != 0)


def test_hertz_run_matches_reference_verlet(tmp_path):
    from granchain.engines import reference
    scene = packed(t_end=5e-6, **{"integrator.method": "verlet"})
    deck = write_deck(scene, tmp_path)
    run_deck(deck)
    d = read_dump(tmp_path / "traj.dump")
    last = max(d)
    traj = next(reference.run(scene, np.zeros((1, scene.n - 1)), np.array([0.1]),
                              method="verlet", trace=True))
    assert traj.t[-1] == pytest.approx(last * 1e-9, rel=1e-12)
    v_lmp = d[last]["vx"][1]
    v_ref = traj.v[-1, 1]
    assert abs(v_ref) > 1e-3
    assert v_lmp == pytest.approx(v_ref, rel=1e-3)
    # every sample of particle 2 agrees
    steps = sorted(d)
    v2 = np.array([d[s]["vx"][1] for s in steps])
    assert len(v2) == len(traj.t)
    np.testing.assert_allclose(v2, traj.v[:, 1], rtol=0, atol=1e-9)   # measured 1e-11


def test_gapped_ensemble_with_effects_matches_reference_verlet(tmp_path):
    """Two gap realisations side by side, every effect but rolling: each chain of the
    LAMMPS run equals the reference verlet run of its member (measured 1e-10 m/s)."""
    from granchain.engines import reference
    from granchain.simulate import member_gaps, members
    scene = packed(effects=ALL_BUT_ROLLING, t_end=5e-6,
                   **{"integrator.method": "verlet", "gaps.distribution": "uniform", "gaps.mean": 20e-9,
                      "ensemble.realisations": 2})
    mem = members(scene)
    gaps = member_gaps(scene, mem)
    deck = write_deck(scene, tmp_path)
    run_deck(deck)
    d = read_dump(tmp_path / "traj.dump")
    v = np.array([d[s]["vx"] for s in sorted(d)])
    n = scene.n
    for b, traj in enumerate(reference.run(scene, gaps, np.array([m.v_striker for m in mem]),
                                           method="verlet", trace=True)):
        np.testing.assert_allclose(v[:, b * n:(b + 1) * n], traj.v, rtol=0, atol=1e-8)


def test_output_option_writes_what_it_says(tmp_path):
    """output "dump" (default): the text dump and ledger.txt; "binary": traj.bin and
    ledger.bin only; "none": no per-sample output but energy.txt. The physics lines are
    the same in all three."""
    scene = effects_scene()
    texts = {out: write_deck(scene, tmp_path / out, output=out).read_text()
             for out in ("dump", "binary", "none")}
    assert "custom 9 traj.dump id x y z vx" in texts["dump"] and "ledger.txt" in texts["dump"]
    b = texts["binary"]
    assert "dump            d all custom 9 traj.bin x vx\ndump_modify     d sort id\n" in b
    assert "chunk/spread/atom chain c_ledger[*]" in b and "group           heads id 1\n" in b
    assert "dump            ledger heads custom 9 ledger.bin c_ledger_atom[*]" in b
    assert "traj.dump" not in b and "ave/time 9 1 9 c_ledger" not in b
    n = texts["none"]
    assert not re.search(r"^dump", n, re.M) and "chunk" not in n
    assert not any("ledger" in ln for ln in n.splitlines() if not ln.startswith("#"))
    assert "energy.txt" in n
    phys = [ln for ln in texts["dump"].splitlines() if re.match(r"(pair|fix|run|timestep)", ln)
            and "ledger" not in ln]
    for out in ("binary", "none"):
        assert phys == [ln for ln in texts[out].splitlines()
                        if re.match(r"(pair|fix|run|timestep)", ln) and "ledger" not in ln]
    with pytest.raises(GranchainError, match="output must be one of"):
        write_deck(scene, tmp_path / "x", output="text")
    for out in ("binary", "none"):
        run_deck(write_deck(scene, tmp_path / f"run-{out}", output=out))
        assert (tmp_path / f"run-{out}" / "traj.bin").exists() == (out == "binary")
        assert not (tmp_path / f"run-{out}" / "traj.dump").exists()


def test_travel_bound_follows_the_propulsive_drag():
    """max_travel: v t without drag or below L/T0; with a propulsive drag the solution of
    dW/dt = W^2/L - W/T0 (checked against a small-step integration); refuses a run past
    the blow-up of W."""
    from granchain.lammps.deck import max_travel
    hertz, drag = packed(), packed(effects="[hertz, air_drag]")
    assert max_travel(hertz, 1.0, 2e-3) == 2e-3
    st = drag.setting("air_drag")
    L_T0 = st.L / st.T0
    assert max_travel(drag, 0.5 * L_T0, 1.0) == 0.5 * L_T0
    w, x, h = 1.0, 0.0, 1e-8
    for _ in range(int(round(2e-3 / h))):
        x += h * (w + 0.5 * h * (w * w / st.L - w / st.T0))
        w += h * (w * w / st.L - w / st.T0)
    assert max_travel(drag, 1.0, 2e-3) == pytest.approx(x, rel=1e-3)
    assert max_travel(drag, 1.0, 2e-3) > 1.9 * 2e-3
    with pytest.raises(GranchainError, match="without bound after"):
        max_travel(drag, 1.0, 3e-3)


def test_long_run_with_propulsive_drag_loses_no_atom(tmp_path, monkeypatch):
    """1 m/s striker, air drag only, 2.4 ms: the spheres that leave the chain are sped up
    to ~15 m/s and travel ~7 mm, beyond the previous margin (2 v_max t_run = 4.8 mm).
    The box sized by max_travel holds them; the previous margin loses atoms."""
    from granchain.engines import lammps as lammps_engine
    from granchain.lammps import deck as lammps_deck
    scene = packed(effects="[hertz, air_drag]", t_end=2.4e-3,
                   **{"striker.velocity": 1.0, "integrator.method": "verlet", "integrator.dt": 1e-8,
                      "output.sample_dt": 1e-7})
    gaps, vs = np.zeros((1, scene.n - 1)), np.array([1.0])
    t = next(lammps_engine.run(scene, gaps, vs, workdir=tmp_path / "ok"))
    assert t.status == "done" and np.all(np.isfinite(t.v))
    assert t.t[-1] == pytest.approx(2.4e-3, rel=1e-9) and t.v.max() > 10.0
    pl = lammps_deck.plan(scene, gaps=gaps, v_striker=vs, output="binary")
    _, cols = lammps_engine.read_binary_dump(tmp_path / "ok" / lammps_deck.BINARY_NAME, ("x", "vx"),
                                             scene.n, pl.nsamples, "traj")
    travel = np.abs(cols["x"][-1] - cols["x"][0]).max() * 1e-6
    assert travel > 2.0 * 1.0 * pl.t_run                      # the previous margin's room
    assert travel < lammps_deck.max_travel(scene, 1.0, pl.t_run)
    monkeypatch.setattr(lammps_deck, "max_travel", lambda scene, v, t: v * t)  # the previous margin
    with pytest.raises(GranchainError, match="Lost atoms"):
        next(lammps_engine.run(scene, gaps, vs, workdir=tmp_path / "old"))
