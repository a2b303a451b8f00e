"""A pytest plugin: under CI (``CI=true``) a skipped test or module is a failure.

The independent oracles (sympy, filterpy, StrikePy) come with the dev extra. A test that
skips because one is missing would make the oracle vanish silently from CI's run, so
there a skip fails, with the reason it gave. Outside CI a skip stays a skip.
"""

import os

import pytest

STRICT = os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")


def _fail(report, what):
    report.outcome = "failed"
    report.longrepr = (f"{what} skipped under CI=true (the dev extra must install every oracle): "
                       f"{report.longrepr}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if STRICT and report.skipped and not hasattr(report, "wasxfail"):
        _fail(report, "test")


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    report = outcome.get_result()
    if STRICT and report.skipped:
        _fail(report, "module")
