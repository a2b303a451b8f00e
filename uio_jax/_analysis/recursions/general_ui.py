"""Martinelli's general analytic solution of unknown-input observability (several UIs, drift).

System ``x' = g0(x, t) + sum_j w_j g_j(x)``, outputs ``h(x)`` (no feedthrough), where
``g0 = f0 + sum_i u_i f_i`` holds the known inputs as generic smooth functions of time (their
jets are known coordinates, :mod:`uio_jax._model.smooth_inputs`) and an explicit time
dependence (the time coordinate, ``t' = 1``). ``D`` below is the Lie derivative along this
augmented drift: the total time derivative. Every rank, zero test and membership is decided
at the sampled states, the jets and the time being known coordinates whose differentials are
in every span. Sources: arXiv 2201.07610 (Algorithm 5.1/6.1) and Martinelli's TUIO6; the
algorithm as implemented is stated in ``docs/general_ui.md``.

**Close(Theta_0, [F_0, F_1..F_q]; guard, filter)**: insert Theta_0 (independent members, each
its own *root*); pass r processes the generators added in pass r - 1 (pass 0: Theta_0): if
``guard(theta)`` holds, abort with (root of theta, ``ord = r``); if ``filter(theta)`` fails,
skip it; else absorb ``L_{F_a} theta`` for every field (children inherit the root). Stop when a
pass adds nothing; without a guard also at full rank (with a guard, full rank is no
certificate: every remaining generator must still pass the guard).

**Reconstructability**: ``R_ij = L_{g_j} theta_i`` over the current Theta; ``m`` = its generic
rank (degree of reconstructability); the first independent rows are the UI identifiers
``h~``, the first independent columns among them the reconstructable UIs (moved first).
Canonic: ``m = mw``. Rescaled fields ``g^0, g^_k, G~_k``: :mod:`uio_jax._calculus.rescaled`.

**Main loop** (at most :data:`ITERATION_CAP` iterations)::

    Theta <- Close(h, [])
    loop:  m, identifiers;  Theta <- Close(Theta, [])
      m = mw:               Omega = Close(Theta, [g^0, g^_1..g^_mw])            finish
      every G~_k = 0:       Omega = Close(Theta, [g^0, g^_1..g^_m])             finish
      guarded Close(Theta, [g^0, g^_1..g^_m]; guard: some L_{G~_k} theta != 0):
          no abort:         Omega = its result                                   finish
          abort (theta*, ord): its result is discarded;
            m = 0:  Theta <- Close(Theta, [g0]; filter: every L_{g_j} theta = 0)
            m >= 1: UI extension: states v_j^(0..ord) with x' = g^0 + sum_j v_j^(0) g^_j and
                    v_j^(i)' = v_j^(i+1), theta_v = D^ord theta*; keep v_j^(0..i_j) (i_j: the
                    highest one theta_v depends on; none: v_j is the new UI along (g^_j, 0));
                    the new UIs are d v_j^(i_j)/dt (unit fields) and G~_k;
                    Theta <- Theta + {kept v} + {theta_v}

**Outputs**: ``dim = rank(Omega) + n - rank([Omega; e_1..e_n])`` on the original state (every
extension state and known coordinate is observable), exact for known inputs that are generic
smooth functions of time (``known_inputs="smooth"``).
"""

import dataclasses

import numpy as np

from ..._calculus.rescaled import rescaled_fields
from ..._errors import OptionError
from ..._model.smooth_inputs import jet_names, known_coordinates
from ..._model.system import System
from ..decisions.context import Context
from ..decisions.settle import DEFAULT_PROB_THRESHOLD
from ..decisions.space import Projection, SampledSpace, report_view
from ..results.evidence import Step
from ..results.report import Report
from .driver import Cap, Recursion, StopReason, iterate
from .eorc import extended_system
from .general_ui_steps import (
    Working,
    close,
    decide_zero,
    extend,
    lift,
    nonzero_votes,
    partial_derivative,
    reconstructability,
    start_working,
)

