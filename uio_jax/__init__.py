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
"""

from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _version

# the model
from ._model.system import System as System
from ._model.experiment import Experiment as Experiment
from ._model.experiment import Measurement as Measurement
from ._model.experiment import Quantity as Quantity
from ._model.experiment import TimeScaleWarning as TimeScaleWarning
from ._model.experiments import Experiments as Experiments

# the analyses and their report
from ._analysis.analyze import analyze as analyze
from ._analysis.report import Report as Report
from ._analysis.report import Question as Question
from ._analysis.identifiability_report import IdentifiabilityReport as IdentifiabilityReport
from ._analysis.identifiability_report import Verdict as Verdict
from ._analysis.evidence import Step as Step
from ._analysis.evidence import Certificate as Certificate
from ._analysis.plots import plot_analysis as plot_analysis
from ._analysis.globally.run import global_identifiability as global_identifiability
from ._analysis.globally.result import GlobalVerdict as GlobalVerdict
from ._analysis.globally.result import GlobalResult as GlobalResult

# Monte Carlo filtering
from ._filter.montecarlo import run_montecarlo as run_montecarlo
from ._filter.trials import trajectories as trajectories
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

# many models at once
from ._batch.run import batch_analyze as batch_analyze
from ._batch.rows import BatchResult as BatchResult
from ._batch.rows import BatchRow as BatchRow

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
    "Question", "IdentifiabilityReport", "Verdict",
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

try:
    __version__ = _version("uio_jax")
except _PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0"
