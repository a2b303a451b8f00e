"""Under CI=true a test that skips (an oracle missing) fails; elsewhere it stays a skip."""

import os
import subprocess
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))

SKIPPING = '''
import pytest
missing = pytest.importorskip("uio_jax_no_such_oracle_module")

def test_never_runs():
    assert missing
'''

SKIPPED_TEST = '''
import pytest

def test_skips():
    pytest.skip("no oracle here")
'''


def _run(tmp_path, text, ci):
    path = tmp_path / "test_case.py"
    path.write_text(text)
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    if ci:
        env["CI"] = "true"
    env["PYTHONPATH"] = HERE + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "strict_skips", "-p", "no:cacheprovider", "-q",
         "-n", "0", "-o", "addopts=", "--rootdir", str(tmp_path), str(path)],
        capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)


@pytest.mark.parametrize("text", [SKIPPING, SKIPPED_TEST], ids=["importorskip", "skip"])
def test_a_skip_fails_under_ci(tmp_path, text):
    strict = _run(tmp_path, text, ci=True)
    assert strict.returncode != 0, strict.stdout
    assert "skipped under CI=true" in strict.stdout
    relaxed = _run(tmp_path, text, ci=False)
    assert relaxed.returncode in (0, 5), relaxed.stdout  # 5: the skipped module left no test
    assert "skipped" in relaxed.stdout
