"""Spiking phasor emulation: neurons, quantisation, Loihi limits, cleanup and the spiking HRN."""

from __future__ import annotations

from dataclasses import replace
import math

from hrn_synth import event_frame, random_scene
import numpy as np
import pytest

from hrn_vo_ros.core.hrn.config import paper_config
from hrn_vo_ros.core.spiking.accounting import (
    cores_for,
    cpu_ops,
    IterationAccount,
    LoihiCosts,
    mean_account,
)
from hrn_vo_ros.core.spiking.backend import SpikingHRN
from hrn_vo_ros.core.spiking.cleanup import SpikingCleanup
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.neurons import (
    _octant_bounds,
    code_steps,
    encode,
    encode_many,
    NEAREST,
    payload_exponent,
    phase_codes,
    phase_to_step,
    rf_cycle_float,
    rf_cycle_int,
    rotation_constants,
    Rounding,
    Spikes,
)
from hrn_vo_ros.core.spiking.synapses import (
    _fit_shift,
    ComplexSynapses,
    LayerCounts,
    quantise_weights,
    QuantisedWeights,
    scale_kicks_float,
    state_shift,
)
from hrn_vo_ros.errors import ConfigError


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


# -- neurons ---------------------------------------------------------------------------------


@pytest.mark.parametrize('steps', [16, 32, 63])
def test_spike_time_reproduces_the_phase_within_one_step(steps: int) -> None:
    rng = np.random.default_rng(0)
    z = rng.uniform(0.1, 2.0, 500) * np.exp(1j * rng.uniform(-np.pi, np.pi, 500))
    sp = encode(z, SpikingConfig(steps_per_cycle=steps))
    err = np.abs(wrap(np.angle(sp.decode()) - np.angle(z)))
    assert err.max() <= np.pi / steps + 1e-12             # rounding: half a step
    assert err.max() > 0.5 * np.pi / steps                # the grid is really 2π/T
    assert np.all((sp.t >= 0) & (sp.t < steps))


