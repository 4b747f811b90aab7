"""The hierarchical resonator network (HRN) for event-camera odometry, Model A (hrn_math.md §2.3).

Public API (engineers D and E code against this; stable):

* ``ResonatorConfig`` (nested: ``codebook``, ``logpolar``, ``cleanup``, ``map``, ``readout``,
  ``scale``, ``imu``, ``sphere``), frozen, validated, YAML/ROS-parameter ready (``configbase``).
* ``HRN(cfg: ResonatorConfig | None = None, *, rng: np.random.Generator)``
    - ``step(image: NDArray (H, W), t_ns: int, *, gyro_delta: NDArray (3,) | None = None)
      -> Estimate`` — one event frame; ``gyro_delta`` is the integrated gyro (rad, camera axes
      x right / y down / z forward) since the previous frame (``core.imu.GyroIntegrator``).
    - ``map_image() -> NDArray (H_c, W_c) float64`` — the map as an intensity image (canvas).
    - ``egocentric_map_image() -> NDArray (H_c, W_c)`` — the map moved to the current view.
    - ``readout_axis(name) -> NDArray (K,)`` — physical value of each similarity entry.
    - ``factors: tuple[str, ...]`` (``('h', 'v', 'r')`` or with ``'z'``), ``iteration: int``,
      ``geometry: logpolar.Geometry``, ``reset()``.
* ``Estimate`` (``core.estimate``): ``t_ns, h, v, r, z, confidence, spread, iteration,
  map_updated, similarity, valid``.
* Pieces for the spiking backend: ``cleanup_weights(c, cfg)`` (the nonlinearity p),
  ``population_readout(sim, half_window, circular)``, ``FactorCodebook`` (1-D FPE codebooks),
  ``fhrr`` (seeds, powers, phasor projection), ``logpolar`` (T, T', Λ, Λ' fast and dense).

Model (A: camera-centred roll, Cartesian map), with C_X(u) = f(X p(Re X† u)), f = phasor
projection, every state update x̂ ← (1-γ) x̂ + γ C_X(·), Λ: Cartesian → log-polar, Λ': back::

    generative:  s ≈ Λ'( Λ(m ⊙ h ⊙ v) ⊙ r [⊙ z] )
    S  = Λ(s)                                   (s = Φ I, the frame encoded, paper Eq. 3)
    p̂ = Λ'( S ⊙ r̂* [⊙ ẑ*] )                    (input with roll/zoom removed)
    ĥ ← C_H( p̂ ⊙ v̂* ⊙ m̂* ) ;  v̂ ← C_V( p̂ ⊙ ĥ* ⊙ m̂* )            (paper Eq. 4, h and v)
    l̂ = Λ( m̂ ⊙ ĥ ⊙ v̂ )                        (map moved to the camera, log-polar)
    r̂ ← C_R( S ⊙ l̂* [⊙ ẑ*] ) ;  ẑ ← C_Z( S ⊙ l̂* ⊙ r̂* )             (paper Eq. 4, r)
    m(t) = Λ'( S ⊙ r^{-r_o} [⊙ z^{-z_o}] ) ⊙ h^{-h_o} ⊙ v^{-v_o}     (paper Eq. 8, Model A form)
    m̂ ← μ1 m̂ + μ2 m̂(0) + (1-μ1-μ2) m(t) ;  m̂(0) = s(0)            (paper Eq. 9)

All states are updated synchronously from the previous iterate (as Eq. 4 is written).

Why Model A: it is the paper's Eq. 4 after the notational fixes, h/v come out directly as the
camera position in the allocentric map (what the paper calibrates with a fixed Umeyama
transform), and the roll is about the image centre, i.e. the optical axis, which is how a
hand-held camera rolls. Model B (map in log-polar, Eq. 8 literally) rotates about the map origin
and couples roll into the translation readout; it is not implemented.

Choices beyond the paper (each a config switch; measured on simulator seeds 1-3):

* ``cleanup.init = identity``: the first map is the first frame, so the true initial transform
  is the identity; random initial states (the paper, ``init = random``) locked onto spurious
  fixed points in 3 of 4 static trials at 96x72.
* ``logpolar.ring_weight``: the roll/scale correlation weights log-polar rings by
  ``(ρ/r_max)^a`` (``D_w S ⊙ (Λ_w(m̂ ⊙ ĥ ⊙ v̂))*``); with equal weights the over-sampled centre
  (half the rings lie within 10 px) dominates and the roll was lost within a second.
* ``max_fill``: frames with too many pixels on are noise (a still camera) and are skipped, so
  that noise never becomes the map.
* ``readout.refine`` (on in all configs): after the population vector, the readout moves to
  the maximum of the continuous similarity ``Re<x, seed^t>`` (fractional powers are band-limited
  shifts). The exp-sharpened state pulls a population vector towards whole codebook entries
  (pixel locking: a saw-tooth error as the camera crosses pixels); refining removed part of it
  and lowered the errors on every kind (sim seeds 1-6).
* ``readout.refine_input`` (``h,v`` for robot_arm, empty for the shapes configs): those factors
  refine on ``phasor(X X† a)`` of their last cleanup input ``a`` instead of the state, i.e. on
  the continuous peak of the phase-only correlation of the frame with the map (the FHRR form of
  phase correlation), not sharpened by ``p``. On the slow arm the state's peak lagged the
  motion by ~4 ms (about 1.7 frames; the roll did not), which the paper's roll-based time
  alignment cannot remove; the input peak lags ~2.5 ms and is less noisy (sim seeds 1-6:
  position 0.150 → 0.123 cm). On the fast shapes sequences the unsharpened input is noisier
  than the state (rotation 0.53 → 0.60°, translation 0.54 → 0.60 cm), so they keep the state.
* ``imu.gamma``: with the gyro prediction on, the states may move more slowly (γ = 0.3 instead
  of 0.9 for shapes_rotation): the prediction carries the fast motion, the frames correct it,
  like a smaller Kalman gain; better on all 13 tuning seeds.
* ``imu.gate_deg`` (5° for shapes_rotation): with the gyro on, a frame whose readout leaves the
  prediction by more than the gate is rejected (states keep the prediction, no map update), the
  innovation gate of a Kalman filter. On tuning seeds 1-20 it never fires (99.9 % of the frames
  within 3°, max 4.1°); it was added after held-out seed 103 slipped its map by 18° of roll in
  one frame at 13.5 s (a jump under fast motion near the canvas edge), so seed 103 is not a
  clean held-out figure for the IMU case any more; seeds 104-106 are (README).
* Slow, half-anchored maps in the configs (μ1 = 0.985, μ2 = 0.0075; arm 0.99, 0.005; instead
  of the paper's faster map): a mistracked frame barely enters the map, and on the toroidal
  canvas a strong anchor aliases the first view when the camera is far from it (the arm failed
  with it).
* A canvas larger than the frame (``codebook.canvas_width/height``; 96x96 for the arm, 128x96
  for shapes_rotation and shapes_translation, the frame centred on it): the map is toroidal
  over the canvas, so with a frame-sized canvas a camera that moves more than half the frame
  (the arm: ~30 px along 48 rows) or tilts and rolls far (a rotated 96x72 view) sees the map
  overlap itself. The larger canvas removed a velocity-correlated bias of the arm's position
  (0.46 -> 0.19 cm on sim seed 1) and lowered the errors of all three kinds on the tuning
  seeds; the fast step costs ~10 % more. 128 columns instead of 96: a pan of 20° moves the
  rotation view by 28 px, and on 96 columns the new content wrapped onto the far side of the
  anchored first view (held-out rotation seed 174 lost track at 18° of pan, right when map
  learning began; rotation tuning seeds 1-20: 0.276 -> 0.263°, with the IMU 0.255 ->
  0.245°); translation moves ~50 px sideways (tuning seeds 1-6: 0.50 -> 0.48 cm, lower on
  all six). Each costs ~10 % more time per step.
* ``codebook.kernel_sigma`` (0.7 px for the 96x72 configs, 0 for the arm): each event pixel is
  encoded as a Gaussian blob, s = Φ (G ∗ I) = (Φ I) ⊙ ĝ with DFT codebooks (kernel shaping of
  the FPE). Sparse binary frames give spiky correlations; the smoother peaks lowered the
  rotation error on 12 of 13 tuning seeds (no IMU), about neutral with the IMU.
* ``cleanup.predict_velocity`` (1 in all configs): without a gyro, the states are bound
  with the smoothed readout change per frame before each frame (a constant-velocity
  prediction, the same fractional binding as the IMU's Eq. 10). Lower rotation error on all
  20 tuning seeds (mean 0.63 -> 0.58°), and with every second frame dropped (2x faster
  motion) 20 of 20 seeds track instead of 18; neutral on translation and the arm. The
  velocity is an exponential average (``predict_smoothing`` 0.5): the raw last change feeds
  the per-frame readout noise back and diverged on synthetic frames.
* ``sphere.enabled`` (shapes_rotation): a rotating camera's frame is a shift and roll of the
  flat map only near its centre; each equidistant-rectified frame is first warped by the
  non-rigid part of the rotation at the previous frame's pose (:mod:`.sphere`), so the
  resonator's rigid model holds across the whole frame. The fitted roll was biased by a
  content-dependent 0.5-1° at pan/tilt of 15-20°; rotation tuning seeds 1-20: mean error
  0.414 -> 0.276°, lower on every seed.
* ``readout.source = drive`` (off by default) and ``cleanup.whiten`` (off) are experiments.
  Whitening (phase correlation inside the resonator) loses track on the simulated sequences:
  on sparse binary frames every frequency gets weight 1, the noise-dominated high frequencies
  (which the encoding kernel had damped) included (rotation tuning seed 1 after 1.04 s,
  translation seeds 1-3 at 11-16 cm).

Two paths with the same equations:

* ``path='fast'`` (DFT codebooks only): vectors are 2-D spectra; Λ = FFT ∘ sparse resampling ∘
  IFFT; each factor state depends on one frequency axis only, so it is stored as a 1-D vector and
  each cleanup is a weighted marginal sum plus a small codebook product (hrn_math.md §3.2).
* ``path='dense'``: the reference. Full N-dimensional states, dense Φ and Λ matrices (the paper's
  ~360 M operations per iteration), DFT or seeded random codebooks (N free, e.g. 3072).

Signs (all checked by tests on synthetic motion): binding the map with ``h0^a`` moves the image
content by +a pixels; the output ``h = -a`` is then the camera's position in the map. Binding with
``r0^b`` rotates the content by +b·2π/n_θ from +x towards +y (y down); a camera roll φ
(right-handed about the optical axis) rotates the content by -φ, so ``r = -b·2π/n_θ``. ``z`` is the
log zoom of the content (ρ shift × Δρ), positive when the camera approaches the scene.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import Any, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.configbase import nested, param, validate
from hrn_vo_ros.core.hrn import fft as hfft
from hrn_vo_ros.core.hrn import fhrr
from hrn_vo_ros.core.hrn.logpolar import (
    dense_lambdas,
    dense_lambdas_dft,
    dense_ring_weighting,
    Geometry,
    LogPolarConfig,
    LogPolarTransform,
    make_geometry,
)
from hrn_vo_ros.core.hrn.sphere import SphereWarp
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.errors import ConfigError, TrackingError

Complex = NDArray[np.complex128]
Real = NDArray[np.float64]
Floats = NDArray[np.floating[Any]]   # the placed canvas: float32 in the fast direct form
Spectrum = NDArray[np.complexfloating[Any, Any]]   # complex64 or complex128 (the fast engine)
_Arr = TypeVar('_Arr', bound=Spectrum)

NONLINEARITIES = ('identity', 'relu', 'relu_k', 'exp')


# --------------------------------------------------------------------------------------------
# Configuration


@dataclass(frozen=True, slots=True)
class CodebookConfig:
    """Codebooks and the Cartesian canvas."""

    kind: str = param('dft', 'dft: centred DFT seeds (fast path); random: seeded random FPE '
                      'seeds (dense path only)', choices=('dft', 'random'), read_only=True)
    dim: int = param(0, 'vector dimension N of random codebooks (0: canvas pixels); DFT '
                     'codebooks have N = canvas pixels', lo=0, hi=100_000, read_only=True)
    canvas_width: int = param(0, 'Cartesian canvas width in frame pixels (0: frame width); '
                              'larger keeps wrapped-around content out of the map',
                              lo=0, hi=4096, read_only=True)
    canvas_height: int = param(0, 'Cartesian canvas height in frame pixels (0: frame height)',
                               lo=0, hi=4096, read_only=True)
    rcond: float = param(1e-6, 'relative cut-off of the pseudo-inverses of random codebooks',
                         lo=0.0, hi=1.0, read_only=True)
    kernel_sigma: float = param(0.0, 'encode each event pixel as a Gaussian blob of this std '
                                '(frame pixels; 0: one pixel): s = Phi (G * I), with DFT '
                                'codebooks s = (Phi I) . g, a fixed weighting of the '
                                'frequencies (FPE kernel shaping); smooths the correlation '
                                'peaks of sparse binary frames', lo=0.0, hi=20.0,
                                read_only=True)

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, slots=True)
class CleanupConfig:
    """Cleanup C_X(u) = f(X p(Re X† u)) and the state update speed."""

    nonlinearity: str = param('exp', 'p: identity, relu, relu_k (relu to the power k) or exp '
                              '(exp(beta (c / max|c| - 1)), a softmax)', choices=NONLINEARITIES)
    k: float = param(3.0, 'exponent of relu_k', lo=0.1, hi=100.0)
    beta: float = param(10.0, 'sharpness of exp, in units of the peak similarity', lo=0.0,
                        hi=1000.0)
    gamma: float = param(0.5, 'state update speed: x <- (1-gamma) x + gamma C_X(.)', lo=0.0,
                         hi=1.0)
    iterations_per_frame: int = param(1, 'resonator iterations per event frame', lo=1, hi=100)
    init: str = param('identity', 'initial states: identity (the known transform between the '
                      'first frame and the map it defines) or random (unit phasors, as the paper)',
                      choices=('identity', 'random'))
    whiten: bool = param(False, 'phasor-project each unbinding product before its cleanup, '
                         'C_X(f(u)) (phase correlation; an experiment that loses track on '
                         'the simulated sequences, see the module docstring)')
    predict_velocity: float = param(0.0, 'constant-velocity prediction (0: off): before a '
                                    'frame without a gyro delta, bind the h/v/r states with '
                                    'this fraction of their velocity (readout change per '
                                    'frame), the way the gyro prediction binds them with the '
                                    'integrated rate', lo=0.0, hi=1.0)
    predict_smoothing: float = param(0.5, 'weight of the newest frame-to-frame readout change '
                                     'in the velocity (an exponential average; 1: the last '
                                     'change only, which amplifies per-frame readout noise)',
                                     lo=0.01, hi=1.0)

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, slots=True)
class MapConfig:
    """The allocentric map and its anchored update (paper Eq. 9)."""

    learn: bool = param(True, "update the map (false: the paper's ablation, map = first frame)")
    mu1: float = param(0.9, 'weight of the previous map', lo=0.0, hi=1.0)
    mu2: float = param(0.01, 'weight of the initial map (anchoring)', lo=0.0, hi=1.0)
    block_iterations: int = param(100, 'no map update during the first iterations',
                                  lo=0, hi=10_000_000)

    def __post_init__(self) -> None:
        validate(self)
        if self.mu1 + self.mu2 > 1.0:
            raise ConfigError(f'MapConfig: mu1 + mu2 = {self.mu1 + self.mu2} must be <= 1')


@dataclass(frozen=True, slots=True)
class ReadoutConfig:
    """Population-vector readout (paper Eq. 7)."""

    half_window: int = param(5, 'neighbours on each side of the peak in the population vector',
                             lo=0, hi=1000)
    source: str = param('state', 'what the population vector reads: state (Re X^H x, the '
                        'paper) or drive (Re X^H u of the last cleanup input: a smooth '
                        'correlation peak that keeps sub-pixel detail the sharpened state '
                        'loses)', choices=('state', 'drive'))
    refine: bool = param(False, 'refine each h/v/r/z readout to the maximum of the continuous '
                         'similarity Re<x, seed^t> near the population vector (fractional '
                         'powers are band-limited shifts): removes the pull towards whole '
                         'codebook entries (pixel locking) of the sharpened state')
    refine_input: str = param('', 'comma-separated factors (h, v, r, z) whose refine reads the '
                              'phasor projection of their last cleanup input, phasor(X X^H u), '
                              'instead of the state: the continuous peak of the phase-only '
                              'correlation, not sharpened by p (more precise on the slow arm, '
                              'less robust on fast motion); empty: all read the state')

    def __post_init__(self) -> None:
        validate(self)
        bad = [f for f in self.input_factors if f not in ('h', 'v', 'r', 'z')]
        if bad:
            raise ConfigError(f'ReadoutConfig.refine_input: unknown factor(s) {bad}; use a '
                              'comma-separated subset of h, v, r, z (or empty)')

    @property
    def input_factors(self) -> tuple[str, ...]:
        """The factors named in ``refine_input``."""
        return tuple(f.strip() for f in self.refine_input.split(',') if f.strip())


@dataclass(frozen=True, slots=True)
class ScaleConfig:
    """The optional scale (zoom) factor z in the log-polar partition."""

    enabled: bool = param(False, 'estimate a scale factor z (translation along the optical axis)',
                          read_only=True)
    max_log_scale: float = param(0.4, 'codebook covers log scales in [-max, max]', lo=0.001,
                                 hi=5.0, read_only=True)
    entries: int = param(41, 'codebook entries over that range (fractional ring shifts)', lo=3,
                         hi=10_000, read_only=True)

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, slots=True)
class ImuConfig:
    """IMU prediction by fractional binding (paper Eq. 10)."""

    enabled: bool = param(False, 'bind the states with the integrated gyro before each frame')
    gamma: float = param(0.0, 'state update speed while the IMU prediction is on (0: '
                         'cleanup.gamma); the gyro carries the fast motion, so the states can '
                         'trust the prediction more, like a smaller Kalman gain', lo=0.0, hi=1.0,
                         read_only=True)
    gate_deg: float = param(0.0, 'innovation gate (0: off): a frame whose readout differs from '
                            'the gyro prediction by more than this angle (roll, or pan/tilt '
                            'through focal_px) is rejected: the states keep the prediction '
                            'and the map is not updated, so one bad frame cannot slip the map',
                            lo=0.0, hi=180.0)
    camera_from_imu: tuple[float, ...] = param(
        (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        'rotation IMU axes -> camera axes (x right, y down, z forward), row-major 3x3',
        lo=-1.0, hi=1.0)

    def __post_init__(self) -> None:
        validate(self)
        if len(self.camera_from_imu) != 9:
            raise ConfigError('ImuConfig.camera_from_imu needs 9 numbers (a row-major 3x3)')


@dataclass(frozen=True, slots=True)
class SphereConfig:
    """Sphere correction of rotating-camera frames (:mod:`hrn_vo_ros.core.hrn.sphere`)."""

    enabled: bool = param(False, 'warp each frame by the non-rigid part of a camera rotation at '
                          'the last pose estimate, so that it is a rigid shift and roll of the '
                          'map (needs equidistant-rectified frames and focal_px)')


@dataclass(frozen=True, slots=True)
class ResonatorConfig:
    """Everything the HRN needs; nested sections map to nested YAML dictionaries."""

    width: int = param(96, 'event frame width in pixels (packetizer output)', lo=2, hi=4096,
                       read_only=True)
    height: int = param(72, 'event frame height in pixels', lo=2, hi=4096, read_only=True)
    path: str = param('fast', 'fast (FFT, DFT codebooks) or dense (reference matrices)',
                      choices=('fast', 'dense'), read_only=True)
    max_fill: float = param(0.3, 'frames with a larger fraction of pixels on are noise (a '
                            'still camera fills fixed-count packets with noise) and are skipped '
                            'like empty ones; 1 keeps all', lo=0.0, hi=1.0)
    focal_px: float = param(0.0, 'focal length in frame pixels (fx / downsample), for the IMU '
                            'prediction (pan/tilt -> h, v) and the sphere correction; 0: the '
                            'caller derives it from the calibration', lo=0.0, hi=100_000.0,
                            read_only=True)
    codebook: CodebookConfig = nested(CodebookConfig, 'codebooks and canvas')
    logpolar: LogPolarConfig = nested(LogPolarConfig, 'log-polar grid')
    cleanup: CleanupConfig = nested(CleanupConfig, 'cleanup nonlinearity and update speed')
    map: MapConfig = nested(MapConfig, 'map learning and anchoring')
    readout: ReadoutConfig = nested(ReadoutConfig, 'population-vector readout')
    scale: ScaleConfig = nested(ScaleConfig, 'optional scale factor z')
    imu: ImuConfig = nested(ImuConfig, 'IMU prediction')
    sphere: SphereConfig = nested(SphereConfig, 'sphere correction (rotating camera)')

    def __post_init__(self) -> None:
        validate(self)
        if self.path == 'fast' and self.codebook.kind != 'dft':
            raise ConfigError('ResonatorConfig: path fast needs codebook.kind dft; use path '
                              'dense for random codebooks')
        make_geometry(self.width, self.height, self.codebook.canvas_width,
                      self.codebook.canvas_height, self.logpolar)


def needs_focal(cfg: ResonatorConfig) -> bool:
    """Whether a switched-on feature (IMU prediction, sphere correction) needs ``focal_px`` and
    it is unset: callers with a calibration set it to fx / downsample."""
    return (cfg.imu.enabled or cfg.sphere.enabled) and not cfg.focal_px


def sphere_rectify_problem(rectify: str, cfg: ResonatorConfig) -> str | None:
    """Why ``cfg``'s sphere correction cannot run on frames rectified with ``rectify`` (the
    packetizer's mode; the warp assumes the equidistant projection), or None."""
    if cfg.sphere.enabled and rectify != 'equidistant':
        return (f'sphere.enabled needs equidistant-rectified frames (packetizer rectify is '
                f'{rectify}): set packetizer.rectify=equidistant or sphere.enabled=false')
    return None