#: At most this many iterations of the main loop (TUIO6's bound).
ITERATION_CAP = 30

#: Jets of the smooth known inputs are kept to order ``n + JET_MARGIN`` at first; when a
#: generator that was differentiated depends on the highest jet, the analysis is run again
#: with twice the order (the truncation ``u^(R+1) = 0`` could have mattered).
JET_MARGIN = 3

#: How many times the jet order is doubled before the report says it may be truncated.
JET_RETRIES = 2

def check_applicable(system: System, known_inputs: str):
    """Raise OptionError when ``method='general_ui'`` does not answer the question asked.

    The general solution is established for known inputs that are generic smooth functions
    of time; for switchable known inputs (the default) no statement is known when there is
    a drift or more than one unknown input, and with one unknown input and no drift the
    switchable answer is ``single_ui``'s.
    """
    if system.known and known_inputs != "smooth":
        raise OptionError(
            "method 'general_ui' answers for known inputs that are generic smooth functions of "
            "time: pass known_inputs='smooth'; for switchable known inputs (the default) use "
            "method='single_ui' (one unknown input, no drift) or 'eorc' (sufficient only)")


# ------------------------------------------------------------------ the main loop
@dataclasses.dataclass
class GeneralRun:
    """The finished general solution: the final working system and span, and the trace."""

    w: Working
    omega: Context
    trace: list
    history: list
    stop: object
    initially_canonic: bool
    canonic: bool
    extended: bool
    degree: int
    spent: list  # Contexts whose decisions count for the certificate


