"""Sparse spiking transforms: butterfly stages, log-polar taps, conformance with the dense form."""

from __future__ import annotations

from dataclasses import replace
import math

from hrn_synth import event_frame, random_scene, trajectory
import numpy as np
import pytest

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.logpolar import LogPolarConfig, LogPolarTransform, make_geometry
from hrn_vo_ros.core.spiking import neurons
from hrn_vo_ros.core.spiking.backend import SpikingHRN
from hrn_vo_ros.core.spiking.butterfly import AxisDFT, radices
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.core.spiking.neurons import encode, rf_cycle_int, rotation_constants
from hrn_vo_ros.core.spiking.report import SYNOPS_TARGET
from hrn_vo_ros.core.spiking.sparse_engine import SparseSpikingEngine
from hrn_vo_ros.core.spiking.transforms import PhasorCode, SparseTransforms, weight_map
from hrn_vo_ros.errors import ConfigError

# The shapes_rotation geometry: 128x96 canvas around the 96x72 frame, 192x36 log-polar grid.
GEOM = make_geometry(96, 72, 128, 96, LogPolarConfig(n_theta=192, n_rho=36, r_min=4.0,
                                                     ring_weight=0.5))


def crandn(rng: np.random.Generator, *shape: int) -> np.ndarray:
    return rng.normal(size=shape) + 1j * rng.normal(size=shape)


# -- butterfly stages ------------------------------------------------------------------------


@pytest.mark.parametrize('n', [1, 2, 3, 4, 8, 12, 36, 96, 128, 192, 7, 10, 50])
@pytest.mark.parametrize('max_radix', [2, 4, 8])
@pytest.mark.parametrize('inverse', [False, True])
def test_butterfly_stages_are_the_dft(n: int, max_radix: int, inverse: bool) -> None:
    """Against numpy's FFT (an independent implementation), along both axes."""
    rng = np.random.default_rng(n)
    d = AxisDFT(n, inverse=inverse, max_radix=max_radix)
    assert int(np.prod(d.radices)) == n and max(d.radices, default=1) <= max(max_radix, 7)
    ref = np.fft.ifft if inverse else np.fft.fft
    for axis, shape in ((0, (n, 3)), (1, (5, n))):
        x = crandn(rng, *shape)
        np.testing.assert_allclose(d.apply(x, axis=axis), ref(x, axis=axis), atol=1e-9)
    x = crandn(rng, n)
    np.testing.assert_allclose(d.apply(x), ref(x), atol=1e-9)


@pytest.mark.parametrize('n', [8, 12, 96])
def test_stage_operation_counts_are_the_stage_matrices_nonzero_components(n: int) -> None:
    """Each stage as a dense matrix (the stage applied to the identity): its nonzero real and
    imaginary weight parts are the stage's operations when every input fires, and those in
    the columns of the inputs that fire otherwise; the axis's total is their sum."""
    d = AxisDFT(n)
    rng = np.random.default_rng(n)
    total = 0
    for s in d.stages:
        m = d.stage(np.eye(n, dtype=np.complex128), s)
        parts = (np.abs(m.real) > 1e-12).astype(int) + (np.abs(m.imag) > 1e-12)
        total += int(parts.sum())
        assert d.spike_synops(np.ones((n, 1), bool), s) == parts.sum()
        live = rng.random(n) < 0.4
        assert d.spike_synops(live[:, None], s) == parts[:, live].sum()
    assert d.components == total


def test_synapse_counts_grow_as_n_log_n() -> None:
    assert radices(128) == [4, 4, 4, 2] and radices(96) == [4, 4, 2, 3]
    assert radices(128, max_radix=2) == [2] * 7
    d = AxisDFT(128)
    assert d.synapses == 128 * 14 < 128 * 128 / 4
    with pytest.raises(ConfigError, match='prime factor 11'):
        radices(22)


