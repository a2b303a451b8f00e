"""Models of the global-identifiability tests, written as the project's model files (TOML).

Each entry: the model (states, parameters, outputs, dynamics, known inputs) and the published
or hand-derived answer: which unknowns are globally identifiable (``G``), locally but not
globally (``L``, with the count where known), not identifiable (``N``).
"""

import os

import uio_jax as uj


def model_text(name, states, params, outputs, dynamics, known=(), domain=None):
    """A TOML model file's text (every parameter boxed in ``[0.5, 1.5]``; ``domain``: state ->
    ``(lo, hi)``)."""
    lines = [f'name = "{name}"', "states = [" + ", ".join(f'"{s}"' for s in states) + "]"]
    if domain:
        lines.append("[domain]")
        lines += [f"{k} = [{lo}, {hi}]" for k, (lo, hi) in domain.items()]
    if params:
        lines.append("[params]")
        lines += [f"{p} = [0.5, 1.5]" for p in params]
    lines.append("[outputs]")
    lines += [f'{k} = "{v}"' for k, v in outputs.items()]
    if known:
        lines += ["[inputs]", "known = [" + ", ".join(f'"{u}"' for u in known) + "]"]
    lines.append("[dynamics]")
    lines += [f'{k} = "{v}"' for k, v in dynamics.items()]
    return "\n".join(lines) + "\n"


def build(folder, name, states, params, outputs, dynamics, known=(), domain=None):
    """The System of a model written into ``folder``."""
    path = os.path.join(str(folder), f"{name}.toml")
    with open(path, "w") as fh:
        fh.write(model_text(name, states, params, outputs, dynamics, known, domain))
    return uj.load_system(path)


#: StructuralIdentifiability.jl's test "Assessing identifiability" (test/identifiability.jl):
#: the models and the published answers, on the unknowns and on its functions of them
#: (``functions``: callables of ``(x, p)`` as the outputs take them, the parameters in the
#: order listed).
SI_JL_TESTS = {
    "two_compartment": dict(
        states=["x0", "x1"], params=["a01", "a21", "a12"], outputs={"y": "x0"},
        dynamics={"x0": "-(a01 + a21)*x0 + a12*x1", "x1": "a21*x0 - a12*x1"},
        functions={"a01_a12": lambda x, p: p[0] * p[2], "sum": lambda x, p: p[0] + p[1] + p[2],
                   "ratio": lambda x, p: (p[0] + p[1] + p[2]) / (p[0] * p[2])},
        answer={"a01": "N", "a21": "N", "a12": "N", "x0": "G", "x1": "N", "a01_a12": "G", "sum": "G", "ratio": "G"}),
    "no_parameters": dict(
        states=["x1", "x2"], params=[], outputs={"y": "x1 + x2"}, dynamics={"x1": "x1", "x2": "x2"},
        functions={"x1_plus_x2": lambda x: x[0] + x[1]},
        answer={"x1": "N", "x2": "N", "x1_plus_x2": "G"}),
    "lotka_volterra_input": dict(
        states=["x0", "x1"], params=["a", "b", "c", "d"], outputs={"y": "x0"}, known=["u"],
        dynamics={"x0": "a*x0 - b*x0*x1 + u", "x1": "c*x1 + d*x0*x1"},
        functions={"b_x1": lambda x, p: p[1] * x[1]},
        answer={"a": "G", "b": "N", "c": "G", "d": "G", "x0": "G", "x1": "N", "b_x1": "G"}),
    "siwr": dict(
        states=["S", "I", "W", "R"], params=["mu", "bi", "bw", "a", "xi", "gam", "k"], outputs={"y": "k*I"},
        dynamics={"S": "mu - bi*S*I - bw*S*W - mu*S + a*R", "I": "bw*S*W + bi*S*I - (gam + mu)*I",
                  "W": "xi*(I - W)", "R": "gam*I - (mu + a)*R"},
        functions={"gam_plus_mu": lambda x, p: p[5] + p[0]},
        answer={**{p: "G" for p in ["mu", "bi", "bw", "a", "xi", "gam", "k"]}, "gam_plus_mu": "G"}),
    "rational_four_states": dict(
        states=["x1", "x2", "x3", "x4"], params=["b", "c", "alpha", "beta", "delta", "gama", "sigma"],
        outputs={"y": "x1"},
        dynamics={"x1": "-b*x1 + 1/(c + x4)", "x2": "alpha*x1 - beta*x2", "x3": "gama*x2 - delta*x3",
                  "x4": "sigma*x4*(gama*x2 - delta*x3)/x3"},
        functions={"beta_plus_delta": lambda x, p: p[3] + p[4], "beta_delta": lambda x, p: p[3] * p[4]},
        answer={"b": "G", "c": "G", "alpha": "N", "beta": "L", "delta": "L", "gama": "N", "beta_plus_delta": "G",
                "beta_delta": "G"}),
    "rational_outputs": dict(
        states=["x1", "x2"], params=["b"], outputs={"y1": "2*x1/(b*(1 + x1**2))", "y2": "x2"},
        dynamics={"x1": "(1 + x1**2)/2", "x2": "(1 - x1**2)/(1 + x1**2)"},
        answer={"b": "G", "x1": "G", "x2": "G"}),
    "two_compartment_leak": dict(
        states=["x1", "x2"], params=["a1", "a2", "a21"], outputs={"y1": "x1"},
        dynamics={"x1": "-a1*x1 + a21*x2", "x2": "-a2*x2 - a21*x2"},
        answer={"a1": "L", "a2": "N", "a21": "N"}),
    "two_compartment_leak_input": dict(
        states=["x1", "x2"], params=["a1", "a2", "a21"], outputs={"y1": "x1"}, known=["u"],
        dynamics={"x1": "-a1*x1 + a21*x2", "x2": "-a2*x2 - a21*x2 + u"},
        functions={"a2_plus_a1": lambda x, p: p[1] + p[0], "a2_a1_minus_a21": lambda x, p: p[1] * (p[0] - p[2])},
        answer={"a1": "L", "a2": "L", "a21": "G", "a2_plus_a1": "G", "a2_a1_minus_a21": "G"}),
    "three_compartment": dict(
        states=["x1", "x2", "x3"], params=["a21", "a31", "a01", "a12", "a13"], outputs={"y": "x1"}, known=["u"],
        dynamics={"x1": "-(a21 + a31 + a01)*x1 + a12*x2 + a13*x3 + u", "x2": "a21*x1 - a12*x2",
                  "x3": "a31*x1 - a13*x3"},
        functions={"a31_plus_a21": lambda x, p: p[1] + p[0],
                   "ratio": lambda x, p: (p[0] - p[1]) / (p[3] - p[4])},
        answer={"x1": "G", "x2": "L", "x3": "L", "a31_plus_a21": "G", "ratio": "G"}),
    "seir_constant_population": dict(
        states=["S", "E", "In"], params=["b", "N", "nu", "a"], outputs={"y1": "In", "y2": "N"},
        dynamics={"S": "-b*S*In/N", "E": "b*S*In/N - nu*E", "In": "nu*E - a*In"},
        functions={"a_nu": lambda x, p: p[3] * p[2], "a_plus_nu": lambda x, p: p[3] + p[2]},
        answer={"b": "G", "N": "G", "In": "G", "a": "L", "nu": "L", "S": "L", "E": "L", "a_nu": "G",
                "a_plus_nu": "G"}),
}

