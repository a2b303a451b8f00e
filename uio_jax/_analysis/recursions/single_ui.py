"""Single unknown input, no drift: Martinelli's analytic observable codistribution.

System ``xdot = sum_i f_i(x) u_i + g(x) w``, outputs ``h``. With ``L_g^1 = L_g h != 0``
(Definition 5 of 004; Algorithms 2-3 of 002)::

    phi^i_0 = f_i,        phi^i_m = [phi^i_{m-1}, g] / L_g^1
    Omega_0 = span{dh (all outputs)}
    Omega_m = Omega_{m-1} + sum_i L_{f_i} Omega_{m-1} + L_{g/L_g^1} Omega_{m-1}
              + sum_i span{d L_{phi^i_{m-1}} h}

Convergence (Lemma 1 of 002; Theorem 2 of 004):

* if every ``phi^i_1`` vanishes, or ``L_{phi^i_j} L_g^1 = 0`` for every j up to where the
  distribution of the ``phi^i_j`` stops growing (Lemma 1), then ``m' = 0``;
* otherwise ``tau = L_g^2 h / (L_g^1)^2`` and ``m'`` = first m with ``d tau in Omega_m``;
* ``m*`` = first ``m >= m'`` with ``Omega_{m+1} = Omega_m``; ``Omega* = Omega_{m*}``.

The rule, with the correction below, is :func:`stopping_rule`; the recursion is
:class:`SingleUi`, run by the shared driver.

**Correction to the papers' stopping rule** (implemented, reported as ``m_star`` next to
the literal ``m_star_paper``): the induction in the proof of Theorem 2 of 004 uses eq. 25,
valid for ``j >= 2``, so a stop at ``m* = 0`` is not justified; we require ``m* >= 1``
unless every ``phi^i_1`` vanishes identically. Counterexample to the literal rule:
``x0' = u + x1 w, x1' = x0 x2 u, x2' = 0, y = x0`` gives ``tau = 0``, ``m' = 0`` and
``Omega_1 = Omega_0 = span{dx0}``, but ``L_{phi_1} h = x0 x2 / x1`` is observable and
``dim Omega_2 = 2``.

**L_g h = 0 for every output** (section 7 of 004, step 1 of 003): the outputs and their
Lie derivatives along the known fields are observable while their ``L_g`` vanishes; we
build them level by level (an ORC along the known fields, pruned) until a kept function
``h~`` has ``L_g h~ != 0``, keep every differential found so far in Omega and run the
recursion with ``h~`` in place of h. Steps are numbered as in the paper (11.1.2: Omega_1 =
span{dr, dh~}). If no such function exists, the unknown input does not affect the outputs
and the result is the ORC of the known fields.

Functions that "vanish identically" are decided at the sampled states with the relative
threshold ``ZERO_ROW_RTOL`` against the natural scale of the product (e.g. ``|dh||g|``
for ``L_g h``), by majority, and the fraction is reported.
"""

import dataclasses

import numpy as np

from ..._errors import OptionError
from ..._progress import announce_step
from ..decisions.context import Context
from ..decisions.rank import ZERO_ROW_RTOL, decide_rank
from ..decisions.sampled_rank import ratios
from .driver import Cap, Recursion, Stop, StopReason, iterate


def check_applicable(system):
    """Raise OptionError when ``method='single_ui'`` does not apply to ``system``."""
    if len(system.unknown) != 1:
        raise OptionError(
            f"method 'single_ui' needs exactly one unknown input, got {len(system.unknown)}; "
            "use method='eorc' (or 'auto')"
        )
    if system.drift is not None:
        raise OptionError(
            "method 'single_ui' is stated by the papers for systems without drift; treating "
            "the drift as a known field with input 1 gives wrong answers. Use method='eorc' "
            "(or 'auto')"
        )


