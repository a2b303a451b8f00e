"""Ctrl-C that always ends the command promptly, with one line.

Python turns SIGINT into a ``KeyboardInterrupt`` raised in whatever Python code the main
thread runs when the signal is handled. Raised inside a garbage-collector callback (JAX
registers one that frees XLA buffers, called at every collection: a large model allocates
enough to spend much of its time there) or a ``__del__``, the exception is *swallowed*:
Python prints "Exception ignored in ..." and the command goes on, so Ctrl-C seemed dead.

The handler of :func:`prompt_interrupts` raises the interrupt only outside such frames;
inside one it traces the frames that called it and every new call, and raises it at the
first line or call outside them, once the collector has returned. With ``watchdog``, a
command still running :data:`GRACE` seconds after the first Ctrl-C (its exception swallowed
elsewhere, or a clean-up that hangs), or a second Ctrl-C, ends the process at once with the
same one line and exit code 130.
"""

import contextlib
import gc
import os
import signal
import sys
import threading

#: Seconds a command has, after Ctrl-C, to end by its own clean-up before it is ended.
GRACE = 5.0
#: Exit code after Ctrl-C (128 + SIGINT).
EXIT_INTERRUPTED = 130
#: The one line printed.
MESSAGE = "uio-jax: interrupted\n"


def hard_exit() -> None:
    """Print the one line (unbuffered) and end the process now, with exit code 130."""
    try:
        os.write(2, MESSAGE.encode())
    finally:
        os._exit(EXIT_INTERRUPTED)


def inside_finalizer(frame) -> bool:
    """Whether ``frame`` (or a caller) is a garbage-collector callback or a ``__del__``,
    where a raised exception is swallowed."""
    codes = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        if frame.f_code in codes or frame.f_code.co_name == "__del__":
            return True
        frame = frame.f_back
    return False


class _Handler:
    """The SIGINT handler of one command (module docstring)."""

    def __init__(self, watchdog: bool):
        self.watchdog, self.seen = watchdog, False

    def __call__(self, signum, frame):
        if self.seen and self.watchdog:
            hard_exit()  # a second Ctrl-C
        if not self.seen and self.watchdog:
            timer = threading.Timer(GRACE, hard_exit)
            timer.daemon = True
            timer.start()
        self.seen = True
        if inside_finalizer(frame):
            _defer(frame)
            return
        raise KeyboardInterrupt


def _defer(frame) -> None:
    """Raise the interrupt at the next line or call outside the finalizers: the frames that
    called the finalizer trace their lines, and every new call is traced, until it is raised."""
    while frame is not None and inside_finalizer(frame):
        frame = frame.f_back
    while frame is not None:
        frame.f_trace, frame.f_trace_lines = _raise_outside_finalizers, True
        frame = frame.f_back
    sys.settrace(_raise_outside_finalizers)


def _raise_outside_finalizers(frame, event, arg):
    """A trace function: raises the deferred interrupt at the first line or call outside a
    garbage-collector callback or ``__del__`` (then tracing stops)."""
    if event in ("call", "line") and not inside_finalizer(frame):
        sys.settrace(None)
        _stop_tracing(frame)
        raise KeyboardInterrupt
    return _raise_outside_finalizers if event == "call" else None


def _stop_tracing(frame) -> None:
    while frame is not None:
        frame.f_trace = None
        frame = frame.f_back


@contextlib.contextmanager
def prompt_interrupts(watchdog: bool = True):
    """Within the block, Ctrl-C raises ``KeyboardInterrupt`` outside garbage-collector
    callbacks and ``__del__`` (never swallowed: inside one, at the next line outside it),
    and with ``watchdog`` ends the process within :data:`GRACE` seconds in any case.
    Outside the main thread, or where SIGINT is ignored (a background job), SIGINT is left
    as it is."""
    try:
        if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
            yield
            return
        previous = signal.signal(signal.SIGINT, _Handler(watchdog))
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


__all__ = ["prompt_interrupts", "inside_finalizer", "hard_exit", "GRACE", "EXIT_INTERRUPTED", "MESSAGE"]
