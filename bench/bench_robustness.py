"""Robustness benchmark: HRN, HRN + IMU, spiking backend and the classical baseline on randomized
simulated sequences (:mod:`hrn_vo_ros.core.sim.family`).

For each kind and each of N fresh draws (seeds 10000 on; ``--tuning`` uses the tuning draws
0-99 instead), a worker simulates the draw, makes the event frames once with the kind's config
(``config/<kind>.yaml`` via :data:`bench_accuracy.CASES`, the packetizer rectifying with the
draw's calibration, as ``hrn-vo run``) and runs every method on the same frames (HRN + IMU on
the packets of a fused gyro when the config sets ``imu.max_frame_ms``, as ``hrn-vo run --imu``
makes them; :func:`imu_framing`); the estimates
are evaluated with the paper's protocol (:func:`hrn_vo_ros.core.evaluation.protocol.evaluate`).
Workers run in parallel over ``--jobs`` processes (default: all cores), each single-threaded.

Definitions (per sequence, on the per-sample error of the protocol's calibrated estimate,
i.e. after its calibration fit, over all samples from 0.5 s on):

* **lost**: the error stays above the threshold (10° geodesic for rotation, 5 cm position for
  translation and arm) for more than 0.5 s; a sequence is *tracked* if it is never lost and its
  median error is within the threshold (an error that hovers above it with brief dips below
  is never above it for 0.5 s at a stretch, yet is no track); a sequence the protocol cannot
  evaluate counts as lost;
* **median error**: the protocol's metric on its evaluated part (median geodesic angle or
  median position error); the table gives the median and p90 over sequences and the worst;
* **silent loss**: a loss during which the estimator reports ``state == 'tracking'`` for most
  of the lost samples; 'n/a' for an estimator whose ``Estimate`` has no ``state`` (the baseline
  always reports ``'tracking'``, so each of its losses is silent); sequences the protocol
  cannot evaluate count as lost but not as silent; a diagnostic line under the breakdown (CSV
  columns ``silent_tc``, ``late_tc``) counts them and the late flags again with the calibration
  fitted only on the estimates reported as ``'tracking'`` (``evaluate``'s ``calib_use``): a
  loss inside the calibration segment makes the protocol fit the lost output (``cal_scale``,
  the fitted scale, then lies far from 1/f) and every error of that sequence with it; the
  same line names the sequences whose protocol lag (CSV column ``lag_s``) lies beyond
  ±``ODD_LAG_S`` (0.1 s): one late jump of the estimate can pull the lag search there and
  shift every error of the sequence;
* **late flag**: a loss whose first ``FLAG_FRAMES`` (10) frames all report ``state ==
  'tracking'`` (the estimator did not say within 10 frames that it may be wrong); 'n/a' as
  for silent losses;
* **re-localisation time**: from the start of a loss to the first moment after which the error
  stays below the threshold for 0.5 s; losses that never recover count in "never";
* **breakdown**: tracked per scene class, event-rate band, background-noise band and band of
  the *junk share* (CSV column ``junk``: the draw's background-noise and hot-pixel events over
  all its events, from its simulator settings; above half, the frames are mostly noise) and
  band of the *scene event rate* (the events that are neither, ``(1 - junk) x events/s``),
  and band of the *motion per frame* (CSV columns ``frame_deg``, ``frame_m``: the 95th
  percentile of the camera's turn and travel from one frame to the next, ``motion_between``
  of ``core/evaluation/samples.py``;
  with the scene rate the best predictors of a track on the family) and band of the frames'
  *structure* (CSV column ``structure``: the median over the frames a method ran on of their
  4-neighbouring on-pixel pairs against randomly placed pixels, ``frame_structure`` of
  ``core/events/content.py``; about 1 where the frames are as scattered as noise, and
  measured from the frames alone, so it reads the same on recordings); a
  last diagnostic line counts the draws tracked with the protocol's lag fixed at 0 (CSV column
  ``tracked_lag0``; a simulation's clocks are exact, so what the lag search moves is the
  evaluation's doing or the estimator's own delay) and names those it gains and loses.
  ``--lag-window training`` (not the protocol) searches every lag before the evaluated part
  only, so that nothing evaluated fits it (``evaluate``'s ``lag_window``).

``--cache DIR`` keeps each simulated sequence's frames, ground truth and IMU there (pickles
keyed by kind, seed, length, ``--pset`` and a hash of the config's packetizer settings), so
that a second run, e.g. with ``--set``, skips the simulation (the events are kept too, so that
``--pset`` runs and changed configs skip it as well); ``--set
KEY=VALUE`` overrides resonator settings of the HRN methods (as ``hrn-vo run --set``),
``--pset KEY=VALUE`` packetizer settings of every method, ``--sset KEY=VALUE`` the spiking
method's emulation settings (``SpikingConfig``). ``--trace DIR`` writes, per
sequence and method, ``DIR/<kind>_<seed>_<method>.csv`` with the per-sample time, error,
state and quality (the error-vs-time of the failures) and ``.png`` beside it: the protocol's
estimate against the ground truth per axis and the error with the states shaded
(:func:`hrn_vo_ros.io.plots.plot_evaluation`; a loss inside the calibration segment bends every
axis, see silent losses above). ``--config FILE`` runs every kind with
that params file instead of ``config/<kind>.yaml`` (``config/live.yaml`` on the rotation
family: a camera without calibration, so no rectification and no sphere correction).
``--sensor WIDTH`` renders every draw on a sensor that many pixels wide with the same field of
view (:func:`hrn_vo_ros.core.sim.family.on_sensor`; with a config whose packetizer downsample
is 0, e.g. ``--sensor 640 --config config/live.yaml``: the family on a 640x480 camera;
``--sensor 640x360``: its middle rows on a 16:9 sensor, frames of 96x54). ``--preset
shapes_rotation`` runs the family's fixed preset instead of randomized draws (60 s like the
Event Camera Dataset's sequence: the real DAVIS240C calibration, a shapes poster 1 m away, the
speed rising 9x to 650 deg/s at the end; seeds vary only texture, waves and noise).

``--rows A.csv B.csv ...`` prints earlier runs' tables again; with ``--paired`` it compares
them draw by draw instead (each file a run on the same draws, e.g. ``--pset
events_per_frame=1950`` and ``2050`` beside the default): tracked per run and method, each
method's mean and range over the runs (its flip noise), the draws not tracked alike, and per
pair of columns the draws only one tracks with an exact sign test (:func:`paired`).

Examples::

    scripts/run.sh python bench/bench_robustness.py --smoke
    scripts/run.sh python bench/bench_robustness.py --kinds rotation translation -n 6 \
        --seconds 10 --methods hrn hrn_imu baseline --csv build/robust.csv --plot build/robust.png
    scripts/run.sh python bench/bench_robustness.py --preset shapes_rotation -n 4 \
        --methods hrn hrn_imu baseline --cache build/preset
"""

from __future__ import annotations

import os

for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ[_var] = '1'     # each worker single-threaded (set before numpy is imported)

import argparse  # noqa: E402
import csv  # noqa: E402
from dataclasses import asdict, dataclass, fields  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
from pathlib import Path  # noqa: E402
import pickle  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
import yaml  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bench'))