# --------------------------------------------------------------- the stopping rule
@dataclasses.dataclass(frozen=True)
class Verdict:
    """The stopping rule's verdict on the steps ``0..M`` (see :func:`stopping_rule`).

    Attributes:
        stop: the :class:`~uio_jax._analysis.recursions.driver.Stop` (None: take another step).
        m_star: the corrected ``m*`` (None unless the recursion converged).
        m_star_paper: the papers' literal ``m*`` (the first ``m >= m'`` with
            ``Omega_{m+1} = Omega_m``, or the full-rank step), None if not reached yet.
    """

    stop: Stop | None = None
    m_star: int | None = None
    m_star_paper: int | None = None


def step_cap(n: int, max_order=None, offset: int = 0, cap=None) -> Cap:
    """The driver's :class:`~uio_jax._analysis.recursions.driver.Cap` of the recursion: the
    user's ``max_order`` on ``m + offset`` (``MAX_ORDER``), else the step bound ``cap``
    (default ``2n + 3``, Lemma 8 of 004; ``STEP_CAP``), whichever comes first (the user's
    at a tie)."""
    cap = 2 * n + 3 if cap is None else cap  # Lemma 8 of 004: m' <= 2n + 2
    user = None if max_order is None else Cap(max_order - offset, StopReason.MAX_ORDER.stop(max_order=max_order))
    return Cap.tightest(user, Cap(cap, StopReason.STEP_CAP.stop(cap=cap)))


def converged(dims, m_prime, *, n, phi1_vanish, offset=0) -> Verdict:
    """The convergence part of :func:`stopping_rule` on ``dims`` (no cap): a :class:`Verdict`
    whose ``stop`` is None while the recursion goes on."""
    return stopping_rule(dims, m_prime, n=n, phi1_vanish=phi1_vanish, cap=None, offset=offset, capped=False)


def stopping_rule(dims, m_prime, *, n, phi1_vanish, cap, max_order=None, offset=0, capped=True) -> Verdict:
    """The single-unknown-input stopping rule (Theorem 2 of 004, with ``m* >= 1``), as a
    function of integers.

    With ``d_m = dim Omega_m`` (``dims``, m = 0..M) and ``m'`` (``m_prime``: the first m
    with ``d tau in Omega_m``, 0 by Lemma 1, None while not known), the rule replays
    ``m = 0..M`` and stops at the first of, in this order at each m:

    * ``d_m = d_{m-1}`` with ``m - 1 >= m'``: the papers' ``m* = m - 1``; the corrected
      rule accepts it only if ``m - 1 >= 1`` or every ``phi^i_1`` vanishes
      (``CONVERGED_AFTER_M_PRIME``, ``Omega_m = Omega_{m-1}``);
    * ``d_m >= n`` with ``m' <= m``: ``m* = m`` (``FULL_RANK``);
    * ``m + offset >= max_order`` (``MAX_ORDER``), ``m >= cap`` (``STEP_CAP``): the
      :func:`step_cap` that the driver applies to the recursion (``capped=False``: the
      convergence part alone, :func:`converged`).

    Args:
        dims, m_prime: as above.
        n: dimension of the state.
        phi1_vanish: whether every ``phi^i_1`` vanishes identically.
        cap: the step bound (default ``2n + 3``).
        max_order: the user's cap on ``m + offset`` (None: none).
        offset: the paper's index offset (level of the chosen output ``h~``); the stop
            messages number the steps ``m + offset``.

    Returns:
        :class:`Verdict`.
    """
    known = m_prime is not None
    paper = None
    limit = step_cap(n, max_order, offset, cap) if capped else None
    for m, dim in enumerate(dims):
        if m >= 1 and known and dim == dims[m - 1] and m - 1 >= m_prime:
            paper = m - 1 if paper is None else paper
            if m - 1 >= 1 or phi1_vanish:
                stop = StopReason.CONVERGED_AFTER_M_PRIME.stop(m=m + offset, prev=m - 1 + offset)
                return Verdict(stop, m - 1, paper)
        if dim >= n and known and m_prime <= m:
            return Verdict(StopReason.FULL_RANK.stop(n=n, m=m + offset), m,
                           m if paper is None else paper)
        if limit is not None and m >= limit.steps:
            return Verdict(limit.stop, None, paper)
    return Verdict(None, None, paper)


