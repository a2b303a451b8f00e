"""Load a Monte Carlo :class:`~uio_jax.Experiment` from ``FILE.py:NAME``."""

from .._errors import LoadError
from .._model.experiment import Experiment
from .loading import call_loaded, load_module, split_spec


def load_experiment(spec: str):
    """Load an Experiment from ``"path/file.py:name"`` (``name`` or ``name_experiment``).

    Raises:
        LoadError: bad spec, missing file or name, or a name that gives no Experiment.
    """
    path, name = split_spec(spec)
    module = load_module(path)
    obj = getattr(module, name, None)
    if obj is None:
        obj = getattr(module, f"{name}_experiment", None)
    if obj is None:
        found = sorted(k.removesuffix("_experiment") for k, v in vars(module).items()
                       if k.endswith("_experiment") and not k.startswith("_")
                       and (callable(v) or isinstance(v, Experiment)))
        raise LoadError(f"{path} has no experiment {name!r} (it defines: "
                        f"{', '.join(found) or 'no *_experiment function'})")
    if callable(obj) and not isinstance(obj, Experiment):
        obj = call_loaded(spec, obj)
    if not isinstance(obj, Experiment):
        raise LoadError(f"{spec} did not give a uio_jax Experiment (got {type(obj).__name__})")
    return obj
