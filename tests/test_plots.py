"""Plots return (fig, axes), draw the expected artists and write files; nothing is shown."""

import matplotlib
import pytest
from conftest import zoo

from uio_jax._errors import OptionError
from uio_jax._filter.montecarlo import run_montecarlo
from uio_jax._filter.plots import plot_errors, plot_montecarlo, plot_nees, plot_trajectories
from uio_jax._io.loading import load_module

UNI = load_module(zoo("unicycle_disturbance.py"))


@pytest.fixture(scope="module")
def result():
    # same experiment and batch as tests/test_montecarlo.py: shares its compiled code
    return run_montecarlo(UNI.range_gamma_unknown_experiment(), 64, seed=2, keep=2)


def test_kept_trajectories_match_statistics(result):
    """The float64 trajectories of the kept trials reproduce the float32 records."""
    import numpy as np

    tr = result.trajectories
    err = tr["x_hat"][:, :, :3] - tr["x_true"][:, :, :3]
    err[..., 2] = (err[..., 2] + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(result.errors[:2, :, :3], err, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(result.sigmas[:2], tr["sigma"], rtol=1e-6)


def test_plot_trajectories(result):
    fig, ax = plot_trajectories(result, trial=1)
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels == ["true", "dead reckoning", "EKF"]
    assert len(ax.get_lines()[0].get_xdata()) == len(result.trajectories["t"])
    with pytest.raises(OptionError):
        plot_trajectories(result, trial=5)


def test_plot_errors_and_nees(result):
    fig, axes = plot_errors(result, ["xv", "bearing phi"])
    assert len(axes) >= 2 and axes[1].get_title() == "bearing phi error (deg)"
    fig, ax = plot_nees(result)
    assert ax.get_yscale() == "log"
    with pytest.raises(OptionError):
        plot_errors(result, ["nope"])


def test_plot_montecarlo_writes_file(result, tmp_path):
    fig, axes = plot_montecarlo(result)
    assert isinstance(fig, matplotlib.figure.Figure)
    path = tmp_path / "mc.png"
    fig.savefig(path, dpi=50)
    assert path.stat().st_size > 1000


def test_every_axis_names_its_quantity_and_unit(result, tmp_path):
    """Units from the experiment (angles in degrees, w1 in unit of w per second); a name
    without a unit says so rather than showing a bare number."""
    exp = result.experiment.with_(units={"xv": "m", "yv": "m", "w": "m/s"})
    res = type(result)(exp, result.trials, result.seed, result.t, result.stats,
                       result.trajectories, result.timings)
    fig, axes = plot_montecarlo(res, names=["xv", "theta", "w1", "bearing phi", "range"])
    shown = [a for a in axes if a.get_visible()]
    for a in shown:
        assert a.get_xlabel() and a.get_ylabel(), a.get_title()
        assert "(" in a.get_xlabel() and "(" in a.get_ylabel(), (a.get_xlabel(), a.get_ylabel())
    assert (shown[0].get_xlabel(), shown[0].get_ylabel()) == ("xv (m)", "yv (m)")
    ylabels = [a.get_ylabel() for a in shown[1:-1]]
    assert ylabels == ["error (m)", "error (deg)", "error (m/s^2)", "error (deg)", "error (m)"]
    bare = result.experiment.with_(units={})  # an experiment that gives no units
    _, axes = plot_errors(type(result)(bare, result.trials, result.seed, result.t, result.stats,
                                       result.trajectories, result.timings), ["yv"])
    assert axes[0].get_ylabel() == "error (unit not given)"
    path = tmp_path / "mc.png"
    fig.savefig(path, dpi=150)
    assert path.stat().st_size > 1000