@pytest.mark.parametrize('steps', [4, 8, 16, 32, 60])
def test_phase_codes_compare_the_ratio_with_each_boundary(steps: int) -> None:
    """phase_codes counts the boundaries below min/max exactly as comparing the ratio with each
    boundary as a Python float (in the input's precision), also at the boundaries' own values
    and their neighbours, in every octant, 1-D and 2-D, both precisions, signed zeros."""

    def reference(z: np.ndarray) -> np.ndarray:
        x, y = z.real, z.imag
        ax, ay = np.abs(x), np.abs(y)
        with np.errstate(invalid='ignore', divide='ignore'):
            ratio = np.minimum(ax, ay) / np.maximum(ax, ay)
        k = sum((ratio > b).astype(np.int64) for b in _octant_bounds(steps))
        octant = (ay > ax) + 2 * np.signbit(x) + 4 * np.signbit(y)
        return (octant * (len(_octant_bounds(steps)) + 1) + k).astype(np.uint8)

    for real, cplx in ((np.float32, np.complex64), (np.float64, np.complex128)):
        r = [real(b) for b in _octant_bounds(steps)]
        r = [v for b in r for v in (np.nextafter(b, real(0)), b, np.nextafter(b, real(2)))]
        r = np.array(r + [0.0, 1.0], real)
        vals = [complex(sx * a, sy * b) for v in r for sx in (1, -1) for sy in (1, -1)
                for a, b in ((1.0, v), (v, 1.0), (3.0, float(real(3.0) * v)))]
        z = np.array(vals + [complex(-0.0, 0.0), complex(0.0, -0.0), 0j], cplx)
        np.testing.assert_array_equal(phase_codes(z, steps), reference(z))
        z2 = z[:len(z) // 4 * 4].reshape(4, -1)
        np.testing.assert_array_equal(phase_codes(z2, steps), reference(z2))


@pytest.mark.parametrize('steps', [4, 8, 12, 16, 20, 32, 60, 63])
def test_spike_step_is_the_rounded_phase(steps: int) -> None:
    """The octant-folded step (no arctan for 4 | T) is round(arg z T / 2 pi) mod T: on the
    axes and diagonals, just either side of every boundary, and against arctan2 in float64 on
    random values of both precisions (except within 1e-5 steps of a boundary)."""
    fixed = {1: 0, 1j: steps / 4, -1: steps / 2, -1j: 3 * steps / 4, 0: 0}
    for z, want in fixed.items():
        if float(want).is_integer():          # a tie (e.g. 1j with T = 6) is either neighbour
            assert phase_to_step(np.array([z], np.complex128), steps)[0] == int(want) % steps
    k = np.arange(steps)
    for off, add in ((0.4999, 0), (0.5001, 1), (-0.4999, 0), (-0.5001, -1)):
        z = 3.0 * np.exp(2j * np.pi * (k + off) / steps)
        np.testing.assert_array_equal(phase_to_step(z, steps), (k + add) % steps)
        np.testing.assert_array_equal(phase_to_step(z.astype(np.complex64), steps),
                                      (k + add) % steps)
    rng = np.random.default_rng(steps)
    z = rng.standard_normal(20000) + 1j * rng.standard_normal(20000)
    z[:100] *= 1e-30                                   # tiny and huge magnitudes
    z[100:200] *= 1e30
    z[200:210] = rng.standard_normal(10)               # on the real axis, both signs
    z[210:220] = 1j * rng.standard_normal(10)
    u = np.angle(z) * steps / (2 * np.pi)
    far = np.abs(np.abs(u - np.floor(u)) - 0.5) > 1e-5
    want = np.rint(u).astype(np.int64) % steps
    for zz in (z, z.astype(np.complex64)):
        got = phase_to_step(zz, steps)
        assert got.dtype == np.int64 and got.shape == z.shape
        np.testing.assert_array_equal(got[far], want[far])


@pytest.mark.parametrize('precision', ['float', 'loihi'])
@pytest.mark.parametrize('steps', [16, 32, 63])
def test_rf_neuron_fires_at_the_phase_of_its_summed_input(precision: str, steps: int) -> None:
    """A resonate-and-fire neuron kicked by phase-coded spikes ends the cycle at the phase of
    the complex sum; its output spike time reproduces that phase within 2π/T."""
    rng = np.random.default_rng(1)
    cfg = SpikingConfig(precision=precision, steps_per_cycle=steps)
    n_in, n_out = 12, 200
    phases = rng.uniform(-np.pi, np.pi, (n_out, n_in))
    t = phase_to_step(np.exp(1j * phases), steps)
    kicks = np.zeros((n_out, steps))
    g = rng.integers(1, 255, (n_out, n_in))
    np.add.at(kicks, (np.repeat(np.arange(n_out), n_in), t.ravel()), g.ravel())
    want = (g * np.exp(2j * np.pi * t / steps)).sum(axis=1)
    if precision == 'float':
        got = rf_cycle_float(kicks.astype(np.complex128))
    else:
        re, im, sat = rf_cycle_int((kicks * 64).astype(np.int64), np.zeros_like(kicks, np.int64),
                                   cfg)
        assert sat == 0
        got = (re + 1j * im) / 64
    # Naive per-step simulation of (RF) for a few neurons: the closed form is the same thing.
    for n in range(3):
        zn = 0j
        for step in range(steps):
            zn = np.exp(-2j * np.pi / steps) * (zn + kicks[n, step])
        np.testing.assert_allclose(zn, want[n], rtol=1e-9, atol=1e-9)
    mass = g.sum(axis=1)                         # fixed-point error relative to the input mass
    rel = np.abs(got - want) / mass
    assert rel.max() < (1e-9 if precision == 'float' else 0.01)
    strong = np.abs(want) > 0.2 * mass           # a clear phase (not a cancelled sum)
    out_t = phase_to_step(got[strong], steps)
    err = np.abs(wrap(2 * np.pi * out_t / steps - np.angle(want[strong])))
    assert strong.sum() > 50 and err.max() <= 2 * np.pi / steps


def test_integer_rf_neuron_rounds_and_saturates_by_hand() -> None:
    """T = 8, 6 fractional bits: c = s = round(cos 45° 2^6) = 45, rounding offset 32. One kick
    (100, 0) in the last step: (45 100 + 32) >> 6 = 70 and (-45 100 + 32) >> 6 = -70. With
    12 state bits the bound is 2047: a kick of 3000 gives (2109, -2109) before the clip, one
    saturated neuron-step. Random kicks: the step loop (with and without its checks) equals
    Python integers step by step."""
    cfg = SpikingConfig(steps_per_cycle=8, decay_bits=6, state_bits=12)
    assert rotation_constants(cfg) == (45, 45)
    kick = np.zeros((2, 8), np.int64)
    kick[0, 7] = 100
    re, im, sat = rf_cycle_int(kick[:1], kick[1:], cfg)
    assert (int(re[0]), int(im[0]), sat) == (70, -70, 0)
    kick[0, 7] = 3000
    re, im, sat = rf_cycle_int(kick[:1], kick[1:], cfg)
    assert (int(re[0]), int(im[0]), sat) == (2047, -2047, 1)

    def naive(kr: list[int], ki: list[int]) -> tuple[int, int, int]:
        r = i = n = 0
        for a, b in zip(kr, ki, strict=True):
            r, i = r + a, i + b
            r, i = (45 * r + 45 * i + 32) >> 6, (45 * i - 45 * r + 32) >> 6
            if abs(r) > 2047 or abs(i) > 2047:
                n += 1
                r, i = max(-2047, min(2047, r)), max(-2047, min(2047, i))
        return r, i, n

    rng = np.random.default_rng(5)
    for scale in (30, 600):                 # the loop without checks, then with saturations
        kr, ki = rng.integers(-scale, scale, (2, 50, 8))
        re, im, sat = rf_cycle_int(kr, ki, cfg)
        want = [naive(a.tolist(), b.tolist()) for a, b in zip(kr, ki, strict=True)]
        assert [(int(a), int(b)) for a, b in zip(re, im, strict=True)] == \
            [(a, b) for a, b, _ in want]
        assert sat == sum(n for _, _, n in want) and (sat > 0) == (scale == 600)


def test_graded_payload_and_binary_spikes() -> None:
    rng = np.random.default_rng(2)
    z = rng.uniform(0.0, 3.0, 400) * np.exp(1j * rng.uniform(-np.pi, np.pi, 400))
    sp = encode(z, SpikingConfig(payload_bits=8))
    unit = 2.0 ** sp.exp
    assert sp.g.max() <= 255
    assert np.abs(np.abs(sp.decode()) - np.abs(z)).max() <= unit / 2 + 1e-12
    binary = encode(z, SpikingConfig(payload_bits=1), fire_threshold=0.5)
    assert set(np.unique(binary.g)) == {0, 1}
    silent = np.abs(z) < 0.5 * np.abs(z).mean()
    np.testing.assert_array_equal(binary.g == 0, silent)


def test_encode_and_decode_by_hand() -> None:
    """z = (3, 0, 0.5i, -0.25) at T = 16: phases 0, -, 90° and 180° are steps 0, -, 4, 8.
    Graded, 4 bits: the largest magnitude 3 in 15 units needs the unit 2^-2 (3 / 2^-3 = 24
    would not fit), payloads 12, 0, 2, 1. A threshold of 0.6 times the mean magnitude
    0.9375 (0.5625) silences all but 3. Binary: the unit is the power of two nearest the firing
    neurons' mean magnitude (1.25: 2^0); decoding gives g 2^exp at the step's phase, 0 where
    g = 0 whatever its step."""
    z = np.array([3.0, 0.0, 0.5j, -0.25])
    graded = encode(z, SpikingConfig(steps_per_cycle=16, payload_bits=4, fire_threshold=0.0))
    assert (graded.exp, list(graded.g), list(graded.t[[0, 2, 3]])) == (-2, [12, 0, 2, 1],
                                                                       [0, 4, 8])
    np.testing.assert_allclose(graded.decode(), [3.0, 0.0, 0.5j, -0.25], atol=1e-15)
    np.testing.assert_allclose(graded.phasor(), [1.0, 0.0, 1j, -1.0], atol=1e-15)
    assert graded.count == 3
    cut = encode(z, SpikingConfig(steps_per_cycle=16, payload_bits=4), fire_threshold=0.6)
    assert list(cut.g) == [12, 0, 0, 0] and cut.exp == -2
    at = encode(np.array([1.0, 3.0]), SpikingConfig(payload_bits=4), fire_threshold=0.5)
    assert list(at.g) == [4, 12]        # |z| = 0.5 mean |z| exactly fires (unit 2^-2)
    binary = encode(z, SpikingConfig(steps_per_cycle=16, payload_bits=1, fire_threshold=0.0))
    assert (binary.exp, list(binary.g)) == (0, [1, 0, 1, 1])
    quiet = encode(np.zeros(3, complex), SpikingConfig(payload_bits=1))     # none fires
    assert (quiet.exp, quiet.count) == (0, 0)
    silent = Spikes(np.array([4, 4]), np.array([0, 2]), -1, 16)
    np.testing.assert_allclose(silent.decode(), [0.0, 1j], atol=1e-15)
    np.testing.assert_allclose(silent.phasor(), [0.0, 1j], atol=1e-15)


def test_payload_exponent_by_hand() -> None:
    """The smallest e with max / 2^e <= 2^B - 1: 255 at 8 bits is e = 0, 256 needs e = 1,
    1000 needs e = 2 (250); 0.1 at 4 bits e = -7 (12.8); nothing to send (0, negative, not
    finite) gives 0."""
    assert [payload_exponent(m, 8) for m in (255.0, 256.0, 1000.0)] == [0, 1, 2]
    assert payload_exponent(0.1, 4) == -7
    assert [payload_exponent(m, 8) for m in (0.0, -3.0, math.inf, math.nan)] == [0, 0, 0, 0]


@pytest.mark.parametrize('case', ['graded', 'threshold', 'binary', 'one', 'dtypes', 'wide'])
def test_encode_many_equals_encoding_each_population(case: str) -> None:
    """encode_many (one step pass over all the populations) gives the spikes of encode per
    population, also where it falls back to it (a threshold, binary payloads, one population,
    mixed precisions) and with wide neurons."""
    rng = np.random.default_rng(8)
    zs = [rng.normal(size=n) * 10.0 ** k + 1j * rng.normal(size=n) * 10.0 ** k
          for n, k in ((40, 0), (7, 2), (1, -3))]
    cfg = SpikingConfig(payload_bits=1 if case == 'binary' else 8, fire_threshold=0.0)
    thr = 0.8 if case == 'threshold' else None
    wides = [np.array([0]), None, None] if case == 'wide' else None
    if case == 'one':
        zs = zs[:1]
    if case == 'dtypes':
        zs[1] = zs[1].astype(np.complex64)
    many = encode_many(zs, cfg, fire_threshold=thr, wides=wides, wide_bits=12)
    for i, (z, sp) in enumerate(zip(zs, many, strict=True)):
        one = encode(z, cfg, fire_threshold=thr, wide=None if wides is None else wides[i],
                     wide_bits=12)
        assert sp.exp == one.exp, i
        np.testing.assert_array_equal(sp.g, one.g)
        np.testing.assert_array_equal(sp.t[sp.g > 0], one.t[one.g > 0])
    if case == 'threshold':
        assert any(np.count_nonzero(sp.g) < sp.g.size for sp in many)


def test_phase_codes_of_a_scalar_and_the_read_only_tables() -> None:
    """A 0-d value gets a 0-d code (its step: 45° at T = 16 is step 2); the cached step
    tables are read-only, so no caller can corrupt them for every other one."""
    code = phase_codes(np.asarray(np.exp(1j * np.pi / 4)), 16)
    assert code.shape == () and code_steps(16)[code] == 2
    assert not code_steps(16).flags.writeable and not code_steps(10).flags.writeable
    assert len(code_steps(16)) == 8 * (len(_octant_bounds(16)) + 1)


def test_a_wide_neuron_does_not_set_the_payload_unit_of_all() -> None:
    # hand-computed: rest max 3 -> 8-bit unit 2^ceil(log2(3/255)) = 2^-6; wide 100 in 12 bits
    # -> 2^ceil(log2(100/4095)) = 2^-5; the unit is the larger, 2^-5
    z = np.array([100.0, 3.0, 1.5, 0.2])
    cfg = SpikingConfig(payload_bits=8)
    sp = encode(z, cfg, wide=np.array([0]), wide_bits=12)
    assert sp.exp == -5
    np.testing.assert_array_equal(sp.g, [3200, 96, 48, 6])
    # without it the largest sets the unit 2^ceil(log2(100/255)) = 2^-1: 0.2 falls silent
    plain = encode(z, cfg)
    assert plain.exp == -1
    np.testing.assert_array_equal(plain.g, [200, 6, 3, 0])
    # a wide value beyond its 12 bits sets the unit itself: 2^ceil(log2(1000/4095)) = 2^-2
    big = encode(np.array([1000.0, 3.0, 1.5, 0.2]), cfg, wide=np.array([0]), wide_bits=12)
    assert big.exp == -2
    np.testing.assert_array_equal(big.g, [4000, 12, 6, 1])
    # wide_bits not above payload_bits: one unit for all, as without
    same = encode(z, cfg, wide=np.array([0]), wide_bits=8)
    assert same.exp == plain.exp


def test_stochastic_rounding_is_unbiased_where_the_nearest_holds_still() -> None:
    """Unit 2^-1 (the largest, 100, sets it: 2^ceil(log2(100/255))): 0.2 is 0.4 of a unit, so
    to the nearest it is silent in every cycle; rounded stochastically it fires with payload 1
    in 40 % of the cycles (mean 0.4 units = 0.2) and never with another payload; 100 = 200
    units exactly stays 200; a value at the top of the range never overflows it."""
    z = np.array([100.0, 0.2, 3.3])
    cfg = SpikingConfig(payload_bits=8)
    assert list(encode(z, cfg).g) == [200, 0, 7]
    rnd = Rounding(np.random.default_rng(4))
    gs = np.array([encode(z, cfg, rounding=rnd).g for _ in range(4000)])
    assert set(np.unique(gs[:, 0])) == {200} and set(np.unique(gs[:, 1])) == {0, 1}
    assert set(np.unique(gs[:, 2])) == {6, 7}
    # 4000 Bernoulli(0.4): std of the mean 0.0077; 3.3 = 6.6 units: 0.6 of them up
    assert gs[:, 1].mean() == pytest.approx(0.4, abs=0.025)
    assert gs[:, 2].mean() == pytest.approx(6.6, abs=0.025)
    top = np.array([255.0 * 0.5, 254.99 * 0.5])          # 255 and 254.99 units of 2^-1
    assert encode(top, cfg, rounding=rnd).exp == -1
    assert all(encode(top, cfg, rounding=rnd).g.max() <= 255 for _ in range(200))
    # the in-place form (the sparse transforms' float32 payloads) rounds the same way
    x = np.full(4000, 2.25, np.float32)
    Rounding(np.random.default_rng(5)).inplace(x)
    assert set(np.unique(x)) == {2.0, 3.0} and x.mean() == pytest.approx(2.25, abs=0.025)
    y = np.array([2.25, 2.5, 2.75], np.float32)
    NEAREST.inplace(y)
    assert list(y) == [2.0, 2.0, 3.0]                    # (half to even, as np.rint)
    # the same generator state gives the same payloads
    a = encode(z, cfg, rounding=Rounding(np.random.default_rng(9))).g
    b = encode(z, cfg, rounding=Rounding(np.random.default_rng(9))).g
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize('field', ['rounding', 'phase_rounding'])
def test_stochastic_rounding_reaches_every_population_and_repeats_with_the_seed(
        field: str) -> None:
    """The engine hands the network's generator to the cleanups and the sparse transforms'
    code, for the payloads (``rounding``) or the spike steps (``phase_rounding``) only; two
    networks of the same seed give the same estimates, another seed and the nearest others,
    all following the motion."""
    cfg = paper_config({})
    nearest = SpikingConfig(rounding='nearest', phase_rounding='nearest')
    sto = replace(nearest, **{field: 'stochastic'})
    rng = np.random.default_rng(0)
    scene = random_scene(rng)
    frames = [event_frame(scene, (0.4 * i, -0.3 * i, 0.004 * i, 0.0), rng) for i in range(12)]
    runs = {}
    for name, seed, scfg in (('a', 1, sto), ('b', 1, sto), ('c', 2, sto),
                             ('nearest', 1, nearest)):
        b = SpikingHRN(cfg, rng=np.random.default_rng(seed), spiking=scfg)
        est = [b.step(f, i * 5_000_000) for i, f in enumerate(frames)]
        eng = b._spiking_engine
        stochastic = name != 'nearest'
        assert (eng.rounding.rng is not None) == (stochastic and field == 'rounding')
        assert (eng.rounding.phase_rng is not None) == (stochastic and field != 'rounding')
        assert all(cl.rounding is eng.rounding for cl in eng.cleanups.values())
        assert eng.tf.code.rounding is eng.rounding             # (the sparse form)
        runs[name] = np.array([(e.h, e.v, e.r) for e in est])
    np.testing.assert_array_equal(runs['a'], runs['b'])
    assert not np.array_equal(runs['a'], runs['c'])
    assert not np.array_equal(runs['a'], runs['nearest'])
    # and they follow the same motion: 0.4 and -0.3 px per frame over 11 frames
    for name in runs:
        np.testing.assert_allclose(runs[name][-1, :2], [4.4, -3.3], atol=1.0)


def test_dithered_spike_steps_are_unbiased_where_the_nearest_holds_still() -> None:
    """T = 32 (steps of 11.25 deg): a phase of 3 deg (0.267 step) is sent at step 0 in every
    cycle to the nearest; dithered it is sent at step 1 in 26.7 % of the cycles and at step 0
    in the rest, never elsewhere; -3 deg goes to step 31 as often; a phase on a step stays on
    it. The payloads are not touched (the phases' generator is not the payloads')."""
    T = 32
    z = np.exp(1j * np.radians([3.0, -3.0, 2.0 * 11.25, 100.0]))
    cfg = SpikingConfig(steps_per_cycle=T)
    assert list(encode(z, cfg).t) == [0, 0, 2, 9]     # 100 deg = 8.89 steps
    rnd = Rounding(phase_rng=np.random.default_rng(3))
    ts = np.array([encode(z, cfg, rounding=rnd).t for _ in range(4000)])
    assert set(np.unique(ts[:, 0])) == {0, 1} and set(np.unique(ts[:, 1])) == {0, 31}
    assert set(np.unique(ts[:, 2])) == {2} and set(np.unique(ts[:, 3])) == {8, 9}
    # 4000 Bernoulli(0.267): std of the mean 0.007
    assert (ts[:, 0] == 1).mean() == pytest.approx(3.0 / 11.25, abs=0.025)
    assert (ts[:, 1] == 31).mean() == pytest.approx(3.0 / 11.25, abs=0.025)
    assert (ts[:, 3] == 9).mean() == pytest.approx(100.0 / 11.25 - 8.0, abs=0.025)
    np.testing.assert_array_equal(encode(z, cfg, rounding=rnd).g, encode(z, cfg).g)
    # without a generator the steps are phase_to_step's
    w = np.exp(1j * np.linspace(-np.pi, np.pi, 101))
    np.testing.assert_array_equal(Rounding().step(w, T), phase_to_step(w, T))


def test_state_shift_counts_each_neurons_largest_payload() -> None:
    q = QuantisedWeights(np.array([[100, 50]]), np.array([[0, 0]]), 0)
    cfg = SpikingConfig(payload_bits=8, state_bits=24)
    # worst 150 * 255 = 38250: floor(log2((2^23 - 1) / (1.125 * 38250))) = 7
    assert state_shift(q, cfg) == 7
    # 100 * 255 + 50 * 4095 = 230250: floor(log2((2^23 - 1) / (1.125 * 230250))) = 5
    assert state_shift(q, cfg, np.array([255, 4095])) == 5


# -- quantisation and Loihi limits -----------------------------------------------------------


def test_weight_quantisation_error_bounds() -> None:
    rng = np.random.default_rng(3)
    w = rng.normal(size=(40, 50)) + 1j * rng.normal(size=(40, 50))
    errors = []
    for bits in (4, 6, 8):
        q = quantise_weights(w, bits)
        top = (1 << (bits - 1)) - 1
        assert np.abs(q.re).max() <= top + 1 and np.abs(q.im).max() <= top + 1
        err = q.value() - w
        assert np.abs(err.real).max() <= 2.0 ** (q.exp - 1) + 1e-12
        assert np.abs(err.imag).max() <= 2.0 ** (q.exp - 1) + 1e-12
        largest = max(np.abs(w.real).max(), np.abs(w.imag).max())
        assert 2.0 ** q.exp <= 2 * largest / top                 # shared exponent is tight
        errors.append(np.abs(err).mean())
    assert errors[0] > errors[1] > errors[2]


def test_weights_shifts_and_kick_scaling_by_hand() -> None:
    """4-bit mantissas (-8..7): the largest component 1.0 needs the unit 2^-2 (1 / 2^-3 = 8
    would not fit), so 0.5 + 0.25i and -1 are (2 + 1i) and -4 of 2^-2; 1.9 is 4 of 2^-1.
    The state shift for a worst input of 1000 on 24 bits: floor(log2((2^23 - 1) / 1125)) =
    12, clipped to the Loihi range [-2, 13] for 10 (19) and 1e9 (-8), 13 for none. Integer
    kicks (held as floats) scaled by 2^shift: a right shift rounds half up (5 / 2 -> 3,
    -5 / 2 -> -2, 7 / 4 -> 2)."""
    q = quantise_weights(np.array([0.5 + 0.25j, -1.0]), 4)
    assert (q.exp, q.re.tolist(), q.im.tolist()) == (-2, [2, -4], [1, 0])
    one = quantise_weights(np.array([1.9]), 4)
    assert (one.exp, one.re.tolist()) == (-1, [4])
    assert quantise_weights(np.zeros(3), 8).exp == 0
    top = quantise_weights(np.array([7.0]), 4)      # the largest mantissa, 7, exactly
    assert (top.exp, top.re.tolist()) == (0, [7])
    imag = quantise_weights(np.array([0.1 + 1.0j, 0.1 + 0.1j]), 4)   # set by an imaginary part
    assert (imag.exp, imag.re.tolist(), imag.im.tolist()) == (-2, [0, 0], [4, 0])
    assert quantise_weights(np.array([1.0, -0.4]), 2).re.tolist() == [1, 0]   # 2 bits: -2..1
    with pytest.raises(ConfigError, match='at least 2 bits'):
        quantise_weights(np.ones(2), 1)
    cfg = SpikingConfig(state_bits=24)
    assert [_fit_shift(w, cfg) for w in (1000.0, 10.0, 1e9, 0.0)] == [12, 13, -2, 13]
    k = np.array([5, -5, 6, -6, 7], np.int64)
    for shift, want in ((0, [5, -5, 6, -6, 7]), (2, [20, -20, 24, -24, 28]),
                        (-1, [3, -2, 3, -3, 4]),
                        (-2, [1, -1, 2, -1, 2])):
        kf = k.astype(np.float64)
        scale_kicks_float(kf, shift)
        assert kf.tolist() == want


@pytest.mark.parametrize('synapse', ['kick', 'delay'])
def test_synapse_counts_by_hand(synapse: str) -> None:
    """One cycle of a 3 x 4 connection whose inputs 1 and 3 are silent (their steps do not
    matter): 2 spikes in (payloads 1 and 5), synaptic operations = the non-zero weights of the
    firing columns (3, and 2: column 2 has a zero weight), twice for complex kicks; every
    target updated at every step. A new LayerCounts is all zeros."""
    w = np.array([[1, 0, 1, 2], [1, 1, 0, 1], [1, 1, 1, 0]], complex)
    syn = ComplexSynapses(w, SpikingConfig(steps_per_cycle=16, synapse=synapse))
    sp = Spikes(np.array([0, 3, 5, 9]), np.array([1, 0, 5, 0]), 0, 16)
    counts = LayerCounts()
    assert (counts.spikes_in, counts.synops, counts.neuron_updates, counts.saturated) == \
        (0, 0, 0, 0)
    syn.count(sp, counts)
    per = 2 if synapse == 'kick' else 1
    assert (counts.spikes_in, counts.synops, counts.neuron_updates) == (2, per * 5, 3 * 16)


def test_spiking_cleanup_step_and_counts_by_hand() -> None:
    """Float integration, T = 16, codebook x0 = (1, 1, 1, 1), x1 = (1, i, -1, -i), θ = 0.1.
    u = 2 x1 is sent exactly (steps 0, 4, 8, 12; payload 128 of 2^-6); a = Re X^H u = (0, 8),
    the input mass 8, p = ReLU(a - 0.8) = (0, 7.2). The cleanup fires unit spikes (255 of
    2^-8) at the phases of X p = 7.2 x1; with no state yet both state inputs are that spike,
    so the new state is 255/256 x1. Counts per layer: input 4 spikes, 4 x 16 updates;
    similarity 4 spikes x 2 targets x 2 (complex kicks), 2 x 16 updates; the inhibitor 4
    spikes in, 4 + 2 operations, 16 updates; cleanup 1 spike x 4 targets x 2, 4 x 16;
    state 8 spikes (own + cleanup) x 2, 4 x 16. A second step with u = 2 x0 and γ = 0.5
    mixes the old state and the new cleanup spike half and half."""
    x = np.array([[1, 1], [1, 1j], [1, -1], [1, -1j]])
    cl = SpikingCleanup(x, SpikingConfig(precision='float', steps_per_cycle=16), gamma=0.5,
                        threshold=0.1)
    state, p = cl.step(2 * x[:, 1], None)
    np.testing.assert_allclose(p, [0.0, 7.2], atol=1e-12)
    assert state.exp == -8 and state.g.tolist() == [255] * 4
    np.testing.assert_allclose(state.decode(), 255 / 256 * x[:, 1], atol=1e-12)
    got = {k: (c.spikes_in, c.synops, c.neuron_updates) for k, c in cl.reset_counts().items()}
    assert got == {'input': (4, 0, 64), 'similarity': (4, 16, 32), 'threshold': (4, 6, 16),
                   'cleanup': (1, 8, 64), 'state': (8, 16, 64)}
    state2, p2 = cl.step(2 * x[:, 0], state)
    np.testing.assert_allclose(p2, [7.2, 0.0], atol=1e-12)
    want = 0.5 * 255 / 256 * (x[:, 0] + x[:, 1])
    assert np.abs(state2.decode() - want).max() <= 2.0 ** -9
    assert state2.g[2] == 0                                      # (-1 + 1) / 2: silent
    np.testing.assert_array_equal(state2.t[[0, 1, 3]], [0, 2, 14])   # 0, 45°, -45°
    # a p that needs max(a) counts a K-input max circuit instead of the inhibitor: K neurons
    # in, K² operations, K x T updates
    wta = SpikingCleanup(x, SpikingConfig(precision='float', steps_per_cycle=16), gamma=0.5,
                         p=lambda a: np.exp(a - a.max()), p_needs_max=True)
    _, p3 = wta.step(2 * x[:, 1], None)
    np.testing.assert_allclose(p3, [np.exp(-8.0), 1.0], rtol=1e-12)
    c = wta.counts['threshold']
    assert (c.spikes_in, c.synops, c.neuron_updates) == (2, 4, 32)


def test_delay_fan_in_and_range_limits_raise_config_errors() -> None:
    SpikingConfig(steps_per_cycle=63)                              # delays up to 62: allowed
    with pytest.raises(ConfigError, match='max_delay'):
        SpikingConfig(steps_per_cycle=64)
    with pytest.raises(ConfigError, match='steps_per_cycle <= 31'):
        SpikingConfig(steps_per_cycle=32, max_delay=30)
    with pytest.raises(ConfigError, match='max_delay'):
        SpikingConfig(max_delay=63)
    with pytest.raises(ConfigError, match='weight_bits'):
        SpikingConfig(weight_bits=9)
    cfg = SpikingConfig(max_fan_in=50)
    with pytest.raises(ConfigError, match='fan-in 60'):
        ComplexSynapses(np.ones((3, 60), complex), cfg)


@pytest.mark.parametrize('synapse', ['kick', 'delay'])
@pytest.mark.parametrize('precision', ['float', 'loihi'])
def test_complex_synapses_compute_the_matrix_product(synapse: str, precision: str) -> None:
    rng = np.random.default_rng(4)
    steps = 32
    cfg = SpikingConfig(precision=precision, synapse=synapse, steps_per_cycle=steps)
    w = np.exp(1j * rng.uniform(-np.pi, np.pi, (20, 30)))
    x = rng.uniform(0.5, 1.5, 30) * np.exp(1j * rng.uniform(-np.pi, np.pi, 30))
    sp = encode(x, cfg)
    counts = LayerCounts()
    got = ComplexSynapses(w, cfg).drive(sp, counts)
    want = w @ sp.decode()
    tol = 0.5 * np.pi / steps if synapse == 'delay' else 0.02
    assert np.abs(got - want).max() / np.abs(want).max() < 2 * tol + 0.02
    assert counts.synops == (2 if synapse == 'kick' else 1) * 30 * 20
    assert counts.neuron_updates == 20 * steps
    if synapse == 'delay':
        # Realised weights have phases on the 2π/T grid and magnitudes of the mantissa.
        eff = ComplexSynapses(w, cfg).effective
        k = np.angle(eff) * steps / (2 * np.pi)
        np.testing.assert_allclose(k, np.round(k), atol=1e-9)


@pytest.mark.parametrize('n_in', [30, 600])
@pytest.mark.parametrize('payload_bits', [8, 12])
def test_kicks_are_the_integer_sums(n_in: int, payload_bits: int) -> None:
    """The kicks (float32 or float64 products of payloads and mantissas) are exactly the
    integer sums of mantissa x payload per target and step, shifted into the state; also with
    payloads above the ones the connection was sized for (``tops``)."""
    rng = np.random.default_rng(n_in + payload_bits)
    cfg = SpikingConfig(steps_per_cycle=32, payload_bits=payload_bits, max_fan_in=1024)
    w = rng.uniform(0.2, 1.0, (40, n_in)) * np.exp(1j * rng.uniform(-np.pi, np.pi, (40, n_in)))
    for tops in (None, np.full(n_in, 3, np.int64)):
        syn = ComplexSynapses(w, cfg, tops=tops)
        q = syn._q
        assert q is not None
        t = rng.integers(0, 32, n_in)
        g = rng.integers(0, 1 << payload_bits, n_in)
        g[::7] = 0
        re, im = syn.kicks(Spikes(t, g, -3, 32))
        onehot = np.zeros((n_in, 32), np.int64)
        onehot[np.arange(n_in), t] = g
        for got, mant in ((re, q.re), (im, q.im)):
            want = mant @ onehot
            want = (want << syn._shift if syn._shift >= 0
                    else (want + (1 << (-syn._shift - 1))) >> -syn._shift)
            np.testing.assert_array_equal(got, want)


# -- network level ---------------------------------------------------------------------------


@pytest.mark.parametrize('precision', ['float', 'loihi'])
def test_spiking_resonator_factorises_a_bound_vector(precision: str) -> None:
    """Three factors from random codebooks, s = a ⊙ b ⊙ c: the spiking cleanups find them."""
    rng = np.random.default_rng(5)
    n, k = 400, 12
    books = [np.exp(1j * rng.uniform(-np.pi, np.pi, (n, k))) for _ in range(3)]
    truth = (3, 7, 10)
    s = books[0][:, truth[0]] * books[1][:, truth[1]] * books[2][:, truth[2]]
    cfg = SpikingConfig(precision=precision, steps_per_cycle=32, max_fan_in=n)
    cls = [SpikingCleanup(b, cfg, gamma=0.7, name=str(i)) for i, b in enumerate(books)]
    state: list[Spikes] = [encode(b.sum(axis=1), cfg, fire_threshold=0.0) for b in books]
    for _ in range(20):
        x = [sp.decode() for sp in state]
        new = []
        for i in range(3):
            others = [x[j].conj() for j in range(3) if j != i]
            out, _ = cls[i].step(s * others[0] * others[1], state[i])
            new.append(out)
        state = new
    found = tuple(int(np.argmax(np.real(b.conj().T @ sp.phasor())))
                  for b, sp in zip(books, state, strict=True))
    assert found == truth
    sims = [abs(np.vdot(b[:, t], sp.phasor())) / n
            for b, t, sp in zip(books, truth, state, strict=True)]
    assert min(sims) > 0.95


def track(b: SpikingHRN, traj: np.ndarray) -> np.ndarray:
    rng = np.random.default_rng(0)
    scene = random_scene(rng)
    out = [b.step(event_frame(scene, tuple(p), rng), i * 5_000_000) for i, p in enumerate(traj)]
    return np.array([(e.h, e.v, e.r) for e in out])


@pytest.mark.parametrize('spiking', [SpikingConfig(),
                                     SpikingConfig(precision='float'),
                                     SpikingConfig(steps_per_cycle=16, weight_bits=4),
                                     SpikingConfig(steps_per_cycle=63, synapse='delay'),
                                     SpikingConfig(transform='dense')],
                         ids=['loihi32', 'float32', 'loihi16w4', 'delay63', 'dense32'])
@pytest.mark.parametrize('pose', [(4.0, -3.0, 0.0), (0.0, 0.0, 0.35)])
def test_spiking_hrn_recovers_a_known_shift_and_roll(spiking: SpikingConfig,
                                                     pose: tuple[float, ...]) -> None:
    cfg = paper_config({'map': {'learn': False}})
    traj = np.array([(0.0, 0.0, 0.0, 0.0)] + [(*pose, 0.0)] * 40)
    b = SpikingHRN(cfg, rng=np.random.default_rng(1), spiking=spiking)
    est = track(b, traj)
    err = np.abs(est[-1] - np.asarray(pose))
    assert np.all(err <= (0.5, 0.5, 0.03)), (est[-1], pose)
    acc = b.account_summary()
    assert acc['spikes'] > 0 and acc['synops'] > acc['spikes']
    # iteration latency: the layers on the critical path (9 in the dense form)
    depth = 9 if b.transform == 'dense' else b._spiking_engine.resources.depth
    assert b.transform == spiking.transform
    assert acc['steps'] == depth * spiking.steps_per_cycle
    raster = b.raster()
    assert raster.shape == (2 * (cfg.width + cfg.height + 96), spiking.steps_per_cycle)
    # Every firing neuron fires once per cycle: at most one non-zero pixel per raster row.
    assert np.all((raster > 0).sum(axis=1) <= 1) and raster.max() > 0


def test_spiking_backend_needs_the_fast_path() -> None:
    cfg = paper_config({'path': 'dense'})
    with pytest.raises(ConfigError, match='path'):
        SpikingHRN(cfg, rng=np.random.default_rng(0))


# -- accounting ------------------------------------------------------------------------------


def test_accounting_energy_and_time_follow_the_counts() -> None:
    acc = IterationAccount(neurons=2048, steps=10, cores=2)
    acc.add_iteration(IterationAccount(layers={'a': LayerCounts(10, 1000, 500, 0)},
                                       neurons=2048, steps=10, cores=2))
    acc.add_iteration(IterationAccount(layers={'a': LayerCounts(30, 3000, 1500, 0)},
                                       neurons=2048, steps=10, cores=2))
    k = LoihiCosts()
    assert acc.iterations == 2 and acc.synops == 2000 and acc.spikes == 20
    assert math.isclose(acc.energy(), 2000 * k.e_synop + 1000 * k.e_neuron + 20 * k.e_spike)
    assert math.isclose(acc.time(), (1000 * k.t_neuron + 2000 * k.t_synop) / 2 + 10 * k.t_sync)
    ops = cpu_ops({'wc': 96, 'hc': 72, 'n_theta': 96, 'n_rho': 72, 'k_h': 96, 'k_v': 72,
                   'k_r': 96})
    # The dense path is dominated by ~5 dense N x N complex products (8 real ops per MAC).
    assert 4.5 * 8 * 6912**2 < ops['dense'] < 6 * 8 * 6912**2
    assert ops['fast'] < ops['dense'] / 100


def test_accounting_by_hand() -> None:
    """Idle updates: every one of 2048 neurons at each of 10 steps less the 1000 counted
    ones; the split by the transform marker; the summary's figures; saturations and means per
    iteration; cores; the CPU counts on a tiny network (canvas 4 x 2, log-polar 4 x 2, codebooks
    4, 2, 4): FFTs of 8 points 5 8 3 = 120 ops, per Λ 120 + 120 + 16 8 = 368, bindings
    48 8 = 384, the factor cleanups 2 8 (4 4 + 2 2 + 4 4) + 3 (8 8) = 768, so the fast
    path 120 + 4 368 + 384 + 768 = 2744 (2376 without the map update); the dense path
    8 64 + 4 (8 8 8) + 384 + (512 + 256 + 512) = 4224."""
    k = LoihiCosts()
    acc = IterationAccount(neurons=2048, steps=10, cores=2, iterations=2)
    acc.add('Λ: taps', LayerCounts(10, 1000, 500, 0))
    acc.add('h cleanup', LayerCounts(30, 3000, 1500, 4))
    assert acc.neuron_updates == 1000 and acc.saturated == 2
    assert acc.idle_updates == 2048 * 10 - 1000
    assert math.isclose(acc.idle_energy(), 19480 * k.e_neuron_idle)
    assert math.isclose(acc.idle_time(), 19480 * k.t_neuron_idle / 2)
    transforms, core = acc.split()
    assert (transforms.synops, core.synops, core.iterations) == (500, 1500, 2)
    summary = acc.summary()
    assert summary['synops_core'] == 1500 and summary['synops'] == 2000
    assert math.isclose(summary['energy_core_uJ'], core.energy() * 1e6)
    assert math.isclose(summary['energy_transforms_uJ'], transforms.energy() * 1e6)
    assert math.isclose(summary['time_idle_us'], acc.idle_time() * 1e6)
    assert math.isclose(summary['energy_idle_uJ'], acc.idle_energy() * 1e6)
    assert math.isclose(summary['energy_uJ'], acc.energy() * 1e6)
    assert math.isclose(summary['time_us'], acc.time() * 1e6)
    assert math.isclose(IterationAccount(neurons=10, steps=10, cores=1).idle_time(),
                        100 * k.t_neuron_idle)
    other = IterationAccount(neurons=2048, steps=10, cores=2, iterations=1)
    other.add('h cleanup', LayerCounts(0, 500, 0, 0))
    assert mean_account([]) == {}
    assert mean_account([acc, other])['synops'] == (2000 + 500) / 2
    assert [cores_for(n, 1024) for n in (0, 1024, 1025)] == [1, 1, 2]
    tiny = {'wc': 4, 'hc': 2, 'n_theta': 4, 'n_rho': 2, 'k_h': 4, 'k_v': 2, 'k_r': 4}
    assert cpu_ops(tiny) == {'fast': 2744.0, 'dense': 4224.0}
    assert cpu_ops(tiny, map_update=False)['fast'] == 2376.0
    # a log-polar grid of 4 x 3 (12 > 8: the larger size sets the resampling and bindings)
    ops = cpu_ops({**tiny, 'n_rho': 3})
    per_lambda = 120 + 5 * 12 * math.log2(12) + 16 * 12
    assert math.isclose(ops['fast'], 120 + 4 * per_lambda + 48 * 12 + 768)
    assert ops['dense'] == 8 * 64 + 4 * (8 * 8 * 12) + 48 * 12 + (512 + 256 + 2 * 8 * 12 * 4)


def test_spiking_imu_prediction_shifts_the_state_spikes_like_the_float_backend() -> None:
    """A gyro increment moves the spiking states (re-encoded spikes) as it moves the float ones."""
    from hrn_vo_ros.core.hrn.network import HRN
    focal = 80.0
    cfg = paper_config({'map': {'learn': False},
                                      'focal_px': focal, 'imu': {'enabled': True}})
    moved = (7.0, -5.0, 0.0, 0.0)
    gyro = np.array([-moved[1] / focal, moved[0] / focal, 0.0])   # camera turn for that shift
    out = {}
    for name, b in (('float', HRN(cfg, rng=np.random.default_rng(1))),
                    ('spiking', SpikingHRN(cfg, rng=np.random.default_rng(1)))):
        rng = np.random.default_rng(0)
        scene = random_scene(rng)
        for i in range(15):
            b.step(event_frame(scene, (0.0, 0.0, 0.0, 0.0), rng), i * 5_000_000)
        e = b.step(event_frame(scene, moved, rng), 15 * 5_000_000, gyro_delta=gyro)
        out[name] = np.array([e.h, e.v])
    np.testing.assert_allclose(out['spiking'], out['float'], atol=0.5)
    assert np.all(np.abs(out['spiking'] - moved[:2]) < 1.0), out


@pytest.mark.parametrize('precision', ['loihi', 'float'])
def test_the_dc_neuron_keeps_the_similarities_of_a_spectrum(precision: str) -> None:
    # The cross-power spectrum of a texture and its shifted copy: the DC element is ~800 x the
    # median one, as in the HRN's marginals. Silent or coarse small elements flatten the
    # similarity neurons' states; the DC neuron's wider payload keeps them.
    n = 64
    k = np.arange(n)
    X = np.exp(2j * np.pi * np.outer(k, k) / n)
    rng = np.random.default_rng(3)
    sig = (rng.random(n) < 0.3).astype(float)
    amp = np.abs(np.fft.fft(sig + np.roll(sig, 1) + np.roll(sig, -1) + 0.5)) ** 2
    errors, fired = {}, {}
    for bits in (8, 12):
        cl = SpikingCleanup(X, SpikingConfig(precision=precision, dc_payload_bits=bits),
                            gamma=1.0, p=lambda a: a)
        np.testing.assert_array_equal(cl._dc, [0] if bits > 8 else [])
        err = []
        for delta in np.linspace(3.1, 50.3, 30):
            u = amp * np.exp(2j * np.pi * k * delta / n)
            exact = (X.conj().T @ u).real
            cl.step(u, None)
            assert cl.last_similarity is not None and cl.last_input is not None
            d = cl.last_similarity - exact
            err.append(np.abs(d - d.mean()).max() / np.ptp(exact))
        errors[bits], fired[bits] = float(np.median(err)), cl.last_input.count
    # (up to a constant: it adds the same to every similarity) measured: 8 bits 0.155 (float
    # and loihi), 17 of 64 fire; 12 bits 0.033 (float) / 0.034 (loihi), 50 fire
    assert errors[12] < 0.05 < 0.12 < errors[8]
    assert fired[12] > 40 > 20 > fired[8]
    # a codebook without an entry-independent row has no DC neuron
    assert SpikingCleanup(X[1:], SpikingConfig(), gamma=1.0)._dc.size == 0


def test_drive_readout_uses_the_similarity_neurons() -> None:
    cfg = paper_config({'map': {'learn': False}, 'readout': {'source': 'drive'}})
    traj = np.array([(0.0, 0.0, 0.0, 0.0)] + [(4.0, -3.0, 0.0, 0.0)] * 30)
    b = SpikingHRN(cfg, rng=np.random.default_rng(1))
    est = track(b, traj)
    assert set(b._spiking_engine.drive) == {'h', 'v', 'r'}
    assert np.all(np.abs(est[-1] - (4.0, -3.0, 0.0)) <= (0.5, 0.5, 0.03)), est[-1]
