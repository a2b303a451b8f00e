"""uio_jax: which states of a nonlinear system can be estimated when inputs are unknown.

Public API (see DESIGN.md section 2)::

    import uio_jax as uj
    sys = uj.System(states=..., outputs=..., known=..., unknown=..., drift=..., domain=...)
    rep = uj.analyze(sys, method="auto", samples=4096, seed=0)
"""

from importlib.metadata import PackageNotFoundError, version

from ._analysis_plots import plot_analysis as plot_analysis
from ._analyze import analyze as analyze
from ._batch import BatchResult as BatchResult
from ._batch import BatchRow as BatchRow
from ._batch import batch_analyze as batch_analyze
from ._compile_cache import enable_compile_cache as enable_compile_cache
from ._errors import LoadError as LoadError
from ._errors import ModelError as ModelError
from ._errors import OptionError as OptionError
from ._errors import UioJaxError as UioJaxError
from ._experiment import Experiment as Experiment
from ._experiment import Measurement as Measurement
from ._experiment import Quantity as Quantity
from ._expressions import ExpressionError as ExpressionError
from ._loading import load_system as load_system
from ._model_file import load_model_file as load_model_file
from ._model_file import save_model as save_model
from ._montecarlo import run_montecarlo as run_montecarlo
from ._montecarlo import trajectories as trajectories
from ._montecarlo_cli import load_experiment as load_experiment
from ._plots import plot_errors as plot_errors
from ._plots import plot_montecarlo as plot_montecarlo
from ._plots import plot_nees as plot_nees
from ._plots import plot_trajectories as plot_trajectories
from ._rank import RankDecision as RankDecision
from ._rank import decide_rank as decide_rank
from ._rank import default_rtol as default_rtol
from ._report import Certificate as Certificate
from ._report import Report as Report
from ._report import Step as Step
from ._result import MonteCarloResult as MonteCarloResult
from ._strikepy_import import load_strikepy as load_strikepy
from ._system import System as System

try:
    __version__ = version("uio_jax")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0"
