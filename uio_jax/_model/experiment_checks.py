"""An experiment's checks before a Monte Carlo run: memory and the time scale of its dynamics.

:func:`memory_bytes` and :func:`check_memory` for the memory of a run; :func:`time_scale` and
:func:`time_scale_messages` for the shortest time scale of the filter's dynamics at the true
start. :class:`~uio_jax.Experiment` delegates to them (and warns).
"""

import math
import os

import numpy as np

from .._errors import OptionError

#: Warn when the shortest time scale of the dynamics is shorter than this many Euler steps
#: (``rate * dt`` above it; see :meth:`Experiment.time_scale`).
MAX_RATE_DT = 1.0
#: Warn when the whole trial lasts less than this fraction of that time scale.
MIN_RATE_HORIZON = 1e-2
#: Warn when a trial has fewer Euler steps (``dt`` above a tenth of the horizon).
MIN_STEPS = 10
#: A run may use at most this fraction of the memory available (:meth:`Experiment.check_memory`).
MEMORY_FRACTION = 0.8
#: Bytes per recorded number at the peak of a run: the float32 records, their concatenation
#: and the float64 copies the statistics make (4 + 4 + 8).
BYTES_PER_RECORD_NUMBER = 16


def memory_bytes(exp, trials: int, keep: int = 0) -> int:
    """Estimated peak memory (bytes) of a run of ``trials`` trials keeping ``keep``
    full trajectories.

    Records: ``trials * (n_records + 1) * (2 N + 2 d + 1)`` numbers at
    ``BYTES_PER_RECORD_NUMBER`` (16) bytes each; the filter carries (``N^2 + 4 N``
    float64 per trial, in and out); per kept trajectory the float64 arrays of
    :func:`~uio_jax.trajectories` (``(n_epochs + 1) (2 n + 2 N [+ N^2 when keep <= 4])``
    and ``n_steps * m`` readings), three copies (device, host, concatenated).
    """
    N, n = exp.n_aug, exp.n
    d, m = len(exp.quantities), len(exp.system.known)
    E = exp.n_epochs
    records = trials * (exp.n_records + 1) * (2 * N + 2 * d + 1) * BYTES_PER_RECORD_NUMBER
    carry = trials * (N * N + 4 * N + len(exp.istate0)) * 8 * 2
    per_traj = (E + 1) * (2 * n + 2 * N + (N * N if keep <= 4 else 0)) \
        + E * len(exp.measurements) + exp.n_steps * m
    return int(records + carry + keep * per_traj * 8 * 3)


def check_memory(exp, trials: int, keep: int = 0) -> int:
    """:meth:`uio_jax.Experiment.check_memory`: refuse a run whose :func:`memory_bytes`
    exceeds ``MEMORY_FRACTION`` of the memory available (OptionError); returns the estimate."""
    need, have = memory_bytes(exp, trials, keep), memory_available()
    if have is not None and need > MEMORY_FRACTION * have:
        raise OptionError(f"experiment {exp.name!r}: {trials} trials of {exp.n_steps} steps "
                          f"({exp.n_records + 1} records each, {keep} kept) need about "
                          f"{gib(need)} of memory, more than the {gib(have)} available: "
                          "fewer trials, a larger record_every or fewer n_steps")
    return need


def start_jacobian(exp):
    """``(f, D)``: the vector field at ``(x0, u0, w0)`` and ``d f / d(x, w)`` there,
    ``u0`` the input law's known inputs at ``z = 0``."""
    import jax
    import jax.numpy as jnp

    s = exp.system
    n, m = s.n, len(s.known)
    drift, known, unknown = s.drift, tuple(s.known.values()), tuple(s.unknown.values())

    def flow(xw, u):
        x = xw[:n]
        dx = drift(x) if drift is not None else jnp.zeros(n, x.dtype)
        for i, f in enumerate(known):
            dx = dx + f(x) * u[i]
        for j, g in enumerate(unknown):
            dx = dx + g(x) * xw[n + j]
        return dx

    def values(xw, istate0):
        _, u, _ = exp.inputs(istate0, jnp.zeros(exp.n_input_normals))
        u = jnp.asarray(u, jnp.float64).reshape(m)
        return flow(xw, u), jax.jacfwd(flow)(xw, u)

    xw = np.concatenate([np.asarray(exp.x0, np.float64), np.asarray(exp.w0, np.float64)])
    with jax.enable_x64(True):
        return jax.jit(values)(xw, np.asarray(exp.istate0, np.float64))