from bench_accuracy import CASES  # noqa: E402

from hrn_vo_ros.cli.evaluate import FAST_TURN_DEG  # noqa: E402
from hrn_vo_ros.cli.run import parse_size  # noqa: E402
from hrn_vo_ros.core.evaluation.baseline import config_like, PhaseCorrelationBaseline  # noqa: E402
from hrn_vo_ros.core.evaluation.protocol import EstimateSeries, evaluate, LAG_WINDOWS  # noqa: E402
from hrn_vo_ros.core.evaluation.samples import motion_between  # noqa: E402
from hrn_vo_ros.core.events.content import frame_structure, NOISE_LIKE  # noqa: E402
from hrn_vo_ros.core.events.frames import frames_from_events  # noqa: E402
from hrn_vo_ros.core.events.packet_config import with_calibration  # noqa: E402
from hrn_vo_ros.core.events.sequence import Sequence  # noqa: E402
from hrn_vo_ros.core.hrn.backends import BackendConfig, make_backend  # noqa: E402
from hrn_vo_ros.core.odometry.imu import GyroIntegrator  # noqa: E402
from hrn_vo_ros.core.pipeline import OdometryPipeline  # noqa: E402
from hrn_vo_ros.core.sim.family import (  # noqa: E402
    draw,
    fresh_seeds,
    on_sensor,
    preset,
    PRESETS,
    simulate_draw,
    tuning_seeds,
)
from hrn_vo_ros.core.sim.simulator import describe_motion  # noqa: E402
from hrn_vo_ros.core.spiking.config import SpikingConfig  # noqa: E402
from hrn_vo_ros.errors import ConfigError, DatasetError  # noqa: E402
from hrn_vo_ros.io import ecd  # noqa: E402
from hrn_vo_ros.io.plots import plot_evaluation  # noqa: E402
from hrn_vo_ros.io.yamlconfig import dataset_configs, load_configs  # noqa: E402

KINDS = ('rotation', 'translation', 'arm')
METHODS = ('hrn', 'hrn_imu', 'spiking', 'baseline')
THRESHOLD = {'rotation': 10.0, 'translation': 0.05, 'arm': 0.05}   # deg, m, m
UNIT = {'rotation': 'deg', 'translation': 'm', 'arm': 'm'}
METRIC = {'rotation': 'median_angle_deg', 'translation': 'median_pos_m', 'arm': 'median_pos_m'}
LOST_S = 0.5        # a loss lasts longer than this
START_S = 0.5       # losses are looked for from this time on
RECOVER_S = 0.5     # re-localised: below the threshold for this long
FLAG_FRAMES = 10    # a loss must be flagged (state != 'tracking') within this many frames


@dataclass
class Row:
    """One method on one sequence."""

    kind: str
    seed: int
    method: str
    seconds: float
    events_per_s: float
    peak: float
    median_err: float
    lost: bool
    lost_s: float
    losses: int
    silent: int | None
    late: int | None
    reloc_s: str          # ';'-separated re-localisation times, 'never' for unrecovered
    wall_s: float
    note: str
    draw: str
    # (fields added later keep defaults, so that older CSVs still read)
    cal_scale: float = math.nan   # the protocol's fitted calibration scale (rad or m per px)
    silent_tc: int | None = None  # silent losses with the calibration on 'tracking' estimates
    late_tc: int | None = None    # late flags, the same way
    lag_s: float = math.nan       # the protocol's lag (s, + = the estimate lags)
    junk: float = math.nan        # share of the draw's events from background noise and hot
                                  # pixels (:func:`junk_share`; capped at 1)
    tracked_lag0: bool | None = None   # tracked with the protocol's lag fixed at 0 (None: not
                                       # evaluated)
    frame_deg: float = math.nan   # the camera's turn from one frame to the next, 95th
                                  # percentile over the draw (deg; motion_between)
    frame_m: float = math.nan     # ... and its travel (m)
    structure: float = math.nan   # median neighbour_ratio of the frames the method ran on
                                  # (core/events/content.py: 1 = as scattered as noise)


#: Resonator overrides of the HRN methods (``--set``), set in each worker by :func:`_init`.
OVERRIDES: dict[str, Any] = {}
#: Packetizer overrides of every method (``--pset``; they change the frames).
P_OVERRIDES: dict[str, Any] = {}
#: Spiking-emulation settings of the spiking method (``--sset``, :class:`SpikingConfig`).
S_OVERRIDES: dict[str, Any] = {}
#: A config file for every kind instead of ``config/<kind>.yaml`` (``--config``).
CONFIG: dict[str, Path] = {}
#: ``{'width': W, 'height': H}``: every draw seen by a sensor W pixels wide (H 0: the same
#: vertical field of view; else H rows, the middle ones; ``--sensor``, ``on_sensor``).
SENSOR: dict[str, int] = {}
#: ``{'name': NAME}``: run the family's preset NAME (``--preset``) instead of its draws.
PRESET: dict[str, str] = {}
#: Where the protocol searches the lag (``--lag-window``: ``run``, the protocol, or
#: ``training``, only before the evaluated part).
LAG: dict[str, str] = {'window': 'run'}


def _init(overrides: dict[str, Any], p_overrides: dict[str, Any] | None = None,
          s_overrides: dict[str, Any] | None = None, config: Path | None = None,
          sensor: tuple[int, int] | None = None, preset_name: str | None = None,
          lag_window: str = 'run') -> None:
    LAG['window'] = lag_window
    if preset_name is not None:
        PRESET['name'] = preset_name
    if sensor is not None:
        SENSOR['width'], SENSOR['height'] = sensor
    OVERRIDES.update(overrides)
    P_OVERRIDES.update(p_overrides or {})
    S_OVERRIDES.update(s_overrides or {})
    if config is not None:
        CONFIG['path'] = config


def config_path(kind: str) -> Path:
    """The config file the kind runs with: ``--config`` or ``config/<kind>.yaml``."""
    return CONFIG.get('path', ROOT / 'config' / CASES[kind].config)


def _value(text: str) -> Any:
    """A ``--set`` value: bool, int, float or the string."""
    low = text.lower()
    if low in ('true', 'false'):
        return low == 'true'
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def _configs(kind: str, seq: Sequence, imu: bool) -> tuple[Any, Any]:
    """Packetizer and resonator configs as ``hrn-vo run`` makes them for this sequence."""
    with tempfile.TemporaryDirectory() as tmp:        # calib.txt + meta.json, one event
        stub = ecd.write_sequence(Path(tmp) / 'stub', Sequence(seq.events[:1], seq.calib))
        over: dict[str, Any] = dict(OVERRIDES)
        pk: dict[str, Any] = dict(P_OVERRIDES)
        if imu:                             # as hrn-vo run --imu: both stages know the gyro
            over['imu.enabled'] = True
            pk['imu.enabled'] = True
        dc = dataset_configs(config_path(kind), stub,
                             packetizer=pk, resonator=over)
    return dc.packetizer, dc.resonator


def _config_tag(kind: str) -> str:
    """A short hash of the kind's packetizer settings in its config file: frames cached
    under another config's settings are not reused (the events are)."""
    with open(config_path(kind)) as f:
        section = yaml.safe_load(f)['packetizer_node']['ros__parameters']
    text = json.dumps(section, sort_keys=True)
    return '_p' + hashlib.sha1(text.encode()).hexdigest()[:8]


