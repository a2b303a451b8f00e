"""Option ranges up front: seeds, every analysis option, the memory estimate, the fast fallback,
the compilation cache's default directory."""

import functools
import glob
import math
import os
import re
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import ROOT, zoo_system

import uio_jax as uj
from uio_jax._analysis.decisions import context as context_module
from uio_jax._analysis.decisions import memory
from uio_jax._analysis.decisions.rank import Codistribution
from uio_jax._analysis.options import check_options, check_seed
from uio_jax._analysis.recursions.eorc import check_eorc_memory, default_k_max, extended_system
from uio_jax._filter import compile_cache

SMALL = dict(samples=64)


zoo = functools.cache(zoo_system)


@functools.cache
def polar():
    """One System for every test (its compiled programs are kept with it)."""
    return zoo_system("unicycle_polar", "range_v_unknown")


@functools.cache
def polar_known():
    """The ORC's quick case: dim 2 of 3."""
    return zoo_system("unicycle_polar", "range_known")


# ---------------------------------------------------------------------------- seeds
@pytest.mark.parametrize("seed", [0, 1, 2**63 - 1, 2**63, 2**64 - 1, np.uint64(2**64 - 1), np.int8(3)])
def test_seeds_in_range_are_taken(seed):
    assert check_seed(seed) == int(seed) and type(check_seed(seed)) is int


@pytest.mark.parametrize("seed", [-1, 2**64, 2**100, True, 1.0, "3", None])
def test_seeds_out_of_range_are_one_line_option_errors(seed):
    with pytest.raises(uj.OptionError, match=r"^seed must be a non-negative integer below 2\*\*64") as e:
        check_seed(seed)
    assert "\n" not in str(e.value)
    with pytest.raises(uj.OptionError, match="below 2\\*\\*64"):
        uj.analyze(polar(), seed=seed, **SMALL)


def test_a_uint64_key_is_the_int_key():
    """analyze hands seeds >= 2**63 to jax.random.key as uint64: the same key below 2**63."""
    with jax.enable_x64(True):
        for s in (0, 7, 2**40 + 3, 2**63 - 1):
            a = jax.random.key_data(jax.random.key(s))
            b = jax.random.key_data(jax.random.key(np.uint64(s)))
            assert np.array_equal(a, b)
        top = jax.random.key_data(jax.random.key(np.uint64(2**64 - 1)))
        assert np.array_equal(top, [2**32 - 1, 2**32 - 1])


def test_large_seeds_analyse():
    """Seeds from 2**63 (where JAX's int64 conversion overflowed) to the last one."""
    low, top = (uj.analyze(polar_known(), seed=seed, **SMALL) for seed in (2**63, 2**64 - 1))
    assert low.dim == top.dim == 2 and low.dims == top.dims


# ---------------------------------------------------------------------------- every other range
@pytest.mark.parametrize("options, message", [
    (dict(samples=7), "samples must be an integer >= 8"),
    (dict(samples=64.0), "samples must be an integer >= 8"),
    (dict(samples=True), "samples must be an integer >= 8"),
    (dict(rtol=math.nan), r"rtol must be a number in \(0, 1\)"),
    (dict(rtol=math.inf), r"rtol must be a number in \(0, 1\)"),
    (dict(rtol=0.0), r"rtol must be a number in \(0, 1\)"),
    (dict(rtol=1.0), r"rtol must be a number in \(0, 1\)"),
    (dict(rtol=True), r"rtol must be a number in \(0, 1\)"),
    (dict(max_order=-1), "max_order must be a non-negative integer"),
    (dict(max_order=1.5), "max_order must be a non-negative integer"),
    (dict(k_max=0), "k_max must be a positive integer"),
    (dict(k_max=math.inf), "k_max must be a positive integer"),
    (dict(method="quick"), "unknown method 'quick'"),
])
def test_option_ranges(options, message):
    with pytest.raises(uj.OptionError, match=message) as e:
        check_options(**options)
    assert "\n" not in str(e.value)
    with pytest.raises(uj.OptionError, match=message):
        uj.analyze(polar(), **{**SMALL, **options})


