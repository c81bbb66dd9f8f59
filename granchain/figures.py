"""The chapter's figures, drawn from the workflow's tables (issue 4, contract columns).

One function per chapter panel. Each takes pandas DataFrames read from
``results/{preset}/tables/{study}.csv`` (one row per chain, units in column names; see
/work/coord/WORKFLOW_CONTRACT.md) -- or, for Fig. 5.1a, the trace npz -- and writes
``{out}.png`` and ``{out}.pdf``. Nothing here simulates: figures only read tables.

- :func:`fig5_1a`  particle velocities in time along the packed chain (one trace);
- :func:`fig5_1b`  v_max vs striker velocity, linear fit through the origin (packed_sweep);
- :func:`fig5_1c`  v_g vs striker velocity with Nesterenko's curve (packed_sweep);
- :func:`fig5_3b`  peak velocity along a chain with 20 nm mean gaps (gap_profile);
- :func:`fig5_3c`  v_g vs striker velocity for mean gaps 10..190 nm, bands and Eq. 5.4 (gap_sweep);
- :func:`fig5_4b`  v_g vs the mean gap inferred from the extra chain length (extra_length).

Output is deterministic: fixed rcParams (matplotlib defaults + RC below, whatever the
user's matplotlibrc says), no dates or software strings in PNG/PDF metadata, so a rerun on
the same tables gives byte-identical files.

Command line (what workflow/rules/figures.smk calls)::

    python -m granchain.figures fig5_3c --gap-sweep G.csv --packed-sweep P.csv --out DIR/fig5_3c

A missing table or column is a one-line :class:`~granchain.errors.GranchainError`.
"""
from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from .analytic import eq54_group_velocity, nesterenko_speed
from .errors import GranchainError
from .materials import library
from .scene import DEFAULTS

# The chapter's probes (particles 2 and 13) and chain radius, used where a table cannot
# say them. The tables carry every particle's v_max but not the probes.
PROBES = tuple(DEFAULTS["probes"])
MATERIAL_LABEL = {"ss316": "316", "ss440c": "440C"}
MATERIAL_COLOR = {"ss316": "#1f77b4", "ss440c": "#d62728"}
CHAPTER_VMAX_SLOPE = 0.64          # chapter Fig. 5.1b fit (used only as a drawn reference)

# Fixed style on top of matplotlib's defaults (deterministic, readable in print).
RC = {
    "figure.dpi": 100,
    "savefig.dpi": 150,
    "font.size": 9,
    "axes.titlesize": 9,
    "axes.labelsize": 9,
    "legend.fontsize": 7.5,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.3,
    "lines.markersize": 4,
    "pdf.fonttype": 42,
    "svg.hashsalt": "granchain",
    "path.simplify": False,
}

VMAX_RE = re.compile(r"^vmax_p(\d+)_m_s$")

# Columns each study's figure needs (contract names).
NEEDS = {
    "fig5_1b": ["material", "v_striker_m_s", "v_max_1_m_s", "v_max_2_m_s"],
    "fig5_1c": ["material", "v_striker_m_s", "v_max_2_m_s", "v_g_m_s", "wave_arrived"],
    "fig5_3b": ["material", "v_striker_m_s", "realisation", "gap_mean_nm"],
    "fig5_3c": ["material", "v_striker_m_s", "gap_mean_nm", "realisation", "v_g_m_s",
                "wave_arrived"],
    "fig5_4b": ["material", "v_striker_m_s", "extra_length_um", "realisation", "v_g_m_s",
                "wave_arrived"],
    "packed_reference": ["material", "v_striker_m_s", "v_g_m_s", "wave_arrived"],
    "trace": ["t_s", "v_m_s", "v_striker_m_s", "material"],
}


# ---------------------------------------------------------------------------------------
# reading and checking tables
# ---------------------------------------------------------------------------------------
def read_table(path) -> pd.DataFrame:
    """One contract table (CSV); a clear one-line error when it is missing."""
    path = Path(path)
    if not path.is_file():
        raise GranchainError(f"table '{path}' not found; produce it with the workflow "
                             f"(snakemake --cores 2 {path})")
    from .tables import read_csv
    df = read_csv(path)
    df.attrs["name"] = path.name
    return df


def read_trace(path) -> dict:
    """The Fig. 5.1a trace npz: t_s (S,), v_m_s (S, n), v_striker_m_s, material."""
    path = Path(path)
    if not path.is_file():
        raise GranchainError(f"trace '{path}' not found; produce it with the workflow "
                             f"(snakemake --cores 2 {path})")
    with np.load(path, allow_pickle=False) as z:
        missing = [k for k in NEEDS["trace"] if k not in z.files]
        if missing:
            raise GranchainError(f"trace '{path.name}' lacks {', '.join(missing)}; "
                                 "regenerate it with the workflow (contract: t_s, v_m_s, "
                                 "v_striker_m_s, material)")
        out = {k: z[k] for k in z.files}
    out["material"] = str(out["material"])
    out["v_striker_m_s"] = float(out["v_striker_m_s"])
    out["name"] = path.name
    return out