def imu_framing(kind: str) -> bool:
    """Whether the kind's config (with ``--pset``) makes other packets for a fused gyro
    (its packet time limit, ``PacketizerConfig.frame_ms``, or the refill of packets closed by
    time, ``refills``, changes with ``imu.enabled``):
    HRN + IMU then runs on those."""
    path = config_path(kind)
    plain = load_configs(path, packetizer=P_OVERRIDES)[0]
    gyro = load_configs(path, packetizer={**P_OVERRIDES, 'imu.enabled': True})[0]
    return (gyro.frame_ms, gyro.refills) != (plain.frame_ms, plain.refills)


def _frames(kind: str, seed: int, seconds: float, cache: str, imu: bool = False
            ) -> tuple[Any, Sequence, dict[str, float], np.ndarray, np.ndarray]:
    """The draw, its sequence (events cut to one), motion summary and frames (``imu``: the
    packets of a fused gyro); cached."""
    wide = (f'_w{SENSOR["width"]}' + (f'x{SENSOR["height"]}' if SENSOR['height'] else '')
            if SENSOR else '')
    tag = (''.join(f'_{k}={v}' for k, v in sorted(P_OVERRIDES.items())) + _config_tag(kind)
           + ('_imu' if imu else ''))
    name = f'preset-{PRESET["name"]}' if PRESET else kind
    path = Path(cache) / f'{name}_{seed}_{seconds:g}{wide}{tag}.pkl' if cache else None
    if path is not None and path.exists():
        with open(path, 'rb') as f:
            return tuple(pickle.load(f))
    d = preset(PRESET['name'], seed) if PRESET else draw(kind, seed)
    if SENSOR:
        d = on_sensor(d, SENSOR['width'], SENSOR['height'] or None)
    raw = Path(cache) / f'{name}_{seed}_{seconds:g}{wide}_events.pkl' if cache else None
    if raw is not None and raw.exists():
        with open(raw, 'rb') as f:
            seq = pickle.load(f)
    else:
        seq = simulate_draw(d, seconds)
        if raw is not None:
            raw.parent.mkdir(parents=True, exist_ok=True)
            with open(raw, 'wb') as f:
                pickle.dump(seq, f)
    info = describe_motion(seq)
    pcfg, _ = _configs(kind, seq, imu)
    if pcfg.rectify != 'none':
        pcfg = with_calibration(pcfg, seq.calib)
    t, imgs = frames_from_events(seq.events, pcfg)
    small = Sequence(seq.events[:1], seq.calib, seq.imu, seq.groundtruth)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, 'wb') as f:
            pickle.dump((d, small, info, t, imgs), f)
    return d, small, info, t, imgs


def _run(method: str, kind: str, seq: Sequence, t: np.ndarray, imgs: np.ndarray
         ) -> tuple[EstimateSeries, list[str] | None, np.ndarray]:
    """Run one method over the frames; returns the estimate, the states (None: no state) and
    the qualities (NaN where an estimate has none)."""
    _, rcfg = _configs(kind, seq, method == 'hrn_imu')
    gyro = None
    if method == 'baseline':
        est: Any = PhaseCorrelationBaseline(config_like(rcfg))
    else:
        backend = (BackendConfig(name='spiking', spiking=SpikingConfig(**S_OVERRIDES))
                   if method == 'spiking' else BackendConfig())
        est = make_backend(rcfg, rng=np.random.default_rng(0), backend=backend)
        if method == 'hrn_imu':
            assert seq.imu is not None
            rot = np.asarray(rcfg.imu.camera_from_imu, dtype=np.float64).reshape(3, 3)
            gyro = GyroIntegrator.from_imu(seq.imu, rot)
    pipe = OdometryPipeline(est, gyro=gyro, with_z=rcfg.scale.enabled)
    for i in range(len(t)):
        pipe.step(imgs[i], int(t[i]))
    return pipe.series(), pipe.states(), pipe.quality()


def is_lost(r: Row) -> bool:
    """Whether a row is not tracked: a loss, a median error above the threshold, or no
    evaluation (module docstring; also applied to rows read from older CSVs)."""
    return lost_verdict(r.lost, r.median_err, r.kind)


def lost_verdict(lost: bool, median_err: float, kind: str) -> bool:
    """Not tracked: a loss, or a median error not within the kind's threshold (NaN, inf)."""
    return lost or not median_err <= THRESHOLD[kind]


def late_flags(st: np.ndarray, eps: list[tuple[int, int, float | None]]) -> int:
    """Losses whose first ``FLAG_FRAMES`` samples all report ``'tracking'``."""
    return sum(bool(np.all(st[i:min(i + FLAG_FRAMES, j + 1)] == 'tracking')) for i, j, _ in eps)


