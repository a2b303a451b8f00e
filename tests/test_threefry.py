"""The unrolled threefry of uio_jax._engine.threefry gives jax.random's numbers bit for bit."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from uio_jax._engine import threefry

SEEDS = [0, 1, 12345, 2**31 + 7, 2**32 - 1, 2**40 + 3]
DATA = [0, 1, 77, 4095, 2**31, 2**32 - 1]


def _jax_key(seed):
    with jax.enable_x64(True):  # seeds above 2**31 need a 64-bit integer
        return jax.random.key(seed)


@pytest.mark.parametrize("seed", SEEDS)
def test_seed_key_is_jax_key_data(seed):
    np.testing.assert_array_equal(threefry.seed_key(seed), jax.random.key_data(_jax_key(seed)))


@pytest.mark.parametrize("seed", [-1, 2**64])
def test_seed_key_outside_64_bits_is_refused(seed):
    with pytest.raises(ValueError, match="2\\*\\*64"):
        threefry.seed_key(seed)


@pytest.mark.parametrize("seed", SEEDS)
def test_fold_in_split_bits_normal_equal_jax_random(seed):
    key = _jax_key(seed)
    raw = jnp.asarray(threefry.seed_key(seed))
    for data in DATA:
        k = jax.random.fold_in(key, data)
        r = threefry.fold_in(raw, data)
        np.testing.assert_array_equal(r, jax.random.key_data(k))
        np.testing.assert_array_equal(threefry.split(r), jax.random.key_data(jax.random.split(k)))
        np.testing.assert_array_equal(threefry.split(r, 5),
                                      jax.random.key_data(jax.random.split(k, 5)))
        for n in (1, 6, 301):
            np.testing.assert_array_equal(threefry.bits(r, n),
                                          jax.random.bits(k, (n,), jnp.uint32))
            np.testing.assert_array_equal(threefry.normal(r, n),
                                          jax.random.normal(k, (n,), jnp.float32))


def test_batched_and_traced_draws_equal_jax_random():
    """Under jit and vmap, with a traced fold-in counter, as the Monte Carlo run uses them."""
    ids = jnp.arange(200, dtype=jnp.uint32)
    key = jax.random.key(3)

    @jax.jit
    def ours(ids, root, j):
        return jax.vmap(lambda i: threefry.normal(threefry.fold_in(threefry.fold_in(root, i), j),
                                                  97))(ids)

    @jax.jit
    def theirs(ids, root, j):
        return jax.vmap(lambda i: jax.random.normal(jax.random.fold_in(jax.random.fold_in(root, i), j),
                                                    (97,), jnp.float32))(ids)

    j = jnp.asarray(11, jnp.int32)
    got = ours(ids, jnp.asarray(threefry.seed_key(3)), j)
    np.testing.assert_array_equal(got, theirs(ids, key, j))
    # and the normals are normals: mean 0, variance 1 over 19 400 draws
    assert abs(float(got.mean())) < 0.03 and abs(float(got.var()) - 1) < 0.05
