"""What goes out of the program: output files, and text from models made safe for a terminal.

**Files.** :func:`write_output` writes every output file of the command line (and the
figures of :func:`uio_jax.plot_analysis`): the whole file or an OSError that names it,
never "written" after a lost write.

**Terminal text.** A model file from someone else can carry names, units or messages with
terminal escape sequences (``\\x1b[2J`` clears the screen), carriage returns or newlines (a forged report or
table line), or bidirectional overrides (text shown in another order than it is). Every
place that prints text taken from a model (the report's text, the batch table, the Monte
Carlo summary, the command line's error line) passes it through :func:`printable`: such
characters are shown as escapes (``\\x1b``, ``\\n``, ``\\u202e``), visible and inert; the
data itself (JSON, ``Report.system_name``) keeps the original text.
"""

import contextlib
import io
import os
import re


def write_output(path, data):
    """Write ``data`` (str or bytes) to the output file ``path``, or fail with an OSError
    that names it (exit code 2 on the command line, never "written" after a lost write).

    A regular file (or a new one) is written through a temporary file beside it then
    ``os.replace``: a reader, or a crash, never sees half a file; through a symbolic link,
    its target is replaced. Anything else that exists (``/dev/null``, ``/dev/full``, a
    FIFO) is written in place, never replaced.
    """
    mode = "wb" if isinstance(data, bytes) else "w"
    encoding = None if isinstance(data, bytes) else "utf-8"
    real = os.path.realpath(path)
    try:
        if os.path.exists(real) and not os.path.isfile(real):
            with open(real, mode, encoding=encoding) as fh:
                fh.write(data)
            return
        tmp = f"{real}.{os.getpid()}.tmp"
        try:
            with open(tmp, mode, encoding=encoding) as fh:
                fh.write(data)
            os.replace(tmp, real)
        except BaseException:
            with contextlib.suppress(OSError):
                os.remove(tmp)
            raise
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror or str(exc), os.fspath(path)) from None


def write_figure(fig, path, fmt, **savefig_kwargs):
    """Render the matplotlib ``fig`` in the format ``fmt`` and write it to ``path``
    (:func:`write_output`: the file complete, or an OSError naming it)."""
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, **savefig_kwargs)
    write_output(path, buf.getvalue())


#: Control characters (C0, DEL, C1) and the invisible bidirectional formatting characters.
_UNSAFE = re.compile("[\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]")
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _escape(match) -> str:
    c = match.group()
    if c in _NAMED:
        return _NAMED[c]
    code = ord(c)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text, keep: str = "") -> str:
    """``text`` (any object, through ``str``) with every control character and
    bidirectional override replaced by a visible escape (``\\x1b``, ``\\n``, ``\\u202e``),
    except the characters in ``keep`` (``"\\n"`` for a multi-line text whose lines this
    program made)."""
    text = str(text)
    if not _UNSAFE.search(text):
        return text
    return _UNSAFE.sub(lambda m: m.group() if m.group() in keep else _escape(m), text)


#: Lines of a text report longer than this are wrapped (at :data:`WRAP_WIDTH` columns).
WRAP_LIMIT = 160
#: Width of the wrapped lines.
WRAP_WIDTH = 100


def wrapped(text, limit: int = WRAP_LIMIT, width: int = WRAP_WIDTH) -> str:
    """``text`` with every line longer than ``limit`` characters broken at spaces into lines
    of at most ``width`` (a word longer than that kept whole), the continuation lines
    indented four spaces past the line's own indentation: a report never prints a line of
    kilobytes (a 401-coordinate point, a long list of generators)."""
    import textwrap

    out = []
    for line in str(text).split("\n"):
        if len(line) <= limit:
            out.append(line)
            continue
        indent = line[:len(line) - len(line.lstrip(" "))]
        out += textwrap.wrap(line, width=width, subsequent_indent=indent + "    ", break_long_words=False,
                             break_on_hyphens=False) or [line]
    return "\n".join(out)


def abridged(items, head: int = 6, tail: int = 2) -> str:
    """``a, b, c`` for a short list; the first ``head``, ``...``, the last ``tail`` and the
    count for a long one (``y, L_f0 y, ..., y_30 (31 in all)``)."""
    items = [str(i) for i in items]
    if len(items) <= head + tail + 1:
        return ", ".join(items)
    return ", ".join(items[:head]) + ", ..., " + ", ".join(items[-tail:]) + f" ({len(items)} in all)"

