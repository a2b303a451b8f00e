"""Which inputs enter a right-hand side ``x' = f(x, p, u, w)`` non-affinely: the affinity test
of the split into the control-affine form (:mod:`uio_jax._io.affine`), and the reasons an
input is promoted to a state.

**Affinity check.** ``f`` is affine in the inputs ``v = (u, w)`` iff its Hessian in ``v``
vanishes identically. It is evaluated by forward-mode automatic differentiation to second
order in float64 (numpy "jets" ``(value, gradient, Hessian)`` run through the same
compiled expression closures as the JAX functions; they agree with ``jax.hessian`` to
round-off, see the tests, and cost milliseconds where compiling ``jax.hessian`` costs
seconds per model) at :data:`AFFINE_SAMPLES` random points ``(x, p, v)`` of the sampling boxes (states and
parameters in their boxes, inputs in their ``domain`` box or ``(0.5, 1.5)``). Input pair
``(a, b)`` (``a == b`` included) is declared non-affine when, at some sample where
everything is finite, for some state ``k``

    |H_kab| |v_a| |v_b| > AFFINE_RTOL * (|f_k| + sum_c |J_kc v_c| + TINY),

i.e. the second-order term is not negligible against the terms of ``f_k`` there.
The threshold: automatic differentiation of an expression graph that is affine in ``v``
gives exact zeros for the second derivatives, so affine models give ``H == 0`` exactly; only
identities such as ``exp(log(u))`` leave round-off (about ``1e-16`` relative), far below
``1e-8``, where a genuinely non-affine term (``u/(p + u)``, ``u**2``, ``u*w``) gives ``O(1)``.
An input that enters through ``abs``, ``sign``, ``min`` or ``max`` (not differentiable at 0)
is treated as non-affine without a test. The cross terms are covered as
:mod:`uio_jax._io.affine` says.
"""

from collections.abc import Mapping, Sequence

import numpy as np

from .._errors import ModelError
from .expression_functions import compile_raw
from .expressions import Binary, Call, Expr, Unary
from .jets import JET_OPS, Jet, jet_parts

#: Random points where the Hessian in the inputs is evaluated.
AFFINE_SAMPLES = 32
#: Relative size of a second-order term above which an input is non-affine (see module doc).
AFFINE_RTOL = 1e-8
#: Absolute floor of the scale (a row of f that is exactly 0 at a sample).
TINY = 1e-300
#: Sampling box of an input (affinity check, promoted state) without a ``domain`` entry.
INPUT_BOX = (0.5, 1.5)
#: Functions through which an input makes the model non-smooth: promoted without a test.
_NONSMOOTH = {"abs", "Abs", "sign", "min", "max", "Min", "Max"}


def compile_rows(exprs: Mapping[str, Expr], rows: Sequence[str], names: Sequence[str], constants):
    """One compiled expression per row (:func:`~uio_jax._io.expression_functions.compile_raw`,
    reading ``z`` by ``names``), None for a row absent from ``exprs`` (a zero row)."""
    return [compile_raw(exprs[r], names, constants) if r in exprs else None for r in rows]


def promotion_reasons(inputs, unknown_inputs, in_outputs, other, pattern, after=None) -> dict:
    """Input name -> why it is promoted to a state (the rules of the module doc, in order).

    Args:
        inputs: input names, known then unknown (the order of ``v``).
        unknown_inputs: the unknown ones (preferred when covering cross terms).
        in_outputs: inputs that appear in an output.
        other: input -> reason found before the Hessian test (non-smooth entry).
        pattern: ``() -> (m, m)`` boolean matrix of :func:`nonaffine_pattern`, called only
            when some input is left to test.
        after: input -> reason found by a test that applies to the inputs the Hessian
            test did not promote (before the cross terms are covered).
    """
    reasons = {v: "appears in an output" for v in inputs if v in in_outputs}
    reasons.update({v: other[v] for v in inputs if v in other and v not in reasons})
    if any(v not in reasons for v in inputs):
        pat = pattern()
        for a, v in enumerate(inputs):
            if pat[a, a] and v not in reasons:
                reasons[v] = "enters the dynamics non-affinely (second derivative in it is not 0)"
        reasons.update({v: after[v] for v in inputs if v in (after or {}) and v not in reasons})
        _cover_cross_terms(list(inputs), pat, reasons, set(unknown_inputs))
    return reasons


def inputs_in_nonsmooth(exprs, inputs):
    """The inputs that appear inside ``abs``, ``sign``, ``min`` or ``max`` in ``exprs``."""
    found = set()

    def walk(e, inside):
        if isinstance(e, Call):
            inside = inside or e.func in _NONSMOOTH
            for a in e.args:
                walk(a, inside)
        elif isinstance(e, Binary):
            walk(e.left, inside)
            walk(e.right, inside)
        elif isinstance(e, Unary):
            walk(e.operand, inside)
        elif inside and getattr(e, "id", None) in inputs:
            found.add(e.id)

    for e in exprs:
        walk(e, False)
    return found


def box(name, domain, angles, default):
    """Sampling box of ``name``: its ``domain`` entry, ``[-pi, pi)`` for an angle, else ``default``."""
    if name in domain:
        return tuple(map(float, domain[name]))
    if name in angles:
        return (-np.pi, np.pi)
    return default


