"""Streaming statistics of the Monte Carlo: Welford and log-sum-exp sums, proportions, JSON.

Sample columns are accumulated in path order, so every statistic is bit-identical for any batch
size. Values beyond float64 are carried as natural logs (log-sum-exp sums) and reported as
log10; nothing here ever returns a silent inf or NaN for a finite sample.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

Z95 = 1.959963984540054
"""Two-sided 95 % normal quantile."""


class quiet_numerics:  # noqa: N801 - used like a function: ``with quiet_numerics():``
    """Silence floating-point ``RuntimeWarning``s and scipy's ``LinAlgWarning`` inside a block.

    Overflow and ill-conditioning are handled explicitly where they can occur (divergence
    thresholds, ``np.isfinite`` checks, warnings in the record); this keeps NumPy/scipy from
    also printing them on stderr, which carries only kfcrit's own messages.
    """

    def __enter__(self) -> quiet_numerics:
        import warnings

        from scipy.linalg import LinAlgWarning

        self._err = np.seterr(all="ignore")
        self._ctx = warnings.catch_warnings()
        self._ctx.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.simplefilter("ignore", LinAlgWarning)
        return self

    def __exit__(self, *exc: object) -> None:
        self._ctx.__exit__(*exc)
        np.seterr(**self._err)


LOG_SAFE = 345.0
"""ln of ~1e150: above it, means and variances of a sample column come from log-sum-exp sums."""
LOG_KEEP = LOG_SAFE - 100.0
"""Sample values below e^LOG_KEEP enter the log-sum-exp sums as −inf (nothing): those sums are
used only for columns whose maximum exceeds e^LOG_SAFE, where each such value weighs less than
e^{−100} relative to the maximum — below float64 rounding for any number of paths < 1e27."""


LN10 = math.log(10.0)


@njit(cache=True)
def accumulate_log(lvalues, lmax, s1, s2):
    """Streaming log-sum-exp per column: Σ e^{x − M} and Σ e^{2(x − M)}, M the running max.

    Rows in order (bit-identical for any batch size); −inf entries (a zero trace, or a value
    below e^LOG_KEEP recorded as −inf by the kernel) add nothing.
    """
    for b in range(lvalues.shape[0]):
        for s in range(lvalues.shape[1]):
            x = lvalues[b, s]
            if x == -math.inf:
                continue
            if x > lmax[s]:
                if lmax[s] > -math.inf:
                    e = math.exp(lmax[s] - x)
                    s1[s] *= e
                    s2[s] *= e * e
                lmax[s] = x
            d = math.exp(x - lmax[s])
            s1[s] += d
            s2[s] += d * d


@njit(cache=True)
def accumulate(values, count, mean, m2):
    """Welford update of per-column mean and M2 with the rows of ``values``, in row order."""
    for b in range(values.shape[0]):
        count += 1
        for s in range(values.shape[1]):
            x = values[b, s]
            d = x - mean[s]
            mean[s] += d / count
            m2[s] += d * (x - mean[s])
    return count


def finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def json_array(a: np.ndarray) -> list:
    """Nested lists with non-finite values (an overflowing unstable state) as None."""
    if np.isfinite(a).all():
        return a.tolist()
    out = a.astype(object)
    out[~np.isfinite(a)] = None
    return out.tolist()


def proportion(k: int, n: int) -> dict[str, Any]:
    """Estimate k/n with its 95 % Wilson score interval."""
    if n == 0:
        return {"estimate": None, "lower": None, "upper": None, "count": 0, "total": 0}
    ph = k / n
    z2 = Z95 * Z95
    centre = (ph + z2 / (2 * n)) / (1 + z2 / n)
    half = Z95 * math.sqrt(ph * (1 - ph) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    lower = 0.0 if k == 0 else max(0.0, centre - half)   # exact ends (no 1e-19 round-off)
    upper = 1.0 if k == n else min(1.0, centre + half)
    return {"estimate": ph, "lower": lower, "upper": upper,
            "count": k, "total": n}


def column_stats(count: int, mean_w: np.ndarray, m2_w: np.ndarray, lmax: np.ndarray,
                  s1: np.ndarray, s2: np.ndarray) -> tuple[np.ndarray, ...]:
    """Mean, sample sd and their log10 per sample time.

    Columns whose largest value stays below e^LOG_SAFE (~1e150) use the Welford sums (the
    ordinary path, bit-identical for any batch size); larger ones use the log-sum-exp sums:
    ln mean = M + ln(Σe^{x−M}/N), ln E[x²] = 2M + ln(Σe^{2(x−M)}/N), var = N/(N−1)·(E[x²] − mean²).
    Values beyond float64 are then inf in the plain arrays and finite in the log10 ones.
    """
    N = max(count, 1)
    denom = max(count - 1, 1)
    with quiet_numerics():
        mean = mean_w.copy()
        std = np.sqrt(m2_w / denom)
        lmean = np.log10(mean)
        lstd = np.log10(std)
        big = lmax > LOG_SAFE
        if big.any():
            ln_mean = lmax[big] + np.log(s1[big] / N)
            ln_m2 = 2 * lmax[big] + np.log(s2[big] / N)
            gap = np.minimum(2 * ln_mean - ln_m2, 0.0)   # ln(mean²/E[x²]) ≤ 0
            ln_var = ln_m2 + np.log1p(-np.exp(gap)) + math.log(N / denom)
            lmean[big] = ln_mean / LN10
            lstd[big] = 0.5 * ln_var / LN10
            mean[big] = np.exp(ln_mean)
            std[big] = np.exp(0.5 * ln_var)
    return mean, std, lmean, lstd
