"""Load a Monte Carlo :class:`~uio_jax.Experiment` from ``FILE.py:NAME``."""

from .._errors import LoadError, UioJaxError, exit_message
from .._model.experiment import Experiment
from .loading import load_module, one_line, split_spec


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
        try:
            obj = obj()
        except UioJaxError as exc:
            raise type(exc)(f"{spec}: {exc}") from None
        except Exception as exc:
            raise LoadError(f"{spec} raised {one_line(exc)}") from None
        except SystemExit as exc:
            raise LoadError(f"{spec} {exit_message(exc)}") from None
    if not isinstance(obj, Experiment):
        raise LoadError(f"{spec} did not give a uio_jax Experiment (got {type(obj).__name__})")
    return obj
