"""SBML models with declared outputs and inputs (``load_system("model.xml", outputs=...)``).

Every SBML file here is written by the test with python-libsbml; each conversion is compared
with a hand-derived model: the same equations (sympy, exactly) and the same report as the
hand-written ``System.from_sympy`` model. The refusals are one line in the API and exit code
2 with one line on the command line.
"""

import os

import pytest

import uio_jax as uj
from uio_jax.cli import main

libsbml = pytest.importorskip("libsbml")
pytest.importorskip("sbmlmath")
sp = pytest.importorskip("sympy")

SAMPLES = 256


# ----------------------------------------------------------------------------- writing SBML
class Builder:
    """A small SBML Level 3 model written with libsbml."""

    def __init__(self, model_id="m", level=3, version=2):
        self.doc = libsbml.SBMLDocument(level, version)
        self.m = self.doc.createModel()
        self.m.setId(model_id)

    def compartment(self, cid, size=None, constant=True):
        c = self.m.createCompartment()
        c.setId(cid)
        c.setConstant(constant)
        if size is not None:
            c.setSize(size)
        return self

    def species(self, sid, comp, init=1.0, amount=False, boundary=False, constant=False):
        s = self.m.createSpecies()
        s.setId(sid)
        s.setCompartment(comp)
        s.setHasOnlySubstanceUnits(amount)
        s.setBoundaryCondition(boundary)
        s.setConstant(constant)
        if init is not None:
            (s.setInitialAmount if amount else s.setInitialConcentration)(init)
        return self

    def parameter(self, pid, value=None, constant=True):
        p = self.m.createParameter()
        p.setId(pid)
        p.setConstant(constant)
        if value is not None:
            p.setValue(value)
        return self

    def reaction(self, rid, reactants, products, formula, local=None, fast=None):
        r = self.m.createReaction()
        r.setId(rid)
        r.setReversible(False)
        if fast is not None:
            r.setFast(fast)
        for refs, create in ((reactants, r.createReactant), (products, r.createProduct)):
            for sid, n in refs.items():
                ref = create()
                ref.setSpecies(sid)
                ref.setStoichiometry(n)
                ref.setConstant(True)
        law = r.createKineticLaw()
        for pid, value in (local or {}).items():
            lp = law.createLocalParameter()
            lp.setId(pid)
            lp.setValue(value)
        law.setMath(_formula(formula))
        return self

    def assignment(self, var, formula):
        self.m.createAssignmentRule().setVariable(var)
        self.m.getRule(self.m.getNumRules() - 1).setMath(_formula(formula))
        return self

    def rate_rule(self, var, formula):
        self.m.createRateRule().setVariable(var)
        self.m.getRule(self.m.getNumRules() - 1).setMath(_formula(formula))
        return self

    def write(self, path):
        assert libsbml.writeSBMLToFile(self.doc, str(path)) == 1
        return str(path)


def _formula(text):
    ast = libsbml.parseL3Formula(text)
    assert ast is not None, libsbml.getLastParseL3Error()
    return ast


def equations(system):
    """The converted model's right-hand sides and outputs as sympy (constants substituted)."""
    spec = system.source
    names = {nm: sp.Symbol(nm) for nm in (*spec.states, *spec.params, *spec.constants, *spec.inputs_known,
                                          *spec.inputs_unknown, *([spec.time] if spec.time else []))}
    consts = {sp.Symbol(k): sp.Rational(repr(v)) for k, v in spec.constants.items()}

    def read(text):
        return sp.sympify(text, locals=names).xreplace(consts)

    return ({k: read(v) for k, v in spec.dynamics.items()}, {k: read(v) for k, v in spec.outputs.items()})


def same_equations(got, want):
    assert set(got) == set(want), (got, want)
    for k in want:
        assert sp.simplify(got[k] - want[k]) == 0, (k, got[k], want[k])


def verdicts(rep):
    return rep.method, rep.dim, dict(rep.observable), dict(rep.identifiable), rep.exact