def without_unset_sphere(cfg: ResonatorConfig) -> tuple[ResonatorConfig, str | None]:
    """``cfg`` with the sphere correction off, and why, if ``focal_px`` is unset (a caller
    without a calibration, such as the resonator node, still runs); else ``(cfg, None)``."""
    if not (cfg.sphere.enabled and not cfg.focal_px):
        return cfg, None
    return replace(cfg, sphere=replace(cfg.sphere, enabled=False)), (
        'sphere.enabled needs focal_px (fx / downsample, in frame pixels; about 79.6 for a '
        'DAVIS240C at 2.5) as a start parameter: running without the sphere correction')


def state_gamma(cfg: ResonatorConfig) -> float:
    """The state update speed γ in use: ``imu.gamma`` while the IMU prediction is on (if set),
    ``cleanup.gamma`` otherwise."""
    if cfg.imu.enabled and cfg.imu.gamma > 0.0:
        return cfg.imu.gamma
    return cfg.cleanup.gamma


def blend_state(x: Spectrum, cleaned: _Arr, gamma: float) -> _Arr:
    """The state update x̂ ← (1-γ) x̂ + γ C_X(·), in place of ``cleaned``; rows: (n,) or (k, n).

    A blank cleanup (all zero: its input carried nothing, e.g. an empty warped frame) leaves the
    state as it was instead of shrinking it by (1-γ): two blank iterations took a state to 1 %
    and a zero h and v are a fixed point of the resonator (each factor's input is unbound with
    the other's state), so one blank stretch used to freeze the network for good.
    """
    rows = cleaned if cleaned.ndim == 2 else cleaned[None, :]
    # index 0 is Σp (> 0) for cleanups of complete DFT books, so the full test rarely runs
    blank = [i for i in range(rows.shape[0]) if rows[i, 0] == 0 and not rows[i].any()]
    np.multiply(cleaned, gamma, out=cleaned)
    np.add(cleaned, (1 - gamma) * x, out=cleaned)
    for i in blank:
        rows[i] = x[i] if cleaned.ndim == 2 else x
    return cleaned


