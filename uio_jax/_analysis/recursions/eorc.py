"""Extended observability rank criterion (EORC): any number of unknown inputs, drift allowed.

Martinelli, INRIA RR-8608 (004) sections 4-6 and MED 2015 (001) section IV, Algorithm 1.

**Extended system** (004 eq. 4-7). With ``m_w`` unknown inputs ``w = [w_1..w_mw]`` the state
is augmented by the inputs and their time derivatives up to order ``K - 1``::

    x^(K) = [x; w; w^(1); ...; w^(K-1)]                       (n + K m_w)
    F0    = [f0(x) + sum_j g_j(x) w_j; w^(1); ...; w^(K-1); 0]   (extended drift)
    F_i   = [f_i(x); 0]                                        (known fields)

and the output is still ``h(x)``. ``Omega-bar_k`` is the span of the gradients (with respect
to the whole extended state) of every Lie derivative of the outputs along ``F0, F_1..F_mu``
of order ``<= k`` (001 Algorithm 1)::

    Omega-bar_0 = span{dh},   Omega-bar_k = Omega-bar_{k-1} + sum_{v in {F0, F_i}} L_v Omega-bar_{k-1}.

``x_j`` satisfies the EORC at order k when ``e_j`` (padded with zeros) lies in
``Omega-bar_k``; then ``x_j`` is weakly locally observable (001 Proposition 4). It is a
sufficient condition only: a component not shown observable up to ``k_max`` may become so
at a higher order.

**One extension, every order.** By Proposition 2 of 004 the Lie derivatives of order
``<= k`` computed in ``Sigma^(k)`` and in ``Sigma^(K)`` (``K >= k``) coincide, and by Lemma 1
they do not depend on ``w^(f)``, ``f >= k``: the order-``<= k`` part of one run on
``Sigma^(k_max)`` *is* ``Omega-bar_k`` of the k-th extension (padded with zero columns).
So the extension is built once, at ``K = k_max``, and an ORC-like recursion runs on it with
step ``k`` = order ``k``.

**Pruning.** As in :mod:`uio_jax._analysis.recursions.orc`, only the generators kept at order ``k - 1`` are
differentiated at order ``k``: if ``dc = sum_i a_i dk_i`` (``a_i`` functions of the
extended state) then ``L_v dc = sum_i (L_v a_i) dk_i + a_i d L_v k_i``, and ``L_v k_i`` was
formed at the step after ``k_i`` was kept, at order ``<= k``. The argument holds in
``Sigma^(K)`` for every order ``<= K`` (the truncation ``dw^(K-1)/dt = 0`` only changes
orders ``> K``). If no generator is kept at some order ``k <= K``, ``Omega-bar`` is
invariant under every ``L_v`` and no higher order (in any extension) adds anything.

**Per order k** the report gives: the rank of ``Omega-bar_k`` (augmented rank, out of
``n + k m_w``), the dimension on the original state ::

    dim_k = rank(Omega-bar_k) + n - rank([Omega-bar_k; e_1..e_n])
          = dim(Omega-bar_k  intersected with  span{dx_1..dx_n}),

the state components with ``e_j`` in ``Omega-bar_k``, and the extended coordinates
(unknown inputs and their derivatives, ``w^(d)`` with ``d < k``) whose ``e`` lies in
``Omega-bar_k``: those are observable too, so the disturbance can be estimated.
For a single unknown input and no drift, Theorem 1 of 004 gives
``Omega-bar_k = [Omega_k, 0] + span{d L_G^1 h .. d L_G^k h}``, so ``dim_k = dim Omega_k``.

**Evaluation.** The order-k generators are mostly ``L_F0^j`` of a short word, so a generator
is a node of the System's expression graph (``L_F0^j base`` one power node, ``L_{F_i} phi`` a
Lie node, :mod:`uio_jax._calculus.generators`), its gradients evaluated by numpy.

**Sampling.** The extended coordinates are sampled, like states without a given domain, in
``uio_jax._model.system.DEFAULT_BOX`` = (0.5, 1.5): away from 0, where inputs such as a speed
make the rank drop. For analytic models the generic rank is the same on every open set.
"""