def test_a_wrong_twiddle_is_caught() -> None:
    """One perturbed weight of one stage changes the transform far beyond rounding."""
    rng = np.random.default_rng(0)
    x = crandn(rng, 96, 4)
    d = AxisDFT(96)
    s = d.stages[2]
    s.weights[0, 1, 3] *= np.exp(0.05j)
    assert np.abs(d.apply(x, axis=0) - np.fft.fft(x, axis=0)).max() > 1e-3


@pytest.mark.parametrize('synapse', ['kick', 'delay'])
def test_quantised_stages_factorised_equal_composite_weights(synapse: str) -> None:
    """Radix 2 and 4 run as realised twiddles times an exact F_r: the same layer as the
    realised composite weights (kick); delays use the composite weights."""
    rng = np.random.default_rng(1)
    cfg = SpikingConfig(weight_bits=6, synapse=synapse)
    x = crandn(rng, 128, 8)
    fast = AxisDFT(128, weight_map=weight_map(cfg), factorised=synapse == 'kick')
    slow = AxisDFT(128, weight_map=weight_map(cfg), factorised=False)
    np.testing.assert_allclose(fast.apply(x, 0), slow.apply(x, 0), atol=1e-9)
    err = np.abs(slow.apply(x, 0) - np.fft.fft(x, axis=0)).max() / np.abs(x).sum(axis=0).max()
    assert 1e-4 < err < 0.1               # really quantised, and still the DFT


# -- phasor code and integer dynamics --------------------------------------------------------


@pytest.mark.parametrize('steps', [16, 32, 63])
def test_phasor_code_is_the_neuron_code(steps: int) -> None:
    rng = np.random.default_rng(steps)
    z = crandn(rng, 500)
    cfg = SpikingConfig(precision='float', steps_per_cycle=steps)
    got = PhasorCode(cfg).fire(z.astype(np.complex64))
    # the transforms' populations send on cfg.transform_bits, the neuron code's payload_bits
    # elsewhere: the same code at that width (both 8 by default)
    ref = encode(z, replace(cfg, payload_bits=cfg.transform_bits))
    np.testing.assert_allclose(got, ref.decode(), rtol=1e-5, atol=1e-5)


def test_transform_populations_send_on_their_own_payload_width() -> None:
    # hand-computed: largest 100 on 12 bits -> unit 2^ceil(log2(100/4095)) = 2^-5, so 0.2
    # carries round(0.2 * 32) = 6 units; on 8 bits the unit is 2^ceil(log2(100/255)) = 2^-1
    # and 0.2 rounds to silence
    z = np.array([100.0, 3.0, 0.2], np.complex64)
    for bits, unit, g in ((12, 2.0**-5, [3200, 96, 6]), (8, 0.5, [200, 6, 0])):
        cfg = SpikingConfig(precision='float', transform_payload_bits=bits)
        assert cfg.payload_bits == 8 and cfg.widest_payload == 12
        got = PhasorCode(cfg).fire(z.copy())
        np.testing.assert_allclose(got.real, np.array(g) * unit, rtol=1e-6)
    assert SpikingConfig().transform_payload_bits == 8
    assert SpikingConfig(transform_payload_bits=16).widest_payload == 16
    assert SpikingConfig(transform_payload_bits=16, transform='dense').widest_payload == 12
    # binary spikes stay binary everywhere (the Loihi 1 code)
    binary = SpikingConfig(payload_bits=1, transform_payload_bits=12)
    assert binary.transform_bits == 1 and binary.widest_payload == 1


