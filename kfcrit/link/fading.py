r"""Fast fading in the link budget: Rayleigh and Nakagami-m, averaged exactly per attempt.

With fading, the instantaneous SNR γ of one attempt is Gamma distributed around the mean γ̄ that
the path loss (and the shadowing of the period) sets:

.. math:: \gamma \sim \mathrm{Gamma}(m, \bar\gamma/m),\qquad
          f(\gamma) = \frac{m^m \gamma^{m-1}}{\bar\gamma^m \Gamma(m)} e^{-m\gamma/\bar\gamma}

(Nakagami-m amplitude, m ≥ 1/2; Rayleigh is m = 1, an exponential γ). Assumption: *fast*
fading, redrawn independently for every attempt. Retries are milliseconds apart, while
multipath fading decorrelates within a fraction of a wavelength of motion (6 cm at 2.4 GHz) or
of movement of the scatterers around the link, so successive attempts see independent fades.
The attempt success is then q(γ̄) = 1 − E_γ[PER(γ)] and a period with k retries delivers with

.. math:: p = 1 - \bigl(1 - q(\bar\gamma)\bigr)^{k+1} = 1 - E_\gamma[\mathrm{PER}(\gamma)]^{k+1}.

Log-normal shadowing sets γ̄ (per link, per period, or per attempt as configured) and the fast
fading varies around it.

The average is computed (docs/theory.md §11.1) by generalised Gauss–Laguerre quadrature in
x = γ·m/γ̄ (weight x^{m−1}e^{−x}) with 64 and 128 nodes; the 128-node value is taken where the
two agree to :data:`GL_TOLERANCE` and the PER is resolved by the nodes (the probability mass
below the smallest node, times the PER change across it, is below :data:`GL_TOLERANCE`/10).
Where the mean SNR is far above the PER threshold (the design regime) the whole PER transition
sits below the smallest Laguerre node and both node counts see only the success plateau; there,
and for m > :data:`GL_MAX_M`, a composite Gauss–Legendre rule in u = ln x is used instead
(vectorised over the mean SNRs; its tails beyond the 1e-15 quantiles are added exactly).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from kfcrit.errors import InputError
from kfcrit.link.fields import mapping_field, real_field
from kfcrit.records.channel import FadingRecord

FADING_MODELS = ("none", "rayleigh", "nakagami")
"""Fast-fading models of a link budget (default first)."""
MIN_NAKAGAMI_M = 0.5
MAX_NAKAGAMI_M = 1e4
GL_NODES = (64, 128)
"""Node counts of the generalised Gauss–Laguerre rule and its convergence check."""
GL_TOLERANCE = 1e-9
"""Largest accepted disagreement of the two Gauss–Laguerre node counts."""
GL_MAX_M = 100.0
"""Above this m the Laguerre weights overflow; the composite rule is used."""
TAIL = 1e-15
"""Probability mass of each Gamma tail outside the composite rule's interval."""
LEGENDRE_NODES = 10
"""Gauss–Legendre nodes per panel of the composite rule in u = ln x."""
PANEL_WIDTH = 0.4
"""Largest panel of the composite rule, in u = ln x (1.7 dB of SNR)."""

SHADOWING_STEP_DB = 0.02
"""Step (dB) of the shadowing average without fading (σ·h of the trapezoid rule)."""

PerFunction = Callable[[np.ndarray], np.ndarray]
"""PER of one attempt as a function of the linear SNR γ (vectorised)."""