import time

import numpy as np

from ..._errors import ModelError
from ..._model.smooth_inputs import known_coordinates, with_input_jets
from ..._model.system import DEFAULT_BOX
from ..decisions.context import Context
from ..decisions.memory import analysis_bytes, check_memory, memory_limit
from ..decisions.settle import DEFAULT_PROB_THRESHOLD
from ..decisions.space import Projection, SampledSpace, report_view
from ..decisions.symmetry import symmetry_notes, verify_symmetries
from ..results.evidence import Step
from ..results.report import Report
from .driver import Cap, Recursion, StopReason, iterate
from .eorc_extension import default_k_max as default_k_max
from .eorc_extension import extended_system as extended_system
from .eorc_extension import input_names as input_names
from .known_bound import known_input_bound, stop_note

#: Name of the extended drift field in generator labels.
DRIFT_LABEL = "F0"

class _Eorc(Recursion):
    """One EORC run (001 Algorithm 1) on ``Sigma^(K)``, order ``k`` = step ``k`` of the driver.

    After each order, :meth:`coordinates` reads the observable coordinates off
    ``Omega-bar_k``; the next order's gradients are evaluated during this order's rank work
    (:meth:`record`).
    """

    def __init__(self, system, K, samples, seed, rtol, early_stop=True, analysed=None,
                 prob_threshold=DEFAULT_PROB_THRESHOLD):
        self.system = system
        #: the System before the jets of smooth known inputs were added (its symmetries)
        self.analysed = system if analysed is None else analysed
        self.K = K
        self.N = system.n  # coordinates before the unknown-input ones
        self.n = system.n - known_coordinates(system)  # those reported on (not known ones)
        self.mw = len(system.unknown)
        self.ext = extended_system(system, K)
        self.names = input_names(system, K)
        self.ctx = Context(self.ext, samples, seed, rtol, prob_threshold)
        builder = self.ctx.builder
        self.drift = builder.field(DRIFT_LABEL, self.ext.drift)
        self.known = tuple(builder.field(k, f) for k, f in self.ext.known.items())
        self.steps = []  # per order: frontier size, candidates, eval seconds
        self.frontier = []  # the generators kept at the last order
        self.started = []  # the next order's block, dispatched during this order's rank work
        self._escalations_seen = 0
        self.samples, self.seed, self.rtol = samples, seed, rtol
        self.bound = None  # the known-input bound (known_bound.KnownBound), once computed
        self.early_stop = early_stop  # False: k_max given, every order up to it is reported
        self._bound_tried = not early_stop
        self._symmetry = None  # (symmetry.SymmetryBound or None,) once verified

    # ------------------------------------------------------------------ the recursion
    def init(self) -> Step:
        """``Omega-bar_0 = span{dh}``: the outputs, kept where they raise the rank."""
        self.frontier = self.ctx.absorb(self.ctx.output_nodes())
        return self.record(0)

    def step(self, k) -> Step:
        """``Omega-bar_k = Omega-bar_{k-1} + sum_v L_v Omega-bar_{k-1}`` (pruned: only the
        children of the generators kept at order ``k - 1``)."""
        started = self.started.pop() if self.started else None
        self.frontier = self.absorb_children(self.frontier, k, started)
        return self.record(k)

    def terminate(self, k, history):
        """Omega-bar closed (nothing kept at order ``k >= 1``, some state not observable),
        every state observable, the states at the known-input bound with every unknown
        input observable (:meth:`at_known_bound`), or ``k = K``; None to go on."""
        full = len(history[-1].extra["observable_states"]) == self.n
        if k > 0 and not self.frontier and not full:
            return StopReason.EXTENSION_CLOSED.stop(k=k, prev=k - 1)
        if full:
            return StopReason.ALL_STATES.stop(k=k)
        if self.early_stop:
            stop = self.at_bound(history[-1])
            if stop is not None:
                return stop
        return None

    def symmetry_bound(self):
        """The verified symmetries of the analysed System
        (:func:`uio_jax._analysis.decisions.symmetry.verify_symmetries`, once), or None."""
        if self._symmetry is None:
            self._symmetry = (verify_symmetries(self.analysed, seed=self.seed, prob_threshold=self.ctx.prob_threshold,
                                                charge=self.ctx.settler),)
        return self._symmetry[0]

    def at_bound(self, last):
        """The Stop when order ``last.m`` is final, else None. No decision so far may be
        undecided, and then either ``dim_k`` equals the bound of the verified symmetries
        (:mod:`.symmetry`) and every unknown input is observable or proved unobservable by
        one of them, or :meth:`at_known_bound` holds.
        """
        if any(e.result == "undecided" for e in self.ctx.codist.record.escalations):
            return None
        observed = set(last.extra["observable_inputs"])
        inputs = self.names[: self.mw]
        sym = self.symmetry_bound()
        if sym is not None and sym.rank and last.dim == sym.dim and all(
                nm in observed or nm in sym.unobservable_inputs for nm in inputs):
            return StopReason.SYMMETRY_BOUND.stop(k=last.m, bound=sym.dim)
        if self.at_known_bound(observed, last.dim):
            return StopReason.KNOWN_BOUND.stop(k=last.m, bound=self.bound.dim)
        return None

    def at_known_bound(self, observed, dim) -> bool:
        """Whether every unknown input ``w_j`` is observable (``observed``: the observable
        input coordinates) and ``dim`` (``dim_k``) equals the known-input bound
        (:mod:`.known_bound`, computed once, the first time they all are)."""
        if not all(nm in observed for nm in self.names[: self.mw]):
            return False
        if not self._bound_tried:
            self._bound_tried = True
            self.bound = known_input_bound(self.system, samples=self.samples, seed=self.seed,
                                           rtol=self.rtol, prob_threshold=self.ctx.prob_threshold)
        return self.bound is not None and dim == self.bound.dim

    def record(self, k) -> Step:
        """The Step of order ``k`` (``Step.m = k``, ``Step.dim = dim_k``; ``extra``:
        augmented rank and dimension, observable states and input coordinates)."""
        added = self.frontier

        def start_next():  # the next order will run: frontier not empty, k < K, not full
            if k < self.K and added:
                self.started.append(self.dispatch(added, k + 1))

        states, inputs, dim = self.coordinates(k, start_next)
        escalations = self.ctx.codist.record.escalations
        extra = {
            "augmented_rank": self.ctx.dim,
            "augmented_dim": self.N + k * self.mw,
            "observable_states": tuple(states),
            "observable_inputs": tuple(inputs),
            # decisions of this order that neither float64 nor exact arithmetic settled,
            # and the escalations recorded up to this order (their index)
            "undecided": sum(e.result == "undecided" for e in escalations[self._escalations_seen:]),
            "escalations": len(escalations),
        }
        self._escalations_seen = len(escalations)
        decided = self.ctx.codist.acceptances[-len(added):] if added else []
        fraction = min((d.fraction for d in decided), default=1.0)
        return Step(k, dim, tuple(nd.label for nd in added), fraction, extra)

    # ------------------------------------------------------------------ one order
    def children(self, phi) -> list:
        """``L_F0 phi`` (a power: ``L_F0^(j+1) base`` for ``phi = L_F0^j base``), then
        ``L_{F_i} phi`` for the known fields, as nodes of the graph."""
        b = self.ctx.builder
        base, j = b.power_of(phi, self.drift)
        up = b.power(self.drift, base, j + 1, depth=phi.depth + 1)
        return [up] + [b.lie(v, phi) for v in self.known]

    def dispatch(self, frontier, k):
        """The children of ``frontier`` (order ``k``) and their gradients, evaluated now in
        the expression graph: ``(frontier, t1, gradients (S, c, N))``."""
        t1 = time.perf_counter()
        children = [c for phi in frontier for c in self.children(phi)]
        return frontier, t1, self.ctx.gradients(children)

    def absorb_children(self, frontier, k, started=None):
        """Form ``L_v phi`` for every phi of the frontier and v in ``F0, F_i``; absorb them.

        ``started``: the :meth:`dispatch` of the same frontier, if it was made earlier
        (its ``eval_s`` then includes the work done meanwhile).
        """
        if not frontier:
            return []
        if started is None:
            started = self.dispatch(frontier, k)
        frontier, t1, grads = started
        nodes = [c for phi in frontier for c in self.children(phi)]
        self.steps.append({"k": k, "frontier": len(frontier), "candidates": len(nodes),
                           "eval_s": time.perf_counter() - t1})
        return self.ctx.absorb(nodes, np.asarray(grads))

    def coordinates(self, k, meanwhile=None):
        """What ``Omega-bar_k`` says about the coordinates of ``Sigma^(k)``, certified.

        One test of the unit covectors ``e_1..e_{n + k m_w}`` against the span
        (:meth:`~uio_jax._analysis.decisions.rank.Codistribution.test_units`) decides every
        membership; ``dim_k`` (module docstring) absorbs ``e_1..e_n`` one by one into a copy of
        the codistribution. ``meanwhile()`` is called once the memberships are known and some
        state is not observable (the run starts the next order's block there).

        Returns:
            ``(states, inputs, dim)``: names of the states and of the input coordinates
            (orders < k) whose ``e`` lies in Omega-bar, and ``dim_k``.
        """
        n = self.n
        N_k = self.N + k * self.mw
        members, dim = self.ctx.coordinates(N_k, n, meanwhile)
        names = self.ext.states[:N_k]
        states = [s for s, m in zip(names[:n], members[:n]) if m]
        inputs = [s for s, m in zip(names[self.N:], members[self.N:]) if m]
        return states, inputs, dim


