"""SIAN's differential equations as polynomials: the model in jet variables.

A rational model ``x_i' = P_i / Q_i``, ``y_j = P_j / Q_j`` (numerators and denominators
polynomials in the states ``x``, the parameters ``mu`` and the known inputs ``u``; the
fractions of :mod:`.rational`) becomes the polynomials

    X_i^(0) = Q_i x_i^(1) - P_i,        Y_j^(0) = Q_j y_j^(0) - P_j,

in *jet variables*: ``x_i^(k)``, ``u^(k)``, ``y_j^(k)`` stand for the ``k``-th derivatives at
``t = 0``, the parameters for themselves. Their ``k``-th total derivatives ``X_i^(k)``,
``Y_j^(k)`` (``D x^(k) = x^(k+1)``, ``D mu = 0``, by the product rule) are the equations the
Taylor coefficients satisfy: ``X_i^(k)`` is linear in its leader ``x_i^(k+1)`` with coefficient
``Q_i`` (the separant), ``Y_j^(k)`` linear in ``y_j^(k)`` with coefficient ``Q_j``. The
derivatives of the states stay variables (SIAN's choice) instead of being eliminated into
Lie derivatives, so the degrees stay those of the model.

``Q`` is the least common multiple of the denominators: the solutions that count are those
with ``Q != 0``, imposed by a new variable ``z`` and the equation ``z Q - 1 = 0`` (the
saturation). ``d0``, the largest degree of ``Q`` and of the numerators of ``Q x_i'``,
``Q y_j``, enters SIAN's probability bound (:mod:`.sample`).
"""

import functools

from ..._calculus.generators import builder_for
from ..._errors import ModelError, OptionError
from .rational import Fractions, flint_fmpq, fraction_sum, normal_fraction


def flint_module():
    """python-flint, imported when the global question is asked (the optional extra)."""
    try:
        import flint
    except ImportError:
        raise OptionError("global identifiability needs python-flint and msolve: pip install 'uio_jax[global]'") \
            from None
    return flint


#: The key of the saturating variable ``z`` (not an identifier: no model name can take it).
SATURATION = "<z>"


class JetRing:
    """The variables of the jet polynomials and their total derivative.

    Args:
        states, params, inputs, outputs: the names.
        functions: names of functions of the unknowns asked about (one variable each).
        top: the highest order of every jet (``x_i^(0..top)``, ``u^(0..top)``, ``y^(0..top)``).

    Attributes:
        ctx: the ``fmpq_mpoly`` context; variable ``i`` is called ``v{i}`` there.
        labels: per variable its reading name: ``x1^(2)``, ``k``, ``z``.
        kinds: per variable ``"state"``, ``"param"``, ``"input"``, ``"output"``, ``"function"`` or
            ``"z"``.
    """

    def __init__(self, states, params, inputs, outputs, top, functions=()):
        self.top = int(top)
        self.labels, self.kinds, self.index, self.base = [], [], {}, []
        for kind, names in (("state", states), ("input", inputs), ("output", outputs)):
            for name in names:
                for k in range(self.top + 1):
                    self._add(kind, name, k)
        for name in params:
            self._add("param", name, 0)
        for name in functions:
            self._add("function", name, 0)
        self._add("z", SATURATION, 0)
        flint = flint_module()
        self.ctx = flint.fmpq_mpoly_ctx.get(tuple(f"v{i}" for i in range(len(self.labels))), ordering="degrevlex")
        self.gens = self.ctx.gens()

    def _add(self, kind, name, order):
        i = len(self.labels)
        self.index[(name, order)] = i
        label = "z (saturation)" if kind == "z" else name if kind in ("param", "function") else f"{name}^({order})"
        self.labels.append(label)
        self.kinds.append(kind)
        self.base.append((name, order))

    def var(self, name, order=0):
        """The polynomial of jet variable ``name^(order)`` (a parameter: order 0)."""
        return self.gens[self.index[(name, order)]]

    def occurring(self, poly) -> list[int]:
        """The variables that occur in ``poly``."""
        return [i for i, d in enumerate(poly.degrees()) if d > 0]

    def derivative(self, poly):
        """The total derivative ``D poly``: ``sum_v (d poly / d v) D v`` over the jet
        variables, ``D v^(k) = v^(k+1)``, parameters and ``z`` constant.

        Raises:
            OptionError: a jet past ``top`` would be needed (the ring is too short).
        """
        out = self.ctx.constant(0)
        for i in self.occurring(poly):
            kind = self.kinds[i]
            if kind in ("param", "z", "function"):
                continue
            name, k = self.base[i]
            if k >= self.top:
                raise OptionError(f"global identifiability: the derivative of {self.labels[i]} is past the "
                                  f"highest order {self.top} of this run")
            out += poly.derivative(i) * self.gens[self.index[(name, k + 1)]]
        return out


