"""Second implementation: our per-step dimensions equal an exact symbolic route (sympy).

The oracle (``scripts/sympy_oracle.py``) writes each model again from its equations in
sympy (``scripts/_sympy_models.py``), forms the Lie derivatives symbolically and takes the
rank at a random point in 50-digit arithmetic: no code is shared with the library.
"""

import os
import sys

import pytest
from helpers import ROOT, published, zoo_module, zoo_report

sys.path.insert(0, os.path.join(ROOT, "scripts"))
sympy_oracle = pytest.importorskip("sympy_oracle", reason="needs sympy (dev extra)")
import _sympy_models  # noqa: E402


def _entry(spec):
    module, name = spec[len("systems/"):].replace(".py", "").split(":")
    return module, name


def _method(spec):
    module, name = _entry(spec)
    return zoo_module(module).PUBLISHED.get(name, {}).get("method")


# The 3-state models with an ORC or single_ui entry (the oracle has no EORC; the vehicle
# and the tan-bearing outputs take tens of seconds symbolically: bench_analysis.py has them).
SMALL = [spec for spec in sorted(_sympy_models.MODELS)
         if "vehicle_wind" not in spec and "bearing" not in spec
         and _method(spec) in ("orc", "single_ui")]


@pytest.mark.parametrize("spec", SMALL)
def test_dims_per_step_equal_the_symbolic_route(spec):
    module, name = _entry(spec)
    model = _sympy_models.get(spec)
    rep = zoo_report(module, name)
    assert rep.method == published(module, name)["method"]
    oracle = sympy_oracle.orc_dims if rep.method == "orc" else sympy_oracle.single_ui_dims
    assert list(rep.dims) == list(oracle(model))