def check_eorc_memory(system, samples: int, K: int) -> int:
    """Refuse an EORC whose arrays on ``Sigma^(K)`` cannot fit, before any is allocated.

    The codistribution lives on ``N = n + K m_w`` coordinates, so its rank basis alone is
    ``(N, S', N)`` float64: quadratic in ``k_max``. The message says to lower ``k_max`` when
    the default order ``n + 2`` fits with these samples, else ``samples`` (and ``k_max``).

    Returns:
        The estimated bytes.

    Raises:
        OptionError: the estimate exceeds :func:`uio_jax._analysis.decisions.memory.memory_limit`.
    """
    n, mw = system.n, len(system.unknown)
    N = n + K * mw
    K0 = default_k_max(system)
    N0 = n + K0 * mw
    lower_k = K > K0 and sum(analysis_bytes(samples, N0, N0).values()) <= memory_limit()[0]
    what = (f"the EORC to k_max={K} (samples={samples} x N={N} coordinates: {n} states + "
            f"{K} x {mw} unknown-input derivatives)")
    advice = (f"lower k_max (default {K0})" if lower_k
              else "lower samples and k_max" if K > K0 else "lower samples")
    return check_memory(samples, N, N, what=what, advice=advice)


def run_eorc(system, *, samples, seed, rtol, k_max=None, early_stop=None, analysed=None,
             prob_threshold=DEFAULT_PROB_THRESHOLD):
    """Run the EORC recursion up to ``k_max`` (default ``n + 2``) by the shared driver.

    ``early_stop``: stop at the bound of the verified symmetries or at the known-input bound
    (:mod:`uio_jax._analysis.decisions.symmetry`, :mod:`uio_jax._analysis.recursions.known_bound`); default: only
    when ``k_max`` is not given (a given ``k_max`` asks for every order up to it).
    ``analysed``: the System whose symmetries are verified (``system`` before the jets of
    smooth known inputs were added; default ``system``).

    Returns:
        ``(run, history, stop_reason, k_reached)``: the :class:`_Eorc`, one Step per order
        ``k = 0..k_reached``, the :class:`~uio_jax._analysis.recursions.driver.Stop`.
    """
    K = default_k_max(system) if k_max is None else int(k_max)
    check_eorc_memory(system, samples, K)
    if early_stop is None:
        early_stop = k_max is None
    run = _Eorc(system, K, samples, seed, rtol, early_stop=early_stop, analysed=analysed,
                prob_threshold=prob_threshold)
    out = iterate(run, cap=Cap(K, StopReason.K_MAX.stop(k_max=K)))
    return run, out.history, out.stop, out.m


