"""Outputs of the accuracy-vs-cost study: the tables and their provenance, the packaged
cost model (``write_model``) and the figure (``plot``)."""
from __future__ import annotations

import json
import os
import platform
from pathlib import Path

import numpy as np

from .. import costmodel
from ..errors import GranchainError
from ..scenekeys import TOLERANCE_METHODS
from .envelope import DAMPED_PREFIX, cheapest, cheapest_table, model_from_table, scene_class
from .harness import DETERMINISTIC, METHODS, full_config, to_frame


def machine() -> dict:
    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "system": platform.system(),
            "machine": platform.machine()}


def provenance_fields(info: dict, cost: dict, base: dict, preset: str | None) -> dict:
    """What the tables' provenance adds to granchain.tables.environment()."""
    from ..tables import config_hash
    return {"study": "accuracy_cost", "preset": preset, "scenes": info["scenes"],
            "scene_hashes": {k: v["scene_hash"] for k, v in info["scenes"].items()},
            "seeds": sorted({v["seed"] for v in info["scenes"].values()}),
            "engines": ["reference"] + ([] if "lammps" in info["skipped"] else ["lammps"]),
            "skipped": info["skipped"], "method": "see rows", "dt": "see rows",
            "config_hash": config_hash({"cost": cost, "base": base}), "cost": cost, "base": base}


def write_outputs(rows, info, cost, base, *, preset=None, table=None, provenance=None,
                  timing=None, cheapest_csv=None) -> None:
    """The deterministic table and its provenance; the table with wall times (with the
    machine and ``info["timing"]``, every timed repeat and its spread, in its provenance)
    and the cheapest settings, which depend on wall times."""
    from .. import tables
    cost, base = full_config(cost, base)
    df = to_frame(rows)
    fields = provenance_fields(info, cost, base, preset)
    lmp = "lammps" not in info["skipped"] and "lammps" in cost["methods"]
    if table:
        tables.write_csv(df[list(DETERMINISTIC)], table)
    if provenance:
        tables.write_provenance(provenance, lammps=lmp, **fields)
    if timing:
        tables.write_csv(df, timing)
        tables.write_provenance(Path(timing).with_suffix(".provenance.json"), lammps=lmp,
                                machine=machine(), timing=info.get("timing"), **fields)
    if cheapest_csv:
        tables.write_csv(cheapest_table(df, cost["cheapest_tolerances"]), cheapest_csv)


def write_model(timing_csv, out, *, force: bool = False) -> None:
    """The cost model (package data) from a measured table, with its provenance beside it."""
    from .. import tables
    out = Path(out)
    prov_out = out.with_name(out.stem + ".provenance.json")
    for p in (out, prov_out):
        if p.exists() and not force:
            raise GranchainError(f"'{p}' exists; pass --force to replace the cost model")
    table = tables.read_csv(timing_csv)
    src = json.loads(Path(timing_csv).with_suffix(".provenance.json").read_text())
    floor: dict[str, float] = {}
    for name, sc in src["scenes"].items():
        c = scene_class(name)
        floor[c] = max(floor.get(c, 0.0), sc.get("sampling_floor_v_g") or 0.0)
    if costmodel.DAMPED in floor:       # the damped class is the worst over every scene
        floor[costmodel.DAMPED] = max(floor.values())
    prov = {"source": f"python -m granchain.accuracy model {Path(timing_csv).as_posix()}",
            "preset": src.get("preset"),
            "scenes": {k: {kk: v.get(kk) for kk in ("name", "scene_hash", "uncertainty",
                                                    "plateau_at_probes", "realisations",
                                                    "work")}
                       for k, v in src["scenes"].items()},
            "scene_class": {k: scene_class(k) for k in src["scenes"]},
            "sampling_floor_v_g": floor, "machine": src.get("machine"),
            "versions": {k: src.get(k) for k in ("granchain_version", "git_commit", "git_dirty", "python",
                                                  "numpy", "numba")},
            "config_hash": src.get("config_hash"), "cost": src.get("cost"), "base": src.get("base"),
            "rows": "one per (scene_class, setting); error: largest over the class's scenes "
                    "(damped: over every scene); wall_s_per_chain: mean over the class's",
            "dt": "t_c / steps_per_contact, t_c = Scene.contact_time(fastest striker speed)"}
    tables.write_csv(model_from_table(table), out)
    tables.write_json(prov_out, prov)
    costmodel.load_model.cache_clear()