# --------------------------------------------------------------- the recursion
class SingleUi(Recursion):
    """Steps ``m >= 1`` of the single-unknown-input recursion (the module docstring's
    ``Omega_m``, numbered ``m + offset``), after the chosen output: Omega_0 is the span built
    by :func:`_choose_output`, its last Step passed to ``iterate`` as history.

    Args:
        ctx: the analysis context.
        fs: Nodes of the known fields ``f_i``.
        g: Node of the unknown-input field.
        h_tilde: Node of the chosen function (``L_g h~ != 0``).
        offset: its level (the paper's index offset).
    """

    def __init__(self, ctx: Context, fs, g, h_tilde, offset):
        b = ctx.builder
        self.ctx, self.fs, self.g, self.h_tilde, self.offset = ctx, fs, g, h_tilde, offset
        self.Lg1 = b.lie(g, h_tilde)
        self.g_scaled = b.scaled(g, self.Lg1, label=f"{g.label}/L_g^1")
        self.tau = b.ratio(b.lie(g, self.Lg1), self.Lg1, 2, label="tau")
        self.phis = list(fs)  # phi^i_0 = f_i
        phi_next = [b.scaled(b.bracket(p, g), self.Lg1, label=f"phi^{p.label}_1") for p in fs]
        self.phi1_vanish = _fields_vanish(ctx, phi_next, fs, g, self.Lg1)
        self.rule = "tau"
        if self.phi1_vanish:
            self.rule = "all phi^i_1 vanish (Lemma 1)"
        elif _lemma1_holds(ctx, fs, g, self.Lg1):
            self.rule = "Lemma 1"
        self.m_prime = 0 if self.rule != "tau" else None
        self.verdict = Verdict()
        self.frontier, self.dims = [], []

    def tau_in(self, m):
        """Test ``d tau in Omega_m`` until it holds (``m'`` = the first such m)."""
        if self.m_prime is None and self.ctx.contains_nodes([self.tau])[0]:
            self.m_prime = m
        return self.m_prime is not None

    def extra(self, m):
        """The Step's ``extra`` at step m: ``tau_in_omega`` when ``m'`` is the tau rule's."""
        return {} if self.rule != "tau" else {"tau_in_omega": self.tau_in(m)}

    def init(self):
        """Omega_0 is already built: L_{g/L} of every generator so far is new."""
        self.frontier = list(self.ctx.codist.nodes)
        self.dims = [self.ctx.dim]
        return None

    def step(self, m):
        """Omega_m from Omega_{m-1} (see the class), then ``phi^i_m`` for the next step."""
        ctx, b = self.ctx, self.ctx.builder
        blocks = [(self.frontier, self.fs + [self.g_scaled])]
        # phi-terms: phi^i_0 = f_i repeats L_{f_i} h~ (h~ is in Omega_0), and when every
        # phi^i_1 vanishes so do all later phi^i_m: only m >= 2 with live phis adds terms
        if m >= 2 and not self.phi1_vanish:
            blocks.append(([self.h_tilde], self.phis))
        cand_nodes, cand_grads = [], []
        for phis_block, fields in blocks:
            nodes, grads = ctx.lie_block(phis_block, fields)
            cand_nodes += nodes
            cand_grads.append(grads)
        self.frontier = ctx.absorb(cand_nodes, np.concatenate(cand_grads, axis=1))
        self.dims.append(ctx.dim)
        step = ctx.step(m + self.offset, self.frontier, **self.extra(m))
        self.phis = [b.scaled(b.bracket(p, self.g), self.Lg1, label=f"phi^{f.label}_{m}")
                     for p, f in zip(self.phis, self.fs)]
        return step

    def terminate(self, m, history):
        """:func:`converged` on the dims so far (the driver applies :func:`step_cap`)."""
        self.verdict = converged(self.dims, self.m_prime, n=self.ctx.system.n, phi1_vanish=self.phi1_vanish,
                                 offset=self.offset)
        return self.verdict.stop

    def postprocess(self, history, stop):
        """A stop of the driver's cap: the verdict keeps the papers' ``m*`` found so far."""
        if self.verdict.stop is None:
            self.verdict = Verdict(stop, None, self.verdict.m_star_paper)
        return self.verdict