def test_checked_options_are_python_numbers():
    opts = check_options(max_order=np.int64(2), k_max=np.int32(4), seed=np.uint64(2**63))
    assert (opts["max_order"], opts["k_max"], opts["seed"]) == (2, 4, 2**63)
    assert all(type(opts[k]) is int for k in ("max_order", "k_max", "seed"))


# ---------------------------------------------------------------------------- memory
@pytest.mark.parametrize("text, size", [
    ("123", 123), ("4G", 4 * 2**30), ("4g", 4 * 2**30), ("512M", 512 * 2**20), ("1.5T", int(1.5 * 2**40)),
    ("2GiB", 2 * 2**30), ("64KB", 64 * 1024), (" 8G ", 8 * 2**30), ("1e9", 10**9),
])
def test_parse_size(text, size):
    assert memory.parse_size(text) == size


@pytest.mark.parametrize("text", ["", "lots", "4X", "-1G", "0", "nan", "inf", "4 G B"])
def test_parse_size_refuses(text):
    with pytest.raises(uj.OptionError, match="UIO_JAX_MEMORY_LIMIT must be a positive size"):
        memory.parse_size(text)


def test_memory_limit_default_and_override(monkeypatch):
    monkeypatch.delenv(memory.ENV, raising=False)
    limit, source = memory.memory_limit()
    phys = memory.physical_memory()
    assert limit == (int(0.5 * phys) if phys else memory.FALLBACK_LIMIT)
    assert "UIO_JAX_MEMORY_LIMIT overrides" in source
    monkeypatch.setenv(memory.ENV, "3G")
    assert memory.memory_limit() == (3 * 2**30, "UIO_JAX_MEMORY_LIMIT=3G")
    monkeypatch.setenv(memory.ENV, "a lot")
    with pytest.raises(uj.OptionError, match="UIO_JAX_MEMORY_LIMIT"):
        uj.analyze(polar(), **SMALL)


def test_the_estimate_is_the_arrays_the_analysis_allocates():
    """Each term of analysis_bytes is the size of the array it names, in the real classes."""
    sys = polar()
    S = 64
    ctx = context_module.Context(sys, S, 0, 1e-8)
    parts = memory.analysis_bytes(S, sys.n)
    assert parts["the sampled states"] == np.asarray(ctx.xs).nbytes
    ctx.codist._reserve(sys.n)  # the basis at full rank (rows are allocated as the span grows)
    assert parts["the rank basis"] == ctx.codist.basis.nbytes
    tested = ctx.codist.test_units(sys.n)  # cands and dirs (and two residuals of their size)
    assert parts["the unit-covector test"] == 2 * (tested.cands.nbytes + tested.dirs.nbytes)
    # the EORC on Sigma^(K): N = n + K m_w coordinates
    gps = zoo("gps", "inputs_unknown")
    ext = extended_system(gps, 7)
    assert ext.n == gps.n + 7 * len(gps.unknown)
    # every order tests the unit covectors of all its coordinates (the observable inputs too)
    assert check_eorc_memory(gps, S, 7) == sum(memory.analysis_bytes(S, ext.n, ext.n).values())
    full = Codistribution(ext.n, S, np.ones(ext.n), 1e-8)
    full._reserve(ext.n)
    assert full.basis.nbytes == memory.analysis_bytes(S, ext.n)["the rank basis"]
    # past the certificate's cap, the rank arrays span fewer samples than were drawn
    big = 10**6
    cap = memory.certify_samples(big, ext.n)
    assert memory.DECISION_SAMPLES <= cap < big
    assert memory.analysis_bytes(big, ext.n)["the rank basis"] == 8 * cap * ext.n**2
    assert memory.analysis_bytes(big, ext.n)["the sampled states"] == 8 * big * ext.n


