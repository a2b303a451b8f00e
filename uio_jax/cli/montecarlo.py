"""``uio-jax montecarlo MODEL:EXPERIMENT --trials N --seed S [--plot FILE] [--json FILE]``."""

import contextlib
import json
import os
import sys
import warnings

from .._engine.seeds import check_seed
from .._errors import OptionError
from .._io.experiment_loading import load_experiment
from .._model.experiment import TimeScaleWarning
from .._output import write_figure
from .common import check_writable, model_prints_on_stderr, write_output

#: Figures are saved at this resolution (raster formats; vector formats ignore it).
FIGURE_DPI = 150


def add_parser(subparsers):
    """Add the ``montecarlo`` sub-command to an argparse ``subparsers`` object."""
    p = subparsers.add_parser("montecarlo", help="Monte Carlo EKF of a zoo experiment")
    p.add_argument("experiment", help="FILE.py:NAME, a function returning an Experiment "
                                      "(NAME or NAME_experiment)")
    p.add_argument("--trials", type=int, default=256, help="number of trials (default 256)")
    p.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    p.add_argument("--keep", type=int, default=4, help="full trajectories kept (default 4)")
    p.add_argument("--plot", metavar="FILE", help="write the figure (PNG, PDF, ...)")
    p.add_argument("--json", metavar="FILE", help="write the summary as JSON")
    p.add_argument("--filter", choices=("fast", "reference"), default="fast",
                   help="the EKF: the fast CPU kernels (default) or the reference equations "
                        "(F P F^T + Q, Joseph update; slower, for checking)")
    p.add_argument("--no-analysis", action="store_true",
                   help="skip the observability analysis shown beside the verdict")
    p.add_argument("--known-inputs", choices=("switchable", "smooth"), default="switchable",
                   help="the meaning of a known input in the analysis beside the verdict: switchable "
                        "(default: it may jump) or smooth (a generic smooth function of time); the "
                        "simulated inputs are the experiment's own"),
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="split the trials over the workers of a running Dask cluster "
                        "(tcp://host:8786; needs uio_jax[cluster]): the same statistics, bit for bit")
    return p


def split_host_devices():
    """On a CPU, split the host into one JAX device per core (before the backend starts).

    Returns the number of devices requested, or 0 when the backend was already running
    (then the run uses the devices it has).
    """
    import jax

    n = os.cpu_count() or 1
    try:
        jax.config.update("jax_num_cpu_devices", n)
    except Exception:  # backend already initialised: keep its devices
        return 0
    return n


def check_options(args):
    """Every option and output path checked before any work (one-line errors).

    ``--trials >= 1``, ``--seed`` in ``[0, 2**64)``, ``--keep >= 0``; ``--plot``: a suffix
    matplotlib writes; ``--json`` / ``--plot``: an existing, writable directory, not a
    directory themselves, not the same file; ``--scheduler``: a Dask scheduler answers there.
    """
    if args.trials <= 0:
        raise OptionError(f"--trials must be a positive integer, got {args.trials}")
    check_seed(args.seed, "--seed")
    if args.keep < 0:
        raise OptionError(f"--keep must be a non-negative integer, got {args.keep}")
    if args.plot:
        from .._analysis.results.plots import check_figure_path

        check_figure_path(args.plot)
    check_writable(args.json, args.plot, names=("--json", "--plot"), 
                   inputs=[args.experiment] if getattr(args, "experiment", None) else ())
    if getattr(args, "scheduler", None) is not None:
        from .._filter.cluster import check_scheduler, pin_workers

        pin_workers()
        check_scheduler(args.scheduler)


@contextlib.contextmanager
def warnings_on_stderr(categories=(TimeScaleWarning,)):
    """Show warnings of ``categories`` as one line ``uio-jax: warning: ...`` on stderr,
    as they happen (each message once); other warnings as Python shows them."""
    shown = set()
    with warnings.catch_warnings():
        previous = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, categories):
                text = " ".join(str(message).split())
                if text not in shown:
                    shown.add(text)
                    print(f"uio-jax: warning: {text}", file=sys.stderr)
            else:
                previous(message, category, filename, lineno, file, line)

        for c in categories:
            warnings.simplefilter("always", c)
        warnings.showwarning = show
        yield


def run(args) -> int:
    """Run the sub-command; returns the exit code (errors propagate as UioJaxError)."""
    check_options(args)
    split_host_devices()
    from .._filter.montecarlo import run_montecarlo

    comparison = None
    with warnings_on_stderr(), model_prints_on_stderr():
        exp = load_experiment(args.experiment)
        res = run_montecarlo(exp, args.trials, seed=args.seed, keep=args.keep, filter=args.filter,
                             progress=False if args.no_progress else None,
                             client=getattr(args, "scheduler", None))
        if not args.no_analysis:
            from .._analysis.analyze import analyze

            comparison = res.compare(analyze(exp.analysis_system(), known_inputs=args.known_inputs))
    print(res.summary(comparison))
    if args.json:
        d = res.to_dict(comparison)  # says what the text says: outcome, headline, filter
        write_output(args.json, json.dumps(d, indent=1))
        print(f"summary written to {args.json}")
    if args.plot:
        from .._analysis.results.plots import check_figure_path
        from .._filter.plots import plot_montecarlo

        fig, _ = plot_montecarlo(res)
        try:
            write_figure(fig, args.plot, check_figure_path(args.plot), dpi=FIGURE_DPI)
        finally:
            import matplotlib.pyplot as plt

            plt.close(fig)
        print(f"figure written to {args.plot}")
    return 0
