"""Compiled programs kept on disk under a key found without tracing.

JAX's persistent compilation cache (:mod:`uio_jax._compile_cache`) stores XLA executables
keyed by the lowered program, so a later process still has to *trace* every nested Lie
derivative in Python and lower it to find the key: for deep models that is most of a warm
run. This module stores each compiled program (``jax.experimental.serialize_executable``)
under a key that identifies the computation without tracing it:

    key = sha256( environment    jax / jaxlib versions, backend, machine and CPU model and
                                 flags, the uio_jax source files,
                  model          the jaxprs of the model's own functions (outputs and
                                 fields, with their constants), traced once: milliseconds,
                  program        what is differentiated: the structural signatures of the
                                 generator nodes (operation tree down to the model's named
                                 outputs and fields), the kind of evaluation, the sample
                                 shape and dtype )

A later process with the same key loads the executable (a fraction of a second) and runs
it: no tracing, no lowering, no XLA compilation. Anything that changes the computation
changes the key: another model function or constant, another version of uio_jax or jax,
another CPU. A program whose nodes have no structural signature (a user callable given to
``Report.is_observable``), a model whose functions cannot be traced on their own, or an
executable the backend cannot serialize is traced and compiled as before.

The program cache is active exactly when the persistent compilation cache is
(:func:`uio_jax.enable_compile_cache`, on by default on the command line); its files live in
``<cache dir>/uio_jax_programs``. Like JAX's cache it is trusted input (the files are
unpickled): keep it in a directory only you can write.
"""

import contextlib
import hashlib
import json
import math
import os
import pickle
import platform
import tempfile
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path

import jax
import numpy as np

from .compile_cache import cache_dir_in_use


def _physical_memory() -> int:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # not POSIX: assume 8 GiB
        return 8 << 30