def same_report(a, b):
    ra = uj.analyze(a, samples=SAMPLES)
    rb = uj.analyze(b, samples=SAMPLES)
    assert verdicts(ra) == verdicts(rb)
    return ra


# ----------------------------------------------------------------------------- the models
@pytest.fixture
def two_compartment(tmp_path):
    """Central (V=1) and peripheral (V=2.5) compartments, a known dose into the central one,
    elimination from the peripheral one; reaction rates in amount per time (mass action)."""
    return (Builder().compartment("c1", 1).compartment("c2", 2.5)
            .species("A", "c1").species("B", "c2")
            .parameter("k12", 0.3).parameter("k20", 0.2).parameter("dose", 1)
            .reaction("dosing", {}, {"A": 1}, "c1*dose")
            .reaction("transport", {"A": 1}, {"B": 1}, "k12*A*c1")
            .reaction("elimination", {"B": 1}, {}, "k20*B*c2")
            .write(tmp_path / "two_compartment.xml"))


def test_two_compartment_equals_the_hand_model(two_compartment):
    system = uj.load_system(two_compartment, outputs={"y": "B"}, known=["dose"])
    A, B, k12, k20, dose = sp.symbols("A B k12 k20 dose")
    dyn = {"A": dose - k12 * A, "B": k12 * A / sp.Rational(5, 2) - k20 * B}
    same_equations(equations(system)[0], dyn)
    hand = uj.System.from_sympy([A, B], {"y": B}, dynamics=[dyn["A"], dyn["B"]], known=[dose],
                                params=[k12, k20])
    rep = same_report(system, hand)
    assert rep.observable["A"] and rep.observable["B"]


@pytest.fixture
def michaelis_menten(tmp_path):
    """S -> P at Vmax*S/(Km+S) with Km a local parameter of the reaction, S fed by an
    unknown inflow k_in."""
    return (Builder().compartment("cell", 1)
            .species("S", "cell").species("P", "cell")
            .parameter("Vmax", 0.1).parameter("k_in", 0.5).parameter("Km", 7)  # a global Km: shadowed
            .reaction("R1", {"S": 1}, {"P": 1}, "cell*Vmax*S/(Km+S)", local={"Km": 1e-3})
            .reaction("inflow", {}, {"S": 1}, "cell*k_in")
            .write(tmp_path / "mm.xml"))


def test_michaelis_menten_local_parameter_renamed(michaelis_menten):
    system = uj.load_system(michaelis_menten, outputs=["P", "S"], unknown=["k_in"])
    S, P, Vmax, Km, w = sp.symbols("S P Vmax R1_Km k_in")
    dyn = {"S": w - Vmax * S / (Km + S), "P": Vmax * S / (Km + S)}
    got, outs = equations(system)
    same_equations(got, dyn)
    assert set(system.source.params) == {"Vmax", "R1_Km"}  # the global Km is used nowhere
    assert system.source.params["R1_Km"] == (0.0005, 0.0015)  # around the file's value
    hand = uj.System.from_sympy([S, P], {"P": P, "S": S}, dynamics=list(dyn.values()), unknown=[w],
                                params={Vmax: (0.05, 0.15), Km: (0.0005, 0.0015)})
    rep = same_report(system, hand)
    assert dict(rep.observable) == {"S": True, "P": True}


@pytest.fixture
def rules_model(tmp_path):
    """An assignment rule used in a kinetic law and in another rule, and a rate rule on a
    parameter that reads an assignment."""
    return (Builder().compartment("cell", 1)
            .species("S", "cell").species("P", "cell")
            .parameter("k", 2).parameter("kz", 0.5)
            .parameter("flux", constant=False).parameter("total", constant=False).parameter("z", 0, constant=False)
            .assignment("flux", "k*S")
            .assignment("total", "S + P + flux - flux")
            .rate_rule("z", "-kz*z + total")
            .reaction("R1", {"S": 1}, {"P": 1}, "cell*flux")
            .write(tmp_path / "rules.xml"))


