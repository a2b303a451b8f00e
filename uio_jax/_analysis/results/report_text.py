"""A Report as text: what ``print(report)`` shows, and its answer line."""

from ..._output import printable, wrapped
from .kinds import Answer, FollowUp, Method

#: The analysis behind a necessary and sufficient answer, per method.
WHAT = {"orc": "observability rank condition, no unknown input",
        "series": "rank of the output series, the ORC's final codistribution",
        "single_ui": "Martinelli's observable codistribution, one unknown input",
        "general_ui": "Martinelli's general solution, any number of unknown inputs"}
EORC_BY_SYMMETRY = ("EORC at the bound of its verified symmetries: every state it does not show is "
                    "moved by one")
EORC_AT_KNOWN_BOUND = ("EORC at the known-input bound: its span on the states is that of the ORC with "
                       "every input known")


def answer_text(report) -> str:
    """The answer line of ``report``: its :class:`~uio_jax._analysis.results.kinds.Answer`
    (decided by the analysis, :func:`uio_jax._analysis.decisions.answer.decide_answer`) in
    words, with the question answered and the arithmetic of the decisions."""
    if report.answer is Answer.SUFFICIENT_ONLY:
        if report.stop.reason.capped:
            return ("sufficient only (the recursion was capped before it converged): "
                    "'observable' is proven; 'not observable' means not shown")
        if report.method is Method.GENERAL_UI:
            return ("not certified exact (general_ui: the jets of the known inputs may have "
                    "been truncated, see the notes): 'observable' is proven")
        return ("sufficient only (EORC): 'observable' is proven; 'not observable' means "
                "not shown observable up to the last order k")
    symmetric = report.details.get("symmetries") if report.method is Method.EORC else None
    by_symmetry = bool(symmetric and symmetric.get("reached_at") is not None)
    what = WHAT.get(report.method) or (EORC_BY_SYMMETRY if by_symmetry else EORC_AT_KNOWN_BOUND)
    meaning = {"smooth": "; known inputs generic smooth functions of time",
               "switchable": "; known inputs switchable (may jump)"}.get(report.known_inputs, "")
    question = f"({what}{meaning}): the observable functions at generic states"
    if report.answer is Answer.EXACT:
        return f"exact {question}, every decision in exact arithmetic modulo p"
    return (f"necessary and sufficient {question}; decided in {report.certificate.arithmetic.value}: "
            "not certified exact")


def report_text(report) -> str:
    """The text of ``str(report)``: title, answer, dimensions per step, stop, details,
    verdicts per state and parameter (UNDECIDED where the certificate leaves one open),
    certificate and notes."""
    title = f"uio_jax report: {printable(report.system_name or 'system')} ({report.method})"
    lines = [title, "=" * len(title), f"answer: {report.answer_kind()}",
             f"question: {report.question.value} ({report.question.description})"]
    obs = [s for s in report.states if report.observable[s]]
    of = f"{report.n}" + (" (states and parameters)" if report.params else "")
    lines.append(f"observable codistribution: dim {report.dim} of {of}"
                 + ("  (fully observable)" if report.fully_observable else ""))
    label = report.method.step_name
    lines.append("steps:")
    for st in report.history:
        extra = "".join(f", {k}={v}" for k, v in st.extra.items())
        added = ", ".join(st.added) if st.added else "-"
        lines.append(f"  {label}={st.m}: dim {st.dim}  (+ {added}{extra})")
    lines.append(f"stopped: {report.stop_reason}")
    for k, v in report.details.items():
        lines.append(f"{k}: {v}")
    undecided = set(report.undecided)
    lines += ["states:"] + _verdict_lines(report.states, report.observable, "observable", undecided)
    if not obs:
        lines.append("  (no single state component is observable)")
    if report.params:
        lines += ["parameters:"] + _verdict_lines(report.params, report.identifiable, "identifiable", undecided)
    lines += followup_lines(report)
    lines.append(f"certificate: {report.certificate}")
    if report.global_answer is not None:
        lines += report.global_answer.lines()
    for note in report.notes:
        lines.append(f"note: {note}")
    return wrapped("\n".join(map(printable, lines)))  # no model text raw, no line of kilobytes


def _verdict_lines(names, verdicts, word, undecided) -> list:
    """One line per name: ``word`` or ``not word`` (``verdicts``: name -> bool), UNDECIDED
    where the certificate leaves it open."""
    width = max(len(v) for v in names)
    lines = []
    for v in names:
        verdict = word if verdicts[v] else f"not {word}"
        shown = f"UNDECIDED (float64: {verdict})" if v in undecided else verdict
        lines.append(f"  {v:<{width}}  {shown}")
    return lines


def followup_lines(report) -> list:
    """The lines of the follow-up answers computed on ``report`` (``report.followups``): the
    named observable functions and the symmetries found, each where it was asked."""
    lines = []
    named = report.followups.get(FollowUp.OBSERVABLE_FUNCTIONS)
    if named is not None:
        lines.append(f"observable functions: {named.summary()}")
        lines += [f"  {f.text}" + (f"   (globally: {f.globally})" if f.globally else "") for f in named.functions]
        lines += [f"  {f.text}   (uses an unknown input)" for f in named.input_functions]
    found = report.followups.get(FollowUp.SYMMETRIES)
    if found is not None:
        lines.append(f"symmetries found: {found.summary()}")
        lines += [f"  {f.text()}" for f in found.fields]
    return lines


__all__ = ["answer_text", "report_text", "followup_lines"]