def require(df: pd.DataFrame, columns, what: str) -> None:
    """Raise a one-line error naming the table and the missing contract columns."""
    if df is None:
        raise GranchainError(f"{what}: no table given; pass it (see python -m granchain.figures -h)")
    missing = [c for c in columns if c not in df.columns]
    if missing:
        name = df.attrs.get("name", "table")
        raise GranchainError(f"{what}: table '{name}' lacks column(s) {', '.join(missing)}; "
                             "regenerate it with the workflow (granchain/tables.py writes "
                             "the contract's columns)")
    if len(df) == 0:
        raise GranchainError(f"{what}: table '{df.attrs.get('name', 'table')}' has no rows; "
                             "check the study's settings in config/config.yaml")


def vmax_columns(df: pd.DataFrame) -> list[str]:
    """The per-particle v_max columns vmax_p01_m_s ... in particle order."""
    cols = [(int(m.group(1)), c) for c in df.columns if (m := VMAX_RE.match(c))]
    return [c for _, c in sorted(cols)]


def require_vmax(df: pd.DataFrame, what: str) -> list[str]:
    cols = vmax_columns(df)
    if not cols:
        raise GranchainError(f"{what}: table '{df.attrs.get('name', 'table')}' lacks the "
                             "per-particle columns vmax_p01_m_s ...; regenerate it with the "
                             "workflow")
    return cols


def reference_engine(df: pd.DataFrame) -> pd.DataFrame:
    """Rows of the reference engine when a table mixes engines (else all rows)."""
    if "engine" in df.columns and df["engine"].nunique() > 1:
        df = df[df["engine"] == "reference"]
    return df


def arrived(df: pd.DataFrame) -> pd.DataFrame:
    """Members whose wave reached the far probe with a finite v_g."""
    ok = df["wave_arrived"].astype(bool) & np.isfinite(df["v_g_m_s"].astype(float))
    return df[ok]


def materials_in(df: pd.DataFrame) -> list[str]:
    order = list(MATERIAL_LABEL)
    found = list(dict.fromkeys(df["material"]))
    return sorted(found, key=lambda m: (order.index(m) if m in order else len(order), m))


def material(name: str):
    lib = library()
    if name not in lib:
        raise GranchainError(f"material '{name}' of the table is not in granchain/data/"
                             f"materials.yaml; known: {', '.join(lib)}")
    return lib[name]


def label(mat: str) -> str:
    return MATERIAL_LABEL.get(mat, mat)


def color(mat: str) -> str:
    return MATERIAL_COLOR.get(mat, "#2ca02c")


# ---------------------------------------------------------------------------------------
# numbers the figures and the thesis table share (one place each)
# ---------------------------------------------------------------------------------------
def fit_through_origin(x, y) -> float:
    """Least-squares slope of y = a x (the chapter's linear fit of Fig. 5.1b)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return math.nan
    return float(np.dot(x[ok], y[ok]) / np.dot(x[ok], x[ok]))


def vmax_fits(packed: pd.DataFrame) -> dict:
    """{material: {"v_max_1": slope, "v_max_2": slope}} of the packed sweep."""
    require(packed, NEEDS["fig5_1b"], "fig5_1b")
    packed = reference_engine(packed)
    out = {}
    for mat in materials_in(packed):
        d = packed[packed["material"] == mat]
        out[mat] = {c: fit_through_origin(d["v_striker_m_s"], d[c + "_m_s"])
                    for c in ("v_max_1", "v_max_2")}
    return out


def packed_vg(packed: pd.DataFrame, mat: str, v_striker, column: str = "v_g_m_s") -> np.ndarray:
    """Packed chain's v_g (``column``) of ``mat`` at the given striker speeds.

    Exact rows where the packed sweep has that speed (median if repeated); elsewhere
    linear interpolation in log v_g vs log v_s between the sweep's speeds, and outside
    the sweep the power law fitted to its two nearest ends (v_g ~ v_s^(1/5) for Hertz).
    """
    require(packed, NEEDS["packed_reference"] + [column], "packed reference")
    d = arrived(reference_engine(packed))
    d = d[(d["material"] == mat) & np.isfinite(d[column].astype(float))]
    if d.empty:
        raise GranchainError(f"packed reference: no arrived packed-chain row for material "
                             f"'{mat}'; add it to studies.packed_sweep in config/config.yaml")
    g = d.groupby("v_striker_m_s")[column].median()
    xs = np.log(g.index.to_numpy(dtype=float))
    ys = np.log(g.to_numpy(dtype=float))
    q = np.log(np.atleast_1d(np.asarray(v_striker, dtype=float)))
    if xs.size == 1:
        # one speed: Nesterenko's v_g ~ v_m^(1/5) with v_m proportional to v_s
        return np.exp(ys[0] + 0.2 * (q - xs[0]))
    out = np.interp(q, xs, ys)
    lo, hi = q < xs[0], q > xs[-1]
    if lo.any():
        s = (ys[1] - ys[0]) / (xs[1] - xs[0])
        out[lo] = ys[0] + s * (q[lo] - xs[0])
    if hi.any():
        s = (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
        out[hi] = ys[-1] + s * (q[hi] - xs[-1])
    return np.exp(out)


def radius_or_default(radius: float | None) -> float:
    """Sphere radius (m). The tables do not carry it: the caller passes the preset's
    (figures.smk does), else the chapter's 150 um (scene default)."""
    if radius is None:
        return float(DEFAULTS["chain"]["radius"])
    if not (isinstance(radius, (int, float)) and radius > 0):
        raise GranchainError(f"radius {radius!r} must be a positive number of metres")
    return float(radius)


