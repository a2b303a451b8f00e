"""``uio-jax batch PATH... [options]``: certify many models into one table."""

import contextlib
import signal
import sys

from .._output import printable
from .common import (
    EXIT_FAILED,
    UsageError,
    add_cache_options,
    analysis_kwargs,
    check_writable,
    hold_outputs,
    model_prints_on_stderr,
    write_output,
)
from .sbml_options import add_sbml_options, sbml_options

#: Exit code after Ctrl-C (128 + SIGINT), the partial table printed and written.
EXIT_INTERRUPTED = 130
#: Exit code after SIGTERM (128 + SIGTERM): stopped as by Ctrl-C.
EXIT_TERMINATED = 143


def add_parser(subparsers, analysis_options):
    """Add the ``batch`` sub-command; ``analysis_options(p)`` adds the shared analysis flags."""
    b = subparsers.add_parser(
        "batch", help="certify many models into one table",
        description="Certify many models into one table. A .py file found in a directory or a glob "
                    "is imported (its top-level code runs) only when one of its first lines is "
                    "'# uio-jax: models' or with --import-python; a StrikePy module is parsed, never "
                    "executed; other .py files are listed as not imported. A file named on the command "
                    "line (FILE.py, FILE.py:NAME) is always loaded.")
    b.add_argument("paths", nargs="*", metavar="PATH",
                   help="FILE.py:NAME, zoo files (every function returning a System), .toml/.json "
                        "model files, StrikePy modules, SBML models (.xml/.sbml, with --outputs), "
                        "directories, globs")
    analysis_options(b)
    b.add_argument("--json", metavar="FILE", help="write the table as JSON (rewritten after each model)")
    b.add_argument("--csv", metavar="FILE", help="write the table as CSV (rewritten after each model)")
    b.add_argument("--markdown", metavar="FILE",
                   help="write the table as Markdown (rewritten after each model)")
    b.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    b.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help="time limit per model: a model over it is stopped and reported as timed out, "
                        "with the last order it reached (runs models in worker processes, which also "
                        "import the zoo files, under the limit; default: no limit)")
    b.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the models on the workers of a running Dask cluster (tcp://host:8786; "
                        "needs uio_jax[cluster]); the workers must see the model files and the cache "
                        "directory at the same paths; not with --jobs")
    b.add_argument("--import-python", action="store_true",
                   help="also import .py files of directories and globs without the "
                        "'# uio-jax: models' marker (runs their top-level code)")
    b.add_argument("--no-progress", action="store_true",
                   help="no progress on stderr (by default: a bar on a terminal, one line per finished "
                        "model elsewhere)")
    add_sbml_options(b)
    add_cache_options(b)
    return b


def run(args) -> int:
    """Run the sub-command; returns the exit code (errors propagate as UioJaxError).

    The ``--json/--csv/--markdown`` files are rewritten (atomically) after every finished
    model. ``--scheduler ADDRESS`` sends the models to a Dask cluster (a scheduler that
    cannot be reached is a one-line error, exit code 2). On Ctrl-C the workers are
    stopped, the partial table is printed and written (marked "interrupted after K of N
    models") and the exit code is 130; SIGTERM does the same with exit code 143.
    """
    from .._analysis.options import check_options

    check_options(**analysis_kwargs(args))  # before any model is found
    if not args.paths:
        raise UsageError("batch needs at least one PATH (file, directory, glob or FILE.py:NAME)")
    check_writable(args.json, args.csv, args.markdown, names=("--json", "--csv", "--markdown"),
                   inputs=args.paths)
    if args.scheduler is not None and args.jobs != 1:
        raise UsageError(f"--jobs {args.jobs} and --scheduler exclude each other (the cluster's workers "
                         "run the models)")
    outputs = [(path, fmt) for path, fmt in ((args.json, "json"), (args.csv, "csv"),
                                              (args.markdown, "markdown")) if path]
    with hold_outputs([path for path, _ in outputs]):  # no second batch writes them meanwhile
        return _run(args, outputs)


def _run(args, outputs) -> int:
    """:func:`run` once its options are checked and its output files held."""
    from .._batch.run import BatchInterrupted, batch_analyze

    code, terminated = None, []
    try:
        with _sigterm_as_interrupt(terminated), model_prints_on_stderr():
            result = batch_analyze(
                args.paths, jobs=args.jobs, timeout=args.timeout, client=args.scheduler,
                progress=False if args.no_progress else None, keep_reports=False,
                import_python=args.import_python, sbml=sbml_options(args) or None,
                on_row=(lambda partial: write_outputs(outputs, partial)) if outputs else None,
                scope=args.scope, **analysis_kwargs(args))
    except BatchInterrupted as exc:
        result, code = exc.result, EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
        print(f"uio-jax: {result.partial}", file=sys.stderr)
    print(result.table())
    for path in result.not_imported:
        print(f"not imported: {printable(path)} (no '# uio-jax: models' marker; name the file or pass --import-python)")
    print(result.summary())
    write_outputs(outputs, result)
    for path, _ in outputs:
        print(f"written: {printable(path)}")
    if code is not None:
        return code
    return 0 if result.ok else EXIT_FAILED


@contextlib.contextmanager
def _sigterm_as_interrupt(flag):
    """SIGTERM stops the batch as Ctrl-C does (workers stopped, the partial table printed
    and written; ``flag`` gets an entry), instead of killing this process under its
    workers."""
    def handler(signum, frame):
        flag.append(signum)
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave SIGTERM as it is
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def write_outputs(outputs, result):
    """Write ``result`` to every ``(path, format)`` of ``outputs`` (json, csv, markdown),
    each by :func:`~uio_jax.cli.common.write_output` (a regular file through a temporary
    file then ``os.replace``: a reader, or a crash, never sees half a file; a failed
    write is an OSError naming the file)."""
    for path, fmt in outputs:
        text = {"json": lambda: result.to_json(indent=1), "csv": result.to_csv,
                "markdown": result.to_markdown}[fmt]()
        write_output(path, text)