def test_dense_frames_keep_their_spectrum_on_12_bit_payloads() -> None:
    """A dense frame (about 2000 of 6912 pixels on, as the textured draws of the rotation family
    where the spiking backend lost track): on 8-bit payloads the 2-D spectra's DC sets the
    unit and a fifth of Λ''s output neurons and a tenth of the map population's round to
    silence (measured 0.23 and 0.12); on 12 bits almost none do (0.0009, 0.0005), and the error
    against the float transform falls (measured 0.183 -> 0.153 and 0.117 -> 0.054)."""
    from scipy.ndimage import gaussian_filter
    rng = np.random.default_rng(3)
    tex = gaussian_filter(rng.normal(size=(GEOM.canvas_height, GEOM.canvas_width)), 2.0)
    edge = np.hypot(*np.gradient(tex))
    ox, oy = GEOM.offset
    inner = (slice(oy, oy + GEOM.height), slice(ox, ox + GEOM.width))
    canvas = np.zeros_like(edge)
    canvas[inner] = edge[inner] > np.quantile(edge[inner], 0.7)
    assert 1900 < canvas.sum() < 2200
    lp = LogPolarTransform(GEOM)
    want = lp.reverse_theta(np.fft.fft(lp.lp_image(canvas), axis=1))
    m = np.fft.fft2(canvas).astype(np.complex64)
    out = {}
    for bits in (8, 12):
        cfg = SpikingConfig(transform_payload_bits=bits)
        tf = SparseTransforms(GEOM, cfg)
        rev = tf.reverse(tf.frame(canvas))
        mp = PhasorCode(cfg).fire(m.copy())
        out[bits] = (float(np.mean(rev == 0)), rel(rev, want), float(np.mean(mp == 0)),
                     rel(mp, m))
    assert out[8][0] > 0.2 and out[8][2] > 0.1, out
    assert out[12][0] < 0.002 and out[12][2] < 0.002, out
    assert out[12][1] < 0.9 * out[8][1] and out[12][3] < 0.5 * out[8][3], out


def test_loihi_phase_table_is_the_fixed_point_rotation() -> None:
    """A spike at step t ends the cycle turned by rho^(T - t), rho the RF-int rotation."""
    cfg = SpikingConfig(steps_per_cycle=32)
    code = PhasorCode(cfg)
    for t in (0, 5, 31):
        kre = np.zeros((1, 32), np.int64)
        kre[0, t] = 1 << 20
        re, im, _ = rf_cycle_int(kre, np.zeros_like(kre), cfg)
        np.testing.assert_allclose((re[0] + 1j * im[0]) / 2**20, code.table[t], atol=1e-4)


def test_unchecked_rf_loop_equals_the_checked_one() -> None:
    rng = np.random.default_rng(2)
    cfg = SpikingConfig(steps_per_cycle=32)
    c, s = rotation_constants(cfg)
    kre, kim = (rng.integers(-5000, 5000, (50, 32)) for _ in range(2))
    kicks = np.stack([kre.T, kim.T], axis=1).astype(np.float64)        # (T, 2, n)
    fast = neurons._rf_loop_unchecked(kicks, c, s, cfg.decay_bits, 1 << (cfg.decay_bits - 1))
    re, im = np.zeros(50, np.int64), np.zeros(50, np.int64)
    for t in range(32):
        re, im = re + kre[:, t], im + kim[:, t]
        re, im = ((c * re + s * im + 2048) >> 12, (c * im - s * re + 2048) >> 12)
    np.testing.assert_array_equal(fast[0], re)
    np.testing.assert_array_equal(fast[1], im)
    big = np.full((3, 32), 1 << 22, np.int64)        # saturates: the checked loop runs
    assert rf_cycle_int(big, big, cfg)[2] > 0


# -- the transforms against the float fast path ----------------------------------------------