def losses(t_s: np.ndarray, err: np.ndarray, thr: float
           ) -> list[tuple[int, int, float | None]]:
    """Lost episodes: (first, last sample index, re-localisation time s or None)."""
    bad = err > thr
    out = []
    i, n = 0, len(err)
    while i < n:
        if not bad[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and bad[j + 1]:
            j += 1
        if t_s[j] - t_s[i] > LOST_S:
            reloc = None
            k = j + 1
            while k < n:          # the first good stretch of RECOVER_S after the episode
                m = k
                while m + 1 < n and not bad[m + 1]:
                    m += 1
                if t_s[m] - t_s[k] >= RECOVER_S:
                    reloc = float(t_s[k] - t_s[i])
                    break
                k = m + 1
                while k < n and bad[k]:
                    k += 1
            out.append((i, j, reloc))
        i = j + 1
    return out


def job(task: tuple[str, int, float, tuple[str, ...], str, str]) -> list[Row]:
    """Simulate one draw and run and evaluate every method on it (in a worker process)."""
    kind, seed, seconds, methods, trace, cache = task
    gyro_packets = imu_framing(kind)
    framings = {imu: _frames(kind, seed, seconds, cache, imu)
                for imu in {m == 'hrn_imu' and gyro_packets for m in methods}}
    structure = {imu: frame_structure(f[4]) for imu, f in framings.items()}
    out = []
    for method in methods:
        d, seq, info, t, imgs = framings[method == 'hrn_imu' and gyro_packets]
        peak = info['peak_deg_s'] if kind == 'rotation' else info['peak_m_s']
        assert seq.groundtruth is not None
        t0 = time.perf_counter()
        note, med, lost, lost_s, eps = '', math.inf, True, seconds, []
        silent: int | None = None
        late: int | None = None
        silent_tc: int | None = None
        late_tc: int | None = None
        tracked0: bool | None = None
        scale = lag = math.nan
        traced: tuple[Any, np.ndarray | None, np.ndarray] | None = None
        try:
            est, states, quality = _run(method, kind, seq, t, imgs)
            res = evaluate(seq.groundtruth, est, kind, lag_window=LAG['window'])
            s = res.series
            keep = s.t_s >= START_S
            t_s, err = s.t_s[keep], s.err[keep]
            med = res.metrics[METRIC[kind]]
            scale = float(res.calibration['scale'])
            lag = float(res.lag_s)
            eps = losses(t_s, err, THRESHOLD[kind])
            lost = bool(eps)
            lost_s = float(sum(t_s[j] - t_s[i] for i, j, _ in eps))
            # the frame of each evaluated sample (its time minus the lag, nearest)
            tf = (t.astype(np.float64) - float(seq.groundtruth.t[0])) * 1e-9 - res.lag_s
            idx = np.clip(np.searchsorted(tf, s.t_s), 0, len(tf) - 1)
            prev = np.clip(idx - 1, 0, len(tf) - 1)
            idx = np.where(np.abs(tf[prev] - s.t_s) < np.abs(tf[idx] - s.t_s), prev, idx)
            st_all = None if states is None else np.asarray(states)[idx]
            if st_all is not None:
                st = st_all[keep]
                silent = sum(np.mean(st[i:j + 1] == 'tracking') > 0.5 for i, j, _ in eps)
                late = late_flags(st, eps)
                silent_tc, late_tc = silent_tracking_calibrated(seq, est, kind, res.lag_s,
                                                       list(states or ()), keep, st)
            traced = res, st_all, quality[idx]
            tracked0 = tracked_at_lag0(seq, est, kind, res, med)
        except Exception as err:      # a failed evaluation counts as lost
            note = f'{type(err).__name__}: {str(err)[:80]}'
        wall = time.perf_counter() - t0
        if trace and traced is not None:    # (outside the try: a failed write is no loss)
            res, st_all, q = traced
            stem = Path(trace) / f'{kind}_{seed}_{method}'
            _trace(stem.with_suffix('.csv'), res.series.t_s, res.series.err, st_all, q)
            plot_evaluation(res, stem.with_suffix('.png'),
                            states=None if st_all is None else [str(x) for x in st_all],
                            title=f'{kind} {seed}, {method}: {_fmt(med, kind)}'
                                  f'{" LOST" if lost else ""}\n{d.summary()}')
        reloc = ';'.join('never' if r is None else f'{r:.2f}' for *_, r in eps)
        out.append(Row(kind, seed, method, seconds, info['events_per_s'], peak, med, lost, lost_s,
                       len(eps), silent, late, reloc, wall, note,
                       d.summary(), scale, silent_tc, late_tc, lag,
                       junk_share(d, info['events_per_s']), tracked0,
                       *motion_between(seq.groundtruth, t),
                       structure[method == 'hrn_imu' and gyro_packets]))
    return out


def tracked_at_lag0(seq: Sequence, est: EstimateSeries, kind: str, res: Any,
                    med: float) -> bool | None:
    """Whether the sequence counts as tracked when the protocol's lag is fixed at 0 (a
    simulation's clocks are exact, so a lag the search finds is the evaluation's, or the
    estimator's own delay); None when that evaluation fails. ``res``, ``med``: the protocol's
    result, reused when its lag is 0 already."""
    assert seq.groundtruth is not None
    try:
        if res.lag_s != 0.0:
            res = evaluate(seq.groundtruth, est, kind, lag_s=0.0)
            med = res.metrics[METRIC[kind]]
    except Exception:
        return None
    keep = res.series.t_s >= START_S
    eps = losses(res.series.t_s[keep], res.series.err[keep], THRESHOLD[kind])
    return not lost_verdict(bool(eps), med, kind)


def silent_tracking_calibrated(seq: Sequence, est: EstimateSeries, kind: str, lag_s: float,
                               states: list[str], keep: np.ndarray, st: np.ndarray
                               ) -> tuple[int | None, int | None]:
    """Silent losses and late flags when only the estimates reported as ``'tracking'`` fit the
    calibration (``evaluate``'s ``calib_use``; same lag, so the same samples): a lost stretch
    inside the calibration segment makes the protocol's fit, and with it every error of the
    sequence, meaningless (a scale of 0.1-25x the camera's), and this asks instead whether the
    estimator's own claims agree with one calibration. None when fewer than the protocol's
    minimum of calibration estimates report ``'tracking'`` (the estimator flagged the segment:
    nothing to judge its later claims by), for both."""
    assert seq.groundtruth is not None
    try:
        res = evaluate(seq.groundtruth, est, kind, lag_s=lag_s,
                       calib_use=np.asarray(states) == 'tracking')
    except DatasetError:
        return None, None
    t_s, err = res.series.t_s[keep], res.series.err[keep]
    eps = losses(t_s, err, THRESHOLD[kind])
    return (int(sum(np.mean(st[i:j + 1] == 'tracking') > 0.5 for i, j, _ in eps)),
            late_flags(st, eps))


def _trace(path: Path, t_s: np.ndarray, err: np.ndarray, states: np.ndarray | None,
           quality: np.ndarray) -> None:
    """Per-sample error, state and quality of one method on one sequence."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['t_s', 'err', 'state', 'quality'])
        for i in range(len(t_s)):
            w.writerow([f'{t_s[i]:.4f}', f'{err[i]:.6g}',
                        '' if states is None else states[i], f'{quality[i]:.4f}'])


def _fmt(v: float, kind: str) -> str:
    if not math.isfinite(v):
        return 'fail'
    return f'{v:.2f}°' if UNIT[kind] == 'deg' else f'{100 * v:.2f}cm'


def table(rows: list[Row], kinds: list[str], methods: list[str]) -> list[str]:
    """The summary lines per kind and method."""
    lines = [f'lost: error > 10° (rotation) / 5 cm (translation, arm) for > {LOST_S:g} s, '
             f'on the calibrated estimate from {START_S:g} s on; tracked = never lost and the '
             'median within it',
             f'{"kind":12s} {"method":9s} {"tracked":>8s} {"time ok":>8s} {"median":>8s} '
             f'{"p90":>8s} {"worst":>16s} {"silent":>7s} {"late":>5s} {"reloc med":>9s} '
             f'{"never":>6s}']
    for kind in kinds:
        for method in methods:
            rs = [r for r in rows if r.kind == kind and r.method == method]
            if not rs:
                continue
            meds = np.array([r.median_err for r in rs])
            tracked = sum(not is_lost(r) for r in rs)
            span = np.array([max(r.lost_s, 0.0) for r in rs])
            worst = rs[int(np.argmax(meds))]
            # (None: no state, or the protocol failed on the sequence)
            silent = ('n/a' if all(r.silent is None for r in rs)
                      else str(sum(int(r.silent or 0) for r in rs)))
            late = ('n/a' if all(r.late is None for r in rs)
                    else str(sum(int(r.late or 0) for r in rs)))
            rel = [float(x) for r in rs for x in r.reloc_s.split(';') if x and x != 'never']
            never = sum(x == 'never' for r in rs for x in r.reloc_s.split(';'))
            finite = meds[np.isfinite(meds)]
            med = float(np.median(meds)) if len(finite) else math.inf
            p90 = float(np.percentile(meds, 90)) if np.all(np.isfinite(meds)) else math.inf
            dur = np.array([max(r.seconds - START_S, 1e-9) for r in rs])
            ok = float(np.mean(1.0 - np.clip(span / dur, 0.0, 1.0)))
            lines.append(f'{kind:12s} {method:9s} {tracked:>3d}/{len(rs):<4d} {100 * ok:7.1f}% '
                         f'{_fmt(med, kind):>8s} {_fmt(p90, kind):>8s} '
                         f'{_fmt(worst.median_err, kind) + f" (s{worst.seed})":>16s} '
                         f'{silent:>7s} {late:>5s} '
                         f'{(f"{np.median(rel):.2f} s" if rel else "-"):>9s} {never:>6d}')
    return lines


#: Event-rate bands of the breakdown (events/s): below 20 k a 10 s draw gives the configs'
#: fixed-count frames at a few per second.
RATE_BANDS = ((0.0, 2e4, '<20k ev/s'), (2e4, 1e5, '20-100k'), (1e5, math.inf, '>=100k'))


#: Bands of the share of events that carry no scene (background noise and hot pixels,
#: :func:`junk_share`): above half, the frames are mostly noise.
JUNK_BANDS = ((0.0, 0.15, 'junk <15%'), (0.15, 0.5, '15-50%'), (0.5, math.inf, '>=50%'))


#: Bands of the scene event rate (events/s that are neither noise nor hot pixels,
#: :func:`scene_rate`): below 10 k a draw gives the frames too few edges to follow.
SCENE_BANDS = ((0.0, 1e4, 'scene <10k ev/s'), (1e4, 5e4, '10-50k'), (5e4, math.inf, '>=50k'))


#: Bands of the frames' structure (:func:`frame_structure`, the median over a draw's frames of
#: their 4-neighbour on-pixel pairs over the count of randomly placed pixels): below
#: ``NOISE_LIKE`` (1.5) the frames are about as scattered as noise.
STRUCTURE_BANDS = ((0.0, NOISE_LIKE, f'structure <{NOISE_LIKE:g}'),
                   (NOISE_LIKE, 3.0, f'{NOISE_LIKE:g}-3'), (3.0, math.inf, '>=3'))


def scene_rate(r: Row) -> float:
    """The draw's scene events per second: its event rate less the junk share (NaN where
    the row has no junk share)."""
    return (1.0 - r.junk) * r.events_per_s


#: Bands of the camera's motion per frame (``motion_between``, the 95th percentile over a
#: draw), by the kind's :data:`UNIT`: the turn in degrees (rotation), the travel in cm (the
#: kinds measured in metres: translation and the arm).
#: The top band starts where ``hrn-vo evaluate`` notes a fast rotation (``FAST_TURN_DEG``,
#: 4° per frame: the network without a gyro loses most tracks there).
MOTION_BANDS = {
    'deg': ((0.0, 2.0, '<2 deg/frame'), (2.0, FAST_TURN_DEG, f'2-{FAST_TURN_DEG:g}'),
            (FAST_TURN_DEG, math.inf, f'>={FAST_TURN_DEG:g}')),
    'm': ((0.0, 0.5, '<0.5 cm/frame'), (0.5, 1.0, '0.5-1'), (1.0, math.inf, '>=1')),
}


def motion_of(r: Row) -> float:
    """A row's motion per frame in its kind's band unit (:data:`MOTION_BANDS`): degrees, or
    cm for the kinds measured in metres."""
    return r.frame_deg if UNIT[r.kind] == 'deg' else 100.0 * r.frame_m


def junk_share(d: Any, events_per_s: float) -> float:
    """The share of a draw's events that are background noise or hot pixels, from its
    simulator settings (noise Hz per sensor pixel, the hot pixels' expected rate) over its
    measured event rate; capped at 1."""
    c = d.config
    junk = c.noise_rate_hz * d.calib.width * d.calib.height + c.hot_events_per_s
    return min(junk / events_per_s, 1.0) if events_per_s > 0 else 1.0


#: Background-noise bands of the breakdown (events per pixel per second, the draw's
#: ``noise_rate_hz``, log-uniform 0.01-1 Hz: about a quarter of the draws are at 0.3 or more).
NOISE_BANDS = ((0.0, 0.3, 'noise <0.3 Hz'), (0.3, math.inf, '>=0.3 Hz'))


def noise_of(r: Row) -> float | None:
    """The draw's background-noise rate in Hz per pixel (from its summary line:
    ``..., noise 0.12 Hz, ...``), or None where the summary has none."""
    _, found, rest = r.draw.partition(', noise ')
    if not found:
        return None
    try:
        return float(rest.split(' Hz')[0])
    except ValueError:
        return None


def scene_of(r: Row) -> str:
    """The draw's scene class (from its summary line: ``... (split): <scene> at ...``)."""
    head, _, rest = r.draw.partition('): ')
    return rest.split(' at ')[0] if rest else 'arm'


