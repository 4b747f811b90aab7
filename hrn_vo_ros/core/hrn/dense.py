"""The dense reference engine: full N-dimensional states and dense Φ, X and Λ matrices.

The paper's form of the network (about 360 M operations per iteration at 96x72), with DFT or
seeded random FPE codebooks (N free, e.g. 3072). The fast engine (:mod:`.fast`) computes the
same equations with FFTs; the tests hold the two to 1e-4.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.hrn import fhrr
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.logpolar import (
    dense_lambdas,
    dense_lambdas_dft,
    dense_ring_weighting,
    Geometry,
)
from hrn_vo_ros.core.hrn.shared import (
    blend_state,
    centred_mod,
    cleanup_weights,
    factor_codebooks,
    FactorCodebook,
    Floats,
    normalised_similarity,
    Real,
    state_gamma,
    weighted_overlap,
)


class DenseEngine:
    """Reference path: full N-dimensional states, dense Φ, X and Λ matrices (an
    :class:`.engine.Engine`).

    Args:
        cfg: The resonator configuration (``path='dense'``).
        g: Its geometry.
        rng: Source of the random codebook seeds (``codebook.kind='random'``).
        dtype: Complex type of the matrices (complex64 halves the memory).
    """

    def __init__(self, cfg: ResonatorConfig, g: Geometry, rng: np.random.Generator,
                 dtype: type[np.complexfloating] = np.complex128) -> None:
        self.cfg = cfg
        self.g = g
        self.dtype = dtype
        small = factor_codebooks(cfg, g)
        hc, wc, nr, nt = g.canvas_height, g.canvas_width, g.n_rho, g.n_theta
        if cfg.codebook.kind == 'dft':
            # Full-vector phases of the 2-D DFT seeds: broadcast of the 1-D ones.
            ph = {'h': np.broadcast_to(small['h'].phases[None, :], (hc, wc)).ravel(),
                  'v': np.broadcast_to(small['v'].phases[:, None], (hc, wc)).ravel(),
                  'r': np.broadcast_to(small['r'].phases[None, :], (nr, nt)).ravel(),
                  'z': np.broadcast_to(fhrr.dft_phases(nr)[:, None], (nr, nt)).ravel()}
            self.periodic = True
            # (grid shape, axis summed) of each factor's marginal: h varies along x, v along
            # y, r along θ, z along ρ
            self._marginal = {'h': ((hc, wc), 0), 'v': ((hc, wc), 1), 'r': ((nr, nt), 0),
                              'z': ((nr, nt), 1)}
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
        # the overlap's high-pass weight (tracking.overlap_highpass) over the DFT frequencies
        # k = phase n / 2π of each element; random codebooks have no frequencies: plain overlap
        self._ov_w: Real | None = None
        if cfg.codebook.kind == 'dft':
            kx = centred_mod(ph['h'] * wc / (2.0 * math.pi), wc)
            ky = centred_mod(ph['v'] * hc / (2.0 * math.pi), hc)
            c = cfg.tracking.overlap_highpass
            k2 = kx ** 2 + ky ** 2
            self._ov_w = (np.asarray(1.0 - np.exp(-k2 / (2.0 * c ** 2)), np.float64) if c > 0.0
                          else (k2 > 1e-12).astype(np.float64))

    @property
    def blur_dtype(self) -> type[np.floating]:
        """float64: the reference blurs the canvas in double precision whatever its ``dtype``."""
        return np.float64

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
        bound = self._bound(name, u)
        self.drive[name] = c / bound if bound > 0 else np.zeros_like(c)
        out = self.X[name] @ cleanup_weights(c, self.cfg.cleanup, bound).astype(self.dtype)
        return fhrr.phasor(out.astype(np.complex128)).astype(self.dtype)

    def _bound(self, name: str, u: NDArray[np.complexfloating]) -> float:
        """The bound ``|x_j| |a|`` of ``Re X† u``, from the factor's marginal ``a`` for DFT
        codebooks: ``Re X† u = Re X₁† a`` with the 1-D codebook ``X₁``, the input the fast
        engine cleans, so the drive (``Re X† u`` over the bound) is the same normalised
        similarity in both engines; ``|x_j| |u|`` for random codebooks, which have no
        marginal."""
        if not self.periodic:
            return self.col_norm[name] * float(np.linalg.norm(u))
        shape, axis = self._marginal[name]
        a = np.asarray(u).reshape(shape).sum(axis=axis)
        return math.sqrt(a.shape[0]) * float(np.linalg.norm(a))

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
        return {k: normalised_similarity((self.XH[k] @ x).astype(np.complex128),
                                         x.astype(np.complex128), self.col_norm[k])
                for k, x in self.state.items()}

    def input_projection(self, name: str) -> NDArray[np.complexfloating]:
        """``phasor(X X† u)`` of factor ``name``'s last cleanup input (readout.refine_input)."""
        u = self.inputs[name]
        return fhrr.phasor((self.X[name] @ (self.XH[name] @ u)).astype(np.complex128))

    def shift(self, name: str, delta: float) -> None:
        self.state[name] = self.state[name] * fhrr.power(self.phases[name], delta).astype(
            self.dtype)

    def set_point(self, point: dict[str, float]) -> None:
        """Set every factor state to its codebook vector at ``point`` (index units)."""
        for name, x in self.state.items():
            self.state[name] = np.ones_like(x)
            self.shift(name, point[name])

    def map_target(self, S: NDArray[np.complexfloating], point: dict[str, float]
                   ) -> NDArray[np.complexfloating]:
        """The frame moved into the map at ``point`` (the map update's target)."""
        ph = self.phases
        q = S * fhrr.power(ph['r'], -point['r'])
        if self.has_z:
            q = q * fhrr.power(ph['z'], -point['z'])
        t: NDArray[np.complexfloating] = (self.lam_r @ q.astype(self.dtype)) * fhrr.power(
            ph['h'], -point['h']) * fhrr.power(ph['v'], -point['v'])
        return t

    def overlap(self, target: NDArray[np.complexfloating]) -> float:
        """Normalised frame-map overlap in [-1, 1]: with DFT codebooks high-passed as the fast
        engine's (``Re<w m, w t> / (|w m| |w t|)``), else ``Re<m, t> / (|m| |t|)``."""
        if self._ov_w is not None:
            return weighted_overlap(self.m, target, self._ov_w)
        nm = float(np.linalg.norm(self.m)) * float(np.linalg.norm(target))
        return float(np.vdot(self.m, target).real) / nm if nm > 0.0 else 0.0

    def distinctiveness(self, target: NDArray[np.complexfloating]) -> float:
        """Not computed by the reference path (NaN: the quality has no distinctiveness term)."""
        return math.nan

    def update_map(self, S: NDArray[np.complexfloating], point: dict[str, float], mu1: float,
                   mu2: float, target: NDArray[np.complexfloating] | None = None) -> None:
        t = self.map_target(S, point) if target is None else target
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
