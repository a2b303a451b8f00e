"""A reparametrised model whose parameters are all identifiable (``Report.reparametrised_model``).

When some parameters are not identifiable, the unobservable directions move them: a group
of transformations of states and parameters leaves the outputs unchanged. Fixing the
parameters of a **cross-section** of that group loses no output behaviour: choose non-identifiable
parameters ``S`` such that the unobservable directions' components on ``S`` have the rank of
their components on all parameters (at a random point modulo ``p``, :mod:`.ansatz`); then a
direction that keeps ``S`` fixed keeps every parameter fixed, so in the model with ``S`` fixed
every remaining parameter is identifiable, and every orbit meets the section (locally), so
every output of the original model is an output of the fixed one. A fixed parameter takes 0
when a verified symmetry translates it, 1 when one scales it (``p -> l p``), else the centre
of its box; the remaining parameters then stand for the identifiable combinations (for
``x' = -(a + b) x``, fixing ``b = 0`` leaves ``a``, which stands for ``a + b``).

The model is written in the model-file schema (:func:`uio_jax.save_model` writes it as
TOML): outputs and fields printed from the expression graph in the model's names
(:mod:`.expression_text`), the fixed parameters as numbers.
"""

from ..._engine import graph_exact
from . import ansatz
from .expression_text import Printer


def cross_section(parts, params) -> list:
    """The parameters to fix: indices into ``parts.names`` (greedy, last parameters first,
    each kept when it raises the rank of the unobservable directions' components)."""
    span = ansatz.ModularSpan(parts.builder.graph, [nd.expr for nd in parts.nodes], seed=1)
    point = span.point(0)
    if point is None:
        return []
    idx = [parts.names.index(p) for p in params]
    total = graph_exact.rank_mod_p([[v[i] for v in point.V] for i in idx]) if point.V else 0
    chosen, ech = [], graph_exact.Echelon()
    for i in reversed(idx):
        if len(chosen) == total:
            break
        if ech.add([v[i] for v in point.V]):
            chosen.append(i)
    return sorted(chosen)


def fixed_values(parts, chosen, symmetries) -> dict:
    """``{index: value}``: 0 for a translated parameter, 1 for a scaled one, else the centre."""
    lo, hi = parts.box
    out = {}
    for i in chosen:
        name = parts.names[i]
        comps = [f.components.get(name) for f in symmetries.fields if f.components.get(name)]
        if any(c.lstrip("-").isdigit() for c in comps):
            out[i] = 0
        elif any(c.lstrip("-").split("*")[-1] == name for c in comps):
            out[i] = 1
        else:
            out[i] = round(0.5 * (float(lo[i]) + float(hi[i])), 6)
    return out


def reparametrised_model(parts, report, symmetries) -> dict:
    """The model-file dictionary of the reparametrised model (see the module docstring).

    Args:
        parts: the final codistribution (:class:`~uio_jax._analysis.decisions.space.SpanParts`) of a
            report on a model with parameters, analysed on ``[x; p]``.
        report: the Report (names, verdicts).
        symmetries: its :class:`~uio_jax._analysis.followups.found_symmetries.FoundSymmetries`.

    Returns:
        ``{"name", "notes", "states", "params", "outputs", "drift", "known", "unknown"}``; the
        notes say which parameters were fixed and which combinations the others stand for.

    Raises:
        ValueError: a function of the model has no text (a comparison, ``select``).
    """
    params = [p for p in report.params if not report.identifiable[p]]
    chosen = cross_section(parts, params)
    values = fixed_values(parts, chosen, symmetries)
    names = [str(values[i]) if i in values else nm for i, nm in enumerate(parts.names)]
    printer = Printer(parts.builder.graph, names, cap=100_000)
    system, builder = parts.system, parts.builder
    n_states = len(report.states)

    def text(node):
        t = printer.text(node)
        if t is None:
            raise ValueError("a function of the model has no expression text")
        return t

    def field_table(label, fn):
        exprs = builder.field(label, fn).expr
        return {report.states[i]: text(e) for i, e in enumerate(exprs[:n_states]) if e != builder.graph.zero}

    outputs = {k: text(builder.scalar(k, fn).expr) for k, fn in system.outputs.items()}
    kept = [p for p in report.params if parts.names.index(p) not in values]
    lo, hi = parts.box
    data = {"name": f"{report.system_name or 'model'} (reparametrised)",
            "notes": [f"fixed: {', '.join(f'{parts.names[i]} = {v}' for i, v in values.items())} (a cross-section "
                      "of the unobservable directions: every output of the original model is an output of this "
                      "one, and every parameter here is identifiable)"],
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


__all__ = ["cross_section", "fixed_values", "reparametrised_model"]
