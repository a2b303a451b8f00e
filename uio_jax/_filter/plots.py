"""Figures of a Monte Carlo run (matplotlib; every function returns ``(fig, axes)``).

As in the figures of 003 (trajectories: truth, dead reckoning, EKF) and 002 (error per
quantity against time): error bands over trials with the filter's +-sigma, and a NEES band.
Nothing is shown; save with ``fig.savefig(path)`` (the command line uses 150 dpi). Every
axis names its quantity and unit: the experiment's units (:meth:`~uio_jax.Experiment.unit`;
angles in degrees), ``(unit not given)`` where the experiment has none.
"""

import math

import numpy as np

from .._errors import OptionError

_DEG = 180.0 / math.pi


def _unit_label(exp, name) -> tuple[str, float]:
    """``(" (unit)", scale)`` of a state or quantity for axis labels."""
    unit, scale = exp.display_unit(name)
    return (f" ({unit})" if unit else " (unit not given)"), scale


def _axes(ax, size=(5.0, 4.0)):
    """``(fig, ax)``: ``ax`` and its figure, or a new figure of one panel of ``size`` inches."""
    import matplotlib.pyplot as plt

    return (ax.figure, ax) if ax is not None else plt.subplots(figsize=size)


def _grid(n, ncols, height, **kw):
    """``(fig, axes)``: a new figure of ``n`` panels in rows of ``ncols`` (3.6 x ``height``
    inches each; ``kw`` to ``plt.subplots``), ``axes`` a flat list, the spare panels hidden."""
    import matplotlib.pyplot as plt

    nrows = -(-n // ncols)
    fig, grid = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, height * nrows), squeeze=False, **kw)
    axes = list(grid.ravel())
    for a in axes[n:]:
        a.set_visible(False)
    return fig, axes


def _label(ax, title, xlabel, ylabel):
    """A panel's title (9 pt), axis labels (8 pt) and tick labels (7 pt)."""
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(xlabel, fontsize=8)
    ax.set_ylabel(ylabel, fontsize=8)
    ax.tick_params(labelsize=7)


def plot_trajectories(result, *, trial=0, pair=(0, 1), ax=None):
    """One kept trial in the plane of two states: truth, dead reckoning, EKF.

    Args:
        result: a :class:`MonteCarloResult` with kept trajectories (``keep >= 1``).
        trial: index among the kept trials.
        pair: the two state indices plotted (default ``(0, 1)``: the horizontal plane).
        ax: optional matplotlib axes.

    Returns:
        ``(fig, ax)``.
    """
    tr = result.trajectories
    if not tr or trial >= len(tr["ids"]):
        raise OptionError(f"trial {trial} has no kept trajectory (run with keep > {trial})")
    fig, ax = _axes(ax)
    i, j = pair
    names = result.state_names
    ax.plot(tr["x_true"][trial, :, i], tr["x_true"][trial, :, j], ".", ms=2, color="tab:blue",
            label="true")
    ax.plot(tr["x_dr"][trial, :, i], tr["x_dr"][trial, :, j], "o", ms=3, mfc="none",
            color="tab:red", markevery=4, label="dead reckoning")
    ax.plot(tr["x_hat"][trial, :, i], tr["x_hat"][trial, :, j], "*", ms=3, color="k",
            markevery=4, label="EKF")
    exp = result.experiment
    (ui, si), (uj, sj) = _unit_label(exp, names[i]), _unit_label(exp, names[j])
    if si != 1.0 or sj != 1.0:  # an angle: redraw in degrees
        for line in ax.get_lines()[-3:]:
            line.set_data(np.asarray(line.get_xdata()) * si, np.asarray(line.get_ydata()) * sj)
        ax.relim()
        ax.autoscale_view()
    _label(ax, result.experiment.name.split(":")[-1], f"{names[i]}{ui}", f"{names[j]}{uj}")
    ax.legend(fontsize=7)
    return fig, ax


