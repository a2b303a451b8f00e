"""Monte Carlo runs: reproducibility, the papers' contrasts, errors, the command line.

Oracles: identities (a trial depends only on (seed, index): batch 64 == first 64 of 256)
and the published simulation findings of 003 section 5 (fig. 3 and 5) and 002 section
III-D (figs. 4-7), judged by ratios end/start along the named directions.
"""

import json

import numpy as np
import pytest
from conftest import zoo

import uio_jax as uj
from uio_jax import cli
from uio_jax._errors import ModelError, OptionError
from uio_jax._filter.montecarlo import run_montecarlo
from uio_jax._io.loading import load_module

UNI = load_module(zoo("unicycle_disturbance.py"))
VEH = load_module(zoo("vehicle_wind.py"))


def test_batch_size_independent():
    # 2 s of the 10 s experiment (4000 steps, 80 output epochs): the property is per step
    exp = UNI.range_gamma_known_experiment().with_(n_steps=4000)
    a = run_montecarlo(exp, 64, seed=3, keep=0)
    b = run_montecarlo(exp, 256, seed=3, keep=0)
    np.testing.assert_array_equal(a.stats, b.stats[:64])
    c = run_montecarlo(exp, 64, seed=4, keep=0)
    assert not np.array_equal(a.stats, c.stats)


def _phi_ratio(res):
    return res.verdict()["quantities"]["bearing phi"]


def test_unicycle_range_rotation_observable_only_with_gamma_known():
    """003 fig. 3: the error along the rotation about the origin (bearing phi) shrinks
    with gamma known and does not with gamma unknown (range output)."""
    known = run_montecarlo(UNI.range_gamma_known_experiment(), 64, seed=0, keep=0)
    unknown = run_montecarlo(UNI.range_gamma_unknown_experiment(), 64, seed=0, keep=0)
    k, u = _phi_ratio(known), _phi_ratio(unknown)
    # at 4096 trials the ratios are 0.48 (known) and 0.95 (unknown): docs/benchmarks/ekf.md, "Sanity"
    assert k["converges"] is True and k["ratio"] < 0.6
    assert u["converges"] is False and u["ratio"] > 0.8
    assert k["late_sigma_ratio"] < 0.7 < 0.9 < u["late_sigma_ratio"]
    # the range itself is observed in both cases
    for res in (known, unknown):
        assert res.verdict()["quantities"]["range"]["ratio"] < 0.1


@pytest.mark.parametrize("name", ["phi_gamma_known_experiment", "phi_gamma_unknown_experiment"])
def test_unicycle_phi_converges_in_both(name):
    """003 fig. 5: with the bearing phi the estimate converges whether gamma is known or not."""
    res = run_montecarlo(getattr(UNI, name)(), 64, seed=0, keep=0)
    v = res.verdict()
    assert v["quantities"]["bearing phi"]["converges"] is True
    for s in ("xv", "yv", "theta"):
        assert v["states"][s]["converges"] is True, s
    assert v["divergent_fraction"] == 0.0


def test_vehicle_with_wind_z_converges_yaw_does_not():
    """002 section III-C/D, the analysed system (one feature), hovering near it: with wind
    z, roll and pitch converge, the yaw about the wind axis does not."""
    wind = run_montecarlo(VEH.wind_unknown_hover_experiment(), 32, seed=0, keep=0).verdict()
    assert wind["states"]["z"]["converges"] is True
    for q in ("roll", "pitch", "distance 1"):
        assert wind["quantities"][q]["converges"] is True, q
    assert wind["quantities"]["yaw"]["converges"] is False


@pytest.mark.slow
def test_vehicle_without_wind_only_the_distance_converges():
    """002 section III-D without wind (the same hover): roll, pitch and yaw do not converge,
    the distance to the feature does."""
    calm = run_montecarlo(VEH.no_wind_hover_experiment(), 32, seed=0, keep=0).verdict()
    for q in ("roll", "pitch", "yaw"):
        assert calm["quantities"][q]["converges"] is False, q
    assert calm["quantities"]["distance 1"]["converges"] is True


