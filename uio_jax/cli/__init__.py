"""Command line: ``uio-jax analyze | batch | montecarlo | save-model``, one module per sub-command.

``main(argv) -> int`` returns the exit code: 0 on success, 2 on bad input (one line on
stderr, never a traceback from inside JAX), 1 when a batch has failures.

``batch`` and ``montecarlo`` use JAX's persistent compilation cache
(:func:`uio_jax.enable_compile_cache`; ``--cache-dir`` moves it, ``--no-cache`` turns it off,
the two together are a usage error). ``analyze`` and ``save-model`` compile nothing: they
check the directory and leave JAX alone, so that a model file is analysed without JAX.

Every option is checked before any work (:func:`uio_jax._analysis.options.check_options`;
the memory a run needs, :mod:`uio_jax._analysis.decisions.memory`, as soon as its size is known).
"""

import os
import sys

from .._analysis.decisions.memory import ENV as MEMORY_ENV
from .._analysis.decisions.rank import default_rtol
from .._analysis.options import DEFAULTS, KNOWN_INPUTS, METHODS, MIN_SAMPLES
from .._errors import UioJaxError, exit_message
from .._output import printable
from . import analyze, batch, montecarlo, save_model
from .common import EXIT_USAGE, Parser, UsageError, add_cache_options, check_cache_options, compile_cache
from .interrupts import prompt_interrupts

#: Exit code when the reader of stdout left early (128 + SIGPIPE, as ``yes | head`` gives).
EXIT_STDOUT_CLOSED = 141

COMMANDS = {"analyze": analyze, "batch": batch, "montecarlo": montecarlo, "save-model": save_model}
#: The commands that may compile XLA programs (the Monte Carlo; a batch keeps its timings in
#: the cache directory): the others only check the cache directory (:func:`compile_cache`).
COMPILING = ("batch", "montecarlo")


def _build_parser():
    p = Parser(prog="uio-jax", description="Unknown-input observability of nonlinear systems.")
    sub = p.add_subparsers(dest="command", parser_class=Parser)
    analyze.add_parser(sub, _analysis_options)
    batch.add_parser(sub, _analysis_options)
    add_cache_options(montecarlo.add_parser(sub))
    add_cache_options(save_model.add_parser(sub))
    return p


def _analysis_options(p):
    """The options of :func:`uio_jax.analyze`, with its defaults (one place:
    :mod:`uio_jax._analysis.options`)."""
    d = DEFAULTS
    p.add_argument("--method", default=d["method"], choices=METHODS,
                   help=f"analysis (default {d['method']}; fast falls back to orc where the series "
                        "engine cannot expand the model)")
    p.add_argument("--samples", type=int, default=d["samples"],
                   help=f"sampled states, >= {MIN_SAMPLES} (default {d['samples']}); a run whose arrays "
                        f"exceed ${MEMORY_ENV} (default half the physical memory) is refused")
    p.add_argument("--seed", type=int, default=d["seed"],
                   help=f"seed of the samples, in [0, 2**64) (default {d['seed']})")
    p.add_argument("--rtol", type=float, default=d["rtol"],
                   help=f"rank tolerance, in (0, 1) (default {default_rtol():g})")
    p.add_argument("--max-order", type=int, default=d["max_order"], help="cap on the steps m (order k), >= 0")
    p.add_argument("--k-max", type=int, default=d["k_max"],
                   help="highest order k of the EORC, >= 1 (default n + 2, or earlier where no "
                        "higher order can change a verdict; given, every order up to it is run); "
                        "the other methods do not use it (the report notes it)")
    p.add_argument("--prob-threshold", type=float, default=d["prob_threshold"],
                   help="probability of correctness of the exact decisions, in (0, 1) "
                        f"(default {d['prob_threshold']}; the report states the bound reached)")
    p.add_argument("--known-inputs", default=d["known_inputs"], choices=KNOWN_INPUTS,
                   help="what a known input is: switchable (default: it may jump, the papers' "
                        "meaning) or smooth (a generic smooth function of time, TUIO6's)")
    p.add_argument("--global", dest="scope", action="store_const", const="global", default=d["scope"],
                   help="also the global question: how many values each parameter and unknown initial state "
                        "takes (global / local / not / undecided; SIAN's algorithm solved by msolve, the "
                        "'global' extra: pip install 'uio_jax[global]'; docs/global.md)")


def main(argv=None) -> int:
    """Entry point of ``uio-jax``; returns the exit code."""
    try:
        parser = _build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return EXIT_USAGE
        if args.command not in COMMANDS:
            raise UsageError(f"unknown command {args.command!r}")
        check_cache_options(args)  # a usage error before any side effect
        if args.command == "montecarlo":
            montecarlo.split_host_devices()  # before anything starts JAX's backend
        # Ctrl-C ends the command promptly, never swallowed (batch cleans up its workers itself)
        with compile_cache(args, compiles=args.command in COMPILING), \
                prompt_interrupts(watchdog=args.command != "batch"):
            try:
                return COMMANDS[args.command].run(args)
            except SystemExit as exc:  # a model or experiment function JAX traced in the run
                raise UsageError(f"a model function {exit_message(exc)} during {args.command}; a "
                                 "model must not end the program") from None
    except (UsageError, UioJaxError) as exc:
        print(f"uio-jax: error: {printable(exc)}", file=sys.stderr)  # one line, inert
        return EXIT_USAGE
    except BrokenPipeError as exc:
        if exc.filename is not None:  # an output file (a FIFO whose reader left): lost, an error
            print(printable(f"uio-jax: error: {exc.strerror}: {exc.filename}"), file=sys.stderr)
            return EXIT_USAGE
        return _stdout_closed()
    except OSError as exc:
        print(printable(f"uio-jax: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": ")),
              file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("uio-jax: interrupted", file=sys.stderr)
        return 130


def _stdout_closed() -> int:
    """The reader of stdout left (``uio-jax ... | head``): end quietly, as a process killed by
    SIGPIPE would (exit code 141), without a second error when Python flushes stdout at exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout without a file descriptor (captured): nothing to redirect
        pass
    return EXIT_STDOUT_CLOSED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