@dataclass(frozen=True)
class FastFading:
    r"""Fast fading of a link: ``none``, ``rayleigh`` (m = 1) or ``nakagami`` (m ≥ 1/2).

    .. math:: \gamma \sim \mathrm{Gamma}(m, \bar\gamma/m),\qquad
              \bar{\mathrm{PER}}(\bar\gamma) = E_\gamma[\mathrm{PER}(\gamma)]

    Parameters
    ----------
    model : {"none", "rayleigh", "nakagami"}
        The fading model.
    m : float, optional
        Nakagami shape (``nakagami`` only, 0.5 ≤ m ≤ 1e4).

    Raises
    ------
    kfcrit.errors.InputError
        An unknown model, or m missing, out of range or given without ``nakagami``.

    References
    ----------
    docs/theory.md §11.1 (fast fading).

    Examples
    --------
    >>> FastFading.from_mapping({"model": "nakagami", "m": 2}, "channel.fading").shape
    2.0
    >>> FastFading.from_mapping({"model": "nakagami", "m": 0.3}, "channel.fading")
    Traceback (most recent call last):
        ...
    kfcrit.errors.InputError: channel.fading.m: must be >= 0.5, got 0.3
    """

    model: str = "none"
    m: float | None = None

    def __post_init__(self) -> None:
        if self.model not in FADING_MODELS:
            raise InputError(f"must be one of: {', '.join(FADING_MODELS)}", field="fading.model")
        if self.model == "nakagami":
            if self.m is None or not MIN_NAKAGAMI_M <= self.m <= MAX_NAKAGAMI_M:
                raise InputError(f"nakagami needs {MIN_NAKAGAMI_M:g} <= m <= "
                                 f"{MAX_NAKAGAMI_M:g}, got {self.m}", field="fading.m")
        elif self.m is not None:
            raise InputError("only with model: nakagami", field="fading.m")

    @classmethod
    def from_mapping(cls, value: Any, prefix: str) -> FastFading:
        """Read ``{model, m}`` (``prefix`` names the mapping, e.g. ``channel.fading``)."""
        data = mapping_field(value, prefix)
        unknown = sorted(set(data) - {"model", "m"})
        if unknown:
            raise InputError(f"unknown key {unknown[0]!r} (allowed: model, m)",
                             field=f"{prefix}.{unknown[0]}")
        if "model" not in data:
            raise InputError("is required", field=f"{prefix}.model")
        model = data["model"]
        if not isinstance(model, str) or model not in FADING_MODELS:
            raise InputError(f"must be one of: {', '.join(FADING_MODELS)}",
                             field=f"{prefix}.model")
        m = None
        if "m" in data:
            if model != "nakagami":
                raise InputError("only with model: nakagami", field=f"{prefix}.m")
            m = real_field(data, "m", prefix, low=MIN_NAKAGAMI_M, high=MAX_NAKAGAMI_M)
        elif model == "nakagami":
            raise InputError("is required with model: nakagami", field=f"{prefix}.m")
        return cls(model, m)

    @property
    def active(self) -> bool:
        return self.model != "none"

    @property
    def shape(self) -> float | None:
        """The Gamma shape m of the SNR (1 for Rayleigh; None without fading)."""
        return None if self.model == "none" else (1.0 if self.model == "rayleigh"
                                                  else float(self.m))

    def mean_per(self, per: PerFunction, mean_snr: Any) -> np.ndarray:
        """E_γ[PER(γ)] at the mean linear SNRs ``mean_snr`` (PER itself without fading)."""
        if not self.active:
            return np.asarray(per(np.asarray(mean_snr, dtype=float)), dtype=float)
        return faded_per(per, mean_snr, float(self.shape))[0]

    def spread_db(self) -> float:
        r"""Standard deviation of 10·log10(γ/γ̄) under the fading (0 without fading).

        .. math:: \mathrm{sd}[10\log_{10}\gamma] = \frac{10}{\ln 10}\sqrt{\psi'(m)}

        (ψ′ the trigamma function; 5.57 dB for Rayleigh).
        """
        if not self.active:
            return 0.0
        from scipy.special import polygamma

        return float(10.0 / math.log(10.0) * math.sqrt(polygamma(1, float(self.shape))))

    def shadowing_step_db(self) -> float:
        """Step (dB) of the shadowing average: 0.02 dB, or spread/20 ≤ 0.25 dB with fading.

        The fading average of the PER is a convolution with a kernel of width
        :meth:`spread_db`, smooth on that scale, so a step of a twentieth of it keeps the
        trapezoid rule's geometric convergence (checked in tests/link/test_fading.py).
        """
        return max(SHADOWING_STEP_DB, min(0.25, self.spread_db() / 20.0))

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model, "m": self.shape}

    def record(self) -> FadingRecord:
        """The fast fading as the record states it (``channel.fading``)."""
        return FadingRecord(model=self.model, m=self.shape)


NO_FADING = FastFading()


@lru_cache(maxsize=64)
def laguerre_rule(nodes: int, m: float) -> tuple[np.ndarray, np.ndarray]:
    r"""Nodes and weights of ∫ x^{m−1}e^{−x} g(x) dx / Γ(m) (weights sum to 1).

    .. math:: E[g(X)] \approx \sum_i w_i\, g(x_i),\qquad X \sim \mathrm{Gamma}(m, 1)
    """
    from scipy.special import gamma, roots_genlaguerre

    x, w = roots_genlaguerre(nodes, m - 1.0)
    return x, w / gamma(m)


