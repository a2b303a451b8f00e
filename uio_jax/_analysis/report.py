"""The result of an analysis: dimensions per step, verdicts, evidence, symmetries."""

import inspect
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ModelError
from .._output import printable
from .evidence import Arithmetic, Certificate, Step, jsonable

#: What every analysis answers, as in the papers (Martinelli 2015/2017).
SEMANTICS = (
    "Unknown inputs are smooth (analytic) functions of time and known inputs may be chosen "
    "freely (they may jump), as in Martinelli's papers: a direction that could only be "
    "hidden by an unknown input that jumps together with a known input counts as "
    "observable. Tools such as STRIKE-GOLDD/StrikePy by default model an unknown input as "
    "a polynomial in time of fixed degree, which answers a different question."
)

#: The same, for known inputs that are generic smooth functions of time (``known_inputs="smooth"``).
SEMANTICS_SMOOTH = (
    "Unknown inputs are smooth (analytic) functions of time and known inputs are generic "
    "smooth functions of time, known with their derivatives (TUIO6's meaning): a direction "
    "that a smooth unknown input can hide for a generic smooth known input counts as "
    "unobservable, even if a jump of the known input would reveal it. Tools such as "
    "STRIKE-GOLDD/StrikePy by default model an unknown input as a polynomial in time of "
    "fixed degree, which answers a different question."
)


