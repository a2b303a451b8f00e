"""uio_jax: which states of a nonlinear system can be estimated when inputs are unknown.

Public API (see DESIGN.md section 2)::

    import uio_jax as uj
    sys = uj.System(states=..., outputs=..., known=..., unknown=..., drift=..., domain=...)
    rep = uj.analyze(sys, method="auto", samples=4096, seed=0)
"""

from importlib.metadata import PackageNotFoundError, version

from ._analyze import analyze as analyze
from ._errors import LoadError as LoadError
from ._errors import ModelError as ModelError
from ._errors import OptionError as OptionError
from ._errors import UioJaxError as UioJaxError
from ._loading import load_system as load_system
from ._rank import RankDecision as RankDecision
from ._rank import decide_rank as decide_rank
from ._rank import default_rtol as default_rtol
from ._report import Certificate as Certificate
from ._report import Report as Report
from ._report import Step as Step
from ._system import System as System

try:
    __version__ = version("uio_jax")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0"