class _Reached(Exception):
    """Raised in place of the first array of an analysis."""


@pytest.fixture
def no_allocation(monkeypatch):
    """Any Context or Codistribution (the first arrays of any analysis) fails the test."""
    def refuse(*args, **kwargs):
        raise _Reached

    monkeypatch.setattr(context_module.Context, "__init__", refuse)
    monkeypatch.setattr(Codistribution, "__init__", refuse)


def _zoo_systems():
    out = []
    for path in sorted(glob.glob(os.path.join(ROOT, "systems", "*.py"))):
        for name in re.findall(r"^def ([a-z]\w*)\(\)", Path(path).read_text(), re.M):
            try:
                sys = uj.load_system(f"{path}:{name}")
            except uj.UioJaxError:
                continue
            if isinstance(sys, uj.System):
                out.append((f"{os.path.basename(path)}:{name}", sys))
    for path in sorted(glob.glob(os.path.join(ROOT, "systems", "*.toml"))):
        out.append((os.path.basename(path), uj.load_system(path)))
    return out


def _reaches_its_arrays(systems):
    """Every System at the default options passes the check and gets to its first array
    (which the fixture turns into _Reached), with a 1 GB limit."""
    for label, sys in systems:
        for method in ("auto", "fast"):
            with pytest.raises(_Reached):
                uj.analyze(sys, method=method)


def test_zoo_models_are_not_refused(monkeypatch, no_allocation):
    """The EORC of the zoo's two-input model and the 7-state vehicle (single_ui); every zoo
    model: the slow test below."""
    monkeypatch.setenv(memory.ENV, "1G")
    _reaches_its_arrays([("gps", zoo("gps", "inputs_unknown")),
                         ("vehicle", zoo("vehicle_wind", "wind_unknown"))])


@pytest.mark.slow
def test_no_zoo_model_is_refused_at_the_defaults(monkeypatch, no_allocation):
    monkeypatch.setenv(memory.ENV, "1G")
    models = _zoo_systems()
    assert len(models) >= 20
    _reaches_its_arrays(models)


@pytest.mark.parametrize("options, words", [
    (dict(samples=10**9), ["samples=1000000000 x 3 states", "lower samples", "the limit is 8.6 GB",
                           "UIO_JAX_MEMORY_LIMIT=8G"]),
    (dict(samples=10**9, method="orc"), ["samples=1000000000 x 3 states"]),
])
def test_huge_samples_are_refused_before_allocating(monkeypatch, no_allocation, options, words):
    monkeypatch.setenv(memory.ENV, "8G")
    sys = zoo_system("unicycle_polar", "range_known")
    with pytest.raises(uj.OptionError) as e:
        uj.analyze(sys, **options)
    msg = str(e.value)
    assert "\n" not in msg and all(w in msg for w in words), msg
    # 8 N (S + S' (N + 4 n)) with S = 1e9, N = n = 3: the sampled states alone are 24 GB (the
    # rank arrays span the certificate's capped samples S')
    total = memory.format_bytes(sum(memory.analysis_bytes(10**9, 3).values()))
    assert f"needs about {total} (the sampled states alone: 24.0 GB)" in msg


def test_huge_k_max_is_refused_before_allocating(monkeypatch, no_allocation):
    monkeypatch.setenv(memory.ENV, "1G")
    gps = zoo("gps", "inputs_unknown")  # two unknown inputs
    with pytest.raises(uj.OptionError) as e:
        uj.analyze(gps, k_max=1000, method="eorc")
    msg = str(e.value)
    N = gps.n + 1000 * len(gps.unknown)
    assert f"the EORC to k_max=1000 (samples=4096 x N={N} coordinates" in msg
    assert f"lower k_max (default {default_k_max(gps)})" in msg and "unit-covector test alone" in msg
    with pytest.raises(uj.OptionError, match="lower samples and k_max"):
        uj.analyze(gps, k_max=1000, samples=10**9, method="eorc")
    with pytest.raises(uj.OptionError, match="lower samples$"):
        uj.analyze(gps, samples=10**9, method="eorc")
    # the EORC chosen by name, on a one-input model, is checked the same way
    with pytest.raises(uj.OptionError, match="k_max=1000"):
        uj.analyze(polar(), method="eorc", k_max=1000)