def n_particles(df: pd.DataFrame) -> int:
    cols = vmax_columns(df)
    if cols:
        return len(cols)
    return int(DEFAULTS["chain"]["n"])


def peak_profile(df: pd.DataFrame, what: str, last: int | None = None) -> np.ndarray:
    """(members, particles) of v_max,i / v_s for particles 1..last (default: far probe)."""
    cols = require_vmax(df, what)
    last = PROBES[-1] if last is None else last
    cols = cols[:last]
    return df[cols].to_numpy(dtype=float) / df["v_striker_m_s"].to_numpy(dtype=float)[:, None]


def oscillation(profile: np.ndarray, first: int = PROBES[0]) -> np.ndarray:
    """Relative peak-to-peak spread of v_max along each chain, (max - min)/mean over
    particles first..last of the profile (the striker, particle 1, excluded)."""
    p = np.asarray(profile, dtype=float)[:, first - 1:]
    return (p.max(axis=1) - p.min(axis=1)) / p.mean(axis=1)


def band(values, lo=5.0, hi=95.0):
    """(p_lo, median, p_hi) of finite values, NaNs if none (numpy linear percentiles)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan, math.nan
    p = np.percentile(v, [lo, 50.0, hi])
    return float(p[0]), float(p[1]), float(p[2])


def fmt(x: float, digits: int = 3) -> str:
    return "nan" if not np.isfinite(x) else f"{x:.{digits}g}"


# ---------------------------------------------------------------------------------------
# drawing helpers
# ---------------------------------------------------------------------------------------
def _figure(ncols=1, nrows=1, size=(6.0, 4.0), **kw):
    """A figure outside pyplot (no global backend state; saved through Agg)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=size)
    return fig, fig.subplots(nrows, ncols, **kw)


