"""The fast engine: DFT codebooks, FFTs and factorised 1-D factor states.

Each factor state depends on one frequency axis only, so it is stored as a 1-D spectrum and
each cleanup is a weighted marginal sum plus a small codebook product; Λ and Λ' are FFTs around
a sparse resampling (:class:`~hrn_vo_ros.core.hrn.logpolar.LogPolarTransform`). The equations
are those of the dense reference (:mod:`.dense`); ``docs/model.md`` derives the factorised form.
"""

from __future__ import annotations

import math

import numpy as np

from hrn_vo_ros.core.hrn import fft as hfft
from hrn_vo_ros.core.hrn import fhrr
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.logpolar import Geometry, LogPolarTransform
from hrn_vo_ros.core.hrn.shared import (
    blend_state,
    cleanup_weights,
    Complex,
    factor_codebooks,
    Floats,
    highpass_weights,
    normalised_similarity,
    peak_to_sidelobe,
    PSR_EXCLUDE,
    Real,
    Spectrum,
    state_gamma,
    weighted_overlap,
)


class FastEngine:
    """DFT codebooks; factor states as 1-D spectra along their axis (an :class:`.engine.Engine`).

    Without a scale factor and without whitening, the engine never forms the 2-D log-polar
    spectra (the "direct" form): the input is kept as ``S_θ = fft_θ(T · canvas)`` (``S`` =
    ``fft_ρ(S_θ)``), the roll binding acts along θ only, so ``Λ'(S ⊙ r̂*)`` needs one inverse FFT
    along θ, and the roll marginal ``Σ_ρ S_w ⊙ (Λ_w l)*`` is, by Parseval along ρ,
    ``n_ρ Σ_ρ w² ⊙ S_θ ⊙ fft_θ(T · ifft2(l))*``. Same equations, about a third fewer FFTs.

    Extension points (the spiking backend, :mod:`hrn_vo_ros.core.spiking.backend`, uses them):
    :meth:`send` (what a population passes on), :meth:`update` (one factor's cleanup and state
    update) and the class attribute ``direct``: a subclass whose populations exchange full
    spectra through ``send`` sets it to False, so the general form runs (the direct form never
    calls ``send``, and cleans h and v together without ``update`` where it can), and
    ``single``: the frame and map spectra in single precision in either form (the factor
    states and cleanups stay double); the spiking backend's dense reference sets it to False.

    Args:
        cfg: The resonator configuration (``path='fast'``, DFT codebooks).
        g: Its geometry.
    """

    #: Run the direct form where the configuration allows it (see the class docstring).
    direct = True
    #: Frame and map spectra in single precision also in the general form (class docstring).
    single = True

    def __init__(self, cfg: ResonatorConfig, g: Geometry) -> None:
        self.cfg = cfg
        self.g = g
        self.lp = LogPolarTransform(g)
        self.books = factor_codebooks(cfg, g)
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
        self._keep_drive = cfg.readout.source == 'drive'   # (only that readout needs them)
        self._direct = self.direct and not self.has_z and not cfg.cleanup.whiten
        self._hv_rows = (self._direct and self._full['h'] and self._full['v']
                         and len(self.books['h'].phases) == len(self.books['v'].phases))
        # h, v and r cleaned as one concatenated vector where each step is elementwise (see
        # _update_direct); update() stays the hook of a subclass that overrides it
        self._rows = ('h', 'v', 'r')
        self._row_batch = (self._direct and all(self._full[k] for k in self._rows)
                           and cfg.cleanup.nonlinearity == 'exp' and not self._keep_drive
                           and type(self).update is FastEngine.update)
        lens = [len(self.books[k].phases) for k in self._rows]
        ends = np.cumsum(lens, dtype=np.intp)
        self._row_slices = [slice(int(e) - n, int(e)) for e, n in zip(ends, lens, strict=True)]
        self._row_start = ends - np.asarray(lens, np.intp)
        self._row_count = np.asarray(lens, np.intp)
        self._row_len = np.repeat(np.asarray(lens, np.float64), lens)   # n of each entry
        self._row_dec = np.concatenate([self._perm_dec[k] + sl.start for k, sl in
                                        zip(self._rows, self._row_slices, strict=True)])
        # the frame and map spectra: single precision (rounding ~1e-7 of the map's own
        # scale; the factor states and cleanups stay double), unless a subclass asks for double
        self._cdt: type[np.complexfloating] = (np.complex64 if self._direct or self.single
                                               else np.complex128)
        self._S_roll: Spectrum = np.zeros(0, self._cdt)   # n_ρ w² ⊙ S_θ (direct form)
        w2 = self.lp.w ** 2 if self.lp.weighted else np.ones(g.n_rho)
        self._roll_rows = (g.n_rho * w2).astype(np.float32)[:, None]   # its per-ring factor
        self._sw_key: Spectrum | None = None
        self._sw: Spectrum = np.zeros(0, self._cdt)
        self.state: dict[str, Complex] = {}
        self.drive: dict[str, Real] = {}      # normalised Re X† u of the last cleanups
        self.inputs: dict[str, Complex] = {}   # the last cleanup inputs (marginals) a
        self._ov_w = highpass_weights(g.canvas_height, g.canvas_width,
                                      cfg.tracking.overlap_highpass).astype(np.float32)
        self.m: Spectrum = np.zeros((g.canvas_height, g.canvas_width), self._cdt)
        self.m0 = self.m
        self._mc = self.m                           # m̂* (changes once per frame)
        self._mvh = np.empty_like(self.m)           # m̂ ⊙ v̂ ⊙ ĥ scratch (Λ_w copies it)
        self._q = np.empty((g.n_rho, g.n_theta), self._cdt)   # S ⊙ r̂* scratch (direct form)
        self._m0_src: Spectrum | None = None         # the m0 that _m0_scaled = μ2 m0 was made of
        self._m0_mu2 = 0.0
        self._m0_scaled = self.m0

    @property
    def blur_dtype(self) -> type[np.floating]:
        """float32 in the direct form (the frame and map spectra are single precision, so the
        network blurs the canvas in single precision too), float64 otherwise."""
        return np.float32 if self._cdt is np.complex64 else np.float64

    def encode(self, canvas: Floats) -> Spectrum:
        """The frame's log-polar spectrum: ``S`` (2-D), or ``S_θ`` in the direct form."""
        if self._direct:
            lp = self.lp.lp_image(canvas).astype(np.float32)
            S: Spectrum = np.asarray(hfft.fft(lp, axis=1), self._cdt)
            self._S_roll = S * self._roll_rows
            return S
        S = np.asarray(self.lp.encode_image_lp(canvas), self._cdt)
        if self.lp.weighted and self.lp.last_lp_image is not None:
            self._sw_key = S
            self._sw = np.asarray(self.lp.weight_image(self.lp.last_lp_image), self._cdt)
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

    def _update_direct(self, xs: tuple[Complex, ...], inputs: tuple[Complex, ...]
                       ) -> tuple[Complex, ...]:
        """``update`` of h, v and r (complete DFT codebooks, ``exp`` cleanup) as one vector.

        Between the per-factor FFTs every step of ``_clean`` and ``_blend`` is elementwise,
        or a maximum per factor, so it runs once over the three concatenated (416 entries
        instead of three calls of 96-192 each: the numpy calls, not the arithmetic, cost the
        time at this size). The same operations on the same values, so the same bits; where a
        factor would take a branch of :func:`cleanup_weights` other than the plain ``exp`` one
        (a blank or tiny input), all three go through ``update`` instead. Returns the new
        states (views of one array), in ``_rows`` order.
        """
        names, starts, rows = self._rows, self._row_start, self._row_slices
        cfg = self.cfg.cleanup
        bounds = np.array([self.col_norm[k] * math.sqrt(float(np.vdot(a, a).real))
                           for k, a in zip(names, inputs, strict=True)])
        c = np.concatenate([hfft.ifft(a).real for a in inputs])
        c *= self._row_len                          # n Re ifft a: the similarities
        mag = np.abs(c)
        top = np.maximum.reduceat(mag, starts)
        # no entry below cleanup_weights' rounding-noise floor 1e-9 |x_j| |a| (nor a blank
        # input, bound 0): else its other branches, per factor
        if not (np.fmin.reduceat(mag, starts) > 1e-9 * bounds).all():
            return tuple(self.update(k, x, a)
                         for k, x, a in zip(names, xs, inputs, strict=True))
        y = c * np.repeat(cfg.beta / top, self._row_count)
        y -= cfg.beta
        p = np.exp(y, out=y)
        cleaned = fhrr.phasor(np.concatenate([hfft.fft(p[sl]) for sl in rows]))
        blank = [sl for sl in rows if cleaned[sl.start] == 0 and not cleaned[sl].any()]
        x = np.concatenate(xs)
        gamma = state_gamma(self.cfg)
        np.multiply(cleaned, gamma, out=cleaned)
        np.add(cleaned, (1 - gamma) * x, out=cleaned)
        for sl in blank:                            # (as blend_state)
            cleaned[sl] = x[sl]
        return tuple(cleaned[sl] for sl in rows)

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

    def _weighted_input(self, S: Spectrum) -> Spectrum:
        if not self.lp.weighted:
            return S
        if self._sw_key is not S:                   # once per frame (S is fixed within it)
            self._sw_key, self._sw = S, np.asarray(self.lp.weight(S), S.dtype)
        return self._sw

    def iterate(self, S: Complex) -> None:
        if self._direct:
            self._iterate_direct(S)
            return
        st = self.state
        h, v, r = st['h'], st['v'], st['r']
        z = st.get('z')
        dt = self._cdt          # the spectra's precision (the states, double, are cast to it)
        S = self.send('S', S)
        m = self.send('m', np.asarray(self.m, dt))
        mc = self._mc if m is self.m else m.conj()
        q = S * r.conj().astype(dt)[None, :]
        if z is not None:
            q *= z.conj().astype(dt)[:, None]
        u = self.send('p', self.lp.reverse(q))      # p̂ = Λ'(S ⊙ r̂* ⊙ ẑ*)
        u *= mc                                     # p̂ ⊙ m̂*
        # l̂ = Λ(m̂ ⊙ ĥ ⊙ v̂); the roll/scale correlation uses ring-weighted log-polar images
        # (D_w S ⊙ (D_w l̂)*, identity when logpolar.ring_weight = 0).
        mvh = np.multiply(m, v.astype(dt)[:, None], out=self._mvh)
        mvh *= h.astype(dt)[None, :]
        w = self.send('l', self.lp.forward_weighted(mvh))
        np.conjugate(w, out=w)
        w *= self._weighted_input(S)                # S ⊙ l̂*
        hb, vb, rb, zb = h, v, r, z
        if self.cfg.cleanup.whiten:                 # f(a ⊙ b) = f(a) ⊙ f(b): whiten factorwise
            u, w = fhrr.phasor(u), fhrr.phasor(w)
            hb, vb, rb = fhrr.phasor(h), fhrr.phasor(v), fhrr.phasor(r)
            zb = None if z is None else fhrr.phasor(z)
        # (broadcast products and sums, not einsum: see _iterate_direct; in the spectra's
        # precision, the marginals then cast back to double, the states' precision)
        c128 = np.complex128
        a_h = (u * vb.conj().astype(u.dtype)[:, None]).sum(axis=0).astype(c128)  # Σ_ky p̂m̂*v̂*
        a_v = (u * hb.conj().astype(u.dtype)[None, :]).sum(axis=1).astype(c128)  # Σ_kx p̂m̂*ĥ*
        if z is not None and zb is not None:
            a_r = (w * zb.conj().astype(w.dtype)[:, None]).sum(axis=0).astype(c128)
            a_z = (w * rb.conj().astype(w.dtype)[None, :]).sum(axis=1).astype(c128)
            st['z'] = self.update('z', z, a_z)
        else:
            a_r = w.sum(axis=0).astype(c128)
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
        # (the products into scratch arrays: fresh 100 kB temporaries cost more than the
        # products on a shared machine)
        q = np.multiply(S_theta, r.conj().astype(dt)[None, :], out=self._q)
        u = self.lp.reverse_theta(q)                             # Λ'(S ⊙ r̂*)
        u *= self._mc                                            # p̂ ⊙ m̂*
        mvh = np.multiply(self.m, vs[:, None], out=self._mvh)
        mvh *= hs[None, :]
        lt = self.lp.forward_theta(mvh)                          # fft_θ(T ifft2(m̂ ⊙ v̂ ⊙ ĥ))
        np.conjugate(lt, out=lt)
        lt *= self._S_roll
        a_r = lt.sum(axis=0).astype(np.complex128)               # Σ_kρ S_w ⊙ l̂_w*
        # (broadcast products and sums: einsum takes 3-10x longer on complex64 at this size,
        # and BLAS gemv may go multi-threaded)
        a_h = np.multiply(u, vs.conj()[:, None], out=self._mvh).sum(axis=0).astype(np.complex128)
        a_v = np.multiply(u, hs.conj()[None, :], out=u).sum(axis=1).astype(np.complex128)
        self.inputs.update(h=a_h, v=a_v, r=a_r)
        if self._hv_rows:      # one cleanup for both (update() is no hook in the direct form)
            cleaned = self._clean_full(('h', 'v'), np.stack((a_h, a_v)))
            hv = self._blend(np.stack((h, v)), cleaned)
            st['h'], st['v'] = hv[0], hv[1]
        elif self._row_batch:
            st['h'], st['v'], st['r'] = self._update_direct((h, v, r), (a_h, a_v, a_r))
            return
        else:
            st['h'] = self.update('h', h, a_h)
            st['v'] = self.update('v', v, a_v)
        st['r'] = self.update('r', r, a_r)

    def similarities(self) -> dict[str, Real]:
        st = self.state
        if self._row_batch and len(st) == len(self._rows):    # h, v, r as one vector
            norms = [float(np.linalg.norm(st[k])) for k in self._rows]
            if all(norms):      # (as book_decode and normalised_similarity, elementwise)
                c = np.concatenate([hfft.ifft(st[k]) for k in self._rows])[self._row_dec]
                c *= self._row_len
                scale = [self.col_norm[k] * n for k, n in zip(self._rows, norms, strict=True)]
                sims = np.real(c) / np.repeat(scale, self._row_count)
                return {k: sims[sl] for k, sl in zip(self._rows, self._row_slices, strict=True)}
        return {k: normalised_similarity(self.book_decode(k, x), x, self.col_norm[k])
                for k, x in st.items()}

    def input_projection(self, name: str) -> Complex:
        """``phasor(X X† a)`` of factor ``name``'s last cleanup input (readout.refine_input);
        a complete DFT codebook has ``X X† = n I``, so it is ``phasor(a)``."""
        a = self.inputs[name]
        if not self._full[name]:
            a = self.book_encode(name, self.book_decode(name, a))
        return fhrr.phasor(a)

    def shift(self, name: str, delta: float) -> None:
        # seed^delta = fhrr.power(phases, delta), from the cached 1j phases (the same product)
        self.state[name] = self.state[name] * np.exp(self._jphases[name] * float(delta))

    def _to_map(self, S: Spectrum, point: dict[str, float]) -> Spectrum:
        jp, dt = self._jphases, self._cdt           # z0^a = exp((1j φ) a), as fhrr.power
        q = S * np.exp(jp['r'] * float(-point['r'])).astype(dt)[None, :]
        if self.has_z:
            q *= np.exp(jp['z'] * float(-point['z'])).astype(dt)[:, None]
        t = self.lp.reverse_theta(q) if self._direct else self.lp.reverse(q)
        t *= np.exp(jp['v'] * float(-point['v'])).astype(dt)[:, None]
        t *= np.exp(jp['h'] * float(-point['h'])).astype(dt)[None, :]
        return t

    def map_target(self, S: Spectrum, point: dict[str, float]) -> Spectrum:
        """The frame ``S`` moved into the map at ``point`` (the map update's target ``m(t)``;
        the network reuses it for the update, so the overlap costs one inner product)."""
        return self._to_map(S, point)

    def overlap(self, target: Spectrum) -> float:
        """Normalised frame-map overlap ``Re<w m, w t> / (|w m| |w t|)``, in [-1, 1], with
        the high-pass weight ``w`` of ``tracking.overlap_highpass`` (no DC: the canvas is
        non-negative; no low frequencies: the frame's support window overlaps the map at any
        pose); 0 for a blank frame."""
        return weighted_overlap(self.m, target, self._ov_w)

    def distinctiveness(self, target: Spectrum) -> float:
        """Peak-to-sidelobe ratio of the frame-map correlation at the estimate
        (:func:`~hrn_vo_ros.core.hrn.shared.peak_to_sidelobe`, high-passed as the overlap)."""
        return peak_to_sidelobe(self._mc, target, self._ov_w, PSR_EXCLUDE)

    def relocalise(self, S: Spectrum, rolls: int, z: float, keep: int
                   ) -> list[tuple[float, dict[str, float]]]:
        """Global search of the frame against the map over roll and shift (re-localisation).

        For each of ``rolls`` roll candidates (evenly over the full turn) the frame is rotated
        into the map's orientation, ``t0 = _to_map(S, (0, 0, r_k, z))``, and its half-whitened
        cross-power with the map, ``C = t0 ⊙ m̂* / |t0 ⊙ m̂*|^(1/2)`` (DC removed), is decoded
        over every h/v codebook pair, ``Re X_v† C X_h†ᵀ``: a phase correlation over all shifts.

        Returns:
            Up to ``keep`` candidates ``(score, point)``, best first, one per roll (score: the
            correlation peak over its bound, in [-1, 1]).
        """
        books = self.books
        bh, bv, br = books['h'], books['v'], books['r']
        n_r = len(br.phases)
        mc = self._mc
        out: list[tuple[float, dict[str, float]]] = []
        for k in range(rolls):
            r_k = br.wrap(k * n_r / rolls)
            t0 = self._to_map(S, {'h': 0.0, 'v': 0.0, 'r': r_k, 'z': z})
            c = np.asarray(t0 * mc, np.complex128)
            c[0, 0] = 0.0
            mag = np.sqrt(np.abs(c))
            bound = float(mag.sum())
            if bound <= 0.0:
                continue
            c /= np.maximum(mag, 1e-30)
            corr = self._decode_shifts(c)
            i, j = np.unravel_index(int(np.argmax(corr)), corr.shape)
            out.append((float(corr[i, j]) / bound,
                        {'h': bh.wrap(float(bh.values[j])), 'v': bv.wrap(float(bv.values[i])),
                         'r': r_k, 'z': z}))
        out.sort(key=lambda sc: -sc[0])
        return out[:keep]

    def _decode_shifts(self, c: Complex) -> Real:
        """``Re X_v† c X_h†ᵀ`` over every h/v codebook pair: for full DFT codebooks the 2-D
        form of :meth:`book_decode` (one inverse FFT, read in entry order), else the dense
        products."""
        if not (self._full['h'] and self._full['v']):
            return np.asarray(np.real(self.XH['v'] @ c @ self.XH['h'].T), np.float64)
        full = np.real(hfft.ifft2(c))[np.ix_(self._perm_dec['v'], self._perm_dec['h'])]
        full *= float(c.size)
        return np.asarray(full, np.float64)

    def set_point(self, point: dict[str, float]) -> None:
        """Set every factor state to its codebook vector at ``point`` (seed^a, index units)."""
        for name, x in self.state.items():
            self.state[name] = np.ones_like(x)
            self.shift(name, point[name])

    def update_map(self, S: Complex, point: dict[str, float], mu1: float, mu2: float,
                   target: Spectrum | None = None) -> None:
        if target is None:
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
