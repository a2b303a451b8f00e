"""A Report as text: what ``print(report)`` shows."""

from .._output import printable, wrapped


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
    label = "k" if report.method in ("eorc", "series") else "m"
    lines.append("steps:")
    for st in report.history:
        extra = "".join(f", {k}={v}" for k, v in st.extra.items())
        added = ", ".join(st.added) if st.added else "-"
        lines.append(f"  {label}={st.m}: dim {st.dim}  (+ {added}{extra})")
    lines.append(f"stopped: {report.stop_reason}")
    for k, v in report.details.items():
        lines.append(f"{k}: {v}")
    lines.append("states:")
    width = max(len(s) for s in report.states)
    undecided = set(report.undecided)
    for s in report.states:
        verdict = "observable" if report.observable[s] else "not observable"
        if s in undecided:
            verdict = f"UNDECIDED (float64: {verdict})"
        lines.append(f"  {s:<{width}}  {verdict}")
    if not obs:
        lines.append("  (no single state component is observable)")
    if report.params:
        lines.append("parameters:")
        width = max(len(p) for p in report.params)
        for p in report.params:
            verdict = "identifiable" if report.identifiable[p] else "not identifiable"
            if p in undecided:
                verdict = f"UNDECIDED (float64: {verdict})"
            lines.append(f"  {p:<{width}}  {verdict}")
    named = report.named_functions
    lines.append(f"observable functions: {named.summary()}")
    lines += [f"  {f.text}" for f in named.functions]
    lines += [f"  {f.text}   (uses an unknown input)" for f in named.input_functions]
    found = report.symmetries
    lines.append(f"symmetries found: {found.summary()}")
    lines += [f"  {f.text()}" for f in found.fields]
    lines.append(f"certificate: {report.certificate}")
    for note in report.notes:
        lines.append(f"note: {note}")
    return wrapped("\n".join(map(printable, lines)))  # no model text raw, no line of kilobytes


__all__ = ["report_text"]
