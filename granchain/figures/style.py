"""Drawing helpers shared by the chapter's figures: fixed style, colours, axes, saving.

Output is deterministic: fixed rcParams (matplotlib defaults + :data:`RC`, whatever the
user's matplotlibrc says), no dates or software strings in PNG/PDF metadata, so a rerun
on the same tables gives byte-identical files.
"""
from __future__ import annotations

from pathlib import Path

MATERIAL_COLOR = {"ss316": "#1f77b4", "ss440c": "#d62728"}

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


def color(mat: str) -> str:
    """Line colour of a material (green for one without its own)."""
    return MATERIAL_COLOR.get(mat, "#2ca02c")


def material_style(mat: str, k: int) -> dict:
    """Marker style per material: later materials drawn smaller and filled on top of
    earlier hollow ones, so identical data (Hertz scaling) stays visible for both."""
    big = k == 0
    return {"ms": 8 if big else 4, "mew": 1.3 if big else 1.0,
            "mfc": "none" if big else color(mat), "mec": color(mat)}


def figure(ncols=1, nrows=1, size=(6.0, 4.0), **kw):
    """A figure outside pyplot (no global backend state; saved through Agg)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=size)
    return fig, fig.subplots(nrows, ncols, **kw)


def plain_log(ax, which="y", subs=(1.0, 2.0, 3.0, 4.0, 5.0, 7.0)):
    """Log axis labelled with plain numbers at subs x 10^k (no 6x10^2 labels)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    axis = ax.yaxis if which == "y" else ax.xaxis
    axis.set_major_locator(LogLocator(base=10, subs=subs))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def colormap(name):
    """A registered matplotlib colormap."""
    import matplotlib
    return matplotlib.colormaps[name]


def figure_paths(out) -> list[Path]:
    """The files a figure drawn into ``out`` is written to: ``{out}.png`` and
    ``{out}.pdf`` (a .png or .pdf suffix of ``out`` dropped first)."""
    out = Path(out)
    if out.suffix in (".png", ".pdf"):
        out = out.with_suffix("")
    return [Path(f"{out}.png"), Path(f"{out}.pdf")]


def save(fig, out) -> list[Path]:
    """Write ``{out}.png`` and ``{out}.pdf`` (:func:`figure_paths`) without dates or
    software strings."""
    png, pdf = figure_paths(out)
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, metadata={"Software": None})
    fig.savefig(pdf, metadata={"CreationDate": None, "ModDate": None, "Producer": None,
                               "Creator": None})
    return [png, pdf]


def drawn(func):
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
