"""The model zoo: every published entry and every documented alias loads to a System."""

import glob
import os

import pytest
from helpers import ROOT, zoo_module

import uio_jax as uj

FILES = sorted(os.path.basename(p)[:-3] for p in glob.glob(os.path.join(ROOT, "systems", "*.py")))
ENTRIES = [(m, n) for m in FILES for n in getattr(zoo_module(m), "PUBLISHED", {})]


@pytest.mark.parametrize("module, name", ENTRIES, ids=[f"{m}:{n}" for m, n in ENTRIES])
def test_published_entries_load_and_cite_a_source(module, name):
    system = uj.load_system(os.path.join(ROOT, "systems", f"{module}.py:{name}"))
    assert isinstance(system, uj.System)
    pub = zoo_module(module).PUBLISHED[name]
    assert pub["source"] and "dim" in pub
    assert pub.get("method", "auto") in ("auto", "orc", "single_ui", "general_ui", "eorc")


@pytest.mark.parametrize("spec, unknown, known_any", [
    # names other tools use (the public API's examples): what each must mean
    ("unicycle_wind.py:range_gamma_unknown", ("w",), True),  # the wind on the unicycle unknown
    ("drone_wind.py:wind_unknown", ("w",), True),  # the drone in unknown wind
    ("drone_wind.py:no_wind", (), True),  # the same drone, no unknown input
])
def test_design_contract_names(spec, unknown, known_any):
    """The contract's names load and mean what they say: which inputs are unknown, and the
    same drone with and without its wind (same states, outputs and known inputs)."""
    system = uj.load_system(os.path.join(ROOT, "systems", spec))
    assert isinstance(system, uj.System)
    assert tuple(system.unknown) == unknown
    assert bool(system.known) == known_any
    if spec.startswith("drone_wind"):
        other = uj.load_system(os.path.join(ROOT, "systems", "drone_wind.py:no_wind"))
        assert (system.states, tuple(system.outputs), tuple(system.known)) == \
            (other.states, tuple(other.outputs), tuple(other.known))