def test_assignment_and_rate_rules(rules_model):
    system = uj.load_system(rules_model, outputs={"y": "z", "y_flux": "flux"})
    S, P, z, k, kz = sp.symbols("S P z k kz")
    dyn = {"S": -k * S, "P": k * S, "z": -kz * z + S + P}
    got, outs = equations(system)
    same_equations(got, dyn)
    same_equations(outs, {"y": z, "y_flux": k * S})
    assert system.source.states == ("S", "P", "z")
    hand = uj.System.from_sympy([S, P, z], {"y": z, "y_flux": k * S}, dynamics=list(dyn.values()),
                                params=[k, kz])
    same_report(system, hand)


@pytest.fixture
def amount_species(tmp_path):
    """X in amount (hasOnlySubstanceUnits) and Y in concentration in one compartment of
    volume 2.5; X -> Y at k*X (amount per time)."""
    return (Builder().compartment("c", 2.5)
            .species("X", "c", init=3, amount=True).species("Y", "c")
            .parameter("k", 1)
            .reaction("R", {"X": 1}, {"Y": 1}, "k*X")
            .write(tmp_path / "amount.xml"))


def test_amount_and_concentration_species(amount_species):
    system = uj.load_system(amount_species, outputs={"y": "Y"})
    X, Y, k = sp.symbols("X Y k")
    dyn = {"X": -k * X, "Y": sp.Rational(2, 5) * k * X}
    same_equations(equations(system)[0], dyn)
    assert dict(system.source.constants) == {"c": 2.5}
    hand = uj.System.from_sympy([X, Y], {"y": Y}, dynamics=list(dyn.values()), params=[k])
    rep = same_report(system, hand)
    # y' = 2/5 k X and y'' = -2/5 k^2 X: k = -y''/y', then X
    assert dict(rep.observable) == {"X": True, "Y": True} and dict(rep.identifiable) == {"k": True}


def test_mitotic_oscillator_mirrored_by_hand(tmp_path):
    """A hand-written mirror of a small published BioModels model, Goldbeter's minimal
    mitotic oscillator (1991): cyclin C, active cdc2 fraction M, active protease fraction X,
    with the rates V1 and V3 as assignment rules and Michaelis-Menten laws."""
    b = (Builder("goldbeter").compartment("cell", 1).species("C", "cell").species("M", "cell")
         .species("X", "cell"))
    for pid in ("vi", "kd", "vd", "Kd", "K1", "VM1", "Kc", "V2", "K2", "VM3", "K3", "V4", "K4"):
        b.parameter(pid, 0.5)
    b.parameter("V1", constant=False).parameter("V3", constant=False)
    b.assignment("V1", "C*VM1/(Kc+C)").assignment("V3", "M*VM3")
    b.reaction("r1", {}, {"C": 1}, "cell*vi").reaction("r2", {"C": 1}, {}, "cell*C*vd*X/(C+Kd)")
    b.reaction("r3", {"C": 1}, {}, "cell*C*kd").reaction("r4", {}, {"M": 1}, "cell*(1-M)*V1/(K1-M+1)")
    b.reaction("r5", {"M": 1}, {}, "cell*M*V2/(K2+M)").reaction("r6", {}, {"X": 1}, "cell*V3*(1-X)/(K3-X+1)")
    b.reaction("r7", {"X": 1}, {}, "cell*V4*X/(K4+X)")
    system = uj.load_system(b.write(tmp_path / "goldbeter.xml"), outputs={"y": "C"},
                            fixed=["vi", "kd", "K1", "K2", "K3", "K4", "Kc", "Kd"])
    C, M, X, vd, VM1, V2, VM3, V4 = sp.symbols("C M X vd VM1 V2 VM3 V4")
    h = sp.Rational(1, 2)
    V1, V3 = C * VM1 / (h + C), M * VM3
    dyn = {"C": h - vd * X * C / (C + h) - h * C,
           "M": V1 * (1 - M) / (h + 1 - M) - V2 * M / (h + M),
           "X": V3 * (1 - X) / (h + 1 - X) - V4 * X / (h + X)}
    same_equations(equations(system)[0], dyn)
    hand = uj.System.from_sympy([C, M, X], {"y": C}, dynamics=list(dyn.values()),
                                params={s: (0.25, 0.75) for s in (vd, VM1, V2, VM3, V4)})
    same_report(system, hand)


