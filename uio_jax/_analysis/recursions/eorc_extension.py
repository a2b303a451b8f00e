"""The extended system ``Sigma^(K)`` of the EORC (004 eq. 4-7; :mod:`.eorc` runs on it):
the state augmented by the unknown inputs and their derivatives up to order ``K - 1``,
built on the expression graph from the System's own expressions."""

import weakref

from ..._calculus.generators import builder_for
from ..._engine.graph import Graph
from ..._model.graph_system import graph_system
from ..._model.naming import derivative_names
from ..._model.system import DEFAULT_BOX, System

_EXTENSIONS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def default_k_max(system: System) -> int:
    """Default highest order: ``n + 2`` (the bound of the single-input case, 004 section 9)."""
    return system.n + 2


def input_names(system: System, K: int) -> tuple[str, ...]:
    """Names of the extended coordinates ``w, w^(1), .., w^(K-1)`` (order-major).

    Each unknown input keeps its name for order 0 and gets ``^(d)`` for its d-th derivative;
    a clash with a state name gets a ``'`` appended
    (:func:`uio_jax._model.naming.derivative_names`).

    Returns:
        ``K * m_w`` names, ordered ``[w_1..w_mw, w_1^(1)..w_mw^(1), ...]`` as in 004 eq. 4.
    """
    return derivative_names(tuple(system.unknown), K, system.states, order_major=True)


def extended_system(system: System, K: int) -> System:
    """``Sigma^(K)`` of 004 section 4 as a :class:`~uio_jax.System` (cached per System and K).

    Args:
        system: the original System (``n`` states, ``m_w`` unknown inputs, ``m_u`` known).
        K: number of input orders in the extension (``K >= 1``).

    Returns:
        A System with ``n + K m_w`` states (``states + input_names``), the same outputs
        (functions of the first n coordinates), the known fields padded with zeros, the
        extended drift ``F0`` (eq. 6) and no unknown input (the last derivatives
        ``w^(K)`` enter only through unit vectors along which every Lie derivative of
        order ``<= K`` vanishes, Proposition 1 of 004).
    """
    per = _EXTENSIONS.setdefault(system, {})
    ext = per.get(K)
    if ext is not None:
        return ext
    n, mw = system.n, len(system.unknown)
    names = input_names(system, K)
    N = n + K * mw
    b = builder_for(system)  # the System's expressions, imported into the extension's graph
    g = Graph(N)
    x, xi = g.coords[:n], g.coords[n:]
    w = xi[:mw]

    def pad(nodes):  # a function of x, as a function of X = [x; xi]
        return g.import_nodes(b.graph, list(nodes), x)

    fields = {k: b.translate(f, (n,), f"known field {k!r}") for k, f in system.known.items()}
    dx = [g.zero] * n if system.drift is None else pad(b.translate(system.drift, (n,), "drift"))
    for j, (k, f) in enumerate(system.unknown.items()):
        dx = [g.add(d, g.mul(gi, w[j])) for d, gi in zip(dx, pad(b.translate(f, (n,), f"unknown field {k!r}")))]
    F0 = tuple(dx) + tuple(xi[mw:]) + (g.zero,) * mw
    domain = dict(system.domain)
    domain.update({nm: DEFAULT_BOX for nm in names})
    ext = graph_system(
        g, system.states + names,
        {k: pad([b.translate(h, (), f"output {k!r}")])[0] for k, h in system.outputs.items()},
        known={k: tuple(pad(f)) + (g.zero,) * (N - n) for k, f in fields.items()},
        drift=F0, domain=domain, angles=system.angles,
        name=f"{system.name or 'system'} extended to order {K}")
    per[K] = ext
    return ext


__all__ = ["default_k_max", "input_names", "extended_system"]
