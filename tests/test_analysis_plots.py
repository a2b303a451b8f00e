"""``uj.plot_analysis`` and ``uio-jax analyze --plot``: dims per step, per-sample rank evidence."""

from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
from helpers import zoo_path

import uio_jax as uj
from uio_jax import cli

GOOD = f"{zoo_path('unicycle_polar')}:range_known"


def _fake_report(method="orc", sv=None, with_sv=True, aug=None):
    """A Report-like object: the plot reads only these attributes."""
    history = tuple(uj.Step(m, d, (), 1.0, {} if aug is None else {"augmented_rank": aug[m]})
                    for m, d in enumerate((1, 2, 2)))
    cert = uj.Certificate(samples=16, used=16, dropped=0, fraction=1.0, min_fraction=1.0,
                          sigma_r_min=0.3, sigma_next_max=1e-14, rtol=1e-8, decisions=4)
    rep = SimpleNamespace(method=method, dim=2, n=3, history=history, dims=(1, 2, 2),
                          certificate=cert, system_name="fake")
    if with_sv:
        rep.sample_singular_values = lambda: (
            np.column_stack([np.ones(16), np.linspace(0.3, 0.9, 16)]) if sv is None else sv)
    return rep


def _hlines(ax):
    """y of every horizontal line drawn with axhline."""
    return [ln.get_ydata()[0] for ln in ax.get_lines() if len(set(ln.get_ydata())) == 1
            and list(ln.get_xdata()) == [0, 1]]


def test_panels_of_a_fake_report(tmp_path):
    path = tmp_path / "a.png"
    fig = uj.plot_analysis(_fake_report(), path)
    assert isinstance(fig, matplotlib.figure.Figure)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    left, right = fig.axes[:2]
    dims = left.get_lines()[0]
    assert list(dims.get_xdata()) == [0, 1, 2] and list(dims.get_ydata()) == [1, 2, 2]
    assert 3 in _hlines(left)  # n as a dashed line
    assert right.get_yscale() == "log"
    assert sorted(_hlines(right)) == [1e-14, 1e-8]  # sigma_next_max and rtol
    median = [ln for ln in right.get_lines() if ln.get_label() == "median"][0]
    assert np.allclose(median.get_ydata(), [1.0, 0.6])
    assert len(right.collections) == 3  # min-max, 5-95 %, 25-75 % bands
    assert "13.5 decades" in right.get_title()  # log10(0.3 / 1e-14)


@pytest.mark.parametrize("kw", [{}, dict(method="eorc", with_sv=False, aug=(1, 3, 4)),
                                dict(sv=np.zeros((8, 0)))])
def test_every_panel_has_axis_labels(kw):
    fig = uj.plot_analysis(_fake_report(**kw))
    left, right = fig.axes[:2]
    assert left.get_ylabel() == "dimension (independent covectors)"
    assert left.get_xlabel() in ("step m", "order k")
    assert "s_i" in right.get_ylabel() and "log scale" in right.get_ylabel()
    assert right.get_xlabel().startswith("index i of the singular value")


def test_n_line_says_what_n_counts():
    rep = _fake_report()
    fig = uj.plot_analysis(rep)
    assert "n = 3 (states)" in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    rep.params = ("a",)
    fig = uj.plot_analysis(rep)
    assert "n = 3 (states + parameters)" in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]


def test_eorc_augmented_rank_and_missing_evidence():
    fig = uj.plot_analysis(_fake_report("eorc", with_sv=False, aug=(1, 3, 4)))
    left, right = fig.axes[:2]
    assert left.get_xlabel() == "order k"
    assert [list(ln.get_ydata()) for ln in left.get_lines()][:2] == [[1, 2, 2], [1, 3, 4]]
    assert any("not available" in t.get_text() for t in right.texts)
    assert 1e-8 in _hlines(right)


def test_zeros_and_empty_codistribution():
    sv = np.column_stack([np.ones(8), np.zeros(8)])  # exact zeros: drawn at the floor, not dropped
    fig = uj.plot_analysis(_fake_report(sv=sv))
    assert fig.axes[1].get_ylim()[0] > 0
    fig = uj.plot_analysis(_fake_report(sv=np.zeros((8, 0))))
    assert any("empty" in t.get_text() for t in fig.axes[1].texts)


def test_real_report_formats_and_given_axes(tmp_path):
    rep = uj.analyze(uj.load_system(GOOD), samples=64)
    for suffix, magic in (("svg", b"<?xml"), ("pdf", b"%PDF")):
        uj.plot_analysis(rep, tmp_path / f"r.{suffix}")
        assert (tmp_path / f"r.{suffix}").read_bytes().startswith(magic)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2)
    assert uj.plot_analysis(rep, ax=axes) is fig
    assert list(axes[0].get_lines()[0].get_ydata()) == list(rep.dims)
    if hasattr(rep, "sample_singular_values"):
        sv = rep.sample_singular_values()
        assert sv.shape == (64, rep.dim)
        median = [ln for ln in axes[1].get_lines() if ln.get_label() == "median"][0]
        assert np.allclose(median.get_ydata(), np.median(sv, axis=0))


def test_bad_arguments(tmp_path):
    with pytest.raises(uj.OptionError, match="suffixes"):
        uj.plot_analysis(_fake_report(), tmp_path / "a.txt")
    with pytest.raises(uj.OptionError, match="two matplotlib Axes"):
        uj.plot_analysis(_fake_report(), ax=object())


def test_cli_analyze_plot(tmp_path, capsys):
    path = tmp_path / "fig.png"
    assert cli.main(["analyze", GOOD, "--samples", "64", "--no-cache", "--plot", str(path)]) == 0
    out, _ = capsys.readouterr()
    assert f"figure written to {path}" in out and path.stat().st_size > 1000
    # a bad suffix is refused before the analysis runs: one line, exit 2
    assert cli.main(["analyze", GOOD, "--no-cache", "--plot", str(tmp_path / "fig.txt")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("uio-jax: error: figure file") and err.count("\n") == 1
