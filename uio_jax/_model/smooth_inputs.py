"""Known inputs as generic smooth functions of time: their jets as known coordinates.

Two meanings of a known input ``u`` in ``x' = f0 + sum_i u_i f_i + sum_j w_j g_j``:

* **switchable** (the default, Martinelli's single-input papers and the classical ORC/EORC):
  ``u`` may be chosen freely and may jump, so the analyses close under every raw field
  ``f_i`` separately;
* **smooth** (TUIO6, Martinelli's general solution): ``u`` is a generic smooth function of
  time, known with all its derivatives. Its jet ``u, u^(1), .., u^(R)`` enters the drift
  ``g0 = f0 + sum_i u_i f_i``, and the analyses take total time derivatives along ``g0``::

      D theta = L_g0 theta + sum_{i, r} u_i^(r+1) d theta / d u_i^(r).

This module builds the autonomous System on ``[z; u_1^(0..R); ..]`` whose drift is
``[g0; u^(1..R); 0]``: a Lie derivative along it IS the total derivative ``D``, exact up to
order ``R + 1``. Every jet coordinate is measured (an output): the ``dz`` part of a
codistribution that holds every ``du^(r)`` is then the codistribution "with respect to the
state only" that the papers define.
"""

import weakref

import numpy as np

from .._engine.graph_trace import graph_native
from .derivation import Derivation
from .joint import Coordinate, PaddedFunction
from .naming import derivative_names
from .system import DEFAULT_BOX, System, derived_system

_WITH_JETS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()  # System -> {R: System}

#: The two meanings of a known input (``analyze(known_inputs=...)``).
KNOWN_INPUT_MEANINGS = ("switchable", "smooth")


def jet_names(system: System, order: int) -> tuple[str, ...]:
    """Names of the jet coordinates ``u_i^(r)``, ``r = 0..order`` (input-major).

    Order 0 keeps the input's name, order r gets ``^(r)``; a clash with a state name gets a
    ``'`` appended (:func:`uio_jax._model.naming.derivative_names`).
    """
    return derivative_names(tuple(system.known), order + 1, system.states)


def with_input_jets(system: System, order: int) -> System:
    """The System whose drift carries the known inputs as jets up to ``order``.

    Args:
        system: a parameter-free System (``System.joint()``) with ``N`` states, ``mu``
            known inputs.
        order: ``R``, the highest jet order (``>= 0``).

    Returns:
        A System on ``N + mu (R + 1)`` states (``states + jet_names``): drift
        ``[f0 + sum_i u_i f_i; u^(1); ..; u^(R); 0]`` per input, the unknown fields padded
        with zeros, NO known field, and outputs = the System's outputs plus one output per
        jet coordinate; its ``known_coordinates`` are ``mu (R + 1)`` plus those of ``system``.
        A System without known inputs is returned unchanged. Cached per System and order.
    """
    mu = len(system.known)
    if mu == 0:
        return system
    cached = _WITH_JETS.setdefault(system, {}).get(int(order))
    if cached is not None:
        return cached
    N = system.n
    R = int(order)
    names = jet_names(system, R)
    outputs = {k: PaddedFunction(h, N, 0, rest=False) for k, h in system.outputs.items()}
    jet_outputs = []
    for j, nm in enumerate(names):
        key = nm
        while key in outputs:
            key += "'"
        outputs[key] = Coordinate(N + j)
        jet_outputs.append(key)
    domain = dict(system.domain)
    domain.update({nm: DEFAULT_BOX for nm in names})
    with derived_system():  # the validated System's functions, padded
        out = System(
            states=system.states + names,
            outputs=outputs,
            unknown={k: PaddedFunction(g, N, mu * (R + 1), rest=False) for k, g in system.unknown.items()},
            drift=_JetDrift(system.drift, tuple(system.known.values()), N, R),
            domain=domain,
            angles=system.angles,
            name=system.name,
            notes=system.notes,
            derivation=Derivation(known_coordinates=known_coordinates(system) + mu * (R + 1),
                                  known_outputs=known_outputs(system) + tuple(jet_outputs)),
        )
    _WITH_JETS[system][R] = out
    return out


class _JetDrift:
    """``Z -> [f0(z) + sum_i u_i^(0) f_i(z); u^(1); ..; u^(R); 0]`` per input, ``z = Z[:N]``
    (``f0`` None: no drift)."""

    __slots__ = ("drift", "fields", "N", "R", "__weakref__")

    def __init__(self, drift, fields, N, R):
        self.drift, self.fields, self.N, self.R = drift, fields, N, R

    @property
    def graph_native(self) -> bool:
        return all(graph_native(f) for f in (self.drift, *self.fields) if f is not None)

    def __call__(self, Z):
        N, R, mu = self.N, self.R, len(self.fields)
        if isinstance(Z, np.ndarray):
            xp = np
        else:
            import jax.numpy as xp
        z, jets = Z[:N], Z[N:].reshape((mu, R + 1))
        dz = xp.zeros(N, dtype=Z.dtype) if self.drift is None else self.drift(z)
        for i, f in enumerate(self.fields):
            dz = dz + jets[i, 0] * f(z)
        chain = xp.concatenate([jets[:, 1:], xp.zeros((mu, 1), dtype=Z.dtype)], axis=1)
        return xp.concatenate([dz, chain.reshape(-1)])

    def emit(self, Z):
        if not self.graph_native:
            return None
        N, R, mu = self.N, self.R, len(self.fields)
        z, jets = Z[:N], Z[N:].reshape((mu, R + 1))
        dz = [0.0] * N if self.drift is None else list(self.drift.emit(z))
        for i, f in enumerate(self.fields):
            dz = [a + jets[i, 0] * b for a, b in zip(dz, f.emit(z))]
        return dz + [v for i in range(mu) for v in (*jets[i, 1:], 0.0)]


def known_coordinates(system: System) -> int:
    """How many trailing coordinates of ``system`` are known quantities (time, jets of
    smooth known inputs): 0 for a user's System."""
    return int(getattr(system, "known_coordinates", 0))


def known_outputs(system: System) -> tuple[str, ...]:
    """Names of the outputs of ``system`` that measure its known coordinates (the time
    of :meth:`System.autonomous`, the jets of :func:`with_input_jets`)."""
    return system.known_outputs
