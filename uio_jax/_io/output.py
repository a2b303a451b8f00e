"""Writing an output file: every output written, or an OSError that names it."""

import contextlib
import io
import os


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
