"""Quaternion helpers shared by the visual-inertial zoo files (not a zoo file: its name
starts with ``_``, so discovery skips it; the zoo files load it by path)."""

import jax.numpy as jnp


def rotation_columns(q):
    """Columns of the rotation local -> global, homogeneous (quadratic) in q: three (3,) arrays.

    ``R(q) = |q|^2 R(q / |q|)``: for a unit quaternion the usual rotation matrix.
    """
    qt, qx, qy, qz = q[0], q[1], q[2], q[3]
    c1 = jnp.stack([qt**2 + qx**2 - qy**2 - qz**2, 2 * (qx * qy + qt * qz), 2 * (qx * qz - qt * qy)])
    c2 = jnp.stack([2 * (qx * qy - qt * qz), qt**2 - qx**2 + qy**2 - qz**2, 2 * (qy * qz + qt * qx)])
    c3 = jnp.stack([2 * (qx * qz + qt * qy), 2 * (qy * qz - qt * qx), qt**2 - qx**2 - qy**2 + qz**2])
    return c1, c2, c3


def right_pure(q, i):
    """``q * [0, e_i]`` (quaternion product with a pure unit quaternion on the right), (4,)."""
    qt, qx, qy, qz = q[0], q[1], q[2], q[3]
    return [jnp.stack([-qx, qt, qz, -qy]), jnp.stack([-qy, -qz, qt, qx]),
            jnp.stack([-qz, qy, -qx, qt])][i]