# --------------------------------------------------------------------------------------------
# Pieces shared with the spiking backend


def cleanup_weights(c: Real, cfg: CleanupConfig, bound: float = 0.0) -> Real:
    """The cleanup nonlinearity p applied to the similarities ``c = Re(X† u)``.

    ``identity``: c; ``relu``: max(c, 0); ``relu_k``: max(c, 0)^k; ``exp``:
    exp(β (c / max|c| - 1)). The phasor projection after ``X p(c)`` makes all of them invariant
    to a positive scale of c, so no normalisation of u is needed.

    Args:
        c: Similarities.
        cfg: The cleanup settings.
        bound: An upper bound of |c| (``|x_j| |u|``); similarities below ``1e-9 * bound`` are
            rounding noise and count as 0 (so a blank input gives p = 0, not amplified noise).

    Shapes:
        c: (K,); returns (K,).
    """
    mag = np.abs(c)
    top = float(mag.max()) if mag.size else 0.0
    if bound > 0.0:
        if top < 1e-9 * bound:
            return np.zeros_like(c)
        small = mag < 1e-9 * bound
        if small.any():
            c = np.where(small, 0.0, c)
    kind = cfg.nonlinearity
    if kind == 'identity':
        return c
    if kind == 'relu':
        return np.maximum(c, 0.0)
    if kind == 'relu_k':
        return np.maximum(c, 0.0) ** cfg.k
    if top <= 0.0:
        return np.zeros_like(c)
    y = c * (cfg.beta / top)
    y -= cfg.beta
    return np.exp(y, out=y)


