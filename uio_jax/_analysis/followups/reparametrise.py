"""A reparametrised model whose parameters are all identifiable (``Report.reparametrised_model``).

When some parameters are not identifiable, the unobservable directions move them: a group
of transformations of states and parameters leaves the outputs unchanged. Fixing the
parameters ``S`` of a **cross-section** of that group loses no output behaviour near the
section: let ``V`` be the unobservable directions and ``t`` the generic rank of their
components on all parameters. Choose ``S`` (``|S| = t``) with ``V_S`` of rank ``t`` at a
random point, then values ``p_S = v`` such that ``V_S`` still has rank ``t`` **at the
section** ``{p_S = v}``: checked exactly modulo ``p = 2^127 - 1`` at a random point of the
section itself (the kept generators evaluated there at full rank, so that ``V`` there is the
true kernel; a rank ``t`` at one such point holds on a dense open part of the section). Then

* the section is transversal to the orbits there, so the model with ``p_S = v`` has the
  observable dimension of the original (its codistribution is the original one with the
  columns of ``S`` dropped, of rank ``N - dim V`` again) on ``t`` fewer coordinates: no
  identifiable combination is lost;
* a direction that keeps ``S`` fixed keeps every parameter fixed (``V_S`` and ``V_P`` have
  the same rank), so every parameter left is identifiable.

A choice that is right at a random point need not be right at the values chosen: for
``x' = -(a b + c) x`` fixing ``b = 0`` makes the section tangent to the scaling
``(a, b) -> (l a, b / l)`` and loses ``a b + c``; the check at the section rejects it and
the next values are tried (``b = 1``).

The values tried, per fixed parameter: 0 where a verified symmetry translates it, 1 where
one scales it (``p -> l p``), then 1, 2, the centre of its box, -1, 1/2 and two random
fractions (a random value is transversal unless it lies on a proper subvariety). **Every
output of the original model is an output of this one** where each fixed value is reached
along the flow of a verified symmetry (found, polynomial of degree <= 1: its flow is defined
for all time) that leaves the parameters fixed before it alone: a translation reaches the
value from every value, a scaling from every value of the same sign (the condition is
stated). Otherwise the claim is local: the fixed model represents the parameter values
whose orbit meets the section (``x' = -(a^2 + b^2) x`` at ``b = 1``: those with
``a^2 + b^2`` a value that ``a^2 + 1`` takes), and the note says so with the identifiable
combinations that decide it.

The model is written in the model-file schema (:func:`uio_jax.save_model` writes it as
TOML): outputs and fields printed from the expression graph in the model's names
(:mod:`.expression_text`), the fixed parameters substituted as exact numbers.
"""

import dataclasses
import itertools
import re
from fractions import Fraction

import numpy as np

from ..._engine import graph_exact
from ..._engine.graph import Graph
from . import ansatz
from .expression_text import Printer

#: Most sets of values checked at the section before giving up.
MAX_TRIES = 64


@dataclasses.dataclass(frozen=True)
class Section:
    """The fixed parameters of a cross-section.

    Attributes:
        values: ``{coordinate index: Fraction}``, transversal to the orbits there (checked).
        reached: ``{coordinate index: how every orbit reaches the value}`` for the values
            reached along a verified symmetry; the others hold locally only.
    """

    values: dict
    reached: dict

    @property
    def is_global(self) -> bool:
        """Whether every fixed value is reached along a verified symmetry."""
        return set(self.reached) == set(self.values)