class GeneralSolution(Recursion):
    """The main loop of the module docstring as a driver Recursion: step ``it`` is iteration
    ``it`` (``init`` is iteration 0) and records one Step; an iteration that finishes sets the
    Stop that :meth:`terminate` returns. The driver's cap: :data:`ITERATION_CAP` iterations.

    Args:
        w: the working system (:func:`~.general_ui_steps.start_working`).
        samples, seed, rtol: the options of the extensions' contexts.
    """

    def __init__(self, w: Working, samples, seed, rtol):
        self.w, self.samples, self.seed, self.rtol = w, samples, seed, rtol
        self.trace, self.spent = [], []
        self.c = close(w, w.theta, [])
        w.theta = list(self.c.ctx.codist.nodes)
        self.initially, self.extended = None, False
        self.stop, self.omega, self.canonic, self.degree = None, None, False, 0

    def _finish(self, omega, it, added, extra, reason, canonic, degree):
        """Iteration ``it`` finished the analysis: Omega and its Step."""
        self.omega, self.canonic, self.degree = omega, canonic, degree
        self.stop = reason.stop(m=it)
        return _dim_step(self.w, omega, it, added, extra)

    def init(self) -> Step:
        if not self.w.uis:  # no unknown input: the closure along the drift
            w = self.w
            omega = close(w, w.theta, [w.drift]).ctx
            self.initially = True
            return self._finish(omega, 0, omega.codist.nodes, {"action": "closure along g0"},
                                StopReason.CLOSURE_CONVERGED, True, 0)
        return self.step(0)

    def step(self, it) -> Step:
        """Iteration ``it``: the degree of reconstructability, then finish or extend."""
        w = self.w
        mw = len(w.uis)
        self.spent.append(self.c.ctx)
        rec = reconstructability(w, w.theta)
        w.rank_tests.append(rec.settled)
        m = rec.m
        if self.initially is None:
            self.initially = m == mw
        order_idx = list(rec.cols) + [i for i in range(mw) if i not in rec.cols]
        ui_names = list(w.system.unknown)
        entry = {"iteration": it, "m": m, "identifiers": [w.theta[i].label for i in rec.rows],
                 "reconstructable": [ui_names[i] for i in rec.cols],
                 "canonic": m == mw, "fraction": rec.fraction}
        self.trace.append(entry)
        self.degree = m
        fields_ordered = [w.uis[i] for i in order_idx]
        if m >= 1:
            hat0, hats, tildes = rescaled_fields(
                w.ctx.builder, w.drift, fields_ordered, [w.theta[i] for i in rec.rows],
                [ui_names[i] for i in order_idx])
        else:
            hat0, hats, tildes = w.drift, [], fields_ordered
        if m == mw:
            entry["action"] = "canonic: closure under the rescaled fields"
            omega = close(w, w.theta, [hat0] + hats).ctx
            return self._finish(omega, it, omega.codist.nodes, {"m": m, "canonic": True},
                                StopReason.CANONIC_CLOSURE, True, m)
        tilde_vals = w.field_values(tildes)
        raw_norms = [np.linalg.norm(v, axis=-1) for v in w.field_values(fields_ordered[m:])]
        if all(_field_zero(w, t, v, ref) for t, v, ref in zip(tildes, tilde_vals, raw_norms)):
            entry["action"] = "every unreconstructed field vanishes: closure"
            omega = close(w, w.theta, [hat0] + hats).ctx
            return self._finish(omega, it, omega.codist.nodes, {"m": m, "canonic": False},
                                StopReason.REMAINING_UIS_VANISH, False, m)
        guarded = close(w, w.theta, [hat0] + hats, guard=tildes, guard_scale=raw_norms)
        self.spent.append(guarded.ctx)
        if not guarded.aborted:
            entry["action"] = "guarded closure converged"
            return self._finish(guarded.ctx, it, guarded.ctx.codist.nodes, {"m": m, "canonic": False},
                                StopReason.GUARD_PASSED, False, m)
        entry.update({"aborted_at_order": guarded.order, "root": guarded.root.label})
        if m == 0:
            return self._closure_of_free_generators(it, entry)
        return self._extension(it, entry, guarded, hat0, hats, tildes, rec)

    def _closure_of_free_generators(self, it, entry) -> Step:
        """m = 0: Theta <- Close(Theta, [g0]; filter: every L_{g_j} theta = 0)."""
        w = self.w
        entry["action"] = "m = 0: closure of the UI-free generators along g0"
        before = len(w.theta)
        self.c = close(w, w.theta, [w.drift], filter_fields=w.uis)
        w.theta = list(self.c.ctx.codist.nodes)
        if len(w.theta) == before:  # no progress: cannot happen for a generic system
            entry["action"] += " (added nothing)"
            return self._finish(self.c.ctx, it, w.theta[before:], {"m": 0, "canonic": False},
                                StopReason.GENERAL_STALLED, False, 0)
        return _dim_step(w, self.c.ctx, it, w.theta[before:], {"m": 0, "canonic": False})

    def _extension(self, it, entry, guarded, hat0, hats, tildes, rec) -> Step:
        """m >= 1: the UI extension, then Theta <- Close(Theta, [])."""
        self.extended = True
        m = rec.m
        w, info = extend(self.w, guarded.root, guarded.order, hat0, hats, tildes, rec, self.samples, self.seed,
                         self.rtol)
        self.w = w
        entry["action"] = "UI extension"
        entry["extension"] = info
        self.c = close(w, w.theta, [])
        w.theta = list(self.c.ctx.codist.nodes)
        return _dim_step(w, self.c.ctx, it, w.theta, {"m": m, "canonic": False,
                                                      "extension": len(info["new_states"])})

    def terminate(self, it, history):
        return self.stop

    def postprocess(self, history, stop) -> GeneralRun:
        omega = self.omega if self.omega is not None else self.c.ctx
        degree = self.degree if self.stop is not None else self.trace[-1]["m"]
        return GeneralRun(self.w, omega, self.trace, history, stop, bool(self.initially), self.canonic,
                          self.extended, degree, self.spent)


def _dim_step(w, ctx, it, added, extra):
    """A Step of the main loop: the dimension of ``ctx``'s span on the original state."""
    _, dim = ctx.coordinates(w.system.n, w.n0)
    fraction = min((d.fraction for d in ctx.codist.acceptances), default=1.0)
    labels = tuple(nd.label for nd in added if nd.label not in w.known)
    return Step(it, dim, labels, fraction, extra)


