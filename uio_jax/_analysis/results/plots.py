"""Figure of one analysis: the dimension per step, and how sure the final rank is."""

import math

import numpy as np

from ..._errors import OptionError
from .kinds import Method

#: Ratios below this are drawn at this value on the log axis (exact zeros have no log).
_FLOOR = 1e-18
#: Percentile bands of the per-sample ratios, widest first: (low, high, alpha).
_BANDS = ((0.0, 100.0, 0.15), (5.0, 95.0, 0.3), (25.0, 75.0, 0.5))


def plot_analysis(report, path=None, ax=None):
    """Plot a :class:`~uio_jax.Report`: dimension per step and the evidence of the rank.

    Left: the dimension of the observable codistribution at each step m (each order k for
    the EORC and the series, where the augmented rank is drawn too), with n (states plus
    parameters) dashed. Right: at every used sample, the singular values ``s_i / s_1`` of
    the final generator matrix (scaled as in every rank decision), as percentile bands over
    the samples on a log scale, with ``certificate.rtol`` and ``certificate.sigma_next_max``
    as horizontal lines: the distance between the lowest band and these lines is how sure
    the rank is.

    Main arguments:
        report: a :class:`~uio_jax.Report`.

    Other arguments:
        path: if given, the figure is written there; the format follows the suffix (png,
            pdf, svg, or any other matplotlib format).
        ax: two matplotlib Axes ``(left, right)`` to draw into. Default: a new figure; a
            standalone :class:`matplotlib.figure.Figure` (no GUI backend, nothing to close)
            when ``path`` is given, a ``pyplot`` figure otherwise (shown by notebooks).

    Returns:
        the matplotlib Figure.

    Raises:
        TypeError: ``report`` is not a Report.
        OptionError: ``ax`` is not two Axes, or ``path`` has an unknown format.
    """
    try:  # a Report, or anything with its fields (the figure reads nothing else)
        report.method, report.dim, report.n, report.history, report.certificate  # noqa: B018
    except AttributeError:
        raise TypeError(f"plot_analysis needs a uio_jax.Report (uio_jax.analyze(...)), got "
                        f"{type(report).__name__}") from None
    if path is not None:
        fmt = check_figure_path(path)
    fig, (ax_dim, ax_sv) = _axes(ax, standalone=path is not None)
    _plot_dims(report, ax_dim)
    _plot_singular_values(report, ax_sv)
    name = report.system_name or "system"
    fig.suptitle(f"{name} ({report.method}): dim {report.dim} of {report.n}", fontsize=11)
    if path is not None:
        from ..._output import write_figure

        write_figure(fig, path, fmt, dpi=100, bbox_inches="tight")
    return fig


def check_figure_path(path) -> str:
    """The format of a figure path from its suffix; OptionError when matplotlib lacks it."""
    from matplotlib.backend_bases import FigureCanvasBase

    suffix = str(path).rpartition(".")[2].lower() if "." in str(path) else ""
    formats = FigureCanvasBase.get_supported_filetypes()
    if suffix not in formats:
        raise OptionError(f"figure file {path!r} needs one of the suffixes "
                          f"{', '.join('.' + f for f in sorted(formats))}")
    return suffix


def _axes(ax, standalone):
    if ax is not None:
        try:
            left, right = ax
        except (TypeError, ValueError):
            raise OptionError("ax must be two matplotlib Axes (left, right)") from None
        return left.figure, (left, right)
    size = (11.0, 4.0)
    if standalone:
        from matplotlib.figure import Figure

        fig = Figure(figsize=size, layout="constrained")
        return fig, tuple(fig.subplots(1, 2))
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=size, layout="constrained")
    return fig, tuple(axes)


def _plot_dims(report, ax):
    steps = [s.m for s in report.history]
    label = "order k" if Method(report.method).step_name == "k" else "step m"
    ax.plot(steps, report.dims, "o-", color="C0", label="dim of the codistribution")
    aug = [s.extra.get("augmented_rank") for s in report.history]
    top = report.n
    if steps and all(a is not None for a in aug):
        ax.plot(steps, aug, "s:", color="C2", ms=4, label="augmented rank (EORC)")
        top = max(top, *aug)
    of = " (states + parameters)" if getattr(report, "params", ()) else " (states)"
    ax.axhline(report.n, ls="--", color="0.4", label=f"n = {report.n}{of}")
    ax.set_xlabel(label)
    ax.set_ylabel("dimension (independent covectors)")
    ax.set_ylim(-0.2, top + 0.8)
    if steps:
        ax.set_xticks(steps)
    ax.yaxis.get_major_locator().set_params(integer=True)
    ax.set_title(f"codistribution per {label.split()[1]}", fontsize=10)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)


def _plot_singular_values(report, ax):
    cert = report.certificate
    ax.set_title("rank evidence: s_i / s_1 per sample", fontsize=10)
    ax.set_xlabel("index i of the singular value (1 = largest)")
    ax.set_ylabel(r"$s_i\,/\,s_1$ (singular value ratio, log scale)")
    ax.set_yscale("log")
    try:
        sv = np.asarray(report.sample_singular_values(), dtype=float)
    except (AttributeError, NotImplementedError):
        sv = None
    if sv is None or sv.ndim != 2 or sv.shape[1] == 0 or sv.shape[0] == 0:
        why = ("empty codistribution" if sv is not None
               else "per-sample singular values not available for this report")
        ax.text(0.5, 0.5, why, ha="center", va="center", transform=ax.transAxes)
        _tolerance_lines(ax, cert, low=1.0)
        return
    sv = np.clip(sv, _FLOOR, None)
    idx = np.arange(1, sv.shape[1] + 1)
    for lo, hi, alpha in _BANDS:
        ax.fill_between(idx, np.percentile(sv, lo, axis=0), np.percentile(sv, hi, axis=0),
                        color="C0", alpha=alpha, lw=0,
                        label=f"{lo:g}-{hi:g} % of {sv.shape[0]} samples")
    ax.plot(idx, np.median(sv, axis=0), "o-", color="C0", ms=4, label="median")
    _tolerance_lines(ax, cert, low=float(np.min(sv)))
    ax.set_xticks(idx)
    ax.set_xlim(0.6, sv.shape[1] + 0.4)
    gap = cert.gap_decades
    ax.set_title("rank evidence: s_i / s_1 per sample; weakest gap "
                 + ("inf" if math.isinf(gap) else f"{gap:.1f} decades"), fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7, borderaxespad=0.0)
    ax.grid(alpha=0.3, which="major")


def _tolerance_lines(ax, cert, low):
    """rtol and the largest rejected margin; the y range from ``low`` (smallest ratio) to 3."""
    low = min(low, cert.rtol, cert.sigma_next_max if cert.sigma_next_max > 0 else 1.0)
    ax.set_ylim(10 ** math.floor(math.log10(max(low, _FLOOR)) - 1), 3.0)
    ax.axhline(cert.rtol, ls="--", color="C3", label=f"rtol = {cert.rtol:.0e}")
    if cert.sigma_next_max > 0:
        ax.axhline(cert.sigma_next_max, ls=":", color="C1",
                   label=f"largest rejected margin {cert.sigma_next_max:.1e}")