def _plain_log(ax, which="y", subs=(1.0, 2.0, 3.0, 4.0, 5.0, 7.0)):
    """Log axis labelled with plain numbers at subs x 10^k (no 6x10^2 labels)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    axis = ax.yaxis if which == "y" else ax.xaxis
    axis.set_major_locator(LogLocator(base=10, subs=subs))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def _cmap(name):
    import matplotlib
    return matplotlib.colormaps[name]


def save(fig, out) -> list[Path]:
    """Write ``{out}.png`` and ``{out}.pdf`` without dates or software strings."""
    out = Path(out)
    if out.suffix in (".png", ".pdf"):
        out = out.with_suffix("")
    out.parent.mkdir(parents=True, exist_ok=True)
    png, pdf = Path(f"{out}.png"), Path(f"{out}.pdf")
    fig.savefig(png, metadata={"Software": None})
    fig.savefig(pdf, metadata={"CreationDate": None, "ModDate": None, "Producer": None,
                               "Creator": None})
    return [png, pdf]


def _drawn(func):
    """Run a drawing function inside the fixed style."""
    def wrapper(*args, **kw):
        import matplotlib as mpl
        with mpl.rc_context():
            mpl.rcdefaults()
            mpl.rcParams.update(RC)
            return func(*args, **kw)
    wrapper.__name__ = func.__name__
    wrapper.__doc__ = func.__doc__
    wrapper.__wrapped__ = func
    return wrapper


# ---------------------------------------------------------------------------------------
# the panels
# ---------------------------------------------------------------------------------------
@_drawn
def fig5_1a(trace: dict, out) -> list[Path]:
    """Chapter Fig. 5.1a: velocity of every particle vs time, packed chain, one trace."""
    for k in NEEDS["trace"]:
        if k not in trace:
            raise GranchainError(f"fig5_1a: trace lacks '{k}'; regenerate it with the workflow")
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    t = np.asarray(trace["t_s"], dtype=float) * 1e6
    v = np.asarray(trace["v_m_s"], dtype=float)
    if v.ndim != 2 or v.shape[0] != t.size:
        raise GranchainError(f"fig5_1a: trace v_m_s has shape {v.shape}, expected "
                             f"({t.size}, n); regenerate it with the workflow")
    vs = float(trace["v_striker_m_s"])
    mat = str(trace["material"])
    n = v.shape[1]
    fig, ax = _figure(size=(6.4, 4.0))
    cmap = _cmap("viridis")
    for i in range(n):
        ax.plot(t, v[:, i] * 1e3, color=cmap(i / max(n - 1, 1)), lw=1.0)
    vmax = v.max(axis=0)
    p1, p2 = PROBES
    if n >= p2:
        for p, dx, ha in ((p1, 8, "left"), (p2, -6, "right")):
            j = int(np.argmax(v[:, p - 1]))
            ax.annotate(f"particle {p}: v_max = {vmax[p - 1] / vs:.3f} v_s",
                        xy=(t[j], vmax[p - 1] * 1e3), xytext=(dx, 12),
                        textcoords="offset points", ha=ha, fontsize=7.5,
                        arrowprops={"arrowstyle": "-", "lw": 0.6})
    # particles whose peak lies at the trace's end were cut off by the run's end time
    cut = [i + 1 for i in range(n) if int(np.argmax(v[:, i])) >= t.size - 2 or vmax[i] <= 0]
    note = (f"\ntrace ends before particle{'s' if len(cut) > 1 else ''} "
            f"{', '.join(map(str, cut))} peak{'' if len(cut) > 1 else 's'} (the run stops "
            "before the wave has crossed the chain)") if cut else ""
    sm = ScalarMappable(cmap=cmap, norm=Normalize(1, n))
    cb = fig.colorbar(sm, ax=ax, pad=0.02)
    cb.set_label("particle index (1 = striker)")
    ax.set_xlabel("time t (us)")
    ax.set_ylabel("particle velocity (mm/s)")
    ax.set_xlim(t[0], t[-1])
    ax.set_title(f"Packed {label(mat)} chain, n = {n}, striker v_s = {vs:g} m/s "
                 f"(chapter Fig. 5.1a)" + note, fontsize=8.5)
    fig.tight_layout()
    return save(fig, out)


def _material_style(mat: str, k: int) -> dict:
    """Marker style per material: later materials drawn smaller and filled on top of
    earlier hollow ones, so identical data (Hertz scaling) stays visible for both."""
    big = k == 0
    return {"ms": 8 if big else 4, "mew": 1.3 if big else 1.0,
            "mfc": "none" if big else color(mat), "mec": color(mat)}


@_drawn
def fig5_1b(packed: pd.DataFrame, out) -> list[Path]:
    """Chapter Fig. 5.1b: v_max,1 and v_max,2 vs v_s, both materials, fit through 0."""
    from matplotlib.legend_handler import HandlerTuple
    from matplotlib.patches import Patch
    fits = vmax_fits(packed)
    packed = reference_engine(packed)
    fig, (ax, ax2) = _figure(ncols=2, size=(10.0, 4.2))
    p1, p2 = PROBES
    marker = {"v_max_1": "o", "v_max_2": "s"}
    ls = {"v_max_1": "-", "v_max_2": "--"}
    vmax_all = vmax_columns(packed)
    xs_max = float(packed["v_striker_m_s"].max())
    xx = np.linspace(0.0, xs_max * 1.05, 50)
    handles, labels = [], []
    for k, (mat, fit) in enumerate(fits.items()):
        st = _material_style(mat, k)
        lw = 2.2 if k == 0 else 0.9
        alpha = 0.45 if k == 0 else 1.0
        d = packed[packed["material"] == mat].sort_values("v_striker_m_s")
        x = d["v_striker_m_s"].to_numpy(dtype=float)
        for c in ("v_max_1", "v_max_2"):
            y = d[c + "_m_s"].to_numpy(dtype=float)
            a = fit[c]
            h1, = ax.plot(x, y, marker[c], ls="none", color=color(mat), **st)
            h2, = ax.plot(xx, a * xx, ls[c], color=color(mat), lw=lw, alpha=alpha)
            handles.append((h1, h2))
            labels.append(f"{label(mat)} v_max,{c[-1]} (particle {p1 if c == 'v_max_1' else p2}):"
                          f" fit {a:.4f} v_s")
            ax2.plot(x, y / x, marker[c], ls=ls[c], color=color(mat), lw=lw * 0.6,
                     alpha=1.0, **st)
        if vmax_all:
            prof = peak_profile(d, "fig5_1b")[:, p1 - 1:]
            ax2.fill_between(x, prof.min(axis=1), prof.max(axis=1), color=color(mat),
                             alpha=0.10, lw=0)
    hc, = ax.plot(xx, CHAPTER_VMAX_SLOPE * xx, ":", color="0.35", lw=1.0)
    handles.append(hc)
    labels.append(f"chapter fit v_max = {CHAPTER_VMAX_SLOPE} v_s")
    ax.legend(handles, labels, handler_map={tuple: HandlerTuple(ndivide=None)},
              loc="upper left", handlelength=3.0)
    ax.set_xlim(0, xs_max * 1.05)
    ax.set_ylim(0, None)
    ax.set_xlabel("striker velocity v_s (m/s)")
    ax.set_ylabel("maximum particle velocity v_max (m/s)")
    ax.set_title("v_max vs v_s, packed chains; least-squares fits through the origin")
    ax2.axhline(CHAPTER_VMAX_SLOPE, ls=":", color="0.35", lw=1.0)
    h2 = [Patch(color=color(m), alpha=0.25, label=f"{label(m)}: range of v_max,i / v_s, "
                f"particles {p1}..{p2}") for m in fits]
    h2.append(ax2.plot([], [], ":", color="0.35", label="chapter 0.64")[0])
    ax2.legend(handles=h2, loc="lower right")
    ax2.set_xscale("log")
    _plain_log(ax2, "x", subs=(1.0, 2.0, 5.0))
    ax2.set_xlabel("striker velocity v_s (m/s), log scale")
    ax2.set_ylabel("v_max / v_s")
    ax2.set_title("normalised (markers as left): flat = linear law")
    ax2.set_ylim(0.45, 0.8)
    if len(fits) > 1:
        same = max(abs(fits[m]["v_max_1"] / next(iter(fits.values()))["v_max_1"] - 1)
                   for m in fits)
        ax2.text(0.02, 0.50, f"materials differ by at most {same:.1e} (relative) in the\n"
                 "v_max,1 slope: v_max / v_s does not depend on E, rho (Hertz scaling)",
                 transform=ax2.transAxes, fontsize=7, va="top", color="0.25")
    fig.suptitle("Chapter Fig. 5.1b counterpart", fontsize=9)
    fig.tight_layout()
    return save(fig, out)


@_drawn
def fig5_1c(packed: pd.DataFrame, out) -> list[Path]:
    """Chapter Fig. 5.1c: v_g vs v_s with Nesterenko's curve at v_m = slope * v_s."""
    require(packed, NEEDS["fig5_1c"], "fig5_1c")
    fits = vmax_fits(packed)
    packed = reference_engine(packed)
    fig, (ax, axr) = _figure(nrows=2, size=(6.4, 5.2), sharex=True,
                             gridspec_kw={"height_ratios": [3, 1.3]})
    vmin = float(packed["v_striker_m_s"].min())
    vmax = float(packed["v_striker_m_s"].max())
    xx = np.geomspace(vmin / 1.3, vmax * 1.3, 100)
    for k, mat in enumerate(fits):
        st = _material_style(mat, k)
        m = material(mat)
        d = arrived(packed[packed["material"] == mat]).sort_values("v_striker_m_s")
        a = fits[mat]["v_max_2"]
        x = d["v_striker_m_s"].to_numpy(dtype=float)
        y = d["v_g_m_s"].to_numpy(dtype=float)
        ax.plot(x, y, "o", ls="none", color=color(mat), **st,
                label=f"{label(mat)} simulated v_g (Eq. 5.1)")
        ax.plot(xx, nesterenko_speed(m, a * xx), "-", color=color(mat), lw=0.9,
                label=f"{label(mat)} Nesterenko, v_m = {a:.4f} v_s (fit of 5.1b)")
        ax.plot(xx, nesterenko_speed(m, CHAPTER_VMAX_SLOPE * xx), ":", color=color(mat),
                lw=0.9, label=f"{label(mat)} Nesterenko, v_m = 0.64 v_s (chapter)")
        axr.plot(x, y / nesterenko_speed(m, a * x), "o-", color=color(mat), lw=0.8, **st,
                 label=f"{label(mat)}: v_g / fit curve")
        axr.plot(x, y / nesterenko_speed(m, CHAPTER_VMAX_SLOPE * x), "^:", color=color(mat),
                 lw=0.8, **st, label=f"{label(mat)}: v_g / 0.64 curve")
    ax.set_xscale("log")
    ax.set_yscale("log")
    _plain_log(ax, "y")
    ax.set_ylabel("group velocity v_g (m/s), log scale")
    ax.set_title("v_g vs v_s, packed chains, with Nesterenko's solitary-wave speed\n"
                 "(chapter Fig. 5.1c counterpart)")
    ax.legend(loc="upper left")
    axr.axhline(1.0, color="0.3", lw=0.8)
    axr.set_xscale("log")
    _plain_log(axr, "x", subs=(1.0, 2.0, 5.0))
    axr.set_xlabel("striker velocity v_s (m/s), log scale")
    axr.set_ylabel("v_g / Nesterenko")
    axr.legend(loc="best", ncol=2, fontsize=6.5)
    fig.tight_layout()
    return save(fig, out)


