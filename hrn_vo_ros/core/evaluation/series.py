"""Types and constants of the evaluation: raw estimates in, metrics and plot series out.

* :class:`EstimateSeries`: the raw readouts of the network or the baseline (t, h, v, r[, z]);
* :class:`KindResult`: what one kind's metric function returns (metrics, calibration, series);
* :class:`EvalSeries`, :class:`EvalResult`: the outcome of
  :func:`~hrn_vo_ros.core.evaluation.protocol.evaluate`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
EvalKind = Literal['rotation', 'translation', 'arm']
EVAL_KINDS = ('rotation', 'translation', 'arm')
CALIB_MODES = ('last10', 'full')
MIN_SAMPLES = 20
"""Fewest estimates accepted in the input, the calibration segment and the evaluated part."""
TRAIN_FRACTION = 0.7
"""Share of the ground-truth lines in the training part (the rest is the test part)."""
ARM_FIRST_ARC_S = 5.0
"""The arm's calibration segment ends this long after the first ground-truth pose."""
LAG_WINDOWS = ('run', 'training')
"""Where the lag is searched: the whole run (the protocol) or only before the evaluated part."""
DEG = 180.0 / np.pi


@dataclass(frozen=True, slots=True, eq=False)
class EstimateSeries:
    """Raw network (or baseline) readouts, one row per event frame.

    Shapes:
        t: (n,) int64 ns, sensor clock (packet midpoints); h, v: (n,) map pixels;
        r: (n,) roll in radians; z: (n,) log scale or None.
    """

    t: NDArray[np.int64]
    h: F64
    v: F64
    r: F64
    z: F64 | None = None

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass(frozen=True, slots=True, eq=False)
class EvalSeries:
    """Aligned, calibrated series for plots (float seconds from the first ground-truth pose).

    Shapes:
        t_s: (n,); gt, est: (n, 3) in ``units``; err: (n,) per-sample error; calib, test: (n,)
        masks of the calibration segment and of the evaluated samples.
    """

    t_s: F64
    gt: F64
    est: F64
    err: F64
    calib: NDArray[np.bool_]
    test: NDArray[np.bool_]
    labels: tuple[str, str, str]
    units: tuple[str, str, str]
    err_label: str


@dataclass(frozen=True, slots=True, eq=False)
class KindResult:
    """The outcome of one kind's metric function (:mod:`~hrn_vo_ros.core.evaluation.metrics`).

    ``calibration`` holds only the kind's own entries (depth model, similarity), in the order
    they are reported; ``warnings`` only the kind's own warnings.

    Shapes:
        gt_plot, est_plot: (n, 3) in ``units``; err: (n,) per-sample error.
    """

    metrics: dict[str, float]
    calibration: dict[str, float | bool | str]
    gt_plot: F64
    est_plot: F64
    err: F64
    labels: tuple[str, str, str]
    units: tuple[str, str, str]
    err_label: str
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True, eq=False)
class EvalResult:
    """Outcome of ``evaluate``: the headline metrics and everything needed to check them."""

    kind: str
    calib_mode: str
    lag_s: float
    roll_corr: float
    metrics: dict[str, float]
    calibration: dict[str, float | bool | str]
    counts: dict[str, int]
    split_s: float
    warnings: tuple[str, ...]
    series: EvalSeries = field(repr=False)

    def to_dict(self) -> dict[str, object]:
        """A JSON-able summary (no per-sample series)."""
        return {'kind': self.kind, 'calib': self.calib_mode, 'lag_s': round(float(self.lag_s), 6),
                'roll_corr': round(self.roll_corr, 4),
                'metrics': {k: round(v, 6) for k, v in self.metrics.items()},
                'calibration': self.calibration, 'counts': self.counts,
                'split_s': round(float(self.split_s), 3), 'warnings': list(self.warnings)}
