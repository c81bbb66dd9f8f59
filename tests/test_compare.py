"""granchain.compare and ``granchain compare``: the table, its tolerances, exit status."""
from __future__ import annotations

import json
import math

import pandas as pd
import pytest

import granchain.compare as compare_mod
from granchain.cli import main as cli_main
from granchain.scene import scene_from_dict
from granchain.trajectory import ENERGY_COLUMNS
from tests.conftest import packed

pytestmark = pytest.mark.lammps

# Hertz only: the scene file's groove, drag and contact parameters back to their defaults
# (null), since keys of effects that are off are refused
HERTZ = ["--set", "effects=[hertz]", "--set", "groove=null", "--set", "drag=null",
         "--set", "contact=null"]


@pytest.fixture
def scene_yaml(repo):
    return str(repo / "granchain/scenes/packed-440c.yaml")


def test_rows_of_a_hertz_chain():
    cmp = compare_mod.compare(packed())
    df = cmp.rows
    assert list(df.columns) == ["member", "realisation", "v_striker", "quantity", "reference",
                                "lammps", "diff", "measure", "tolerance", "ok", "why"]
    q = df.quantity.tolist()
    assert q[0] == "samples" and [f"v_max[{i}]" for i in range(1, 16)] == q[1:16]
    for name in ("v_max_1", "v_max_2", "dt_peak", "v_g", "v_g_front", "balance_error",
                 *ENERGY_COLUMNS):
        assert name in q
    assert df.ok.map(lambda x: x is True).all() and cmp.ok     # every row checked and met
    final = df.quantity == "v_final, every particle"
    assert final.sum() == 1 and (df.loc[final, "tolerance"] == compare_mod.TRAJ_TOL).all()
    vrows = df.quantity.str.startswith("v_") & ~final
    assert vrows.sum() == 15 + 4 and (df.loc[vrows, "tolerance"] == compare_mod.V_TOL).all()
    assert (df.loc[df.quantity.str.startswith("dt_"), "tolerance"] == compare_mod.T_TOL).all()
    assert cmp.meta["balance"] == "independent"
    assert cmp.scene.method == "verlet" and cmp.scene.sample_dt == pytest.approx(9e-9)
    # the reference's own ledger is the yardstick: its balance error is Verlet's
    bal = df[df.quantity == "balance_error"].iloc[0]
    assert 1e-8 < bal.reference < 1e-5 and bal["diff"] < 1e-9


def test_contact_friction_rows_are_marked_not_independent():
    cmp = compare_mod.compare(packed(effects="[hertz, rotation, particle_friction]"))
    df = cmp.rows
    # the residual group is the scene's effects.residual_work: contact friction alone here;
    # the works of effects that are off (rolling friction) are checked rows, 0 on both sides
    row = df[df.quantity == "work_particle_friction"].iloc[0]
    assert row.ok is None and "not independent" in row.why
    roll = df[df.quantity == "work_rolling_friction"].iloc[0]
    assert roll.ok is True and roll.reference == roll.lammps == 0.0
    bal = df[df.quantity == "balance_error"].iloc[0]
    assert bal.ok is None and bal.lammps < 1e-12
    assert cmp.ok and cmp.meta["balance"] == "residual"


def test_cli_table_and_exit_status(scene_yaml, capsys, monkeypatch):
    assert cli_main(["compare", scene_yaml, *HERTZ]) == 0
    out = capsys.readouterr().out
    assert "v_max[15]" in out and "v_g" in out and "kinetic_translational" in out
    assert "] not the 1e-3 of a loose cross-check" in out and out.rstrip().endswith("all tolerances met")
    assert "v(t), every particle" in out                      # --traces 1, the default
    monkeypatch.setattr(compare_mod, "V_TOL", 0.0)            # nothing agrees to the last bit
    assert cli_main(["compare", scene_yaml, *HERTZ]) == 1
    out = capsys.readouterr().out
    assert "FAIL" in out and "tolerance(s) missed" in out


