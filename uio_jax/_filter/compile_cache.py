"""JAX's persistent compilation cache, set up for the Monte Carlo's programs.

The analyses compile nothing (numpy over the expression graph); the Monte Carlo
(:mod:`uio_jax._filter.montecarlo`: the EKF of every trial, one XLA program per experiment)
does. JAX can keep compiled programs on disk and reuse them in a later process when the
program is the same, so a second ``uio-jax montecarlo`` of the same experiment skips the
compile. uio_jax lowers JAX's thresholds (compile time, entry size) so every program is written.

Directory: :func:`default_cache_dir` unless given. The command line enables the cache by
default; the library does not touch JAX's configuration unless :func:`enable_compile_cache`
is called. As JAX warns, the cache is trusted input: do not point it at a directory others
can write.
"""

import contextlib
import errno
import os

#: JAX options set by :func:`enable_compile_cache` (name -> value; the directory is added).
_SETTINGS = {
    "jax_enable_compilation_cache": True,
    "jax_persistent_cache_min_compile_time_secs": 0.0,
    "jax_persistent_cache_min_entry_size_bytes": -1,
}
_DIR_KEY = "jax_compilation_cache_dir"


#: How :func:`default_cache_dir` resolves the directory, in words (the ``--cache-dir`` help).
DEFAULT_DIR_RULE = ("$UIO_JAX_CACHE_DIR if set, else $XDG_CACHE_HOME/uio_jax/xla if "
                    "XDG_CACHE_HOME is set, else ~/.cache/uio_jax/xla")


def default_cache_dir() -> str:
    """The default cache directory (not created): :data:`DEFAULT_DIR_RULE`.

    ``$UIO_JAX_CACHE_DIR`` if set and non-empty (``~`` expanded, made absolute), else
    ``$XDG_CACHE_HOME/uio_jax/xla`` if ``XDG_CACHE_HOME`` is set and non-empty, else
    ``~/.cache/uio_jax/xla``.
    """
    env = os.environ.get("UIO_JAX_CACHE_DIR")
    if env:
        return os.path.abspath(os.path.expanduser(env))
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "uio_jax", "xla")


def enable_compile_cache(path: str | os.PathLike | None = None) -> str:
    """Turn on JAX's persistent compilation cache for this process.

    Every XLA program compiled afterwards (by any JAX code in the process, not only uio_jax)
    is written to the cache directory, whatever its compile time or size, and a later
    process that compiles the same program loads it from there instead. Call it before the
    analyses; calling it again with another directory switches to that directory.

    Args:
        path: cache directory, created if missing (default :func:`default_cache_dir`).

    Returns:
        The absolute directory in use.

    Raises:
        OSError: the directory cannot be created.
    """
    import jax

    path = prepare_cache_dir(path)
    changed = jax.config.values.get(_DIR_KEY) != path
    for key, value in _SETTINGS.items():
        jax.config.update(key, value)
    jax.config.update(_DIR_KEY, path)
    if changed:
        _reset_jax_cache()
    return path


def prepare_cache_dir(path: str | os.PathLike | None = None) -> str:
    """The cache directory ``path`` (default :func:`default_cache_dir`), absolute and created,
    without touching JAX (the command line's commands that compile nothing check it so).

    Raises:
        OSError: the directory cannot be created (``NotADirectoryError``: a file is there).
    """
    path = os.path.abspath(os.path.expanduser(os.fspath(path))) if path is not None else default_cache_dir()
    if os.path.exists(path) and not os.path.isdir(path):  # makedirs would say only "File exists"
        raise NotADirectoryError(errno.ENOTDIR, "not a directory (the compilation cache needs one)", path)
    os.makedirs(path, exist_ok=True)
    return path


def disable_compile_cache() -> None:
    """Turn the persistent compilation cache off again (JAX's default: no directory)."""
    import jax

    jax.config.update(_DIR_KEY, None)
    _reset_jax_cache()


@contextlib.contextmanager
def compile_cache(path: str | os.PathLike | None = None):
    """Context manager: :func:`enable_compile_cache` inside, JAX's previous settings after.

    Yields:
        The absolute directory in use.
    """
    import jax

    saved = {key: jax.config.values.get(key) for key in (*_SETTINGS, _DIR_KEY)}
    try:
        yield enable_compile_cache(path)
    finally:
        for key, value in saved.items():
            jax.config.update(key, value)
        _reset_jax_cache()


def cache_dir_in_use() -> str | None:
    """The persistent cache directory JAX is configured with, or None."""
    import jax

    return jax.config.values.get(_DIR_KEY) or None


def _reset_jax_cache():
    """Make JAX re-read the cache settings at its next compile (it reads them once), through
    JAX's public ``jax.experimental.compilation_cache.compilation_cache.reset_cache``."""
    from jax.experimental.compilation_cache import compilation_cache

    compilation_cache.reset_cache()