def population_readout(sim: Real, half_window: int, circular: bool
                       ) -> tuple[float, float, float]:
    """Population vector around the peak (paper Eq. 7), negative weights clipped to 0.

    Args:
        sim: Readout similarities over codebook entries.
        half_window: Neighbours on each side of the peak.
        circular: Wrap the window around the ends (periodic codebooks); the returned index is
            then not wrapped (it may lie just outside [0, K)).

    Returns:
        ``(index, spread, peak)``: fractional entry index, weighted standard deviation of the
        index in the window, and the peak similarity.

    Shapes:
        sim: (K,).
    """
    n = sim.shape[0]
    k = int(np.argmax(sim))
    idx = np.arange(k - half_window, k + half_window + 1)
    if circular:
        w = sim[np.mod(idx, n)]
    else:
        idx = idx[(idx >= 0) & (idx < n)]
        w = sim[idx]
    w = np.maximum(w, 0.0)
    total = float(w.sum())
    if total <= 0.0:
        return float(k), 0.0, float(sim[k])
    mean = float(np.dot(w, idx) / total)
    spread = math.sqrt(max(float(np.dot(w, (idx - mean) ** 2) / total), 0.0))
    return mean, spread, float(sim[k])


def centred_mod(x: Any, period: float) -> Any:
    """``x`` wrapped into ``[-period/2, period/2)`` (scalars or arrays)."""
    return (x + 0.5 * period) % period - 0.5 * period


@dataclass(frozen=True, slots=True)
class FactorCodebook:
    """A 1-D FPE codebook along one axis: entries ``seed^{values[j]}``.

    Attributes:
        name: Factor name (h, v, r, z).
        phases: Seed phases along the axis (the factor's frequency axis in the fast path).
        values: Exponent of each entry (index units: pixels, angle samples, ring shifts).
        period: The codebook wraps after this many index units (None: not periodic).
        unit: Physical size of one index unit (pixel 1, 2π/n_θ rad, Δρ).
        sign: Output sign: physical value = sign · unit · index.
    """

    name: str
    phases: Real
    values: Real
    period: float | None
    unit: float
    sign: float

    def wrap(self, index: float) -> float:
        """An exponent (index units) wrapped into the codebook's period, if it has one."""
        return index if self.period is None else float(centred_mod(index, self.period))

    @property
    def matrix(self) -> Complex:
        """(n, K) codebook matrix."""
        return fhrr.codebook(self.phases, self.values)


def _factor_codebooks(cfg: ResonatorConfig, g: Geometry) -> dict[str, FactorCodebook]:
    """The 1-D DFT factor codebooks of the fast path (also the dense DFT path's factors)."""
    def centred(n: int) -> Real:      # entries -n/2 .. n/2-1 (shifts both ways)
        return np.arange(n, dtype=float) - n // 2

    books = {
        'h': FactorCodebook('h', fhrr.dft_phases(g.canvas_width), centred(g.canvas_width),
                            float(g.canvas_width), 1.0, -1.0),
        'v': FactorCodebook('v', fhrr.dft_phases(g.canvas_height), centred(g.canvas_height),
                            float(g.canvas_height), 1.0, -1.0),
        'r': FactorCodebook('r', fhrr.dft_phases(g.n_theta), centred(g.n_theta),
                            float(g.n_theta), 2.0 * math.pi / g.n_theta, -1.0),
    }
    if cfg.scale.enabled:
        top = cfg.scale.max_log_scale / g.d_rho
        books['z'] = FactorCodebook('z', fhrr.dft_phases(g.n_rho),
                                    np.linspace(-top, top, cfg.scale.entries), None, g.d_rho, 1.0)
    return books


# --------------------------------------------------------------------------------------------
# Engines: the same equations, fast (FFT, factorised) and dense (matrices)


class _Engine(Protocol):
    books: dict[str, FactorCodebook]
    state: dict[str, Any]

    def encode(self, canvas: Floats) -> Any: ...
    def start(self, canvas: Floats, rng: np.random.Generator) -> None: ...
    def iterate(self, S: Any) -> None: ...
    def similarities(self) -> dict[str, Real]: ...
    def shift(self, name: str, delta: float) -> None: ...
    def update_map(self, S: Any, point: dict[str, float], mu1: float, mu2: float) -> None: ...
    def map_image(self, point: dict[str, float] | None) -> Real: ...
    def input_projection(self, name: str) -> Any: ...


def _normalised(c: Complex, x: Complex, col_norm: float) -> Real:
    nx = float(np.linalg.norm(x))
    if nx == 0.0:
        return np.zeros(c.shape[0])
    return np.real(c) / (col_norm * nx)


_REFINE_GRID = np.linspace(-1.0, 1.0, 41)


def refine_kernel(phases: Real, step: float) -> Complex:
    """``seed^(-step·g)`` for the refinement grid g (cache it per factor; see
    :func:`refine_exponent`). Shapes: phases (n,) → (41, n)."""
    return np.asarray(np.exp(-1j * step * np.outer(_REFINE_GRID, phases)), np.complex128)


def refine_exponent(x: NDArray[np.complexfloating], phases: Real, value: float,
                    step: float, kernel: Complex | None = None) -> float:
    """The exponent t within ``value ± step`` that maximises ``Re<seed^t, x>``.

    Fractional powers of an FPE seed are band-limited shifts, so the similarity of a state to
    the codebook is a smooth function of the exponent between the entries; its maximum (41-point
    grid, then a parabola through the best three) is the readout without the pull towards
    whole entries that the sharpened state gives a population vector (pixel locking).

    Shapes:
        x, phases: (n,); kernel: (41, n), :func:`refine_kernel` of ``phases`` and ``step``.
    """
    t = value + step * _REFINE_GRID
    if kernel is None:
        kernel = refine_kernel(phases, step)
    sim = np.real(kernel @ (x * np.exp(-1j * value * phases)))
    j = int(np.argmax(sim))
    if 0 < j < len(t) - 1:
        den = float(sim[j - 1] - 2.0 * sim[j] + sim[j + 1])
        if den < 0.0:
            return float(t[j] + 0.5 * float(sim[j - 1] - sim[j + 1]) / den * (t[1] - t[0]))
    return float(t[j])


