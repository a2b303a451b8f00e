"""``uio-jax batch PATH... [options]``: certify many models into one table."""

from .common import EXIT_FAILED, UsageError, add_cache_options, check_writable


def add_parser(subparsers, analysis_options):
    """Add the ``batch`` sub-command; ``analysis_options(p)`` adds the shared analysis flags."""
    b = subparsers.add_parser("batch", help="certify many models into one table")
    b.add_argument("paths", nargs="*", metavar="PATH",
                   help="FILE.py:NAME, zoo files (every function returning a System), .toml/.json "
                        "model files, directories, globs")
    analysis_options(b)
    b.add_argument("--json", metavar="FILE", help="write the table as JSON")
    b.add_argument("--csv", metavar="FILE", help="write the table as CSV")
    b.add_argument("--markdown", metavar="FILE", help="write the table as Markdown")
    b.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    b.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help="time limit per model: a model over it is stopped and reported as timed out "
                        "(runs models in worker processes; default: no limit)")
    b.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_cache_options(b)
    return b


def run(args) -> int:
    """Run the sub-command; returns the exit code (errors propagate as UioJaxError)."""
    from .._batch.run import batch_analyze

    if not args.paths:
        raise UsageError("batch needs at least one PATH (file, directory, glob or FILE.py:NAME)")
    check_writable(args.json, args.csv, args.markdown)
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