COLORS = {"rk4": "C0", "verlet": "C1", "adaptive": "C2", "lammps": "C3", "event": "C4"}
PANELS = (("v_max_2", "relative error of $v_{max,2}$"), ("v_g", "relative error of $v_g$"),
          ("balance", "energy balance error"))
STYLES = ("-", "--", ":", "-.")


def plot(table, png, pdf=None, *, tolerances=(1e-3, 1e-5)) -> None:
    """Error against wall time per chain, log-log: one panel per observable, one curve per
    method and scene (line style; square markers: a damped scene), in order of
    refinement; reference uncertainty grey; the cheapest settings for ``tolerances`` on
    v_g (all scenes) starred."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    floor = 1e-16
    fig, axes = plt.subplots(1, 3, figsize=(14, 5.8), layout="constrained")
    scenes = list(dict.fromkeys(table["scene"]))
    # a damped scene: its undamped twin's line style, square markers
    twins = [sc for sc in scenes if not sc.startswith(DAMPED_PREFIX)]
    for ax, (obs, label) in zip(axes, PANELS):
        col = "balance_error" if obs == "balance" else f"err_{obs}"
        for sc in scenes:
            twin = sc.removeprefix(DAMPED_PREFIX)
            si = twins.index(twin) if twin in twins else len(twins)
            mk = "s" if sc.startswith(DAMPED_PREFIX) else "o"
            sub = table[table["scene"] == sc]
            for m in METHODS:
                s = sub[sub["method"] == m]
                if s.empty or s[col].isna().all():
                    continue
                s = s.sort_values("tolerance", ascending=False) if m in TOLERANCE_METHODS else \
                    s.sort_values("steps_per_contact")
                ax.plot(s["wall_s_per_chain"], np.maximum(s[col], floor), STYLES[si % 4],
                        marker=mk, ms=3, color=COLORS[m], label=f"{m}, {sc}")
            if obs != "balance":
                u = float(sub[f"ref_uncertainty_{obs}"].max())
                ax.axhline(max(u, floor), color="0.6", ls=STYLES[si % 4], lw=0.8)
        if obs == "v_g":
            for tol in tolerances:
                ax.axhline(tol, color="k", lw=0.5, alpha=0.4)
                c = cheapest(table, tol, "v_g")
                if c is not None:
                    ax.plot([c["wall_s_per_chain"]], [max(c["envelope"], floor)], "*", ms=15,
                            mfc="none", mec="k")
                    ax.annotate(f"cheapest for {tol:g}: {_label(c)}",
                                (c["wall_s_per_chain"], max(c["envelope"], floor)),
                                textcoords="offset points", xytext=(8, 4), fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time per chain (s)")
        ax.set_ylabel(label)
        ax.grid(True, which="major", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", fontsize=6,
               ncol=min(6, max(1, len(scenes))))
    fig.suptitle("What accuracy costs in time: error against wall time per chain "
                 "(grey: the reference's own uncertainty)", fontsize=10)
    Path(png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=150, metadata={"Software": None})
    if pdf:
        fig.savefig(pdf, metadata={"CreationDate": None, "ModDate": None, "Producer": None})
    plt.close(fig)


def _label(c: dict) -> str:
    if c["method"] in TOLERANCE_METHODS:
        return f"{c['method']}, tolerance {c['tolerance']:g}"
    dt = f", dt {c['dt_s']:.3g} s" if c.get("dt_s") is not None else ""
    return f"{c['method']}, N = {c['steps_per_contact']}{dt}"

