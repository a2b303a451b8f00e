"""Result of a Monte Carlo run: statistics over trials, verdict, comparison with analysis."""

import enum
import math
from dataclasses import dataclass, field

import numpy as np

from .._errors import OptionError
from .._output import printable

#: A quantity "converges" when its RMSE at the end and its RMS filter sigma at the end are
#: both at most this fraction of the prior std (the expected RMSE at t = 0).
CONVERGED_RATIO = 0.6
#: ... and "does not converge" when its RMSE at the end is at least this fraction of the
#: prior std, or when its filter sigma has reached a plateau (``PLATEAU_RATIO``) well above
#: the noise floor (sigma ratio > ``CONVERGED_RATIO / 2``). In between: undecided (None).
STALLED_RATIO = 0.8
#: sigma(end) / sigma(t_end / 2) above this means the filter sigma has stopped shrinking.
PLATEAU_RATIO = 0.9
#: RMSE(end) above this multiple of the RMS filter sigma(end): the filter is overconfident.
OVERCONFIDENT = 2.0
#: A trial diverged when its error at the end, in units of the prior std, has an RMS over
#: the NEES states above this (3 prior sigmas).
DIVERGED_PRIOR_SIGMAS = 3.0


def _record(index: int, doc: str) -> property:
    """A read-only property: part ``index`` of ``MonteCarloResult._split()`` in float64."""
    return property(lambda self: self._split()[index].astype(np.float64), doc=doc)