@lru_cache(maxsize=64)
def log_rule(m: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    r"""Composite Gauss–Legendre rule for E[g(X)], X ~ Gamma(m, 1), in u = ln x.

    .. math:: E[g(X)] = \int g(e^u)\,\frac{e^{mu - e^u}}{\Gamma(m)}\,du

    over [ln x_lo, ln x_hi] with P(X < x_lo) = P(X > x_hi) = :data:`TAIL`; panels of width
    min(:data:`PANEL_WIDTH`, 0.5/√m) in u (at most 1.7 dB of SNR, each with
    :data:`LEGENDRE_NODES` nodes). The weights are normalised to 1 − 2·:data:`TAIL` (this only
    removes the rounding of the constant ln Γ(m)). Returns the nodes x, the weights, x_lo and
    x_hi.
    """
    from scipy.special import gammainccinv, gammaincinv, gammaln

    x_lo, x_hi = float(gammaincinv(m, TAIL)), float(gammainccinv(m, TAIL))
    lo, hi = math.log(x_lo / m), math.log(x_hi / m)   # v = ln(x/m) = ln(γ/γ̄)
    width = min(PANEL_WIDTH, 0.5 / math.sqrt(m))
    panels = max(1, math.ceil((hi - lo) / width))
    t, tw = np.polynomial.legendre.leggauss(LEGENDRE_NODES)
    edges = np.linspace(lo, hi, panels + 1)
    half = 0.5 * np.diff(edges)
    v = (0.5 * (edges[:-1] + edges[1:])[:, None] + half[:, None] * t[None, :]).ravel()
    # density of v: exp(m ln m + m v − m e^v − ln Γ(m)), written without large cancelling terms
    log_density = -m * (np.expm1(v) - v) + (m * math.log(m) - m - gammaln(m))
    w = (half[:, None] * tw[None, :]).ravel() * np.exp(log_density)
    w *= (1.0 - 2.0 * TAIL) / w.sum()   # the constant's rounding (≈ 1e-13 for m = 1e4)
    return m * np.exp(v), w, x_lo, x_hi


def faded_per_log_rule(per: PerFunction, mean_snr: np.ndarray, m: float) -> np.ndarray:
    """E_γ[PER(γ)] by the composite rule of :func:`log_rule` plus its two tails.

    The tails hold mass :data:`TAIL` each; PER is non-increasing in γ, so PER(x_lo·γ̄/m) and
    PER(x_hi·γ̄/m) stand for it there with an error below 1e-15.
    """
    x, w, x_lo, x_hi = log_rule(m)
    g = np.asarray(mean_snr, dtype=float)[..., None] / m
    body = np.sum(per(g * x) * w, axis=-1)
    return body + TAIL * (per(g[..., 0] * x_lo) + per(g[..., 0] * x_hi))


def faded_per(per: PerFunction, mean_snr: Any, m: float) -> tuple[np.ndarray, np.ndarray]:
    r"""E_γ[PER(γ)], γ ~ Gamma(m, γ̄/m), at every mean SNR γ̄, with an error estimate.

    .. math:: E_\gamma[\mathrm{PER}(\gamma)] = \frac{1}{\Gamma(m)}\int_0^\infty
              x^{m-1} e^{-x}\,\mathrm{PER}(\bar\gamma x/m)\,dx
              \approx \sum_{i=1}^{128} w_i\,\mathrm{PER}(\bar\gamma x_i/m)

    (generalised Gauss–Laguerre, α = m − 1). The estimate is |Q_128 − Q_64| where the
    Laguerre value is accepted (both agree within :data:`GL_TOLERANCE` and the PER is resolved
    by the nodes), else the composite rule of :func:`log_rule` is used and the estimate is the
    tail bound 2·:data:`TAIL` (its panel error is far below it; tests/link/test_fading.py
    checks both rules against scipy.integrate.quad).

    Parameters
    ----------
    per : callable
        PER of one attempt at linear SNR (vectorised, non-increasing).
    mean_snr : array_like
        Mean linear SNRs γ̄.
    m : float
        Gamma shape (1: Rayleigh).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The averaged PER and the error estimate, both of the shape of ``mean_snr``.

    References
    ----------
    docs/theory.md §11.1.
    """
    shape = np.shape(mean_snr)
    gbar = np.asarray(mean_snr, dtype=float).ravel()
    if m > GL_MAX_M:
        return (np.clip(faded_per_log_rule(per, gbar, m), 0.0, 1.0).reshape(shape),
                np.full(shape, 2 * TAIL))
    from scipy.special import gammainc

    g = gbar[..., None] / m
    (x1, w1), (x2, w2) = (laguerre_rule(n, m) for n in GL_NODES)
    coarse = np.sum(per(g * x1) * w1, axis=-1)
    fine = np.sum(per(g * x2) * w2, axis=-1)
    err = np.abs(fine - coarse)
    # PER change below the smallest node, weighted by its probability mass
    hidden = gammainc(m, x2[0]) * np.abs(per(np.zeros(gbar.shape)) - per(gbar * x2[0] / m))
    bad = (err > GL_TOLERANCE) | (hidden > 0.1 * GL_TOLERANCE)
    if np.any(bad):
        err[bad] = 2 * TAIL
        fine[bad] = faded_per_log_rule(per, gbar[bad], m)
    return np.clip(fine, 0.0, 1.0).reshape(shape), err.reshape(shape)


def fading_note(fading: FastFading) -> str | None:
    """What the link's fading assumes, in words for the record (None without fading)."""
    if not fading.active:
        return None
    what = "Rayleigh (m = 1)" if fading.model == "rayleigh" else f"Nakagami-m (m = {fading.shape:g})"
    return (f"{what} fast fading: the SNR of each attempt is Gamma(m, mean/m) around the mean "
            "SNR, redrawn independently per attempt (retries are milliseconds apart; multipath "
            "fading decorrelates within a fraction of a wavelength); the attempt PER is "
            "E[PER(gamma)] by Gauss-Laguerre quadrature (64 vs 128 nodes, <= 1e-9) or a "
            "composite rule in ln gamma where the nodes do not resolve it; shadowing sets the "
            "mean SNR")


def correlated_all_fail(per: Callable[[np.ndarray], np.ndarray], z: np.ndarray,
                        weights: np.ndarray, rho: float, attempts: int,
                        nodes: int = 64) -> float:
    r"""P(all ``attempts`` attempts of a period fail) when attempt j sees the shadowing
    :math:`\sigma Z_j` of a stationary Gauss–Markov sequence,

    .. math::

        Z_{j+1} = \rho Z_j + \sqrt{1 - \rho^2}\, W_j, \qquad
        P_{\text{fail}} = E\Bigl[\prod_{j} \mathrm{PER}(s + \sigma Z_j)\Bigr],

    with :math:`\rho = e^{-\Delta/T_c}` (attempt spacing Δ, coherence time T_c). Computed by the
    backward recursion :math:`g_{J}(z) = \mathrm{PER}(z)`,
    :math:`g_j(z) = \mathrm{PER}(z)\, E[g_{j+1}(\rho z + \sqrt{1-\rho^2} W)]` on the grid ``z``
    (the Gaussian transition density on the grid; for ρ near 1, where it is narrower than the
    grid, linear interpolation with Gauss–Hermite in W with ``nodes`` points), then
    :math:`P_{\text{fail}} = \int g_0(z) \varphi(z)\,dz` by the trapezoid rule with ``weights``
    (φ on ``z``). ρ = 1 gives the shared value E[PER^J], ρ = 0 the independent (E[PER])^J.

    Parameters
    ----------
    per : callable
        PER of one attempt on an array of grid points z (the caller maps z to s + σz).
    z, weights : numpy.ndarray
        The standard-normal grid and its density values.
    rho : float
        Correlation of consecutive attempts, in [0, 1].
    attempts : int
        k + 1.
    nodes : int
        Gauss–Hermite nodes of the inner expectation.

    Returns
    -------
    float
        The probability that every attempt fails.
    """
    base = np.clip(np.asarray(per(z), dtype=float), 0.0, 1.0)
    g = base.copy()
    spread = math.sqrt(max(0.0, 1.0 - rho * rho))
    step = float(z[1] - z[0]) if z.size > 1 else 1.0
    if spread > 4 * step:
        # the transition density of Z_{j+1} given Z_j on the grid (rows normalised): resolves
        # a PER step as finely as the grid, where a fixed Gauss–Hermite rule would not
        kernel = np.exp(-0.5 * ((z[None, :] - rho * z[:, None]) / spread) ** 2)
        kernel /= kernel.sum(axis=1, keepdims=True)

        def expect(values: np.ndarray) -> np.ndarray:
            return kernel @ values
    else:
        # nearly deterministic step (ρ ≈ 1): interpolate at ρz + spread·W, W by Gauss–Hermite
        w, wt = np.polynomial.hermite_e.hermegauss(nodes)
        wt = wt / wt.sum()

        def expect(values: np.ndarray) -> np.ndarray:
            return np.interp(rho * z[:, None] + spread * w[None, :], z, values) @ wt
    for _ in range(attempts - 1):
        g = base * expect(g)
    return float(min(1.0, max(0.0, np.trapezoid(g * weights, z))))