@pytest.mark.slow
def test_compare_with_analysis_range_gamma_known():
    """Beside the analysis (single_ui on the outputs read): every row agrees."""
    res = run_montecarlo(UNI.range_gamma_known_experiment(), 64, seed=0, keep=0)
    cmp = res.compare(uj.analyze(res.experiment.analysis_system(), samples=256))
    assert cmp["analysis"] is not None, cmp["note"]  # single_ui is available
    assert cmp["analysis"] == "single_ui"
    assert all(r["observable"] for r in cmp["states"].values())
    assert cmp["quantities"]["bearing phi"]["agree"] is True
    verdict = res.summary(cmp).splitlines()[1]  # the verdict first, under the title
    assert verdict.startswith("verdict: ") and "the analysis (single_ui)" in verdict, verdict


def test_compare_refuses_a_report_of_other_states():
    """A report of another system is a one-line OptionError, not silently kept labels."""
    exp = UNI.range_gamma_known_experiment()
    res = uj.MonteCarloResult(exp, 1, 0, np.zeros(2), np.zeros((1, 2, 2 * 5 + 2 * 2 + 1)), None)
    other = uj.analyze(uj.System(("a", "b"), {"y": lambda x: x[0]}, drift=lambda x: x[::-1]),
                       samples=16)
    with pytest.raises(OptionError, match="report of the experiment's states") as info:
        res.compare(other)
    assert "\n" not in str(info.value)
    assert res.compare()["note"] == "no analysis given"


def test_bad_inputs_raise_one_line_errors():
    exp = UNI.range_gamma_known_experiment()
    with pytest.raises(OptionError, match="trials"):
        run_montecarlo(exp, 0)
    with pytest.raises(OptionError, match="seed"):
        run_montecarlo(exp, 4, seed=-1)
    with pytest.raises(ModelError, match="NaN"):  # caught before anything is compiled
        run_montecarlo(exp.with_(known_std=lambda u: u * float("nan")), 2, keep=0)


@pytest.mark.slow
def test_filter_nan_midway_is_one_line_error():
    import jax.numpy as jnp

    from uio_jax._model.experiment import Measurement

    exp = UNI.range_gamma_known_experiment()
    # finite at the start (xv = 1), NaN once the vehicle has moved
    meas = Measurement("bad", lambda x: jnp.where(x[0] > 1.0001, jnp.nan, x[0]), 0.01, 50)
    with pytest.raises(ModelError, match="NaN"):
        run_montecarlo(exp.with_(measurements=(meas,), n_steps=1000), 2, keep=0)


def test_cli_montecarlo(tmp_path, capsys):
    out_json = tmp_path / "mc.json"
    code = cli.main(["montecarlo", zoo("unicycle_disturbance.py:range_gamma_known"),
                     "--trials", "64", "--seed", "1", "--keep", "0", "--no-analysis",
                     "--json", str(out_json), "--no-progress", "--no-cache"])
    assert code == 0
    text = capsys.readouterr().out
    assert "bearing phi" in text and "NEES" in text
    import json

    d = json.loads(out_json.read_text())
    assert d["trials"] == 64 and "verdict" in d


def test_cli_montecarlo_reference_filter_gives_the_fast_filters_statistics(tmp_path, capsys):
    """``--filter reference`` runs the plain-equation EKF: on the same trials its end-of-run
    statistics equal the fast kernels' (float32 summaries; agreement to 1e-12 is tested in
    test_ekf_reference.py)."""
    import json

    outs = {}
    for name in ("fast", "reference"):
        out = tmp_path / f"{name}.json"
        assert cli.main(["montecarlo", zoo("unicycle_disturbance.py:phi_gamma_known"),
                         "--trials", "4", "--keep", "0", "--no-analysis", "--no-progress",
                         "--no-cache", "--filter", name, "--json", str(out)]) == 0
        outs[name] = json.loads(out.read_text())
    assert outs["fast"]["verdict"] == outs["reference"]["verdict"]
    np.testing.assert_allclose(outs["fast"]["rmse"], outs["reference"]["rmse"], rtol=1e-6)
    assert cli.main(["montecarlo", zoo("unicycle_disturbance.py:phi_gamma_known"), "--filter", "slow"]) == 2
    assert "invalid choice: 'slow'" in capsys.readouterr().err