def test_a_low_limit_refuses_a_normal_run_and_a_normal_limit_does_not(monkeypatch):
    monkeypatch.setenv(memory.ENV, "1K")
    with pytest.raises(uj.OptionError, match=r"samples=64 x 3 states needs about .*UIO_JAX_MEMORY_LIMIT=1K"):
        uj.analyze(polar_known(), **SMALL)
    monkeypatch.setenv(memory.ENV, "1G")
    assert uj.analyze(polar_known(), **SMALL).dim == 2


# ---------------------------------------------------------------------------- fast
def sort_system(explicit=False):
    """``y = sort(x)[0]``, which is ``x_0`` on the domain (a < b), and ``u`` along ``[b, 0]``."""
    first = (lambda x: x[0]) if explicit else (lambda x: jax.lax.sort(x)[0])
    return uj.System(states=("a", "b"), outputs={"y": first},
                     known={"u": lambda x: jnp.stack([x[1], 0.0 * x[0]])},
                     domain={"a": (0.5, 1.0), "b": (2.0, 3.0)})


def test_a_primitive_without_a_graph_rule_is_refused_in_one_line():
    """The expression graph is the only evaluator: ``lax.sort`` is refused where the System
    is built, in one line naming the function and the primitive."""
    with pytest.raises(uj.ModelError) as info:
        sort_system()
    msg = str(info.value)
    assert msg.startswith("output 'y': the expression graph has no rule for the JAX primitive 'sort'")
    assert "(supported: " in msg and "\n" not in msg


def test_fast_without_the_fallback_is_the_series():
    rep = uj.analyze(sort_system(explicit=True), method="fast", samples=16)
    assert rep.method == "series" and rep.dim == 2
    assert not any("-> ORC" in note for note in rep.notes)


# ---------------------------------------------------------------------------- cache directory
def test_default_cache_dir_rule(monkeypatch, tmp_path):
    monkeypatch.setenv("UIO_JAX_CACHE_DIR", str(tmp_path / "mine"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert compile_cache.default_cache_dir() == str(tmp_path / "mine")
    monkeypatch.setenv("UIO_JAX_CACHE_DIR", "")
    assert compile_cache.default_cache_dir() == str(tmp_path / "xdg" / "uio_jax" / "xla")
    monkeypatch.delenv("UIO_JAX_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", "")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert compile_cache.default_cache_dir() == str(tmp_path / "home" / ".cache" / "uio_jax" / "xla")
    for words in ("$UIO_JAX_CACHE_DIR", "$XDG_CACHE_HOME/uio_jax/xla", "~/.cache/uio_jax/xla"):
        assert words in compile_cache.DEFAULT_DIR_RULE


def test_an_analysis_that_outgrows_the_memory_limit_stops_in_one_line(monkeypatch):
    """The arrays' estimate before a run cannot see the expression graph of deep derivatives
    (a 100-variable chain grew past 16 GB): the run is stopped when the process passes the
    limit, with one line naming where it was (issue 40: no guard covered that path)."""
    monkeypatch.setenv(memory.ENV, "1G")
    monkeypatch.setattr(memory, "resident_bytes", lambda: 2 * 2**30)
    with pytest.raises(uj.OptionError, match=r"grew to 2\.1 GB resident at rank 0 of 7 .* past the limit 1\.1 GB"):
        uj.analyze(zoo("vehicle_wind", "no_wind"))
