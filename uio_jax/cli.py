"""Command line: ``uio-jax analyze | batch | montecarlo``.

``main(argv) -> int`` returns the exit code: 0 on success, 2 on bad input (one line on
stderr, never a traceback from inside JAX), 1 when a batch has failures.
"""

import argparse
import json
import sys

from ._errors import UioJaxError

EXIT_USAGE = 2


class _Parser(argparse.ArgumentParser):
    """argparse that reports errors as one line and exit code 2."""

    def error(self, message):
        raise _UsageError(message)


class _UsageError(Exception):
    pass


def _build_parser():
    from ._analyze import METHODS

    p = _Parser(prog="uio-jax", description="Unknown-input observability of nonlinear systems.")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)
    a = sub.add_parser("analyze", help="observability analysis of one model")
    a.add_argument("model", help="FILE.py:FUNCTION returning a uio_jax.System")
    a.add_argument("--method", default="auto", choices=METHODS, help="analysis (default auto)")
    a.add_argument("--samples", type=int, default=4096, help="sampled states (default 4096)")
    a.add_argument("--seed", type=int, default=0, help="seed of the samples (default 0)")
    a.add_argument("--rtol", type=float, default=None, help="rank tolerance (default 1e-8)")
    a.add_argument("--max-order", type=int, default=None, help="cap on the steps m (order k)")
    a.add_argument("--json", metavar="FILE", help="also write the report as JSON")
    try:
        from . import _montecarlo_cli
    except ImportError:  # the Monte Carlo module is optional at this stage
        _montecarlo_cli = None
    if _montecarlo_cli is not None:
        _montecarlo_cli.add_parser(sub)
    return p


def _state_for_directions(report, system):
    """A representative state: the centre of the sampling box."""
    lo, hi = system.box()
    return 0.5 * (lo + hi)


def _analyze(args) -> int:
    from ._analyze import analyze
    from ._loading import load_system

    system = load_system(args.model)
    rep = analyze(system, method=args.method, samples=args.samples, seed=args.seed,
                  rtol=args.rtol, max_order=args.max_order)
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
    return 0


def main(argv=None) -> int:
    """Entry point of ``uio-jax``; returns the exit code."""
    try:
        parser = _build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return EXIT_USAGE
        if args.command == "analyze":
            return _analyze(args)
        if args.command == "montecarlo":
            from . import _montecarlo_cli

            return _montecarlo_cli.run(args)
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
