"""Identifiability at t = 0: known initial states and several experiments.

The mathematics is in :mod:`uio_jax._analysis.at_t0.initial`; this module runs it.

**Several experiments.** Experiment ``e`` is a System with its own states, inputs and initial
state; the parameters named in ``shared`` are one unknown for every experiment, the others one
per experiment (named ``k[e]``): the Jacobian is ``[A_e | B_e]`` per experiment, ``A_e`` on
the shared parameters. The experiments are absorbed one after another (the report lists what
each adds); an experiment's own span is closed once one of its orders adds nothing to it (no
known initial value, no unknown input), so the joint span is complete.

**Generic experiments.** Copies of one System with independent generic states and inputs.
Let ``W(x)`` be the space of shared-parameter covectors that one copy's rows give once its own
unknowns are eliminated (``{a^T A : a^T B = 0}``); ``m`` copies give the rank
``m rho + dim(W(x_1) + .. + W(x_m))``, ``rho`` the rank of ``B``. ``d_m = dim(W(x_1) + .. +
W(x_m))`` at generic points never decreases with ``m``. If ``d_{m+1} = d_m``, then for generic
``x_1..x_m`` the set of ``x`` with ``W(x)`` inside ``S = W(x_1) + .. + W(x_m)`` contains a
non-empty Zariski-open set; a covector ``c`` orthogonal to ``S`` is then orthogonal to ``W(x)``
on that open set, hence (a polynomial identity in ``x``) everywhere, so ``S`` contains every
``W(x)``: no further copy adds anything. The smallest ``m`` with ``d_{m+1} = d_m`` (or
``d_m`` equal to the number of shared parameters) is the answer; ``m`` is at most that number
plus one.
"""

import dataclasses
from collections.abc import Mapping

from ..._engine import graph_exact
from ..._engine.graph import Graph
from ..._errors import OptionError
from ..._model.system import System
from ..decisions.settle import Settler
from ..results.evidence import Arithmetic, Finding, Settlement
from ..results.identifiability_report import IdentifiabilityReport, StopKind
from ..results.kinds import Verdict
from ..results.report import Question
from .initial import Coordinates, Experiment, Role, Span, check_defined, check_initial, unused_note, unused_parameters
from .initial_proofs import Search, prove_not_determined
from .space import InitialSpace


def default_max_order(unknowns: int) -> int:
    """The highest order by default, ``2 * unknowns + 2`` (unknowns: the unknown initial states
    and the parameters). At a specific initial state no bound is known (the module docstring of
    :mod:`uio_jax._analysis.at_t0.initial`); generic orders close by the number of unknowns."""
    return 2 * unknowns + 2


def analyze_initial(system: System, initial, *, seed: int, prob_threshold: float, max_order=None):
    """Local identifiability of ``system`` at the known initial state ``initial``
    (:mod:`uio_jax._analysis.at_t0.initial`): an :class:`IdentifiabilityReport`."""
    return analyze_experiments([system], [initial], shared=None, seed=seed, prob_threshold=prob_threshold,
                               max_order=max_order, generic=False)


def analyze_experiments(systems, initials, *, shared, seed: int, prob_threshold: float, max_order=None,
                        generic: bool = True):
    """Identifiability from several experiments (module docstring): each experiment a System
    with its known initial state (``initials[e]``, possibly empty); ``shared`` the shared
    parameter names (None: every parameter name common to all experiments).

    Returns:
        :class:`IdentifiabilityReport`, with the experiments' contributions and, when
        ``generic``, the smallest number of generic experiments of each distinct System.
    """
    systems, initials, shared = _check_experiments(systems, initials, shared)
    checked = [check_initial(s, i) for s, i in zip(systems, initials)]
    many = len(systems) > 1
    unknowns = max(s.n - len(i) + len(s.params) for s, i in zip(systems, checked))
    cap = default_max_order(unknowns) if max_order is None else int(max_order)
    coords = Coordinates()
    exps = [Experiment(s, i, coords, max(cap, 1), f"[{e + 1}]" if many else "", shared)
            for e, (s, i) in enumerate(zip(systems, checked))]
    target = Graph(len(coords.names))
    lo, hi = coords.box()
    for ex in exps:
        ex.attach(target)
        where = ", ".join(f"{k}{ex.suffix} = {v.text}" for k, v in ex.initial.items()) or "generic"
        check_defined(target, ex.order(0) + ex.order(1), seed, where, (lo, hi))
    settler = Settler(target, lo, hi, seed, prob_threshold)
    span = Span(settler, [i for ex in exps for i in ex.seeds])
    determined, contributions, ranks = {}, [], []
    for e, ex in enumerate(exps):
        contributions.append(_absorb(ex, span, settler, coords, exps[:e + 1], determined, ranks, cap, many))
    proved_not = all(c["closed"] for c in contributions)
    search = _symmetry_proofs(exps, settler, coords, determined, proved_not, seed, prob_threshold)
    moved = {i for proof in search.proofs for i in proof.moved}
    verdict = {i: Verdict.DETERMINED if i in determined else
               Verdict.NOT_DETERMINED if proved_not or i in moved else Verdict.UNDECIDED
               for i in coords.of(Role.STATE, Role.PARAM)}
    generic_rows = []
    if generic:  # once per distinct System (by identity)
        distinct = [s for i, s in enumerate(systems) if all(s is not t for t in systems[:i])]
        rows = (generic_experiments(s, shared, seed, prob_threshold) for s in distinct)
        generic_rows = [g for g in rows if g]
    escalations = list(span.escalations)
    report = _report(systems, exps, coords, verdict, contributions, ranks, escalations, settler,
                     prob_threshold, many, generic_rows, search)
    space = InitialSpace(span, exps, proved_not, report.order)
    return dataclasses.replace(report, space=space)


