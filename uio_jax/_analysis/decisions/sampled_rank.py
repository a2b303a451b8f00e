"""Per-sample numerical ranks and distances, and the vote across samples.

The kernels of :mod:`uio_jax._analysis.decisions.rank` (the growing span,
:class:`~uio_jax._analysis.decisions.rank.Codistribution`):

* **Scaling.** Columns are scaled by the width of the sampling box (a diagonal change of
  coordinates: ranks and memberships are unchanged, states of different units become
  comparable) and rows to unit norm; a row below ``ZERO_ROW_RTOL`` of the largest row of
  its sample is an exact zero (the round-off gradient of a function that vanishes
  identically must not be blown up into a direction).
* **A candidate against a span** (:func:`residuals`, :func:`sequential_qr`): per sample, its
  distance ``rho`` to an orthonormal basis of the span (Gram-Schmidt, twice); for unit rows
  this is the last singular value of ``[basis; candidate]`` up to a factor in
  [1/sqrt(2), 1].
* **A whole matrix** (:func:`decide_rank`, used on the final set): per-sample SVD of the
  scaled rows, numerical rank = number of ``s_i / s_1`` above ``rtol``.
* **Across samples** (:func:`decide_rank`, :func:`decide_increase`): the generic answer is
  the majority (the mode of the per-sample ranks). Rank is lower semicontinuous, so a
  sample can only *drop* rank (near the singular set), while round-off in high-order
  derivatives can *fake* a little rank at a badly conditioned sample; both are minorities
  and the majority resists both. Every decision carries its evidence
  (:class:`RankDecision`): the agreeing fraction and the margins on both sides of ``rtol``.
"""

from dataclasses import dataclass

import numpy as np

from ..results.evidence import Settlement


def default_rtol() -> float:
    """Default relative tolerance on ``s_i / s_1`` (after row and column scaling).

    Why 1e-8: forward-mode derivatives are exact up to floating-point round-off, which
    for the nested Lie derivatives of our models (order <= 10, row- and column-scaled)
    stays below ~1e-12 relative to the row norm; directions that are genuinely
    independent at random states of a reasonable box have ``s_r / s_1`` well above 1e-6
    except on a thin neighbourhood of the singular set. 1e-8 sits in the middle of that
    gap, at least three decades from both sides; every report prints the measured gap
    so a user can see the margin.
    """
    return 1e-8


#: A row whose norm is below this fraction of the largest row norm of its matrix (same
#: sample) is treated as exactly zero before rows are scaled to unit norm: the round-off
#: gradient of a function that vanishes identically must not fake a rank. Genuine gradients
#: of our models differ in norm by far fewer than ten decades within one sample.
ZERO_ROW_RTOL = 1e-10


def ratios(mats):
    """Singular-value ratios ``s_i / s_1`` of row-normalized matrices.

    Rows below ``ZERO_ROW_RTOL`` times the largest row norm are zeroed; the others are
    scaled to unit norm.

    Args:
        mats: ``(..., k, n)``.

    Returns:
        ``(..., min(k, n))``, sorted descending; all zero for a zero matrix.
    """
    mats = np.asarray(mats, dtype=np.float64)
    norms = np.linalg.norm(mats, axis=-1, keepdims=True)
    ref = np.max(norms, axis=-2, keepdims=True)
    keep = norms > ZERO_ROW_RTOL * ref
    unit = np.where(keep, mats / np.where(keep, norms, 1.0), 0.0)
    s = np.linalg.svd(unit, compute_uv=False)
    top = s[..., :1]
    return s / np.where(top > 0, top, 1.0)


@dataclass(frozen=True)
class RankDecision:
    """The generic rank of one sampled matrix family, with its evidence.

    Attributes:
        rank: generic rank r (mode of the per-sample numerical ranks).
        fraction: fraction of the valid samples whose numerical rank is r.
        sigma_r_min: smallest ``s_r / s_1`` among the samples at rank r (1.0 when r = 0).
        sigma_next_max: largest ``s_{r+1} / s_1`` among the samples at rank r (0.0 when
            the matrix has only r singular values).
        samples: number of valid samples the decision used.
        settled: how the vote was settled again (:class:`Settlement`; a plain string is
            taken as its value).
    """

    rank: int
    fraction: float
    sigma_r_min: float
    sigma_next_max: float
    samples: int
    settled: "Settlement" = ""

    def __post_init__(self):
        object.__setattr__(self, "settled", Settlement(self.settled))


