"""Generic rank of a codistribution, certified by sampling: the growing span.

A codistribution here is the span of the gradients of a few scalar functions. Its rank is
the same at almost every state (the *generic* rank) and lower on a thin singular set. We
evaluate the gradients at S random states of the domain and decide on the host, with the
per-sample kernels and the votes of :mod:`uio_jax._analysis.decisions.sampled_rank` (scaling,
distances, the majority across samples, the evidence of each decision).

* **Growing a span** (:class:`Codistribution`, the hot path): per sample, an orthonormal
  basis of the kept rows (Gram-Schmidt, twice); a candidate raises the rank at a sample
  when its distance ``rho`` to the span exceeds ``rtol``. Membership of a covector is the
  same test. O(S r n) per candidate, kept rows never re-factorized.
* **Beyond float64**: a weak vote (near ``rtol``, or split) is settled again in exact or
  extended arithmetic, a generator kept on a clear vote of a rational model is verified
  exactly, and so is every rejection of a step that keeps nothing
  (:attr:`Codistribution.settle`, :mod:`uio_jax._analysis.decisions.settle`).
"""

from dataclasses import dataclass, replace

import numpy as np

from .policy import Record, evidence
from .sampled_rank import (
    QR_FROM,
    ZERO_ROW_RTOL,
    RankDecision,
    decide_increase,
    decide_rank,
    default_rtol,
    ratios,
    residuals,
    sequential_qr,
)

_BLOCK_BYTES = 64 * 2**20

#: A unit covector whose first residual is shorter than this at some sample is projected
#: a second time (:meth:`Codistribution.test_units`).
_REPROJECT_BELOW = 0.7

#: Distance above which a direction settled independent beyond float64 enters the
#: per-sample basis (round-off of unit-scaled rows stays below 1e-13).
SETTLED_FLOOR = 1e-13


@dataclass(frozen=True)
class Tested:
    """Covectors tested against a span (:meth:`Codistribution.test`).

    Attributes:
        cands: ``(C, S, n)`` column-scaled covectors (non-finite entries set to 0).
        finite: ``(S,)`` samples where every covector is finite.
        rho: ``(C, S)`` distances of the unit-normalized covectors to the span.
        dirs: ``(C, S, n)`` unit residuals.
    """

    cands: np.ndarray
    finite: np.ndarray
    rho: np.ndarray
    dirs: np.ndarray

    def first(self, count: int) -> "Tested":
        """The first ``count`` covectors of the family (same samples)."""
        return Tested(self.cands[:count], self.finite, self.rho[:count], self.dirs[:count])

    def take(self, positions) -> "Tested":
        """The covectors at ``positions`` of the family, in that order (same samples)."""
        at = np.asarray(positions, dtype=np.intp)
        return Tested(self.cands[at], self.finite, self.rho[at], self.dirs[at])


