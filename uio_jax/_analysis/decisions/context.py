"""Shared machinery of the analyses: samples, memoized nodes, the growing codistribution.

Each recursion (ORC, single unknown input, EORC, general solution) is a Python loop over
steps m; inside a step the new candidate generators are evaluated in one call (numpy over
the System's expression graph) at the decision samples and pruned by
:class:`~uio_jax._analysis.decisions.rank.Codistribution`; the final span is certified on all
the samples (:meth:`Context.certify`).
"""

import dataclasses

import numpy as np

from ..._calculus.generators import Node, builder_for
from ..._engine import graph_exact
from ..._errors import ModelError
from ..._model.sampling import sample_states
from ..._model.smooth_inputs import known_coordinates
from ..results.evidence import Certificate, Escalation, Finding, Settlement, Step
from ..results.kinds import Arithmetic
from ..results.report import SEMANTICS, SEMANTICS_SMOOTH, Report
from .answer import decide_answer
from .memory import (
    CERTIFY_BYTES,
    DECISION_SAMPLES,
    certify_samples,
    check_resident,
    decision_count,
    screen_samples,
)
from .policy import DecisionPolicy
from .rank import Codistribution
from .settle import DEFAULT_PROB_THRESHOLD, model_roots, new_settler
from .space import Projection, SampledSpace, report_view, system_known

#: A report gets a note when more than this fraction of the sampled states was dropped
#: (NaN/inf there): the verdict is valid on the states kept, but past a tenth of the box the
#: model is undefined on a part of the domain the user should know the verdict does not cover.
DROPPED_NOTE_FRACTION = 0.10