def single_ui_report(ctx: Context, *, notes=(), max_order=None):
    """Run the single-unknown-input analysis on ``ctx`` and build the Report: the chosen
    output's levels (:func:`_choose_output`), then :class:`SingleUi` until
    :func:`stopping_rule` stops it. Steps ``m`` of the history are the paper's
    (``Step.dim = dim Omega_m``, ``extra["tau_in_omega"]``).
    """
    system = ctx.system
    check_applicable(system)
    (g_label,) = tuple(system.unknown)
    g = ctx.field_node(g_label)
    fs = [ctx.field_node(lbl) for lbl in system.known]
    notes = list(notes)
    history, h_tilde, offset, fraction = _choose_output(ctx, fs, g)
    if h_tilde is None:
        notes.append(
            f"the unknown input {g_label!r} does not affect the outputs (L_g vanishes on the "
            "outputs and on all their Lie derivatives along the known fields): the result is "
            "the ORC of the known fields"
        )
        details = {"unknown_input_affects_outputs": False}
        return ctx.report("single_ui", history, StopReason.KNOWN_FIELDS_ORC.stop(),
                          notes=notes, details=details)
    rec = SingleUi(ctx, fs, g, h_tilde, offset)
    if rec.rule == "tau":  # Omega_0 is the last history entry (the chosen output's level)
        history[-1] = dataclasses.replace(history[-1], extra={"tau_in_omega": rec.tau_in(0)})
    out = iterate(rec, history, cap=step_cap(system.n, max_order, offset))
    details = {
        "unknown_input_affects_outputs": True,
        "output": h_tilde.label,
        "L_g^1": rec.Lg1.label,
        "relative_degree": offset + 1,
        "lg1_nonzero_fraction": fraction,
        "phi1_vanish": rec.phi1_vanish,
        "convergence_rule": rec.rule,
    }
    if out.stop.reason is StopReason.STEP_CAP:
        notes.append("d tau never entered Omega within the step bound (Lemma 8 of 004); "
                     "the codistribution may be incomplete")
    _m_star_details(rec.verdict, rec.m_prime, offset, details, notes)
    return ctx.report("single_ui", out.history, out.stop, notes=notes, details=details)


def _m_star_details(verdict, m_prime, offset, details, notes):
    """Add ``m_prime``, ``m_star`` (and ``m_star_paper``) to ``details``, numbered with the
    paper's offset, and a note where the corrected rule went past the papers' ``m*``."""
    shift = lambda m: None if m is None else m + offset  # noqa: E731
    details["m_prime"] = shift(m_prime)
    details["m_star"] = shift(verdict.m_star)
    if verdict.m_star is None:
        return
    details["m_star_paper"] = shift(verdict.m_star_paper)
    if verdict.m_star_paper is not None and verdict.m_star_paper != verdict.m_star:
        notes.append(
            f"the papers' stopping rule would stop at m*={verdict.m_star_paper + offset}; the "
            f"corrected rule (m* >= 1 unless every phi^i_1 vanishes) continued to "
            f"m*={verdict.m_star + offset}"
        )


def _choose_output(ctx, fs, g):
    """Pick the function ``h~`` with ``L_g h~ != 0`` (an output, else a Lie derivative).

    Returns:
        ``(history, h_tilde or None, level, fraction)``: the history of the levels built
        (Omega_0 .. Omega_level), the chosen function, its level (the paper's index offset)
        and the fraction of samples where ``L_g h~`` is non-zero.
    """
    outs = ctx.output_nodes()
    frontier = ctx.absorb(outs)
    history = [announce_step(ctx.step(0, frontier))]  # before the driver runs: announced here
    candidates = outs  # every output may be chosen (first in order wins)
    level = 0
    while True:
        for node in candidates:
            nonzero, fraction = _lie_nonzero(ctx, node, g)
            if nonzero:
                return history, node, level, fraction
        if not frontier or ctx.dim >= ctx.system.n and level > 0 and not fs:
            return history, None, level, 0.0
        level += 1
        frontier = ctx.absorb_lie(frontier, fs)
        history.append(announce_step(ctx.step(level, frontier)))
        if not frontier:
            return history, None, level, 0.0
        candidates = frontier