def _packed_profile(packed: pd.DataFrame, mat: str, vs: float, what: str):
    """v_max,i / v_s of the packed chain of ``mat`` at the speed closest to ``vs``."""
    d = reference_engine(packed)
    d = d[d["material"] == mat]
    if d.empty or not vmax_columns(d):
        return None, None
    speeds = d["v_striker_m_s"].to_numpy(dtype=float)
    k = int(np.argmin(np.abs(np.log(speeds / vs))))
    row = d.iloc[[k]]
    return peak_profile(row, what, last=n_particles(row))[0], float(speeds[k])


@_drawn
def fig5_3b(gap_profile: pd.DataFrame, packed: pd.DataFrame | None, out) -> list[Path]:
    """Chapter Fig. 5.3b: v_max,i / v_s along a chain with random gaps (20 nm mean)."""
    require(gap_profile, NEEDS["fig5_3b"], "fig5_3b")
    d = reference_engine(gap_profile)
    mats = materials_in(d)
    prof = peak_profile(d, "fig5_3b", last=n_particles(d))   # every particle's peak is measured
    n_show = prof.shape[1]
    idx = np.arange(1, n_show + 1)
    p1, p2 = PROBES
    osc = oscillation(prof[:, :p2])      # the chapter's stretch, clear of the free chain end
    fig, ax = _figure(size=(6.4, 4.2))
    for row in prof:
        ax.plot(idx, row, "-", color="0.55", lw=0.5, alpha=0.35)
    lo, med, hi = np.nanpercentile(prof, [5, 50, 95], axis=0)
    gaps = ", ".join(f"{g:g}" for g in sorted(set(d["gap_mean_nm"].astype(float))))
    vss = sorted(set(d["v_striker_m_s"].astype(float)))
    ax.fill_between(idx, lo, hi, color="#e377c2", alpha=0.3, lw=0,
                    label=f"5-95% over {len(prof)} realisations")
    ax.plot(idx, med, "o-", color="#8c1d6b", label="median over realisations")
    ax.plot([], [], "-", color="0.55", lw=0.5, label="single realisations")
    first = d["realisation"].astype(int).to_numpy().argmin()
    ax.plot(idx, prof[first], "-", color="#1f77b4", lw=1.0,
            label=f"realisation {int(d['realisation'].iloc[first])} (one chain)")
    packed_txt = ""
    if packed is not None:
        for mat in mats:
            p, vs_ref = _packed_profile(packed, mat, vss[0], "fig5_3b")
            if p is not None:
                ax.plot(idx[:p.size], p[:n_show], "s-", color="k", mfc="none",
                        label=f"packed {label(mat)} chain (v_s = {vs_ref:g} m/s)")
                packed_txt = (f"\npacked chain on the same measure: "
                              f"{oscillation(p[None, :p2])[0]:.1%} (monotone decay)")
    o_lo, o_med, o_hi = band(osc)
    ax.text(0.98, 0.04,
            f"spread along the chain, (max - min)/mean of v_max,i, i = {p1}..{p2}:\n"
            f"median {o_med:.1%} (5-95%: {o_lo:.1%} - {o_hi:.1%})  [chapter: ~20%]"
            + packed_txt,
            transform=ax.transAxes, ha="right", va="bottom", fontsize=7.5,
            bbox={"boxstyle": "round", "fc": "white", "ec": "0.7"})
    ax.set_xlabel(f"particle index (1 = striker, {n_show} = the free end)")
    ax.set_ylabel("peak velocity v_max,i / v_s")
    ax.set_xticks(idx)
    ax.set_ylim(0.4, 1.1)
    ax.set_title(f"{'/'.join(label(m) for m in mats)} chain with random gaps, mean {gaps} nm, "
                 f"v_s = {', '.join(f'{v:g}' for v in vss)} m/s\n(chapter Fig. 5.3b counterpart)")
    ax.legend(loc="lower left")
    fig.tight_layout()
    return save(fig, out)