def _notes(run, last, notes, reason, dropped, k, k_used, dim_all, states, observable, smooth, K):
    """The notes of the EORC's Report: orders whose decisions could not be settled, the
    certifying samples' dimension, smooth known inputs, the stop at the known-input bound or
    at the bound of the verified symmetries, what a sufficient condition leaves open, the
    extended coordinates' box. ``last``: the Step of order ``k_used`` (the verdicts').
    Returns ``(notes, at_bound, symmetry bound, at_symmetry)``."""
    ctx = run.ctx
    notes = list(notes)
    if k_used < k:
        notes.append(
            f"orders k={k_used + 1}..{k}: {sum(e.result == 'undecided' for e in dropped)} rank decisions could "
            "not be settled (float64 round-off in derivatives of that order; exact arithmetic found the "
            f"span inconsistent or could not decide); the verdicts are those of order k={k_used}, whose "
            "decisions are all certified (the EORC's answer only grows with k)")
    if dim_all != last.dim or set(states) != set(last.extra["observable_states"]):
        notes.append(f"order k={k_used} decided on the first {ctx.decisions} samples gave "
                     f"dim {last.dim}; the {len(ctx.xs)} certifying samples give dim {dim_all}: the report "
                     "gives the latter")
    if smooth:
        notes.append(
            "known inputs taken as generic smooth functions of time (known_inputs='smooth'): "
            f"their derivatives up to order {K - 1} are known coordinates of the drift")
    stopped = reason.reason is StopReason.KNOWN_BOUND
    at_bound = stopped and k_used == k and dim_all == run.bound.dim
    hidden = [s for s, v in observable.items() if not v]
    if stopped:
        notes.append(stop_note(run.bound, k, last.dim, dim_all, hidden, at_bound))
    sym = run.symmetry_bound()
    at_symmetry = False
    if sym is not None:
        sym_notes, at_symmetry = symmetry_notes(sym, observable, f"k={k_used}", dim_all)
        notes.extend(sym_notes)
    if hidden and not (at_bound or at_symmetry):
        notes.append(
            f"the EORC is a sufficient condition only: {', '.join(hidden)} not shown "
            f"observable up to order k={k} (k_max={run.K}); a higher order may show more"
        )
    notes.append(
        "extended coordinates (unknown inputs and their derivatives) sampled in "
        f"{DEFAULT_BOX}; unobservable_directions(x) sets them to one generic point of that box (seeded)"
    )
    return notes, at_bound, sym, at_symmetry


