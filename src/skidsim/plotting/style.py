"""One figure style for the whole project.

Figures are drawn on matplotlib's Agg canvas without pyplot (no figure manager, no global figure registry),
and matplotlib is imported on the first figure: a module that only defines figures costs nothing to import."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

from skidsim.atomic import atomic_path

RC = {
    "figure.dpi": 110,
    "savefig.dpi": 130,
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "image.cmap": "viridis",
}

#: Colours for the study's method and ours, and for bands.
COLORS = {
    "study": "#d95f02",
    "ours": "#1b9e77",
    "measured": "#333333",
    "raw": "#7570b3",
    "macro": "#1b9e77",
    "micro": "#d95f02",
}


@contextmanager
def figure(path: str | Path | None = None, *, nrows: int = 1, ncols: int = 1, figsize=(6.0, 4.0), **kw):
    """Context manager yielding ``(fig, axes)`` (``**kw`` go to ``Figure.subplots``: squeeze, sharex,
    gridspec_kw, ...); on exit saves to ``path`` (PNG) atomically.

    The file is written through :func:`skidsim.atomic.atomic_path`, so a failed figure leaves nothing behind. The
    figure belongs to no pyplot registry: there is nothing to close, it is freed with its last reference.
    """
    _import_matplotlib()
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    with matplotlib.rc_context(RC):
        fig = Figure(figsize=figsize)
        FigureCanvasAgg(fig)
        axes = fig.subplots(nrows, ncols, **kw)
        yield fig, axes
        if path is not None:
            fig.tight_layout()
            # tight_layout leaves a placeholder layout engine, for which savefig draws the figure once more
            # (renderer disabled) before drawing it; the layout is done, so no engine: the same pixels, one draw
            fig.set_layout_engine(None)
            with atomic_path(path, suffix=".png") as tmp:
                fig.savefig(tmp, format="png")


def _import_matplotlib() -> None:
    """Import matplotlib's Agg canvas, Figure and the 3-D axes, without building the property tables of the
    ``Artist.set`` docstrings (``matplotlib.artist.kwdoc``, called for every Artist subclass as it is defined):
    about 0.1 s of the start-up of every figure step, docstrings only (not one pixel changes). The original
    ``kwdoc`` is put back at once; a process that imported matplotlib before keeps its docstrings."""
    import sys

    if "matplotlib.figure" in sys.modules:
        return
    import matplotlib.artist as artist

    kwdoc = getattr(artist, "kwdoc", None)
    if kwdoc is not None:
        artist.kwdoc = lambda _artist: ""
    try:
        import matplotlib.backends.backend_agg
        import matplotlib.figure  # noqa: F401
        import mpl_toolkits.mplot3d  # noqa: F401
    finally:
        if kwdoc is not None:
            artist.kwdoc = kwdoc