class Codistribution:
    """A growing set of kept generators, evaluated at fixed sample states.

    Holds, per sample, the column-scaled gradients of the kept generators and an orthonormal
    basis of their span (Gram-Schmidt, rows zeroed at the samples where a kept row was
    dependent), stored row-major ``(capacity, S, n)`` and grown on demand (:attr:`grads` and
    :meth:`kept_basis` are ``(S, r, n)`` views). A candidate is kept when its distance to the
    span raises the generic rank (:func:`decide_increase`), O(S r n) per candidate; the final
    set is checked by a full SVD (:meth:`decision`).
    """

    def __init__(self, n, samples, col_scale, rtol):
        self.n = n
        self.col_scale = np.asarray(col_scale, dtype=np.float64)
        self.rtol = float(rtol)
        self.valid = np.ones(samples, dtype=bool)
        # per kept row (row-major: writing one is one contiguous block), grown on demand
        self._rows = np.zeros((0, samples, n))  # (capacity, S, n) the kept rows, column-scaled
        self.basis = np.zeros((0, samples, n))  # (capacity, S, n) their orthonormal basis
        self.ref = np.zeros(samples)
        self.nodes = []
        self.rejections: list[RankDecision] = []
        self.acceptances: list[RankDecision] = []
        #: what every vote is settled again by (:class:`~uio_jax._analysis.decisions.policy.DecisionPolicy`);
        #: None: the float64 votes stand
        self.policy = None
        #: what this span's decisions found beyond float64 (:class:`~uio_jax._analysis.decisions.policy.Record`)
        self.record = Record()
        self._decided = (None, None)  # (key, RankDecision) of the last decision()
        #: unit covectors ``e_i`` decided members of the span (``i -> RankDecision``): the
        #: span only grows, so they are not tested again
        self.unit_members: dict = {}

    @property
    def grads(self) -> np.ndarray:
        """``(S, r, n)``: the column-scaled gradients of the kept generators (a view)."""
        return np.moveaxis(self._rows[: self.rank], 0, 1)

    def kept_basis(self) -> np.ndarray:
        """``(S, r, n)``: per sample, the orthonormal rows of the span (zero rows where a kept
        generator was dependent at that sample; a view)."""
        return np.moveaxis(self.basis[: self.rank], 0, 1)

    @property
    def rank(self) -> int:
        """The generic rank ``r`` of the span: the number of kept generators."""
        return len(self.nodes)

    def copy(self, trial: bool = False) -> "Codistribution":
        """A copy of the span, with no decisions yet.

        The arrays and the list of kept nodes are copied, so absorbing into the copy leaves
        this one unchanged; ``acceptances`` and ``rejections`` start empty.

        ``trial``: the copy shares the storage of the kept rows and their basis instead: it
        writes only the rows past this span's rank, which this span does not read; the copy is
        valid until this span keeps another generator (a trial absorb, then discarded).
        """
        c = Codistribution.__new__(Codistribution)
        c.n, c.col_scale, c.rtol = self.n, self.col_scale, self.rtol
        r = self.rank
        c.valid, c.ref = self.valid.copy(), self.ref.copy()
        if trial:
            c._rows, c.basis = self._rows, self.basis
        else:
            c._rows, c.basis = np.zeros(self._rows.shape), np.zeros(self.basis.shape)  # same room
            c._rows[:r], c.basis[:r] = self._rows[:r], self.basis[:r]
        c.nodes = list(self.nodes)
        c.rejections, c.acceptances = [], []
        c.policy, c.record = self.policy, Record(contradicted=self.record.contradicted)
        c._decided = self._decided
        c.unit_members = dict(self.unit_members)
        return c

    def _scaled(self, cands):
        """Column-scale ``(C, S, n)`` covectors; non-finite -> 0, plus the finite mask (S,)."""
        cands = np.asarray(cands, dtype=np.float64)
        mask = np.isfinite(cands)
        finite = mask.all(axis=(0, 2))
        if not finite.all():
            cands = np.where(mask, cands, 0.0)
        return cands * self.col_scale, finite

    def _distances(self, cands):
        """``rho (C, S)`` and unit residuals ``(C, S, n)`` of scaled candidates, in chunks
        of about ``_BLOCK_BYTES``."""
        C, S, n = cands.shape
        chunk = max(1, _BLOCK_BYTES // (S * n * 8 * 4))
        basis = self.basis[: self.rank]
        rhos, dirs = [], []
        for start in range(0, C, chunk):
            rho, d = residuals(basis, self.ref, cands[start:start + chunk])
            rhos.append(rho)
            dirs.append(d)
        return np.concatenate(rhos), np.concatenate(dirs)

    def _reserve(self, rows: int):
        """Room for ``rows`` kept rows (capacity at least doubled when it grows, at most ``n``)."""
        cap = len(self._rows)
        if rows <= cap:
            return
        new = min(self.n, max(rows, 4, 2 * cap))
        S = len(self.valid)
        for name in ("_rows", "basis"):
            old = getattr(self, name)
            grown = np.zeros((new, S, self.n))
            grown[:cap] = old
            setattr(self, name, grown)

    def _keep(self, node, cand, rho, direction, decision):
        self._reserve(self.rank + 1)
        r = self.rank
        self._rows[r] = cand
        # a direction settled independent beyond float64 is kept wherever it stands out of
        # round-off (its distance may sit under rtol at every sample)
        floor = SETTLED_FLOOR if decision.settled in ("exact mod p", "mpmath") else self.rtol
        self.basis[r] = np.where((rho > floor)[:, None], direction, 0.0)
        self.ref = np.maximum(self.ref, np.linalg.norm(cand, axis=-1))
        self.nodes.append(node)
        self.acceptances.append(decision)

    def test(self, covectors) -> "Tested":
        """Distances of covector families ``(C, S, n)`` to the current span (one pass).

        The result can serve :meth:`contains` and :meth:`absorb` (of this codistribution or
        of a copy with the same basis) without testing the same covectors twice.
        """
        cands, finite = self._scaled(np.asarray(covectors))
        rho, dirs = self._distances(cands) if len(cands) else (np.zeros((0, len(finite))), cands)
        return Tested(cands, finite, rho, dirs)

    def test_units(self, count: int, only=None) -> "Tested":
        """:meth:`test` of the unit covectors ``e_1..e_count`` (same arithmetic, cheaper);
        ``only``: the indices (0-based, below ``count``) of the ones to test, in that order.

        With ``B (S, r, n)`` the kept orthonormal rows, the residuals of every ``e_j`` at
        once are the columns of ``R1 = I - B^T B`` and, where a column is shorter than
        :data:`_REPROJECT_BELOW` at some sample, ``R2 = R1 - B^T (B R1)``. A unit covector is
        never taken for a round-off zero row: its norm is exact.
        """
        S, n = len(self.valid), self.n
        at = np.arange(count) if only is None else np.asarray(only, dtype=np.intp)
        B = np.ascontiguousarray(self.kept_basis())  # (S, r, n)
        Bt = np.swapaxes(B, 1, 2)
        res = np.moveaxis(np.eye(n)[:, at] - Bt @ B[:, :, at], 2, 0)  # (len(at), S, n)
        rho = np.linalg.norm(res, axis=-1)
        # the second projection only where the first left less than 0.7 of the unit norm
        # at some sample ("twice is enough", Kahan-Parlett): elsewhere it changes the
        # residual by round-off, and skipping it spares two of the three products
        near = np.flatnonzero((rho < _REPROJECT_BELOW).any(axis=1))
        if len(near):
            r1 = np.ascontiguousarray(np.moveaxis(res[near], 0, 2))  # (S, n, len(near))
            res[near] = np.moveaxis(r1 - Bt @ (B @ r1), 2, 0)
            rho[near] = np.linalg.norm(res[near], axis=-1)
        dirs = res / np.where(rho > 0, rho, 1.0)[..., None]
        cands = np.zeros((len(at), S, n))
        cands[np.arange(len(at)), :, at] = np.broadcast_to(self.col_scale, (n,))[at, None]
        return Tested(cands, np.ones(S, dtype=bool), rho, dirs)

    def absorb(self, nodes, grads, tested: "Tested | None" = None, confirm_empty: bool = False,
               expect_rise: bool = False):
        """Keep the candidates that raise the generic rank, in order.

        Args:
            nodes: c candidate Nodes.
            grads: their gradients at the samples, ``(S, c, n)`` (unused when ``tested``).
            tested: :meth:`test` of the same ``(c, S, n)`` covectors against this span.
            expect_rise: every candidate is expected to raise the rank (the kept generators
                re-decided on more samples): a vote that it does not is settled again.
            confirm_empty: when no candidate is kept, settle every rejection exactly where
                the graph is rational (:meth:`_confirm_empty`).

        Returns:
            The list of kept nodes.
        """
        if not nodes:
            return []
        if tested is None:
            cands, finite = self._scaled(np.moveaxis(np.asarray(grads), 1, 0))
        else:
            cands, finite = tested.cands, tested.finite
        self.valid &= finite
        if not self.valid.any():
            raise FloatingPointError("every sample is NaN/inf")
        added = []
        if self.rank >= self.n:
            return added
        if tested is not None:
            rho, dirs = tested.rho, tested.dirs
        elif self.rank == 0:  # an empty span (a final span re-decided): distance 1 or 0
            norms = np.linalg.norm(cands, axis=-1)
            rho = (norms > 0).astype(np.float64)
            dirs = cands / np.where(norms > 0, norms, 1.0)[..., None]
        else:
            rho, dirs = self._distances(cands)
        first = [self._decide(r, nd, self.valid, expect_rise) for r, nd in zip(rho, nodes)]
        rising = [i for i, d in enumerate(first) if d.rank > self.rank]
        self.rejections.extend(d for d in first if d.rank <= self.rank)
        self._reserve(min(self.n, self.rank + len(rising)))
        # residuals of the rising candidates against the current span; each kept direction
        # is projected out of the later ones (twice), so no candidate is re-tested in full
        res = rho[rising, :, None] * dirs[rising]
        # many rising candidates (the final span re-decided on all samples): their
        # sequential Gram-Schmidt is one batched QR per sample (LAPACK), valid as long as
        # every candidate rises; the first that does not ends it (the loop goes on)
        qr = sequential_qr(res) if len(rising) >= QR_FROM else None
        for j, i in enumerate(rising):
            if self.rank >= self.n:
                break
            if j == 0:  # tested against the current span already
                d, r_i, dir_i = first[i], rho[i], dirs[i]
            elif qr is not None and j < qr[0].shape[0]:
                r_i, dir_i = np.abs(qr[1][:, j]), qr[0][j] * np.sign(qr[1][:, j])[:, None]
                d = self._decide(r_i, nodes[i], self.valid, expect_rise)
            else:
                r_i = np.linalg.norm(res[j], axis=-1)
                dir_i = res[j] / np.where(r_i > 0, r_i, 1.0)[:, None]
                d = self._decide(r_i, nodes[i], self.valid, expect_rise)
            if d.rank > self.rank:
                self._keep(nodes[i], cands[i], r_i, dir_i, d)
                added.append(nodes[i])
                if qr is None:
                    new = self.basis[self.rank - 1]  # (S, n), zero where not independent
                    for _ in range(2):
                        coef = np.einsum("csn,sn->cs", res[j + 1:], new)
                        res[j + 1:] -= coef[..., None] * new
            else:
                self.rejections.append(d)
                if qr is not None:  # the QR took this one in: the rest against the span
                    qr = None
                    rest = [rising[t] for t in range(j + 1, len(rising))]
                    if rest:
                        r_rest, d_rest = residuals(self.basis[: self.rank], self.ref, cands[rest])
                        res[j + 1:] = r_rest[..., None] * d_rest
        if confirm_empty and not added and grads is not None:
            return self._confirm_empty(nodes, grads, first, cands, rho, dirs)
        return added

    def _confirm_empty(self, nodes, grads, first, cands, rho, dirs):
        """No candidate was kept: each float64 rejection not settled yet is settled again
        (:meth:`~uio_jax._analysis.decisions.policy.DecisionPolicy.settle_stop`): a genuine
        direction of a deep derivative can sit under float64's round-off. The first candidate
        found independent is kept and the others are absorbed against the grown span.
        Returns the kept nodes."""
        if self.policy is None or self.rank >= self.n:
            return []
        for i, (node, d) in enumerate(zip(nodes, first)):
            if node is None or d.settled:  # settled beyond float64 already
                continue
            text = evidence(d, rho[i], self.valid, self.rtol, self.rank)
            esc = self.policy.settle_stop(self.nodes, node, text, self.record)
            if esc is None:
                continue
            how = esc.how
            if esc.result == "dependent":
                self.rejections = [replace(r, settled=how) if r is d else r for r in self.rejections]
                continue
            if esc.result == "independent":
                self.rejections = [r for r in self.rejections if r is not d]
                self._keep(node, cands[i], rho[i], dirs[i], replace(d, rank=self.rank + 1, settled=how))
                rest = list(range(i + 1, len(nodes)))
                more = self.absorb([nodes[j] for j in rest], np.asarray(grads)[:, rest]) if rest else []
                return [node, *more]
        return []

    def _decide(self, rho, node, valid, expect_rise=False) -> RankDecision:
        """The decision on one candidate: a span of every direction contains every covector
        (``settled="implied"``); otherwise the float64 vote (:func:`decide_increase`),
        settled again by :attr:`policy` (:meth:`~uio_jax._analysis.decisions.policy.DecisionPolicy.decide`)
        where there is one and the candidate has an expression."""
        if self.rank >= self.n:
            return replace(decide_increase(rho, valid, self.rtol, self.rank), rank=self.rank, settled="implied")
        if self.policy is None or node is None:
            return decide_increase(rho, valid, self.rtol, self.rank)
        return self.policy.decide(rho, valid, self.rtol, self.nodes, node, self.record, expect_rise=expect_rise)

    def contains(self, covectors, tested: "Tested | None" = None, nodes=None):
        """Membership of covector families in the span.

        Args:
            covectors: ``(C, S, n)`` unscaled covectors (e.g. gradients, or unit vectors);
                unused when ``tested`` is given.
            tested: :meth:`test` of the same covectors against this span.
            nodes: the covectors' Nodes (their expressions settle weak votes); None: weak
                votes are not settled again.

        Returns:
            list of ``(bool, RankDecision)``: member iff the generic rank does not grow.
        """
        if tested is None:
            tested = self.test(covectors)
        valid = self.valid & tested.finite
        if not valid.any():
            raise FloatingPointError("the covector is NaN/inf at every valid sample")
        out = []
        nodes = [None] * len(tested.rho) if nodes is None else list(nodes)
        for r, nd in zip(tested.rho, nodes):
            d = self._decide(r, nd, valid)
            out.append((d.rank <= self.rank, d))
        return out

    def sample_ratios(self) -> np.ndarray:
        """``(S_used, r)`` ratios ``s_i / s_1`` of the kept set at the valid samples."""
        if self.rank == 0:
            return np.zeros((int(self.valid.sum()), 0))
        return ratios(self.grads)[self.valid]

    def decision(self) -> RankDecision:
        """SVD rank decision of the kept set alone: its fraction and smallest ``s_r/s_1``."""
        if self.rank == 0:
            return RankDecision(0, 1.0, 1.0, 0.0, int(self.valid.sum()))
        key = (self.rank, int(self.valid.sum()))  # rows only grow, valid samples only shrink
        if self._decided[0] != key:
            self._decided = (key, decide_rank(ratios(self.grads), self.valid, self.rtol))
        return self._decided[1]


#: The kernels' public names are re-exported: the analyses import them from here.
__all__ = ["Codistribution", "Tested", "SETTLED_FLOOR", "default_rtol", "ZERO_ROW_RTOL", "RankDecision",
           "decide_rank", "decide_increase"]