def _symmetry_proofs(exps, settler, coords, determined, proved_not, seed, prob_threshold) -> Search:
    """Proofs that undecided unknowns are not determined, by symmetries keeping the known
    initial values (:mod:`.initial_proofs`); one experiment only."""
    undecided = [i for i in coords.of(Role.STATE, Role.PARAM) if i not in determined]
    if not undecided or proved_not:
        return Search((), "")
    if len(exps) > 1:
        return Search((), "no symmetry search for several experiments (a symmetry would have to act on every "
                          "experiment at once)")
    return prove_not_determined(exps[0], settler, undecided, seed, prob_threshold)


def _check_experiments(systems, initials, shared):
    """The experiments' Systems, initial states and shared names, checked (OptionError)."""
    systems = list(systems)
    if not systems or not all(isinstance(s, System) for s in systems):
        raise OptionError("experiments must be a non-empty sequence of uio_jax.System")
    if isinstance(initials, Mapping) or isinstance(initials, str):
        raise OptionError("several experiments take one initial state per experiment: initial=[{...}, None, ...]")
    initials = [{} for _ in systems] if initials is None else list(initials)
    if len(initials) != len(systems):
        raise OptionError(f"initial gives {len(initials)} initial states for {len(systems)} experiments")
    initials = [{} if i is None else i for i in initials]
    params = [set(s.params) for s in systems]
    common = set.intersection(*params)
    if shared is None:
        shared = tuple(p for p in systems[0].params if p in common)
    elif isinstance(shared, str):
        raise OptionError("shared must be a sequence of parameter names, got a string")
    else:
        shared = tuple(shared)
        repeated = sorted({p for p in shared if shared.count(p) > 1}, key=str)
        if repeated:
            raise OptionError(f"shared names {', '.join(map(repr, repeated))} more than once")
        for p in shared:
            if p not in common:
                raise OptionError(f"shared parameter {p!r} is not a parameter of every experiment")
    return systems, initials, shared


def _absorb(ex, span, settler, coords, upto, determined, ranks, cap, many):
    """Absorb experiment ``ex``'s orders into ``span`` until every unknown of the experiments
    so far is determined, its own span closes, or the cap; returns its contribution."""
    own = Span(settler, ex.seeds) if (many and ex.closable) else None
    targets = list(dict.fromkeys(i for x in upto for i in x.z_index if i is not None))
    added, closed, k = [], False, 0
    for k in range(cap + 1):
        rows = ex.order(k)
        grew = span.absorb(rows)
        own_grew = own.absorb(rows) if own is not None else grew
        ranks.append(span.rank)
        for i in targets:
            if i not in determined and span.contains(i) is Finding.DEPENDENT:
                determined[i] = k
                added.append(coords.names[i])
        if all(i in determined for i in targets):
            closed = not ex.joint.unknown  # its rows live in determined or known columns
            break
        if ex.closable and not own_grew:
            closed = True
            break
    initial = {f"{s}{ex.suffix}": v.text for s, v in ex.initial.items()}
    return {"name": ex.system.name or ex.suffix.strip("[]") or "1", "initial": initial, "order": k, "closed": closed,
            "added": added}


