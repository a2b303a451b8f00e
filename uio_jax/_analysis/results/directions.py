"""A Report's unobservable directions: at which point, labelled, as text and as JSON.

The directions are the null space of the final codistribution at a point (the continuous
symmetries of the system); the point is the centre of the sampling box when the
codistribution has its generic rank there, else a fixed point off the centre
(:func:`representative_point`). :class:`~uio_jax.Report` delegates its direction methods
here, with the sampled space behind it (``space``: what evaluates the final generators).
"""

import math
from collections.abc import Mapping

import numpy as np

from ..._errors import ModelError
from ..._output import abridged, wrapped

CENTRE = "centre of the sampling box of every state and parameter"
OFF_CENTRE = ("a fixed point off the centre of the sampling box (the codistribution drops "
              "rank at the centre)")


def domain_centre(report, space) -> np.ndarray:
    """The representative point of the report: the centre of the sampling box.

    Returns:
        ``(n,)`` array ``z = [x; p]``: for every state and then every parameter
        (:attr:`variables`), the midpoint of its sampling box (``System.domain``,
        the ``params=`` boxes).

    Raises:
        ModelError: the report does not know the sampling box (built by hand).
    """
    domain = domain_of(space)
    if domain is None or any(v not in domain for v in report.variables):
        raise ModelError("this report does not know the sampling box of its variables")
    return np.array([0.5 * (float(domain[v][0]) + float(domain[v][1]))
                     for v in report.variables])


def point(report, space, x, p, what) -> np.ndarray:
    """``z = [x; p]`` from ``z`` or ``(x, p)`` (shapes checked, ModelError otherwise)."""
    ns, npar = len(report.states), len(report.params)
    forms = (f"a state of shape ({report.n},)" if not npar else
             f"z = [x; p] of shape ({report.n},) or (x, p) with x ({ns},), p ({npar},)")
    if x is None:
        if p is not None:
            raise ModelError(f"{what} needs {forms}; got p without x")
        return domain_centre(report, space)
    try:
        x = np.asarray(x, dtype=np.float64)
        p = None if p is None else np.asarray(p, dtype=np.float64)
    except (TypeError, ValueError):
        raise ModelError(f"{what} needs {forms}; got a non-numeric point") from None
    if p is None:
        if x.shape != (report.n,):
            raise ModelError(f"{what} needs {forms}; got shape {x.shape}")
        return x
    if not npar:
        raise ModelError(f"{what}: this model has no parameters; give {forms}")
    if x.shape != (ns,) or p.shape != (npar,):
        raise ModelError(f"{what} needs {forms}; got x {x.shape}, p {p.shape}")
    return np.concatenate([x, p])


def direction_summary(report, space, x=None, p=None) -> dict:
    """The unobservable directions at a point, labelled by the variables' names.

    Each direction (a column of :meth:`unobservable_directions`, unit norm, not unique when
    there are several) is signed so that its largest component is positive; components below
    ``1e-12`` are set to 0. For a model with parameters, the identifiable parameter
    combinations are given by their differentials at the point: the covectors ``c`` on the
    parameters that are not identifiable one by one with ``[0; c]`` in the codistribution
    (for ``x' = -(a + b) x``: ``da + db``, the differential of ``a + b``).

    Args:
        x, p: the point, as in :meth:`unobservable_directions` (default: the centre
            of the sampling box).

    Returns:
        ``{"point": {name: value}, "directions": [{name: coefficient}, ...],
        "identifiable_combinations": [{param: coefficient}, ...]}`` (combination
        coefficients scaled so that the largest magnitude is 1).
    """
    if x is None and p is None:
        z, rule = representative_point(report, space)
    else:
        z, rule = point(report, space, x, p, "direction_summary"), "the given point"
    names = report.variables
    if report.dim >= report.n:
        dirs = np.zeros((report.n, 0))
    else:
        ratio = rank_ratio_at(space, z)
        if ratio is not None and not ratio > report.certificate.rtol:
            raise ModelError(f"the codistribution drops rank at {point_text(names, z)} "
                             f"(s_r/s_1 = {ratio:.1e} <= rtol {report.certificate.rtol:.0e}):"
                             " its directions there are not the generic ones")
        dirs = np.asarray(space.unobservable_directions(z), dtype=float)
    out = []
    for j in range(dirs.shape[1]):
        v = np.where(np.abs(dirs[:, j]) < 1e-12, 0.0, dirs[:, j])
        lead = int(np.argmax(np.round(np.abs(v), 9)))
        v = -v if v[lead] < 0 else v
        out.append({nm: float(c) + 0.0 for nm, c in zip(names, v)})
    return {"point": {nm: float(c) for nm, c in zip(names, z)}, "rule": rule,
            "directions": out, "identifiable_combinations": combinations(report, dirs)}