def nonaffine_pattern(states, dynamics, inputs, params, constants, domain, angles, *, seed=0,
                      samples=AFFINE_SAMPLES) -> np.ndarray:
    """Boolean ``(m, m)`` matrix: entry ``(a, b)`` when ``d2 f / dv_a dv_b`` is not negligible.

    ``f`` is the dynamics (state -> Expr) on ``[x; p; v]`` with ``v = inputs``; the test
    and its threshold are in the module doc.

    Raises:
        ModelError: ``f`` is not finite at any of the samples.
    """
    pnames = tuple(params)
    names = tuple(states) + pnames + tuple(inputs)
    fns = compile_rows(dynamics, states, names, constants)
    zs = affine_points(sample_boxes(states, params, inputs, domain, angles), seed, samples)
    k, m = len(states) + len(pnames), len(inputs)
    z = [zs[:, i] for i in range(k)] + [Jet.seed(zs[:, k + a], m, a) for a in range(m)]
    with np.errstate(all="ignore"):
        parts = [jet_parts(0.0 if fn is None else fn(z, JET_OPS), (samples,), m) for fn in fns]
        f, J, H = (np.stack(a, 1) for a in zip(*parts))  # (S, n), (S, n, m), (S, n, m, m)
    return pattern_from_derivatives(f, J, H, zs[:, k:])


def affine_points(boxes, seed=0, samples=AFFINE_SAMPLES) -> np.ndarray:
    """The ``(samples, len(boxes))`` random points of the affinity test, uniform in ``boxes``."""
    lo = np.array([b[0] for b in boxes], dtype=np.float64).reshape(-1)
    hi = np.array([b[1] for b in boxes], dtype=np.float64).reshape(-1)
    return lo + (hi - lo) * np.random.default_rng(seed).random((samples, len(boxes)))


def sample_boxes(states, params, inputs, domain, angles) -> list:
    """Sampling boxes of ``[x; p; v]`` for the affinity test (module doc)."""
    from .._model.system import DEFAULT_BOX

    return ([box(s, domain, angles, DEFAULT_BOX) for s in states]
            + [tuple(map(float, params[q])) for q in params]
            + [box(v, domain, (), INPUT_BOX) for v in inputs])


def pattern_from_derivatives(f, J, H, v) -> np.ndarray:
    """The affinity test of the module doc on values at the samples.

    Args:
        f: ``(S, n)`` right-hand side; J: ``(S, n, m)`` its Jacobian in the inputs;
        H: ``(S, n, m, m)`` its Hessian in the inputs; v: ``(S, m)`` the inputs.

    Returns:
        ``(m, m)`` boolean: pair ``(a, b)`` has a non-negligible second-order term at a
        sample where everything is finite.

    Raises:
        ModelError: nothing is finite at any sample.
    """
    f, J, H, v = (np.asarray(a, dtype=np.float64) for a in (f, J, H, v))
    samples = f.shape[0]
    with np.errstate(all="ignore"):
        finite = np.isfinite(f).all(axis=1) & np.isfinite(J).all(axis=(1, 2)) & np.isfinite(H).all(axis=(1, 2, 3))
        if not finite.any():
            raise ModelError(
                f"the dynamics are not finite at any of {samples} sampled points "
                "(states, parameters and inputs in their boxes)"
            )
        f, J, H, v = f[finite], J[finite], H[finite], v[finite]
        scale = np.abs(f) + np.sum(np.abs(J * v[:, None, :]), axis=2) + TINY  # (S, n)
        second = np.abs(H) * np.abs(v)[:, None, :, None] * np.abs(v)[:, None, None, :]  # (S, n, m, m)
        big = second > AFFINE_RTOL * scale[:, :, None, None]
    return big.any(axis=(0, 1))


def _cover_cross_terms(inputs, pattern, reasons, unknown):
    """Promote inputs until no cross term u_a*u_b between two unpromoted inputs remains."""
    m = len(inputs)
    while True:
        alive = [a for a in range(m) if inputs[a] not in reasons]
        degree = {a: sum(1 for b in alive if b != a and (pattern[a, b] or pattern[b, a])) for a in alive}
        if not degree or max(degree.values()) == 0:
            return
        pick = max(alive, key=lambda a: (degree[a], inputs[a] in unknown, a))
        partners = [inputs[b] for b in alive if b != pick and (pattern[pick, b] or pattern[b, pick])]
        reasons[inputs[pick]] = f"multiplies input {', '.join(map(repr, partners))} (the dynamics are not affine)"


def vanishes(fn, boxes, seed=1, samples=AFFINE_SAMPLES) -> bool:
    """True when ``fn(z)`` is exactly 0 at every sampled ``z`` where it is finite.

    A drift ``f(x, p, 0, 0)`` of a model such as ``r' = v cos(theta)`` is exactly 0 in
    floating point (``0 * c == 0``); passing it on as a drift would send the analyses to
    the EORC, so it is dropped.
    """
    vals = np.array([fn(z) for z in affine_points(boxes, seed, samples)])
    finite = np.isfinite(vals).all(axis=1)
    return bool(finite.any()) and not np.any(vals[finite] != 0.0)


__all__ = ["AFFINE_RTOL", "AFFINE_SAMPLES", "INPUT_BOX", "TINY", "affine_points", "box", "compile_rows",
           "inputs_in_nonsmooth", "nonaffine_pattern", "pattern_from_derivatives", "promotion_reasons",
           "sample_boxes", "vanishes"]