def generic_experiments(system, shared, seed, prob_threshold):
    """The smallest number of generic experiments of ``system`` reaching the maximal rank of
    the shared parameters (module docstring), or None (unknown inputs, no shared parameter)."""
    shared = tuple(p for p in system.params if p in shared)
    if system.unknown or not shared or system.time is not None:
        return None
    copies = len(shared) + 1
    cap = system.n + len(system.params) + 1
    coords = Coordinates()
    exps = [Experiment(system, {}, coords, cap, f"[{c + 1}]", shared) for c in range(copies)]
    target = Graph(len(coords.names))
    for ex in exps:
        ex.attach(target)
    lo, hi = coords.box()
    settler = Settler(target, lo, hi, seed + 1, prob_threshold)
    first = exps[0]
    own, closing = Span(settler, first.seeds), cap
    for k in range(cap + 1):
        if not own.absorb(first.order(k)):
            closing = k
            break
    p_index = [coords.index[p] for p in shared]
    local = Span(settler, first.seeds + p_index)  # the copy's own columns: shared ones known
    for k in range(closing + 1):
        local.absorb(first.order(k))
    rho = local.rank
    joint = Span(settler, [i for ex in exps for i in ex.seeds])
    ranks, determined, minimal = [], [], copies
    for m, ex in enumerate(exps, start=1):
        for k in range(closing + 1):
            joint.absorb(ex.order(k))
        ranks.append(joint.rank - m * rho)
        determined.append([p for p, i in zip(shared, p_index) if joint.contains(i) is Finding.DEPENDENT])
        if m > 1 and ranks[-1] == ranks[-2]:
            minimal = m - 1
            ranks, determined = ranks[:-1], determined[:-1]
            break
        if ranks[-1] == len(shared):
            minimal = m
            break
    return {"system": system.name or "system", "minimal": minimal, "ranks": ranks, "determined": determined,
            "closing_order": closing, "error_bound": settler.error_bound,
            "exact": all(e.how is Settlement.EXACT for e in own.escalations + local.escalations + joint.escalations)}


def _report(systems, exps, coords, verdict, contributions, ranks, escalations, settler, prob_threshold, many,
            generic_rows, search):
    """The :class:`IdentifiabilityReport` of a run."""
    free = any(ex.joint.unknown for ex in exps)
    question = ((Question.EXPERIMENTS_FREE_INPUT_JETS if free else Question.EXPERIMENTS) if many else
                (Question.KNOWN_INITIAL_STATE_FREE_INPUT_JETS if free else Question.KNOWN_INITIAL_STATE))
    hows = [e.how for e in escalations]
    exact = all(h is Settlement.EXACT for h in hows) and all(g["exact"] for g in generic_rows)
    arithmetic = Arithmetic.EXACT if exact else (
        Arithmetic.EXTENDED if all(h in (Settlement.EXACT, Settlement.EXTENDED) for h in hows) else Arithmetic.FLOAT64)
    undecided = sum(e.result is Finding.UNDECIDED for e in escalations)
    states, params = coords.of(Role.STATE), coords.of(Role.PARAM)
    stop = (StopKind.ALL_DETERMINED if all(v is Verdict.DETERMINED for v in verdict.values()) else
            StopKind.SPAN_CLOSED if all(c["closed"] for c in contributions) else StopKind.MAX_ORDER)
    notes = _notes(exps, verdict, coords, contributions, free, search)
    return IdentifiabilityReport(
        question=question, system_name=systems[0].name,
        states=tuple(coords.names[i] for i in states), params=tuple(coords.names[i] for i in params),
        observable={coords.names[i]: verdict[i] for i in states},
        identifiable={coords.names[i]: verdict[i] for i in params},
        initial={k: v for c in contributions for k, v in c["initial"].items()},
        order=max(c["order"] for c in contributions), ranks=tuple(ranks), stop=stop, arithmetic=arithmetic,
        decisions=len(escalations), undecided_decisions=undecided,
        error_bound=settler.error_bound + sum(g["error_bound"] for g in generic_rows),
        prime=graph_exact.PRIME, prob_threshold=prob_threshold, notes=tuple(notes),
        experiments=tuple(contributions) if many else (), generic_experiments=tuple(generic_rows))


def _notes(exps, verdict, coords, contributions, free, search):
    """What the verdicts rest on, in words."""
    notes = [f"not determined (proved at this initial state): {proof.text(coords.names)}, which keeps the "
             f"known initial values; {proof.how}" for proof in search.proofs]
    undecided = [coords.names[i] for i, v in verdict.items() if v is Verdict.UNDECIDED]
    if undecided:
        order = max(c["order"] for c in contributions)
        tried = f"; {search.tried}" if search.tried else ""
        notes.append(f"undecided ({', '.join(undecided)}): not determined by the output coefficients up to order "
                     f"{order}; at a specific initial state an order that adds nothing proves nothing and no order "
                     f"bound is known (raise max_order to look further){tried}")
    unused = sorted({p for ex in exps for p in unused_parameters(ex.system)})
    if unused:
        notes.append(unused_note(unused))
    inexact = [f"{k}{ex.suffix} = {v.text}" for ex in exps for k, v in ex.initial.items() if isinstance(v.value, float)]
    if inexact:
        notes.append(f"{', '.join(inexact)}: a constant known in float64 only (a non-rational function of "
                     "constants), so no decision that uses it is exact; give an exact value (a number, a fraction) "
                     "if that is what is meant (sin(pi) is 0)")
    if free:
        notes.append("unknown inputs: their derivatives at t = 0 are free unknowns of the Jacobian (an "
                     "analytic unknown input); 'determined' is proven, 'undecided' is not a proof")
    if any(ex.joint.known for ex in exps):
        notes.append("known inputs: generic (their derivatives at t = 0 drawn at random with the point, "
                     "covered by the probability bound)")
    return notes


__all__ = ["analyze_initial", "analyze_experiments", "generic_experiments", "default_max_order"]