def test_cli_json_and_out(scene_yaml, tmp_path, capsys):
    out = tmp_path / "cmp.json"
    assert cli_main(["compare", scene_yaml, *HERTZ, "--json", "--out", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["ok"] is True and doc["scene"] == "packed-440c"
    assert {r["quantity"] for r in doc["rows"]} >= {"v_max[1]", "v_g", "hertz_potential"}
    assert doc["meta"]["tolerances"] == {"v": compare_mod.V_TOL, "t": compare_mod.T_TOL,
                                         "energy_over_E0": compare_mod.E_TOL,
                                         "trajectory_over_v_s": compare_mod.TRAJ_TOL}
    assert cli_main(["compare", scene_yaml, *HERTZ, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "exists" in err and err.count("\n") == 1


def test_ensemble_table_shows_worst_member(scene_yaml, capsys):
    assert cli_main(["compare", scene_yaml, *HERTZ, "--set", "gaps.distribution=uniform",
                     "--set", "gaps.mean=20e-9", "--set", "ensemble.realisations=3",
                     "--set", "probes=[2, 6]"]) == 0
    out = capsys.readouterr().out
    assert "3 chain(s)" in out and "worst member" in out
    assert sum(line.startswith("v_g ") for line in out.splitlines()) == 1


@pytest.mark.lammps
def test_compare_trajectory_reads_the_text_dump_and_checks_every_sample(tmp_path):
    import dataclasses

    from granchain.compare import compare, member_rows
    sc = scene_from_dict({"name": "traj", "chain": {"n": 6}, "probes": [2, 6],
                          "effects": ["hertz", "groove_friction", "air_drag", "rotation",
                                      "particle_friction"],
                          "gaps": {"distribution": "uniform", "mean": 2.0e-8, "seed": 3},
                          "ensemble": {"realisations": 2},
                          "integrator": {"method": "verlet", "dt": 1.0e-9}})
    cmp = compare(sc, workdir=tmp_path / "w", trajectory=True)
    rows = cmp.rows[cmp.rows.quantity == "v(t), every particle"]
    assert cmp.ok and len(rows) == 2 and (rows["diff"] < 1e-8).all()
    assert (tmp_path / "w" / "traj.dump").is_file() and cmp.meta["lammps_output"].startswith("dump")
    # observables measured on the fly (every member) and one member's records: the same
    # values on both sides as from the records, and the trajectory row for member 0 only
    few = compare(sc, traces=1)
    assert few.ok and few.meta["traced_chains"] == 1 and cmp.meta["traced_chains"] == 2
    t_rows = few.rows[few.rows.quantity == "v(t), every particle"]
    assert t_rows.member.tolist() == [0] and t_rows["diff"].iloc[0] == rows["diff"].iloc[0]
    keep = lambda df: df[df.quantity != "v(t), every particle"].reset_index(drop=True)  # noqa: E731
    pd.testing.assert_frame_equal(keep(few.rows), keep(cmp.rows))
    # the row fails when one sample of one particle is off by 1e-5 v_s
    from granchain.engines import reference
    from granchain.gaps import member_gaps, members
    cs = cmp.scene
    mem = members(cs)
    ref = next(reference.run(cs, member_gaps(cs, mem)[:1], [mem[0].v_striker], method="verlet",
                             dt=cs.dt))
    v = ref.v.copy()
    v[len(v) // 2, 3] += 1e-5 * ref.v_striker
    bad = dataclasses.replace(ref, v=v)
    row, = [r for r in member_rows(cs, ref, bad, trace=ref)
            if r["quantity"] == "v(t), every particle"]
    assert row["ok"] is False and row["diff"] == pytest.approx(1e-5, rel=1e-6)


def test_walled_scene_compares_the_wall_force():
    """A preloaded chain on an elastic end wall: rows for the wall's dynamic peak, its time
    and the static preload, within W_TOL/T_TOL (measured <= 5e-10); a free end has none.
    The peak row fails when one engine's wall force is 1e-5 off, the static row when its
    preload is."""
    import dataclasses

    from granchain.engines import reference
    from granchain.gaps import member_gaps, members
    sc = packed(**{"chain.n": 8, "probes": "[2, 7]", "walls.end": "ss316",
                   "precompression.force": 0.02, "striker.velocity": 0.2})
    cmp = compare_mod.compare(sc)
    df = cmp.rows.set_index("quantity")
    assert cmp.ok and cmp.meta["tolerances"]["wall_force"] == compare_mod.W_TOL
    for q, tol in (("wall_force_max", compare_mod.W_TOL), ("t_wall_peak", compare_mod.T_TOL),
                   ("wall_force_static", compare_mod.W_TOL)):
        r = df.loc[q]
        assert r.ok is not None and bool(r.ok) and r.tolerance == tol and r["diff"] < 1e-8, (q, r)
        assert math.isfinite(r.reference) and r.reference > 0, q
    assert df.loc["wall_force_static", "reference"] == pytest.approx(0.02, rel=1e-12)
    assert "wall_force_max" not in compare_mod.compare(packed(**{"chain.n": 6, "probes": "[2, 6]"})
                                             ).rows.quantity.tolist()
    # a wall force 1e-5 too large (the whole record), or a preload 1e-5 too large
    cs = cmp.scene
    mem = members(cs)
    ref = next(reference.run(cs, member_gaps(cs, mem), [mem[0].v_striker], method="verlet",
                             dt=cs.dt, trace=True))
    for change, failing in (({"wall_force": ref.wall_force * (1 + 1e-5)}, "wall_force_max"),
                            ({"wall_static": ref.wall_static * (1 + 1e-5)}, "wall_force_static")):
        bad = dataclasses.replace(ref, **change)
        rows = {r["quantity"]: r for r in compare_mod.member_rows(cs, ref, bad)}
        assert rows[failing]["ok"] is False, failing
        assert rows["t_wall_peak"]["ok"] is True


def test_tolerances_see_what_rounding_cannot_explain():
    """The tolerances sit about 10x above the engines' measured disagreement (module doc
    of granchain.compare: v_max 3.5e-9, v(t) 5.0e-8 v_s, times 1.2e-9, energies 7.3e-9 E0,
    wall force 2.0e-9), so a difference 10x above each tolerance, still far below any
    physics term, fails its row, and rounding-sized ones pass. The reference's own
    record stands in for LAMMPS's, altered."""
    import dataclasses

    import numpy as np

    from granchain.engines import reference
    from granchain.gaps import member_gaps, members
    for name, tol in (("V_TOL", 3.5e-9), ("TRAJ_TOL", 5.0e-8), ("T_TOL", 1.2e-9),
                      ("E_TOL", 7.3e-9), ("W_TOL", 2.0e-9)):
        assert 3 * tol < getattr(compare_mod, name) <= 11 * tol, name
    cs = compare_mod.comparison_scene(packed(**{"chain.n": 8, "probes": "[2, 7]",
                                                "walls.end": "ss316", "striker.velocity": 0.2}))
    mem = members(cs)
    ref = next(reference.run(cs, member_gaps(cs, mem), [mem[0].v_striker], method="verlet",
                             dt=cs.dt, trace=True))

    def rows(**change):
        return {r["quantity"]: r for r in compare_mod.member_rows(
            cs, ref, dataclasses.replace(ref, **change), trace=ref)}

    same = rows()
    assert all(r["ok"] is not False for r in same.values())
    for scale in (0.1, 10.0):
        dv = scale * compare_mod.V_TOL
        got = rows(v=ref.v * (1 + dv))                 # every peak scaled, v_g unchanged
        assert (got["v_max[4]"]["ok"] is False) == (scale > 1), scale
        assert got["v(t), every particle"]["ok"] is True  # dv < 3e-7 v_s: below TRAJ_TOL
    v = ref.v.copy()
    v[len(v) // 2, 3] += 10 * compare_mod.TRAJ_TOL * ref.v_striker
    assert rows(v=v)["v(t), every particle"]["ok"] is False
    t = ref.t * (1 + 10 * compare_mod.T_TOL)           # every time, stretched
    assert rows(t=t)["dt_peak"]["ok"] is False
    e = ref.energy.copy()
    e[:, 0] += 10 * compare_mod.E_TOL * e[0, :3].sum()  # the kinetic energy, shifted
    assert rows(energy=e)["kinetic_translational"]["ok"] is False
    w = rows(wall_force=ref.wall_force * (1 + 10 * compare_mod.W_TOL))
    assert w["wall_force_max"]["ok"] is False and w["t_wall_peak"]["ok"] is True

