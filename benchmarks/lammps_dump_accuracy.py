"""What the LAMMPS dump's cadence and MDAnalysis' float32 velocities cost in accuracy.

    python benchmarks/lammps_dump_accuracy.py

For two one-chain scenes (the packed 440C chain and one 20 nm uniform-gap realisation,
every effect on, v_s = 0.1 m/s, dt = 1 ns, t_end = 25 us so that every particle has
peaked) LAMMPS dumps every step once. Truth: the every-step record, v_max = its largest
sample refined by the parabola through its neighbours, t_peak that parabola's vertex
(at 1 ns spacing the observables code would call every peak a plateau, see below).
From the same dump, the observables code (granchain.observables.summarize) is applied
to the record subsampled at 1x, 4x and 16x the default cadence (400 samples per
solitary-wave width, 9 steps here), with the float64 columns and with the velocities
rounded to float32 (``read_dump(velocities="float32")``: what MDAnalysis' own float32
velocity parsing gives; the dump no longer writes vy vz, so MDAnalysis parses none).
Printed: the largest error over particles of v_max (relative) and
t_peak (ns), and the relative error of v_g and v_g_front. Not a test: run by hand.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from granchain.engines.lammps import read_dump  # noqa: E402
from granchain.stoprule import sample_interval  # noqa: E402
from granchain.gaps import realise  # noqa: E402
from granchain.lammps import deck as lammps_deck  # noqa: E402
from granchain.lammps.runner import run_lammps  # noqa: E402
from granchain.observables import summarize  # noqa: E402
from granchain.scene import scene_from_dict  # noqa: E402
from granchain.trajectory import Trajectory  # noqa: E402

ALL = ["hertz", "groove_friction", "air_drag", "rotation", "particle_friction"]
T_END = 25e-6


def scene(gapped: bool):
    raw = {"name": "gapped" if gapped else "packed", "material": "ss440c",
           "chain": {"n": 15, "radius": 150e-6}, "striker": {"velocity": 0.1},
           "effects": ALL, "integrator": {"method": "verlet", "dt": 1e-9}, "t_end": T_END}
    if gapped:
        raw["gaps"] = {"distribution": "uniform", "mean": 20e-9, "seed": 0}
    return scene_from_dict(raw)


def truth(t, v):
    """v_max and t_peak of every particle: largest sample + parabola through neighbours."""
    vm, tp = [], []
    for i in range(v.shape[1]):
        y = v[:, i]
        j = int(np.argmax(y))
        if 0 < j < len(y) - 1:
            y0, y1, y2 = y[j - 1], y[j], y[j + 1]
            den = y0 - 2 * y1 + y2
            off = 0.5 * (y0 - y2) / den if den < 0 else 0.0
            vm.append(y1 - 0.25 * (y0 - y2) * off)
            tp.append(t[j] + off * (t[j + 1] - t[j]))
        else:
            vm.append(y[j])
            tp.append(t[j])
    return np.array(vm), np.array(tp)


def main():
    default_every = None
    rows = []
    for gapped in (False, True):
        sc = scene(gapped)
        gaps = realise(sc, 0)[None, :]
        every_default = int(round(sample_interval(sc, 0.1) / sc.dt))
        default_every = every_default
        fine = sc.derive(**{"output.sample_dt": sc.dt})
        pl = lammps_deck.plan(fine, gaps=gaps, v_striker=[0.1])
        with tempfile.TemporaryDirectory(prefix="granchain-cadence-") as wd:
            deck = lammps_deck.write_deck(fine, Path(wd), gaps=gaps, v_striker=[0.1])
            run_lammps(deck, Path(wd))
            d64 = read_dump(Path(wd) / lammps_deck.DUMP_NAME, fine, pl)
            d32 = read_dump(Path(wd) / lammps_deck.DUMP_NAME, fine, pl, velocities="float32")
        t = d64["step"] * sc.dt
        v64, v32 = d64["v"][:, 0, :], d32["v"][:, 0, :]
        vm_true, tp_true = truth(t, v64)
        p1, p2 = sc.probes[0] - 1, sc.probes[1] - 1
        span = (p2 - p1) * (2 * sc.radius + float(np.mean(gaps[0, p1:p2])))
        vg_true = span / (tp_true[p2] - tp_true[p1])
        def observe(e, v):
            return summarize(Trajectory(t=t[::e], v=v[::e], energy=d64["energy"][::e, 0],
                                        gaps=gaps[0], radius=sc.radius, v_striker=0.1),
                             sc.probes)

        base = observe(every_default, v64)
        sharp = ~np.array(base.plateau)          # particles with a sharp peak
        for k in (1, 4, 16):
            e = k * every_default
            s64, s32 = observe(e, v64), observe(e, v32)
            vm64, vm32 = np.array(s64.v_max), np.array(s32.v_max)
            tp64, tp32 = np.array(s64.t_peak), np.array(s32.t_peak)
            rows.append((sc.name, k, e, int(sharp.sum()),
                         float(np.max(np.abs(vm64 - vm_true)[sharp] / vm_true[sharp])),
                         float(np.max(np.abs(tp64 - tp_true)[sharp])) * 1e9,
                         abs(s64.v_g - vg_true) / vg_true,
                         abs(s64.v_g_front - base.v_g_front) / base.v_g_front,
                         float(np.max(np.abs(vm32 - vm64) / vm64)),
                         float(np.max(np.abs(tp32 - tp64))) * 1e9,
                         abs(s32.v_g - s64.v_g) / s64.v_g))
    print(f"default cadence: every {default_every} steps (dt = 1 ns); truth: every step.")
    print("errors vs truth (float64 columns; v_max, t_peak over the sharp peaks), and what "
          "MDAnalysis' float32 velocities change at the same cadence")
    print(f"{'scene':7} {'x':>3} {'every':>5} {'sharp':>5} | {'v_max rel':>9} {'t_peak ns':>9} "
          f"{'v_g rel':>9} {'v_gf rel*':>9} | {'f32 v_max':>9} {'f32 t_pk ns':>11} {'f32 v_g':>9}")
    for r in rows:
        print(f"{r[0]:7} {r[1]:>3} {r[2]:>5} {r[3]:>5} | {r[4]:>9.2e} {r[5]:>9.3g} {r[6]:>9.2e} "
              f"{r[7]:>9.2e} | {r[8]:>9.2e} {r[9]:>11.3g} {r[10]:>9.2e}")
    print("* v_g_front: relative to its value at the default cadence (the truth has no "
          "arrival-time refinement)")


if __name__ == "__main__":
    main()