@dataclass(frozen=True, eq=False)
class Report:
    """Result of :func:`uio_jax.analyze`.

    Attributes:
        method: analysis that ran (``"orc"``, ``"single_ui"``, ``"eorc"`` or ``"series"``).
        states: state names (order of the state vector).
        dim: generic dimension of the observable codistribution on the original state
            (on ``[x; p]`` when the System has parameters).
        observable: state name -> whether its differential lies in the codistribution.
        params: names of the unknown constant parameters (empty without ``params=``).
        identifiable: parameter name -> whether it is identifiable (its differential lies
            in the codistribution of the joint system ``[x; p]``, ``p' = 0``).
        history: one :class:`Step` per step m (per order k for the EORC).
        certificate: the sampling evidence behind every rank decision.
        generators: labels of the functions whose gradients span the final codistribution.
        stop_reason: why the recursion stopped.
        notes: remarks (method choice, sufficiency of the EORC, corrections applied).
        details: method-specific results (``m_prime``, ``m_star``, ``k``, ...).
        semantics: what "unknown input" and "known input" mean in this answer.
        known_inputs: the meaning of the known inputs the answer is for: ``"switchable"``
            (they may jump), ``"smooth"`` (generic smooth functions of time) or ``"none"``
            (the System has no known input: one meaning).
        system_name: name of the analyzed System.
    """

    method: str
    states: tuple[str, ...]
    dim: int
    observable: Mapping[str, bool]
    history: tuple[Step, ...]
    certificate: Certificate
    generators: tuple[str, ...]
    stop_reason: str
    notes: tuple[str, ...] = ()
    details: Mapping = field(default_factory=dict)
    semantics: str = SEMANTICS
    system_name: str = ""
    params: tuple[str, ...] = ()
    identifiable: Mapping[str, bool] = field(default_factory=dict)
    known_inputs: str = "switchable"
    _space: object = field(default=None, repr=False)

    def __post_init__(self):
        params = tuple(self.params)
        observable = dict(self.observable)
        identifiable = dict(self.identifiable)
        for p in params:  # verdicts on parameters given among the states: move them
            if p in observable:
                identifiable[p] = observable.pop(p)
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "states", tuple(s for s in self.states if s not in params))
        object.__setattr__(self, "observable", MappingProxyType(observable))
        object.__setattr__(self, "identifiable", MappingProxyType(identifiable))
        object.__setattr__(self, "details", MappingProxyType(dict(self.details)))

    @property
    def variables(self) -> tuple[str, ...]:
        """Coordinates of the analysed vector: states, then parameters."""
        return self.states + self.params

    @property
    def n(self) -> int:
        """Dimension of the analysed vector (states plus parameters)."""
        return len(self.variables)

    @property
    def undecided(self) -> tuple[str, ...]:
        """The states and parameters whose verdict is not certified (empty when every rank
        decision was clear in float64 or settled beyond it).

        From the undecided escalations of the certificate: the membership of ``e_i``
        leaves variable ``i``'s verdict open; a generator kept on its float64 vote leaves
        open every "observable" verdict (the span may be smaller), one rejected every "not
        observable" one (the span may be larger).
        """
        names = self.variables
        verdict = {**dict(self.observable), **dict(self.identifiable)}
        open_ = set()
        for e in self.certificate.escalations:
            if e.result != "undecided":
                continue
            head = e.what.split(" ", 1)[0]
            if head.startswith("e_") and head[2:].isdigit():
                i = int(head[2:])
                if i < len(names):
                    open_.add(names[i])
                continue
            kept = e.float64.startswith("independent")
            open_.update(v for v in names if verdict.get(v) == kept)
        return tuple(v for v in names if v in open_)

    @property
    def fully_observable(self) -> bool:
        """True when every state component is observable and every parameter identifiable."""
        return all(self.observable.values()) and all(self.identifiable.values())

    @property
    def dims(self) -> tuple[int, ...]:
        """Dimension per step, ``tuple(step.dim for step in history)``."""
        return tuple(s.dim for s in self.history)

    def domain_centre(self) -> np.ndarray:
        """The representative point of the report: the centre of the sampling box.

        Returns:
            ``(n,)`` array ``z = [x; p]``: for every state and then every parameter
            (:attr:`variables`), the midpoint of its sampling box (``System.domain``,
            the ``params=`` boxes).

        Raises:
            ModelError: the report does not know the sampling box (built by hand).
        """
        domain = _domain_of(self._space)
        if domain is None or any(v not in domain for v in self.variables):
            raise ModelError("this report does not know the sampling box of its variables")
        return np.array([0.5 * (float(domain[v][0]) + float(domain[v][1]))
                         for v in self.variables])

    def unobservable_directions(self, x=None, p=None) -> np.ndarray:
        """Basis of the unobservable directions (null space of the codistribution) at a point.

        These are the continuous symmetries of the system: moving the state (and the
        parameters) along them does not change the outputs (e.g. a rotation about the
        feature; for ``x' = -(a + b) x`` the direction ``(0, 1, -1) / sqrt(2)`` on
        ``(x, a, b)``: only ``a + b`` is identifiable).

        Args:
            x: the point ``z = [x; p]``, shape ``(n,)`` with ``n = len(states) +
                len(params)`` (:attr:`variables`); or, with ``p``, the state alone, shape
                ``(len(states),)``. Default: :meth:`domain_centre`.
            p: the parameters, shape ``(len(params),)``, when ``x`` is the state alone.

        Returns:
            ``(n, n - dim)`` array with orthonormal columns (rows: :attr:`variables`).

        Raises:
            ModelError: a point of the wrong shape or with NaN/inf, or a point where the
                codistribution is not defined.
        """
        return self._space.unobservable_directions(self._point(x, p, "unobservable_directions"))

    def direction_summary(self, x=None, p=None) -> dict:
        """The unobservable directions at a point, labelled by the variables' names.

        Each direction (a column of :meth:`unobservable_directions`, unit norm) is
        signed so that its largest component is positive; components below ``1e-12``
        (round-off) are set to 0. For a model with parameters, the identifiable
        parameter combinations are given by their differentials at the point: the
        covectors ``c`` on the parameters that are not identifiable one by one with
        ``[0; c]`` orthogonal to every direction, i.e. in the codistribution (for
        ``x' = -(a + b) x``: ``da + db``, the differential of ``a + b``; for a product
        ``a b`` at ``a = b = 1`` it would read the same). Directions with several
        columns are a basis of the null space, not unique.

        Args:
            x, p: the point, as in :meth:`unobservable_directions` (default: the centre
                of the sampling box).

        Returns:
            ``{"point": {name: value}, "directions": [{name: coefficient}, ...],
            "identifiable_combinations": [{param: coefficient}, ...]}`` (combination
            coefficients scaled so that the largest magnitude is 1).
        """
        if x is None and p is None:
            z, rule = self.representative_point()
        else:
            z, rule = self._point(x, p, "direction_summary"), "the given point"
        names = self.variables
        if self.dim >= self.n:
            dirs = np.zeros((self.n, 0))
        else:
            ratio = _rank_ratio_at(self._space, z)
            if ratio is not None and not ratio > self.certificate.rtol:
                raise ModelError(f"the codistribution drops rank at {_point_text(names, z)} "
                                 f"(s_r/s_1 = {ratio:.1e} <= rtol {self.certificate.rtol:.0e}):"
                                 " its directions there are not the generic ones")
            dirs = np.asarray(self._space.unobservable_directions(z), dtype=float)
        out = []
        for j in range(dirs.shape[1]):
            v = np.where(np.abs(dirs[:, j]) < 1e-12, 0.0, dirs[:, j])
            lead = int(np.argmax(np.round(np.abs(v), 9)))
            v = -v if v[lead] < 0 else v
            out.append({nm: float(c) + 0.0 for nm, c in zip(names, v)})
        return {"point": {nm: float(c) for nm, c in zip(names, z)}, "rule": rule,
                "directions": out, "identifiable_combinations": self._combinations(dirs)}

    def representative_point(self) -> tuple[np.ndarray, str]:
        """Where the report's directions are given: the centre of the sampling box if the
        codistribution has its generic rank there, else the first of a fixed sequence of
        points off the centre (``centre + 0.3 * width * t``, ``t`` a fixed pattern in
        ``[-1, 1]`` per coordinate) where it does.

        Returns:
            ``(z, rule)``: ``z`` of shape ``(n,)`` (:attr:`variables`) and a sentence
            naming the choice.

        Raises:
            ModelError: the sampling box is unknown, or the rank drops at every candidate.
        """
        centre = self.domain_centre()
        domain, rtol = _domain_of(self._space), self.certificate.rtol
        if self.dim >= self.n:
            return centre, _CENTRE
        width = np.array([float(domain[v][1]) - float(domain[v][0]) for v in self.variables])
        for j in range(4):
            t = 2.0 * np.modf((np.arange(self.n) + 1.0) * (0.6180339887 + 0.1 * j))[0] - 1.0
            z = centre if j == 0 else centre + 0.3 * width * t
            ratio = _rank_ratio_at(self._space, z)
            if ratio is None or ratio > rtol:
                return z, (_CENTRE if j == 0 else _OFF_CENTRE)
        raise ModelError("the codistribution drops rank at the centre of the sampling box and "
                         "at the points tried around it; give a point to unobservable_directions")

    def _combinations(self, dirs) -> list:
        """Identifiable parameter combinations (by differential) orthogonal to ``dirs``."""
        ns = len(self.states)
        hidden = [j for j, nm in enumerate(self.params) if not self.identifiable.get(nm, False)]
        if len(hidden) < 2 or dirs.shape[1] == 0:
            return []
        m = dirs[ns:][hidden]  # (len(hidden), k)
        u, s, _ = np.linalg.svd(m, full_matrices=True)
        rank = int(np.sum(s > 1e-8 * max(1.0, float(s[0]) if s.size else 1.0)))
        combos = []
        for c in u[:, rank:].T:
            c = np.where(np.abs(c) < 1e-12, 0.0, c)
            lead = int(np.argmax(np.round(np.abs(c), 9)))
            c = c / c[lead]
            combos.append({self.params[j]: float(v) + 0.0 for j, v in zip(hidden, c) if v != 0.0})
        return combos

    def format_directions(self, summary=None) -> str:
        """Text of :meth:`direction_summary` (default: at the centre of the sampling box).

        One line naming the point, one line per direction (components that print as
        zero at 3 decimals omitted), and for a model with parameters one line per
        identifiable combination of parameters that are not identifiable one by one.
        """
        summary = self.direction_summary() if summary is None else summary
        at = ", ".join(f"{k}={v:.3g}" for k, v in summary["point"].items())
        where = {_CENTRE: "the centre of the domain",
                 _OFF_CENTRE: "the centre of the domain: the rank drops there; instead at"}
        lines = [f"unobservable directions at {where.get(summary.get('rule'), 'the point')} "
                 f"({at}):"]
        if not summary["directions"]:
            lines.append("  none")
        for d in summary["directions"]:
            terms = [f"{c:+.3f} {k}" for k, c in d.items() if abs(c) >= 5e-4]
            lines.append("  " + "  ".join(terms))
        for c in summary["identifiable_combinations"]:
            lines.append("identifiable combination (its differential at this point): "
                         + _linear_text({f"d{k}": v for k, v in c.items()}))
        return "\n".join(lines)

    def _point(self, x, p, what) -> np.ndarray:
        """``z = [x; p]`` from ``z`` or ``(x, p)`` (shapes checked, ModelError otherwise)."""
        ns, npar = len(self.states), len(self.params)
        forms = (f"a state of shape ({self.n},)" if not npar else
                 f"z = [x; p] of shape ({self.n},) or (x, p) with x ({ns},), p ({npar},)")
        if x is None:
            if p is not None:
                raise ModelError(f"{what} needs {forms}; got p without x")
            return self.domain_centre()
        try:
            x = np.asarray(x, dtype=np.float64)
            p = None if p is None else np.asarray(p, dtype=np.float64)
        except (TypeError, ValueError):
            raise ModelError(f"{what} needs {forms}; got a non-numeric point") from None
        if p is None:
            if x.shape != (self.n,):
                raise ModelError(f"{what} needs {forms}; got shape {x.shape}")
            return x
        if not npar:
            raise ModelError(f"{what}: this model has no parameters; give {forms}")
        if x.shape != (ns,) or p.shape != (npar,):
            raise ModelError(f"{what} needs {forms}; got x {x.shape}, p {p.shape}")
        return np.concatenate([x, p])

    def sample_singular_values(self) -> np.ndarray:
        """How sure the rank is: per-sample singular values of the final generators.

        The kept generators' gradients at every used sample, columns scaled by the
        sampling box and rows by their norm (as in every rank decision), give a matrix
        ``(r, n)`` per sample; its singular values divided by the largest are returned.
        ``certificate.rtol`` and ``certificate.sigma_next_max`` (largest rejected margin)
        lie below the last column at every sample at the generic rank: the gap is the
        evidence.

        Returns:
            ``(S_used, r)`` array, descending along each row (``r = 0``: shape ``(S, 0)``).
        """
        return self._space.sample_singular_values()

    def is_observable(self, fn) -> bool:
        """Whether the scalar function ``fn`` is observable (``d fn`` in the span).

        Args:
            fn: callable returning a scalar ``()``, traceable by JAX: ``fn(z)`` with
                ``z = [x; p]`` of shape ``(n,)`` (:attr:`variables`: states then
                parameters), or, for a model with parameters, ``fn(x, p)`` with ``x``
                of shape ``(len(states),)`` and ``p`` of shape ``(len(params),)``. The
                form is read from the number of required positional parameters.

        Raises:
            ModelError: not a callable, a signature of neither form, a function that
                fails on those shapes or does not return a scalar.
        """
        return self._space.is_observable(self._function_of_z(fn, "is_observable"))

    def _function_of_z(self, fn, what):
        """``fn`` as a function of ``z (n,)``, checked on shapes (one-line ModelError)."""
        ns, npar = len(self.states), len(self.params)
        forms = (f"fn(x) with x ({self.n},)" if not npar else
                 f"fn(z) with z = [x; p] ({self.n},) or fn(x, p) with x ({ns},), p ({npar},)")
        if not callable(fn):
            raise ModelError(f"{what} needs a callable {forms}, got {type(fn).__name__}")
        nargs = _positional_arity(fn)
        if nargs == 2 and npar:
            def of_z(z):
                return fn(z[:ns], z[ns:])
            of_z.__name__ = getattr(fn, "__name__", "fn")
            form = f"fn(x, p) with x ({ns},), p ({npar},)"
        elif nargs in (None, 1):
            of_z = fn
            form = f"fn(z) with z ({self.n},)" if npar else f"fn(x) with x ({self.n},)"
        else:
            has = "no parameters" if not npar else f"{npar} parameters"
            raise ModelError(f"{what} needs {forms} (this model has {has}); got a function "
                             f"of {nargs} required positional arguments")
        try:  # JAX clamps an index past the end (p[5] of 2): plain numpy raises instead
            of_z(np.full(self.n, 0.75))
        except IndexError as exc:
            raise ModelError(f"{what}: {form} indexes outside its arguments ({exc})") from None
        except Exception:  # numpy input not supported by this function: the trace decides
            pass
        with jax.enable_x64(True):
            try:
                out = jax.eval_shape(of_z, jax.ShapeDtypeStruct((self.n,), jnp.float64))
            except Exception as exc:  # the user's function: any failure is a bad function
                msg = (str(exc).strip().splitlines() or [""])[0][:160]
                raise ModelError(f"{what}: {form} fails ({type(exc).__name__}"
                                 f"{': ' + msg if msg else ''}); expected {forms}") from None
        if getattr(out, "shape", None) != ():
            raise ModelError(f"{what}: function must return a scalar (), got shape "
                             f"{getattr(out, 'shape', None)}")
        if np.issubdtype(np.dtype(getattr(out, "dtype", np.float64)), np.complexfloating):
            raise ModelError(f"{what}: function returns a complex value ({out.dtype}); it must be real")
        return of_z

    def to_dict(self) -> dict:
        """JSON-ready dictionary (no callables).

        For a model with parameters it also holds ``unobservable_directions`` (the
        directions of :meth:`direction_summary` as ``{name: coefficient}``, None when they
        cannot be computed there), ``identifiable_combinations`` and ``directions_at``
        (``{"rule": ..., "point": {name: value}}``, plus ``"error"`` when the directions
        failed): the point is the centre of the sampling box of every state and parameter.
        Reports without parameters have no such keys.
        """
        return jsonable({
            "system": self.system_name,
            "method": self.method,
            "states": list(self.states),
            "dim": self.dim,
            "n": self.n,
            "fully_observable": self.fully_observable,
            "observable": dict(self.observable),
            "undecided": list(self.undecided),
            "params": list(self.params),
            "identifiable": dict(self.identifiable),
            "dims": list(self.dims),
            "history": [s.to_dict() for s in self.history],
            "generators": list(self.generators),
            "stop_reason": self.stop_reason,
            "certificate": self.certificate.to_dict(),
            "details": dict(self.details),
            "notes": list(self.notes),
            "semantics": self.semantics,
            "exact": self.exact,
            "known_inputs": self.known_inputs,
            **(self._directions_dict() if self.params else {}),
        })

    def _directions_dict(self) -> dict:
        """The direction keys of :meth:`to_dict` (at the centre of the sampling box)."""
        try:
            summary = self.direction_summary()
        except ModelError as exc:
            try:
                point = dict(zip(self.variables, self.domain_centre().tolist()))
            except ModelError:
                point = None
            return {"unobservable_directions": None, "identifiable_combinations": None,
                    "directions_at": {"rule": _CENTRE, "point": point, "error": str(exc)}}
        return {"unobservable_directions": summary["directions"],
                "identifiable_combinations": summary["identifiable_combinations"],
                "directions_at": {"rule": summary["rule"], "point": summary["point"]}}

    def answer_kind(self) -> str:
        """Which question the verdicts answer: exact, or a sufficient condition only.

        The ORC (Hermann-Krener rank condition, no unknown input), the series test (its
        final codistribution) and Martinelli's single-unknown-input codistribution are
        exact at generic states once the recursion converged; the EORC, or a recursion
        stopped by a cap (``max_order``, the step cap), shows observability sufficiently
        only: "observable" is proven, "not observable" means not shown. An EORC stopped at
        the known-input bound (:mod:`uio_jax._analysis.known_bound`) is exact: a state it
        does not show is not observable even with every input known; so is one whose states
        reach the bound of its verified symmetries (:mod:`uio_jax._analysis.symmetry`): a
        state it does not show is moved by a symmetry.
        """
        capped = any(t in self.stop_reason for t in ("reached before convergence",
                                                     "no convergence certified",
                                                     "no convergence within"))
        if self.method == "general_ui" and self.details.get("exact") is False and not capped:
            return ("not certified exact (general_ui: the jets of the known inputs may have "
                    "been truncated, see the notes): 'observable' is proven")
        bound = self.details.get("known_input_bound") if self.method == "eorc" else None
        symmetric = self.details.get("symmetries") if self.method == "eorc" else None
        by_symmetry = bool(symmetric and symmetric.get("reached_at") is not None)
        if self.method == "eorc" and not (by_symmetry or bound and bound.get("reached_at") is not None):
            return ("sufficient only (EORC): 'observable' is proven; 'not observable' means "
                    "not shown observable up to the last order k")
        if capped:
            return ("sufficient only (the recursion was capped before it converged): "
                    "'observable' is proven; 'not observable' means not shown")
        what = {"orc": "observability rank condition, no unknown input",
                "series": "rank of the output series, the ORC's final codistribution",
                "single_ui": "Martinelli's observable codistribution, one unknown input",
                "general_ui": "Martinelli's general solution, any number of unknown inputs",
                "eorc": "EORC at the bound of its verified symmetries: every state it does not "
                        "show is moved by one" if by_symmetry else
                        "EORC at the known-input bound: its span on the states is that of the "
                        "ORC with every input known"}
        meaning = {"smooth": "; known inputs generic smooth functions of time",
                   "switchable": "; known inputs switchable (may jump)"}.get(self.known_inputs, "")
        question = f"({what.get(self.method, self.method)}{meaning}): the observable functions at generic states"
        arithmetic = self.certificate.arithmetic
        if arithmetic is Arithmetic.EXACT:
            return f"exact {question}, every decision in exact arithmetic modulo p"
        return f"necessary and sufficient {question}; decided in {arithmetic.value}: not certified exact"

    @property
    def exact(self) -> bool:
        """Whether the verdicts are exact: the question is the necessary and sufficient one
        (not a sufficient condition) and every decision was made in exact arithmetic, with
        the probability bound of the certificate (:meth:`answer_kind`,
        :attr:`Certificate.arithmetic`)."""
        return self.answer_kind().startswith("exact")

    def to_json(self, **kw) -> str:
        """``json.dumps(self.to_dict())``."""
        return json.dumps(self.to_dict(), **kw)

    def __str__(self) -> str:
        title = f"uio_jax report: {printable(self.system_name or 'system')} ({self.method})"
        lines = [title, "=" * len(title), f"answer: {self.answer_kind()}"]
        obs = [s for s in self.states if self.observable[s]]
        of = f"{self.n}" + (" (states and parameters)" if self.params else "")
        lines.append(f"observable codistribution: dim {self.dim} of {of}"
                     + ("  (fully observable)" if self.fully_observable else ""))
        label = "k" if self.method in ("eorc", "series") else "m"
        lines.append("steps:")
        for st in self.history:
            extra = "".join(f", {k}={v}" for k, v in st.extra.items())
            added = ", ".join(st.added) if st.added else "-"
            lines.append(f"  {label}={st.m}: dim {st.dim}  (+ {added}{extra})")
        lines.append(f"stopped: {self.stop_reason}")
        for k, v in self.details.items():
            lines.append(f"{k}: {v}")
        lines.append("states:")
        width = max(len(s) for s in self.states)
        undecided = set(self.undecided)
        for s in self.states:
            verdict = "observable" if self.observable[s] else "not observable"
            if s in undecided:
                verdict = f"UNDECIDED (float64: {verdict})"
            lines.append(f"  {s:<{width}}  {verdict}")
        if not obs:
            lines.append("  (no single state component is observable)")
        if self.params:
            lines.append("parameters:")
            width = max(len(p) for p in self.params)
            for p in self.params:
                verdict = "identifiable" if self.identifiable[p] else "not identifiable"
                if p in undecided:
                    verdict = f"UNDECIDED (float64: {verdict})"
                lines.append(f"  {p:<{width}}  {verdict}")
        lines.append(f"certificate: {self.certificate}")
        for note in self.notes:
            lines.append(f"note: {note}")
        return "\n".join(map(printable, lines))  # no text from a model file reaches a terminal raw