def test_cli_montecarlo_keeps_its_programs_in_the_compile_cache(tmp_path, capsys):
    """The second run of an experiment loads the compiled programs from the cache directory
    (the first one wrote them) and gives the same numbers."""
    import json

    cache = tmp_path / "cache"
    outs = []
    for i in range(2):
        out = tmp_path / f"mc{i}.json"
        assert cli.main(["montecarlo", zoo("unicycle_disturbance.py:phi_gamma_known"),
                         "--trials", "8", "--keep", "0", "--no-analysis", "--no-progress",
                         "--cache-dir", str(cache), "--json", str(out)]) == 0
        if i == 0:
            written = sorted(p.name for p in cache.rglob("*") if p.is_file())
            assert any("chunk_local" in name for name in written), written
        outs.append(json.loads(out.read_text()))
    assert sorted(p.name for p in cache.rglob("*") if p.is_file()) == written  # nothing new
    assert outs[0]["verdict"] == outs[1]["verdict"]


@pytest.mark.parametrize("argv, needle", [
    (["montecarlo", zoo("unicycle_disturbance.py:nope"), "--trials", "4", "--no-cache"],
     "no experiment"),
    (["montecarlo", zoo("unicycle_disturbance.py:phi_gamma_known"), "--trials", "0", "--no-cache"],
     "trials"),
    (["montecarlo", zoo("unicycle_disturbance.py:gamma_known_range"), "--trials", "4", "--no-cache"],
     "Experiment"),
])
def test_cli_montecarlo_bad_input(argv, needle, capsys):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_cli_montecarlo_unusable_cache_dir_is_one_line_error(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    argv = ["montecarlo", zoo("unicycle_disturbance.py:phi_gamma_known"), "--trials", "4",
            "--cache-dir", str(blocker / "cache")]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "a_file" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_unknown_experiment_lists_the_names_to_type(capsys):
    assert cli.main(["montecarlo", zoo("unicycle_disturbance.py:nope"), "--trials", "4", "--no-cache"]) == 2
    listed = capsys.readouterr().err.split("it defines: ")[1].rstrip(")\n").split(", ")
    assert "range_gamma_known" in listed and "phi_gamma_unknown" in listed
    assert not any(name.startswith("_") or name.endswith("_experiment") for name in listed)


@pytest.mark.slow
def test_sharded_equals_single_device(tmp_path):
    """Two host devices (fresh process) give the same trials as one device (this one)."""
    import subprocess
    import sys

    exp = UNI.range_gamma_known_experiment().with_(n_steps=2000)
    one = run_montecarlo(exp, 8, seed=5, keep=0)
    out = tmp_path / "two.npy"
    code = (
        "import jax, numpy as np\n"
        "jax.config.update('jax_num_cpu_devices', 2)\n"
        "from uio_jax._io.loading import load_module\n"
        "from uio_jax._filter.montecarlo import run_montecarlo\n"
        f"m = load_module({zoo('unicycle_disturbance.py')!r})\n"
        "exp = m.range_gamma_known_experiment().with_(n_steps=2000)\n"
        "assert len(jax.devices()) == 2\n"
        f"np.save({str(out)!r}, run_montecarlo(exp, 8, seed=5, keep=0).stats)\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    two = np.load(out)
    # float32 records; the two compilations may round differently in the last f64 bits
    np.testing.assert_allclose(two, one.stats, rtol=1e-5, atol=1e-7)


def test_seed_outside_64_bits_is_one_line_error():
    from uio_jax import trajectories

    exp = UNI.range_gamma_known_experiment()
    for seed in (-1, 2**64):
        with pytest.raises(OptionError, match="seed"):
            run_montecarlo(exp, 2, seed=seed)
        with pytest.raises(OptionError, match="seed"):
            trajectories(exp, [0], seed=seed)


# ---------------------------------------------------------------------- dt and the horizon
def _toy(**changes):
    """x' = -a x (a = 2/s), one output every step: the fastest mode |lambda| = 2/s."""
    import jax.numpy as jnp

    sys_ = uj.System(("x",), {"y": lambda x: x[0]}, drift=lambda x: -2.0 * x)
    kw = dict(name="toy", system=sys_, dt=0.05, n_steps=20, x0=(0.0,),
              inputs=lambda s, z: (s, jnp.zeros(0), jnp.zeros(0)), istate0=(),
              n_input_normals=0, known_std=lambda u: jnp.zeros(0),
              measurements=(uj.Measurement("y", lambda x: x[0], 0.1, 1),), prior_std=(1.0,))
    kw.update(changes)
    return uj.Experiment(**kw)


@pytest.mark.parametrize("changes, needle", [
    (dict(dt=0.0), "dt must be a positive number"),
    (dict(dt=-1e-3), "dt must be a positive number"),
    (dict(dt=float("nan")), "dt must be a positive number"),
    (dict(dt=float("inf")), "not a finite horizon"),
    (dict(dt=1e300, n_steps=10**10), "not a finite horizon"),
    (dict(n_steps=0), "n_steps"),
    (dict(measurements=(uj.Measurement("y", lambda x: x[0], 0.1, 40),), n_steps=20),
     "never read"),
    (dict(record_every=3), "not a multiple of record_every"),
    (dict(n_steps=10**15), "memory"),
    (dict(units={"nope": "m"}), "not a state"),
])
def test_impossible_dt_or_horizon_is_a_one_line_model_error(changes, needle):
    with pytest.raises(ModelError, match=needle) as info:
        _toy(**changes)
    assert "\n" not in str(info.value)


def test_run_refused_before_any_work_when_the_records_do_not_fit_in_memory():
    exp = _toy(n_steps=10**6)
    assert exp.memory_bytes(10**6) > 10**6 * (10**6 + 1) * 3 * 4  # at least the float32 records
    with pytest.raises(OptionError, match="memory") as info:
        run_montecarlo(exp, 10**6, keep=0)
    assert "\n" not in str(info.value) and "fewer trials" in str(info.value)


def test_time_scale_of_a_linear_mode_and_of_a_kinematic_model():
    ts = _toy().time_scale()
    assert ts["eigen_rate"] == pytest.approx(2.0) and ts["motion_rate"] == 0.0  # x0 = 0
    assert ts["time_scale_s"] == pytest.approx(0.5) and ts["rate_dt"] == pytest.approx(0.1)
    # the unicycle is kinematic (nilpotent Jacobian): its scale is the motion, theta' = omega
    # = 0.2 pi rad/s against a 5 deg prior: 7.2 prior stds per second
    uni = UNI.range_gamma_unknown_experiment().time_scale()
    assert uni["eigen_rate"] == pytest.approx(0.0, abs=1e-12)
    assert uni["rate"] == pytest.approx(0.2 * np.pi / (5 * np.pi / 180))


@pytest.mark.parametrize("changes, needle", [
    (dict(dt=1.0), "lower dt"),                     # |lambda| dt = 2 > 1
    (dict(dt=1e-6), "nothing moves"),              # 20 steps: 4e-5 of the 0.5 s scale
    (dict(n_steps=5), "a tenth of the horizon"),
])
def test_dt_far_from_the_time_scale_warns(changes, needle):
    exp = _toy(**changes)
    with pytest.warns(uj._model.experiment.TimeScaleWarning, match=needle):
        msgs = exp.check_time_scale()
    assert len(msgs) == 1 and "\n" not in msgs[0]


def test_zoo_experiments_and_a_sound_dt_do_not_warn():
    assert _toy().check_time_scale() == []
    # (every zoo run checks it too: a TimeScaleWarning fails the tests that run them)
    assert UNI.range_gamma_unknown_experiment().check_time_scale() == []


def test_run_warns_before_compiling_when_dt_is_far_from_the_time_scale():
    from uio_jax._model.experiment import TimeScaleWarning

    with pytest.warns(TimeScaleWarning, match="lower dt"):
        run_montecarlo(_toy(dt=1.0), 2, keep=0)


def test_units_of_states_derivatives_and_angles():
    exp = UNI.range_gamma_unknown_experiment().with_(units={"xv": "m", "w": "m/s"})
    assert exp.unit("xv") == "m" and exp.unit("yv") == "" and exp.unit("w1") == "m/s^2"
    assert exp.display_unit("theta") == ("deg", pytest.approx(180 / np.pi))
    assert exp.display_unit("bearing phi")[0] == "deg" and exp.display_unit("range") == ("m", 1.0)
    with pytest.raises(OptionError):
        exp.unit("nope")


# ---------------------------------------------------------------------- the summary
def _fabricated(values, exp=None):
    """A result whose every record holds ``values`` (errors and sigmas; NEES 3)."""
    exp = exp or UNI.range_gamma_unknown_experiment()
    N, d = exp.n_aug, len(exp.quantities)
    stats = np.empty((2, 3, 2 * N + 2 * d + 1), np.float32)
    stats[:] = np.resize(np.asarray(values, np.float32), 2 * N + 2 * d + 1)
    stats[..., -1] = 3.0
    return uj.MonteCarloResult(exp, 2, 0, np.array([0.0, 1.0, 2.0]), stats, None)


def test_format_table_keeps_columns_apart_for_any_value():
    from uio_jax._filter.result import _num, format_table

    values = [1.469e6, 29372044.28, 1e-30, float("nan"), float("inf"), -2.5e-7, 0.05]
    cells = [_num(v) for v in values]
    assert cells == ["1.469e+06", "2.937e+07", "1e-30", "nan", "inf", "-2.5e-07", "0.05"]
    rows = [[f"s{i}", c, _num(v * 3, ".3g"), "deg" if i % 2 else ""] for i, (c, v) in
            enumerate(zip(cells, values))]
    lines = format_table(["name", "value", "x3", "unit"], rows, "lrrl")
    for line, row in zip(lines[1:], rows):
        assert line.split() == [c for c in row if c]          # no cells ran together
    ends = {len(ln[:ln.index(r[1]) + len(r[1])]) for ln, r in zip(lines[1:], rows)}
    assert len(ends) == 1                                     # right-aligned: same right edge
    with pytest.raises(OptionError):
        format_table(["a", "b"], [["1"]], "lr")


def test_summary_table_aligned_with_huge_tiny_nan_and_deg():
    res = _fabricated([1.469e6, 1e-30, float("nan"), 29372044.28, 0.05, 3e30])
    lines = res.summary().splitlines()
    table = lines[lines.index(next(ln for ln in lines if "prior std" in ln)):][:1 + 8]
    header = table[0]
    cols = [header.index(h) + len(h) for h in ("prior std", "RMSE end", "ratio", "sigma end")]
    for ln in table[1:]:
        for c in cols:  # every number ends at its header's right edge, a space before it
            assert ln[c - 1] != " " and (c == len(ln) or ln[c] == " "), ln
    theta = next(ln for ln in table if ln.split()[0] == "theta")
    assert theta.split()[1] == "deg" and theta.index("deg") == header.index("unit")


def test_summary_starts_with_the_verdict_and_explains_it():
    """The 003 case (range, gamma unknown): the states moved by the rotation look
    converging, the named quantities agree: 'consistent', with the reason next to it."""
    res = _fabricated([0.01] * 4)
    cmp = {"analysis": "single_ui", "note": "",
           "states": {s: {"observable": False, "converges": True, "agree": False}
                      for s in ("xv", "theta", "gamma")}
           | {"yv": {"observable": False, "converges": None, "agree": None}},
           "quantities": {"bearing phi": {"observable": False, "converges": False, "agree": True},
                          "range": {"observable": True, "converges": True, "agree": True}},
           "agree": False}
    lines = res.summary(cmp).splitlines()
    assert lines[1].startswith("verdict: consistent with the analysis (single_ui) on the named")
    assert "xv, theta, gamma look converging though unobservable" in lines[2]
    assert "undecided: yv" in lines[3]
    cmp["quantities"]["bearing phi"] = {"observable": True, "converges": False, "agree": False}
    assert res.headline(cmp)[0].startswith("verdict: Monte Carlo and the analysis (single_ui) "
                                           "disagree on bearing phi (observable, does not converge)")
    assert res.headline()[0] == "verdict: Monte Carlo only (no analysis compared)"


def test_json_says_what_the_text_says():
    """Issue 40: the states moved by an unobservable direction look converging, the named
    quantities agree: the text says 'consistent'; ``comparison.agree`` and the JSON's
    ``outcome`` say the same, and the JSON names the filter that ran."""
    from types import SimpleNamespace

    res = _fabricated([1.0] * 4)
    res.stats[:, 1:, :2 * res.experiment.n_aug] = 1e-3  # every state converges; not the quantities
    states = tuple(res.experiment.system.states)
    report = SimpleNamespace(method="single_ui", states=states, observable=dict.fromkeys(states, False),
                             is_observable=lambda fn: False)
    cmp = res.compare(report)
    line = res.summary(cmp).splitlines()[1]
    assert line.startswith("verdict: consistent with the analysis (single_ui)"), line
    assert cmp["agree"] is True and cmp["verdict"] == "consistent"
    d = json.loads(json.dumps(res.to_dict(cmp)))
    assert d["outcome"] == "consistent" and d["headline"][0] == line and d["filter"] == "fast"
    assert d["comparison"]["agree"] is True
    assert res.to_dict()["outcome"] == "monte_carlo_only" and "comparison" not in res.to_dict()
