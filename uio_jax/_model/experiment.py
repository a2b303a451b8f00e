"""A Monte Carlo experiment as data: the system, the true inputs' law, noises, rates, prior.

An :class:`Experiment` lives in the model zoo next to the :class:`~uio_jax.System` it
simulates (``systems/unicycle_disturbance.py:range_gamma_known_experiment``). It says

* how the truth moves: Euler steps of ``system`` at ``dt``, driven by true inputs drawn by
  ``inputs(istate, z) -> (istate, u, w)`` from standard normals ``z`` every step;
* what the filter reads: known inputs ``u + known_std(u) * N(0, 1)`` every step and the
  outputs of ``measurements`` (each with its own period, a multiple of ``dt``);
* what the filter assumes: each unknown input ``w`` augmented by ``order - 1`` derivatives
  (``w' = w1``, ..., top derivative ``= 0`` plus white noise of spectral density ``q_aug``),
  a white part ``w_white_std`` of ``w`` itself, and a Gaussian prior ``prior_std`` around
  the true initial augmented state;
* what to report: the states, and the named scalar quantities (``quantities``) along
  which convergence is judged (e.g. the bearing of the unicycle from the origin, i.e. the
  error along the rotation about the origin), with their units (``units``).

Checks of the time step. At construction (one-line :class:`~uio_jax.ModelError`): ``dt``
finite and positive, a finite horizon ``n_steps * dt``, every output read at least once
(its period at most ``n_steps``), a whole number of records, and one trial's records
within the machine's memory. Before a run (:meth:`Experiment.check_memory`, OptionError):
the records of all trials within memory. Against the dynamics' time scale
(:meth:`Experiment.time_scale`, a :class:`TimeScaleWarning`), with the shortest time scale
``1 / rate`` of the dynamics at the true start (see :meth:`Experiment.time_scale`):

* ``rate * dt > MAX_RATE_DT`` (1): one Euler step moves a state, or spreads its error, by
  more than one prior standard deviation, or outruns the fastest linear mode
  (``|lambda| dt > 1``: Euler's factor ``1 + lambda dt`` is no longer close to
  ``exp(lambda dt)``);
* ``rate * n_steps * dt < MIN_RATE_HORIZON`` (0.01): the whole trial lasts under 1 % of
  that time scale, so nothing moves (e.g. ``dt = 1e-30``);
* ``n_steps < MIN_STEPS`` (10): ``dt`` is more than a tenth of the horizon.
"""

import math
import numbers
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from .._errors import ModelError, OptionError
from . import experiment_checks as checks
from .system import System


class TimeScaleWarning(UserWarning):
    """``dt`` or the horizon is far from the time scale of the experiment's dynamics."""


@dataclass(frozen=True)
class Measurement:
    """One scalar output read by the filter.

    Args:
        name: label in reports.
        fn: ``h(x) -> ()`` on the system state ``x`` of shape ``(n,)``.
        sigma: standard deviation of its additive Gaussian noise (units of ``h``).
        every: period in Euler steps (the output is read at steps ``every, 2 every, ...``).
        angle: wrap the innovation ``y - h(x_hat)`` to ``(-pi, pi]`` (radians).
    """

    name: str
    fn: Callable
    sigma: float
    every: int
    angle: bool = False


@dataclass(frozen=True)
class Quantity:
    """A named scalar function of the state along which errors are reported.

    Args:
        name: label in reports (e.g. ``"bearing phi"``).
        fn: ``q(x) -> ()`` on the system state ``x`` of shape ``(n,)``.
        angle: wrap its error ``q(x_hat) - q(x)`` to ``(-pi, pi]``.
        unit: unit shown in reports and plots (``"rad"`` is shown in degrees).
        observable: what the analysis implies for it, if known (``True``/``False``);
            used only to label plots, never to decide the verdict.
    """

    name: str
    fn: Callable
    angle: bool = False
    unit: str = ""
    observable: bool | None = None


