"""Command line: ``uio-jax analyze | batch | montecarlo``.

``main(argv) -> int`` returns the exit code: 0 on success, 2 on bad input (one line on
stderr, never a traceback from inside JAX), 1 when a batch has failures.

All three use JAX's persistent compilation cache (:func:`uio_jax.enable_compile_cache`;
``--cache-dir`` moves it, ``--no-cache`` turns it off) for the duration of the command: a
second run of the same models, or of the same experiment with as many trials, skips XLA
compilation.
"""

import argparse
import contextlib
import json
import os
import sys

from .._analysis.options import DEFAULTS, METHODS
from .._analysis.rank import default_rtol
from .._errors import UioJaxError
from . import montecarlo

EXIT_USAGE = 2
EXIT_FAILED = 1


class _Parser(argparse.ArgumentParser):
    """argparse that reports errors as one line and exit code 2."""

    def error(self, message):
        raise _UsageError(message)


class _UsageError(Exception):
    pass


def _build_parser():
    p = _Parser(prog="uio-jax", description="Unknown-input observability of nonlinear systems.")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)
    a = sub.add_parser("analyze", help="observability analysis of one model")
    a.add_argument("model", help="FILE.py:FUNCTION returning a uio_jax.System, a .toml/.json model file, "
                   "or a StrikePy model module (FILE.py)")
    _analysis_options(a)
    a.add_argument("--json", metavar="FILE", help="also write the report as JSON")
    a.add_argument("--plot", metavar="FILE", help="also draw dims per step and the rank evidence "
                                                  "(png, pdf, svg by suffix)")
    a.add_argument("--no-progress", action="store_true",
                   help="do not print each step as it is decided (printed on a terminal only)")
    _cache_options(a)
    b = sub.add_parser("batch", help="certify many models into one table")
    b.add_argument("paths", nargs="*", metavar="PATH",
                   help="FILE.py:NAME, zoo files (every function returning a System), .toml/.json "
                        "model files, directories, globs")
    _analysis_options(b)
    b.add_argument("--json", metavar="FILE", help="write the table as JSON")
    b.add_argument("--csv", metavar="FILE", help="write the table as CSV")
    b.add_argument("--markdown", metavar="FILE", help="write the table as Markdown")
    b.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    b.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help="time limit per model: a model over it is stopped and reported as timed out "
                        "(runs models in worker processes; default: no limit)")
    b.add_argument("--no-progress", action="store_true", help="no progress bar")
    _cache_options(b)
    _cache_options(montecarlo.add_parser(sub))
    return p


def _analysis_options(p):
    """The options of :func:`uio_jax.analyze`, with its defaults (one place:
    :mod:`uio_jax._analysis.options`)."""
    d = DEFAULTS
    p.add_argument("--method", default=d["method"], choices=METHODS, help=f"analysis (default {d['method']})")
    p.add_argument("--samples", type=int, default=d["samples"], help=f"sampled states (default {d['samples']})")
    p.add_argument("--seed", type=int, default=d["seed"], help=f"seed of the samples (default {d['seed']})")
    p.add_argument("--rtol", type=float, default=d["rtol"], help=f"rank tolerance (default {default_rtol():g})")
    p.add_argument("--max-order", type=int, default=d["max_order"], help="cap on the steps m (order k)")
    p.add_argument("--k-max", type=int, default=d["k_max"], help="highest order k of the EORC (default n + 2)")


def _cache_options(p):
    p.add_argument("--no-cache", action="store_true",
                   help="do not use the persistent compilation cache")
    p.add_argument("--cache-dir", metavar="DIR",
                   help="compilation cache directory (default $UIO_JAX_CACHE_DIR or ~/.cache/uio_jax/xla)")