def representative_point(report, space) -> tuple[np.ndarray, str]:
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
    centre = domain_centre(report, space)
    domain, rtol = domain_of(space), report.certificate.rtol
    if report.dim >= report.n:
        return centre, CENTRE
    width = np.array([float(domain[v][1]) - float(domain[v][0]) for v in report.variables])
    for j in range(4):
        t = 2.0 * np.modf((np.arange(report.n) + 1.0) * (0.6180339887 + 0.1 * j))[0] - 1.0
        z = centre if j == 0 else centre + 0.3 * width * t
        ratio = rank_ratio_at(space, z)
        if ratio is None or ratio > rtol:
            return z, (CENTRE if j == 0 else OFF_CENTRE)
    raise ModelError("the codistribution drops rank at the centre of the sampling box and "
                     "at the points tried around it; give a point to unobservable_directions")


def combinations(report, dirs) -> list:
    """Identifiable parameter combinations (by differential) orthogonal to ``dirs``."""
    ns = len(report.states)
    hidden = [j for j, nm in enumerate(report.params) if not report.identifiable.get(nm, False)]
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
        combos.append({report.params[j]: float(v) + 0.0 for j, v in zip(hidden, c) if v != 0.0})
    return combos


#: A point with more coordinates than this is printed abridged (its first and last ones).
POINT_NAMES = 12


def format_directions(report, space, summary=None) -> str:
    """:meth:`Report.format_directions`: the point (abridged past :data:`POINT_NAMES`
    coordinates), then one line per direction (a long one wrapped) and per identifiable
    combination."""
    summary = direction_summary(report, space) if summary is None else summary
    coords = [f"{k}={v:.3g}" for k, v in summary["point"].items()]
    at = abridged(coords) if len(coords) <= POINT_NAMES else f"{len(coords)} coordinates: {abridged(coords)}"
    known = getattr(space, "known_point", dict)()
    if known:  # a time-varying System: the directions hold at this time
        at += "; " + ", ".join(f"{k}={v:.3g}" for k, v in known.items())
    where = {CENTRE: "the centre of the domain",
             OFF_CENTRE: "the centre of the domain: the rank drops there; instead at"}
    lines = [f"unobservable directions at {where.get(summary.get('rule'), 'the point')} "
             f"({at}):"]
    if not summary["directions"]:
        lines.append("  none")
    for d in summary["directions"]:
        terms = [f"{c:+.3f} {k}" for k, c in d.items() if abs(c) >= 5e-4]
        lines.append("  " + "  ".join(terms))
    for c in summary["identifiable_combinations"]:
        lines.append("identifiable combination (its differential at this point): "
                     + linear_text({f"d{k}": v for k, v in c.items()}))
    return wrapped("\n".join(lines))


def directions_dict(report, space) -> dict:
    """The direction keys of :meth:`to_dict` (at the centre of the sampling box)."""
    try:
        summary = direction_summary(report, space)
    except ModelError as exc:
        try:
            point = dict(zip(report.variables, domain_centre(report, space).tolist()))
        except ModelError:
            point = None
        return {"unobservable_directions": None, "identifiable_combinations": None,
                "directions_at": {"rule": CENTRE, "point": point, "error": str(exc)}}
    return {"unobservable_directions": summary["directions"],
            "identifiable_combinations": summary["identifiable_combinations"],
            "directions_at": {"rule": summary["rule"], "point": summary["point"]}}


def point_text(names, z) -> str:
    """``(a=1, b=2)``: a point by the names of its coordinates (3 significant digits)."""
    return "(" + ", ".join(f"{k}={v:.3g}" for k, v in zip(names, z)) + ")"


def rank_ratio_at(space, z):
    """``s_r / s_1`` of the space's generators at ``z`` (:meth:`Space.rank_ratio_at`), or
    None for a space that cannot evaluate them."""
    at = getattr(space, "rank_ratio_at", None)
    return None if at is None else at(z)


def domain_of(space):
    """The sampling box ``name -> (lo, hi)`` behind a Report's space, or None."""
    domain = getattr(space, "domain", None)
    return domain if isinstance(domain, Mapping) else None


def linear_text(coefs) -> str:
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


__all__ = ["CENTRE", "OFF_CENTRE", "combinations", "direction_summary", "directions_dict", "domain_centre",
           "format_directions", "point", "representative_point"]
