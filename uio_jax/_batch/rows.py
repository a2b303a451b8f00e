"""The rows of a batch and its tables: :class:`BatchRow`, :class:`BatchResult` (JSON, CSV,
Markdown, the terminal table), and the row of one analysed model."""

import csv
import io
import json
import math
from dataclasses import dataclass, field

from .._analysis.followups.questions import observable_functions
from .._filter.result import format_table
from .._output import printable


@dataclass(frozen=True)
class BatchRow:
    """One model of a batch: its verdict, certificate and time, or its error.

    Attributes:
        model: the model's name (``FILE.py:NAME``, the model file, or the System's name).
        method: analysis that ran (None when the model failed before it).
        n: dimension of the analysed vector (states, plus parameters when there are any).
        dim: generic dimension of the observable codistribution.
        observable: names of the observable state components.
        params: names of the unknown constant parameters (empty when none).
        identifiable: names of the identifiable parameters.
        fraction: fraction of the samples at the generic rank (``certificate.fraction``).
        gap_decades: margin of the weakest rank decision, ``log10(sigma_r_min /
            sigma_next_max)`` (``certificate.gap_decades``; inf when nothing was rejected).
        seconds: wall time of building/loading plus analysing the model, in seconds.
        error: the one-line error of a failed model, None when it passed.
        reached: for a model stopped in a worker (timed out, or its worker died), the last
            step its analysis had decided, e.g. ``"k=5, dim 4/7"``; None otherwise.
        exact: whether the verdicts are exact (``Report.exact``); False for a sufficient
            condition only (the EORC, a capped recursion); None for a failed model.
        inputs: the unknown inputs shown observable (the general solution's
            ``unknown_inputs_observable``, or the EORC's observable input coordinates).
        status: the certificate's status (:attr:`uio_jax.Certificate.status`: ``"ok"``,
            ``"escalated"`` or ``"undecided"``); None for a failed model.
        undecided: the states and parameters whose verdict is not certified.
        functions: the named observable functions (:func:`uio_jax.observable_functions`).
        global_verdicts: with ``scope="global"``, ``"name: verdict"`` per unknown that is not
            globally identifiable (``"a: local (2 values)"``; ``"all global"`` when every one is).
        functions_complete: whether they span the observable codistribution (their number
            is ``dim``); None for a failed model.
        report: the :class:`~uio_jax.Report` (None for a failed model, with
            ``keep_reports=False``, or when the model ran in a worker process).
        notes: what the row does not say by itself (a model file's ``[initial]`` table that
            the batch does not use).
    """

    model: str
    method: str | None = None
    n: int | None = None
    dim: int | None = None
    observable: tuple[str, ...] = ()
    params: tuple[str, ...] = ()
    identifiable: tuple[str, ...] = ()
    fraction: float | None = None
    gap_decades: float | None = None
    seconds: float = 0.0
    error: str | None = None
    reached: str | None = None
    exact: bool | None = None
    inputs: tuple[str, ...] = ()
    status: str | None = None
    undecided: tuple[str, ...] = ()
    functions: tuple[str, ...] = ()
    functions_complete: bool | None = None
    global_verdicts: tuple[str, ...] = ()
    report: object = field(default=None, repr=False, compare=False)
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """True when the model was analysed."""
        return self.error is None

    @property
    def unobservable(self) -> int | None:
        """Number of unobservable directions, ``n - dim`` (None for a failed model)."""
        return None if self.n is None or self.dim is None else self.n - self.dim

    def to_dict(self) -> dict:
        """JSON-ready dictionary (no report; inf/NaN as strings)."""
        d = {
            "model": self.model, "ok": self.ok, "method": self.method, "n": self.n,
            "dim": self.dim, "unobservable": self.unobservable,
            "observable": list(self.observable), "params": list(self.params),
            "identifiable": list(self.identifiable), "fraction": _num(self.fraction),
            "gap_decades": _num(self.gap_decades), "seconds": round(self.seconds, 4),
            "error": self.error, "reached": self.reached, "exact": self.exact,
            "observable_inputs": list(self.inputs), "status": self.status,
            "undecided": list(self.undecided), "observable_functions": list(self.functions),
            **({"global": list(self.global_verdicts)} if self.global_verdicts else {}),
            "functions_complete": self.functions_complete, "notes": list(self.notes),
        }
        return d