def frame_canvas(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = event_frame(random_scene(rng), (0.0, 0.0, 0.0, 0.0), rng)
    canvas = np.zeros((GEOM.canvas_height, GEOM.canvas_width))
    ox, oy = GEOM.offset
    canvas[oy:oy + GEOM.height, ox:ox + GEOM.width] = img
    return canvas


def test_transform_wiring_is_the_fast_path_exactly(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the neurons' code replaced by the identity, the spiking layers are exactly the
    float fast path's Λ, Λ' (FFTs and the sparse matrices of core/hrn/logpolar.py): a wrong
    tap, twiddle or axis fails here."""
    tf = SparseTransforms(GEOM, SpikingConfig(precision='float'))
    monkeypatch.setattr(tf.code, 'fire', lambda z: np.asarray(z, np.complex64))
    lp = LogPolarTransform(GEOM)
    canvas = frame_canvas()
    S = tf.frame(canvas)
    want_S = np.fft.fft(lp.lp_image(canvas), axis=1)
    np.testing.assert_allclose(S, want_S, rtol=0, atol=1e-4 * np.abs(want_S).max())
    q = crandn(np.random.default_rng(3), GEOM.n_rho, GEOM.n_theta).astype(np.complex64)
    want_p = lp.reverse_theta(q.astype(np.complex128))
    np.testing.assert_allclose(tf.reverse(q), want_p, atol=1e-4 * np.abs(want_p).max())
    m = np.fft.fft2(canvas).astype(np.complex64)
    want_l = lp.forward_theta(m.astype(np.complex128))
    np.testing.assert_allclose(tf.forward(m), want_l, atol=1e-4 * np.abs(want_l).max())


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def test_spiking_transforms_error_is_the_phase_grid_and_payloads() -> None:
    """Stated tolerance (T = 32, 8-bit weights and payloads; measured 0.090 / 0.182 / 0.167 on
    a frame): the relative error of S, Λ' and Λ stays below 0.15 / 0.3 / 0.2 and halves roughly
    with T doubled (the phase grid is the main error)."""
    lp = LogPolarTransform(GEOM)
    canvas = frame_canvas(1)
    m = np.fft.fft2(canvas)
    err = {}
    for steps in (16, 32, 63):
        tf = SparseTransforms(GEOM, SpikingConfig(steps_per_cycle=steps))
        S = tf.frame(canvas)
        Sf = np.fft.fft(lp.lp_image(canvas), axis=1)
        # (forward_theta overwrites its argument: a copy, so that every T sees the map)
        err[steps] = (rel(S, Sf), rel(tf.reverse(S), lp.reverse_theta(Sf)),
                      rel(tf.forward(m.astype(np.complex64)), lp.forward_theta(m.copy())))
    assert err[32] < (0.15, 0.3, 0.2), err
    assert all(err[63][i] < 0.8 * err[32][i] < 0.8 * err[16][i] for i in range(3)), err


def test_counts_follow_the_spikes() -> None:
    cfg = SpikingConfig()
    tf = SparseTransforms(GEOM, cfg)
    S = tf.frame(frame_canvas(2))
    tf.reset_counts()
    tf.reverse(S)
    c = tf.reset_counts()
    stages = c["Λ': fft_y stages"]
    assert 0 < stages.spikes_in <= 4 * GEOM.n_cart
    assert stages.spikes_in <= stages.synops <= 2 * 4 * stages.spikes_in
    assert stages.neuron_updates == 4 * GEOM.n_cart * cfg.steps_per_cycle
    full = sum(row[3] for row in tf.layers() if row[0].startswith("Λ': fft_y"))
    assert stages.synops <= full


def test_tap_layer_counts_the_taps_of_the_firing_inputs() -> None:
    """A tap layer's synaptic operations are the nonzero weights in the columns of the inputs
    that fire, counted here from the realised matrix itself; all inputs firing is every tap."""
    tf = SparseTransforms(GEOM, SpikingConfig())
    layer = tf.T
    rng = np.random.default_rng(2)
    x = (rng.normal(size=layer.matrix.shape[1]) * (rng.random(layer.matrix.shape[1]) < 0.3)
         ).astype(np.complex64)
    live = int(np.count_nonzero(x))
    tf._taps(layer, x, live, 'taps')
    want = int((layer.matrix[:, np.flatnonzero(x)] != 0).sum())
    c = tf.reset_counts()['taps']
    assert (c.spikes_in, c.synops, c.neuron_updates) == (
        live, want, layer.matrix.shape[0] * SpikingConfig().steps_per_cycle)
    full = np.ones(layer.matrix.shape[1], np.complex64)
    tf._taps(layer, full, full.size, 'taps')
    assert tf.reset_counts()['taps'].synops == layer.matrix.nnz == layer.synapses


@pytest.mark.parametrize('fire_input', [True, False])
@pytest.mark.parametrize('bits', [8, 1])
def test_stage_counts_are_the_firing_inputs_operations(fire_input: bool, bits: int) -> None:
    """The operations of an axis's butterfly stages: per stage, those of the inputs that fire
    (``AxisDFT.spike_synops`` of the firing pattern, stage by stage, as a reference), with
    silent inputs at every stage (a sparse spectrum); the input's silent neurons are read from
    it (a binding population) or after the code fired it, the later stages' from the code's
    list (graded payloads) or from the firing pattern (binary spikes: no list)."""
    rng = np.random.default_rng(3)
    q = np.asarray(np.fft.fft2(frame_canvas(2)), np.complex64)
    q[rng.random(q.shape) < 0.5] = 0.0
    cfg = SpikingConfig(payload_bits=bits)
    tf = SparseTransforms(GEOM, cfg)
    tf.code.last_count = int(np.count_nonzero(q))       # as if the code had just fired q
    tf._axis(q.copy(), 'iy', 0, 'A', fire_input=fire_input)
    got = tf.reset_counts()['A']
    ax, ref = tf.axes['iy'], SparseTransforms(GEOM, cfg)
    front, want, spikes = ax.to_front(q.copy(), 0), 0, 0
    for s in ax.stages:
        want += ax.spike_synops(front != 0, s)
        spikes += int(np.count_nonzero(front))
        front = ref.code.fire(ax.stage(front, s))
    assert (got.spikes_in, got.synops) == (spikes, want)
    assert spikes < len(ax.stages) * q.size                    # some were silent


def test_depth_counts_the_layers_on_each_path() -> None:
    """One cycle per layer: Λ' and Λ pass through as many layers as ``layers()`` lists under
    their names (the stages of two axes, a tap layer, the stages of a third)."""
    tf = SparseTransforms(GEOM, SpikingConfig())
    names = [row[0] for row in tf.layers()]
    assert tf.depth() == (sum(n.startswith("Λ'") for n in names),
                          sum(n.startswith('Λ:') for n in names))


# -- the sparse backend ----------------------------------------------------------------------


def run(b: SpikingHRN, frames: list[np.ndarray]) -> np.ndarray:
    return np.array([(e.h, e.v, e.r) for e in
                     (b.step(f, i * 5_000_000) for i, f in enumerate(frames))])


def test_sparse_form_conforms_to_the_dense_form_on_the_same_frames() -> None:
    """Conformance (stated tolerance, near what a 10 s simulated sequence gives: 0.08 deg,
    0.04 px median): on 80 synthetic frames of a known smooth motion, the sparse and the dense
    spiking forms agree within median 0.5 deg of roll and 0.3 px of h and v after 20 frames,
    and both within the same of the float backend."""
    from hrn_vo_ros.core.hrn.network import HRN
    cfg = from_dict(ResonatorConfig, {'cleanup': {'gamma': 0.6},
                                      'map': {'mu1': 0.99, 'mu2': 0.002}})
    rng = np.random.default_rng(5)
    scene = random_scene(rng)
    traj = trajectory(80, amp_xy=8.0, amp_roll=0.3, period=200.0)
    frames = [event_frame(scene, tuple(p), rng) for p in traj]
    sparse = SpikingHRN(cfg, rng=np.random.default_rng(0))
    assert sparse.transform == 'sparse'
    dense = SpikingHRN(cfg, rng=np.random.default_rng(0),
                       spiking=SpikingConfig(transform='dense'))
    out = {'sparse': run(sparse, frames), 'dense': run(dense, frames),
           'float': run(HRN(cfg, rng=np.random.default_rng(0)), frames)}
    for a, b in (('sparse', 'dense'), ('sparse', 'float'), ('dense', 'float')):
        d = np.abs(out[a][20:] - out[b][20:])
        d[:, 2] = np.degrees(np.abs((d[:, 2] + np.pi) % (2 * np.pi) - np.pi))
        med = np.median(d, axis=0)
        assert med[0] <= 0.3 and med[1] <= 0.3 and med[2] <= 0.5, (a, b, med)
    truth = traj[20:, :3]
    assert np.median(np.abs(out['sparse'][20:, :2] - truth[:, :2])) < 1.0


def test_sparse_network_fits_one_loihi2_chip_within_the_synops_target() -> None:
    cfg = from_dict(ResonatorConfig, {
        'codebook': {'canvas_width': 128, 'canvas_height': 96},
        'logpolar': {'n_theta': 192, 'n_rho': 36, 'r_min': 4.0, 'ring_weight': 0.5},
        'cleanup': {'iterations_per_frame': 2}})
    b = SpikingHRN(cfg, rng=np.random.default_rng(0))
    eng = b._spiking_engine
    assert isinstance(eng, SparseSpikingEngine)
    res = eng.resources
    assert res.violations() == [] and res.chips == 1, res.violations()
    assert res.components < 4 * GEOM.n_cart * GEOM.n_lp / 100    # dense Λ/Λ' synapses / 100
    rng = np.random.default_rng(0)
    scene = random_scene(rng)
    for i in range(6):
        b.step(event_frame(scene, (0.5 * i, 0.0, 0.0, 0.0), rng), i * 5_000_000)
    acc = b.account_summary()
    assert 1e5 < acc['synops'] <= SYNOPS_TARGET, acc
    assert acc['cores'] == res.cores and acc['steps'] == res.depth * b.spiking.steps_per_cycle
    assert acc['energy_uJ'] > 0 and acc['energy_idle_uJ'] > 0 and acc['time_us'] > 0


def test_scale_factor_configs_run_the_dense_form() -> None:
    cfg = from_dict(ResonatorConfig, {'scale': {'enabled': True}})
    assert SpikingHRN(cfg, rng=np.random.default_rng(0)).transform == 'dense'


def test_batched_cleanups_equal_one_factor_at_a_time() -> None:
    """step_many runs the factors' layers as one population each: the same states."""
    from hrn_vo_ros.core.spiking.cleanup import SpikingCleanup, step_many
    rng = np.random.default_rng(7)
    cfg = SpikingConfig()
    books = {n: np.exp(2j * np.pi * np.outer(np.arange(n), np.arange(n) - n // 2) / n)
             for n in (12, 16, 20)}

    def make() -> list[SpikingCleanup]:
        return [SpikingCleanup(x, cfg, gamma=0.7, name=str(n), p=lambda a: np.maximum(a, 0))
                for n, x in books.items()]

    us = [crandn(rng, n) for n in books]
    one = [cl.step(u, None) for cl, u in zip(make(), us, strict=True)]
    many = step_many([(cl, u, None) for cl, u in zip(make(), us, strict=True)])
    for (a, pa), (b, pb) in zip(one, many, strict=True):
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.g, b.g)
        np.testing.assert_array_equal(pa, pb)


def test_phasor_code_threshold_and_binary_spikes_match_the_neuron_code() -> None:
    rng = np.random.default_rng(9)
    z = crandn(rng, 400)
    for cfg in (SpikingConfig(precision='float', fire_threshold=0.5),
                SpikingConfig(precision='float', payload_bits=1, fire_threshold=0.5)):
        got = PhasorCode(cfg).fire(z.astype(np.complex64))
        np.testing.assert_allclose(got, encode(z, cfg).decode(), rtol=1e-5, atol=1e-5)


def test_phasor_code_counts_and_thresholds_by_hand() -> None:
    """Nothing fired yet, or nothing to send: count 0, zeros out. A threshold of 0.5 times
    the mean magnitude 2 of (1, 3) is met exactly by 1: both fire, graded (8 bits: unit 2^-6,
    1 and 3 exact) and binary; of (0.1, 3, 2) the first is below it, the one silent neuron
    listed. Binary (0, 2): the zero stays silent and the unit is the firing neuron's
    magnitude, 2."""
    for bits in (8, 1):
        cfg = SpikingConfig(precision='float', transform_payload_bits=bits,
                            payload_bits=bits, fire_threshold=0.5)
        code = PhasorCode(cfg)
        assert code.last_count == 0
        np.testing.assert_array_equal(code.fire(np.zeros(3, np.complex64)), np.zeros(3))
        assert code.last_count == 0
        got = code.fire(np.array([1.0, 3.0j], np.complex64))
        assert code.last_count == 2
        np.testing.assert_allclose(got, [1.0, 3.0j] if bits == 8 else [2.0, 2.0j], atol=1e-6)
    graded = PhasorCode(SpikingConfig(precision='float', fire_threshold=0.5))
    graded.fire(np.array([0.1, 3.0, 2.0], np.complex64))     # 0.1 < 0.5 x 1.7: silent
    assert graded.last_count == 2 and graded.last_silent is not None
    assert graded.last_silent.tolist() == [0]
    binary = PhasorCode(SpikingConfig(precision='float', payload_bits=1,
                                      transform_payload_bits=1))
    np.testing.assert_allclose(binary.fire(np.array([0.0, -2.0], np.complex64)), [0.0, -2.0],
                               atol=1e-6)
    assert binary.last_count == 1


def test_payload_probe_measures_the_rounding_against_wide_payloads() -> None:
    # hand-computed: on 8 bits the unit is 2^ceil(log2(1000/255)) = 4, so 1000 carries 250
    # units and 1 rounds to silence; on 24 bits both are exact. Error 1/sqrt(1000^2 + 1),
    # one neuron of two silenced. On 12 bits (unit 2^-2) both are exact: no error.
    from hrn_vo_ros.core.spiking.report import PayloadProbe
    z = np.array([1000.0, 1.0], np.complex64)
    for bits, err, silenced in ((8, 1 / math.hypot(1000, 1), 0.5), (12, 0.0, 0.0)):
        cfg = SpikingConfig(transform_payload_bits=bits)
        code, probe = PhasorCode(cfg), PayloadProbe(cfg)
        code.probe, code.label = probe, 'two neurons'
        out = code.fire(z)
        assert np.count_nonzero(out) == (1 if bits == 8 else 2)
        ((label, got_err, got_silenced, fires),) = probe.rows()
        assert (label, fires, got_silenced) == ('two neurons', 1, silenced)
        assert got_err == pytest.approx(err, rel=1e-4, abs=1e-9)


def test_payload_errors_cover_every_transform_population() -> None:
    """On known-motion frames: every population of S, Λ', Λ and the map update is probed; on
    24-bit payloads nothing differs from the reference; on 8 bits the last fft_x stage of Λ'
    is among the worst (its 2-D spectrum's DC sets the unit)."""
    from hrn_vo_ros.core.hrn.config import paper_config
    from hrn_vo_ros.core.spiking.report import payload_errors, payload_lines
    cfg = paper_config()
    rng = np.random.default_rng(2)
    scene = random_scene(rng)
    imgs = np.array([event_frame(scene, tuple(p), rng)
                     for p in trajectory(6, amp_xy=3.0, amp_roll=0.1, period=50.0)])
    t = np.arange(len(imgs), dtype=np.int64) * 5_000_000
    rows = {}
    for bits in (8, 24):
        scfg = SpikingConfig(transform_payload_bits=bits)
        probe = payload_errors(cfg, scfg, t, imgs)
        rows[bits] = {label: (err, silenced) for label, err, silenced, _ in probe.rows()}
        assert payload_lines(probe, scfg)[0].startswith(f'payload rounding per population '
                                                        f'of the sparse transforms ({bits}-bit')
    labels = set(rows[8])
    assert {'S: pixels', 'S: T taps (pixels → log-polar)', "Λ': T' taps", 'Λ: T taps',
            'map population', "map: Λ': T' taps"} <= labels
    assert any(label.startswith("Λ': fft_x stages ") for label in labels), labels
    assert set(rows[24]) == labels
    assert all(err == 0.0 and silenced == 0.0 for err, silenced in rows[24].values()), rows[24]
    worst = sorted(rows[8], key=lambda k: -rows[8][k][0])[:4]
    assert any(k.startswith("Λ': fft_x stages") for k in worst), rows[8]
    # binary pixels are exact on any width; every other population rounds
    assert rows[8]['S: pixels'] == (0.0, 0.0)
    assert all(err > 0.0 for k, (err, _) in rows[8].items() if k != 'S: pixels'), rows[8]