@contextlib.contextmanager
def _compile_cache(args):
    """JAX's persistent compilation cache for the command, unless ``--no-cache``.

    An unusable default directory only costs the cache (one warning line); an unusable
    ``--cache-dir`` is an error.
    """
    from .._engine.compile_cache import compile_cache

    with contextlib.ExitStack() as stack:
        if not args.no_cache:
            try:
                stack.enter_context(compile_cache(args.cache_dir))
            except OSError as exc:
                if args.cache_dir:
                    raise
                print(f"uio-jax: warning: compilation cache off ({exc.strerror or exc}: {exc.filename})",
                      file=sys.stderr)
        yield


def _check_writable(*paths):
    """Refuse output files whose directory is missing before hours of work, not after."""
    for path in paths:
        if path:
            parent = os.path.dirname(os.path.abspath(path))
            if not os.path.isdir(parent):
                raise _UsageError(f"cannot write {path}: no directory {parent}")


def _state_for_directions(report, system):
    """A representative state: the centre of the sampling box."""
    lo, hi = system.box()
    return 0.5 * (lo + hi)


def _analyze(args) -> int:
    from .._analysis.analyze import analyze
    from .._io.loading import load_system
    from .._progress import StepPrinter, step_listener

    if args.plot:
        from .._analysis.plots import check_figure_path

        check_figure_path(args.plot)
    _check_writable(args.json, args.plot)
    system = load_system(args.model)
    printer = StepPrinter(enabled=False if args.no_progress else None)
    with step_listener(printer):
        rep = analyze(system, method=args.method, samples=args.samples, seed=args.seed,
                      rtol=args.rtol, max_order=args.max_order, k_max=args.k_max)
    print(rep)
    if rep.dim < rep.n:
        x = _state_for_directions(rep, system)
        try:
            dirs = rep.unobservable_directions(x)
        except UioJaxError:
            dirs = None
        if dirs is not None:
            print("unobservable directions at the centre of the domain "
                  f"({', '.join(f'{s}={v:.3g}' for s, v in zip(rep.states, x))}):")
            for j in range(dirs.shape[1]):
                print("  [" + ", ".join(f"{v:+.3f}" for v in dirs[:, j]) + "]")
    if args.json:
        d = rep.to_dict()
        with open(args.json, "w") as fh:
            json.dump(d, fh, indent=2)
        print(f"report written to {args.json}")
    if args.plot:
        from .._analysis.plots import plot_analysis

        plot_analysis(rep, args.plot)
        print(f"figure written to {args.plot}")
    return 0


def _batch(args) -> int:
    from .._batch.run import batch_analyze

    if not args.paths:
        raise _UsageError("batch needs at least one PATH (file, directory, glob or FILE.py:NAME)")
    _check_writable(args.json, args.csv, args.markdown)
    result = batch_analyze(args.paths, jobs=args.jobs, timeout=args.timeout,
                           progress=False if args.no_progress else None,
                           keep_reports=False, method=args.method, samples=args.samples,
                           seed=args.seed, rtol=args.rtol, max_order=args.max_order, k_max=args.k_max)
    print(result.table())
    print(result.summary())
    for path, text in ((args.json, lambda: result.to_json(indent=1)), (args.csv, result.to_csv),
                       (args.markdown, result.to_markdown)):
        if path:
            with open(path, "w") as fh:
                fh.write(text())
            print(f"written: {path}")
    return 0 if result.ok else EXIT_FAILED


def main(argv=None) -> int:
    """Entry point of ``uio-jax``; returns the exit code."""
    try:
        parser = _build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return EXIT_USAGE
        if args.command in ("analyze", "batch"):
            with _compile_cache(args):
                return _analyze(args) if args.command == "analyze" else _batch(args)
        if args.command == "montecarlo":
            montecarlo.split_host_devices()  # before anything starts JAX's backend
            with _compile_cache(args):
                return montecarlo.run(args)
        raise _UsageError(f"unknown command {args.command!r}")
    except _UsageError as exc:
        print(f"uio-jax: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except UioJaxError as exc:
        print(f"uio-jax: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"uio-jax: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "),
              file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("uio-jax: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
