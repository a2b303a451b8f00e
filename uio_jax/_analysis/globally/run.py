"""The global question, from a System to a :class:`~.result.GlobalResult` (the docs: docs/global.md).

1. Refuse what SIAN's theorem does not cover (unknown inputs, explicit time, a non-rational
   model): one line each.
2. The local test at ``t = 0`` (:func:`uio_jax._analysis.identifiability.analyze_initial`, the
   project's exact rank decisions): which unknowns are locally identifiable, which are proved
   not, and the order ``K`` where the rank stopped growing.
3. SIAN's truncated system at ``beta = K + 1`` orders per output (:mod:`.truncation`), a random
   point with SIAN's bound (:mod:`.sample`), the fibre made zero-dimensional (:mod:`.fibre`).
4. msolve's parametrisation of the solutions modulo a prime (:mod:`.msolve`), read by
   :mod:`.values`: one value ("global") or the count ("local"), and the simple symmetries.

The error bound splits ``1 - prob_threshold``: a quarter to the local test's decisions, a
quarter to the functions' membership decisions, a half to SIAN's random point. The reduction
modulo the prime is correct for all but finitely many primes, not bounded a priori (said in
the notes).
"""

import math
import random
import sys
import time
from fractions import Fraction

from ..._errors import OptionError
from ..._model.system import System
from ..._progress import CountProgress, is_terminal
from ..at_t0.identifiability import analyze_initial
from ..at_t0.initial import check_initial
from ..decisions.settle import DEFAULT_PROB_THRESHOLD
from ..results.evidence import Finding
from ..results.identifiability_report import StopKind
from ..results.kinds import Verdict
from .fibre import Fibre
from .functions import check_functions, function_nodes, local_functions
from .jets import ModelEquations, flint_module, refuse_unsupported
from .msolve import require_msolve, run_msolve
from .result import GlobalResult, GlobalVerdict
from .sample import Point, draw_prime, sample_range, sian_degree
from .truncation import truncate
from .values import SolutionSet, symmetry

#: Default seconds msolve may take.
DEFAULT_TIMEOUT = 600.0

#: Powers tried when counting the values of one unknown (past it: "local", count unknown).
COUNT_CAP = 512

#: Primes tried when one divides a denominator or makes the point singular.
PRIME_TRIES = 5


def global_identifiability(system: System, *, initial=None, seed: int = 0,
                           prob_threshold: float = DEFAULT_PROB_THRESHOLD, timeout: float = DEFAULT_TIMEOUT,
                           memory_gb: float | None = None, max_order: int | None = None,
                           progress: bool | None = None, functions=None) -> GlobalResult:
    """How many values each unknown of ``system`` can take given its output: global identifiability.

    For every parameter and every unknown initial state ``theta_j``: ``"global"`` when generic
    outputs determine one value, ``"local"`` when finitely many (``value_counts`` says how
    many, over the complex numbers), ``"not"`` when infinitely many, ``"undecided"`` when a
    limit was hit (``undecided_reason``). SIAN's algorithm (Hong, Ovchinnikov, Pogudin, Yap
    2019) on the output's Taylor coefficients at ``t = 0``, solved modulo a prime by msolve.

    Args:
        system: a rational :class:`~uio_jax.System` with known inputs only.
        initial: known initial states ``{state: value}`` (a number, a parameter name, a
            function of the parameters), as for :func:`uio_jax.analyze`; they enter the
            equations, and the answer holds for generic values of the other unknowns.
        seed: seed of the random point and the prime.
        prob_threshold: the probability of correctness asked for (the local decisions and the
            random point share ``1 - prob_threshold``).
        timeout: seconds msolve may take (then the locally identifiable unknowns are
            undecided, with the reason).
        memory_gb: address-space limit of msolve in GiB (None: none).
        max_order: highest order of the local test (default: the local test's).
        progress: show the solve's running time on stderr (None: on a terminal).
        functions: ``{name: f}``, functions of the unknowns asked about too (``f`` takes the
            arguments of the System's outputs, ``(x, p)`` with parameters, and reads the
            initial state in ``x``): ``{"ab": lambda x, p: p[0] * p[1]}``.

    Returns:
        :class:`GlobalResult`.

    Raises:
        OptionError: unknown inputs, explicit time, a bad ``initial`` or option, or the
            optional extra missing (one line).
        ModelError: a model that is not rational (the expression named).
    """
    checked, functions, nodes = check_global(system, initial, seed=seed, prob_threshold=prob_threshold,
                                             timeout=timeout, memory_gb=memory_gb, functions=functions)
    eps = 1.0 - prob_threshold
    t0 = time.perf_counter()
    local = analyze_initial(system, dict(initial or {}), seed=seed, prob_threshold=1.0 - eps / 4,
                            max_order=max_order)
    verdicts = {**dict(local.observable), **dict(local.identifiable)}
    order = _rank_order(local.ranks)
    closed = local.stop is not StopKind.MAX_ORDER
    f_outcomes, f_bound = local_functions(system, checked, functions, local.order, seed, 1.0 - eps / 4, closed)
    verdicts.update({name: _FROM_OUTCOME[o] for name, o in f_outcomes.items()})
    seconds = {"local": time.perf_counter() - t0}
    run = _Run(system, checked, verdicts, order, local, eps, seed, seconds, nodes, f_bound)
    return run.answer(timeout, None if memory_gb is None else int(memory_gb * 2**30), progress)