def time_scale(exp, values=None) -> dict:
    """The shortest time scale of ``exp``'s dynamics at the true start: the dict of
    :meth:`uio_jax.Experiment.time_scale` (see there), computed afresh."""
    s = exp.system
    n, p = s.n, len(s.unknown)
    if values is None:
        values = start_jacobian(exp)
    f, D = (np.asarray(v, np.float64) for v in values)
    N = exp.n_aug
    A = np.zeros((N, N))
    A[:n, :n + p] = D
    for k in range(exp.order - 1):  # w^(k)' = w^(k+1)
        A[n + k * p:n + (k + 1) * p, n + (k + 1) * p:n + (k + 2) * p] = np.eye(p)
    F = np.concatenate([f, np.zeros(N - n)])  # the derivatives of w start at 0
    prior = np.asarray(exp.prior_std, np.float64)
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(F))):
        eig = coupling = motion = math.nan
    else:
        eig = float(np.max(np.abs(np.linalg.eigvals(A)))) if N else 0.0
        keep = prior > 0
        Sk = prior[keep]
        scaled = A[np.ix_(keep, keep)] * Sk[None, :] / Sk[:, None]
        coupling = float(np.linalg.norm(scaled, 2)) if keep.any() else 0.0
        motion = float(np.max(np.abs(F[keep]) / Sk)) if keep.any() else 0.0
    rate = max(eig, coupling, motion)
    return {"rate": rate, "time_scale_s": (1.0 / rate if rate > 0 else math.inf),
            "eigen_rate": eig, "coupling_rate": coupling, "motion_rate": motion,
            "rate_dt": rate * exp.dt, "rate_horizon": rate * exp.duration}


def time_scale_messages(exp, ts) -> list[str]:
    """Why ``dt`` or the horizon of ``exp`` is far from its dynamics' time scale ``ts``
    (:func:`time_scale`), one message per criterion met (criteria: the module doc of
    :mod:`uio_jax._model.experiment`); empty when none is."""
    msgs = []
    what = f"experiment {exp.name!r}: dt={exp.dt:.4g} s"
    if math.isfinite(ts["rate"]) and ts["rate"] > 0:
        tau = ts["time_scale_s"]
        if ts["rate_dt"] > MAX_RATE_DT:
            msgs.append(f"{what} is {ts['rate_dt']:.3g} times the dynamics' shortest time "
                        f"scale {tau:.3g} s at the start (an Euler step moves the state by "
                        "more than its prior std or outruns the fastest mode): lower dt")
        if ts["rate_horizon"] < MIN_RATE_HORIZON:
            msgs.append(f"{what}: the trial ({exp.n_steps} steps, {exp.duration:.3g} s) "
                        f"lasts {ts['rate_horizon']:.3g} of the dynamics' time scale "
                        f"{tau:.3g} s: nothing moves; raise dt or n_steps")
    if exp.n_steps < MIN_STEPS:
        msgs.append(f"{what} is more than a tenth of the horizon ({exp.n_steps} Euler steps "
                    f"of {exp.duration:.3g} s): raise n_steps")
    return msgs


def memory_available():
    """Bytes of memory available (``MemAvailable`` of /proc/meminfo, else the physical
    memory), or ``None`` when unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def gib(nbytes) -> str:
    """``nbytes`` in GiB, 3 significant digits."""
    return f"{nbytes / 2**30:.3g} GiB"


__all__ = ["BYTES_PER_RECORD_NUMBER", "MAX_RATE_DT", "MEMORY_FRACTION", "MIN_RATE_HORIZON", "MIN_STEPS",
           "check_memory", "gib", "memory_available", "memory_bytes", "start_jacobian", "time_scale",
           "time_scale_messages"]