@_drawn
def fig5_3c(gap_sweep: pd.DataFrame, packed: pd.DataFrame, out, radius=None) -> list[Path]:
    """Chapter Fig. 5.3c: v_g vs v_s for each mean gap, bands, packed curve, Eq. 5.4."""
    require(gap_sweep, NEEDS["fig5_3c"], "fig5_3c")
    require(packed, NEEDS["packed_reference"], "fig5_3c packed reference")
    d = reference_engine(gap_sweep)
    mats = materials_in(d)
    gaps = sorted(set(d["gap_mean_nm"].astype(float)))
    radius = radius_or_default(radius)
    cmap = _cmap("viridis")
    gcol = {g: cmap(0.9 * k / max(len(gaps) - 1, 1)) for k, g in enumerate(gaps)}
    fig, axes = _figure(ncols=len(mats), size=(max(5.0 * len(mats), 6.4), 5.6),
                        sharey=True, squeeze=False)
    vall = np.array(sorted(set(d["v_striker_m_s"].astype(float))))
    xx = np.geomspace(vall.min(), vall.max(), 60) if vall.size > 1 else vall
    for ax, mat in zip(axes[0], mats):
        dm = d[d["material"] == mat]
        pk = packed[(packed["material"] == mat)]
        pa = arrived(reference_engine(pk)).sort_values("v_striker_m_s")
        ax.plot(pa["v_striker_m_s"], pa["v_g_m_s"], "o-", color="k", lw=1.6, ms=3.5,
                label="packed chain (gap = 0)", zorder=5)
        vg0 = packed_vg(packed, mat, xx)
        missing = []
        for g in gaps:
            dg = dm[dm["gap_mean_nm"].astype(float) == g]
            if dg.empty:
                continue
            ok = arrived(dg)
            nfail = len(dg) - len(ok)
            if nfail:
                missing.append(f"{g:g} nm: {nfail}/{len(dg)}")
            st = ok.groupby("v_striker_m_s")["v_g_m_s"]
            if len(ok):
                x = np.array(sorted(st.groups), dtype=float)
                q = np.array([band(st.get_group(v)) for v in x])
                ax.fill_between(x, q[:, 0], q[:, 2], color=gcol[g], alpha=0.28, lw=0)
                ax.plot(x, q[:, 1], "-", color=gcol[g], lw=1.0)
            ax.plot(xx, eq54_group_velocity(vg0, g * 1e-9, xx, radius), "--", color=gcol[g],
                    lw=0.9)
        ax.set_xscale("log")
        ax.set_yscale("log")
        _plain_log(ax, "x", subs=(1.0, 2.0, 5.0))
        ax.set_xlabel("striker velocity v_s (m/s), log scale")
        nr = int(dm.groupby(["gap_mean_nm", "v_striker_m_s"]).size().max())
        note = ("not arrived (excluded): " + "; ".join(missing)) if missing else \
            "every member arrived"
        ax.set_title(f"{label(mat)}: up to {nr} realisations per (gap, v_s)\n{note}",
                     fontsize=7.5)
    axes[0][0].set_ylabel("group velocity v_g (m/s), log scale")
    _plain_log(axes[0][0], "y", subs=(1.0, 2.0, 5.0))
    # legend: gap colours + line styles, in the empty lower-right corner
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    handles = [Line2D([], [], color="k", marker="o", ms=3.5, lw=1.6, label="packed chain")]
    handles += [Patch(color=gcol[g], alpha=0.5, label=f"mean gap {g:g} nm") for g in gaps]
    handles += [Line2D([], [], color="0.3", lw=1.0, label="median over realisations"),
                Patch(color="0.6", alpha=0.5, label="5-95% of arrived realisations"),
                Line2D([], [], color="0.3", ls="--", lw=0.9,
                       label="Eq. 5.4 bound at the mean gap")]
    ncol = min(len(handles), 5 if len(mats) > 1 else 3)
    nrow = -(-len(handles) // ncol)
    fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=7)
    fig.suptitle("v_g vs v_s with random gaps (chapter Fig. 5.3c counterpart)", fontsize=9)
    fig.tight_layout(rect=(0, 0.032 * nrow + 0.01, 1, 1))
    return save(fig, out)