def check_global(system, initial=None, *, seed=0, prob_threshold=DEFAULT_PROB_THRESHOLD, timeout=DEFAULT_TIMEOUT,
                 memory_gb=None, functions=None):
    """Everything :func:`global_identifiability` refuses, checked before any work (one line
    each): the options, unknown inputs and explicit time, the optional extra, a bad
    ``initial`` or ``functions``, a model that is not rational. Returns ``(checked initial,
    checked functions, their graph nodes)``."""
    _check_options(system, seed, prob_threshold, timeout, memory_gb)
    refuse_unsupported(system)
    flint_module()
    require_msolve()
    checked = check_initial(system, initial) if initial else {}
    functions = check_functions(system, functions)
    nodes = function_nodes(system, functions)
    ModelEquations(system, 1, nodes)  # a non-rational model is refused before any work
    return checked, functions, nodes


def _check_options(system, seed, prob_threshold, timeout, memory_gb):
    if not isinstance(system, System):
        raise OptionError(f"global identifiability takes a uio_jax.System, got {type(system).__name__}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise OptionError(f"seed must be a non-negative integer, got {seed!r}")
    if isinstance(prob_threshold, bool) or not isinstance(prob_threshold, (int, float)) or \
            not 0.0 < float(prob_threshold) < 1.0:
        raise OptionError(f"prob_threshold must be a number in (0, 1), got {prob_threshold!r}")
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not float(timeout) > 0 or \
            not math.isfinite(float(timeout)):
        raise OptionError(f"timeout must be a positive number of seconds, got {timeout!r}")
    if memory_gb is not None and (isinstance(memory_gb, bool) or not isinstance(memory_gb, (int, float))
                                  or not float(memory_gb) > 0):
        raise OptionError(f"memory_gb must be a positive number of GiB, got {memory_gb!r}")


#: A function's local membership decision as the local test's verdict.
_FROM_OUTCOME = {Finding.DEPENDENT: Verdict.DETERMINED, Finding.INDEPENDENT: Verdict.NOT_DETERMINED,
                 Finding.UNDECIDED: Verdict.UNDECIDED}


def _rank_order(ranks) -> int:
    """The last order at which the rank grew (0 when it never did)."""
    last, prev = 0, 0
    for k, r in enumerate(ranks):
        if r > prev:
            last, prev = k, r
    return last


class _Run:
    """One global question after the local test."""

    def __init__(self, system, checked, verdicts, order, local, eps, seed, seconds, nodes, function_bound):
        self.system, self.checked, self.verdicts, self.order = system, checked, verdicts, order
        self.local, self.eps, self.seed, self.seconds = local, eps, seed, seconds
        self.nodes, self.function_bound = nodes, function_bound
        self.states = tuple(local.states)
        self.params = tuple(local.params)
        self.functions = tuple(nodes)
        self.unknowns = list(self.states) + list(self.params)
        self.asked = self.unknowns + list(self.functions)
        self.determined = [u for u in self.asked if verdicts[u] is Verdict.DETERMINED]

    def answer(self, timeout, memory_bytes, progress) -> GlobalResult:
        """Build, solve and read; a limit or a failure makes the determined unknowns undecided."""
        if not self.determined:
            return self._result({}, None, [], [], None, 0.0, None)
        t0 = time.perf_counter()
        eqs = ModelEquations(self.system, self.order + 4, self.nodes)
        known = {s: self._known(eqs, v) for s, v in self.checked.items()}
        beta = {y: self.order + 1 for y in eqs.outputs}
        trunc = truncate(eqs, beta, known)
        for k, name in enumerate(eqs.functions):
            trunc.polys.append(eqs.function_equation(k))
            trunc.labels.append(f"function {name}")
        degree = sian_degree(trunc, eqs, len(self.determined))
        D = sample_range(degree, self.eps / 2)
        point_bound = float(Fraction(degree, D + 1))
        rng = random.Random(self.seed)
        upto = {**trunc.orders, **trunc.max_state_order}
        point = None
        for _ in range(PRIME_TRIES):
            try:
                point = Point(eqs, draw_prime(rng), known, upto, rng, D)
                break
            except ArithmeticError:
                continue
        if point is None:
            return self._result({}, None, [], [], "no prime and point kept the model defined", point_bound, None)
        candidates = [u for u in self.unknowns if u not in self.determined]
        fibre = Fibre(point, trunc.polys, candidates)
        self.seconds["build"] = time.perf_counter() - t0
        if not fibre.full_rank:
            return self._result({}, None, [], fibre.fixed, "the specialised system could not be made "
                                "zero-dimensional at the point drawn", point_bound, point.p)
        solved = self._solve(fibre.msolve_input(self.unknowns, rng), timeout, memory_bytes, progress)
        if solved.parametrisation is None:
            return self._result({}, None, [], fibre.fixed, solved.reason, point_bound, point.p)
        return self._read(solved.parametrisation, point, fibre, point_bound)

    def _known(self, eqs, value):
        v = value.value
        if isinstance(v, (Fraction, str)):
            return v
        ns = len(self.system.states)
        builder = eqs.builder
        expr = builder.function(f"initial value of {value.state}", lambda z: v(z[ns:])).expr
        return eqs.fractions.of([expr])[0]

    def _solve(self, text, timeout, memory_bytes, progress):
        shown = is_terminal(sys.stderr) if progress is None else bool(progress)
        bar = CountProgress(1, enabled=shown, label="global", delay=2.0)
        bar.start("msolve", key=0)
        try:
            solved = run_msolve(text, timeout=timeout, memory_bytes=memory_bytes)
        finally:
            bar.finish("msolve", key=0)
            bar.close()
        self.seconds["solve"] = solved.seconds
        return solved

    def _read(self, param, point, fibre, point_bound):
        ring = point.eqs.ring
        names = {f"v{i}": ring.labels[i] for i in range(len(ring.labels))}
        solutions = SolutionSet(param, names)
        truth = {u: point.values[ring.index[(u, 0)]] for u in self.unknowns}
        asked = {ring.labels[ring.index[(u, 0)]]: u for u in self.asked}
        solutions.element = {asked.get(k, k): e for k, e in solutions.element.items()}
        # the unknowns the solve has: those fixed at their drawn values, and those that enter
        # no equation (a parameter multiplied by 0), are not among its variables
        truth = {u: v for u, v in truth.items() if u in solutions.element}
        if not solutions.squarefree or not solutions.contains(truth):
            return self._result({}, None, [], fibre.fixed, "msolve's solutions do not contain the point drawn "
                                "(an unlucky prime, or an answer this reader does not understand)", point_bound,
                                point.p)
        counts = {u: solutions.count(u, COUNT_CAP) for u in self.determined}
        found, kinds = [], []
        for sol in solutions.rational_solutions(list(truth)):
            sym = symmetry(truth, sol, point.p)
            if sym is not None and sym.text not in found:
                found.append(sym.text)
                kinds.append(sym.kind)
        return self._result(counts, solutions.degree, list(zip(found, kinds)), fibre.fixed, None, point_bound,
                            point.p)

    def _result(self, counts, solution_count, symmetries, fixed, reason, point_bound, prime) -> GlobalResult:
        verdict, value_counts = {}, {}
        for u in self.asked:
            local = self.verdicts[u]
            if local is Verdict.NOT_DETERMINED:
                verdict[u] = GlobalVerdict.NOT
            elif local is Verdict.UNDECIDED:
                verdict[u] = GlobalVerdict.UNDECIDED
            elif counts.get(u) is None:
                verdict[u] = GlobalVerdict.UNDECIDED if u not in counts else GlobalVerdict.LOCAL
            else:
                verdict[u] = GlobalVerdict.GLOBAL if counts[u] == 1 else GlobalVerdict.LOCAL
                value_counts[u] = counts[u]
        if any(v is Verdict.UNDECIDED for v in self.verdicts.values()):
            reason = "; ".join(r for r in (reason, f"the local test did not decide every unknown by order "
                                          f"{self.local.order}") if r)
        return GlobalResult(
            system_name=self.system.name, states=self.states, params=self.params, functions=self.functions,
            global_identifiability=verdict,
            value_counts=value_counts, solution_count=solution_count,
            symmetries=tuple(s for s, _ in symmetries), symmetry_kinds=tuple(k for _, k in symmetries),
            specialised=tuple(fixed), initial=dict(self.local.initial), order=self.order,
            error_bound=self.local.error_bound + self.function_bound + point_bound, point_bound=point_bound,
            local_error_bound=self.local.error_bound + self.function_bound, prime=prime, prob_threshold=1.0 - self.eps,
            undecided_reason=reason, seconds=self.seconds, notes=tuple(self._notes(fixed, prime)))

    def _notes(self, fixed, prime):
        notes = []
        if prime:
            notes.append(f"solved modulo the prime {prime}: the answer over the rationals for all but finitely many "
                         "primes, a set not bounded a priori (as SIAN's p_mod); the error bound covers the local "
                         "test and the random point")
        notes.append("counts are over the complex numbers at generic values of the unknowns: a value outside the "
                     "domain, or complex, counts too")
        if fixed:
            notes.append("the not-identifiable unknowns fixed at their drawn values are algebraically independent "
                         "over the outputs: fixing them keeps every count")
        if self.checked:
            notes.append("known initial states enter the equations exactly; the verdicts hold for generic values "
                         "of the parameters and of the other initial states")
        if self.system.known:
            notes.append("known inputs: generic (their derivatives at t = 0 drawn with the point)")
        return notes


__all__ = ["global_identifiability", "DEFAULT_TIMEOUT"]
