"""``uio-jax save-model MODEL OUT``: write a model as a declarative ``.toml``/``.json`` file
(an SBML model converted with its declared outputs and inputs, a StrikePy module, ...)."""

from .._output import printable
from .common import check_writable, model_prints_on_stderr
from .sbml_options import add_sbml_options, refuse_for, sbml_options


def add_parser(subparsers):
    """Add the ``save-model`` sub-command."""
    s = subparsers.add_parser(
        "save-model", help="write a model as a .toml/.json model file",
        description="Write a model as a declarative model file (.toml or .json by the suffix of OUT): an "
                    "SBML model converted with its --outputs and inputs, a StrikePy module, a model file, "
                    "a System built by System.from_sympy. Systems made of Python functions cannot be written.")
    s.add_argument("model", help="an SBML model (.xml/.sbml, with --outputs), a StrikePy module, a .toml/.json "
                                 "model file, or FILE.py:FUNCTION")
    s.add_argument("out", help="the file to write (.toml or .json)")
    add_sbml_options(s)
    return s


def run(args) -> int:
    """Load the model and write it; returns the exit code (errors propagate as UioJaxError)."""
    from .._io.loading import load_system
    from .._io.model_file import save_model

    refuse_for(args.model, args)
    load_options = sbml_options(args)
    check_writable(args.out, names=("OUT",), inputs=[args.model])
    with model_prints_on_stderr():
        system = load_system(args.model, **load_options)
    save_model(system, args.out)
    print(printable(f"model written to {args.out}"))
    return 0
