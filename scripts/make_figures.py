"""Make the Monte Carlo figures of papers 003 (section 5) and 002 (section III-D).

Writes to ``docs/figures/``:

* ``003_range.png``, ``003_bearing_phi.png``: unicycle with disturbance, gamma known (left)
  and unknown (right): one trajectory (true / dead reckoning / EKF, as in 003 figs. 3, 5),
  the error along the rotation about the origin (bearing phi) over the trials with the
  filter's +-sigma, and the NEES band.
* ``002_paper.png``: 3D vehicle, the paper's setting (two features, 200 s), without (left)
  and with (right) wind: trajectory in the x-z plane, errors of the distance to the first
  feature, roll, pitch and yaw (as in 002 figs. 2-7).
* ``002_hover.png``: the analysed system (one feature), hovering near it: errors of z, roll,
  pitch, yaw without and with wind.
* ``verdicts.md``: the summary tables of every run.

Usage: ``python scripts/make_figures.py [--trials 256] [--out docs/figures]``
"""

import argparse
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _setup():
    os.environ.setdefault("MPLBACKEND", "Agg")
    import jax

    jax.config.update("jax_num_cpu_devices", os.cpu_count() or 1)
    from uio_jax._io.loading import load_module

    uni = load_module(os.path.join(ROOT, "systems", "unicycle_disturbance.py"))
    veh = load_module(os.path.join(ROOT, "systems", "vehicle_wind.py"))
    return uni, veh


def _columns(results, rows, pair, fname, title):
    """One column per result: trajectory, then one error panel per name, then NEES."""
    import matplotlib.pyplot as plt

    from uio_jax._filter.plots import plot_errors, plot_nees, plot_trajectories

    nr = len(rows) + 2
    fig, grid = plt.subplots(nr, len(results), figsize=(4.2 * len(results), 2.3 * nr),
                             squeeze=False)
    for c, (label, res) in enumerate(results):
        plot_trajectories(res, pair=pair, ax=grid[0, c])
        grid[0, c].set_title(label, fontsize=9)
        plot_errors(res, rows, axes=list(grid[1:1 + len(rows), c]), ncols=1)
        plot_nees(res, ax=grid[-1, c])
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(fname, dpi=72)
    plt.close(fig)
    print(f"written {fname} ({os.path.getsize(fname) // 1024} KB)")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=256, help="trials per 003 case (default 256)")
    p.add_argument("--vehicle-trials", type=int, default=64, help="trials per 002 case")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=os.path.join(ROOT, "docs", "figures"))
    a = p.parse_args(argv)
    uni, veh = _setup()
    from uio_jax._filter.montecarlo import run_montecarlo

    os.makedirs(a.out, exist_ok=True)
    summaries = []

    def run(exp, trials):
        res = run_montecarlo(exp, trials, seed=a.seed, keep=1)
        summaries.append(res.summary())
        print(summaries[-1], flush=True)
        return res

    for out, tag in (("range", "range"), ("bearing_phi", "phi")):
        known = run(getattr(uni, f"{tag}_gamma_known_experiment")(), a.trials)
        unknown = run(getattr(uni, f"{tag}_gamma_unknown_experiment")(), a.trials)
        _columns([("gamma known (5-state EKF)", known), ("gamma unknown (6-state EKF)", unknown)],
                 ["bearing phi", "theta"], (0, 1), os.path.join(a.out, f"003_{out}.png"),
                 f"003 section 5, output {out.replace('_', ' ')}: {a.trials} trials")
    calm = run(veh.no_wind_experiment(), a.vehicle_trials)
    wind = run(veh.wind_unknown_experiment(), a.vehicle_trials)
    _columns([("no wind (7-state EKF)", calm), ("wind along z (9-state EKF)", wind)],
             ["distance 1", "roll", "pitch", "yaw"], (0, 2),
             os.path.join(a.out, "002_paper.png"),
             f"002 section III-D (two features, 200 s): {a.vehicle_trials} trials")
    calm = run(veh.no_wind_hover_experiment(), 2 * a.vehicle_trials)
    wind = run(veh.wind_unknown_hover_experiment(), 2 * a.vehicle_trials)
    _columns([("no wind", calm), ("wind along z", wind)], ["z", "roll", "pitch", "yaw"], (0, 1),
             os.path.join(a.out, "002_hover.png"),
             f"002, the analysed system (one feature), hovering: {2 * a.vehicle_trials} trials")
    with open(os.path.join(a.out, "verdicts.md"), "w") as fh:
        fh.write("# Monte Carlo verdicts behind the figures\n\nMade by "
                 "`scripts/make_figures.py`; ratios are end / prior std (see "
                 "`MonteCarloResult.verdict`).\n\n```text\n" + "\n\n".join(summaries)
                 + "\n```\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
