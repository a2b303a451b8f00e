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
    assert pub.get("method", "auto") in ("auto", "orc", "single_ui", "eorc")


@pytest.mark.parametrize("spec", [
    "unicycle_wind.py:range_gamma_unknown",  # names used in DESIGN.md
    "drone_wind.py:with_wind",
    "drone_wind.py:no_wind",
])
def test_design_contract_names(spec):
    assert isinstance(uj.load_system(os.path.join(ROOT, "systems", spec)), uj.System)