@_drawn
def fig5_4b(extra: pd.DataFrame, packed: pd.DataFrame, out, radius=None) -> list[Path]:
    """Chapter Fig. 5.4b: v_g vs gbar = extra_length/(n-1) at fixed v_s, with Eq. 5.4."""
    require(extra, NEEDS["fig5_4b"], "fig5_4b")
    require(packed, NEEDS["packed_reference"], "fig5_4b packed reference")
    d = reference_engine(extra)
    mats = materials_in(d)
    n = n_particles(d)
    radius = radius_or_default(radius)
    fig, axes = _figure(ncols=len(mats), size=(max(4.6 * len(mats), 6.4), 4.4),
                        sharey=True, squeeze=False)
    for ax, mat in zip(axes[0], mats):
        dm = d[d["material"] == mat]
        vss = sorted(set(dm["v_striker_m_s"].astype(float)))
        ok = arrived(dm)
        nfail = len(dm) - len(ok)
        gb = ok["extra_length_um"].to_numpy(dtype=float) * 1e3 / (n - 1)
        ax.plot(gb, ok["v_g_m_s"], "o", color=color(mat), alpha=0.45, ms=3, mew=0,
                label="single realisations at gbar = extra/" + str(n - 1))
        if "gap_mean_probes_nm" in ok.columns:
            ax.plot(ok["gap_mean_probes_nm"], ok["v_g_m_s"], "x", color="0.45", ms=3.5,
                    mew=0.7, label=f"same, at their realised gbar between\n"
                                   f"probes {PROBES[0]} and {PROBES[1]}")
        st = ok.groupby("extra_length_um")["v_g_m_s"]
        xs = np.array(sorted(st.groups), dtype=float)
        if xs.size:
            q = np.array([band(st.get_group(v)) for v in xs])
            ax.errorbar(xs * 1e3 / (n - 1), q[:, 1], yerr=[q[:, 1] - q[:, 0], q[:, 2] - q[:, 1]],
                        fmt="o", color="k", mfc=color(mat), capsize=3, lw=0.9,
                        label="median, 5-95%")
        span = np.asarray(sorted(set(dm["extra_length_um"].astype(float)))) * 1e3 / (n - 1)
        if "gap_mean_probes_nm" in ok.columns and len(ok):
            span = np.concatenate([span, ok["gap_mean_probes_nm"].to_numpy(dtype=float)])
        gg = np.linspace(span.min() * 0.9, span.max() * 1.05, 80)
        for vs in vss:
            vg0 = float(packed_vg(packed, mat, vs)[0])
            ax.plot(gg, eq54_group_velocity(vg0, gg * 1e-9, vs, radius), "--", color="0.2",
                    lw=1.0, label=f"Eq. 5.4 bound (v_s = {vs:g} m/s,\npacked v_g = {vg0:.0f} m/s)")
        ax.set_xlim(gg[0], gg[-1])
        sec = ax.secondary_xaxis("top", functions=(lambda g: g * (n - 1) / 1e3,
                                                   lambda L: L * 1e3 / (n - 1)))
        sec.set_xlabel("extra chain length (um)")
        ax.set_xlabel(f"mean gap gbar (nm); nominal: extra length / {n - 1}")
        nr = int(dm.groupby(["extra_length_um", "v_striker_m_s"]).size().max())
        ax.set_title(f"{label(mat)}, v_s = {', '.join(f'{v:g}' for v in vss)} m/s, up to "
                     f"{nr} realisations per length" +
                     (f"\nnot arrived (excluded): {nfail}/{len(dm)}" if nfail else ""),
                     fontsize=8)
        ax.legend(loc="lower left")
        ax.set_ylim(0, None)
    axes[0][0].set_ylabel("group velocity v_g (m/s)")
    fig.suptitle("Loose chains: v_g vs mean gap from the extra length\n"
                 "(chapter Fig. 5.4b counterpart)", fontsize=9)
    fig.tight_layout()
    return save(fig, out)