# ----------------------------------------------------------------------------- exactness, time
def test_constants_are_exact_rationals(tmp_path):
    path = (Builder().compartment("c", 1).species("S", "c").parameter("k", 1)
            .reaction("R", {"S": 1}, {}, "0.1*k*S + 1e-3*S").write(tmp_path / "exact.xml"))
    system = uj.load_system(path, outputs=["S"])
    text = system.source.dynamics["S"]
    assert "/10 " in text and "/1000)" in text, text  # decimals, not binary floats
    S, k = sp.symbols("S k")
    same_equations(equations(system)[0], {"S": -(k * S / 10 + S / 1000)})  # over c = 1


def test_time_becomes_the_models_time(tmp_path):
    b = Builder().compartment("c", 1).species("S", "c").parameter("k", 1)
    b.reaction("R", {}, {"S": 1}, "k*exp(-time)")
    system = uj.load_system(b.write(tmp_path / "time.xml"), outputs=["S"])
    assert system.source.time == "t"
    S, k, t = sp.symbols("S k t")
    same_equations(equations(system)[0], {"S": k * sp.exp(-t)})
    rep = uj.analyze(system, samples=SAMPLES)
    assert rep.observable["S"]


# ----------------------------------------------------------------------------- round trip, CLI
def test_round_trip_sbml_system_toml_same_report(michaelis_menten, tmp_path):
    system = uj.load_system(michaelis_menten, outputs={"y": "P"}, unknown=["k_in"], fixed={"Vmax": 0.1})
    path = tmp_path / "mm.toml"
    uj.save_model(system, path)
    back = uj.load_system(str(path))
    a, b = uj.analyze(system, samples=SAMPLES), uj.analyze(back, samples=SAMPLES)
    da, db = a.to_dict(), b.to_dict()
    for d in (da, db):
        d.pop("certificate", None)
    assert da == db


def test_cli_analyze_and_save_model(michaelis_menten, tmp_path, capsys):
    out = tmp_path / "cli.toml"
    args = ["--outputs", "y=P", "--unknown", "k_in", "--fixed", "Vmax=0.1"]
    assert main(["save-model", michaelis_menten, str(out), *args]) == 0
    assert dict(uj.load_system(str(out)).source.constants) == {"Vmax": 0.1, "cell": 1.0}
    assert main(["analyze", michaelis_menten, "--samples", str(SAMPLES), "--no-progress", *args]) == 0
    text = capsys.readouterr().out
    assert "P  observable" in text and "R1_Km" in text


def test_batch_over_a_folder_with_one_rule(michaelis_menten, amount_species, tmp_path):
    folder = _folder_of_two(tmp_path, michaelis_menten, amount_species)
    result = uj.batch_analyze(folder, sbml={"outputs": {"y": "P"}}, samples=SAMPLES, progress=False)
    rows = {os.path.basename(r.model): r for r in result}
    assert rows["mm.xml"].error is None and "P" in rows["mm.xml"].observable
    assert "'P'" in rows["amount.xml"].error  # the rule names an id the file does not have


def test_petab_observables_table(michaelis_menten, tmp_path):
    table = tmp_path / "observables.tsv"
    table.write_text("observableId\tobservableFormula\tnoiseFormula\n"
                     "obs_P\tscale * P^1\t1\n")
    system = uj.load_system(michaelis_menten, observables=str(table), unknown=["k_in"])
    assert "scale" in system.source.params
    _, outs = equations(system)
    same_equations(outs, {"obs_P": sp.Symbol("scale") * sp.Symbol("P")})
    assert any("scale" in n for n in system.notes)


