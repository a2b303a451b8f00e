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
  error along the rotation about the origin).
"""

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._errors import ModelError, OptionError
from .system import System


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
    _derived: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        sys_ = self.system
        if not isinstance(sys_, System):
            raise ModelError(f"experiment {self.name!r}: system must be a uio_jax.System")
        if sys_.params:
            raise ModelError(
                f"experiment {self.name!r}: the Monte Carlo filter does not take a System with "
                "params yet; give the parameters values (or make them states with zero derivative)"
            )
        n, p = sys_.n, len(sys_.unknown)
        _positive(self.dt, "dt", self.name, real=True)
        _positive(self.n_steps, "n_steps", self.name)
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

    def state_names(self) -> tuple[str, ...]:
        """Names of the filter state: system states, then ``w``, ``w1``, ... per input."""
        names = list(self.system.states)
        unk = list(self.system.unknown)
        for k in range(self.order):
            names += [u if k == 0 else f"{u}{k}" for u in unk]
        return tuple(names)

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