def _details(run, history, k, k_used, first_seen, at_bound, sym, at_symmetry) -> dict:
    """``Report.details`` of the EORC (see :func:`eorc_report`)."""
    return {
        "k": k,
        "k_verdict": k_used,
        "k_max": run.K,
        "extended_state": list(run.ext.states[: run.N + max(k, 1) * run.mw]),
        "augmented_ranks": [st.extra["augmented_rank"] for st in history],
        "observable_inputs": {st.m: list(st.extra["observable_inputs"]) for st in history},
        "inputs_observable_at": first_seen,
        # the rank with every input known (None: not needed, or no sound bound), and the
        # order at which the states reached it with every unknown input observable
        "known_input_bound": None if run.bound is None else {
            "dim": run.bound.dim, "series_order": run.bound.order,
            "settled_beyond_float64": run.bound.settled, "reached_at": k if at_bound else None},
        # the verified symmetries (None: none declared) and the order at which the states
        # reached their bound
        "symmetries": None if sym is None else {**sym.to_dict(), "reached_at": k_used if at_symmetry else None},
    }


def eorc_report(system, *, samples, seed, rtol, k_max=None, notes=(),
                known_inputs="switchable", prob_threshold=DEFAULT_PROB_THRESHOLD) -> Report:
    """The EORC of ``system`` as a :class:`~uio_jax.Report` (called by ``analyze``).

    Args:
        system: the original System.
        samples, seed, rtol: sampling certificate options (see :func:`uio_jax.analyze`).
        prob_threshold: the probability of correctness of the exact decisions.
        k_max: highest order (default ``n + 2``). Not given, the run may stop earlier, at
            the known-input bound (:mod:`uio_jax._analysis.recursions.known_bound`); given, every
            order up to it is run (unless the span closes or every state is observable).
        notes: notes to carry (e.g. why ``auto`` chose the EORC).
        known_inputs: ``"switchable"`` (close under every raw known field, the papers'
            EORC) or ``"smooth"`` (the known inputs are generic smooth functions of time:
            their jets to order ``k_max - 1`` enter the drift, :mod:`uio_jax._model.smooth_inputs`,
            and are known coordinates).

    Returns:
        Report on the ORIGINAL state: ``dim`` = dim of ``Omega-bar_k`` intersected with
        ``span{dx}`` at the last order ``k``; ``history`` has one Step per order
        ``k = 0..k_reached`` (``Step.m = k``; ``extra``: ``augmented_rank``,
        ``augmented_dim``, ``observable_states``, ``observable_inputs``;
        ``Step.fraction`` is the smallest fraction of agreeing samples among the rank
        decisions that kept the order's generators); ``details``:
        ``k``, ``k_max``, ``extended_state``, ``inputs_observable_at`` (first order at
        which each input coordinate is observable).
    """
    if k_max is not None and (isinstance(k_max, bool) or int(k_max) < 1):
        raise ModelError(f"k_max must be a positive integer, got {k_max!r}")
    K = default_k_max(system) if k_max is None else int(k_max)
    smooth = known_inputs == "smooth" and bool(system.known)
    working = with_input_jets(system, K - 1) if smooth else system
    run, history, reason, k = run_eorc(working, samples=samples, seed=seed, rtol=rtol,
                                       k_max=K, early_stop=k_max is None, analysed=system,
                                       prob_threshold=prob_threshold)
    ctx = run.ctx
    # the EORC is monotone in k: the answer is the one of the last order whose
    # decisions are all certified (float64 or beyond); later orders are reported, not used
    uncertain = [st.m for st in history if st.extra["undecided"]]
    k_used = uncertain[0] - 1 if uncertain and uncertain[0] > 0 else k
    if k_used < k:
        at = history[k_used]
        dropped = ctx.codist.record.escalations[at.extra["escalations"]:]
        ctx.codist.record.escalations = ctx.codist.record.escalations[:at.extra["escalations"]]
        ctx.certify(upto=at.extra["augmented_rank"])
    else:
        dropped = []
        ctx.certify()  # the final span at every sample; the verdicts read there
    states, _, dim_all = run.coordinates(k_used)
    last = history[k_used]
    view = report_view(system, run.n)  # the known coordinates (time) left out
    observable = {s: s in states for s in view.states}
    first_seen = {}
    for st in history:
        for nm in st.extra["observable_inputs"]:
            first_seen.setdefault(nm, st.m)
    notes, at_bound, sym, at_symmetry = _notes(run, last, notes, reason, dropped, k, k_used, dim_all, states,
                                               observable, smooth, K)
    details = _details(run, history, k, k_used, first_seen, at_bound, sym, at_symmetry)
    # Omega-bar_k queried about the original state: the extended coordinates at the centre
    # of their sampling box
    space = SampledSpace(ctx, n=run.n, dim=dim_all, original=run.analysed)
    return ctx.report("eorc", history, reason, notes=notes, details=details,
                      projection=Projection(view, dim_all, observable, space), known_inputs=known_inputs)
