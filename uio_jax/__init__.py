"""uio_jax: which states of a nonlinear system can be estimated when inputs are unknown.

Public API (the names below are a contract; everything under ``uio_jax._*`` is private)::

    import uio_jax as uj
    sys = uj.System(states=..., outputs=..., known=..., unknown=..., drift=..., domain=...)
    rep = uj.analyze(sys, method="auto", samples=4096, seed=0)

The implementation lives in private layers (README, "Layout"): ``_engine`` <- ``_model`` <-
``_calculus`` <- ``_analysis``; ``_filter``; ``_io``; ``_batch``; ``cli``.

``System.from_sympy`` and ``System.from_dynamics`` (the one exception to the layout rule,
named in ``tests/test_layout.py``): the constructors from sympy expressions and from
``x' = f(x, u, w)`` are plain functions of the importers' layer, public as
:func:`system_from_sympy` and :func:`system_from_dynamics`. ``System`` lives in the model
layer, which may not import the importers (``_io`` imports ``_model``, never the reverse), so
no module below this one can define them on the class. They have been public names since the
first release and users call them, so this module, the API layer (which imports every layer),
attaches the two functions to ``System`` as static methods, once, below: ``System.from_sympy``
IS ``system_from_sympy``. Nothing else in the package assigns an attribute onto a class or
module it imports; the layout test fails on any other such assignment.

``import uio_jax`` does not import JAX: a model file, a sympy, SBML or StrikePy model is
read, translated into the expression graph and analysed without it (JAX is imported the
first time a Python model's JAX functions are traced). The two names whose modules are JAX
programs, :func:`run_montecarlo` and :func:`trajectories`, and the batch's names
(:func:`batch_analyze`, :class:`BatchResult`, :class:`BatchRow`) and ``__version__`` (read
from the installed metadata) are lazy attributes of this module (:func:`__getattr__`): their
modules (JAX for the first two) are imported the first time they are used; ``dir(uio_jax)``
lists them.
"""

# the model
from ._model.system import System as System
from ._model.experiment import Experiment as Experiment
from ._model.experiment import Measurement as Measurement
from ._model.experiment import Quantity as Quantity
from ._model.experiment import TimeScaleWarning as TimeScaleWarning
from ._model.experiments import Experiments as Experiments

# the analyses and their report
from ._analysis.analyze import analyze as analyze
from ._analysis.results.report import Report as Report
from ._analysis.results.report import Question as Question
from ._analysis.results.identifiability_report import IdentifiabilityReport as IdentifiabilityReport
from ._analysis.results.kinds import Verdict as Verdict
from ._analysis.results.evidence import Step as Step
from ._analysis.results.evidence import Certificate as Certificate
from ._analysis.results.plots import plot_analysis as plot_analysis
from ._analysis.results.kinds import Method as Method
from ._analysis.results.kinds import Route as Route
from ._analysis.results.kinds import Answer as Answer
from ._analysis.results.kinds import Plan as Plan
from ._analysis.plan import plan as plan
from ._analysis.globally.run import global_identifiability as global_identifiability
from ._analysis.globally.result import GlobalVerdict as GlobalVerdict
from ._analysis.globally.result import GlobalResult as GlobalResult

# follow-up questions of a report
from ._analysis.followups.questions import observable_functions as observable_functions
from ._analysis.followups.questions import find_symmetries as find_symmetries
from ._analysis.followups.questions import reparametrise as reparametrise

# Monte Carlo filtering (run_montecarlo and trajectories: lazy attributes, see __getattr__)
from ._filter.result import MonteCarloResult as MonteCarloResult
from ._filter.plots import plot_montecarlo as plot_montecarlo
from ._filter.plots import plot_trajectories as plot_trajectories
from ._filter.plots import plot_errors as plot_errors
from ._filter.plots import plot_nees as plot_nees

# loading and saving models
from ._io.loading import load_system as load_system
from ._io.model_file import save_model as save_model
from ._io.experiment_loading import load_experiment as load_experiment
from ._io.sympy_import import system_from_sympy as system_from_sympy
from ._io.dynamics_form import system_from_dynamics as system_from_dynamics

# many models at once: batch_analyze, BatchResult, BatchRow (lazy attributes, see __getattr__)

# the compilation cache
from ._filter.compile_cache import enable_compile_cache as enable_compile_cache

# errors
from ._errors import UioJaxError as UioJaxError
from ._errors import ModelError as ModelError
from ._errors import OptionError as OptionError
from ._errors import LoadError as LoadError
from ._errors import ExpressionError as ExpressionError

__all__ = [
    "System", "Experiment", "Measurement", "Quantity", "Experiments",
    "analyze", "Report", "Step", "Certificate", "plot_analysis",
    "Question", "IdentifiabilityReport", "Verdict", "Method", "Route", "Answer", "Plan", "plan",
    "observable_functions", "find_symmetries", "reparametrise",
    "global_identifiability", "GlobalVerdict", "GlobalResult",
    "run_montecarlo", "trajectories", "MonteCarloResult",
    "plot_montecarlo", "plot_trajectories", "plot_errors", "plot_nees",
    "load_system", "save_model", "load_experiment", "system_from_sympy", "system_from_dynamics",
    "batch_analyze", "BatchResult", "BatchRow",
    "enable_compile_cache",
    "UioJaxError", "ModelError", "OptionError", "LoadError", "ExpressionError",
    "TimeScaleWarning",
]

# the documented exception to the layout rule (see the module docstring)
System.from_sympy = staticmethod(system_from_sympy)
System.from_dynamics = staticmethod(system_from_dynamics)

#: public name -> (module, attribute) of the names imported the first time they are used
_LAZY = {"run_montecarlo": ("._filter.montecarlo", "run_montecarlo"),
         "trajectories": ("._filter.trials", "trajectories"),
         "batch_analyze": ("._batch.run", "batch_analyze"),
         "BatchResult": ("._batch.rows", "BatchResult"),
         "BatchRow": ("._batch.rows", "BatchRow")}


def __getattr__(name):
    """The lazy public names (:data:`_LAZY`): their module imported on first use (it imports
    JAX), the name then kept in this module."""
    if name == "__version__":
        from importlib.metadata import PackageNotFoundError, version

        try:
            value = version("uio_jax")
        except PackageNotFoundError:  # running from a source tree
            value = "0.0.0"
        globals()[name] = value
        return value
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib import import_module

    module, attr = _LAZY[name]
    value = getattr(import_module(module, __name__), attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