_CENTRE = "centre of the sampling box of every state and parameter"
_OFF_CENTRE = ("a fixed point off the centre of the sampling box (the codistribution drops "
               "rank at the centre)")


def _point_text(names, z) -> str:
    return "(" + ", ".join(f"{k}={v:.3g}" for k, v in zip(names, z)) + ")"


def _rank_ratio_at(space, z):
    """``s_r / s_1`` of the space's generators at ``z`` (:meth:`Space.rank_ratio_at`), or
    None for a space that cannot evaluate them."""
    at = getattr(space, "rank_ratio_at", None)
    return None if at is None else at(z)


def _domain_of(space):
    """The sampling box ``name -> (lo, hi)`` behind a Report's space, or None."""
    domain = getattr(space, "domain", None)
    return domain if isinstance(domain, Mapping) else None


def _positional_arity(fn):
    """Required positional parameters of ``fn``; None when it takes ``*args`` or is opaque."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return None
    kinds = [q.kind for q in sig.parameters.values()]
    if inspect.Parameter.VAR_POSITIONAL in kinds:
        return None
    positional = [q for q in sig.parameters.values()
                  if q.kind in (q.POSITIONAL_ONLY, q.POSITIONAL_OR_KEYWORD)]
    required = sum(1 for q in positional if q.default is q.empty)
    return required if required or not positional else 1


def _linear_text(coefs) -> str:
    """``{"da": 1.0, "db": -0.5}`` -> ``"da - 0.5 db"`` (3 significant digits)."""
    out = ""
    for name, c in coefs.items():
        mag = abs(c)
        term = name if math.isclose(mag, 1.0, rel_tol=1e-6) else f"{mag:.3g} {name}"
        if not out:
            out = ("-" if c < 0 else "") + term
        else:
            out += (" - " if c < 0 else " + ") + term
    return out
