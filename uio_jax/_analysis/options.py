"""The analysis options, their defaults and their checks: one place for :func:`uio_jax.analyze`,
:func:`uio_jax.batch_analyze` and the command line."""

import numbers

from .._engine.seeds import check_seed
from .._errors import OptionError
from .._model.smooth_inputs import KNOWN_INPUT_MEANINGS
from .decisions.rank import default_rtol
from .decisions.settle import DEFAULT_PROB_THRESHOLD

#: The analyses ``method`` may name (``analyze``'s docstring says what each one does).
METHODS = ("auto", "orc", "single_ui", "general_ui", "eorc", "series", "fast")

#: The meanings of a known input (``known_inputs``): may jump, or generic smooth in time.
KNOWN_INPUTS = KNOWN_INPUT_MEANINGS

#: The questions ``scope`` may ask: ``"local"`` (observable / locally identifiable) or also
#: ``"global"`` (how many values each unknown takes: :mod:`uio_jax._analysis.globally`).
SCOPES = ("local", "global")

#: Default of every analysis option (``rtol`` None: :func:`~uio_jax._analysis.decisions.rank.default_rtol`;
#: ``max_order`` None: no cap; ``k_max`` None: ``n + 2``).
DEFAULTS = {"method": "auto", "samples": 4096, "seed": 0, "rtol": None, "max_order": None, "k_max": None,
            "known_inputs": "switchable", "prob_threshold": DEFAULT_PROB_THRESHOLD, "scope": "local"}

#: Smallest sample count: fewer random states cannot certify a rank.
MIN_SAMPLES = 8

def check_options(**options) -> dict:
    """Check the analysis options and return them normalised.

    Args:
        **options: any of ``method``, ``samples``, ``seed``, ``rtol``, ``max_order``,
            ``k_max``, ``known_inputs``, ``prob_threshold``, ``scope`` (those not given take
            :data:`DEFAULTS`). The memory a run needs
            depends on the model and is checked where the analysis knows its size
            (:func:`~uio_jax._analysis.decisions.memory.check_memory`).

    Returns:
        dict of all nine: ``method`` (str), ``scope`` (str), ``samples`` and ``seed`` (int), ``rtol``
        (float; None resolved to :func:`~uio_jax._analysis.decisions.rank.default_rtol`),
        ``max_order`` and ``k_max`` (int, or None), ``known_inputs`` (str),
        ``prob_threshold`` (float).

    Raises:
        OptionError: an unknown option name, an unknown method, ``samples`` not an integer
            >= 8, ``seed`` not an integer in ``[0, 2**64)`` (:func:`check_seed`), ``rtol``
            not a finite number in (0, 1) (NaN refused),
            ``max_order`` not a non-negative integer, ``k_max`` not a positive integer,
            ``known_inputs`` not one of :data:`KNOWN_INPUTS`, ``prob_threshold`` not a
            number in (0, 1), ``scope`` not one of :data:`SCOPES`.
    """
    unknown = set(options) - set(DEFAULTS)
    if unknown:
        raise OptionError(f"unknown analysis option {sorted(unknown)[0]!r}")
    opts = {**DEFAULTS, **options}
    method, samples, seed, rtol = opts["method"], opts["samples"], opts["seed"], opts["rtol"]
    if method not in METHODS:
        raise OptionError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if not _is_int(samples) or samples < MIN_SAMPLES:
        raise OptionError(f"samples must be an integer >= {MIN_SAMPLES}, got {samples!r}")
    seed = check_seed(seed)
    if rtol is None:
        rtol = default_rtol()
    if isinstance(rtol, bool) or not (isinstance(rtol, numbers.Real) and 0 < rtol < 1):
        raise OptionError(f"rtol must be a number in (0, 1), got {rtol!r}")
    max_order, k_max = opts["max_order"], opts["k_max"]
    if max_order is not None and (not _is_int(max_order) or max_order < 0):
        raise OptionError(f"max_order must be a non-negative integer, got {max_order!r}")
    if k_max is not None and (not _is_int(k_max) or k_max < 1):
        raise OptionError(f"k_max must be a positive integer, got {k_max!r}")
    known_inputs = opts["known_inputs"]
    if known_inputs not in KNOWN_INPUTS:
        raise OptionError(f"unknown known_inputs {known_inputs!r}; choose one of "
                          f"{', '.join(KNOWN_INPUTS)}")
    prob = opts["prob_threshold"]
    if isinstance(prob, bool) or not (isinstance(prob, numbers.Real) and 0 < prob < 1):
        raise OptionError(f"prob_threshold must be a number in (0, 1), got {prob!r}")
    if opts["scope"] not in SCOPES:
        raise OptionError(f"unknown scope {opts['scope']!r}; choose one of {', '.join(SCOPES)}")
    return {"method": method, "samples": int(samples), "seed": seed, "rtol": float(rtol), "scope": opts["scope"],
            "known_inputs": known_inputs, "prob_threshold": float(prob),
            "max_order": None if max_order is None else int(max_order),
            "k_max": None if k_max is None else int(k_max)}


def _is_int(x) -> bool:
    """An integer that is not a bool."""
    return isinstance(x, numbers.Integral) and not isinstance(x, bool)