# ----------------------------------------------------------------------------- refusals
def _refused(b, tmp_path, name, **kwargs):
    kwargs.setdefault("outputs", ["S"])
    return _one_line(b.write(tmp_path / f"{name}.xml"), kwargs)


def _one_line(path, kwargs):
    with pytest.raises(uj.UioJaxError) as exc:
        uj.load_system(path, **kwargs)
    msg = str(exc.value)
    assert "\n" not in msg and "Traceback" not in msg
    return msg


def _base():
    return Builder().compartment("c", 1).species("S", "c").parameter("k", 1)


def test_refuses_events(tmp_path):
    b = _base().reaction("R", {"S": 1}, {}, "k*S")
    ev = b.m.createEvent()
    ev.setId("pulse")
    ev.setUseValuesFromTriggerTime(True)
    trig = ev.createTrigger()
    trig.setMath(_formula("time > 1"))
    trig.setInitialValue(False)
    trig.setPersistent(True)
    ea = ev.createEventAssignment()
    ea.setVariable("S")
    ea.setMath(_formula("1"))
    assert "events" in _refused(b, tmp_path, "events")


@pytest.mark.parametrize("formula, word", [
    ("k*delay(S, 1)", "delay"),
    ("piecewise(k*S, S > 1, 0)", "piecewise"),
    ("k*floor(S)", "floor"),
])
def test_refuses_formulas(tmp_path, formula, word):
    b = _base().reaction("R", {"S": 1}, {}, formula)
    assert word in _refused(b, tmp_path, word)


def test_refuses_algebraic_rules_varying_compartments_and_fast_reactions(tmp_path):
    b = _base().parameter("a", constant=False).reaction("R", {"S": 1}, {}, "k*S")
    b.m.createAlgebraicRule().setMath(_formula("a - S"))
    assert "algebraic" in _refused(b, tmp_path, "algebraic")
    b = Builder().compartment("c", 1, constant=False).species("S", "c").parameter("k", 1)
    assert "not constant" in _refused(b.reaction("R", {"S": 1}, {}, "k*S"), tmp_path, "volume")
    b = Builder(level=3, version=1).compartment("c", 1).species("S", "c").parameter("k", 1)
    assert "fast" in _refused(b.reaction("R", {"S": 1}, {}, "k*S", fast=True), tmp_path, "fast")


@pytest.mark.parametrize("kwargs, words", [
    ({"outputs": None}, "declares no outputs"),
    ({"outputs": {"y": "Q"}}, "'Q'"),
    ({"known": ["nope"]}, "'nope'"),
    ({"unknown": ["nope"]}, "'nope'"),
    ({"fixed": {"nope": 1}}, "'nope'"),
    ({"unknown": ["S"]}, "a state"),
    ({"unknown": ["k"]}, "not affine"),  # k is in the rate's denominator
    ({"known": ["k"], "unknown": ["k"]}, "one role"),
    ({"colour": "red"}, "'colour'"),
])
def test_refuses_bad_declarations(tmp_path, kwargs, words):
    b = _base().reaction("R", {"S": 1}, {}, "k*S/(k + S)")  # k in a denominator: not affine
    kw = {"outputs": ["S"], **kwargs}
    if kw["outputs"] is None:
        del kw["outputs"]
    assert words in _one_line(b.write(tmp_path / "decl.xml"), kw)


def test_refuses_unreadable_files(tmp_path):
    bad = tmp_path / "bad.xml"
    bad.write_text("<sbml><model><listOfSpecies><species id='S'")
    assert "not a valid SBML file" in _one_line(str(bad), {"outputs": ["S"]})
    other = tmp_path / "other.xml"
    other.write_text("<?xml version='1.0'?><html><body/></html>")
    assert "SBML" in _one_line(str(other), {"outputs": ["S"]})
    assert "not found" in _one_line(str(tmp_path / "missing.sbml"), {"outputs": ["S"]})