class ModelEquations:
    """SIAN's equations ``X_i^(k)``, ``Y_j^(k)`` of one System, built on demand.

    Args:
        system: a :class:`~uio_jax.System` without unknown inputs or explicit time.
        top: the highest jet order of the ring.
        functions: ``{name: graph node}`` of functions of the unknowns asked about, nodes of
            the joint System's graph (:func:`~.functions.function_nodes`).

    Attributes:
        ring: the :class:`JetRing`.
        Q: the saturating polynomial (order-0 variables).
        d0: SIAN's degree ``d0``.
    """

    def __init__(self, system, top, functions=None):
        joint = system.joint()
        functions = dict(functions or {})
        self.states, self.params = tuple(system.states), tuple(system.params)
        self.inputs, self.outputs = tuple(joint.known), tuple(joint.outputs)
        self.functions = tuple(functions)
        self.ring = ring = JetRing(self.states, self.params, self.inputs, self.outputs, top, self.functions)
        self.builder = builder = builder_for(joint)
        coords = [ring.var(s) for s in self.states] + [ring.var(p) for p in self.params]
        names = list(self.states) + list(self.params)
        fractions = Fractions(builder.graph, coords, names)
        n = len(self.states)
        zero = (ring.ctx.constant(0), ring.ctx.constant(1))
        rhs = ([fractions.of(list(builder.field("f0", joint.drift).expr)[:n])] if joint.drift is not None
               else [[zero] * n])[0]
        for u, fn in joint.known.items():
            field = fractions.of(list(builder.field(u, fn).expr)[:n])
            rhs = [fraction_sum(a, _times(ring.var(u), b)) for a, b in zip(rhs, field)]
        outs = fractions.of([builder.scalar(k, fn).expr for k, fn in joint.outputs.items()])
        self.fractions = fractions
        fractions.what = "a function asked about"
        self.function_fractions = fractions.of(list(functions.values()))
        fractions.what = "the model"
        self.X = [[den * ring.var(s, 1) - num] for s, (num, den) in zip(self.states, rhs)]
        self.Y = [[den * ring.var(y, 0) - num] for y, (num, den) in zip(self.outputs, outs)]
        both = list(rhs) + list(outs)
        self.Q = q = functools.reduce(_lcm, (den for _, den in both), ring.ctx.constant(1))
        self.d0 = max([1, int(q.total_degree())] + [int((num * (q / den)).total_degree()) for num, den in both])

    def x_equation(self, i: int, k: int):
        """``X_i^(k)``: the ``k``-th total derivative of state ``i``'s equation."""
        return self._derivative(self.X[i], k)

    def y_equation(self, j: int, k: int):
        """``Y_j^(k)``: the ``k``-th total derivative of output ``j``'s equation."""
        return self._derivative(self.Y[j], k)

    def _derivative(self, eqs, k):
        """``eqs[k]``, the list of an equation's total derivatives extended up to order ``k``."""
        while len(eqs) <= k:
            eqs.append(self.ring.derivative(eqs[-1]))
        return eqs[k]

    def function_equation(self, k: int):
        """``den w - num`` of the ``k``-th function ``num / den`` asked about (``w`` its variable)."""
        num, den = self.function_fractions[k]
        return den * self.ring.var(self.functions[k]) - num

    def initial_equation(self, state: str, value):
        """The polynomial ``x^(0) - value`` of a known initial state: ``value`` a
        :class:`~fractions.Fraction`, a parameter name, or a ``(num, den)`` fraction of the
        parameters (``den x^(0) - num``)."""
        x = self.ring.var(state, 0)
        if isinstance(value, str):
            return x - self.ring.var(value)
        if isinstance(value, tuple):
            num, den = value
            return den * x - num
        return x - self.ring.ctx.constant(flint_fmpq(value))


def _times(poly, frac):
    num, den = frac
    return normal_fraction(poly * num, den)


def _lcm(a, b):
    if a.is_constant():
        return b
    if b.is_constant():
        return a
    return a * (b / a.gcd(b))


def refuse_unsupported(system) -> None:
    """Refuse in one line what SIAN's theorem does not cover (OptionError)."""
    if system.unknown:
        raise OptionError("global identifiability with unknown inputs is not decided by any tool: SIAN's "
                          f"theorem covers known inputs only (unknown: {', '.join(system.unknown)})")
    if system.time is not None:
        raise OptionError("global identifiability of a time-varying System is not supported: make time a state "
                          "with t' = 1 and a known initial value")
    if not system.outputs:
        raise ModelError("a System needs at least one output")


__all__ = ["SATURATION", "JetRing", "ModelEquations", "refuse_unsupported", "flint_module"]