def unevaluable(r: Row) -> str:
    """Why the protocol could not evaluate the row: 'few' (too few estimates: a draw too
    sparse for the config's frames), 'still' (an estimate that never moves: lost or held from
    the start), 'other', or '' (evaluated)."""
    if not r.note:
        return ''
    if 'estimates' in r.note:
        return 'few'
    return 'still' if 'does not move' in r.note else 'other'


def breakdown(rows: list[Row], kinds: list[str], methods: list[str]) -> list[str]:
    """Tracked / draws per scene class, event-rate, background-noise, junk-share and
    scene-rate band, and the unevaluated rows by cause: where each method fails."""
    lines = ['tracked per scene class, event rate, background noise (Hz per pixel), share '
             'of noise and hot-pixel events (junk), rate of the other events (scene) and the '
             "camera's motion from one frame to the next (95th percentile) and the frames' "
             'structure (neighbouring on pixels against random placement, median; 1: as '
             'scattered as noise); unevaluated: too few estimates (few), an estimate that never '
             'moves (still), other']
    for kind in kinds:
        for method in methods:
            rs = [r for r in rows if r.kind == kind and r.method == method]
            if not rs:
                continue
            parts = []
            for scene in sorted({scene_of(r) for r in rs}):
                sub = [r for r in rs if scene_of(r) == scene]
                parts.append(f'{scene} {sum(not is_lost(r) for r in sub)}/{len(sub)}')
            for bands, value in ((RATE_BANDS, lambda r: r.events_per_s),
                                 (NOISE_BANDS, noise_of), (JUNK_BANDS, lambda r: r.junk),
                                 (SCENE_BANDS, scene_rate),
                                 (MOTION_BANDS[UNIT[kind]], motion_of),
                                 (STRUCTURE_BANDS, lambda r: r.structure)):
                for lo, hi, name in bands:
                    sub = [r for r in rs if (x := value(r)) is not None and lo <= x < hi]
                    if sub:
                        parts.append(f'{name} {sum(not is_lost(r) for r in sub)}/{len(sub)}')
            why = [unevaluable(r) for r in rs]
            parts.append('unevaluated ' + ' '.join(
                f'{k} {why.count(k)}' for k in ('few', 'still', 'other')))
            lines.append(f'{kind:12s} {method:9s} ' + ', '.join(parts))
    lines.append('silent losses and late flags, calibration fitted on the estimates reported as '
                 'tracking only (a diagnostic; unjudged: too few of them to calibrate)')
    for kind in kinds:
        for method in methods:
            rs = [r for r in rows if r.kind == kind and r.method == method
                  and r.silent is not None]
            if not rs and any(r.kind == kind and r.method == method for r in rows):
                lines.append(f'{kind:12s} {method:9s} silent n/a (no evaluated sequence with '
                             'states)')
            if rs:
                judged = [r for r in rs if r.silent_tc is not None]
                lines.append(f'{kind:12s} {method:9s} silent '
                             f'{sum(int(r.silent or 0) for r in rs)} -> '
                             f'{sum(int(r.silent_tc or 0) for r in judged)}, late '
                             f'{sum(int(r.late or 0) for r in rs)} -> '
                             f'{sum(int(r.late_tc or 0) for r in judged)} '
                             f'(unjudged {len(rs) - len(judged)}: '
                             f'{" ".join(str(r.seed) for r in rs if r.silent_tc is None) or "-"})'
                             + _odd_lags(rs))
    lag0 = [_lag0_line(kind, method, [r for r in rows if r.kind == kind and r.method == method])
            for kind in kinds for method in methods]
    if any(lag0):
        lines.append("tracked with the protocol's lag fixed at 0 (simulated clocks are exact; a "
                     'diagnostic)')
        lines += [line for line in lag0 if line]
    return lines