def cross_section(parts, params, symmetries, seed: int = 1) -> Section | None:
    """The parameters to fix and their values (module docstring), or None when the kept
    generators cannot be evaluated at any point (no exact arithmetic).

    Args:
        parts: the final codistribution (:class:`~uio_jax._analysis.space.SpanParts`).
        params: the names of the parameters that are not identifiable.
        symmetries: the report's :class:`~uio_jax._analysis.found_symmetries.FoundSymmetries`.
        seed: seed of the points.
    """
    kept = [nd.expr for nd in parts.nodes]
    point = ansatz.ModularSpan(parts.builder.graph, kept, seed=seed).point(0)
    if point is None:
        return None
    idx = [parts.names.index(p) for p in params]
    total = _rank(point.V, idx)
    chosen, ech = [], graph_exact.Echelon()
    for i in reversed(idx):  # the last parameters first
        if len(chosen) == total:
            break
        if ech.add([v[i] for v in point.V]):
            chosen.append(i)
    chosen.sort()
    if not chosen:
        return Section({}, {})
    rng = np.random.default_rng([int(seed), 0x5EC7])
    options = [_candidate_values(parts, i, symmetries, rng) for i in chosen]
    combos = sorted(itertools.product(*[range(len(o)) for o in options]), key=lambda c: (sum(c), c))
    for tries, combo in enumerate(combos[:MAX_TRIES]):
        values = {i: options[k][c] for k, (i, c) in enumerate(zip(chosen, combo))}
        at = ansatz.ModularSpan(parts.builder.graph, kept, seed=seed + 1 + tries, fixed=values).point(0)
        if at is not None and _rank(at.V, chosen) == total:
            return Section(values, _reached(parts, values, symmetries))
    return None


def _rank(V, idx) -> int:
    """Rank modulo p of the directions' components on the coordinates ``idx``."""
    return graph_exact.rank_mod_p([[v[i] for v in V] for i in idx]) if V and idx else 0


def _candidate_values(parts, i, symmetries, rng) -> list:
    """The values tried for coordinate ``i``, the simplest first (module docstring)."""
    name = parts.names[i]
    lo, hi = parts.box
    out = []
    for f in symmetries.fields:
        kind = _component_kind(f.components.get(name), name)
        if kind and kind[0] == "translation":
            out.append(Fraction(0))
        elif kind and kind[0] == "scaling":
            out.append(Fraction(1))
    centre = Fraction(str(round(0.5 * (float(lo[i]) + float(hi[i])), 3)))
    out += [Fraction(1), Fraction(2), centre, Fraction(-1), Fraction(1, 2)]
    out += [Fraction(int(rng.integers(1, 1000)), int(rng.integers(1, 1000))) for _ in range(2)]
    return list(dict.fromkeys(out))


_TERM = re.compile(r"^(-?)(?:(\d+)\*)?([A-Za-z_][A-Za-z_0-9]*|\d+)$")


def _component_kind(text, name):
    """``("translation", c)`` for a nonzero constant component ``c``, ``("scaling", k)`` for
    ``k * name``, else None (a found field's component text, :mod:`.found_symmetries`)."""
    if not text:
        return None
    m = _TERM.match(text.replace(" ", ""))
    if m is None:
        return None
    sign, factor, body = m.groups()
    s = -1 if sign else 1
    if body.isdigit():
        return ("translation", s * int(body) * int(factor or 1)) if int(body) else None
    return ("scaling", s * int(factor or 1)) if body == name else None


def _reached(parts, values, symmetries) -> dict:
    """``{index: text}`` of the fixed values reached along a verified symmetry from every
    value (translation) or every value of the same sign (scaling), each field leaving the
    parameters fixed before it alone (then the flows, applied in turn, reach the section)."""
    names = parts.names
    done, out = [], {}
    remaining = list(values)
    while remaining:
        for i in remaining:
            field = kind = None
            for f in symmetries.fields:
                kind = _component_kind(f.components.get(names[i]), names[i])
                if kind and not any(names[d] in f.components for d in done) and (
                        kind[0] == "translation" or values[i] != 0):
                    field = f
                    break
            if field is not None:
                break
        else:
            return out
        v = values[i]
        if kind[0] == "translation":
            out[i] = f"{names[i]} = {v} from every {names[i]} (along the verified {field.text()})"
        else:
            sign = ">" if v > 0 else "<"
            out[i] = f"{names[i]} = {v} from every {names[i]} {sign} 0 (along the verified {field.text()})"
        done.append(i)
        remaining.remove(i)
    return out


