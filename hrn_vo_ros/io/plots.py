"""Trajectory plots of a calibrated estimate against the ground truth (matplotlib, Agg).

Public API:

* :func:`plot_evaluation(result, out, *, title=None, states=None) <plot_evaluation>` — one PNG:
  the three evaluated quantities over time (ground truth, estimate, calibration segment and
  evaluated part shaded), the per-sample error (with the tracking states, when given, shaded:
  degraded yellow, lost red), and a top view (pan/tilt or x/y plane).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use('Agg')

from matplotlib.axes import Axes
from matplotlib.backend_bases import FigureCanvasBase
import matplotlib.pyplot as plt
import numpy as np

from hrn_vo_ros.core.evaluation.series import EvalResult
from hrn_vo_ros.errors import ConfigError

_GT = '#d95f02'
_EST = '#1b6ac9'
_CAL = '#9ecae1'
_TEST = '#e5e5e5'
_STATE_COLORS = {'degraded': '#fee391', 'lost': '#fb6a4a'}


def _spans(ax: Axes, t: np.ndarray, mask: np.ndarray, color: str, label: str | None) -> None:
    """Shade the time ranges where ``mask`` holds (contiguous runs)."""
    if not np.any(mask):
        return
    idx = np.flatnonzero(mask)
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], [idx[-1]]])
    for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
        ax.axvspan(t[a], t[b], color=color, alpha=0.5, lw=0, label=label if k == 0 else None,
                   zorder=0)


DEFAULT_NAME = 'trajectory.png'
"""The file name :func:`plot_evaluation` writes into a folder given as its output."""

_FORMATS = frozenset(FigureCanvasBase.get_supported_filetypes())


def plot_path(out: Path | str) -> Path:
    """Where :func:`plot_evaluation` writes for ``out``: ``out / DEFAULT_NAME`` when ``out`` is
    an existing folder, else ``out`` itself."""
    out = Path(out)
    return out / DEFAULT_NAME if out.is_dir() else out


def plot_evaluation(result: EvalResult, out: Path | str, *, title: str | None = None,
                    states: Sequence[str] | None = None) -> Path:
    """Write a PNG of the calibrated estimate against the ground truth.

    Args:
        result: An :class:`~hrn_vo_ros.core.evaluation.protocol.EvalResult`.
        out: Image path (parent folders are created), written exactly there: the format
            follows the suffix (PNG without one); an existing folder gets
            :data:`DEFAULT_NAME` inside it.
        title: Figure title (default: kind and headline metrics).
        states: The tracking state of every sample of ``result.series`` (``tracking``,
            ``degraded``, ``lost``), shaded on the error panel; None: not shown.

    Returns:
        The written path.

    Raises:
        ConfigError: for a suffix that is no image format matplotlib writes.
    """
    s = result.series
    out = plot_path(out)
    fmt = out.suffix[1:].lower() or 'png'
    if fmt not in _FORMATS:
        raise ConfigError(f'{out}: {out.suffix} is no image format matplotlib writes; use '
                          f'one of {", ".join("." + f for f in sorted(_FORMATS))}')
    out.parent.mkdir(parents=True, exist_ok=True)
    fig = plt.figure(figsize=(13, 8.5), dpi=110)
    gs = fig.add_gridspec(4, 2, width_ratios=(2.3, 1), hspace=0.12, wspace=0.18)
    axes = [fig.add_subplot(gs[i, 0]) for i in range(4)]
    for ax in axes[1:]:
        ax.sharex(axes[0])
    for i in range(3):
        ax = axes[i]
        _spans(ax, s.t_s, s.calib, _CAL, 'calibration' if i == 0 else None)
        _spans(ax, s.t_s, s.test & ~s.calib, _TEST, 'evaluated' if i == 0 else None)
        ax.plot(s.t_s, s.gt[:, i], color=_GT, lw=1.4, label='ground truth' if i == 0 else None)
        ax.plot(s.t_s, s.est[:, i], color=_EST, lw=0.9, label='estimate' if i == 0 else None)
        ax.set_ylabel(f'{s.labels[i]} ({s.units[i]})')
        ax.grid(alpha=0.3)
        ax.tick_params(labelbottom=False)
    axes[0].legend(loc='upper left', ncol=4, fontsize=8, framealpha=0.9)
    ax = axes[3]
    _spans(ax, s.t_s, s.calib, _CAL, None)
    _spans(ax, s.t_s, s.test & ~s.calib, _TEST, None)
    if states is not None and len(states) == len(s.t_s):
        st = np.asarray(list(states))
        for name, color in _STATE_COLORS.items():
            _spans(ax, s.t_s, st == name, color, name)
    ax.plot(s.t_s, s.err, color='#444444', lw=0.8)
    med = float(np.median(s.err[s.test])) if np.any(s.test) else float('nan')
    ax.axhline(med, color='#c51b7d', lw=1, ls='--', label=f'median (evaluated) {med:.3g}')
    ax.set_ylabel(f'error, {s.err_label}')
    ax.set_xlabel('time (s)')
    ax.grid(alpha=0.3)
    ax.legend(loc='upper left', fontsize=8)
    top = np.percentile(s.err, 99) if len(s.err) else 1.0
    ax.set_ylim(0, max(top * 1.2, 1e-6))

    _side_panels(fig, gs, result)
    if title is None:
        head = next(iter(result.metrics.items()), ('', float('nan')))
        title = f'{result.kind}: {head[0]} = {head[1]:.3g}'
    fig.suptitle(title, fontsize=12)
    fig.savefig(out, bbox_inches='tight', format=fmt)
    plt.close(fig)
    return out


def _side_panels(fig: Any, gs: Any, result: EvalResult) -> None:
    """The top view of both trajectories and the protocol's figures beside the time series."""
    s = result.series
    right = gs[:, 1].subgridspec(2, 1, height_ratios=(3.0, 1.2), hspace=0.32)
    top_ax = fig.add_subplot(right[0])
    top_ax.plot(s.gt[:, 0], s.gt[:, 1], color=_GT, lw=1.2, label='ground truth')
    top_ax.plot(s.est[:, 0], s.est[:, 1], color=_EST, lw=0.7, alpha=0.85, label='estimate')
    top_ax.plot(s.gt[0, 0], s.gt[0, 1], 'ko', ms=4, label='start')
    top_ax.set_xlabel(f'{s.labels[0]} ({s.units[0]})')
    top_ax.set_ylabel(f'{s.labels[1]} ({s.units[1]})')
    top_ax.set_aspect('equal', adjustable='datalim')
    top_ax.grid(alpha=0.3)
    top_ax.legend(fontsize=8, loc='best')
    top_ax.set_title('top view', fontsize=10)

    txt_ax = fig.add_subplot(right[1])
    txt_ax.axis('off')
    lines = [f'lag {result.lag_s * 1e3:+.1f} ms, roll corr {result.roll_corr:.3f}',
             f'calibration: {result.calibration.get("segment", "")}']
    for k, v in result.metrics.items():
        lines.append(f'{k} = {v:.4g}')
    txt_ax.text(0, 1, '\n'.join(lines[:9]), va='top', ha='left', fontsize=8.5,
                family='monospace')
