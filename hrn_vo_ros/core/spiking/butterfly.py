"""Mixed-radix butterfly stages of the DFT: the Fourier layers of the sparse spiking transforms.

A length-``n`` DFT (``X[k] = sum_j x[j] e^{-2 pi i jk/n}``; the inverse has ``+`` and ``1/n``)
factors as ``n = r_1 r_2 ... r_S`` (radices 4 first, then 2, 3, 5, any other prime; at most
``max_radix``) into a digit-reversal permutation (wiring, no neurons) followed by ``S`` layers of
neurons, decimation in time (Cooley-Tukey):

    stage s, m = r_1 ... r_{s-1}, M = m r_s:   for every block of M neurons,
    out[k1 + m k2] = sum_{j < r_s} W_s[k2, j, k1] y[j m + k1],
    W_s[k2, j, k1] = w_M^{j k1} w_r^{j k2}

with ``w_M = e^{-2 pi i / M}`` (``+`` for the inverse, whose weights also carry ``1/r_s`` so the
layer keeps the input's magnitude range). Each neuron of a stage has fan-in ``r_s``, so a stage of
an ``n``-point axis has ``n r_s`` synapses and the whole axis ``n sum_s r_s`` (~ ``2 n log2 n``
for powers of two), instead of ``n^2`` for a dense DFT layer. 2-D transforms apply the stages of
each axis in turn (row-column), so a (H, W) spectrum takes ``H W (sum r_x + sum r_y)`` synapses.

:class:`AxisDFT` emulates the stages on an axis of an array, vectorised per stage (``r`` strided
multiply-adds of the whole array); its ``quantise`` callback is applied to every stage's output,
which is where the spiking transforms put the phasor neurons' code (phase on the ``2 pi / T``
grid, graded payload). With the identity callback and float weights it reproduces ``numpy.fft``
to rounding (a test checks every radix).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.errors import ConfigError

Complex = NDArray[np.complexfloating]
Int = NDArray[np.int64]

#: Radices the factorisation tries, in order (4 first: as few synapses as radix 2, half the
#: layers; then 2, 3, 5; a remaining prime factor becomes one dense stage of its size).
PREFERRED = (4, 2, 3, 5)


def radices(n: int, max_radix: int = 4) -> list[int]:
    """Stage radices of an ``n``-point DFT, innermost (first applied) first.

    Raises:
        ConfigError: for ``n < 1`` or a prime factor above ``max_radix`` and 7 (such a stage
            would be a dense layer of that size; choose another canvas or grid size).
    """
    if n < 1:
        raise ConfigError(f'a DFT needs at least one point, got n = {n}')
    out: list[int] = []
    rest = n
    for r in sorted((r for r in PREFERRED if r <= max_radix), key=lambda r: (r != 4, r)):
        while rest % r == 0 and rest > 1:
            out.append(r)
            rest //= r
    p = 2
    while rest > 1:
        while rest % p == 0:
            if p > max(max_radix, 7):
                raise ConfigError(f'DFT of {n} points has the prime factor {p}: a butterfly '
                                  f'stage of radix {p} > {max(max_radix, 7)}; choose a canvas '
                                  'or log-polar size with factors 2, 3, 5 and 7')
            out.append(p)
            rest //= p
        p += 1
    return out


def digit_reversal(n: int, rad: list[int]) -> Int:
    """Input order of the stages: position ``i`` of the first stage reads ``x[perm[i]]``."""
    if len(rad) <= 1:
        return np.arange(n, dtype=np.int64)
    r, m = rad[-1], n // rad[-1]
    inner = digit_reversal(m, rad[:-1])
    return np.concatenate([j + r * inner for j in range(r)]).astype(np.int64)


def stage_weights(r: int, m: int, inverse: bool) -> NDArray[np.complex128]:
    """``W[k2, j, k1] = w_M^{j k1} w_r^{j k2}`` of a stage (``/ r`` for the inverse).

    Shapes:
        returns (r, r, m).
    """
    sign = 1.0 if inverse else -1.0
    j = np.arange(r)[None, :, None]
    k1 = np.arange(m)[None, None, :]
    k2 = np.arange(r)[:, None, None]
    w = np.exp(sign * 2j * np.pi * (j * k1 / (m * r) + j * k2 / r))
    return np.asarray(w / r if inverse else w, np.complex128)


@dataclass(frozen=True, slots=True)
class Stage:
    """One butterfly layer: radix ``r``, sub-transform length ``m`` and its (realised) weights.

    Attributes:
        r: Fan-in of every neuron of the layer.
        m: Length of the sub-transforms it combines (``m r`` after it).
        weights: The weights ``W[k2, j, k1]`` as realised (quantised, or exact).
        small: For radix 2 and 4: the exact ``F_r`` (the realised twiddles are ``weights[0]``).
        comps: Per input position within a block of ``m r``: the number of nonzero real
            weight components over its ``r`` outgoing synapses (one synaptic operation each).

    Shapes:
        weights: (r, r, m); comps: (m r,).
    """

    r: int
    m: int
    weights: Complex
    comps: Int
    small: Complex | None = None


WeightMap = Callable[[NDArray[np.complex128]], tuple[Complex, Int]]


def exact_weights(w: NDArray[np.complex128]) -> tuple[Complex, Int]:
    """Float weights and their component counts (a component below 1e-12 counts as zero)."""
    comps = ((np.abs(w.real) > 1e-12).astype(np.int64) + (np.abs(w.imag) > 1e-12))
    return w, comps


class AxisDFT:
    """The butterfly stages of an ``n``-point (inverse) DFT along one axis.

    Args:
        n: Length of the axis.
        inverse: Inverse DFT (``+`` sign, ``1/n`` spread over the stages) instead of the DFT.
        max_radix: Largest radix of the factorisation (see :func:`radices`).
        weight_map: Realises each stage's float weights: returns the weights to use and the
            nonzero component count of each (default: float weights).
        dtype: Complex type of the emulation.
        factorised: Run radix-2/4 stages as twiddles and an exact ``F_r`` (valid when
            ``weight_map`` realises ``F_r t`` as ``F_r`` times the realised ``t``: float or
            quantised components; not for delays off the quarter-turn grid).
    """

    def __init__(self, n: int, *, inverse: bool = False, max_radix: int = 4,
                 weight_map: WeightMap = exact_weights,
                 dtype: type[np.complexfloating] = np.complex128,
                 factorised: bool = True) -> None:
        self.n = n
        self.inverse = inverse
        self.radices = radices(n, max_radix)
        self.perm = digit_reversal(n, self.radices)
        self.identity_perm = bool(np.array_equal(self.perm, np.arange(n)))
        self.stages: list[Stage] = []
        m = 1
        for r in self.radices:
            w, comps = weight_map(stage_weights(r, m, inverse))
            # input position j m + k1 of a block feeds r outputs with weights W[:, j, k1]
            per_input = comps.sum(axis=0).reshape(r * m)
            small = None
            if factorised and r in (2, 4):
                small = np.asarray(np.exp((1 if inverse else -1) * 2j * np.pi * np.outer(
                    np.arange(r), np.arange(r)) / r).round(12), dtype)
            self.stages.append(Stage(r, m, np.asarray(w, dtype)[..., None], per_input, small))
            m *= r

    @property
    def synapses(self) -> int:
        """Synapses (complex weights) of all stages: ``n * sum(radices)``."""
        return self.n * sum(self.radices)

    @property
    def components(self) -> int:
        """Nonzero real weight components of all stages (synaptic ops if every neuron fires)."""
        return int(sum(int(s.comps.sum()) * (self.n // (s.m * s.r)) for s in self.stages))

    def stage(self, x: Complex, s: Stage) -> Complex:
        """One layer's drive along axis 0: ``out = sum_j W[:, j] * y_j`` per block.

        Radix 2 and 4 run as a twiddle product and a small DFT matrix: their weights are
        ``W[k2, j, k1] = F_r[k2, j] t[j, k1]`` with ``F_r`` entries in {±1, ±i}, and quantising
        the composite weights is quantising ``t`` (rounding is odd, the exponent is shared), so
        this is the same layer. Other radices sum the ``r`` weighted inputs.

        Shapes:
            x: (n, post); returns (n, post).
        """
        n, post = x.shape
        nb = n // (s.m * s.r)
        y = x.reshape(nb, s.r, s.m, post)
        w = s.weights                                          # (r, r, m, 1)
        if s.small is not None:
            z = (y * w[0]).reshape(nb, s.r, s.m * post)
            res: Complex = np.matmul(s.small, z).reshape(n, post)
            return res
        out = w[:, 0] * y[:, 0:1]
        for j in range(1, s.r):
            out += w[:, j] * y[:, j:j + 1]
        return out.reshape(n, post)

    def spike_synops(self, live: NDArray[np.bool_], s: Stage) -> int:
        """Synaptic operations of a stage for the firing pattern ``live`` (n, post) of its
        input layer."""
        blocks = live.sum(axis=1).reshape(-1, s.m * s.r).sum(axis=0)
        return int(blocks @ s.comps)

    def apply(self, x: Complex, axis: int = -1,
              quantise: Callable[[Complex, int], Complex] | None = None) -> Complex:
        """The (inverse) DFT along ``axis`` of a 1-D or 2-D array, ``quantise(out, i)`` after
        stage ``i`` (elementwise; it sees the stages' (n, post) layout).

        Shapes:
            x: (n,) or 2-D with ``x.shape[axis] == n``; returns the same shape.
        """
        front = self.to_front(x, axis)
        for i, s in enumerate(self.stages):
            front = self.stage(front, s)
            if quantise is not None:
                front = quantise(front, i)
        return self.from_front(front, x.shape, axis)

    def to_front(self, x: Complex, axis: int) -> Complex:
        """``x`` as (n, post), the axis first and digit-reversed (the wiring of stage 0)."""
        y = x.reshape(self.n, 1) if x.ndim == 1 else (x if axis % 2 == 0 else x.T)
        y = y if self.identity_perm else y[self.perm]
        return np.ascontiguousarray(y)

    def from_front(self, y: Complex, shape: tuple[int, ...], axis: int) -> Complex:
        """Undo :meth:`to_front`'s layout (the stages' output is in natural order)."""
        if len(shape) == 1:
            return y.reshape(shape)
        return y if axis % 2 == 0 else np.ascontiguousarray(y.T)