def run(system, *, samples, seed, rtol, jet_order, prob_threshold=DEFAULT_PROB_THRESHOLD) -> GeneralRun:
    """The main loop of the module docstring on ``system`` (joint, autonomous), run by the
    driver with its cap of :data:`ITERATION_CAP` iterations."""
    w = start_working(system, jet_order, samples, seed, rtol, prob_threshold)
    cap = Cap(ITERATION_CAP - 1, StopReason.GENERAL_CAP.stop(cap=ITERATION_CAP))
    return iterate(GeneralSolution(w, samples, seed, rtol), cap=cap).result


def _field_zero(w, field, val, ref) -> bool:
    """A field ``G~_k`` (its Node ``field``) identically zero: the float64 vote
    ``|G~_k| <= ZERO_ROW_RTOL |g_k|`` (``ref``: the ``(S,)`` norms of the raw field ``g_k`` it
    was projected from) settled again on its expressions (:func:`decide_zero`)."""
    norms = np.linalg.norm(val, axis=-1)
    nz, frac = nonzero_votes(norms, ref, w.ctx.codist.valid)
    return decide_zero(w, w.ctx, f"{field.label} vanishes", list(field.expr), nz, frac)


# ------------------------------------------------------------------ observable UIs
def observable_inputs(out: GeneralRun, full: bool = False) -> dict:
    """Which final unknown inputs ``w~_k`` can be computed: ``dw~_k`` in
    ``span{d theta, d(D theta + sum_j w~_j L_{g_j} theta): theta in Omega}`` on ``[z; w~]``.

    ``full``: every original state is observable (then, with a canonic system, every final
    unknown input is, without the test)."""
    w = out.w
    if not w.uis:
        return {}
    if out.canonic and full:
        # canonic (B invertible, m = m_w) and every coordinate observable: D h~ = a + B w~
        # gives w~ = B^-1 (D h~ - a), a function of observable quantities
        return {k: True for k in w.system.unknown}
    ext = extended_system(w.system, 1)
    ctx = Context(ext, w.ctx.samples, 0, w.ctx.codist.rtol, w.ctx.prob_threshold)
    N = w.system.n
    b = ctx.builder
    src = out.omega.builder.graph  # the working system's: Omega's nodes, lifted to [z; w~]
    lifted = [b.node(("scalar", nd.label),
                     lambda nd=nd: b.make(nd.label, "scalar", 0, lift(b.graph, src, nd.expr, b.graph.coords[:N])[0]))
              for nd in out.omega.codist.nodes]
    F0 = b.field("F0", ext.drift)
    ctx.absorb(lifted)
    ctx.absorb_lie(lifted, [F0])
    members, _ = ctx.coordinates(ext.n, N)
    out.spent.append(ctx)
    return dict(zip(w.system.unknown, members[N:]))