def _lie_nonzero(ctx, node, g):
    """Is ``L_g node`` not identically zero? (majority of samples, relative threshold)."""
    lg = ctx.builder.lie(g, node)
    val, gval = ctx.builder.values([lg, g], ctx.xs)
    grad = ctx.gradients([node])[:, 0]
    scale = np.linalg.norm(grad, axis=-1) * np.linalg.norm(gval, axis=-1)
    ok = ctx.codist.valid & np.isfinite(val) & np.isfinite(scale)
    nonzero = np.abs(val) > ZERO_ROW_RTOL * scale
    frac = float(nonzero[ok].mean()) if ok.any() else 0.0
    zero, _ = ctx.decide_zero([lg.expr], not frac > 0.5)
    return not zero, frac


def _fields_vanish(ctx, phis, fs, g, Lg1):
    """Do all fields ``phi^i_1 = [f_i, g] / L_g^1`` vanish identically?

    Compared with their natural scale ``(|f_i| + |g|) / |L_g^1|``, by majority of samples.
    """
    vals = ctx.builder.values(list(phis) + list(fs) + [g, Lg1], ctx.xs)
    k = len(phis)
    gnorm = np.linalg.norm(vals[2 * k], axis=-1)
    lg = np.abs(vals[2 * k + 1])
    for phi, v, f in zip(phis, vals[:k], vals[k : 2 * k]):
        ref = (np.linalg.norm(f, axis=-1) + gnorm) / lg
        ok = ctx.codist.valid & np.isfinite(v).all(axis=-1) & np.isfinite(ref)
        zero = np.linalg.norm(v, axis=-1) <= ZERO_ROW_RTOL * ref
        if not ctx.decide_zero(list(phi.expr), bool(ok.any() and zero[ok].mean() > 0.5))[0]:
            return False
    return True


def _lemma1_holds(ctx, fs, g, Lg1):
    """Lemma 1 of 002: ``L_{phi^i_j} L_g^1 = 0`` for j = 0..m_i (Lambda^i converged at m_i)."""
    b = ctx.builder
    n = ctx.system.n
    dlg = ctx.gradients([Lg1])[:, 0]
    dlg_norm = np.linalg.norm(dlg, axis=-1)
    for f in fs:
        phi = f
        basis_rank = 0
        vectors, fields = [], []
        for j in range(n):
            v = b.values([phi], ctx.xs)[0]
            lie = np.einsum("si,si->s", dlg, v)
            ok = ctx.codist.valid & np.isfinite(lie)
            scale = dlg_norm * np.linalg.norm(v, axis=-1)
            float64_zero = bool((np.abs(lie[ok]) <= ZERO_ROW_RTOL * scale[ok]).mean() > 0.5)
            if not ctx.decide_zero([b.lie(phi, Lg1).expr], float64_zero)[0]:
                return False
            vectors.append(v)
            fields.append(phi)
            rank = ctx.decide_vector_rank(fields, _vector_rank(np.stack(vectors, axis=1), ctx.codist.valid,
                                                               ctx.codist.rtol))
            if rank == basis_rank:  # Lambda_j = Lambda_{j-1}: converged
                break
            basis_rank = rank
            phi = b.scaled(b.bracket(phi, g), Lg1, label=f"phi^{f.label}_{j + 1}")
    return True


def _vector_rank(vectors, valid, rtol):
    """Generic rank of sampled vector fields ``(S, k, n)``: rows scaled to unit norm (a row
    below ``ZERO_ROW_RTOL`` of the sample's largest is zero), per-sample SVD, and the rank
    rule of the codistributions (:func:`~uio_jax._analysis.decisions.rank.decide_rank` with ``rtol``)."""
    s_ratios = ratios(np.where(np.isfinite(vectors), vectors, 0.0)[valid])
    return decide_rank(s_ratios, np.ones(len(s_ratios), bool), rtol).rank