def decide_rank(ratios, valid, rtol) -> RankDecision:
    """Decide the generic rank from per-sample singular-value ratios (host, numpy).

    Args:
        ratios: ``(S, m)`` ratios ``s_i / s_1``, descending per row.
        valid: ``(S,)`` boolean, samples to use.
        rtol: relative tolerance; ratios above it count.

    Returns:
        :class:`RankDecision`.
    """
    ratios = np.asarray(ratios)[np.asarray(valid)]
    S, m = ratios.shape
    if S == 0:
        raise ValueError("no valid sample to decide a rank")
    ranks = (ratios > rtol).sum(axis=1)
    counts = np.bincount(ranks, minlength=m + 1)
    rank = int(np.flatnonzero(counts == counts.max())[-1])  # ties: the larger rank
    at = ranks == rank
    sig_r = float(ratios[at, rank - 1].min()) if rank > 0 else 1.0
    sig_next = float(ratios[at, rank].max()) if rank < m else 0.0
    return RankDecision(rank, float(at.mean()), sig_r, sig_next, int(S))


def residuals(basis, ref, cands):
    """Distance of unit-normalized candidates to the span of an orthonormal basis.

    Args:
        basis: ``(r, S, n)`` per-sample orthonormal rows (zero rows are ignored).
        ref: ``(S,)`` largest norm of the kept rows at each sample (zero-row guard).
        cands: ``(C, S, n)`` candidate covectors (column-scaled).

    Returns:
        ``rho (C, S)`` in [0, 1] and the unit residual directions ``(C, S, n)``.
        Candidates below ``ZERO_ROW_RTOL`` times the reference norm count as zero.
    """
    norms = np.linalg.norm(cands, axis=-1)
    zero = norms <= ZERO_ROW_RTOL * np.maximum(ref, norms)
    unit = np.where(zero[..., None], 0.0, cands / np.where(zero, 1.0, norms)[..., None])

    def project_out(v):
        coef = np.einsum("rsi,csi->csr", basis, v, optimize=True)
        return v - np.einsum("csr,rsi->csi", coef, basis, optimize=True)

    res = project_out(project_out(unit))  # Gram-Schmidt, twice is enough
    rho = np.linalg.norm(res, axis=-1)
    direction = res / np.where(rho > 0, rho, 1.0)[..., None]
    return rho, direction


#: From this many rising candidates on, their sequential Gram-Schmidt is a batched QR.
QR_FROM = 8


def sequential_qr(res):
    """``(Q (k, S, n), d (S, k))``: per sample, the QR of the residual columns ``res``
    ``(C, S, n)`` (``k = min(n, C)``): ``Q[j]`` is the direction of candidate ``j`` after the
    ones before it, ``d[:, j] = R_jj`` its signed distance (``Q`` candidate-major)."""
    q, r = np.linalg.qr(np.transpose(res, (1, 2, 0)))
    return np.ascontiguousarray(np.moveaxis(q, 2, 0)), np.diagonal(r, axis1=1, axis2=2)


def decide_increase(rho, valid, rtol, base_rank) -> RankDecision:
    """Does a candidate raise the generic rank? At a sample, when its distance ``rho`` to the
    span (after scaling it to unit norm) exceeds ``rtol``; generically, by majority.

    Args:
        rho: ``(S,)`` distances in [0, 1].
        valid: ``(S,)`` boolean mask of usable samples.
        rtol: tolerance.
        base_rank: generic rank of the span before the candidate.

    Returns:
        :class:`RankDecision` with the resulting rank; ``sigma_r_min`` is the smallest
        distance among the agreeing samples when the rank rises, ``sigma_next_max`` the
        largest distance among the agreeing samples when it does not.
    """
    rho = np.asarray(rho)[np.asarray(valid)]
    if rho.size == 0:
        raise ValueError("no valid sample to decide a rank")
    up = rho > rtol
    rises = up.mean() > 0.5
    agree = up if rises else ~up
    return RankDecision(
        rank=base_rank + int(rises),
        fraction=float(agree.mean()),
        sigma_r_min=float(rho[agree].min()) if rises else 1.0,
        sigma_next_max=0.0 if rises else float(rho[agree].max()),
        samples=int(rho.size),
    )


__all__ = ["default_rtol", "ZERO_ROW_RTOL", "ratios", "RankDecision", "decide_rank", "residuals", "QR_FROM",
           "sequential_qr", "decide_increase"]