def _note(parts, section, combinations) -> str:
    """The note of the reparametrised model: what was fixed, why, and how far it holds."""
    names = parts.names
    fixed = ", ".join(f"{names[i]} = {v}" for i, v in section.values.items())
    head = (f"fixed: {fixed} (a cross-section of the unobservable directions, transversal to them at these "
            "values: checked exactly modulo p at a random point of the section, so the observable dimension "
            "is the original's and every parameter here is identifiable)")
    reached = "; ".join(section.reached[i] for i in section.values if i in section.reached)
    if section.is_global:
        return (head + "; every output of the original model is an output of this one: each fixed value is "
                f"reached along a symmetry, {reached} (where the model is defined along the way)")
    local = [i for i in section.values if i not in section.reached]
    which = ", ".join(f"{names[i]} = {section.values[i]}" for i in local)
    decided = (f", i.e. whose identifiable combinations {', '.join(combinations)} take values they take there"
               if combinations else "")
    return (head + f"; only locally right for {which}: an output of the original model is an output of this "
            f"one when its parameters' unobservable orbit meets the section (near the section it does{decided}), "
            "not proved for the others" + (f"; {reached}" if reached else ""))


def reparametrised_model(parts, report, symmetries) -> dict:
    """The model-file dictionary of the reparametrised model (see the module docstring).

    Args:
        parts: the final codistribution (:class:`~uio_jax._analysis.decisions.space.SpanParts`) of a
            report on a model with parameters, analysed on ``[x; p]``.
        report: the Report (names, verdicts).
        symmetries: its :class:`~uio_jax._analysis.followups.found_symmetries.FoundSymmetries`.

    Returns:
        ``{"name", "notes", "states", "params", "outputs", "drift", "known", "unknown"}``; the
        notes say which parameters were fixed, that the section was checked there, and how far
        the fixed model represents the original.

    Raises:
        ValueError: a function of the model has no text (a comparison, ``select``), or no
            values transversal to the orbits were found.
    """
    params = [p for p in report.params if not report.identifiable[p]]
    section = cross_section(parts, params, symmetries)
    if section is None:
        raise ValueError("no cross-section transversal to the unobservable directions was found at the values "
                         f"tried (at most {MAX_TRIES} sets, checked exactly at each)")
    values = section.values
    system, builder = parts.system, parts.builder
    graph = builder.graph
    fixed = Graph(graph.n)  # the model's functions with the fixed values substituted, folded
    coord_map = [fixed.const(values[i]) if i in values else fixed.x(i) for i in range(graph.n)]
    printer = Printer(fixed, parts.names, cap=100_000)
    n_states = len(report.states)

    def text(node):
        t = printer.text(fixed.import_nodes(graph, [node], coord_map)[0])
        if t is None:
            raise ValueError("a function of the model has no expression text")
        return t

    def field_table(label, fn):
        exprs = builder.field(label, fn).expr
        return {report.states[i]: text(e) for i, e in enumerate(exprs[:n_states]) if e != graph.zero}

    outputs = {k: text(builder.scalar(k, fn).expr) for k, fn in system.outputs.items()}
    kept = [p for p in report.params if parts.names.index(p) not in values]
    combinations = () if section.is_global else tuple(
        f.text for f in report.named_functions.of_only(report.params))
    lo, hi = parts.box
    data = {"name": f"{report.system_name or 'model'} (reparametrised)",
            "notes": [_note(parts, section, combinations)],
            "states": list(report.states),
            "params": {p: [float(lo[parts.names.index(p)]), float(hi[parts.names.index(p)])] for p in kept},
            "domain": {s: [float(lo[i]), float(hi[i])] for i, s in enumerate(report.states)},
            "outputs": outputs}
    if system.drift is not None:
        data["drift"] = field_table("drift", system.drift)
    for kind in ("known", "unknown"):
        tables = {k: field_table(k, fn) for k, fn in getattr(system, kind).items()}
        if tables:
            data[kind] = tables
    return data


__all__ = ["Section", "cross_section", "reparametrised_model", "MAX_TRIES"]