#: SIAN's tests (SIAN-Julia, test/io_tests.jl, every unknown asked about, none known).
SIAN_TESTS = {
    "lotka_volterra": dict(
        states=["x1", "x2"], params=["a", "b", "c", "d"], outputs={"y1": "x1"},
        dynamics={"x1": "a*x1 - b*x1*x2", "x2": "-c*x2 + d*x1*x2"},
        answer={"a": "G", "c": "G", "d": "G", "x1": "G", "b": "N", "x2": "N"}),
    "quadratic_output": dict(
        states=["x1"], params=["a"], outputs={"y1": "x1", "y2": "a*x1 + a**2"}, dynamics={"x1": "0"},
        answer={"x1": "G", "a": "L"}),
    "seir_population_state": dict(
        states=["S", "E", "In", "N"], params=["b", "nu", "a"], outputs={"y1": "In", "y2": "N"},
        dynamics={"S": "-b*S*In/N", "E": "b*S*In/N - nu*E", "In": "nu*E - a*In", "N": "0"},
        answer={"b": "G", "In": "G", "N": "G", "nu": "L", "S": "L", "a": "L", "E": "L"}),
    "slow_fast": dict(
        states=["xA", "xB", "xC", "eA", "eC"], params=["k1", "k2", "eB"],
        outputs={"y1": "xC", "y2": "eA*xA + eB*xB + eC*xC", "y3": "eA", "y4": "eC"},
        dynamics={"xA": "-k1*xA", "xB": "k1*xA - k2*xB", "xC": "k2*xB", "eA": "0", "eC": "0"},
        answer={"xC": "G", "eC": "G", "eA": "G", "xA": "L", "k1": "L", "xB": "L", "eB": "L", "k2": "L"}),
}

__all__ = ["build", "model_text", "SI_JL_TESTS", "SIAN_TESTS"]
