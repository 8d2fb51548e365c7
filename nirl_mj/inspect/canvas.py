"""Matplotlib figures drawn without pyplot: nothing global changes (no backend is chosen, no figure
is registered), so importing nirl_mj in a notebook or a GUI program leaves its plotting as it was.
Each figure draws on an Agg canvas of its own, for files and arrays alike, and is freed with its last
reference (no ``close`` to forget)."""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def figure(**kwargs: Any) -> Figure:
    """A new figure on its own Agg canvas (``kwargs``: :class:`matplotlib.figure.Figure`'s, e.g.
    ``figsize`` in inches, ``dpi``)."""
    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def subplots(*grid: int, figsize: tuple[float, float] | None = None, dpi: float | None = None,
             **kwargs: Any) -> tuple[Figure, Any]:  # fmt: skip
    """``pyplot.subplots`` without pyplot: the figure and its axes (``grid``: rows, columns;
    ``kwargs``: :meth:`matplotlib.figure.Figure.subplots`'s, e.g. ``squeeze``)."""
    fig = figure(figsize=figsize, dpi=dpi)
    return fig, fig.subplots(*grid, **kwargs)


def to_rgb(fig: Figure) -> np.ndarray:
    """``fig`` drawn, as an (H, W, 3) uint8 image (pixels of its Agg canvas)."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