class _FastEngine:
    """DFT codebooks; factor states as 1-D spectra along their axis (hrn_math.md §3.2).

    Without a scale factor and without whitening, the engine never forms the 2-D log-polar
    spectra (the "direct" form): the input is kept as ``S_θ = fft_θ(T · canvas)`` (``S`` =
    ``fft_ρ(S_θ)``), the roll binding acts along θ only, so ``Λ'(S ⊙ r̂*)`` needs one inverse FFT
    along θ, and the roll marginal ``Σ_ρ S_w ⊙ (Λ_w l)*`` is, by Parseval along ρ,
    ``n_ρ Σ_ρ w² ⊙ S_θ ⊙ fft_θ(T · ifft2(l))*``. Same equations, about a third fewer FFTs. A
    subclass whose populations exchange full spectra (``send``) sets ``direct = False``.
    """

    direct = True

    def __init__(self, cfg: ResonatorConfig, g: Geometry) -> None:
        self.cfg = cfg
        self.g = g
        self.lp = LogPolarTransform(g)
        self.books = _factor_codebooks(cfg, g)
        self.X = {k: b.matrix for k, b in self.books.items()}
        self.XH = {k: np.ascontiguousarray(x.conj().T) for k, x in self.X.items()}
        self.col_norm = {k: math.sqrt(x.shape[0]) for k, x in self.X.items()}
        self._full = {k: b.period is not None and len(b.values) == len(b.phases)
                      and np.array_equal(b.values, np.arange(len(b.values)) - len(b.values) // 2)
                      for k, b in self.books.items()}
        # np.roll(x, n//2) and np.roll(p, -(n//2)) as gathers (entries -n/2..n/2-1 vs FFT order)
        self._perm_dec = {k: np.roll(np.arange(len(b.phases)), len(b.phases) // 2)
                          for k, b in self.books.items()}
        self._perm_enc = {k: np.roll(np.arange(len(b.phases)), -(len(b.phases) // 2))
                          for k, b in self.books.items()}
        self._jphases = {k: 1j * b.phases for k, b in self.books.items()}
        self.has_z = 'z' in self.books
        self._direct = self.direct and not self.has_z and not cfg.cleanup.whiten
        self._hv_rows = (self._direct and self._full['h'] and self._full['v']
                         and len(self.books['h'].phases) == len(self.books['v'].phases))
        # the frame and map spectra: single precision in the direct form (rounding ~1e-7 of
        # the map's own scale; the factor states and cleanups stay double)
        self._cdt: type[np.complexfloating] = np.complex64 if self._direct else np.complex128
        self._S_roll: Spectrum = np.zeros(0, self._cdt)   # n_ρ w² ⊙ S_θ (direct form)
        w2 = self.lp.w ** 2 if self.lp.weighted else np.ones(g.n_rho)
        self._roll_rows = (g.n_rho * w2).astype(np.float32)[:, None]   # its per-ring factor
        self._sw_key: Complex | None = None
        self._sw: Complex = np.zeros(0, np.complex128)
        self.state: dict[str, Complex] = {}
        self.drive: dict[str, Real] = {}      # normalised Re X† u of the last cleanups
        self._keep_drive = cfg.readout.source == 'drive'   # (only that readout needs them)
        self.inputs: dict[str, Complex] = {}   # the last cleanup inputs (marginals) a
        self.m: Spectrum = np.zeros((g.canvas_height, g.canvas_width), self._cdt)
        self.m0 = self.m
        self._mc = self.m                           # m̂* (changes once per frame)
        self._mvh = np.empty_like(self.m)           # m̂ ⊙ v̂ ⊙ ĥ scratch (Λ_w copies it)
        self._m0_src: Spectrum | None = None         # the m0 that _m0_scaled = μ2 m0 was made of
        self._m0_mu2 = 0.0
        self._m0_scaled = self.m0

    def encode(self, canvas: Floats) -> Spectrum:
        """The frame's log-polar spectrum: ``S`` (2-D), or ``S_θ`` in the direct form."""
        if self._direct:
            lp = self.lp.lp_image(canvas).astype(np.float32)
            S: Spectrum = np.asarray(hfft.fft(lp, axis=1), self._cdt)
            self._S_roll = S * self._roll_rows
            return S
        S = self.lp.encode_image_lp(canvas)
        if self.lp.weighted and self.lp.last_lp_image is not None:
            self._sw_key, self._sw = S, self.lp.weight_image(self.lp.last_lp_image)
        return S

    def start(self, canvas: Floats, rng: np.random.Generator) -> None:
        g = self.g
        self.state = {'h': fhrr.random_phasor(g.canvas_width, rng),
                      'v': fhrr.random_phasor(g.canvas_height, rng),
                      'r': fhrr.random_phasor(g.n_theta, rng)}
        if self.has_z:
            self.state['z'] = fhrr.random_phasor(g.n_rho, rng)
        if self.cfg.cleanup.init == 'identity':       # seed^0 = 1: zero shift, roll, zoom
            self.state = {k: np.ones_like(x) for k, x in self.state.items()}
        self.m0 = hfft.fft2(canvas).astype(self._cdt)   # m̂(0) = s(0) = Φ I(0)
        self.m = self.m0.copy()
        self._mc = self.m.conj()

    # No BLAS in the hot path: multi-threaded gemv on these small sizes is slower than one
    # thread and collapses when the cores are shared. Full DFT codebooks (K = n integer entries
    # -n/2 .. n/2-1) decode with an inverse FFT and encode with an FFT; others (z) use
    # elementwise products and sums.

    def book_decode(self, name: str, a: Complex) -> Complex:
        """``X† a`` for factor ``name``. Shapes: a (n,) → (K,)."""
        if self._full[name]:
            out = hfft.ifft(a)[self._perm_dec[name]]
            out *= a.shape[0]
            return np.asarray(out, np.complex128)
        return np.asarray((self.XH[name] * a[None, :]).sum(axis=1), np.complex128)

    def book_encode(self, name: str, p: Real | Complex) -> Complex:
        """``X p`` for factor ``name``. Shapes: p (K,) → (n,)."""
        if self._full[name]:
            return np.asarray(hfft.fft(p[self._perm_enc[name]], overwrite_x=True),
                              np.complex128)
        return np.asarray((self.X[name] * p[None, :]).sum(axis=1), np.complex128)

    def _clean(self, name: str, a: Complex) -> Complex:
        # C_X(u) with u's weighted marginal a along the factor's axis: f(X p(Re X† a)).
        if self._full[name]:     # as _clean_full, 1-D (the 2-D form's bookkeeping costs more)
            c = hfft.ifft(a).real
            c *= a.shape[0]
            return fhrr.phasor(hfft.fft(self._full_weights(name, c, a)))
        c = np.real(self.book_decode(name, a))
        bound = self.col_norm[name] * math.sqrt(float(np.vdot(a, a).real))
        if self._keep_drive:
            self.drive[name] = c / bound if bound > 0 else np.zeros_like(c)
        p = cleanup_weights(c, self.cfg.cleanup, bound)
        return fhrr.phasor(self.book_encode(name, p))

    def _clean_full(self, names: tuple[str, ...], a: Complex) -> Complex:
        """``_clean`` of factors with complete DFT codebooks of one length, a row each (one FFT
        pair for all). p acts entrywise, so the entry order cancels between X† and X: the
        similarities stay in FFT order (n Re ifft a) and X p is their FFT. Shapes: (k, n)."""
        c = hfft.ifft(a, axis=1).real
        c *= a.shape[1]
        p = np.empty_like(c)
        for i, name in enumerate(names):
            p[i] = self._full_weights(name, c[i], a[i])
        return fhrr.phasor(hfft.fft(p, axis=1))

    def _full_weights(self, name: str, c: Real, a: Complex) -> Real:
        """p of the similarities ``c`` (FFT order, ``n Re ifft a``) of a complete DFT codebook,
        from its cleanup input ``a`` (the bound ``|x_j| |a|``; the drive if kept)."""
        b = self.col_norm[name] * math.sqrt(float(np.vdot(a, a).real))
        if self._keep_drive:
            self.drive[name] = c[self._perm_dec[name]] / b if b > 0 else np.zeros(c.shape[0])
        return cleanup_weights(c, self.cfg.cleanup, b)

    def _blend(self, x: Complex, cleaned: Complex) -> Complex:
        """x̂ ← (1-γ) x̂ + γ C_X(·), in place of ``cleaned`` (:func:`blend_state`)."""
        return blend_state(x, cleaned, state_gamma(self.cfg))

    def send(self, name: str, x: Complex) -> Complex:
        """Hook: the population ``name`` (S, m, p, l) sends ``x`` (identity here; the spiking
        backend, core/spiking, returns the value its phase-coded spikes carry)."""
        return x

    def update(self, name: str, x: Complex, a: Complex) -> Complex:
        """Hook: the state update x̂ ← (1-γ) x̂ + γ C_X(a) of factor ``name`` from its marginal
        drive ``a`` (the spiking backend replaces it with its neuron layers)."""
        return self._blend(x, self._clean(name, a))

    def _weighted_input(self, S: Complex) -> Complex:
        if not self.lp.weighted:
            return S
        if self._sw_key is not S:                   # once per frame (S is fixed within it)
            self._sw_key, self._sw = S, self.lp.weight(S)
        return self._sw

    def iterate(self, S: Complex) -> None:
        if self._direct:
            self._iterate_direct(S)
            return
        st = self.state
        h, v, r = st['h'], st['v'], st['r']
        z = st.get('z')
        S = self.send('S', S)
        m = self.send('m', np.asarray(self.m, np.complex128))   # (double unless direct)
        mc = self._mc if m is self.m else m.conj()
        q = S * r.conj()[None, :]
        if z is not None:
            q *= z.conj()[:, None]
        u = self.send('p', self.lp.reverse(q))      # p̂ = Λ'(S ⊙ r̂* ⊙ ẑ*)
        u *= mc                                     # p̂ ⊙ m̂*
        # l̂ = Λ(m̂ ⊙ ĥ ⊙ v̂); the roll/scale correlation uses ring-weighted log-polar images
        # (D_w S ⊙ (D_w l̂)*, identity when logpolar.ring_weight = 0).
        mvh = np.multiply(m, v[:, None], out=self._mvh)
        mvh *= h[None, :]
        w = self.send('l', self.lp.forward_weighted(mvh))
        np.conjugate(w, out=w)
        w *= self._weighted_input(S)                # S ⊙ l̂*
        hb, vb, rb, zb = h, v, r, z
        if self.cfg.cleanup.whiten:                 # f(a ⊙ b) = f(a) ⊙ f(b): whiten factorwise
            u, w = fhrr.phasor(u), fhrr.phasor(w)
            hb, vb, rb = fhrr.phasor(h), fhrr.phasor(v), fhrr.phasor(r)
            zb = None if z is None else fhrr.phasor(z)
        # (broadcast products and sums, not einsum: see _iterate_direct)
        a_h = (u * vb.conj()[:, None]).sum(axis=0)  # Σ_ky over p̂ ⊙ m̂* ⊙ v̂*
        a_v = (u * hb.conj()[None, :]).sum(axis=1)  # Σ_kx over p̂ ⊙ m̂* ⊙ ĥ*
        if z is not None and zb is not None:
            a_r = (w * zb.conj()[:, None]).sum(axis=0)
            a_z = (w * rb.conj()[None, :]).sum(axis=1)
            st['z'] = self.update('z', z, a_z)
        else:
            a_r = w.sum(axis=0)
        self.inputs.update(h=a_h, v=a_v, r=a_r)
        if z is not None:
            self.inputs['z'] = a_z
        st['h'] = self.update('h', h, a_h)
        st['v'] = self.update('v', v, a_v)
        st['r'] = self.update('r', r, a_r)

    def _iterate_direct(self, S_theta: Complex) -> None:
        # iterate() in the direct form (class docstring); the same estimates within rounding
        st = self.state
        h, v, r = st['h'], st['v'], st['r']
        dt = self._cdt
        hs, vs = h.astype(dt), v.astype(dt)
        u = self.lp.reverse_theta(S_theta * r.conj().astype(dt)[None, :])   # Λ'(S ⊙ r̂*)
        u *= self._mc                                            # p̂ ⊙ m̂*
        mvh = np.multiply(self.m, vs[:, None], out=self._mvh)
        mvh *= hs[None, :]
        lt = self.lp.forward_theta(mvh)                          # fft_θ(T ifft2(m̂ ⊙ v̂ ⊙ ĥ))
        np.conjugate(lt, out=lt)
        lt *= self._S_roll
        a_r = lt.sum(axis=0).astype(np.complex128)               # Σ_kρ S_w ⊙ l̂_w*
        # (broadcast products and sums: einsum takes 3-10x longer on complex64 at this size,
        # and BLAS gemv may go multi-threaded)
        a_h = (u * vs.conj()[:, None]).sum(axis=0).astype(np.complex128)
        a_v = (u * hs.conj()[None, :]).sum(axis=1).astype(np.complex128)
        self.inputs.update(h=a_h, v=a_v, r=a_r)
        if self._hv_rows:      # one cleanup for both (update() is no hook in the direct form)
            cleaned = self._clean_full(('h', 'v'), np.stack((a_h, a_v)))
            hv = self._blend(np.stack((h, v)), cleaned)
            st['h'], st['v'] = hv[0], hv[1]
        else:
            st['h'] = self.update('h', h, a_h)
            st['v'] = self.update('v', v, a_v)
        st['r'] = self.update('r', r, a_r)

    def similarities(self) -> dict[str, Real]:
        return {k: _normalised(self.book_decode(k, x), x, self.col_norm[k])
                for k, x in self.state.items()}

    def input_projection(self, name: str) -> Complex:
        """``phasor(X X† a)`` of factor ``name``'s last cleanup input (readout.refine_input);
        a complete DFT codebook has ``X X† = n I``, so it is ``phasor(a)``."""
        a = self.inputs[name]
        if not self._full[name]:
            a = self.book_encode(name, self.book_decode(name, a))
        return fhrr.phasor(a)

    def shift(self, name: str, delta: float) -> None:
        self.state[name] = self.state[name] * fhrr.power(self.books[name].phases, delta)

    def _to_map(self, S: Spectrum, point: dict[str, float]) -> Spectrum:
        jp, dt = self._jphases, self._cdt           # z0^a = exp((1j φ) a), as fhrr.power
        q = S * np.exp(jp['r'] * float(-point['r'])).astype(dt)[None, :]
        if self.has_z:
            q *= np.exp(jp['z'] * float(-point['z']))[:, None]
        t = self.lp.reverse_theta(q) if self._direct else self.lp.reverse(q)
        t *= np.exp(jp['v'] * float(-point['v'])).astype(dt)[:, None]
        t *= np.exp(jp['h'] * float(-point['h'])).astype(dt)[None, :]
        return t

    def update_map(self, S: Complex, point: dict[str, float], mu1: float, mu2: float) -> None:
        target = self._to_map(S, point)
        # Eq. 9, m = μ1 m + μ2 m0 + (1-μ1-μ2) t, into fresh arrays (the old m may be held)
        if self._m0_src is not self.m0 or self._m0_mu2 != mu2:   # μ2 m0 is fixed after start()
            self._m0_src, self._m0_mu2, self._m0_scaled = self.m0, mu2, mu2 * self.m0
        m = mu1 * self.m
        m += self._m0_scaled
        target *= 1.0 - mu1 - mu2
        m += target
        self.m = m
        self._mc = m.conj()

    def map_image(self, point: dict[str, float] | None) -> Real:
        m = self.m
        if point is not None:
            b = self.books
            m = (m * fhrr.power(b['v'].phases, point['v'])[:, None]
                 * fhrr.power(b['h'].phases, point['h'])[None, :])
            m = self.lp.forward(m) * fhrr.power(b['r'].phases, point['r'])[None, :]
            if self.has_z:
                m = m * fhrr.power(b['z'].phases, point['z'])[:, None]
            m = self.lp.reverse(m)
        return np.asarray(np.real(hfft.ifft2(m)), np.float64)


class _DenseEngine:
    """Reference path: full N-dimensional states, dense Φ, X and Λ matrices (§3.1)."""

    def __init__(self, cfg: ResonatorConfig, g: Geometry, rng: np.random.Generator,
                 dtype: type[np.complexfloating] = np.complex128) -> None:
        self.cfg = cfg
        self.g = g
        self.dtype = dtype
        small = _factor_codebooks(cfg, g)
        hc, wc, nr, nt = g.canvas_height, g.canvas_width, g.n_rho, g.n_theta
        if cfg.codebook.kind == 'dft':
            # Full-vector phases of the 2-D DFT seeds: broadcast of the 1-D ones.
            ph = {'h': np.broadcast_to(small['h'].phases[None, :], (hc, wc)).ravel(),
                  'v': np.broadcast_to(small['v'].phases[:, None], (hc, wc)).ravel(),
                  'r': np.broadcast_to(small['r'].phases[None, :], (nr, nt)).ravel(),
                  'z': np.broadcast_to(fhrr.dft_phases(nr)[:, None], (nr, nt)).ravel()}
            self.periodic = True
        else:
            n = cfg.codebook.dim or g.n_cart
            ph = {'h': fhrr.random_phases(n, rng), 'v': fhrr.random_phases(n, rng),
                  'r': fhrr.random_phases(n, rng, period=nt), 'z': fhrr.random_phases(n, rng)}
            self.periodic = False
        self.phases = ph
        self.books: dict[str, FactorCodebook] = {}
        for k, b in small.items():
            period = b.period if (self.periodic or k == 'r') else None
            self.books[k] = FactorCodebook(k, ph[k], b.values, period, b.unit, b.sign)
        self.X = {k: b.matrix.astype(dtype) for k, b in self.books.items()}
        self.XH = {k: np.ascontiguousarray(x.conj().T) for k, x in self.X.items()}
        self.col_norm = {k: math.sqrt(x.shape[0]) for k, x in self.X.items()}
        self.phi_c = fhrr.grid_codebook(ph['h'], ph['v'], wc, hc).astype(dtype)
        self.dw: NDArray[np.complexfloating] | None = None     # ring weighting D_w
        if cfg.codebook.kind == 'dft':
            self.lam, self.lam_r = dense_lambdas_dft(g, dtype=dtype)
            if g.ring_weight:
                self.dw = dense_ring_weighting(None, g, dtype=dtype)
        else:
            phi_lp = fhrr.grid_codebook(ph['r'], ph['z'], nt, nr)
            self.lam, self.lam_r = dense_lambdas(self.phi_c, phi_lp, g, rcond=cfg.codebook.rcond,
                                                 dtype=dtype)
            if g.ring_weight:
                self.dw = dense_ring_weighting(phi_lp, g, rcond=cfg.codebook.rcond, dtype=dtype)
        self._sw_key: NDArray[np.complexfloating] | None = None
        self._sw: NDArray[np.complexfloating] = np.zeros(0, dtype)
        self._pinv_c: NDArray[np.complex128] | None = None
        self.has_z = 'z' in self.books
        self.state: dict[str, NDArray[np.complexfloating]] = {}
        self.drive: dict[str, Real] = {}
        self.inputs: dict[str, NDArray[np.complexfloating]] = {}
        self.m = np.zeros(self.phi_c.shape[0], dtype)
        self.m0 = self.m

    def encode(self, canvas: Floats) -> NDArray[np.complexfloating]:
        s = self.phi_c @ canvas.ravel().astype(self.dtype)        # s = Φ I (Eq. 3)
        S: NDArray[np.complexfloating] = self.lam @ s               # S = Λ s
        return S

    def start(self, canvas: Floats, rng: np.random.Generator) -> None:
        g = self.g
        hc, wc, nr, nt = g.canvas_height, g.canvas_width, g.n_rho, g.n_theta
        if self.periodic:
            # Same draws as the fast path, broadcast to full vectors.
            h, v = fhrr.random_phasor(wc, rng), fhrr.random_phasor(hc, rng)
            r = fhrr.random_phasor(nt, rng)
            self.state = {'h': np.broadcast_to(h[None, :], (hc, wc)).ravel(),
                          'v': np.broadcast_to(v[:, None], (hc, wc)).ravel(),
                          'r': np.broadcast_to(r[None, :], (nr, nt)).ravel()}
            if self.has_z:
                z = fhrr.random_phasor(nr, rng)
                self.state['z'] = np.broadcast_to(z[:, None], (nr, nt)).ravel()
        else:
            n = self.phi_c.shape[0]
            self.state = {k: fhrr.random_phasor(n, rng) for k in self.books}
        if self.cfg.cleanup.init == 'identity':
            self.state = {k: np.ones_like(x) for k, x in self.state.items()}
        self.state = {k: x.astype(self.dtype) for k, x in self.state.items()}
        self.m0 = self.phi_c @ canvas.ravel().astype(self.dtype)
        self.m = self.m0.copy()

    def _clean(self, name: str, u: NDArray[np.complexfloating]) -> NDArray[np.complexfloating]:
        self.inputs[name] = u
        c = np.real(self.XH[name] @ u).astype(np.float64)
        bound = self.col_norm[name] * float(np.linalg.norm(u))
        self.drive[name] = c / bound if bound > 0 else np.zeros_like(c)
        out = self.X[name] @ cleanup_weights(c, self.cfg.cleanup, bound).astype(self.dtype)
        return fhrr.phasor(out.astype(np.complex128)).astype(self.dtype)

    def iterate(self, S: NDArray[np.complexfloating]) -> None:
        st = self.state
        gam = state_gamma(self.cfg)
        h, v, r = st['h'], st['v'], st['r']
        z = st.get('z')
        q = S * r.conj() if z is None else S * r.conj() * z.conj()
        p = self.lam_r @ q                                  # p̂ = Λ'(S ⊙ r̂* ⊙ ẑ*)
        mc = self.m.conj()
        wh = fhrr.phasor if self.cfg.cleanup.whiten else (lambda x: x)
        h_new = blend_state(h, self._clean('h', wh(p * v.conj() * mc)), gam)
        v_new = blend_state(v, self._clean('v', wh(p * h.conj() * mc)), gam)
        lv = self.lam @ (self.m * h * v)                    # l̂ = Λ(m̂ ⊙ ĥ ⊙ v̂)
        sw = S
        if self.dw is not None:                             # ring-weighted D_w S ⊙ (D_w l̂)*
            lv = self.dw @ lv
            if self._sw_key is not S:
                self._sw_key, self._sw = S, self.dw @ S
            sw = self._sw
        w = sw * lv.conj()
        if z is not None:
            st['z'] = blend_state(z, self._clean('z', wh(w * r.conj())), gam)
            w = w * z.conj()
        st['r'] = blend_state(r, self._clean('r', wh(w)), gam)
        st['h'], st['v'] = h_new, v_new

    def similarities(self) -> dict[str, Real]:
        return {k: _normalised((self.XH[k] @ x).astype(np.complex128), x.astype(np.complex128),
                               self.col_norm[k])
                for k, x in self.state.items()}

    def input_projection(self, name: str) -> NDArray[np.complexfloating]:
        """``phasor(X X† u)`` of factor ``name``'s last cleanup input (readout.refine_input)."""
        u = self.inputs[name]
        return fhrr.phasor((self.X[name] @ (self.XH[name] @ u)).astype(np.complex128))

    def shift(self, name: str, delta: float) -> None:
        self.state[name] = self.state[name] * fhrr.power(self.phases[name], delta).astype(
            self.dtype)

    def update_map(self, S: NDArray[np.complexfloating], point: dict[str, float], mu1: float,
                   mu2: float) -> None:
        ph = self.phases
        q = S * fhrr.power(ph['r'], -point['r'])
        if self.has_z:
            q = q * fhrr.power(ph['z'], -point['z'])
        t = (self.lam_r @ q.astype(self.dtype)) * fhrr.power(
            ph['h'], -point['h']) * fhrr.power(ph['v'], -point['v'])
        self.m = (mu1 * self.m + mu2 * self.m0 + (1.0 - mu1 - mu2) * t).astype(self.dtype)

    def map_image(self, point: dict[str, float] | None) -> Real:
        m = self.m
        if point is not None:
            ph = self.phases
            m = self.lam @ (m * fhrr.power(ph['h'], point['h']) * fhrr.power(ph['v'], point['v']))
            m = m * fhrr.power(ph['r'], point['r'])
            if self.has_z:
                m = m * fhrr.power(ph['z'], point['z'])
            m = self.lam_r @ m.astype(self.dtype)
        if self._pinv_c is None:
            self._pinv_c = np.asarray(np.linalg.pinv(self.phi_c.astype(np.complex128),
                                                     rcond=self.cfg.codebook.rcond),
                                      np.complex128)
        img = np.real(self._pinv_c @ m.astype(np.complex128))
        return img.reshape(self.g.canvas_height, self.g.canvas_width)


# --------------------------------------------------------------------------------------------
# The network


class HRN:
    """Hierarchical resonator odometry: one (or a few) resonator iterations per event frame.

    Args:
        cfg: Configuration (defaults: 96x72 frames, DFT codebooks, fast path, h/v/r).
        rng: Source of the random initial states (and of random codebooks).
        dense_dtype: Complex type of the dense reference matrices (complex64 halves memory).

    Raises:
        ConfigError: on inconsistent settings.
    """

    def __init__(self, cfg: ResonatorConfig | None = None, *, rng: np.random.Generator,
                 dense_dtype: type[np.complexfloating] = np.complex128) -> None:
        self.cfg = cfg if cfg is not None else ResonatorConfig()
        self.rng = rng
        c = self.cfg
        self.geometry = make_geometry(c.width, c.height, c.codebook.canvas_width,
                                      c.codebook.canvas_height, c.logpolar)
        self._engine: _Engine = self._make_engine(rng, dense_dtype)
        self.factors: tuple[str, ...] = tuple(self._engine.books)
        self._kernels: dict[str, Complex] = {}      # readout.refine kernels per factor
        self._refine_input = set(c.readout.input_factors)
        self._canvas = np.zeros((self.geometry.canvas_height, self.geometry.canvas_width))
        self._sphere = (SphereWarp(c.width, c.height, c.focal_px) if c.sphere.enabled
                        else None)
        if c.imu.enabled and c.focal_px <= 0.0:     # fail at start, not on the first gyro frame
            raise ConfigError('imu.enabled needs focal_px (fx / downsample, in frame pixels) for '
                              'the gyro prediction: set it (hrn-vo run derives it from calib.txt)')
        # ĝ of codebook.kernel_sigma; real and even, so the blur of the real canvas is a real
        # FFT pair: ĝ on the rfft2 half-spectrum
        self._blur: Real | None = None
        if c.codebook.kernel_sigma > 0.0:
            sig = c.codebook.kernel_sigma
            fy = hfft.fftfreq(self.geometry.canvas_height)[:, None]
            fx = hfft.rfftfreq(self.geometry.canvas_width)[None, :]
            self._blur = np.exp(-2.0 * math.pi ** 2 * sig ** 2 * (fx ** 2 + fy ** 2))
        self._blur32 = (self._blur.astype(np.float32) if self._blur is not None
                        and getattr(self._engine, '_cdt', None) is np.complex64 else None)
        self.reset()

    def _make_engine(self, rng: np.random.Generator,
                     dense_dtype: type[np.complexfloating]) -> _Engine:
        """The engine for ``self.cfg`` (hook: the spiking backend returns its own fast engine)."""
        if self.cfg.path == 'fast':
            return _FastEngine(self.cfg, self.geometry)
        return _DenseEngine(self.cfg, self.geometry, rng, dense_dtype)

    def reset(self) -> None:
        """Forget the map and the states; the next non-empty frame starts a new map."""
        self.iteration = 0
        self._started = False
        self._point = dict.fromkeys(self.factors, 0.0)          # index units, wrapped
        self._last: Estimate | None = None
        self._out = dict.fromkeys(('h', 'v', 'r', 'z'), 0.0)    # physical, unwrapped
        self.innovation_deg = 0.0       # last readout vs gyro prediction (imu.gate_deg on)
        self.rejected_frames = 0        # frames rejected by imu.gate_deg
        self._prev: dict[str, float] | None = None  # readout of the last valid frame
        self._velocity: dict[str, float] | None = None   # smoothed readout change per frame

    # -- helpers ---------------------------------------------------------------------------

    def _place(self, image: NDArray[Any]) -> Floats:
        g = self.geometry
        ox, oy = g.offset
        self._canvas[oy:oy + g.height, ox:ox + g.width] = image
        if self._blur is None:
            return self._canvas
        # G * I on the (toroidal) canvas, i.e. s = (Φ I) ⊙ ĝ for DFT codebooks
        if self._blur32 is not None:        # single precision where the engine rounds to it
            spec = hfft.rfft2(self._canvas.astype(np.float32))
            spec *= self._blur32
            return np.asarray(hfft.irfft2(spec, self._canvas.shape))
        spec = hfft.rfft2(self._canvas)
        spec *= self._blur
        return np.asarray(hfft.irfft2(spec, self._canvas.shape), np.float64)

    def readout_axis(self, name: str) -> Real:
        """Physical value (px, rad, log scale) of each readout entry of factor ``name``."""
        b = self._engine.books[name]
        vals = b.sign * b.unit * b.values
        if b.period is not None:
            vals = centred_mod(vals, b.period * b.unit)
        return vals

    def _readout(self, sims: dict[str, Real]) -> tuple[dict[str, float], dict[str, float],
                                                       dict[str, float]]:
        """Point estimates (index units), spreads and peaks of every factor."""
        hw = self.cfg.readout.half_window
        point, spread, peak = {}, {}, {}
        for name, sim in sims.items():
            b = self._engine.books[name]
            idx, sd, pk = population_readout(sim, hw, b.period is not None)
            step = float(b.values[1] - b.values[0]) if len(b.values) > 1 else 1.0
            value = float(b.values[0]) + idx * step
            if self.cfg.readout.refine:
                if name not in self._kernels:
                    self._kernels[name] = refine_kernel(b.phases, step)
                x = (self._engine.input_projection(name) if name in self._refine_input
                     else self._engine.state[name])
                value = refine_exponent(x, b.phases, value, step, self._kernels[name])
            point[name], spread[name], peak[name] = b.wrap(value), sd * step * b.unit, pk
        return point, spread, peak

    def _imu_predict(self, gyro_delta: NDArray[Any]) -> dict[str, float]:
        g = np.asarray(gyro_delta, dtype=np.float64)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise TrackingError(f'gyro_delta must be 3 finite numbers (rad), got {gyro_delta!r}')
        f = self.cfg.focal_px
        if f <= 0.0:
            raise ConfigError('focal_px must be > 0 for the IMU prediction: set it to the '
                              'focal length in frame pixels (fx / downsample)')
        rb = self._engine.books['r']
        # Camera rotation θ (camera axes): content moves by (-f θy, +f θx) and turns by -θz.
        dx, dy = -f * g[1], f * g[0]
        alpha = self._point['r'] * rb.unit          # current content angle (rad)
        ca, sa = math.cos(alpha), math.sin(alpha)
        # Model A shifts the map before the roll: the map-frame shift is Rot(-α) d.
        shift = {'h': ca * dx + sa * dy, 'v': -sa * dx + ca * dy, 'r': -g[2] / rb.unit}
        for name, delta in shift.items():
            self._engine.shift(name, delta)
        return shift

    def _track_velocity(self, point: dict[str, float]) -> None:
        """Update the smoothed h/v/r change per frame (cleanup.predict_smoothing)."""
        prev, self._prev = self._prev, point
        if prev is None:
            return
        a, books = self.cfg.cleanup.predict_smoothing, self._engine.books
        step = {k: books[k].wrap(point[k] - prev[k]) for k in ('h', 'v', 'r')}
        old = self._velocity
        self._velocity = step if old is None else {
            k: (1.0 - a) * old[k] + a * d for k, d in step.items()}

    def _predict_velocity(self) -> None:
        """Constant-velocity prediction: bind h, v, r with a fraction of their velocity."""
        if self._velocity is None:
            return
        k = self.cfg.cleanup.predict_velocity
        for name, d in self._velocity.items():
            self._engine.shift(name, k * d)

    def _innovation_deg(self, point: dict[str, float], predicted: dict[str, float]) -> float:
        """Largest angle between a readout and the gyro prediction (roll, pan/tilt), degrees."""
        books = self._engine.books
        worst = 0.0
        for name in ('h', 'v', 'r'):
            b = books[name]
            d = b.wrap(point[name] - predicted[name])
            ang = b.unit * abs(d) if name == 'r' else math.atan(abs(d) / self.cfg.focal_px)
            worst = max(worst, ang)
        return math.degrees(worst)

    # -- public ----------------------------------------------------------------------------

    def step(self, image: NDArray[Any], t_ns: int, *,
             gyro_delta: NDArray[Any] | None = None) -> Estimate:
        """Process one event frame.

        Args:
            image: Binary (or any non-negative) event frame.
            t_ns: Frame time, int64 ns.
            gyro_delta: Integrated gyro since the previous frame (rad, camera axes), applied as
                the prediction step (paper Eq. 10) when given.

        Returns:
            The pose readout; an empty frame, one with more than ``max_fill`` of its pixels
            on (noise), or one the sphere correction warps entirely off the frame repeats the
            previous pose with ``valid=False``.

        Shapes:
            image: (height, width); gyro_delta: (3,).

        Raises:
            TrackingError: for a frame of the wrong shape or with non-finite values.
        """
        c = self.cfg
        if image.shape != (c.height, c.width):
            raise TrackingError(f'event frame has shape {image.shape}, expected '
                                f'({c.height}, {c.width}): match the packetizer size to '
                                'resonator width/height')
        img = np.asarray(image, dtype=np.float64)
        if image.dtype.kind not in 'biu' and not np.all(np.isfinite(img)):   # ints are finite
            raise TrackingError('event frame contains non-finite values')
        on = int(np.count_nonzero(img))
        if on == 0 or on > c.max_fill * img.size:
            return self._repeat(t_ns)
        if self._sphere is not None and self._started:   # the last pose's non-rigid part
            img = self._sphere.warp(img, self._out['h'], self._out['v'], self._out['r'])
            if not img.any():             # every event warped off the frame: nothing to use
                return self._repeat(t_ns)
        canvas = self._place(img)
        eng = self._engine
        first = not self._started
        if first:
            eng.start(canvas, self.rng)
            self._started = True
        predicted: dict[str, float] | None = None
        held: dict[str, Any] = {}
        if not first and gyro_delta is not None:       # the gyro, else the velocity predicts
            shift = self._imu_predict(gyro_delta)
            if c.imu.gate_deg > 0.0:
                predicted = {k: self._point[k] + shift.get(k, 0.0) for k in self._point}
                held = {k: x.copy() for k, x in eng.state.items()}
        elif c.cleanup.predict_velocity > 0.0:         # no-op until two valid frames
            self._predict_velocity()
        S = eng.encode(canvas)
        for _ in range(c.cleanup.iterations_per_frame):
            eng.iterate(S)
            self.iteration += 1
        sims = eng.similarities()
        drive = getattr(eng, 'drive', {})
        if c.readout.source == 'drive' and all(k in drive for k in sims):
            sims = {k: drive[k] for k in sims}
        point, spread, peak = self._readout(sims)
        rejected = False
        if predicted is not None:
            self.innovation_deg = self._innovation_deg(point, predicted)
            if self.innovation_deg > c.imu.gate_deg:
                rejected = True
                self.rejected_frames += 1
                eng.state.update(held)
                sims = eng.similarities()
                point = {k: self._engine.books[k].wrap(predicted[k]) for k in point}
        self._point = point
        if c.cleanup.predict_velocity > 0.0:
            self._track_velocity(point)
        updated = False
        if c.map.learn and self.iteration > c.map.block_iterations and not rejected:
            eng.update_map(S, point, c.map.mu1, c.map.mu2)
            updated = True
        return self._emit(t_ns, point, spread, peak, sims, updated)

    def _emit(self, t_ns: int, point: dict[str, float], spread: dict[str, float],
              peak: dict[str, float], sims: dict[str, Real], updated: bool) -> Estimate:
        books = self._engine.books
        for name, idx in point.items():
            b = books[name]
            val = b.sign * b.unit * idx
            if b.period is not None:            # unwrap against the previous output
                prev = self._out[name]
                val = prev + centred_mod(val - prev, b.period * b.unit)
            self._out[name] = val
        est = Estimate(t_ns=int(t_ns), h=self._out['h'], v=self._out['v'], r=self._out['r'],
                       z=self._out['z'], confidence=peak, spread=spread,
                       iteration=self.iteration, map_updated=updated, similarity=sims)
        self._last = est
        return est

    def _repeat(self, t_ns: int) -> Estimate:
        self._prev = self._velocity = None   # a skipped frame breaks the velocity
        last = self._last
        zeros = dict.fromkeys(self.factors, 0.0)
        if last is None:
            return Estimate(t_ns=int(t_ns), h=0.0, v=0.0, r=0.0, z=0.0, confidence=zeros,
                            spread=zeros, iteration=self.iteration, valid=False)
        return Estimate(t_ns=int(t_ns), h=last.h, v=last.v, r=last.r, z=last.z,
                        confidence=zeros, spread=last.spread, iteration=self.iteration,
                        map_updated=False, similarity=last.similarity, valid=False)

    def map_image(self) -> Real:
        """The map as an intensity image on the canvas (allocentric, first frame's frame).

        Shapes:
            returns (canvas_height, canvas_width) float64.
        """
        return self._engine.map_image(None)

    def egocentric_map_image(self) -> Real:
        """The map moved by the current estimate into the camera's view (for overlays).

        Shapes:
            returns (canvas_height, canvas_width) float64; the frame sits at ``geometry.offset``.
        """
        return self._engine.map_image(dict(self._point))