@dataclass(frozen=True, eq=False)
class Experiment:
    """A Monte Carlo experiment: truth, sensors, filter model and prior (see module doc).

    Args:
        name: label (``"unicycle_disturbance:range_gamma_known"``).
        system: the :class:`System` simulated and filtered (its states, known, unknown
            fields and drift). The analysis verdict is computed on it.
        dt: Euler step of truth and filter (s).
        n_steps: number of Euler steps of a trial.
        x0: true initial state, shape ``(n,)``.
        inputs: ``(istate, z) -> (istate, u, w)``: the true inputs of one step from the
            input-law state ``istate`` (shape of ``istate0``) and ``n_input_normals``
            standard normals ``z``; ``u`` has one entry per known input (order of
            ``system.known``), ``w`` one per unknown input.
        istate0: initial input-law state (e.g. the true airspeed of a random walk).
        n_input_normals: normals drawn per step for ``inputs``.
        known_std: ``u -> (m,)``: std of each known-input reading at true value ``u``
            (the filter evaluates it at the reading).
        measurements: the outputs the filter reads, each with its own period.
        w0: true initial value of each unknown input (the prior mean of ``w``; ``w1..``
            start at 0).
        w_white_std: per-step std of the white part of each unknown input (enters Q as
            ``dt^2 sigma^2 g g^T``).
        order: number of augmented entries per unknown input (2: ``w, w1``).
        q_aug: spectral density of the process noise on each augmented entry, shape
            ``(p * order,)`` ordered ``[w_1.., w1_1.., ...]`` (Q gets ``q * dt``).
        prior_std: std of the initial estimate around the truth, shape ``(n + p order,)``.
        quantities: named directions (scalar functions of the state) to report.
        nees_states: states entering the NEES (default: all states of ``system``).
        record_every: statistics are recorded every this many output epochs.
        w_reference: optional ``(istate, w) -> (p,)``: the value of the unknown inputs the
            filter's ``w`` is compared with (default: the per-step sample ``w`` itself).
            When ``w`` is a smooth part plus white noise drawn every step, pass the smooth
            part (e.g. the mean): the white part cannot be estimated.
        notes: the choices the paper leaves open, in words (shown in reports).
        units: state or unknown-input name -> unit (``"m"``, ``"m/s"``), shown in tables
            and on plot axes; angles (``system.angles``) are ``"rad"`` (shown in degrees)
            unless given; the derivative ``w1`` of an unknown input ``w`` gets
            ``"<unit of w>/s"``. Names not given have no unit shown (``""``).

    Raises:
        ModelError: one line naming the problem: a field of the wrong length or not
            finite, ``dt`` not a finite positive number, an infinite horizon, an output
            never read (its period beyond ``n_steps``), ``n_steps`` not a whole number of
            output epochs or of records, one trial's records beyond the machine's memory.
    """

    name: str
    system: System
    dt: float
    n_steps: int
    x0: tuple
    inputs: Callable
    istate0: tuple
    n_input_normals: int
    known_std: Callable
    measurements: tuple
    w0: tuple = ()
    w_white_std: tuple = ()
    order: int = 2
    q_aug: tuple = ()
    prior_std: tuple = ()
    quantities: tuple = ()
    nees_states: tuple | None = None
    record_every: int = 1
    w_reference: Callable | None = None
    notes: str = ""
    units: Mapping = field(default_factory=dict)
    _derived: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        sys_ = self.system
        if not isinstance(sys_, System):
            raise ModelError(f"experiment {self.name!r}: system must be a uio_jax.System")
        if sys_.time is not None:
            raise ModelError(
                f"experiment {self.name!r}: time-varying systems are not simulated yet (System time="
                f"{sys_.time!r}); the Monte Carlo filter takes a time-invariant System"
            )
        if sys_.params:
            raise ModelError(
                f"experiment {self.name!r}: the Monte Carlo filter does not take a System with "
                "params yet; give the parameters values (or make them states with zero derivative)"
            )
        n, p = sys_.n, len(sys_.unknown)
        _positive(self.dt, "dt", self.name, real=True)
        _positive(self.n_steps, "n_steps", self.name)
        if not math.isfinite(self.dt) or not math.isfinite(self.dt * self.n_steps):
            raise ModelError(f"experiment {self.name!r}: dt={self.dt!r} s with n_steps={self.n_steps} "
                             "is not a finite horizon")
        _positive(self.order, "order", self.name)
        _positive(self.record_every, "record_every", self.name)
        if self.n_input_normals < 0:
            raise ModelError(f"experiment {self.name!r}: n_input_normals must be >= 0")
        for attr, length in (("x0", n), ("w0", p), ("w_white_std", p),
                             ("q_aug", p * self.order), ("prior_std", n + p * self.order)):
            arr = np.asarray(getattr(self, attr), dtype=np.float64).reshape(-1)
            if arr.shape != (length,):
                raise ModelError(f"experiment {self.name!r}: {attr} has {arr.size} entries, "
                                 f"expected {length}")
            if not np.all(np.isfinite(arr)):
                raise ModelError(f"experiment {self.name!r}: {attr} is not finite")
            object.__setattr__(self, attr, tuple(float(v) for v in arr))
        object.__setattr__(self, "istate0",
                           tuple(float(v) for v in np.asarray(self.istate0, np.float64).ravel()))
        if not self.measurements:
            raise ModelError(f"experiment {self.name!r} reads no measurement")
        for m in self.measurements:
            if not isinstance(m, Measurement):
                raise ModelError(f"experiment {self.name!r}: measurements must be Measurement")
            _positive(m.every, f"period of {m.name!r}", self.name)
            _positive(m.sigma, f"sigma of {m.name!r}", self.name, real=True)
            if m.every > self.n_steps:
                raise ModelError(f"experiment {self.name!r}: output {m.name!r} is read every "
                                 f"{m.every} steps ({m.every * self.dt:.4g} s), after the last of "
                                 f"the {self.n_steps} steps ({self.duration:.4g} s): never read")
        for q in self.quantities:
            if not isinstance(q, Quantity):
                raise ModelError(f"experiment {self.name!r}: quantities must be Quantity")
        nees = tuple(sys_.states) if self.nees_states is None else tuple(self.nees_states)
        for s in nees:
            if s not in sys_.states:
                raise ModelError(f"experiment {self.name!r}: NEES state {s!r} is not a state")
        object.__setattr__(self, "nees_states", nees)
        every = math.gcd(*[int(m.every) for m in self.measurements])
        if self.n_steps % every:
            raise ModelError(f"experiment {self.name!r}: n_steps={self.n_steps} is not a "
                             f"multiple of the output period {every}")
        self._derived.update(epoch_steps=every, n_epochs=self.n_steps // every)
        if self.n_epochs % self.record_every:
            raise ModelError(f"experiment {self.name!r}: {self.n_epochs} output epochs are not "
                             f"a multiple of record_every={self.record_every} (the last epochs "
                             "would not be recorded)")
        object.__setattr__(self, "units", self._check_units(self.units))
        need, have = self.memory_bytes(1), checks.memory_available()
        if have is not None and need > checks.MEMORY_FRACTION * have:
            raise ModelError(f"experiment {self.name!r}: one trial of {self.n_steps} steps records "
                             f"{self.n_records + 1} times and needs about {checks.gib(need)} of memory, "
                             f"more than the {checks.gib(have)} available: raise record_every or "
                             "lower n_steps")

    def _check_units(self, units):
        if not isinstance(units, Mapping):
            raise ModelError(f"experiment {self.name!r}: units must be a mapping name -> unit, "
                             f"got {type(units).__name__}")
        known = set(self.system.states) | set(self.system.unknown)
        out = {}
        for k, u in units.items():
            if k not in known:
                raise ModelError(f"experiment {self.name!r}: units names {k!r}, not a state or "
                                 f"unknown input ({', '.join(sorted(known))})")
            if not isinstance(u, str):
                raise ModelError(f"experiment {self.name!r}: the unit of {k!r} must be a string, "
                                 f"got {type(u).__name__}")
            out[k] = u
        return out

    # ------------------------------------------------------------------ derived sizes
    @property
    def n(self) -> int:
        """Dimension of the system state."""
        return self.system.n

    @property
    def n_aug(self) -> int:
        """Dimension of the filter state: ``n + p * order``."""
        return self.system.n + len(self.system.unknown) * self.order

    @property
    def epoch_steps(self) -> int:
        """Euler steps between output epochs (gcd of the measurement periods)."""
        return self._derived["epoch_steps"]

    @property
    def n_epochs(self) -> int:
        """Number of output epochs of a trial."""
        return self._derived["n_epochs"]

    @property
    def duration(self) -> float:
        """Length of a trial (s)."""
        return self.n_steps * self.dt

    @property
    def n_records(self) -> int:
        """Number of records of a trial after t = 0 (``n_epochs // record_every``)."""
        return self.n_epochs // self.record_every

    def unit(self, name: str) -> str:
        """Unit of a filter state or named quantity as computed (angles ``"rad"``; ``""``
        when the experiment gives none). ``w1`` of an unknown input ``w`` in ``"<unit>/s"``,
        ``w2`` in ``"<unit>/s^2"``, ...
        """
        for q in self.quantities:
            if q.name == name:
                return q.unit or ("rad" if q.angle else "")
        if name in self.units:
            return self.units[name]
        if name in self.system.angles:
            return "rad"
        if name in self.system.states:
            return ""
        for w in self.system.unknown:
            for k in range(self.order):
                if name == (w if k == 0 else f"{w}{k}"):
                    return _per_second(self.units.get(w, ""), k)
        raise OptionError(f"experiment {self.name!r} has no state or quantity named {name!r}")

    def display_unit(self, name: str) -> tuple[str, float]:
        """``(unit, scale)`` in which ``name`` is shown: angles (wrapped states and angle
        quantities) in ``"deg"`` (scale ``180 / pi``), the rest in :meth:`unit` (scale 1)."""
        angle = name in self.system.angles or any(
            q.name == name and q.angle for q in self.quantities)
        unit = self.unit(name)
        if angle and unit in ("rad", ""):
            return "deg", 180.0 / math.pi
        if unit.startswith("rad/"):
            return "deg" + unit[3:], 180.0 / math.pi
        return unit, 1.0

    # ------------------------------------------------------------------ time step checks
    def memory_bytes(self, trials: int, keep: int = 0) -> int:
        """Estimated peak memory (bytes) of a run of ``trials`` trials keeping ``keep`` full
        trajectories (:func:`uio_jax._model.experiment_checks.memory_bytes` says how)."""
        return checks.memory_bytes(self, trials, keep)

    def check_memory(self, trials: int, keep: int = 0) -> int:
        """Refuse, before any work, a run whose :meth:`memory_bytes` exceeds
        ``MEMORY_FRACTION`` (0.8) of the memory available; returns the estimate (bytes).

        Raises:
            OptionError: one line with the estimate, the memory available and what to lower.
        """
        return checks.check_memory(self, trials, keep)

    def time_scale(self, values=None) -> dict:
        """The shortest time scale of the filter's dynamics at the true start.

        At ``xa0 = [x0, w0, 0, ...]`` with the known inputs of the input law at ``z = 0``,
        with ``F`` the augmented vector field (``x' = f(x, u, w)``, ``w' = w1``, ...,
        top ``= 0``), ``A = dF/dxa`` and ``S = diag(prior_std)`` (entries with a zero prior
        left out of the scaled rates)::

            eigen_rate    = max |lambda(A)|            fastest linear mode (1/s)
            coupling_rate = ||S^-1 A S||_2             errors spread, in prior stds per s
            motion_rate   = max_i |F_i| / prior_i      the state moves, in prior stds per s
            rate          = max of the three,   time_scale_s = 1 / rate

        (``coupling_rate >= eigen_rate``; a kinematic model such as the unicycle has
        ``eigen_rate = 0`` and a time scale set by its motion.) ``rate = 0`` (nothing moves,
        e.g. a constant measured again and again) gives ``time_scale_s = inf``.

        Args:
            values: optional ``(f (n,), D (n, n + p))``, the vector field and its Jacobian
                ``d f / d(x, w)`` at the start, when the caller has them (the Monte Carlo
                driver computes them in its start-up program); else computed here (one
                small jitted program).

        Returns:
            ``{"rate", "time_scale_s", "eigen_rate", "coupling_rate", "motion_rate",
            "rate_dt", "rate_horizon"}`` (``rate * dt`` and ``rate * n_steps * dt``), floats.
        """
        if values is None and "time_scale" in self._derived:
            return self._derived["time_scale"]
        out = checks.time_scale(self, values)
        self._derived["time_scale"] = out
        return out

    def check_time_scale(self, values=None) -> list[str]:
        """Warn (:class:`TimeScaleWarning`) when ``dt`` or the horizon is far from
        :meth:`time_scale` (criteria: module doc); returns the messages (empty: none).
        ``values``: as in :meth:`time_scale`."""
        msgs = checks.time_scale_messages(self, self.time_scale(values))
        for msg in msgs:
            warnings.warn(msg, TimeScaleWarning, stacklevel=2)
        return msgs

    def state_names(self) -> tuple[str, ...]:
        """Names of the filter state: system states, then ``w``, ``w1``, ... per input."""
        derived = (u if k == 0 else f"{u}{k}" for k in range(self.order) for u in self.system.unknown)
        return (*self.system.states, *derived)

    def angle_mask(self) -> np.ndarray:
        """Boolean ``(n_aug,)``: which filter states are angles (wrapped)."""
        ang = set(self.system.angles)
        return np.array([s in ang for s in self.state_names()], dtype=bool)

    def analysis_system(self) -> System:
        """The analysed system: ``system``'s fields with the outputs this experiment reads.

        The Monte Carlo verdict is about these sensors (e.g. two camera features in 002
        section III-D where the zoo's model has one), so the analysis beside it must be too.
        """
        s = self.system
        outputs = {m.name: m.fn for m in self.measurements}
        return System(s.states, outputs, dict(s.known), dict(s.unknown), s.drift,
                      dict(s.domain), s.angles, f"{self.name} (outputs read)")

    def with_(self, **changes) -> "Experiment":
        """A copy with some fields changed (e.g. ``n_steps`` for a shorter run)."""
        from dataclasses import fields, replace

        names = {f.name for f in fields(self)} - {"_derived"}
        for k in changes:
            if k not in names:
                raise OptionError(f"Experiment has no field {k!r}")
        return replace(self, _derived={}, **changes)


def _positive(value, what, name, real=False):
    kind = numbers.Real if real else numbers.Integral
    if isinstance(value, bool) or not isinstance(value, kind) or not value > 0:
        raise ModelError(f"experiment {name!r}: {what} must be a positive "
                         f"{'number' if real else 'integer'}, got {value!r}")


def _per_second(unit: str, k: int) -> str:
    """``unit`` divided by ``s^k``: ``("m/s", 1) -> "m/s^2"``, ``("m", 2) -> "m/s^2"``;
    ``""`` stays ``""`` (no unit given)."""
    if not unit or k == 0:
        return unit
    import re

    m = re.fullmatch(r"(.*)/s(?:\^(\d+))?", unit)
    base, power = (m.group(1), int(m.group(2) or 1)) if m else (unit, 0)
    power += k
    return f"{base}/s" if power == 1 else f"{base}/s^{power}"
