"""The on-disk program cache: a later analysis of the same model skips tracing, and nothing
that changes the computation can reuse a stale program."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import zoo_system

import uio_jax as uj
from uio_jax._calculus.generators import jaxpr_sizes
from uio_jax._engine import program_cache as _program_cache
from uio_jax._engine.compile_cache import compile_cache


@pytest.fixture(autouse=True)
def compiled_route(monkeypatch):
    """These tests are about programs compiled by XLA: every evaluation goes there (the
    expression graph would evaluate these models without compiling anything)."""
    monkeypatch.setenv("UIO_JAX_ENGINE", "xla")


def _programs(cache_dir):
    return sorted((cache_dir / _program_cache.SUBDIR).glob("*.prog"))


def _same_report(a, b):
    assert a.method == b.method and a.dim == b.dim and a.observable == b.observable
    assert [s.dim for s in a.history] == [s.dim for s in b.history]
    assert a.certificate.fraction == b.certificate.fraction
    assert a.generators == b.generators


@pytest.mark.parametrize("spec, method", [("unicycle_polar:range_v_unknown", "auto"),
                                          ("gps:inputs_unknown", "eorc"),
                                          ("unicycle_polar:bearing_known", "auto")])
def test_a_fresh_system_object_loads_every_program_and_reports_the_same(tmp_path, spec, method,
                                                                       monkeypatch):
    """Second analysis on a new System object (as in a new process): no program traced.

    (The general solution's programs after a UI extension live on Systems it builds itself,
    whose nodes carry no signature: they are not kept on disk, so gps:inputs_unknown is run
    here by the EORC.)"""
    with compile_cache(tmp_path):
        first = uj.analyze(zoo_system(*spec.split(':')), samples=256, method=method)
        assert _programs(tmp_path), "nothing was stored"
        traced = []
        real = _program_cache._trace_and_compile
        monkeypatch.setattr(_program_cache, "_trace_and_compile",
                            lambda *a: traced.append(a[0]) or real(*a))
        second = uj.analyze(zoo_system(*spec.split(':')), samples=256, method=method)
    assert traced == []
    _same_report(first, second)


def _system(scale, name="scaled"):
    return uj.System(
        states=("a", "b"),
        outputs={"y": lambda x: scale * x[0]},
        drift=lambda x: jnp.stack([x[1], -x[0]]),
        name=name,
    )


def test_a_changed_constant_or_function_changes_the_model_fingerprint():
    fp = _program_cache.model_fingerprint
    assert fp(_system(1.0)) == fp(_system(1.0))  # same computation, other objects
    assert fp(_system(1.0)) != fp(_system(2.0))  # a literal
    const = np.array([1.0, 2.0])
    other = uj.System(states=("a", "b"), outputs={"y": lambda x: jnp.dot(const, x)},
                      drift=lambda x: jnp.stack([x[1], -x[0]]))
    const2 = np.array([1.0, 3.0])
    other2 = uj.System(states=("a", "b"), outputs={"y": lambda x: jnp.dot(const2, x)},
                       drift=lambda x: jnp.stack([x[1], -x[0]]))
    assert fp(other) != fp(other2)  # a captured array constant
    renamed = uj.System(states=("a", "b"), outputs={"z": lambda x: x[0]}, drift=lambda x: jnp.stack([x[1], -x[0]]))
    assert fp(renamed) != fp(_system(1.0))


def test_a_model_change_is_not_answered_from_a_stale_program(tmp_path):
    """Same names and structure, another constant: a new program, the right answer."""
    with compile_cache(tmp_path):
        uj.analyze(_system(1.0), samples=128)
        n_files = len(_programs(tmp_path))
        # y = 0 * a: nothing observable; a stale program (y = a) would say both are
        rep = uj.analyze(_system(0.0), samples=128)
        assert len(_programs(tmp_path)) > n_files
    assert rep.dim == 0


def test_nodes_without_a_signature_are_not_keyed(tmp_path):
    sys = _system(1.0)
    xs = jnp.zeros((4, 2))
    with compile_cache(tmp_path):
        assert _program_cache.program_key(sys, ["grad", ""], xs) is None
        assert _program_cache.program_key(sys, ["grad", "abc"], xs) is not None
        assert (_program_cache.program_key(sys, ["grad", "abc"], xs)
                != _program_cache.program_key(sys, ["grad", "abc"], jnp.zeros((8, 2))))
    assert _program_cache.program_key(sys, ["grad", "abc"], xs) is None  # cache off: no key


def test_corrupt_program_files_are_ignored_and_rewritten(tmp_path):
    spec = "unicycle_polar:range_known"
    with compile_cache(tmp_path):
        first = uj.analyze(zoo_system(*spec.split(':')), samples=128)
        files = _programs(tmp_path)
        for f in files:
            f.write_bytes(b"not a program")
        second = uj.analyze(zoo_system(*spec.split(':')), samples=128)
        assert all(f.read_bytes() != b"not a program" for f in files)
    _same_report(first, second)


def test_a_loaded_program_that_fails_to_run_is_dropped_and_rebuilt(tmp_path):
    calls = []

    def broken(*args):
        raise jax.errors.JaxRuntimeError("NOT_FOUND: Function fusion not found")

    def rebuild():
        calls.append(1)
        return lambda x: x + 1.0

    with compile_cache(tmp_path):
        path = tmp_path / _program_cache.SUBDIR / "k.prog"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"{}\n")
        loaded = _program_cache._Loaded(broken, "k", rebuild)
        assert loaded(1.0) == 2.0 and loaded(2.0) == 3.0
    assert calls == [1] and not path.exists()


def test_no_cache_no_files(tmp_path, monkeypatch):
    monkeypatch.setenv("UIO_JAX_CACHE_DIR", str(tmp_path))
    assert _program_cache.program_dir() is None  # the library leaves JAX's settings alone
    uj.analyze(_system(1.0, name="nocache"), samples=64)
    assert not (tmp_path / _program_cache.SUBDIR).exists()


def test_programs_over_the_memory_budget_run_in_batches(monkeypatch):
    """A program whose temporaries exceed the budget is rebuilt over batches of samples
    (``lax.map``): same numbers, bounded memory."""
    normal = uj.analyze(zoo_system("unicycle_polar", "range_v_unknown"), samples=64)
    batches = []
    real = _program_cache._trace
    monkeypatch.setattr(_program_cache, "_trace", lambda make, batch, xs, of: batches.append(batch)
                        or real(make, batch, xs, of))
    monkeypatch.setattr(_program_cache, "MEMORY_BUDGET", 1)  # every program is over it
    batched = uj.analyze(zoo_system("unicycle_polar", "range_v_unknown"), samples=64)
    assert any(b is not None and b < 64 for b in batches)
    _same_report(normal, batched)


def test_facts_of_a_program_rebuilt_in_batches_describe_the_whole_program(monkeypatch):
    """The facts ``options_for`` measures on the trace (per-sample sizes) come from the
    trace over all samples, not from the batched rebuild (whose arrays are a batch long)."""
    xs = jnp.linspace(0.0, 1.0, 64)[:, None] * jnp.ones((1, 8))

    def fn(x):  # has XLA temporaries (an outer product), so the budget can be exceeded
        return jnp.sin(jnp.outer(x, x)).sum(axis=0)

    make = lambda batch: _program_cache.vmapped(fn, batch)  # noqa: E731

    def sizes(traced):
        eqns, elements = jaxpr_sizes(traced.jaxpr.jaxpr)
        return eqns, None, {"elements": elements / eqns}

    _, whole = _program_cache.compile_program(None, [""], make, xs, sizes)
    monkeypatch.setattr(_program_cache, "MEMORY_BUDGET", 1)  # every program is over it
    batches = []
    real = _program_cache._trace
    monkeypatch.setattr(_program_cache, "_trace", lambda make, batch, xs, of: batches.append(batch)
                        or real(make, batch, xs, of))
    compiled, rebuilt = _program_cache.compile_program(None, [""], make, xs, sizes)
    assert batches[0] is None and batches[-1] is not None and batches[-1] < 64
    assert rebuilt.facts == whole.facts
    x = np.asarray(xs)
    expected = np.sin(x[:, :, None] * x[:, None, :]).sum(axis=1)
    np.testing.assert_allclose(np.asarray(compiled(xs)), expected, rtol=1e-12)


def test_xla_options_the_backend_does_not_know_fall_back_to_its_defaults():
    """Options are a speed choice (e.g. the EORC blocks' emitters): an XLA that lacks one
    compiles with its defaults instead of failing; other compile errors still raise."""
    xs = jnp.linspace(0.0, 1.0, 8, dtype=jnp.float32)[:, None]
    make = lambda batch: _program_cache.vmapped(lambda x: jnp.sin(x) * 2.0, batch)  # noqa: E731
    unknown = lambda traced: (0, {"xla_no_such_option_for_uio_jax": True})  # noqa: E731
    compiled, _ = _program_cache.compile_program(None, [""], make, xs, unknown)
    np.testing.assert_allclose(np.asarray(compiled(xs)), 2.0 * np.sin(np.asarray(xs)), rtol=1e-6)
    with pytest.raises(Exception, match="not a valid bool"):
        bad = lambda traced: (0, {"xla_cpu_use_fusion_emitters": "not a boolean"})  # noqa: E731
        _program_cache.compile_program(None, [""], make, xs, bad)
