"""Test set-up: float64 everywhere, a non-interactive plot backend, figures closed."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")

import jax  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: under CI=true a skip (a missing oracle) fails the run instead of vanishing; the new-user
#: tests' small models and their fixtures
pytest_plugins = ["strict_skips", "new_user_models"]


def zoo(spec: str) -> str:
    """Absolute ``systems/FILE.py:NAME`` spec of a zoo entry."""
    return os.path.join(ROOT, "systems", spec)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    try:
        import matplotlib.pyplot as plt

        plt.close("all")
    except ImportError:  # pragma: no cover
        pass