# ------------------------------------------------------------------ the report
def general_ui_report(system, *, samples, seed, rtol, known_inputs="smooth", notes=(),
                      prob_threshold=DEFAULT_PROB_THRESHOLD) -> Report:
    """Run the general solution on ``system`` (joint; time as a known coordinate) and build
    the Report on the original state.

    Args:
        system: the System the analyses run on (:meth:`System.autonomous`).
        samples, seed, rtol: the sampling certificate's options.
        prob_threshold: the probability of correctness of the exact decisions.
        known_inputs: the meaning of the known inputs (must be ``"smooth"`` when there are
            any, :func:`check_applicable`).
        notes: notes to carry.

    Returns:
        :class:`~uio_jax.Report` with ``method="general_ui"``; ``details``: ``m`` (final
        degree of reconstructability), ``initially_canonic``, ``canonic``, ``ui_extension``,
        ``unknown_inputs_reconstructable`` (original names), ``unknown_inputs_observable``
        (final unknown inputs -> bool), ``final_unknown_inputs`` (final unknown input ->
        the original one it stands for), ``trace`` (one entry per iteration),
        ``jet_order`` (with known inputs).
    """
    check_applicable(system, known_inputs)
    n = system.n - known_coordinates(system)
    jet = n + JET_MARGIN
    for attempt in range(JET_RETRIES + 1):
        out = run(system, samples=samples, seed=seed, rtol=rtol, jet_order=jet, prob_threshold=prob_threshold)
        if not system.known or not _top_jet_used(out, system, jet) or attempt == JET_RETRIES:
            break
        jet = 2 * jet
    truncated = bool(system.known) and _top_jet_used(out, system, jet)
    omega = out.omega
    omega.certify()  # the final span at every sample; the verdicts read there
    members, dim = omega.coordinates(out.w.system.n, n)
    ui_obs = observable_inputs(out, full=all(members))
    for spent in out.spent:
        omega.memberships += [(False, d) for d in spent.codist.acceptances]
        omega.memberships += [(True, d) for d in spent.codist.rejections]
        omega.memberships += spent.memberships
        if spent.codist is not omega.codist:
            for esc in spent.codist.record.escalations:
                omega.codist.record.add(esc)
    states = system.states[:n]
    observable = dict(zip(states, members[:n]))
    names = list(system.unknown)
    reconstructable = sorted({names[out.w.origin[i]] for i in range(out.degree)},
                             key=names.index) if out.degree else []
    zero_tests = out.w.zero_tests
    weakest = min((t.fraction for t in zero_tests), default=1.0)
    details = {
        "exact": not truncated and out.stop.reason.converged,
        "known_inputs": known_inputs if system.known else "none",
        "m": out.degree,
        "initially_canonic": out.initially_canonic,
        "canonic": out.canonic,
        "ui_extension": out.extended,
        "unknown_inputs_reconstructable": reconstructable,
        "unknown_inputs_observable": ui_obs,
        "final_unknown_inputs": {k: names[out.w.origin[i]] for i, k in enumerate(ui_obs)},
        "zero_tests": len(zero_tests),
        "zero_test_min_fraction": weakest,
        "trace": out.trace,
    }
    if system.known:
        details["jet_order"] = jet
    notes = list(notes) + _report_notes(system, truncated, jet, weakest)
    space = SampledSpace(omega, n=n, dim=dim, original=system)
    omega.extra_decisions = [t.settled for t in zero_tests] + list(out.w.rank_tests)
    view = report_view(system, n)
    return omega.report("general_ui", out.history, out.stop, notes=notes, details=details,
                        projection=Projection(view, dim, observable, space), known_inputs=known_inputs)


def _report_notes(system, truncated, jet, weakest) -> list:
    """The general solution's own notes: the meaning of its known inputs, a jet that may
    have been truncated, a weak zero test."""
    notes = []
    if system.known:
        notes.append(
            "known inputs taken as generic smooth functions of time (known_inputs='smooth'): "
            "the exact answer of the general solution for that meaning")
    if truncated:
        notes.append(f"a differentiated generator depends on the highest jet u^({jet}) kept: "
                     "the answer may be incomplete")
    if weakest < 0.9:
        notes.append(f"weak zero test: a 'vanishes identically' decision was backed by only "
                     f"{100 * weakest:.0f}% of the samples")
    return notes


def _top_jet_used(out: GeneralRun, system, jet) -> bool:
    """Whether a generator of Omega depends on a highest jet ``u_i^(jet)`` (other than that
    coordinate itself)."""
    ctx = out.omega
    N0 = system.n
    mu = len(system.known)
    top = [N0 + i * (jet + 1) + jet for i in range(mu)]
    coordinates = set(jet_names(system, jet))
    nodes = [nd for nd in ctx.codist.nodes if nd.label not in coordinates]
    if not nodes:
        return False
    grads = ctx.gradients(nodes)
    norms = np.linalg.norm(grads, axis=-1)
    for c in top:
        for i in range(len(nodes)):
            nz, frac = nonzero_votes(grads[:, i, c], norms[:, i], ctx.codist.valid)
            expr = partial_derivative(ctx.builder.graph, nodes[i].expr, c)
            if not decide_zero(out.w, ctx, f"d {nodes[i].label}/d u^({jet})", [expr], nz, frac):
                return True
    return False