#: A program whose temporaries would take more bytes than this (a quarter of the machine's
#: memory, at least 1 GiB) runs over the samples in batches (``lax.map``) instead of all at
#: once (``vmap``): deep Taylor passes of large models at 4096 samples can otherwise ask for
#: tens of GB. The check reads XLA's memory analysis of the compiled program.
MEMORY_BUDGET = max(1 << 30, _physical_memory() // 4)

#: XLA options that shorten compiling large element-wise graphs: the CPU's fusion emitters
#: off (XLA's older loop emitters compile them 20-45 % faster and run them as fast; see
#: the EORC blocks and the streamed series programs). An XLA without the option compiles
#: with its defaults (:func:`_compile`).
FAST_COMPILE = {"xla_cpu_use_fusion_emitters": False}

#: Sub-directory of the compilation cache directory holding the serialized programs.
SUBDIR = "uio_jax_programs"

_FORMAT = 2  # bump when the file layout or the key recipe changes
_MODEL_PRINTS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_ENV_PRINT: list = []


def program_dir() -> Path | None:
    """Where programs are kept now: ``<compilation cache dir>/uio_jax_programs``, or None."""
    base = cache_dir_in_use()
    return Path(base) / SUBDIR if base else None


def model_fingerprint(system) -> str | None:
    """Hash of what a System computes: states, and the jaxprs of its outputs and fields.

    Each function is traced once on an abstract float64 state of shape ``(n,)``; the
    printed jaxpr (every operation and literal) and the bytes of its constants are hashed.
    Returns None when a function cannot be traced on its own (the program cache is then not
    used for this System). Cached per System object.
    """
    if system in _MODEL_PRINTS:
        return _MODEL_PRINTS[system]
    digest = hashlib.sha256()
    digest.update(repr((system.states, system.n)).encode())
    try:
        with jax.enable_x64(True):
            x = jax.ShapeDtypeStruct((system.n,), np.float64)
            for kind, fns in (("output", system.outputs), ("field", system.fields())):
                for label, fn in fns.items():
                    closed = jax.make_jaxpr(fn)(x)
                    digest.update(f"{kind}:{label}\n{closed.jaxpr}\n".encode())
                    for const in closed.consts:
                        arr = np.asarray(const)
                        digest.update(f"{arr.dtype}{arr.shape}".encode())
                        digest.update(arr.tobytes())
    except Exception:  # a function that only traces inside a larger program: no cache
        _MODEL_PRINTS[system] = None
        return None
    _MODEL_PRINTS[system] = fp = digest.hexdigest()
    return fp


def _environment_fingerprint() -> str:
    """jax / jaxlib versions, backend platform and the uio_jax source files (cached)."""
    if not _ENV_PRINT:
        digest = hashlib.sha256()
        import jaxlib

        digest.update(f"{_FORMAT} {jax.__version__} {jaxlib.__version__} {jax.default_backend()}".encode())
        digest.update(f"{platform.machine()} {jax.devices()[0].device_kind} {_cpu_identity()}".encode())
        for path in sorted(Path(__file__).parent.glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
        _ENV_PRINT.append(digest.hexdigest())
    return _ENV_PRINT[0]


def _cpu_identity() -> str:
    """CPU model name and feature flags (executables are compiled for the host CPU)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return platform.processor()
    keep = [ln for ln in text.splitlines() if ln.split(":")[0].strip() in ("model name", "flags")]
    return "\n".join(sorted(set(keep)))


def program_key(system, parts, xs) -> str | None:
    """The disk key of one program, or None when it cannot be keyed safely.

    Args:
        system: the System whose functions the program differentiates.
        parts: strings naming the program structurally (evaluation kind, node signatures);
            None or an empty string among them means "not keyable".
        xs: the sample array the program is evaluated on (its shape and dtype are keyed).
    """
    if program_dir() is None or any(not p for p in parts):
        return None
    model = model_fingerprint(system)
    if model is None:
        return None
    digest = hashlib.sha256()
    for part in (_environment_fingerprint(), model, *parts, f"{tuple(xs.shape)} {xs.dtype}"):
        digest.update(part.encode())
        digest.update(b"\0")
    return digest.hexdigest()


def load(key: str):
    """``(compiled, meta)`` stored under ``key``, or None (missing or unreadable file)."""
    directory = program_dir()
    if key is None or directory is None:
        return None
    path = directory / f"{key}.prog"
    try:
        data = path.read_bytes()
        header, _, body = data.partition(b"\n")
        meta = json.loads(header)
        from jax.experimental import serialize_executable

        payload, in_tree, out_tree = pickle.loads(body)
        return serialize_executable.deserialize_and_load(payload, in_tree, out_tree), meta
    except FileNotFoundError:
        return None
    except Exception:  # corrupt, or written by an incompatible version: ignored, rewritten
        return None


def store(key: str, compiled, meta: dict) -> bool:
    """Write the compiled program under ``key``; False when it cannot be serialized or written."""
    directory = program_dir()
    if key is None or directory is None:
        return False
    try:
        from jax.experimental import serialize_executable

        body = pickle.dumps(serialize_executable.serialize(compiled))
    except Exception:  # an executable this backend cannot serialize
        return False
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=directory, delete=False, suffix=".tmp") as tmp:
            tmp.write(json.dumps(meta).encode() + b"\n" + body)
        os.replace(tmp.name, directory / f"{key}.prog")
    except OSError:  # read-only or full cache directory: the program still serves this process
        return False
    return True


@dataclass(frozen=True)
class Timing:
    """How one program was obtained: jaxpr size, seconds tracing / compiling, from disk.

    ``facts``: what ``options_for`` measured on the traced program (kept with it on disk).
    """

    eqns: int
    trace_s: float
    compile_s: float
    from_disk: bool
    facts: dict = field(default_factory=dict)


def compile_program(system, parts, make_jitted, xs, options_for=None):
    """Compile ``make_jitted(batch)`` for ``xs``, through the program cache when it is on.

    Args:
        system: the System whose functions the program differentiates (for the key).
        parts: structural names of the program (see :func:`program_key`).
        make_jitted: ``batch -> jax.jit(...)`` function of one array argument like ``xs``
            (``batch`` None: all samples at once; else that many at a time, see
            :func:`vmapped`).
        xs: the argument (float64 samples).
        options_for: ``traced -> (eqns, xla_options or None[, facts])``, called after
            tracing; ``facts`` (a JSON-able dict) is stored with the program and returned
            in :attr:`Timing.facts`, also when the program comes from disk.

    Returns:
        ``(compiled, Timing)``. Errors raised while tracing (a primitive without a rule)
        propagate unchanged.
    """
    key = program_key(system, parts, xs)
    t0 = time.perf_counter()
    hit = load(key) if key else None
    if hit is not None:
        compiled, meta = hit
        retrace = lambda: _trace_and_compile(key, make_jitted, xs, options_for)[0]  # noqa: E731
        return _Loaded(compiled, key, retrace), Timing(int(meta.get("eqns", 0)), 0.0,
                                                       time.perf_counter() - t0, True,
                                                       dict(meta.get("facts") or {}))
    return _trace_and_compile(key, make_jitted, xs, options_for)


class _Loaded:
    """A program loaded from disk; if it fails to run, the file is dropped and it is rebuilt."""

    def __init__(self, compiled, key, retrace):
        self._compiled, self._key, self._retrace = compiled, key, retrace

    def __call__(self, *args):
        try:
            return self._compiled(*args)
        except jax.errors.JaxRuntimeError:
            directory = program_dir()
            if directory is not None:
                with contextlib.suppress(OSError):
                    (directory / f"{self._key}.prog").unlink()
            self._compiled = self._retrace()
            return self._compiled(*args)


def _trace_and_compile(key, make_jitted, xs, options_for):
    """Trace and compile ``make_jitted(None)``; if its temporaries exceed
    :data:`MEMORY_BUDGET`, trace and compile ``make_jitted(batch)`` instead (the samples in
    batches of a power of two that fits), keeping the facts of the first trace. The result
    is stored under ``key``."""
    t0 = time.perf_counter()
    traced, eqns, options, facts = _trace(make_jitted, None, xs, options_for)
    t1 = time.perf_counter()
    compiled, fresh = _compile(traced, options)
    temp = _temp_bytes(compiled)
    if temp > MEMORY_BUDGET and xs.shape[0] > 1:
        batch = max(1, 2 ** int(math.floor(math.log2(xs.shape[0] * MEMORY_BUDGET / temp))))
        t2 = time.perf_counter()
        # facts stay those of the whole trace: measured on the batched one they would
        # describe the batch, not the program (e.g. the EORC's per-sample sizes)
        traced, eqns, options, _ = _trace(make_jitted, batch, xs, options_for)
        t1 += time.perf_counter() - t2
        compiled, fresh = _compile(traced, options)
    t2 = time.perf_counter()
    if key and fresh:
        store(key, compiled, {"eqns": eqns, "options": options, "facts": facts})
    return compiled, Timing(eqns, t1 - t0, t2 - t1, False, facts)


def _trace(make_jitted, batch, xs, options_for):
    traced = make_jitted(batch).trace(xs)
    eqns, options, *facts = options_for(traced) if options_for else (0, None)
    return traced, eqns, options, (facts[0] if facts else {})


def _compile(traced, options):
    """``(compiled, fresh)``: fresh when JAX's persistent cache was bypassed (storable)."""
    lowered = traced.lower()
    with _fresh_compile() as fresh:
        try:
            compiled = lowered.compile(options) if options else lowered.compile()
        except jax.errors.JaxRuntimeError as exc:
            if not (options and "compile option" in str(exc)):
                raise
            compiled = lowered.compile()  # an XLA without one of the options: its defaults
    return compiled, fresh


def _temp_bytes(compiled) -> int:
    try:
        return int(compiled.memory_analysis().temp_size_in_bytes)
    except Exception:  # a backend without memory analysis
        return 0


def vmapped(fn, batch=None):
    """``jax.jit`` of ``fn`` over a leading sample axis: ``vmap``, or ``lax.map`` in batches."""
    if batch is None:
        return jax.jit(jax.vmap(fn))
    return jax.jit(lambda xs: jax.lax.map(fn, xs, batch_size=batch))


@contextlib.contextmanager
def _fresh_compile():
    """Compile without JAX's persistent cache; yields whether that could be arranged.

    An executable that JAX *loaded* from its persistent cache cannot be serialized again
    on the CPU (the copy fails at run time: "Function ... not found"), so a program is only
    stored when it was compiled here. JAX decides once per process whether its cache is
    used (``compilation_cache._cache_used``); the decision is overridden for this compile
    only. If that private switch is missing (another JAX), nothing is stored.
    """
    try:
        from jax._src import compilation_cache as cc

        lock, saved = cc._cache_initialized_mutex, (cc._cache_checked, cc._cache_used)
    except (ImportError, AttributeError):
        yield False
        return
    with lock:
        cc._cache_checked, cc._cache_used = True, False
    try:
        yield True
    finally:
        with lock:
            cc._cache_checked, cc._cache_used = saved


__all__ = ["program_dir", "model_fingerprint", "program_key", "load", "store", "compile_program",
           "Timing", "vmapped", "MEMORY_BUDGET"]