@dataclass(frozen=True)
class BatchResult:
    """Result of :func:`batch_analyze`: a sequence of :class:`BatchRow` (iterate, index, len).

    Attributes:
        rows: one row per model, in the order the models were given/found.
        skipped: ``(name, reason)`` of the public functions of zoo files that gave no System.
        seconds: wall time of the whole batch (s).
        options: the analysis options used (method, samples, seed, ...).
        partial: None for a finished batch; otherwise why the rows are only some of the
            models (``"interrupted after 3 of 12 models"``, or ``"running: 3 of 12
            models done"`` in the files rewritten while the batch runs).
    """

    rows: tuple[BatchRow, ...]
    skipped: tuple[tuple[str, str], ...] = ()
    seconds: float = 0.0
    options: dict = field(default_factory=dict)
    partial: str | None = None

    def __iter__(self):
        return iter(self.rows)

    def __len__(self):
        return len(self.rows)

    def __getitem__(self, i):
        return self.rows[i]

    @property
    def failed(self) -> tuple[BatchRow, ...]:
        """Rows of the models that failed."""
        return tuple(r for r in self.rows if not r.ok)

    @property
    def ok(self) -> bool:
        """True when every model was analysed."""
        return not self.failed

    @property
    def not_imported(self) -> tuple[str, ...]:
        """The ``.py`` files found in a directory or a glob and not imported (no marker)."""
        return tuple(n for n, why in self.skipped if why.startswith("not imported"))

    def to_dict(self) -> dict:
        """JSON-ready dictionary: ``models`` (rows), ``skipped``, ``options``, ``seconds``,
        ``partial`` (None, or why the rows are only some of the models)."""
        return {
            "models": [r.to_dict() for r in self.rows],
            "failed": len(self.failed),
            "skipped": [{"name": n, "reason": why} for n, why in self.skipped],
            "options": dict(self.options),
            "seconds": round(self.seconds, 3),
            "partial": self.partial,
        }

    def to_json(self, **kw) -> str:
        """``json.dumps(self.to_dict())``."""
        return json.dumps(self.to_dict(), **kw)

    def to_csv(self) -> str:
        """CSV text, one line per model (lists joined by ``;``)."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        cols = ["model", "ok", "method", "n", "dim", "unobservable", "observable", "params",
                "identifiable", "fraction", "gap_decades", "seconds", "error", "reached", "status",
                "undecided"]
        writer.writerow(cols)
        for r in self.rows:
            d = r.to_dict()
            writer.writerow(["" if d[c] is None else ";".join(d[c]) if isinstance(d[c], list) else d[c]
                             for c in cols])
        return buf.getvalue()

    def to_markdown(self) -> str:
        """A Markdown table (failed models carry their error in the last column); a partial
        table ends with a line saying so."""
        headers, body = self._cells()
        lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
        lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in body]
        notes = self._notes()
        if notes:
            lines += [""] + [f"* {n}" for n in notes]
        if self.partial:
            lines += ["", f"*Partial table: {self.partial}.*"]
        return "\n".join(lines) + "\n"

    def _notes(self) -> list[str]:
        return [printable(f"note: {r.model}: {n}") for r in self.rows for n in r.notes]

    def table(self) -> str:
        """The table for a terminal: aligned columns (a list cell longer than
        :data:`TABLE_CELL` characters abridged with how many more it holds: the Markdown,
        JSON and CSV keep it whole), then one line per failed model's error and the notes."""
        headers, body = self._cells()
        body = [[c if i in (0, len(row) - 1) else _abridged_cell(c) for i, c in enumerate(row)] for row in body]
        widths = [max(len(h), *(len(row[i]) for row in body)) if body else len(h)
                  for i, h in enumerate(headers)]
        right = {"dim / n", "unobs.", "fraction", "gap (dec.)", "time (s)"}
        align = ["r" if h in right else "l" for h in headers]
        lines = format_table(headers, [["-" * w for w in widths]] + body, align, indent="")
        return "\n".join(lines + self._notes())

    def summary(self) -> str:
        """One line: models passed / failed, total time, functions skipped, files not
        imported, and whether the batch was cut short."""
        n_fail = len(self.failed)
        text = (f"{len(self.rows) - n_fail} of {len(self.rows)} models analysed"
                + (f", {n_fail} failed" if n_fail else "") + f" in {self.seconds:.1f} s")
        files = len(self.not_imported)
        functions = len(self.skipped) - files
        if functions:
            text += f"; {functions} function{'s' if functions != 1 else ''} giving no System skipped"
        if files:
            text += (f"; {files} .py file{'s' if files != 1 else ''} not imported "
                     f"(no '# uio-jax: models' marker)")
        if self.partial:
            text = f"{self.partial}: {text}"
        return text

    def _cells(self):
        has_params = any(r.params for r in self.rows)
        has_global = any(r.global_verdicts for r in self.rows)
        headers = ["model", "method", "dim / n", "observable states"]
        if has_params:
            headers.append("identifiable params")
        headers += ["unobs.", "observable functions"] + (["global"] if has_global else []) + [
            "fraction", "gap (dec.)", "time (s)", "status"]
        body = []
        for r in self.rows:
            if not r.ok:
                cells = [r.model, r.method or "-", "-", "-"] + (["-"] if has_params else [])
                cells += ["-", "-"] + (["-"] if has_global else [])
                cells += ["-", "-", f"{r.seconds:.2f}", f"FAILED: {r.error}"]
            else:
                method = r.method + ("" if r.exact is not False else " (suff.)")
                cells = [r.model, method, f"{r.dim} / {r.n}", _names(r.observable, r.n - len(r.params))]
                if has_params:
                    cells.append(_names(r.identifiable, len(r.params)) if r.params else "-")
                status = {"undecided": "UNDECIDED: " + ", ".join(r.undecided) if r.undecided else "UNDECIDED",
                          "escalated": "escalated", "ok": "ok"}.get(r.status or "ok", r.status)
                cells += [str(r.unobservable), _functions(r)] + (["; ".join(r.global_verdicts)] if has_global else [])
                # "ok" in Markdown too: an empty cell reads as missing
                cells += [_pct(r.fraction), _gap(r.gap_decades), f"{r.seconds:.2f}", status]
            body.append([printable(c) for c in cells])  # names and errors from model files
        return headers, body


