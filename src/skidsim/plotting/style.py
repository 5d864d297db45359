"""One figure style for the whole project."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

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
    """Context manager yielding ``(fig, axes)``; on exit saves to ``path`` (PNG) atomically and closes.

    The file is written through :func:`skidsim.atomic.atomic_path`, so a failed figure leaves nothing behind.
    """
    with plt.rc_context(RC):
        fig, axes = plt.subplots(nrows, ncols, figsize=figsize, **kw)
        try:
            yield fig, axes
            if path is not None:
                fig.tight_layout()
                with atomic_path(path, suffix=".png") as tmp:
                    fig.savefig(tmp, format="png")
        finally:
            plt.close(fig)
