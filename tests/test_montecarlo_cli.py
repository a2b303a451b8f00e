"""``uio-jax montecarlo``: every option and output path refused before any work, warnings
on dt as one stderr line, the verdict first."""

import argparse
import textwrap

import pytest
from conftest import zoo

from uio_jax import cli
from uio_jax._errors import OptionError
from uio_jax.cli import montecarlo as mc_cli

SPEC = zoo("unicycle_disturbance.py:phi_gamma_known")


@pytest.fixture
def no_work(monkeypatch):
    """Loading or running an experiment fails the test: the checks must come first."""
    def boom(*a, **k):
        raise AssertionError("work started before the options were checked")

    monkeypatch.setattr(mc_cli, "load_experiment", boom)
    import uio_jax._filter.montecarlo as mc

    monkeypatch.setattr(mc, "run_montecarlo", boom)


def _one_line_error(argv, capsys):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith("uio-jax: error: ")
    return err


@pytest.mark.parametrize("extra, needle", [
    (["--plot", "out.xyz"], "suffixes"),
    (["--plot", "{tmp}/missing/mc.png"], "no directory"),
    (["--json", "{tmp}/missing/mc.json"], "no directory"),
    (["--json", "{tmp}"], "is a directory"),
    (["--json", "{tmp}/a.png", "--plot", "{tmp}/a.png"], "same file"),
    (["--seed", str(2**64)], "--seed must be a non-negative integer below 2**64"),
    (["--seed", "-1"], "--seed must be a non-negative integer below 2**64"),
    (["--keep", "-1"], "--keep"),
    (["--trials", "0"], "--trials"),
])
def test_bad_option_or_output_path_refused_before_any_work(extra, needle, tmp_path, capsys, no_work):
    extra = [a.format(tmp=tmp_path) for a in extra]
    err = _one_line_error(["montecarlo", SPEC, "--no-cache", "--no-progress", *extra], capsys)
    assert needle in err


def test_seed_range_is_exactly_64_bits(tmp_path):
    def args(seed):
        return argparse.Namespace(trials=1, seed=seed, keep=0, plot=str(tmp_path / "f.pdf"),
                                  json=str(tmp_path / "f.json"))

    mc_cli.check_options(args(0))
    mc_cli.check_options(args(2**64 - 1))
    for bad in (-1, 2**64):
        with pytest.raises(OptionError, match=r"--seed must be a non-negative integer below 2\*\*64"):
            mc_cli.check_options(args(bad))


TOY = """
import jax.numpy as jnp
import uio_jax as uj

def _system():
    return uj.System(("x",), {{"y": lambda x: x[0]}}, drift=lambda x: -2.0 * x)

def toy_experiment():
    return uj.Experiment(name="toy", system=_system(), dt={dt}, n_steps=20, x0=(1.0,),
                         inputs=lambda s, z: (s, jnp.zeros(0), jnp.zeros(0)), istate0=(),
                         n_input_normals=0, known_std=lambda u: jnp.zeros(0),
                         measurements=(uj.Measurement("y", lambda x: x[0], 0.1, 1),),
                         prior_std=(5.0,), units={{"x": "m"}})
"""


def test_dt_far_from_the_time_scale_is_one_warning_line(tmp_path, capsys):
    """x' = -2 x at dt = 1 s, prior std 5: the fastest mode (|lambda| = 2/s, faster than the
    motion 2 x0 / 5 = 0.4 prior stds/s) sets the rate, rate * dt = 2 > 1: one
    ``uio-jax: warning:`` line on stderr, then the run goes on."""
    path = tmp_path / "toy.py"
    path.write_text(textwrap.dedent(TOY.format(dt=1.0)))
    argv = ["montecarlo", f"{path}:toy", "--trials", "2", "--keep", "0", "--no-analysis",
            "--no-progress", "--no-cache"]
    assert cli.main(argv) == 0
    out = capsys.readouterr()
    warns = [ln for ln in out.err.splitlines() if ln.startswith("uio-jax: warning: ")]
    assert len(warns) == 1 and "dt=1 s" in warns[0] and "time scale 0.5 s" in warns[0], out.err
    assert "Traceback" not in out.err
    lines = out.out.splitlines()
    assert lines[1].startswith("verdict: ")   # the verdict first, right under the title
    assert any(ln.split()[:2] == ["x", "m"] for ln in lines), out.out  # the unit column


def test_sound_dt_gives_no_warning(tmp_path, capsys):
    path = tmp_path / "toy.py"
    path.write_text(textwrap.dedent(TOY.format(dt=0.05)))
    assert cli.main(["montecarlo", f"{path}:toy", "--trials", "2", "--keep", "0",
                     "--no-analysis", "--no-progress", "--no-cache"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_the_analysis_beside_the_verdict_takes_the_meaning_of_known_inputs(tmp_path, capsys, monkeypatch):
    """``--known-inputs smooth`` reaches the analysis shown beside the verdict (issue 40: the
    Monte Carlo had no such option)."""
    import uio_jax._analysis.analyze as analysis

    seen = []
    real = analysis.analyze

    def recording(system, **kw):
        seen.append(kw.get("known_inputs"))
        return real(system, **kw)

    monkeypatch.setattr(analysis, "analyze", recording)
    path = tmp_path / "toy.py"
    path.write_text(textwrap.dedent(TOY.format(dt=0.05)))
    assert cli.main(["montecarlo", f"{path}:toy", "--trials", "2", "--keep", "0", "--no-progress",
                     "--no-cache", "--known-inputs", "smooth"]) == 0
    assert seen == ["smooth"]