# ---------------------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------------------
FIGURES = {
    "fig5_1a": (fig5_1a, ["trace"]),
    "fig5_1b": (fig5_1b, ["packed_sweep"]),
    "fig5_1c": (fig5_1c, ["packed_sweep"]),
    "fig5_3b": (fig5_3b, ["gap_profile", "packed_sweep"]),
    "fig5_3c": (fig5_3c, ["gap_sweep", "packed_sweep"]),
    "fig5_4b": (fig5_4b, ["extra_length", "packed_sweep"]),
}


def render(name: str, paths: dict, out, radius: float | None = None) -> list[Path]:
    """Draw figure ``name`` from {study: path} (trace: npz path) into ``out``.{png,pdf};
    ``radius`` (m) for the figures that draw Eq. 5.4."""
    if name not in FIGURES:
        raise GranchainError(f"unknown figure '{name}'; use one of {', '.join(FIGURES)}")
    func, needs = FIGURES[name]
    args = []
    for study in needs:
        p = paths.get(study)
        if p is None:
            flag = "--" + study.replace("_", "-")
            raise GranchainError(f"{name}: needs {flag} (the {study} "
                                 f"{'npz' if study == 'trace' else 'table'})")
        args.append(read_trace(p) if study == "trace" else read_table(p))
    if name in ("fig5_3c", "fig5_4b"):
        return func(*args, out, radius=radius)
    return func(*args, out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m granchain.figures",
                                 description="Draw one of the chapter's figures from the "
                                             "workflow's tables (PNG and PDF).")
    ap.add_argument("name", help=", ".join(FIGURES))
    for study in ("packed_sweep", "gap_profile", "gap_sweep", "extra_length"):
        ap.add_argument("--" + study.replace("_", "-"), dest=study,
                        help=f"results/<preset>/tables/{study}.csv")
    ap.add_argument("--trace", help="results/<preset>/traces/packed_trace_<material>.npz")
    ap.add_argument("--radius", type=float, help="sphere radius in m for Eq. 5.4 (default "
                    "the chapter's 150e-6; the tables do not carry it)")
    ap.add_argument("--out", required=True, help="output path (.png/.pdf or no extension)")
    a = ap.parse_args(argv)
    paths = {k: v for k, v in vars(a).items() if k not in ("name", "out", "radius") and v}
    try:
        for p in render(a.name, paths, a.out, a.radius):
            print(p)
    except GranchainError as exc:
        print(f"granchain.figures: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
