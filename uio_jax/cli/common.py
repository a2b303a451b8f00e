"""What the sub-commands share: the one-line usage error, the checks of output paths and
JAX's persistent compilation cache for the duration of a command."""

import argparse
import contextlib
import os
import sys

from .._output import write_output  # noqa: F401  (the one writer of every output)

EXIT_USAGE = 2
EXIT_FAILED = 1


def analysis_kwargs(args) -> dict:
    """The keyword arguments of :func:`uio_jax.analyze` given on the command line (``analyze``, ``batch``)."""
    return {k: getattr(args, k) for k in ("method", "samples", "seed", "rtol", "max_order", "k_max",
                                          "prob_threshold", "known_inputs")}


class UsageError(Exception):
    """A bad command line: printed as one line, exit code 2."""


class Parser(argparse.ArgumentParser):
    """argparse that reports errors as one line and exit code 2."""

    def error(self, message):
        raise UsageError(message)


def model_prints_on_stderr():
    """While models load and run: what they ``print`` goes to stderr, so stdout carries the
    report alone (``uio-jax analyze m.toml > report.txt``, ``| head``)."""
    return contextlib.redirect_stdout(sys.stderr)


def add_cache_options(p):
    """``--no-cache`` and ``--cache-dir`` on the sub-command parser ``p`` (the default
    directory's rule in the help is :data:`uio_jax._filter.compile_cache.DEFAULT_DIR_RULE`,
    the rule :func:`~uio_jax._filter.compile_cache.default_cache_dir` applies)."""
    from .._filter.compile_cache import DEFAULT_DIR_RULE

    p.add_argument("--no-cache", action="store_true",
                   help="do not use the persistent compilation cache (not with --cache-dir)")
    p.add_argument("--cache-dir", metavar="DIR",
                   help=f"compilation cache directory (default: {DEFAULT_DIR_RULE})")


def check_cache_options(args):
    """``--no-cache`` with ``--cache-dir DIR`` contradict each other: a usage error."""
    if getattr(args, "no_cache", False) and getattr(args, "cache_dir", None) is not None:
        raise UsageError(f"--no-cache and --cache-dir {args.cache_dir} contradict each other; "
                         "give one of them")


@contextlib.contextmanager
def compile_cache(args, compiles=True):
    """JAX's persistent compilation cache for the command, unless ``--no-cache``.

    An unusable default directory only costs the cache (one warning line); an unusable
    ``--cache-dir`` is an error, and so is ``--cache-dir`` with ``--no-cache``. A command that
    compiles nothing (``compiles`` False: ``analyze``, ``save-model``) only checks the
    directory and leaves JAX alone.
    """
    from .._filter.compile_cache import compile_cache as use_cache
    from .._filter.compile_cache import prepare_cache_dir

    check_cache_options(args)
    with contextlib.ExitStack() as stack:
        if not args.no_cache:
            try:
                if compiles:
                    stack.enter_context(use_cache(args.cache_dir))
                else:
                    prepare_cache_dir(args.cache_dir)
            except OSError as exc:
                if args.cache_dir:
                    raise
                print(f"uio-jax: warning: compilation cache off ({exc.strerror or exc}: {exc.filename})",
                      file=sys.stderr)
        yield


def check_writable(*paths, names=None, inputs=()):
    """Refuse output files that cannot be written, before hours of work, not after.

    Each given path must be a non-empty name in an existing, writable directory, must not
    be a directory itself nor one of the input files, and no two may name the same file. A
    path that exists and is no regular file (a device, a FIFO) is written in place by
    :func:`write_output`.

    Args:
        *paths: output paths (None for an option not given; "" is refused).
        names: the options' names (``"--json"``), one per path, for the messages.
        inputs: the paths the command reads (``FILE.py:NAME``, files, directories, globs).

    Raises:
        UsageError: the first path that fails, named.
    """
    names = names or [None] * len(paths)
    read = _input_files(inputs)
    seen = {}
    for name, path in zip(names, paths):
        if path is None:
            continue
        what = f"{name} {path}" if name else path
        if not str(path).strip():
            raise UsageError(f"{name or 'an output'} needs a file name, got {path!r}")
        full = os.path.abspath(path)
        parent = os.path.dirname(full)
        if not os.path.isdir(parent):
            raise UsageError(f"cannot write {what}: no directory {parent}")
        if os.path.isdir(full):
            raise UsageError(f"cannot write {what}: it is a directory")
        if not os.access(parent, os.W_OK) or (os.path.exists(full) and not os.access(full, os.W_OK)):
            raise UsageError(f"cannot write {what}: {'it' if os.path.exists(full) else 'directory ' + parent}"
                             " is not writable")
        _probe(full, what)
        same = next((src for src in read if _same_file(full, src)), None)
        if same is not None:
            raise UsageError(f"cannot write {what}: it is the input model file {same}, which it would "
                             "overwrite")
        key = os.path.realpath(full)
        if key in seen:
            raise UsageError(f"{seen[key] or 'two outputs'} and {name or 'another output'} name the same "
                             f"file {path}")
        seen[key] = name


@contextlib.contextmanager
def hold_outputs(paths):
    """Hold an exclusive lock per output file for the block: a second command writing one
    of the same files meanwhile is refused up front with a UsageError. The locks are files of
    ``$TMPDIR/uio_jax-outputs-UID/``, released when the block ends or the process dies;
    devices and FIFOs are not locked; a platform without ``fcntl`` locks nothing."""
    try:
        import fcntl
        import hashlib
        import tempfile

        folder = os.path.join(tempfile.gettempdir(), f"uio_jax-outputs-{os.getuid()}")
        os.makedirs(folder, exist_ok=True)
    except (ImportError, OSError, AttributeError):  # no locks here: nothing is held
        yield
        return
    with contextlib.ExitStack() as stack:
        for path in paths:
            real = os.path.realpath(path)
            if os.path.exists(real) and not os.path.isfile(real):
                continue
            name = hashlib.sha1(real.encode("utf-8", "surrogateescape")).hexdigest() + ".lock"
            fh = stack.enter_context(open(os.path.join(folder, name), "a"))
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                raise UsageError(f"{path} is being written by another uio-jax command; give another "
                                 "file or wait for it to finish") from None
        yield


def _probe(full, what):
    """Try the write without writing: open an existing regular file for appending (nothing
    changes), or create and remove a file beside a new one (``/proc/x``, a read-only file
    system: refused here, not after the work). A device or a FIFO is left to the write."""
    try:
        if os.path.isfile(full):
            open(full, "ab").close()
        elif not os.path.exists(full):
            probe = f"{full}.{os.getpid()}.probe"
            open(probe, "wb").close()
            os.remove(probe)
    except OSError as exc:
        raise UsageError(f"cannot write {what}: {exc.strerror or exc}") from None


def _input_files(inputs):
    """The existing files a command reads: each input itself, the FILE of ``FILE.py:NAME``,
    the model files of a directory or a glob."""
    from .._batch.discovery import expand
    from .._errors import UioJaxError

    files = []
    for item in inputs:
        item = os.fspath(item)
        if os.path.isfile(item):
            files.append(item)
            continue
        path, sep, _ = item.rpartition(":")
        if sep and os.path.isfile(path):
            files.append(path)
            continue
        try:
            files += [f.rpartition(":")[0] if not os.path.exists(f) else f for f in expand(item)]
        except (UioJaxError, OSError, ValueError):
            pass  # a missing input is the loader's error, later
    return files


def _same_file(a, b) -> bool:
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False
