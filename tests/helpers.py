"""Shared helpers: cached analyses of zoo entries and their published numbers."""

import functools
import importlib.util
import os

import uio_jax as uj

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: Samples used by the paper tests: enough for a certificate, cheap to evaluate.
SAMPLES = 1024


def zoo_path(module: str) -> str:
    return os.path.join(ROOT, "systems", f"{module}.py")


def zoo_system(module: str, name: str) -> uj.System:
    return uj.load_system(f"{zoo_path(module)}:{name}")


@functools.cache
def zoo_report(module: str, name: str, method: str = "auto", samples: int = SAMPLES, seed: int = 0):
    return uj.analyze(zoo_system(module, name), method=method, samples=samples, seed=seed)


@functools.cache
def script_module(name: str):
    """The module ``scripts/NAME.py`` (an oracle or a tool of the repository), loaded once."""
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, "scripts", f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@functools.cache
def zoo_module(module: str):
    spec = importlib.util.spec_from_file_location(f"zoo_{module}", zoo_path(module))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def published(module: str, name: str) -> dict:
    return zoo_module(module).PUBLISHED[name]


def observable_set(report) -> set:
    return {s for s, ok in report.observable.items() if ok}