def _rms_over_trials(attribute: str, doc: str):
    """A method ``(self) -> (T, k)``: ``sqrt(mean_b a^2)`` of ``a = self.<attribute>`` ``(B, T, k)``."""

    def rms(self) -> np.ndarray:
        return np.sqrt(np.mean(getattr(self, attribute) ** 2, axis=0))

    rms.__doc__ = doc
    return rms


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """Statistics of a Monte Carlo run (host numpy arrays).

    Attributes:
        experiment: the :class:`~uio_jax.Experiment` run.
        trials: B. seed: the seed.
        t: ``(T,)`` record times (s); ``t[0] = 0`` is the prior.
        stats: ``(B, T, 2N + 2d + 1)`` float32 per-trial records: errors (N; angles
            wrapped), filter sigmas (N), errors and sigmas along the d named quantities,
            NEES over ``experiment.nees_states``.
        trajectories: full trajectories of the first ``keep`` trials (see
            :func:`~uio_jax.trajectories`) or ``None``.
        timings: compile and run seconds, trial-steps/s, devices, load average.
        filter: the EKF that ran: ``"fast"`` or ``"reference"``.
    """

    experiment: object
    trials: int
    seed: int
    t: np.ndarray
    stats: np.ndarray
    trajectories: dict | None
    timings: dict = field(default_factory=dict)
    filter: str = "fast"

    # ------------------------------------------------------------------ slices
    @property
    def state_names(self) -> tuple[str, ...]:
        """Filter state names (system states, then the augmented ones)."""
        return self.experiment.state_names()

    @property
    def quantity_names(self) -> tuple[str, ...]:
        """Names of the named quantities."""
        return tuple(q.name for q in self.experiment.quantities)

    def _split(self):
        N = len(self.state_names)
        d = len(self.quantity_names)
        s = self.stats
        return (s[..., :N], s[..., N:2 * N], s[..., 2 * N:2 * N + d],
                s[..., 2 * N + d:2 * N + 2 * d], s[..., -1])

    errors = _record(0, "``(B, T, N)`` estimate minus truth (angles wrapped), float64.")
    sigmas = _record(1, "``(B, T, N)`` filter standard deviations ``sqrt(diag P)``, float64.")
    quantity_errors = _record(2, "``(B, T, d)`` errors along the named quantities, float64.")
    quantity_sigmas = _record(3, "``(B, T, d)`` filter sigma of the named quantities, "
                                 "``sqrt(grad q P grad q^T)``, float64.")
    nees = _record(4, "``(B, T)`` normalised estimation error squared over "
                      "``experiment.nees_states``, float64.")

    # ------------------------------------------------------------------ statistics
    rmse = _rms_over_trials("errors", "``(T, N)`` RMSE over trials per state: ``sqrt(mean_b e^2)``.")
    sigma_rms = _rms_over_trials("sigmas", "``(T, N)`` RMS over trials of the filter sigma "
                                           "(equals the RMSE if consistent).")
    quantity_rmse = _rms_over_trials("quantity_errors", "``(T, d)`` RMSE along the named quantities.")
    quantity_sigma_rms = _rms_over_trials("quantity_sigmas",
                                          "``(T, d)`` RMS filter sigma along the named quantities.")

    def nees_dof(self) -> int:
        """Degrees of freedom of the NEES (its expected value when consistent)."""
        return len(self.experiment.nees_states)

    def divergent(self) -> np.ndarray:
        """``(B,)`` bool: trials whose end error exceeds ``DIVERGED_PRIOR_SIGMAS`` priors."""
        names = self.state_names
        idx = [names.index(s) for s in self.experiment.nees_states]
        prior = np.asarray(self.experiment.prior_std)[idx]
        e = self.errors[:, -1, idx] / prior
        return np.sqrt(np.mean(e**2, axis=1)) > DIVERGED_PRIOR_SIGMAS

    # ------------------------------------------------------------------ verdict
    def verdict(self) -> dict:
        """Convergence per state and per named quantity, judged by ratios end/start.

        For each state (and named quantity): ``prior`` (RMS over trials of the filter
        sigma at t = 0: the expected RMSE of the initial estimate, steadier than the
        sample RMSE at t = 0 for few trials), ``rmse_start`` (sample, t = 0), ``rmse_end``,
        ``ratio = rmse_end / prior``, ``sigma_ratio = sigma_end / prior`` (RMS filter sigma),
        ``late_sigma_ratio = sigma(end) / sigma(t_end / 2)`` and ``converges``:

        * ``True`` when ``ratio`` and ``sigma_ratio`` are both <= ``CONVERGED_RATIO`` (0.6);
        * ``False`` when ``ratio >= STALLED_RATIO`` (0.8), or when the sigma has a plateau
          (``late_sigma_ratio >= PLATEAU_RATIO``, 0.9) with ``sigma_ratio > 0.3``, or when
          the filter is overconfident (RMSE > ``OVERCONFIDENT`` = 2 x sigma at the end: the
          classic EKF inconsistency along unobservable directions, where the shrinking
          sigma is no evidence);
        * ``None`` (undecided) otherwise.

        These are heuristics on finite runs (the verdict depends on the prior and the
        horizon). Also: mean and median NEES at the end, their expected value (dof) and the
        fraction of divergent trials (:meth:`divergent`).

        Returns:
            ``{"states": {name: {...}}, "quantities": {name: {...}}, "nees": {...},
            "divergent_fraction": float, "trials": B, "duration_s": T}``.
        """
        T = len(self.t)
        mid = int(np.argmin(np.abs(self.t - self.t[-1] / 2)))
        out = {"trials": self.trials, "duration_s": float(self.t[-1])}

        def rows(names, rmse, sig, angles):
            res = {}
            for i, nm in enumerate(names):
                r0, r1 = float(rmse[0, i]), float(rmse[-1, i])
                s0, s1, sm = float(sig[0, i]), float(sig[-1, i]), float(sig[mid, i])
                ratio = r1 / s0 if s0 > 0 else math.nan
                sratio = s1 / s0 if s0 > 0 else math.nan
                late = s1 / sm if sm > 0 else math.nan
                res[nm] = {"prior": s0, "rmse_start": r0, "rmse_end": r1, "ratio": ratio,
                           "sigma_end": s1, "sigma_ratio": sratio,
                           "late_sigma_ratio": late, "angle": bool(angles[i]),
                           "converges": _decide(ratio, sratio, late)}
            return res

        out["states"] = rows(self.state_names, self.rmse(), self.sigma_rms(),
                             self.experiment.angle_mask())
        out["quantities"] = rows(self.quantity_names, self.quantity_rmse(),
                                 self.quantity_sigma_rms(),
                                 [q.angle for q in self.experiment.quantities])
        nees = self.nees
        out["nees"] = {"dof": self.nees_dof(), "mean_end": float(np.mean(nees[:, -1])),
                       "median_end": float(np.median(nees[:, -1])),
                       "mean_over_time": float(np.mean(nees[:, T // 10:]))}
        out["divergent_fraction"] = float(np.mean(self.divergent()))
        return out

    def compare(self, report=None) -> dict:
        """The Monte Carlo verdict next to the analysis verdict.

        Per system state: the analysis' ``observable`` against the Monte Carlo
        ``converges``; per named quantity ``q``: ``report.is_observable(q.fn)`` (or, with no
        report, the label ``Quantity.observable`` given by the experiment) against its
        ``converges``.

        Note: per-state ratios can mislead when an unobservable direction moves several
        states (003, range, gamma unknown: the rotation about the origin): each such state's
        error drops to the prior spread along that direction, smaller than its own prior, so
        it may look "converging"; the named quantity along the symmetry is the decisive check.

        Args:
            report: a :class:`~uio_jax.Report` of the system with the outputs the
                experiment reads (``uio_jax.analyze(experiment.analysis_system())``);
                ``None``: no analysis, the quantities keep the experiment's labels and the
                states are undecided. The filter layer never runs an analysis itself.

        Raises:
            OptionError: a report of other states than the experiment's system.

        Returns:
            ``{"analysis": method | None, "note": str, "states": {name: row},
            "quantities": {name: row}, "agree": bool | None}`` with ``row = {"observable":
            bool | None, "converges": bool | None, "agree": bool | None}``; ``agree`` is
            ``None`` when either side is undecided; the overall ``agree`` says what the
            text's verdict line says (:meth:`headline`): ``False`` when they disagree,
            else ``None`` if any row is undecided, else ``True`` (also for "consistent":
            unobservable states that look converging while every named quantity agrees);
            ``verdict``: the :class:`Agreement` value of that line.
        """
        states = tuple(self.experiment.system.states)
        if report is not None and tuple(report.states) != states:
            raise OptionError(f"compare needs a report of the experiment's states {states}, "
                              f"got one of {tuple(report.states)}")
        note = "" if report is not None else "no analysis given"
        v = self.verdict()
        rows_s, rows_q = {}, {}
        for s in states:
            obs = None if report is None else bool(report.observable[s])
            rows_s[s] = _row(obs, v["states"][s]["converges"])
        for q in self.experiment.quantities:
            # on the report's own states a quantity evaluates as in the run (which computed
            # its errors): nothing is left to fail but a bug, which propagates
            obs = q.observable if report is None else bool(report.is_observable(q.fn))
            rows_q[q.name] = _row(obs, v["quantities"][q.name]["converges"])
        agrees = [r["agree"] for r in list(rows_s.values()) + list(rows_q.values())]
        kind = _outcome(rows_s, rows_q)[0]
        agree = (False if kind is Agreement.DISAGREES else None if None in agrees
                 else True)  # "consistent" agrees: the named quantities decide (headline)
        return {"analysis": None if report is None else report.method, "note": note,
                "states": rows_s, "quantities": rows_q, "agree": agree, "verdict": kind.value}

    # ------------------------------------------------------------------ output
    def to_dict(self, comparison=None) -> dict:
        """JSON-ready summary: what the text says (``outcome``, the :class:`Agreement` value of
        the verdict line, and ``headline``, its lines), the ``filter`` that ran, the
        per-row numbers (``verdict``), timings, times and RMSE / sigma curves, and the
        ``comparison`` (:meth:`compare`) when given."""
        out = {
            "experiment": self.experiment.name, "trials": self.trials, "seed": self.seed,
            "filter": self.filter, "outcome": self.outcome(comparison).value,
            "headline": self.headline(comparison),
            "verdict": self.verdict(), "timings": {k: _plain(v) for k, v in self.timings.items()},
            "t": self.t.tolist(), "states": list(self.state_names),
            "rmse": self.rmse().tolist(), "sigma": self.sigma_rms().tolist(),
            "quantities": list(self.quantity_names),
            "quantity_rmse": self.quantity_rmse().tolist(),
            "quantity_sigma": self.quantity_sigma_rms().tolist(),
            "nees_mean": np.mean(self.nees, axis=0).tolist(),
            "nees_median": np.median(self.nees, axis=0).tolist(),
            "notes": self.experiment.notes,
        }
        if comparison is not None:
            out["comparison"] = comparison
        return out

    def outcome(self, comparison=None) -> "Agreement":
        """The kind of the verdict line of :meth:`headline` (an :class:`Agreement`)."""
        if comparison is None:
            return Agreement.MONTE_CARLO_ONLY
        return _outcome(comparison["states"], comparison["quantities"])[0]

    def headline(self, comparison=None) -> list[str]:
        """The verdict first: one line ``verdict: ...``, then the lines that explain it.

        From :meth:`verdict` and, when given, :meth:`compare`'s ``comparison``:

        * no comparison: which rows converge, which do not, which are unclear;
        * every row agrees (or is undecided): "Monte Carlo agrees with the analysis";
        * a named quantity disagrees, or an observable state does not converge: "Monte
          Carlo and the analysis disagree on ..." (a contradiction to look into);
        * only unobservable states look converging while every named quantity agrees:
          "consistent with the analysis on the named quantities", and the next line says
          why those state rows mislead (:meth:`compare`'s note). Without a named quantity
          this stays a disagreement.

        The last line lists the rows that converge, do not and are unclear.
        """
        v = self.verdict()
        rows = {**v["states"], **v["quantities"]}
        groups = {c: [k for k, r in rows.items() if r["converges"] is c] for c in (True, False, None)}
        facts = "; ".join(f"{word} {', '.join(groups[c])}" for c, word in
                          ((True, "converges on"), (False, "does not converge on"),
                           (None, "unclear on")) if groups[c])
        facts = f"  the filter {facts}" if facts else "  nothing to judge"
        if comparison is None:
            return ["verdict: Monte Carlo only (no analysis compared)", facts]
        source = (f"the analysis ({comparison['analysis']})" if comparison["analysis"]
                  else "the experiment's labels")

        def word(r):
            obs = {True: "observable", False: "unobservable", None: "?"}[r["observable"]]
            conv = {True: "converges", False: "does not converge", None: "unclear"}[r["converges"]]
            return f"{obs}, {conv}"

        rows_s, rows_q = comparison["states"], comparison["quantities"]
        kind, bad_q, bad_obs, bad_unobs = _outcome(rows_s, rows_q)
        undecided = [k for k, r in {**rows_s, **rows_q}.items() if r["agree"] is None]
        lines = []
        if kind is Agreement.DISAGREES:
            names = bad_q + bad_obs + bad_unobs
            lines.append(f"verdict: Monte Carlo and {source} disagree on "
                         + ", ".join(f"{k} ({word({**rows_s, **rows_q}[k])})" for k in names))
            if bad_unobs and not rows_q:
                lines.append(f"  {', '.join(bad_unobs)}: a state moved together with others by "
                             "an unobservable direction can look converging (its error drops to "
                             "the prior spread along it); no named quantity to check it along")
        elif kind is Agreement.CONSISTENT:
            agree_q = [k for k, r in rows_q.items() if r["agree"] is True]
            lines.append(f"verdict: consistent with {source} on the named quantities"
                         + (": " + ", ".join(f"{k} ({word(rows_q[k])})" for k in agree_q)
                            if agree_q else ""))
            lines.append(f"  {', '.join(bad_unobs)} look converging though unobservable: an "
                         "unobservable direction moves them together, so each one's error "
                         "drops only to the prior spread along it; the named quantities decide")
        else:
            lines.append(f"verdict: Monte Carlo agrees with {source}"
                         + (" where both decide" if undecided else ""))
        if undecided:
            lines.append(f"  undecided: {', '.join(undecided)}")
        lines.append(facts)
        return lines

    def table(self, comparison=None) -> list[str]:
        """Per state and named quantity: unit, prior std, RMSE and filter sigma at the end
        (in the display unit: angles in degrees), their ratios to the prior, the verdict
        and, with a comparison, the analysis' verdict; fixed-width columns (see
        :func:`format_table`)."""
        v = self.verdict()
        header = ["", "unit", "prior std", "RMSE end", "ratio", "sigma end", "s.ratio", "converges"]
        if comparison is not None:
            header.append("analysis")
        rows = []
        for kind in ("states", "quantities"):
            for nm, r in v[kind].items():
                unit, scale = self.experiment.display_unit(nm)
                row = [nm, unit, _num(r["prior"] * scale), _num(r["rmse_end"] * scale),
                       _num(r["ratio"], ".3g"), _num(r["sigma_end"] * scale),
                       _num(r["sigma_ratio"], ".3g"),
                       {True: "yes", False: "no", None: "unclear"}[r["converges"]]]
                if comparison is not None:
                    o = comparison[kind].get(nm, {}).get("observable")
                    row.append({True: "observable", False: "unobservable", None: "-"}[o])
                rows.append(row)
        align = "ll" + "r" * 5 + "ll"
        return format_table(header, rows, align[:len(header)])

    def summary(self, comparison=None) -> str:
        """The readable summary: title, the verdict first (:meth:`headline`), the table
        (:meth:`table`), NEES and divergent trials, timings."""
        v = self.verdict()
        lines = [f"Monte Carlo {self.experiment.name}: {self.trials} trials, seed {self.seed}, "
                 f"{v['duration_s']:.4g} s"]
        lines += self.headline(comparison)
        lines += self.table(comparison)
        n = v["nees"]
        lines.append(f"  NEES at end ({n['dof']} dof, expected {n['dof']}): mean "
                     f"{_num(n['mean_end'], '.3g')}, median {_num(n['median_end'], '.3g')}; "
                     f"divergent trials {100 * v['divergent_fraction']:.2f}%")
        if comparison is not None and comparison["note"]:
            lines.append(f"  {comparison['note']}")
        tm = self.timings
        if tm:
            lines.append(f"  {tm['trial_steps_per_s'] / 1e6:.2f} M trial-steps/s on "
                         f"{tm['devices']} {tm['device_kind']} device(s); compile "
                         f"{tm['compile_s']:.2f} s, run {tm['run_s']:.2f} s; load average "
                         f"{tm['loadavg'][0]:.2f}")
        return "\n".join(map(printable, lines))  # names and units from a model file, made inert

    def __str__(self) -> str:
        return self.summary()


def _num(v, spec=".4g") -> str:
    """A number in a table cell: ``format(v, spec)`` (``.4g``: ``1.469e+06``, ``2.1e-30``,
    ``0.05``), ``nan`` / ``inf`` / ``-inf`` when not finite (as ``format`` writes them)."""
    return format(float(v), spec)


def format_table(header, rows, align, indent="  ", gap=2) -> list[str]:
    """Lines of a table with fixed-width columns, whatever the cells hold.

    Args:
        header: one string per column.
        rows: sequences of cell strings, as many as ``header``.
        align: one letter per column, ``"l"`` (left) or ``"r"`` (right).
        indent: prefix of every line. gap: spaces between columns (at least 1).

    Returns:
        the header line, then one line per row; each column as wide as its longest cell
        (header included), columns ``gap`` spaces apart, trailing spaces stripped.

    Raises:
        OptionError: a row with another number of cells, an ``align`` letter not l / r.
    """
    k = len(header)
    if len(align) != k or set(align) - set("lr"):
        raise OptionError(f"align needs one of 'l', 'r' per column ({k}), got {align!r}")
    cells = [list(map(printable, header))] + [list(map(printable, r)) for r in rows]
    for r in cells:
        if len(r) != k:
            raise OptionError(f"a table row has {len(r)} cells, the header {k}")
    widths = [max(len(r[j]) for r in cells) for j in range(k)]
    sep = " " * max(int(gap), 1)
    return [(indent + sep.join(c.ljust(w) if a == "l" else c.rjust(w)
                               for c, w, a in zip(r, widths, align))).rstrip() for r in cells]


class Agreement(str, enum.Enum):
    """The kind of a Monte Carlo verdict line (:meth:`MonteCarloResult.headline`), as the
    JSON's ``outcome`` says it."""

    MONTE_CARLO_ONLY = "monte_carlo_only"  # no analysis compared
    AGREES = "agrees"  # every row agrees (or is undecided)
    CONSISTENT = "consistent"  # only unobservable states look converging; quantities agree
    DISAGREES = "disagrees"  # a quantity, or an observable state, contradicts the analysis


def _outcome(rows_s, rows_q):
    """``(Agreement, bad quantities, bad observable states, bad unobservable states)`` of a
    comparison's rows (see :meth:`MonteCarloResult.headline`)."""
    bad_q = [k for k, r in rows_q.items() if r["agree"] is False]
    bad_obs = [k for k, r in rows_s.items() if r["agree"] is False and r["observable"]]
    bad_unobs = [k for k, r in rows_s.items() if r["agree"] is False and not r["observable"]]
    if bad_q or bad_obs or (bad_unobs and not rows_q):
        kind = Agreement.DISAGREES
    else:
        kind = Agreement.CONSISTENT if bad_unobs else Agreement.AGREES
    return kind, bad_q, bad_obs, bad_unobs


def _row(obs, conv):
    return {"observable": obs, "converges": conv,
            "agree": None if obs is None or conv is None else obs == conv}


def _decide(ratio, sratio, late):
    if not (math.isfinite(ratio) and math.isfinite(sratio)):
        return None
    if ratio <= CONVERGED_RATIO and sratio <= CONVERGED_RATIO:
        return True
    plateau = math.isfinite(late) and late >= PLATEAU_RATIO
    # an overconfident filter (error > OVERCONFIDENT x its sigma) shrinks its sigma along
    # directions it cannot see: its sigma is no evidence, only the error ratio counts
    overconfident = ratio > OVERCONFIDENT * sratio
    if ratio >= STALLED_RATIO or (plateau and sratio > CONVERGED_RATIO / 2) or overconfident:
        return False
    return None


def _plain(v):
    if isinstance(v, tuple):
        return [float(x) for x in v]
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v
