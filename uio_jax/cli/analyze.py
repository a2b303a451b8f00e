"""``uio-jax analyze MODEL [options]``: the observability report of one model."""

import json

from .._errors import UioJaxError
from .._output import printable
from .common import UsageError, add_cache_options, analysis_kwargs, check_writable, model_prints_on_stderr, write_output
from .sbml_options import add_sbml_options, refuse_for, sbml_options


def add_parser(subparsers, analysis_options):
    """Add the ``analyze`` sub-command; ``analysis_options(p)`` adds the shared analysis flags."""
    a = subparsers.add_parser("analyze", help="observability analysis of one model")
    a.add_argument("model", help="FILE.py:FUNCTION returning a uio_jax.System, a .toml/.json model file, "
                   "a StrikePy model module (FILE.py), or an SBML model (.xml/.sbml, with --outputs)")
    analysis_options(a)
    a.add_argument("--initial", action="append", default=[], metavar="STATE=VALUE",
                   help="a known initial state (repeat for several): a number, a parameter, or an expression "
                        "in the parameters; answers identifiability at t = 0 at that initial state "
                        "(a model file's [initial] table is used too)")
    a.add_argument("--global-timeout", type=float, default=None, metavar="SECONDS",
                   help="seconds the global solve may take (default 600); past it the answer is undecided")
    a.add_argument("--json", metavar="FILE", help="also write the report as JSON")
    a.add_argument("--plot", metavar="FILE", help="also draw dims per step and the rank evidence "
                                                  "(png, pdf, svg by suffix)")
    a.add_argument("--no-progress", action="store_true",
                   help="do not print each step as it is decided (printed on a terminal only)")
    add_sbml_options(a)
    add_cache_options(a)
    return a


def run(args) -> int:
    """Run the sub-command; returns the exit code (errors propagate as UioJaxError)."""
    from .._analysis.analyze import analyze
    from .._analysis.followups.questions import find_symmetries, observable_functions
    from .._analysis.options import check_options
    from .._io.initial_values import file_initial, initial_values
    from .._io.loading import load_system
    from .._progress import StepPrinter, step_listener

    check_options(**analysis_kwargs(args))  # before loading the model
    given = _initial_pairs(args.initial)
    if args.global_timeout is not None and args.scope != "global":
        raise UsageError("--global-timeout applies with --global")
    scope = {"scope": args.scope, "global_timeout": args.global_timeout}
    if args.plot and given:
        raise UsageError("--plot draws the codistribution's steps; it does not apply with --initial")
    if args.plot:
        from .._analysis.results.plots import check_figure_path

        check_figure_path(args.plot)
    refuse_for(args.model, args)
    load_options = sbml_options(args)
    check_writable(args.json, args.plot, names=("--json", "--plot"), inputs=[args.model])
    printer = StepPrinter(enabled=False if args.no_progress else None)
    with model_prints_on_stderr(), step_listener(printer):
        system = load_system(args.model, **load_options)
        initial = {**file_initial(system), **given}
        rep = analyze(system, initial=initial_values(system, initial) if initial else None,
                      **analysis_kwargs(args), **scope)
    if not initial:  # with known initial values: the identifiability report at t = 0 alone
        # the readable report answers the follow-up questions too (kept on the report: the JSON has them)
        observable_functions(rep)
        find_symmetries(rep)
    print(rep)
    directions = {} if initial else _print_directions(rep)
    if args.json:
        d = rep.to_dict()
        for key, value in directions.items():  # what the text printed, parameters or not
            d.setdefault(key, value)
        write_output(args.json, json.dumps(d, indent=2))
        print(f"report written to {args.json}")
    if args.plot and not initial:
        from .._analysis.results.plots import plot_analysis

        plot_analysis(rep, args.plot)
        print(f"figure written to {args.plot}")
    return 0


def _initial_pairs(items) -> dict:
    """``{state: text}`` from ``--initial STATE=VALUE`` arguments (UsageError on a bad one)."""
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not sep or not name or not value:
            raise UsageError(f"--initial needs STATE=VALUE, got {item!r}")
        if name in out:
            raise UsageError(f"--initial gives {name} twice")
        out[name] = value
    return out


def _print_directions(rep) -> dict:
    """Print the unobservable directions of a report that has some (at the centre of the
    domain); returns them as the JSON keys :meth:`Report.to_dict` gives a model with
    parameters (``unobservable_directions``, ``identifiable_combinations``,
    ``directions_at``), empty when there are none."""
    if rep.dim >= rep.n:  # n: states plus parameters (rep.variables)
        return {}
    try:
        summary = rep.direction_summary()
    except UioJaxError as exc:
        print(printable(f"unobservable directions: not computed at the centre of the domain ({exc})"))
        return {"unobservable_directions": None, "identifiable_combinations": None,
                "directions_at": {"rule": "centre of the domain", "point": None, "error": str(exc)}}
    print(printable(rep.format_directions(summary), keep="\n"))
    return {"unobservable_directions": summary["directions"],
            "identifiable_combinations": summary["identifiable_combinations"],
            "directions_at": {"rule": summary["rule"], "point": summary["point"]}}