def _lag0_line(kind: str, method: str, rs: list[Row]) -> str:
    """``KIND METHOD tracked A/N (gained: SEEDS; lost: SEEDS)`` against the protocol's own lag,
    or '' when no row has the figure."""
    rs = [r for r in rs if r.tracked_lag0 is not None]
    if not rs:
        return ''
    gained = ' '.join(str(r.seed) for r in rs if r.tracked_lag0 and is_lost(r)) or '-'
    lost = ' '.join(str(r.seed) for r in rs if not r.tracked_lag0 and not is_lost(r)) or '-'
    return (f'{kind:12s} {method:9s} tracked {sum(bool(r.tracked_lag0) for r in rs)}/{len(rs)} '
            f'(gained: {gained}; lost: {lost})')


#: A protocol lag beyond this (s) is named after the silent losses: the lag search (the roll's
#: correlation over the whole run) can be pulled far off by one late jump of the estimate.
ODD_LAG_S = 0.1


def _odd_lags(rs: list[Row]) -> str:
    """``, lag beyond ±0.1 s: SEED (LAG s) ...`` for the rows whose protocol lag is that far."""
    odd = [r for r in rs if abs(r.lag_s) > ODD_LAG_S]
    names = ' '.join(f'{r.seed} ({r.lag_s:+.2f} s)' for r in odd)
    return f', lag beyond ±{ODD_LAG_S:g} s: {names}' if odd else ''


#: How a ``--csv`` cell becomes a :class:`Row` field, by the field's annotation.
_PARSE: dict[str, Any] = {'int': int, 'float': float, 'str': str, 'bool': lambda v: v == 'True',
                          'int | None': lambda v: None if v == '' else int(v),
                          'bool | None': lambda v: None if v == '' else v == 'True'}


def _label(path: Path, paths: list[Path]) -> str:
    """A run's name in ``--paired``: its file's stem, or its path when stems repeat."""
    return path.stem if [q.stem for q in paths].count(path.stem) == 1 else str(path)


def write_rows(path: Path, rows: list[Row]) -> None:
    """The ``--csv`` file of some rows (:func:`read_rows` reads it back)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=[x.name for x in fields(Row)])
        w.writeheader()
        for r in rows:
            w.writerow(asdict(r))


def read_rows(path: Path) -> list[Row]:
    """Rows of a ``--csv`` file (to print the table and breakdown again)."""
    parse = {f.name: _PARSE[str(f.type)] for f in fields(Row)}
    with open(path, newline='') as f:
        return [Row(**{k: parse[k](v) for k, v in d.items()}) for d in csv.DictReader(f)]


def sign_test_p(a_only: int, b_only: int) -> float:
    """Two-sided exact sign test (McNemar's exact test) of a paired split: the chance of a
    split at least this uneven if the draws only one of two columns tracks fell either way
    with even odds."""
    n, k = a_only + b_only, min(a_only, b_only)
    return 1.0 if n == 0 else min(1.0, 2.0 * sum(math.comb(n, i) for i in range(k + 1)) / 2**n)


def paired(runs: list[tuple[str, list[Row]]], kinds: list[str]) -> list[str]:
    """The same draws under several runs (one ``--csv`` each, e.g. frames of slightly
    different sizes, or another setting): per kind, each column's (run and method's) tracked
    count on the draws that every column has, each method's mean and range over the runs, the
    draws not tracked alike (T/L per column), and per pair of columns the draws only one of
    them tracks with :func:`sign_test_p`. A difference between two columns is worth as much
    as that split; how far one method's count moves between runs is its flip noise."""
    lines: list[str] = []
    for kind in kinds:
        verdict = {(label, m): {r.seed: not is_lost(r) for r in rows
                                if r.kind == kind and r.method == m}
                   for label, rows in runs for m in METHODS}
        cols = [c for c, v in verdict.items() if v]
        if len(cols) < 2:
            lines.append(f'{kind}: {len(cols)} column (run and method): nothing to pair; '
                         'give --rows files of runs on the same draws')
            continue
        seeds = sorted(set.intersection(*(set(verdict[c]) for c in cols)))
        names = [f'{label}/{m}' for label, m in cols]
        lines.append(f'{kind}: {len(seeds)} draws in all {len(cols)} columns')
        for name, col in zip(names, cols, strict=True):
            lines.append(f'  {name:<28} tracked {sum(verdict[col][s] for s in seeds)}')
        for m in METHODS:
            counts = [sum(verdict[c][s] for s in seeds) for c in cols if c[1] == m]
            if len(counts) > 1:
                lines.append(f'  {m}: mean {sum(counts) / len(counts):.1f} over {len(counts)} '
                             f'runs (range {min(counts)}-{max(counts)})')
        odd = [s for s in seeds if len({verdict[c][s] for c in cols}) > 1]
        lines.append(f'  not tracked alike: {len(odd)} draws ({" ".join(names)})')
        lines += [f'    {s}  ' + ' '.join('T' if verdict[c][s] else 'L' for c in cols)
                  for s in odd]
        for i, a in enumerate(cols):
            for j, b in enumerate(cols[i + 1:], i + 1):
                a_only = sum(verdict[a][s] and not verdict[b][s] for s in seeds)
                b_only = sum(verdict[b][s] and not verdict[a][s] for s in seeds)
                lines.append(f'  {names[i]} vs {names[j]}: {a_only} / {b_only} tracked by one '
                             f'only, sign test p {sign_test_p(a_only, b_only):.3g}')
    return lines


#: Axis label of :func:`scene_rate` in the plots.
SCENE_RATE_LABEL = 'scene events/s (noise and hot pixels removed)'


def motion_label(deg: bool) -> str:
    """Axis label of :func:`motion_of` in the plots: the turn (deg) or the travel (cm)."""
    return ('camera turn per frame, 95th pct (deg)' if deg
            else 'camera travel per frame, 95th pct (cm)')