def _band(ax, t, err, sig, scale, color):
    """Signed errors of every trial: 5-95% band, RMSE (+-), RMS filter sigma (+-)."""
    lo, hi = np.percentile(err, [5, 95], axis=0)
    ax.fill_between(t, lo * scale, hi * scale, color=color, alpha=0.25, lw=0,
                    label="5-95% of trials")
    rmse = np.sqrt(np.mean(err**2, axis=0)) * scale
    s = np.sqrt(np.mean(sig**2, axis=0)) * scale
    ax.plot(t, rmse, color=color, lw=1.2, label="RMSE")
    ax.plot(t, -rmse, color=color, lw=1.2)
    ax.plot(t, s, "k--", lw=0.9, label="filter +-sigma")
    ax.plot(t, -s, "k--", lw=0.9)
    ax.axhline(0.0, color="0.6", lw=0.5)


def plot_errors(result, names=None, *, axes=None, ncols=3):
    """Error bands over trials with the filter's +-sigma, per state or named quantity.

    Args:
        result: a :class:`MonteCarloResult`.
        names: states and/or named quantities to plot (default: the system states and
            every named quantity).
        axes: optional flat sequence of axes, one per name.
        ncols: columns of the grid when ``axes`` is None.

    Returns:
        ``(fig, axes)`` with ``axes`` a flat list.
    """
    exp = result.experiment
    states, quants = list(result.state_names), list(result.quantity_names)
    if names is None:
        names = list(exp.system.states) + quants
    ang_s = exp.angle_mask()
    ang_q = [q.angle for q in exp.quantities]
    if axes is None:
        fig, axes = _grid(len(names), ncols, 2.4, sharex=True)
    else:
        axes = list(axes)
        fig = axes[0].figure
    for a, nm in zip(axes, names):
        if nm in states:
            k = states.index(nm)
            err, sig, ang = result.errors[:, :, k], result.sigmas[:, :, k], ang_s[k]
        elif nm in quants:
            k = quants.index(nm)
            err, sig = result.quantity_errors[:, :, k], result.quantity_sigmas[:, :, k]
            ang = ang_q[k]
        else:
            raise OptionError(f"no state or quantity named {nm!r}")
        unit, scale = _unit_label(exp, nm)
        if ang and scale == 1.0:
            scale, unit = _DEG, " (deg)"
        _band(a, result.t, err, sig, scale, "tab:blue")
        _label(a, f"{nm} error{unit}", "t (s)", f"error{unit}")
    axes[0].legend(fontsize=6, loc="upper right")
    fig.tight_layout()
    return fig, axes


def plot_nees(result, *, ax=None):
    """NEES over time: mean, median and 5-95% band over trials, with the expected dof.

    Returns:
        ``(fig, ax)``.
    """
    fig, ax = _axes(ax, size=(5.0, 3.0))
    nees, t = result.nees, result.t
    lo, hi = np.percentile(nees, [5, 95], axis=0)
    ax.fill_between(t, lo, hi, color="tab:green", alpha=0.25, lw=0, label="5-95%")
    ax.plot(t, np.mean(nees, axis=0), color="tab:green", label="mean")
    ax.plot(t, np.median(nees, axis=0), color="tab:olive", ls=":", label="median")
    ax.axhline(result.nees_dof(), color="k", ls="--", lw=0.9,
               label=f"expected ({result.nees_dof()} dof)")
    ax.set_yscale("log")
    _label(ax, "NEES", "t (s)", "NEES (dimensionless)")
    ax.legend(fontsize=6)
    return fig, ax


def plot_montecarlo(result, names=None):
    """One summary figure: a trajectory (if kept), the error bands and the NEES band.

    Returns:
        ``(fig, axes)`` with ``axes`` a flat list (trajectory first when present).

    Raises:
        TypeError: ``result`` is not a MonteCarloResult.
    """
    from .result import MonteCarloResult

    if not isinstance(result, MonteCarloResult):
        raise TypeError(f"plot_montecarlo needs a uio_jax MonteCarloResult (uio_jax.run_montecarlo"
                        f"(...)), got {type(result).__name__}")

    exp = result.experiment
    if names is None:
        names = list(exp.system.states) + list(result.quantity_names)
    has_traj = bool(result.trajectories) and len(result.trajectories["ids"]) > 0
    fig, axes = _grid(len(names) + 1 + int(has_traj), 3, 2.5)
    k = 0
    if has_traj:
        plot_trajectories(result, ax=axes[0])
        k = 1
    plot_errors(result, names, axes=axes[k:k + len(names)])
    plot_nees(result, ax=axes[k + len(names)])
    fig.suptitle(f"{exp.name}: {result.trials} trials", fontsize=10)
    fig.tight_layout()
    return fig, axes