def row_from_report(label, rep, seconds, report=None, notes=()) -> BatchRow:
    """The row of an analysed model from its :class:`~uio_jax.Report` ``rep`` (``seconds``:
    its wall time; ``report``: what the row keeps, None for nothing; ``notes``: the row's
    notes). A NaN certificate is the row's error."""
    params = tuple(getattr(rep, "params", ()) or ())
    ident = getattr(rep, "identifiable", {}) or {}
    cert = rep.certificate
    named = observable_functions(rep)  # the table's column: asked here, kept on the report
    fraction, gap = float(cert.fraction), float(cert.gap_decades)
    error = None
    if math.isnan(fraction) or math.isnan(gap):
        error = "the certificate is NaN (no usable sample?)"
    return BatchRow(
        model=label, method=rep.method, n=rep.n, dim=rep.dim,
        observable=tuple(s for s, ok in rep.observable.items() if ok),
        params=params, identifiable=tuple(p for p in params if ident.get(p)),
        fraction=fraction, gap_decades=gap, seconds=seconds, error=error, report=report,
        exact=bool(rep.exact), inputs=_observable_inputs(rep),
        status=rep.certificate.status, undecided=tuple(rep.undecided),
        functions=named.texts, functions_complete=named.complete, global_verdicts=_global_verdicts(rep),
        notes=tuple(notes),
    )


def _observable_inputs(rep) -> tuple[str, ...]:
    """The unknown inputs a report shows observable (general_ui: the final unknown inputs;
    EORC: the input coordinates observable at the last order)."""
    details = rep.details
    if "unknown_inputs_observable" in details:
        return tuple(k for k, v in details["unknown_inputs_observable"].items() if v)
    last = rep.history[-1].extra.get("observable_inputs", ()) if rep.history else ()
    return tuple(last)


def _global_verdicts(rep) -> tuple[str, ...]:
    """``"name: verdict"`` of the unknowns not globally identifiable (``scope="global"``), or
    ``("all global",)``; empty when the global question was not asked."""
    answer = rep.global_answer
    if answer is None:
        return ()
    counts = answer.value_counts
    out = tuple(f"{k}: {v.value}" + (f" ({counts[k]} values)" if v.value == "local" and k in counts else "")
                for k, v in answer.global_identifiability.items() if v.value != "global")
    return out or ("all global",)


def verdict(row: BatchRow) -> str:
    """A row's outcome in a few words: ``dim 4/7``, ``timed out after 30 s at order k=5, dim
    4/7 ...`` or ``error: ...`` (cut to 100 characters)."""
    if row.ok:
        return f"dim {row.dim}/{row.n}"
    text = row.error or "failed"
    text = text if text.startswith("timed out") else f"error: {text}"
    return text if len(text) <= 100 else text[:97] + "..."


#: Longest list cell of the terminal table (characters).
TABLE_CELL = 72


def _abridged_cell(cell: str) -> str:
    """A list cell (``; `` or ``, `` separated) cut after the items that fit in
    :data:`TABLE_CELL` characters, with how many more there are."""
    if len(cell) <= TABLE_CELL:
        return cell
    sep = "; " if "; " in cell else ", "
    items, kept = cell.split(sep), []
    for item in items:
        if len(sep.join(kept + [item])) > TABLE_CELL - 12 and kept:
            break
        kept.append(item)
    return sep.join(kept) + f" (+{len(items) - len(kept)} more)" if len(kept) < len(items) else cell


def _functions(row) -> str:
    """The named observable functions of a row, ``; ``-separated, and how many of ``dim``
    when they are fewer."""
    text = "; ".join(row.functions) if row.functions else "-"
    if row.functions_complete is False:
        text += f" ({len(row.functions)} of {row.dim} named)"
    return text


def _names(names, total) -> str:
    if total and len(names) == total:
        return "all"
    return ", ".join(names) if names else "none"


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.1f}%"


def _gap(x) -> str:
    if x is None:
        return "-"
    return "inf" if math.isinf(x) else f"{x:.1f}"


def _num(x):
    if x is None:
        return None
    return x if math.isfinite(x) else str(x)