class Context:
    """Samples, node builder and codistribution of one analysis of one System.

    Args:
        system: the System whose state the codistribution lives on.
        samples: number of sampled states S.
        seed: seed of the samples.
        rtol: rank tolerance.
        prob_threshold: the probability of correctness of the exact decisions
            (:class:`~uio_jax._analysis.decisions.settle.Settler`).
    """

    def __init__(self, system, samples, seed, rtol, prob_threshold=DEFAULT_PROB_THRESHOLD, settler=None):
        self.system = system
        self.builder = builder_for(system)
        self.samples = samples
        self.seed = seed
        #: one Settler per analysis (the plan's, where it made one), shared by its forks: each
        #: question is settled once, and the error bound is summed over all of them
        self.settler = new_settler(system, seed, prob_threshold) if settler is None else settler
        self.prob_threshold = prob_threshold
        xs_all = sample_states(system, samples, seed)
        exact = self.settler.arithmetic(model_roots(system, self.builder)) is Arithmetic.EXACT
        wanted = screen_samples(system.n) if exact else DECISION_SAMPLES
        #: ``(S,)``: the outputs and fields finite at each sample; where they are not, the
        #: sample is dropped, even where their gradients are finite (a NaN chosen by a ``where``)
        self.defined = self._defined(xs_all)
        self._start(xs_all, rtol, decision_count(self.defined, samples, system.n, wanted))

    def _defined(self, xs_all):
        """``(S,)``: whether the outputs and fields are finite at each sample."""
        nodes = [*self.output_nodes(), *(self.field_node(f) for f in self.system.fields())]
        values = self.builder.values(nodes, xs_all)
        return np.all([np.isfinite(v.reshape(len(xs_all), -1)).all(axis=1) for v in values], axis=0)

    def _start(self, xs_all, rtol, decisions):
        """Samples ``xs_all`` ``(S, n)``; the decision samples ``xs`` (the first
        ``decisions``, :func:`~uio_jax._analysis.decisions.memory.decision_count`) and an empty
        codistribution on them."""
        self.xs_all = xs_all
        self.decisions = decisions
        self.xs = xs_all[:decisions]
        self.certified = len(self.xs) == len(xs_all)
        lo, hi = self.system.box()
        self.codist = Codistribution(self.system.n, len(self.xs), hi - lo, rtol)
        self.codist.valid &= self.defined[:decisions]
        self.codist.policy = DecisionPolicy(self.settler.settle)  # every vote settled again in the graph
        self.memberships = []  # RankDecisions of membership tests (for the certificate)
        #: how the decisions outside the codistribution were settled (the general solution's
        #: zero tests: ``"exact mod p"``, ``"mpmath"``, ``""`` for a float64 vote)
        self.extra_decisions = []
        #: the final span was not re-decided on every sample: every decision was exact
        #: (:meth:`certify`)
        self.screen_only = False
        self._decided_before = (0, 0)  # acceptances, rejections at the last step()
        self._grads = {}  # Node -> (S, n) gradient at the samples

    def decided_exactly(self) -> bool:
        """Whether every decision so far (the span's, the memberships, those outside the
        span) was made modulo p (or is implied by a span of every direction)."""
        cd = self.codist
        decisions = cd.acceptances + cd.rejections + [d for _, d in self.memberships]
        return (all(d.settled in ("exact mod p", "implied") for d in decisions)
                and all(how == "exact mod p" for how in self.extra_decisions))

    def fork(self) -> "Context":
        """A fresh Context on the same samples (empty codistribution, no decisions) that
        shares this one's builder and gradient cache: a second span over the same states,
        e.g. a closure that may be discarded."""
        sub = Context.__new__(Context)
        sub.system, sub.builder, sub.samples = self.system, self.builder, self.samples
        sub.seed, sub.settler, sub.prob_threshold = self.seed, self.settler, self.prob_threshold
        sub.defined = self.defined
        sub._start(self.xs_all, self.codist.rtol, self.decisions)
        sub._grads = self._grads if not self.certified or sub.certified else {}
        return sub

    def certify(self, upto: int | None = None) -> None:
        """Decide the final span again at every sample (after the recursion).

        The kept generators are absorbed, in order, into a codistribution over all ``S``
        samples; a weak acceptance, or one that does not confirm the decision samples, is
        settled beyond float64 (undecided if that fails too). The recursion's other decisions
        keep their votes of the decision samples. Afterwards :attr:`codist` and :attr:`xs` are
        those of all the samples. A no-op when they already are and ``upto`` is None, and
        (``upto`` None) when every decision so far was made exactly (:meth:`decided_exactly`:
        the float64 votes were only a screen; :attr:`screen_only`).

        Args:
            upto: keep only the first ``upto`` generators (the span at an earlier step of
                the recursion, e.g. the last EORC order whose decisions are all certified).
        """
        if upto is None and not self.certified and self.decided_exactly():
            self.screen_only = True
            return
        if self.certified and upto is None:
            return
        phase, kept = self.codist, list(self.codist.nodes)[:upto]
        lo, hi = self.system.box()
        count = certify_samples(len(self.xs_all), self.system.n)
        full = Codistribution(self.system.n, count, hi - lo, phase.rtol)
        full.valid &= self.defined[:count]
        full.policy, full.record = phase.policy, phase.record.copy()
        decided, decided_on = self._grads, len(self.xs)  # gradients at the decision samples
        self.xs, self._grads, self.certified = self.xs_all[:count], {}, True
        self._grads.update(self._extended(kept, decided, decided_on))
        if kept:
            # a generator the decision samples kept: settled again if it does not rise here
            added = self.absorb_into(full, kept, expect_rise=True)
            for nd in kept:
                if nd not in added:
                    full.record.add(Escalation(
                        f"{nd.label} (kept on {len(phase.valid)} samples)",
                        f"dependent on the {count} certifying samples", Settlement.NONE, Finding.UNDECIDED,
                        detail=f"{count} samples", vote=Finding.DEPENDENT))
        full.rejections = phase.rejections + full.rejections
        self.codist = full

    def _extended(self, nodes, head, count) -> dict:
        """Gradients ``{node: (S, n)}`` at :attr:`xs` of the ``nodes`` whose gradients at its
        first ``count`` samples are in ``head`` (the decision samples are the first of the
        certifying ones): only the other samples are evaluated."""
        have = [nd for nd in dict.fromkeys(nodes) if nd in head]
        if not have or count >= len(self.xs):
            return {nd: head[nd][:len(self.xs)] for nd in have}
        tail = self.builder.gradients(have, self.xs[count:])
        return {nd: np.concatenate([head[nd], tail[:, i]]) for i, nd in enumerate(have)}

    def absorb_into(self, codist, nodes, expect_rise=False) -> list:
        """Absorb ``nodes`` into ``codist`` with their gradients at :attr:`xs`
        (``expect_rise``: :meth:`~uio_jax._analysis.decisions.rank.Codistribution.absorb`)."""
        grads = self.gradients(nodes)
        try:
            return codist.absorb(nodes, grads, expect_rise=expect_rise)
        except FloatingPointError:
            raise ModelError("the generators are NaN/inf at every sampled state: check the model "
                             "and its domain") from None

    def coordinates(self, count: int, n: int, meanwhile=None):
        """Which unit covectors lie in the span, and its dimension on the first ``n``
        coordinates, certified.

        ``e_1..e_count`` are tested once
        (:meth:`~uio_jax._analysis.decisions.rank.Codistribution.test_units`); the dimension
        ``dim = rank(Omega) + n - rank([Omega; e_1..e_n])`` absorbs ``e_1..e_n`` one by one into
        a copy of the span. Every decision is recorded in :attr:`memberships`. ``meanwhile()``
        is called once the memberships are known and the dimension must be computed.

        Returns:
            ``(members, dim)``: ``count`` booleans, and the dimension (``n`` when the first
            ``n`` are all members).
        """
        codist = self.codist
        known = codist.unit_members  # decided members at an earlier call: the span only grew
        todo = [i for i in range(count) if i not in known]
        tested = codist.test_units(count, only=todo)
        units = self.unit_nodes(count)
        results = codist.contains(None, tested, nodes=[units[i] for i in todo]) if todo else []
        self.memberships.extend(results)
        for i, (member, d) in zip(todo, results):
            if member and d.settled != "undecided":
                known[i] = d
        vote = {i: member for i, (member, _) in zip(todo, results)}
        members = [i in known or vote[i] for i in range(count)]
        if all(members[:n]):
            return members, n
        if meanwhile is not None:
            meanwhile()
        if codist.rank == 0:
            return members, 0
        fork = codist.copy(trial=True)  # discarded below
        # the members are dependent on the span itself: only the others can raise the rank
        at = [p for p, i in enumerate(todo) if i < n and not members[i]]
        added = fork.absorb([units[todo[p]] for p in at], None, tested.take(at))
        codist.record.merge(fork.record)  # the trial's decisions count in the certificate
        self.memberships += [(False, d) for d in fork.acceptances]
        self.memberships += [(True, d) for d in fork.rejections]
        return members, n - len(added)

    # -------------------------------------------------------------- decisions outside the span
    def decide_zero(self, exprs, float64_zero: bool) -> tuple[bool, str]:
        """Whether the graph nodes ``exprs`` vanish identically: the float64 vote
        ``float64_zero`` settled again (:meth:`~uio_jax._analysis.decisions.settle.Settler.vanishes`),
        recorded for the certificate. Returns ``(zero, how)``."""
        zero, how = self.settler.vanishes(exprs)
        self.extra_decisions.append(how)
        return (zero if how else float64_zero), how

    def decide_vector_rank(self, fields, float64_rank: int) -> int:
        """Generic rank of the vector fields ``fields`` (field Nodes): modulo p at the
        Settler's first point where the graph is made rational (its Schwartz-Zippel bound
        added), else the float64 ``float64_rank``; recorded for the certificate."""
        exprs = [e for f in fields for e in f.expr]
        values = self.settler.values_mod_p(exprs)
        if values is None:
            self.extra_decisions.append("")
            return float64_rank
        n = len(fields[0].expr) if fields else 0
        echelon = graph_exact.Echelon()
        for i in range(len(fields)):
            echelon.add(values[i * n:(i + 1) * n])
        self.settler.count_bound(exprs, 1, max(echelon.rank, 1))
        self.extra_decisions.append("exact mod p")
        return echelon.rank

    # -------------------------------------------------------------- nodes
    def unit_nodes(self, count: int) -> list[Node]:
        """The coordinate functions ``z_1..z_count`` as Nodes (labels ``e_i``), whose
        gradients are the unit covectors."""
        b = self.builder
        return [b.make(f"e_{i}", "scalar", 0, b.graph.coords[i]) for i in range(count)]

    def output_nodes(self) -> list[Node]:
        """The outputs ``h_i: x (n,) -> ()`` of the System as scalar nodes, in order."""
        return [self.builder.scalar(k, fn) for k, fn in self.system.outputs.items()]

    def field_node(self, label) -> Node:
        """The System's field ``label`` (``x (n,) -> (n,)``: the drift, a known or unknown
        input's field) as a field node."""
        return self.builder.field(label, self.system.fields()[label])

    @property
    def dim(self) -> int:
        """The generic rank of the codistribution so far (the number of kept generators)."""
        return self.codist.rank

    # -------------------------------------------------------------- evaluation
    def gradients(self, nodes) -> np.ndarray:
        """Gradients of scalar nodes at the samples, ``(S, c, n)`` (cached per node)."""
        nodes = list(nodes)
        missing = [nd for nd in dict.fromkeys(nodes) if nd not in self._grads]
        if missing:
            grads = self.builder.gradients(missing, self.xs)
            for i, nd in enumerate(missing):
                self._grads[nd] = grads[:, i]
        return np.stack([self._grads[nd] for nd in nodes], axis=1)

    def remember_gradients(self, nodes, grads) -> None:
        """Keep gradients ``(S, c, n)`` of ``nodes`` evaluated elsewhere (no re-evaluation)."""
        for i, nd in enumerate(nodes):
            self._grads.setdefault(nd, grads[:, i])

    def absorb(self, nodes, grads=None) -> list[Node]:
        """Keep the candidate nodes that raise the generic rank (the rejections of a step that
        keeps nothing settled exactly where the model is rational: ``confirm_empty`` of
        :meth:`~uio_jax._analysis.decisions.rank.Codistribution.absorb`).

        Args:
            nodes: scalar Nodes.
            grads: their gradients ``(S, c, n)`` if already evaluated.
        """
        nodes = list(nodes)
        if not nodes:
            return []
        check_resident(f"rank {self.dim} of {self.system.n} ({len(self.builder.graph)} graph nodes)")
        if grads is None:
            grads = self.gradients(nodes)
        try:
            return self.codist.absorb(nodes, grads, confirm_empty=True)
        except FloatingPointError:
            bad = [nd.label for i, nd in enumerate(nodes)
                   if not np.isfinite(grads[:, i]).any()]
            what = f"generator {bad[0]!r}" if bad else "the generators"
            raise ModelError(
                f"{what} is NaN/inf at every sampled state: check the model and its domain"
            ) from None

    def absorb_lie(self, phis, field_nodes) -> list[Node]:
        """Form every ``L_v phi`` (phi in ``phis``, v in ``field_nodes``) and absorb them."""
        nodes, grads = self.lie_block(phis, field_nodes)
        return self.absorb(nodes, grads)

    def lie_block(self, phis, field_nodes):
        """Nodes ``L_v phi`` and their gradients ``(S, c, n)`` (cached per node)."""
        nodes, grads = self.builder.lie_block(phis, field_nodes, self.xs)
        self.remember_gradients(nodes, grads)
        return nodes, grads

    def contains(self, covectors) -> list[bool]:
        """Membership of covector families ``(C, S, n)``; evidence goes to the certificate."""
        results = self.codist.contains(np.asarray(covectors))
        self.memberships.extend(results)
        return [member for member, _ in results]

    def contains_nodes(self, nodes) -> list[bool]:
        """Whether the gradients of scalar nodes lie in the span."""
        nodes = list(nodes)
        grads = self.gradients(nodes)
        results = self.codist.contains(np.moveaxis(grads, 1, 0), nodes=nodes)
        self.memberships.extend(results)
        return [member for member, _ in results]

    def observable_states(self) -> dict[str, bool]:
        """State name -> ``e_j`` in the span (one test of every unit covector)."""
        n = self.system.n
        results = self.codist.contains(None, self.codist.test_units(n), nodes=self.unit_nodes(n))
        self.memberships.extend(results)
        return dict(zip(self.system.states, [member for member, _ in results]))

    def step(self, m, added, **extra) -> Step:
        """A history entry for the current state of the codistribution (not announced: the
        recursion driver announces the steps it records, :func:`~uio_jax._analysis.recursions.driver.iterate`).

        ``Step.fraction`` is the smallest agreeing fraction among the rank decisions taken
        since the previous step (candidates kept and rejected; 1.0 if none): evidence for
        free, where an SVD of the whole span at every step would cost ``O(S r^2 n)``.
        """
        cd = self.codist
        a, r = self._decided_before
        decided = cd.acceptances[a:] + cd.rejections[r:]
        self._decided_before = (len(cd.acceptances), len(cd.rejections))
        fraction = min((d.fraction for d in decided), default=1.0)
        return Step(m, self.dim, tuple(nd.label for nd in added), fraction, extra)

    # -------------------------------------------------------------- results
    def certificate(self) -> Certificate:
        """The evidence of every rank decision of the analysis: the final span's SVD
        (:meth:`~uio_jax._analysis.decisions.rank.Codistribution.decision`), the kept candidates and
        the non-members (counted), the rejected candidates and the members (pruned)."""
        cd = self.codist
        final = cd.decision()
        counted = cd.acceptances + [d for m, d in self.memberships if not m]
        pruned = cd.rejections + [d for m, d in self.memberships if m]
        everything = counted + pruned
        # the float64 evidence: decisions settled beyond float64 are certified by their
        # escalation (recorded apart), not by their float64 vote and margins
        def plain(d):
            return d.settled in ("", "undecided")

        used = int(cd.valid.sum())
        certifying = len(cd.valid)
        how = [d.settled for d in everything if d.settled != "implied"] + list(self.extra_decisions)
        return Certificate(
            samples=self.samples,
            used=used,
            dropped=certifying - used,
            capped=self.samples - certifying,
            fraction=final.fraction,
            min_fraction=min((d.fraction for d in everything if plain(d)), default=1.0),
            sigma_r_min=min((d.sigma_r_min for d in counted if plain(d)), default=1.0),
            conditioning=final.sigma_r_min,
            sigma_next_max=max((d.sigma_next_max for d in pruned if plain(d)), default=0.0),
            rtol=cd.rtol,
            decisions=len(everything),
            escalations=tuple(cd.record.escalations),
            verified=cd.record.verified,
            closure_verified=cd.record.closure_verified,
            rejections_verified=cd.record.rejections_verified,
            exact_decisions=how.count("exact mod p"),
            extended_decisions=how.count("mpmath"),
            float64_decisions=len(how) - how.count("exact mod p") - how.count("mpmath"),
            error_bound=self.settler.error_bound,
            prime=graph_exact.PRIME,
            prob_threshold=self.prob_threshold,
            screen_only=self.screen_only,
        )

    def report(self, method, history, stop, *, notes=(), details=None, projection: Projection | None = None,
               known_inputs="switchable") -> Report:
        """Build the Report: certificate, weak-certificate note, generators, the answer.

        ``projection`` (:class:`~uio_jax._analysis.decisions.space.Projection`): the span's
        answer on the original state where it lives on more coordinates; default this
        context's own, without the known coordinates (the time of :meth:`System.autonomous`).
        ``known_inputs``: the meaning of the known inputs (``"none"`` when the System has none).
        """
        self.certify()
        own = self.system
        known = known_coordinates(own)
        if projection is None and known:
            n = own.n - known
            members, dim = self.coordinates(own.n, n)
            projection = Projection(report_view(own, n), dim, dict(zip(own.states[:n], members[:n])),
                                    SampledSpace(self, n=n, dim=dim))
            history = [dataclasses.replace(st, dim=st.dim - known) for st in history]
        if projection is None:
            projection = Projection(own, self.dim, self.observable_states(), SampledSpace(self))
        system = projection.view
        notes = list(system.notes) + list(notes)
        cert = self.certificate()
        certifying = cert.samples - cert.capped
        if cert.dropped > DROPPED_NOTE_FRACTION * certifying:
            notes.append(
                f"{cert.dropped} of {certifying} sampled states "
                f"({100 * cert.dropped / certifying:.0f} %) were dropped: the model is NaN/inf there"
            )
        if cert.capped and not self.screen_only:
            r, N = self.codist.rank, self.system.n
            exact = f"; {cert.verified} rank increases were verified exactly" if cert.verified else ""
            notes.append(
                f"the final span ({r} generators on {N} coordinates) was certified on the first "
                f"{certifying} of the {cert.samples} samples, where its arrays ({N} x {N} per "
                f"sample) fit in {CERTIFY_BYTES / 2**20:.0f} MiB{exact}")
        if cert.undecided:
            what = "; ".join(f"{e.what}: {e.how_text}" for e in cert.escalations if e.result is Finding.UNDECIDED)
            notes.append(
                f"UNDECIDED: {cert.undecided} rank decision{'s' if cert.undecided > 1 else ''} could "
                f"not be settled, in float64 nor beyond ({what}); the verdicts rest on the float64 "
                "majority and are not certified")
        if cert.min_fraction < 0.5:
            notes.append(
                f"weak certificate: a rank decision was backed by only "
                f"{100 * cert.min_fraction:.0f}% of the samples; try more samples or a "
                "smaller domain away from singular states"
            )
        details = details or {}
        return Report(
            method=method,
            states=system.states,
            dim=projection.dim,
            observable=projection.observable,
            history=tuple(history),
            certificate=cert,
            generators=tuple(nd.label for nd in self.codist.nodes),
            stop=stop,
            answer=decide_answer(method, stop, details, cert.arithmetic),
            notes=tuple(notes),
            details=details,
            system_name=system.name,
            params=system.joint_param_names,
            known_inputs=known_inputs if own.known or system_known(system) else "none",
            semantics=SEMANTICS_SMOOTH if known_inputs == "smooth" else SEMANTICS,
            space=projection.space,
        )