def plot(rows: list[Row], kinds: list[str], methods: list[str], path: Path) -> None:
    """Per kind, the per-sequence median errors of every method (strip + box plot) and, below,
    each draw's median error against its scene event rate (:func:`scene_rate`) and against
    its motion per frame (:func:`motion_of`; lost draws as crosses, unevaluated ones on the top
    edge; rows without the figure, from older CSVs, are left out of that panel); then, one
    row per method, where its draws lie in scene rate and motion per frame and which of them
    it tracks (:func:`_verdict_map`)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(3 + len(methods), len(kinds),
                             figsize=(4.5 * len(kinds), 11.0 + 3.4 * len(methods)),
                             squeeze=False)
    for row, method in zip(axes[3:], methods, strict=True):
        for ax, kind in zip(row, kinds, strict=True):
            _verdict_map(ax, [r for r in rows if r.kind == kind and r.method == method],
                         kind, method)
    axes = axes[:3]
    panels = ((scene_rate, 'log', lambda deg: SCENE_RATE_LABEL), (motion_of, 'log', motion_label))
    for (box, *scatters), kind in zip(axes.T, kinds, strict=True):
        deg = UNIT[kind] == 'deg'
        scale = 1.0 if deg else 100.0                     # plotted in deg or cm
        top = THRESHOLD[kind] * scale * 30.0              # where unevaluated draws are drawn
        data = []
        for method in methods:
            mine = [r for r in rows if r.kind == kind and r.method == method]
            v = np.array([r.median_err for r in mine])
            v = np.where(np.isfinite(v), v, np.nan)
            data.append((v * scale)[~np.isnan(v)])
            for scatter, (value, _, _) in zip(scatters, panels, strict=True):
                pts = [(x, r) for r in mine if math.isfinite(x := value(r))]
                x = np.array([x for x, _ in pts])
                y = np.array([min(r.median_err * scale, top) if math.isfinite(r.median_err)
                              else top for _, r in pts])
                lost = np.array([is_lost(r) for _, r in pts], dtype=bool)
                (dots,) = scatter.plot(x[~lost], y[~lost], 'o', ms=3, alpha=0.8, label=method)
                scatter.plot(x[lost], y[lost], 'x', ms=4, alpha=0.8, color=dots.get_color())
        box.boxplot(data, showfliers=False)
        for i, v in enumerate(data):
            box.plot(np.full(len(v), i + 1.0) + np.linspace(-0.15, 0.15, len(v)), v, '.',
                     alpha=0.7)
        box.set_xticks(range(1, len(methods) + 1), methods)
        box.set_title(kind)
        for scatter, (_, xscale, label) in zip(scatters, panels, strict=True):
            scatter.set_xscale(xscale)
            scatter.set_xlabel(label(deg))
            scatter.set_title(f'{kind}: x lost, top edge unevaluated', fontsize=9)
            scatter.legend(fontsize=7)
        for ax in (box, *scatters):
            ax.axhline(THRESHOLD[kind] * scale, ls='--', c='r', lw=0.8)
            ax.set_yscale('log')
            ax.set_ylabel(f'median error ({"deg" if deg else "cm"})')
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def _verdict_map(ax: Any, rows: list[Row], kind: str, method: str) -> None:
    """One method's draws of one kind at their scene event rate (x) and motion per frame (y):
    tracked as dots, lost as crosses (rows without either figure are left out)."""
    pts = [(scene_rate(r), motion_of(r), is_lost(r)) for r in rows]
    pts = [p for p in pts if math.isfinite(p[0]) and p[0] > 0 and math.isfinite(p[1])
           and p[1] > 0]
    for lost, mark, colour, name in ((False, 'o', 'tab:green', 'tracked'),
                                     (True, 'x', 'tab:red', 'lost')):
        xy = np.array([(x, y) for x, y, lo in pts if lo == lost]).reshape(-1, 2)
        ax.plot(xy[:, 0], xy[:, 1], mark, ms=4, alpha=0.75, color=colour,
                label=f'{name} {len(xy)}')
    ax.set_xscale('log')
    ax.set_yscale('log')
    ax.set_xlabel(SCENE_RATE_LABEL)
    ax.set_ylabel(motion_label(UNIT[kind] == 'deg'))
    ax.set_title(f'{kind}, {method}: tracked {sum(not lo for _, _, lo in pts)}/{len(pts)}',
                 fontsize=9)
    ax.legend(fontsize=7)


def _sensor_arg(text: str) -> tuple[int, int]:
    """``--sensor`` WIDTH or WIDTHxHEIGHT (``hrn-vo run --sensor-size``'s parser) as (width,
    height or 0)."""
    if 'x' in text.lower():
        return parse_size(text)
    try:
        return int(text), 0
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not WIDTH or WIDTHxHEIGHT') from None


def _check_overrides(kinds: list[str], over: dict[str, Any], p_over: dict[str, Any],
                     s_over: dict[str, Any]) -> str | None:
    """What is wrong with the ``--set``, ``--pset`` and ``--sset`` overrides (None: nothing):
    each kind's config file (:func:`config_path`) must take the first two,
    :class:`SpikingConfig` the third."""
    known = {f.name for f in fields(SpikingConfig)}
    unknown = sorted(set(s_over) - known)
    if unknown:
        return (f'--sset: no SpikingConfig field {", ".join(unknown)} (the field names, '
                f'without "spiking.": {", ".join(sorted(known))})')
    try:
        SpikingConfig(**s_over)
        for kind in kinds:
            load_configs(config_path(kind), packetizer=p_over, resonator=over)
    except ConfigError as e:
        return f'--set/--pset/--sset: {e}'
    return None


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; returns 0 (figures are printed, not asserted)."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--kinds', nargs='+', choices=KINDS, default=None,
                   help='kinds to run (default: all; rotation with --preset)')
    p.add_argument('--methods', nargs='+', choices=METHODS, default=list(METHODS))
    p.add_argument('-n', type=int, default=30, help='draws per kind (default 30)')
    p.add_argument('--seconds', type=float, default=None,
                   help='per sequence (default 15; with --preset that of the preset, 60 s)')
    p.add_argument('--tuning', action='store_true',
                   help='use the tuning draws (seeds 0-99) instead of the fresh ones (10000+)')
    p.add_argument('--jobs', type=int, default=os.cpu_count() or 1, help='worker processes')
    p.add_argument('--smoke', action='store_true', help='tiny run: 1 draw per kind, 6 s')
    p.add_argument('--csv', type=Path, default=None, help='write the per-sequence rows here')
    p.add_argument('--plot', type=Path, default=None, help='write an error-distribution PNG')
    p.add_argument('--trace', type=Path, default=None,
                   help='write per-sequence error/state/quality CSVs and plots (estimate '
                        'against ground truth, states shaded) into this folder')
    p.add_argument('--cache', type=Path, default=None,
                   help='keep the simulated frames here and reuse them')
    p.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                   help='override a resonator setting of the HRN methods (repeatable)')
    p.add_argument('--pset', action='append', default=[], metavar='KEY=VALUE',
                   help='override a packetizer setting of every method (repeatable; the '
                        'frames change, so the cache keeps them apart)')
    p.add_argument('--sset', action='append', default=[], metavar='KEY=VALUE',
                   help='override a spiking-emulation setting of the spiking method '
                        '(a SpikingConfig field name, without "spiking.", e.g. precision=float; '
                        'repeatable; --set, --pset and --sset are checked before any draw runs)')
    p.add_argument('--lag-window', choices=LAG_WINDOWS, default='run',
                   help="where the protocol searches the lag: 'run' (the protocol: the whole "
                        "run) or 'training' (only before the evaluated part)")
    p.add_argument('--config', type=Path, default=None,
                   help='run every kind with this config file instead of config/<kind>.yaml '
                        '(e.g. config/live.yaml on the rotation family)')
    p.add_argument('--sensor', type=_sensor_arg, default=None, metavar='WIDTH[xHEIGHT]',
                   help='render every draw on a sensor WIDTH pixels wide with the same field '
                        'of view (640: the rotation family on 640x480; 640x360: its middle '
                        'rows, a 16:9 sensor); needs a config whose '
                        'packetizer downsample is 0 (auto) and whose resonator takes the frame '
                        'size (--config config/live.yaml)')
    p.add_argument('--preset', choices=PRESETS, default=None,
                   help='run a fixed preset of the family (shapes_rotation: 60 s, real DAVIS240C '
                        'calibration, speed rising 9x to 650 deg/s) with seeds 0..n-1 (or '
                        '--seeds) instead of randomized draws; rotation only')
    p.add_argument('--seeds', type=int, nargs='+', default=None,
                   help='run these seeds instead of the first -n of the split')
    p.add_argument('--rows', type=Path, nargs='+', default=None,
                   help='print the table and breakdown (and --plot) of --csv files of earlier '
                        'runs, e.g. one per method on the same draws (runs nothing)')
    p.add_argument('--paired', action='store_true',
                   help='with --rows: compare the files draw by draw (each a run on the same '
                        'draws): tracked per run and method, the draws not tracked alike, and '
                        'per pair the draws only one tracks with a sign test')
    args = p.parse_args(argv)
    if args.paired and not args.rows:
        print('--paired compares --rows files: give them', file=sys.stderr)
        return 2
    if args.rows:                       # earlier runs' CSVs: print (and plot) them together
        missing = [str(path) for path in args.rows if not path.is_file()]
        if missing:
            print(f'--rows: no such file: {", ".join(missing)} (give --csv files of earlier '
                  'runs)', file=sys.stderr)
            return 2
        runs = [(_label(path, args.rows), read_rows(path)) for path in args.rows]
        rows: list[Row] = [r for _, rs in runs for r in rs]
        kinds = [k for k in KINDS if any(r.kind == k for r in rows)]
        if args.paired:
            for line in paired(runs, kinds):
                print(line)
            return 0
        methods = [m for m in METHODS if any(r.method == m for r in rows)]
        for line in table(rows, kinds, methods) + [''] + breakdown(rows, kinds, methods):
            print(line)
        if args.plot is not None:
            plot(rows, kinds, methods, args.plot)
            print(f'plot -> {args.plot}')
        return 0
    if args.preset is not None:
        if args.tuning:
            print(f'--preset {args.preset} seeds are neither tuning nor fresh draws (none of them '
                  'was tuned on): drop --tuning', file=sys.stderr)
            return 2
        if args.kinds not in (None, ['rotation']):
            print(f'--preset {args.preset} is a rotation sequence: drop --kinds or give '
                  '--kinds rotation', file=sys.stderr)
            return 2
        args.kinds = ['rotation']
    args.kinds = args.kinds or list(KINDS)
    if args.seconds is None:
        args.seconds = preset(args.preset).seconds if args.preset else 15.0
    if args.smoke:
        args.n, args.seconds = 1, 6.0
    if args.preset is not None:
        seeds = args.seeds or list(range(args.n))
    else:
        seeds = args.seeds or (tuning_seeds(args.n) if args.tuning else fresh_seeds(args.n))
    trace = '' if args.trace is None else str(args.trace)
    cache = '' if args.cache is None else str(args.cache)
    over: dict[str, Any] = {}
    p_over: dict[str, Any] = {}
    s_over: dict[str, Any] = {}
    for items, into in ((args.set, over), (args.pset, p_over), (args.sset, s_over)):
        for item in items:
            key, _, val = item.partition('=')
            into[key.strip()] = _value(val.strip())
    if args.config is not None and not args.config.is_file():
        print(f'--config: no such file: {args.config}', file=sys.stderr)
        return 2
    config = None if args.config is None else args.config.resolve()
    _init({}, config=config)        # this process too resolves config_path as the workers do
    if args.sensor is not None:
        for kind in args.kinds:     # a fixed factor makes frames of another size
            path = config_path(kind)
            if load_configs(path)[0].downsample != 0:
                print(f'--sensor: {path} has a fixed packetizer downsample; give a config '
                      'with downsample 0 (e.g. --config config/live.yaml)', file=sys.stderr)
                return 2
    bad = _check_overrides(args.kinds, over, p_over, s_over)
    if bad:                         # (else every worker fails on it, one draw at a time)
        print(bad, file=sys.stderr)
        return 2
    tasks = [(k, s, args.seconds, tuple(args.methods), trace, cache)
             for k in args.kinds for s in seeds]
    what = (f'preset {args.preset} seeds {seeds[0]}..{seeds[-1]}' if args.preset else
            f'{len(seeds)} given draws per kind, seeds {seeds[0]}..{seeds[-1]}' if args.seeds
            else f'{args.n} {"tuning" if args.tuning else "fresh"} draws per kind')
    print(f'{len(tasks)} sequences ({what}, {args.seconds:g} s), methods '
          f'{", ".join(args.methods)}, {args.jobs} jobs'
          + ('' if args.config is None else f', config {args.config}')
          + ('' if args.sensor is None else f', sensor {args.sensor[0]} px wide'
             + (f', {args.sensor[1]} high' if args.sensor[1] else '')),
          flush=True)
    t0 = time.perf_counter()
    rows = []
    ctx = multiprocessing.get_context('spawn')
    with ctx.Pool(args.jobs, _init, (over, p_over, s_over, config, args.sensor,
                                     args.preset, args.lag_window)) as pool:
        for out in pool.imap_unordered(job, tasks):
            rows += out
            r0 = out[0]
            print(f'  {r0.kind} {r0.seed}: {r0.events_per_s / 1e3:.0f} k ev/s, peak '
                  f'{r0.peak:.2f}; ' + ', '.join(
                      f'{r.method} {_fmt(r.median_err, r.kind)}{" LOST" if is_lost(r) else ""}'
                      for r in out), flush=True)
    rows.sort(key=lambda r: (KINDS.index(r.kind), r.seed, METHODS.index(r.method)))
    print(f'\n{len(tasks)} sequences in {time.perf_counter() - t0:.0f} s')
    for line in table(rows, args.kinds, args.methods) + [''] + breakdown(rows, args.kinds,
                                                                          args.methods):
        print(line)
    if args.csv is not None:
        write_rows(args.csv, rows)
        print(f'rows -> {args.csv}')
    if args.plot is not None:
        plot(rows, args.kinds, args.methods, args.plot)
        print(f'plot -> {args.plot}')
    if args.trace is not None:
        print(f'traces -> {args.trace}: {len(list(args.trace.glob("*.csv")))} CSV, '
              f'{len(list(args.trace.glob("*.png")))} PNG (<kind>_<seed>_<method>)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
