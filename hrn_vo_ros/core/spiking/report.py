"""The resource report of a spiking configuration (``hrn-vo spiking-report``, the bench).

Static part (:func:`resource_lines`): every layer group of the sparse network with its neurons,
synapses, stored weight components, fan-in and cores, the totals against the chip limits
(:mod:`.hardware`) and the critical path. Measured part (:func:`measure`,
:func:`activity_lines`): the network run on event frames, per resonator iteration: spikes,
synaptic operations, Loihi energy and latency from the per-operation figures of
:class:`~.accounting.LoihiCosts` (cited), the dense reference form on the same frames, and the
float fast path's CPU operation count and measured time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.network import HRN
from hrn_vo_ros.core.spiking.accounting import cpu_ops, LoihiCosts, mean_account
from hrn_vo_ros.core.spiking.backend import SpikingHRN
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.hardware import LOIHI1, SOURCES
from hrn_vo_ros.core.spiking.resources import NetworkResources
from hrn_vo_ros.core.spiking.sparse_engine import SparseSpikingEngine
from hrn_vo_ros.core.spiking.transforms import PhasorCode
from hrn_vo_ros.errors import ConfigError

#: The acceptance target of the sparse form: synaptic operations per resonator iteration.
SYNOPS_TARGET = 2e6


def sparse_network(cfg: ResonatorConfig, scfg: SpikingConfig) -> NetworkResources:
    """The sparse network's resources for ``cfg`` (builds the backend once).

    Raises:
        ConfigError: if ``cfg`` cannot run the sparse form (scale factor, whitening).
    """
    b = SpikingHRN(cfg, rng=np.random.default_rng(0),
                   spiking=_with(scfg, transform='sparse'))
    eng = b._spiking_engine
    if not isinstance(eng, SparseSpikingEngine):
        raise ConfigError('the sparse spiking form needs h, v, r without whitening (no '
                          'scale.enabled, no cleanup.whiten); this configuration runs the dense '
                          'form only')
    return eng.resources


def _with(scfg: SpikingConfig, **changes: Any) -> SpikingConfig:
    from dataclasses import replace
    return replace(scfg, **changes)


def resource_lines(res: NetworkResources, scfg: SpikingConfig) -> list[str]:
    """The static table and totals."""
    groups: dict[str, list[int]] = {}
    for ly, cores in zip(res.layers, res.cores_by_layer, strict=True):
        key = ly.name.split(' stage ')[0] + (' stages' if ' stage ' in ly.name else '')
        row = groups.setdefault(key, [0, 0, 0, 0, 0, 0])
        row[0] += 1
        row[1] += ly.neurons
        row[2] += ly.synapses
        row[3] += ly.components
        row[4] = max(row[4], ly.fan_in)
        row[5] += cores
    c = res.chip
    out = [f'designed to {c.name}: {c.cores} cores/chip, {c.neurons_per_core} neurons/core '
           f'([design]), {c.memory_per_core // 1024} KiB/core, {c.fan_in_axons} input axons/'
           f'core, payloads <= {c.payload_bits} bits, delays <= {c.max_delay} steps',
           f'{"layer group":42s} {"layers":>6s} {"neurons":>9s} {"synapses":>10s} '
           f'{"weights":>10s} {"fan-in":>6s} {"cores":>5s}']
    for key, (n, neu, syn, comp, fan, cores) in groups.items():
        out.append(f'{key:42s} {n:6d} {neu:9d} {syn:10d} {comp:10d} {fan:6d} {cores:5d}')
    bad = res.violations()
    out.append(f'{"total":42s} {len(res.layers):6d} {res.neurons:9d} {res.synapses:10d} '
               f'{res.components:10d} {res.max_fan_in:6d} {res.cores:5d}')
    out.append(f'fits one {c.name} chip: {"yes" if not bad else "NO (" + "; ".join(bad) + ")"}'
               f' ({res.cores} of {c.cores} cores, {res.neurons} of {c.neurons_per_chip} '
               f'neurons, {res.components} of {c.synapses_per_chip} synapses, chips '
               f'{res.chips})')
    l1 = NetworkResources(res.layers, LOIHI1, res.weight_bits, res.payload_bits,
                          res.max_delay, res.depth)
    out.append(f'on {LOIHI1.name} ({LOIHI1.neurons_per_core} neurons/core, 128 KiB/core, binary '
               f'spikes): {l1.cores} cores = {l1.chips} chips'
               + ('' if res.payload_bits <= LOIHI1.payload_bits else
                  f', and its {res.payload_bits}-bit graded payloads do not exist there'))
    out.append(f'critical path: {res.depth} layers = {res.depth * scfg.steps_per_cycle} time '
               f'steps per iteration (T = {scfg.steps_per_cycle})')
    return out


@dataclass(slots=True)
class Measured:
    """Per-iteration accounts and per-frame times measured on a frame sequence."""

    frames: int
    iterations: int
    sparse: dict[str, float]
    dense: dict[str, float] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)


def _run(backend: Any, t: NDArray[np.int64], imgs: NDArray[Any]) -> tuple[float, dict[str, float]]:
    """Median seconds per frame and the mean per-iteration account (every 5th frame)."""
    dt, acc = [], []
    for i in range(len(t)):
        t0 = time.perf_counter()
        backend.step(imgs[i], int(t[i]))
        dt.append(time.perf_counter() - t0)
        last = getattr(backend, 'last_account', None)
        if last is not None and i % 5 == 4:
            acc.append(last)
    return float(np.median(dt)), mean_account(acc)


def measure(cfg: ResonatorConfig, scfg: SpikingConfig, t: NDArray[np.int64],
            imgs: NDArray[Any], *, dense: bool = True) -> Measured:
    """Run the float backend, the sparse spiking form and (``dense``) the dense reference on
    the same frames (back to back, one process)."""
    m = Measured(len(t), cfg.cleanup.iterations_per_frame, {})
    m.seconds['float'], _ = _run(HRN(cfg, rng=np.random.default_rng(0)), t, imgs)
    m.seconds['sparse'], m.sparse = _run(SpikingHRN(
        cfg, rng=np.random.default_rng(0), spiking=_with(scfg, transform='sparse')), t, imgs)
    if dense:
        m.seconds['dense'], m.dense = _run(SpikingHRN(
            cfg, rng=np.random.default_rng(0), spiking=_with(scfg, transform='dense')), t, imgs)
    return m


def activity_lines(cfg: ResonatorConfig, res: NetworkResources, m: Measured,
                   costs: LoihiCosts | None = None) -> list[str]:
    """Per-iteration spikes, synaptic operations, energy and time; CPU figures."""
    k = costs or LoihiCosts()
    s, d = m.sparse, m.dense
    out = [f'measured on {m.frames} event frames, {m.iterations} resonator iterations per '
           "frame; per iteration (the frame's own layers, S and the map update, spread over "
           'its iterations):']
    if s:
        ok = 'ok' if s['synops'] <= SYNOPS_TARGET else 'FAIL'
        out.append(f'  sparse: {s["spikes"]:.3g} spikes, {s["synops"]:.3g} synaptic ops '
                   f'(<= {SYNOPS_TARGET:.0e}: {ok}; resonator core {s["synops_core"]:.3g}), '
                   f'{s["neuron_updates"]:.3g} active neuron updates')
        out.append(f'    energy {s["energy_uJ"]:.0f} uJ = synops x {k.e_synop * 1e12:.1f} pJ + '
                   f'active updates x {k.e_neuron * 1e12:.0f} pJ + spikes x '
                   f'{k.e_spike * 1e12:.1f} pJ; idle compartment updates (every neuron, every '
                   f'step, x {k.e_neuron_idle * 1e12:.0f} pJ) add {s["energy_idle_uJ"]:.0f} uJ')
        out.append(f'    time {s["time_us"]:.0f} us = (active updates x {k.t_neuron * 1e9:.1f} '
                   f'ns + synops x {k.t_synop * 1e9:.1f} ns) / {int(s["cores"])} cores + '
                   f'{int(s["steps"])} steps x {k.t_sync * 1e9:.0f} ns barrier; idle updates '
                   f'(x {k.t_neuron_idle * 1e9:.1f} ns) add {s["time_idle_us"]:.0f} us')
    if d:
        ratio = d['synops'] / s['synops'] if s.get('synops') else float('nan')
        out.append(f'  dense reference: {d["synops"]:.3g} synaptic ops ({ratio:.0f}x the sparse '
                   f'form), {d["synapses"]:.3g} synapses, energy {d["energy_uJ"]:.0f} uJ '
                   f'(+{d["energy_idle_uJ"]:.0f} idle), time {d["time_us"]:.0f} us')
    g = _geometry(cfg)
    ops = cpu_ops({'wc': g[0], 'hc': g[1], 'n_theta': g[2], 'n_rho': g[3], 'k_h': g[0],
                   'k_v': g[1], 'k_r': g[2]})
    it = max(m.iterations, 1)
    out.append(f'  CPU, float fast path: {ops["fast"] / 1e6:.1f} M flop per iteration '
               f'(accounting.cpu_ops), measured {m.seconds["float"] * 1e6 / it:.0f} us per '
               f'iteration ({1.0 / m.seconds["float"]:.0f} frames/s, one core, this machine)')
    rates = ', '.join(f'{name} {1.0 / sec:.1f}' for name, sec in m.seconds.items()
                      if name != 'float')
    out.append(f'  emulation frames/s (median frame time): {rates}')
    out.append(f'  sources: {SOURCES}')
    return out


def _geometry(cfg: ResonatorConfig) -> tuple[int, int, int, int]:
    b = HRN(cfg, rng=np.random.default_rng(0))
    g = b.geometry
    return g.canvas_width, g.canvas_height, g.n_theta, g.n_rho


def report(cfg: ResonatorConfig, scfg: SpikingConfig, frames: Sequence[Any] | None = None,
           *, dense: bool = True) -> list[str]:
    """The whole report: resources, and the activity on ``frames = (t, imgs)`` if given."""
    res = sparse_network(cfg, scfg)
    lines = resource_lines(res, scfg)
    if frames is not None:
        t, imgs = frames
        lines += activity_lines(cfg, res, measure(cfg, scfg, t, imgs, dense=dense))
    return lines


class PayloadProbe:
    """Where the graded spikes' payloads round: each population of the sparse transforms
    against the same population with ``reference_bits`` payloads, on the same input.

    A :attr:`PhasorCode.probe <hrn_vo_ros.core.spiking.transforms.PhasorCode.probe>`: per
    label, the relative rms error ``sqrt(sum |out - ref|^2 / sum |ref|^2)`` (the phase grid and
    the decay table are the same in both, so this is the payload's rounding alone), the share
    of the neurons the reference fires that the payload silences (their value rounds to 0),
    and how many times the population fired.
    """

    def __init__(self, scfg: SpikingConfig, reference_bits: int = 24) -> None:
        self.reference_bits = reference_bits
        self._ref = PhasorCode(_with(scfg, payload_bits=reference_bits,
                                     transform_payload_bits=reference_bits))
        self._sums: dict[str, list[float]] = {}

    def __call__(self, label: str, z: NDArray[np.complex64], out: NDArray[np.complex64]
                 ) -> None:
        ref = self._ref.fire(z)
        s = self._sums.setdefault(label, [0.0, 0.0, 0.0, 0.0, 0.0])
        s[0] += float(np.sum(np.abs(out - ref) ** 2))
        s[1] += float(np.sum(np.abs(ref) ** 2))
        fired = ref != 0
        s[2] += float(np.count_nonzero(fired & (out == 0)))
        s[3] += float(np.count_nonzero(fired))
        s[4] += 1.0

    def rows(self) -> list[tuple[str, float, float, int]]:
        """(label, relative rms error, share silenced, fires) in the order first fired."""
        return [(k, float(np.sqrt(s[0] / s[1])) if s[1] > 0 else 0.0,
                 s[2] / s[3] if s[3] > 0 else 0.0, int(s[4])) for k, s in self._sums.items()]


def payload_errors(cfg: ResonatorConfig, scfg: SpikingConfig, t: NDArray[np.int64],
                   imgs: NDArray[Any], reference_bits: int = 24) -> PayloadProbe:
    """Run the sparse spiking form on the frames with a :class:`PayloadProbe` on its
    transforms' populations (the cleanups' populations are not in it)."""
    backend = SpikingHRN(cfg, rng=np.random.default_rng(0),
                         spiking=_with(scfg, transform='sparse'))
    engine = backend._spiking_engine
    if not isinstance(engine, SparseSpikingEngine):
        raise ConfigError('payload errors are measured on the sparse transforms, which this '
                          'resonator config does not support (see sparse_supported)')
    probe = PayloadProbe(scfg, reference_bits)
    engine.tf.code.probe = probe
    for i in range(len(t)):
        backend.step(imgs[i], int(t[i]))
    return probe


def payload_lines(probe: PayloadProbe, scfg: SpikingConfig) -> list[str]:
    """The table of :func:`payload_errors`, worst relative error first."""
    out = [f'payload rounding per population of the sparse transforms ({scfg.transform_bits}'
           f'-bit payloads against {probe.reference_bits}-bit; the same phase grid):',
           f'  {"population":<40} {"rel. rms error":>14} {"silenced":>9} {"fires":>7}']
    for label, err, silenced, n in sorted(probe.rows(), key=lambda r: -r[1]):
        out.append(f'  {label:<40} {err:>14.4f} {silenced:>9.3f} {n:>7d}')
    return out
