"""The recursion decides on the first DECISION_SAMPLES samples; where a decision was not
made exactly the final span is certified on all of them (``Context.certify``), or on the
first that fit when it is very large (``memory.CERTIFY_BYTES``); where every decision was
exact, the float64 screen stops at the decision samples (``Certificate.screen_only``).
The tests of the re-certification force it (``Context.decided_exactly`` False).

Oracle: the same analysis with every sample deciding (``DECISION_SAMPLES`` raised above the
sample count) gives the same dims, verdicts and generators; the evaluations of the run are
at the decision samples except one, of the kept generators, at the other samples.
"""

import pytest
from helpers import zoo_system

import uio_jax as uj
from uio_jax._analysis.decisions import memory
from uio_jax._analysis.decisions.context import Context
from uio_jax._engine import graph_numpy

SAMPLES = 1024


@pytest.fixture
def recertify(monkeypatch):
    """The final span re-decided on every sample, as for a model not decided exactly."""
    monkeypatch.setattr(Context, "decided_exactly", lambda self: False)


def test_an_exact_analysis_screens_on_the_decision_samples_only(monkeypatch):
    """Every decision exact (a rational model): no evaluation past the decision samples, the
    certificate says the screen stopped there, and the verdicts equal the re-certified ones."""
    rows = []
    real = graph_numpy.evaluate

    def recording(graph, roots, xs, gradients=True, **options):
        if gradients:
            rows.append(xs.shape[0])
        return real(graph, roots, xs, gradients, **options)

    monkeypatch.setattr(graph_numpy, "evaluate", recording)
    model = zoo_system("vehicle_wind", "wind_unknown")
    rep = uj.analyze(model, samples=SAMPLES)
    assert set(rows) == {memory.DECISION_SAMPLES}
    cert = rep.certificate
    assert cert.screen_only and cert.used == memory.DECISION_SAMPLES
    assert cert.capped == SAMPLES - memory.DECISION_SAMPLES and rep.exact
    assert "the float64 screen stopped at the decision samples" in str(cert)
    assert not any("certified on the first" in note for note in rep.notes)
    monkeypatch.setattr(Context, "decided_exactly", lambda self: False)
    again = uj.analyze(model, samples=SAMPLES)
    assert again.dims == rep.dims and again.observable == rep.observable and not again.certificate.screen_only


def test_decisions_on_the_first_samples_certified_on_all(monkeypatch, recertify):
    rows = []
    real = graph_numpy.evaluate

    def recording(graph, roots, xs, gradients=True, **options):
        (rows if gradients else screened).append((xs.shape[0], len(roots)))
        return real(graph, roots, xs, gradients, **options)

    screened = []
    monkeypatch.setattr(graph_numpy, "evaluate", recording)
    model = zoo_system("vehicle_wind", "wind_unknown")
    two_phase = uj.analyze(model, samples=SAMPLES)
    # the samples screened once: the values of the outputs and of the fields' components
    fields = len(model.fields())
    assert [r for r in screened if r[0] == SAMPLES] == [(SAMPLES, len(model.outputs) + fields * model.n)]
    rest = SAMPLES - memory.DECISION_SAMPLES  # the model is defined on its whole box
    assert {s for s, _ in rows} == {memory.DECISION_SAMPLES, rest}
    at_rest = [r for s, r in rows if s == rest]
    # one evaluation at the other samples: the kept generators (the decision samples are
    # the first certifying ones, their gradients are reused)
    assert at_rest == [two_phase.dim]
    monkeypatch.setattr(memory, "DECISION_SAMPLES", 10**6)
    every = uj.analyze(zoo_system("vehicle_wind", "wind_unknown"), samples=SAMPLES)
    assert two_phase.dims == every.dims == (3, 5, 6, 6)
    assert two_phase.observable == every.observable and two_phase.generators == every.generators
    for rep in (two_phase, every):
        cert = rep.certificate
        assert cert.samples == SAMPLES and cert.used == SAMPLES and cert.fraction == 1.0


def test_the_eorc_reads_its_final_verdicts_on_all_samples(recertify):
    rep = uj.analyze(zoo_system("gps", "inputs_unknown"), method="eorc", samples=SAMPLES)
    assert rep.dim == 3 and all(rep.observable.values())
    assert rep.certificate.samples == SAMPLES and rep.certificate.used == SAMPLES


def test_a_large_final_span_is_certified_on_the_samples_that_fit(monkeypatch, recertify):
    """Past ``CERTIFY_BYTES`` (``N x N`` float64 per sample) the final span is re-decided on
    the first samples that fit (never fewer than the decision samples): the certificate and
    a note say how many, the verdicts are those of the uncapped run."""

    model = zoo_system("vehicle_wind", "wind_unknown")  # final span: 6 generators on 7 states
    full = uj.analyze(model, samples=SAMPLES)
    assert full.certificate.capped == 0
    fit = 600
    monkeypatch.setattr(memory, "CERTIFY_BYTES", 8 * 7 * 7 * fit)  # 7 x 7 per sample
    assert memory.certify_samples(SAMPLES, 7) == fit
    capped = uj.analyze(model, samples=SAMPLES)
    cert = capped.certificate
    assert cert.samples == SAMPLES and cert.capped == SAMPLES - fit
    assert cert.used + cert.dropped == fit and cert.used == fit
    assert capped.dims == full.dims and capped.observable == full.observable
    assert any(f"certified on the first {fit} of the {SAMPLES} samples" in note for note in capped.notes)
    assert f"{SAMPLES - fit} not evaluated on the final span" in str(cert)
    # the floor: never fewer than the decision samples
    monkeypatch.setattr(memory, "CERTIFY_BYTES", 1)
    assert memory.certify_samples(SAMPLES, 7) == memory.DECISION_SAMPLES
    assert memory.certify_samples(100, 7) == 100