def test_missing_extra_is_one_line(tmp_path, monkeypatch):
    path = _base().reaction("R", {"S": 1}, {}, "k*S").write(tmp_path / "m.xml")
    monkeypatch.setitem(__import__("sys").modules, "sbmlmath", None)
    msg = _one_line(path, {"outputs": ["S"]})
    assert "uio_jax[sbml]" in msg


@pytest.mark.parametrize("extra, words", [
    ([], "declares no outputs"),
    (["--outputs", "y=Q"], "'Q'"),
    (["--outputs", "S", "--unknown", "nope"], "'nope'"),
    (["--outputs", "S", "--fixed", "k=abc"], "finite number"),
    (["--outputs", "S", "--events"], "unrecognized"),
])
def test_cli_refusals_exit_2_with_one_line(tmp_path, capsys, extra, words):
    path = _base().reaction("R", {"S": 1}, {}, "k*S").write(tmp_path / "m.xml")
    assert main(["analyze", path, *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err and "Traceback" not in err


def test_cli_events_exit_2(tmp_path, capsys):
    b = _base().reaction("R", {"S": 1}, {}, "k*S")
    ev = b.m.createEvent()
    ev.setId("e1")
    ev.setUseValuesFromTriggerTime(True)
    trig = ev.createTrigger()
    trig.setMath(_formula("time > 1"))
    trig.setInitialValue(False)
    trig.setPersistent(True)
    assert main(["analyze", b.write(tmp_path / "ev.xml"), "--outputs", "y=S"]) == 2
    err = capsys.readouterr().err.strip()
    assert "events" in err and "\n" not in err


def test_sbml_options_for_another_model_are_a_usage_error(tmp_path, capsys):
    toml = tmp_path / "m.toml"
    toml.write_text('states = ["x"]\n[outputs]\ny = "x"\n')
    assert main(["analyze", str(toml), "--outputs", "y=x"]) == 2
    assert "SBML models" in capsys.readouterr().err


# ----------------------------------------------------------------------------- other SBML features
@pytest.fixture
def enzyme(tmp_path):
    """E + S <-> ES -> E + P through a function definition, S fed from a boundary species S0,
    an assignment rule reading a reaction's rate; species E (the name of Euler's constant)."""
    b = (Builder("enzyme").compartment("c", 2).species("E", "c").species("S", "c").species("ES", "c")
         .species("P", "c").species("S0", "c", init=4, boundary=True)
         .parameter("kf", 1).parameter("kr", 1).parameter("kcat", 1).parameter("kin", 1)
         .parameter("v_cat", constant=False))
    fd = b.m.createFunctionDefinition()
    fd.setId("mass_action2")
    fd.setMath(_formula("lambda(k, a, b, k*a*b)"))
    b.reaction("bind", {"E": 1, "S": 1}, {"ES": 1}, "c*(mass_action2(kf, E, S) - kr*ES)")
    b.reaction("cat", {"ES": 1}, {"E": 1, "P": 1}, "c*kcat*ES")
    b.reaction("feed", {}, {"S": 1}, "c*kin*S0")
    b.assignment("v_cat", "cat")
    return b.write(tmp_path / "enzyme.xml")


def test_function_definitions_boundary_species_and_reaction_rates(enzyme):
    system = uj.load_system(enzyme, outputs={"y": "P", "v": "v_cat"})
    E, S, ES, P, kf, kr, kcat, kin = sp.symbols("E S ES P kf kr kcat kin")
    bind, cat = kf * E * S - kr * ES, kcat * ES
    dyn = {"E": cat - bind, "S": 4 * kin - bind, "ES": bind - cat, "P": cat}
    got, outs = equations(system)
    same_equations(got, dyn)
    same_equations(outs, {"y": P, "v": 2 * kcat * ES})  # the rate in amount per time: times c = 2
    assert dict(system.source.constants) == {"c": 2.0, "S0": 4.0}  # fixed at their file values
    hand = uj.System.from_sympy([E, S, ES, P], {"y": P, "v": 2 * kcat * ES}, dynamics=list(dyn.values()),
                                params=[kf, kr, kcat, kin])
    same_report(system, hand)


def test_boundary_species_as_known_input_or_estimated(enzyme):
    system = uj.load_system(enzyme, outputs={"y": "P"}, known=["S0"])
    assert system.source.inputs_known == ("S0",)
    estimated = uj.load_system(enzyme, outputs={"y": "P"}, estimate=["S0", "c"])
    assert estimated.source.params["S0"] == (2.0, 6.0) and "c" in estimated.source.params


def test_level_2_local_parameters_and_compartment_without_size(tmp_path):
    doc = libsbml.SBMLDocument(2, 4)
    m = doc.createModel()
    m.setId("l2")
    c = m.createCompartment()
    c.setId("v")  # no size: a parameter to identify, with a note
    s = m.createSpecies()
    s.setId("A")
    s.setCompartment("v")
    r = m.createReaction()
    r.setId("deg")
    ref = r.createReactant()
    ref.setSpecies("A")
    ref.setStoichiometry(2)
    law = r.createKineticLaw()
    lp = law.createParameter()
    lp.setId("k")
    lp.setValue(0.5)
    law.setMath(_formula("k*A"))
    path = str(tmp_path / "l2.xml")
    assert libsbml.writeSBMLToFile(doc, path) == 1
    system = uj.load_system(path, outputs=["A"])
    A, k, v = sp.symbols("A deg_k v")
    same_equations(equations(system)[0], {"A": -2 * k * A / v})
    assert any("'v' has no value" in n for n in system.notes)


def _folder_of_two(tmp_path, michaelis_menten, amount_species):
    folder = tmp_path / "models"
    folder.mkdir()
    for src in (michaelis_menten, amount_species):
        os.replace(src, folder / os.path.basename(src))
    return str(folder)


def test_cli_batch_with_one_rule(michaelis_menten, amount_species, tmp_path, capsys):
    folder = _folder_of_two(tmp_path, michaelis_menten, amount_species)
    assert main(["batch", folder, "--outputs", "y=P", "--unknown", "k_in", "--no-progress", "--samples",
                 str(SAMPLES)]) == 1  # amount.xml has no k_in: its row is an error, the batch goes on
    rows = [line for line in capsys.readouterr().out.splitlines() if ".xml" in line]
    assert len(rows) == 2 and rows[1].split()[1] == "general_ui" and "'k_in' in unknown is no id" in rows[0]


@pytest.mark.slow
def test_batch_rule_travels_to_worker_processes(michaelis_menten, amount_species, tmp_path):
    folder = _folder_of_two(tmp_path, michaelis_menten, amount_species)
    rule = {"outputs": {"y": "P"}}
    here = uj.batch_analyze(folder, sbml=rule, samples=SAMPLES, progress=False)
    there = uj.batch_analyze(folder, sbml=rule, samples=SAMPLES, progress=False, timeout=120)
    assert [(r.model, r.dim, r.observable, r.error is None) for r in here] == \
        [(r.model, r.dim, r.observable, r.error is None) for r in there]
    assert [r.error is None for r in here] == [False, True]  # amount.xml (no P), mm.xml


def test_a_constant_no_decimal_writes_stays_exact(tmp_path):
    """A boundary species given as an amount 1 in a compartment of size 3: its concentration
    is 1/3 exactly, substituted as a rational (a float's decimal is not 1/3)."""
    path = (Builder().compartment("c", 3).species("S", "c").species("B", "c", init=None, boundary=True)
            .parameter("k", 1).reaction("R", {}, {"S": 1}, "c*k*B").write(tmp_path / "third.xml"))
    doc = libsbml.readSBMLFromFile(path)
    doc.getModel().getSpecies("B").setInitialAmount(1)
    libsbml.writeSBMLToFile(doc, path)
    system = uj.load_system(path, outputs=["S"])
    assert "B" not in system.source.constants
    same_equations(equations(system)[0], {"S": sp.Symbol("k") / 3})
