"""The options that declare an SBML model's outputs and inputs on the command line
(``analyze``, ``batch``, ``save-model``): ``--outputs``, ``--observables``, ``--known``,
``--unknown``, ``--fixed``, ``--estimate``; they become the keyword arguments of
:func:`uio_jax.load_system` for ``.xml``/``.sbml`` files (rules: ``docs/sbml.md``)."""

import math

from .common import UsageError

#: The options, as argparse destinations.
DESTS = ("outputs", "observables", "known", "unknown", "fixed", "estimate")


def add_sbml_options(p):
    """Add the SBML options to the sub-command parser ``p`` (each may be repeated; lists of
    ids may also be comma-separated)."""
    g = p.add_argument_group("SBML models (.xml, .sbml): outputs and inputs, which SBML does not declare")
    g.add_argument("--outputs", action="append", metavar="NAME=EXPR",
                   help="an output: a name and an expression in the model's ids (y=S1+S2), or an id "
                        "alone; repeat for several")
    g.add_argument("--observables", metavar="FILE",
                   help="outputs from a PEtab observables table (TSV: observableId, observableFormula)")
    g.add_argument("--known", action="append", metavar="IDS", help="ids that are known inputs u(t)")
    g.add_argument("--unknown", action="append", metavar="IDS", help="ids that are unknown inputs w(t)")
    g.add_argument("--fixed", action="append", metavar="ID[=VALUE]",
                   help="parameters fixed (at VALUE, or at their value in the file) instead of identified")
    g.add_argument("--estimate", action="append", metavar="IDS",
                   help="compartments or boundary species to identify instead of fixing them")


def given(args) -> bool:
    """Whether any SBML option was given."""
    return any(getattr(args, d, None) for d in DESTS)


def sbml_options(args) -> dict:
    """The keyword arguments of :func:`uio_jax.load_system` for an SBML model ({} when no
    SBML option was given).

    Raises:
        UsageError: a malformed ``--outputs`` or ``--fixed`` entry.
    """
    if not given(args):
        return {}
    out = {}
    if args.outputs:
        outputs = {}
        for item in args.outputs:
            name, sep, expr = item.partition("=")
            name, expr = (name.strip(), expr.strip()) if sep else (item.strip(), item.strip())
            if not name.isidentifier() or not expr:
                raise UsageError(f"--outputs {item!r}: give NAME=EXPRESSION (or an id alone)")
            if name in outputs:
                raise UsageError(f"--outputs: output {name!r} given twice")
            outputs[name] = expr
        out["outputs"] = outputs
    if args.observables:
        out["observables"] = args.observables
    for dest in ("known", "unknown", "estimate"):
        if getattr(args, dest):
            out[dest] = _ids(getattr(args, dest))
    if args.fixed:
        out["fixed"] = _fixed(args.fixed)
    return out


def refuse_for(model, args):
    """A UsageError when SBML options are given for a model that is no SBML file."""
    from .._io.sbml_import import is_sbml_path

    if given(args) and not is_sbml_path(model):
        used = [f"--{d}" for d in DESTS if getattr(args, d, None)]
        raise UsageError(f"{', '.join(used)}: for SBML models (.xml, .sbml) only, not {model}")


def _ids(items) -> list:
    return [nm.strip() for item in items for nm in item.split(",") if nm.strip()]


def _fixed(items) -> dict:
    out = {}
    for nm in _ids(items):
        name, sep, text = nm.partition("=")
        name = name.strip()
        value = None
        if sep:
            try:
                value = float(text)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise UsageError(f"--fixed {nm!r}: the value must be a finite number")
        out[name] = value
    return out
