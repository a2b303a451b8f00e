"""Several experiments on shared parameters (issue 39, item 2), against hand derivations and
the sympy oracle (``tests/taylor_oracle.py``).

**A model that needs two experiments.** A dose ``c`` is given once and measured (``c' = 0``,
``y2 = c``); the amount ``x`` grows at ``x' = p1 + p2 c``, measured (``y1 = x``). One
experiment gives ``x(0)``, ``c`` and the slope ``p1 + p2 c``, higher coefficients vanish:
rank 3 of the 4 unknowns ``x(0), c, p1, p2``, closed at order 2; neither ``p1`` nor ``p2`` is
identifiable (the line ``p1 + p2 c = s`` is all one experiment sees). Two experiments with
doses ``c1 != c2`` give two slopes, ``p1 + p2 c1`` and ``p1 + p2 c2``: both parameters are
identifiable, and two generic experiments reach the full rank 2 of the shared parameters.
"""

import jax.numpy as jnp
import pytest
import sympy as sp
from taylor_oracle import oracle

import uio_jax as uj

D, N = uj.Verdict.DETERMINED, uj.Verdict.NOT_DETERMINED
X, C, P1, P2 = sp.symbols("x c p1 p2")


def dose():
    return uj.System(states=("x", "c"), outputs={"y1": lambda z, p: z[0], "y2": lambda z, p: z[1]},
                     drift=lambda z, p: jnp.stack([p[0] + p[1] * z[1], 0.0 * z[0]]), params=("p1", "p2"),
                     name="dose")


DOSE = {"states": (X, C), "f": [P1 + P2 * C, 0], "h": [X, C], "initial": {}}


def test_one_experiment_does_not_identify_the_parameters():
    rep = uj.analyze(dose(), initial={})
    assert dict(rep.identifiable) == {"p1": N, "p2": N} and rep.stop.name == "SPAN_CLOSED"
    rank, determined = oracle([DOSE], (P1, P2), (P1, P2), rep.order + 2)
    assert rank == 3 and determined == {"x": True, "c": True, "p1": False, "p2": False}


def test_two_experiments_identify_both_and_two_generic_experiments_are_needed():
    model = dose()
    rep = uj.analyze([model, model], shared=("p1", "p2"))
    assert rep.question is uj.Question.EXPERIMENTS and rep.exact
    assert dict(rep.identifiable) == {"p1": D, "p2": D}
    assert set(rep.observable) == {"x[1]", "c[1]", "x[2]", "c[2]"} and all(v is D for v in rep.observable.values())
    first, second = rep.experiments
    assert set(first["added"]) == {"x[1]", "c[1]"} and set(second["added"]) == {"x[2]", "c[2]", "p1", "p2"}
    (generic,) = rep.generic_experiments
    assert generic["minimal"] == 2 and generic["ranks"] == [1, 2] and generic["determined"] == [[], ["p1", "p2"]]
    rank, determined = oracle([DOSE, DOSE], (P1, P2), (P1, P2), 3)
    assert rank == 6 and all(determined.values())
    assert "generic experiments of dose: 2 reach the maximal rank 2" in str(rep)
    assert rep.to_dict()["question"] == "experiments"


def test_experiments_object_equals_the_list_form_and_unshared_parameters_are_copies():
    listed = uj.analyze([dose(), dose()], shared=("p1",))
    assert len(listed.generic_experiments) == 2  # one per distinct System object
    boxed = uj.analyze(uj.Experiments([dose(), dose()], shared=("p1",)))
    assert dict(listed.identifiable) == dict(boxed.identifiable)
    assert set(listed.params) == {"p1", "p2[1]", "p2[2]"}
    # with p2 per experiment: slopes p1 + p2[e] c[e], two equations, three unknowns
    rank, determined = oracle([DOSE, DOSE], (P1, P2), (P1,), 3)
    assert {k: v is D for k, v in listed.verdicts.items()} == determined
    assert not any(determined[p] for p in ("p1", "p2[1]", "p2[2]"))


def test_known_initial_states_per_experiment():
    """Two-compartment model (``tests/test_initial.py``): an experiment starting from ``x2 = 0``
    identifies every rate; a generic second experiment adds its own ``x1`` and ``x2``."""
    def two():
        return uj.System(states=("x1", "x2"), outputs={"y": lambda x, p: x[0]},
                         drift=lambda x, p: jnp.stack([-(p[0] + p[1]) * x[0] + p[2] * x[1],
                                                       p[1] * x[0] - p[2] * x[1]]),
                         params=("k1", "k12", "k21"), domain={"x1": (0, 2), "x2": (0, 2)})
    model = two()
    rep = uj.analyze(uj.Experiments([model, model], initial=[{"x2": 0}, None]))
    assert all(v is D for v in rep.verdicts.values()) and "x2[1]" not in rep.observable
    x1, x2, k1, k12, k21 = sp.symbols("x1 x2 k1 k12 k21")
    f = [-(k1 + k12) * x1 + k21 * x2, k12 * x1 - k21 * x2]
    exps = [{"states": (x1, x2), "f": f, "h": [x1], "initial": {x2: 0}},
            {"states": (x1, x2), "f": f, "h": [x1], "initial": {}}]
    _, determined = oracle(exps, (k1, k12, k21), (k1, k12, k21), 4)
    assert all(determined.values())
    assert rep.experiments[0]["added"] and set(rep.experiments[1]["added"]) == {"x1[2]", "x2[2]"}
    (generic,) = rep.generic_experiments  # generic copies never identify the rates
    assert generic["minimal"] == 1 and generic["ranks"] == [2]


@pytest.mark.parametrize("call, message", [
    (lambda: uj.analyze([dose(), dose()], shared=("p9",)), "'p9' is not a parameter of every experiment"),
    (lambda: uj.analyze([dose(), dose()], initial={"x": 0}), "one initial state per experiment"),
    (lambda: uj.analyze([dose(), "model"]), "sequence of uio_jax.System"),
    (lambda: uj.Experiments([dose()], initial=[{}, {}]), "2 initial states for 1 experiments"),
    (lambda: uj.analyze([dose(), dose()], shared="p1"), "got a string"),
    (lambda: uj.analyze(uj.Experiments([dose()]), shared=("p1",)), "inside uj.Experiments"),
])
def test_bad_experiments(call, message):
    with pytest.raises(uj.OptionError, match=message):
        call()
