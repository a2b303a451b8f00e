"""The Vi-SfM with partial input knowledge (004 section 11.2.2) in several formulations: at
which EORC order each reaches its final verdict.

The paper gives, for its uncalibrated cases, the verdicts at order k = 2 (case 3, two
accelerometers: the full IMU's properties; case 2, one accelerometer: one unobservable vector
besides them, the rotation about the accelerometer axis, "for every k >= 2"). Its state is not
given, so this script tries the formulations below, each with no bias and, but for
``global_offset``, the camera centre at the accelerometers' origin, for one and two known
accelerometers (the gyroscopes and the other accelerometers unknown) and the full IMU:

* ``global``: ``systems/visual_inertial_no_offset.py`` (``[r, v, q, q_c, F_2..F_nf]``, origin
  at feature 1, gravity known);
* ``global_g``: the same with the gravity magnitude ``g`` an unknown constant state;
* ``global_offset``: ``global`` with the camera centre at an unknown point ``P`` of the
  accelerometer frame (a constant state: the full 6-DOF camera-accelerometer calibration);
* ``local_q``: the features and the speed in the accelerometer frame, the attitude ``q`` kept
  for the direction of gravity (``[F_1^b..F_nf^b, V^b, q, q_c]``, gravity known; same ``n``);
* ``local_G``: the gravity vector in the accelerometer frame instead of ``q``
  (``[F^b, V^b, G^b, q_c]``), its magnitude unknown; ``local_G_known``: ``|G|^2`` measured.

Each System declares its symmetries (the yaw where the yaw is a state, the internal rotation
with one accelerometer), which the analysis verifies exactly; a final dimension equal to their
bound is then exact. Prints one line per (formulation, features, case): the dims per order,
the first order at the final dimension, and whether the verdict is exact.

    python scripts/visfm_formulations.py [--features 3 4 5] [--k-max 6] [--samples 256]
"""

import argparse
import importlib.util
import os
import sys
import time

import jax.numpy as jnp

import uio_jax as uj

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FORMULATIONS = ("global", "global_g", "global_offset", "local_q", "local_G", "local_G_known")
CASES = {"full_imu": 3, "two_acc": 2, "one_acc": 1}


def _zoo():
    path = os.path.join(ROOT, "systems", "visual_inertial_no_offset.py")
    spec = importlib.util.spec_from_file_location("zoo_visual_inertial_no_offset", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


Z = _zoo()


def _inputs(fields, n_known):
    """Split the six IMU fields: ``A_1..A_{n_known}`` known (all six for ``n_known = 3``)."""
    names = [f"A_{i + 1}" for i in range(n_known)] + ([f"omega_{i + 1}" for i in range(3)] if n_known == 3 else [])
    return {k: fields[k] for k in names}, {k: f for k, f in fields.items() if k not in names}


def global_g(n_f, n_known):
    """``global`` with ``g`` an unknown constant (the last state): ``v' = R(q) A - g e_z``."""
    base = getattr(Z, {3: "full_imu", 2: "two_acc", 1: "one_acc"}[n_known])(n_f)
    n = base.n + 1

    def lift(f):
        return lambda x: jnp.concatenate([f(x[:-1]), jnp.zeros(1)])

    def drift(x):
        return jnp.concatenate([x[3:6], jnp.stack([0.0 * x[0], 0.0 * x[0], -x[-1]]), jnp.zeros(n - 6)])

    known = {k: lift(f) for k, f in base.known.items()}
    unknown = {k: lift(f) for k, f in base.unknown.items()}
    outputs = {k: (lambda x, h=h: h(x[:-1])) for k, h in base.outputs.items()}
    symmetries = {k: lift(s) for k, s in base.symmetries.items()}
    domain = {**dict(base.domain), "g": (9.0, 10.5)}
    return uj.System((*base.states, "g"), outputs, known=known, unknown=unknown, drift=drift,
                     domain=domain, symmetries=symmetries, name=f"global_g:{n_known}")


def global_offset(n_f, n_known):
    """``global`` with the camera at ``P`` (the last three states, accelerometer frame):
    ``F_j^c = R(q_c)^T (R(q)^T (F_j - r) - P)``."""
    base = getattr(Z, {3: "full_imu", 2: "two_acc", 1: "one_acc"}[n_known])(n_f)

    def lift(f):
        return lambda x: jnp.concatenate([f(x[:-3]), jnp.zeros(3)])

    outputs = {}
    for j in range(n_f):
        def cam(x, j=j):
            q, qc, f = x[6:10], x[10:14], Z.features(x[:-3])[j]
            return Z.transpose_times(qc, Z.transpose_times(q, f - x[0:3]) - x[-3:])
        outputs[f"u{j + 1}"] = lambda x, cam=cam: cam(x)[0] / cam(x)[2]
        outputs[f"v{j + 1}"] = lambda x, cam=cam: cam(x)[1] / cam(x)[2]
    outputs["q_norm"] = lambda x: jnp.sum(x[6:10] ** 2)
    outputs["qc_norm"] = lambda x: jnp.sum(x[10:14] ** 2)
    symmetries = {"yaw_symmetry": lift(Z.yaw_symmetry)}
    if n_known == 1:  # the lever arm turns with the accelerometer frame
        symmetries["internal_rotation"] = lambda x: jnp.concatenate(
            [Z.internal_rotation(x[:-3]), _turn(x[-3:].reshape((1, 3)), 0)])
    domain = {**dict(base.domain), "Px": (-0.3, 0.3), "Py": (-0.3, 0.3), "Pz": (-0.3, 0.3)}
    return uj.System((*base.states, "Px", "Py", "Pz"), outputs,
                     known={k: lift(f) for k, f in base.known.items()},
                     unknown={k: lift(f) for k, f in base.unknown.items()}, drift=lift(base.drift),
                     domain=domain, symmetries=symmetries, name=f"global_offset:{n_known}")


def _turn(w, i):
    """``-e_i x w`` for the (k, 3) array ``w`` (a vector of the accelerometer frame under a
    rotation of that frame about its axis ``i``), flattened."""
    e = jnp.broadcast_to(jnp.eye(3)[i], w.shape)
    return -jnp.cross(e, w).reshape(-1)


def local(n_f, n_known, gravity):
    """A local form: ``[F_1^b..F_nf^b, V^b, Q, q_c]`` with ``Q = q`` (``gravity="q"``, g known)
    or ``Q = G^b`` (``"G"``: magnitude unknown; ``"G_known"``: ``|G|^2`` measured)."""
    m = 3 * n_f + 3  # start of Q
    nq = 4 if gravity == "q" else 3
    n = m + nq + 4

    def grav(x):
        return -Z.GRAVITY * Z.transpose_times(x[m:m + 4], jnp.eye(3)[2]) if gravity == "q" else x[m:m + 3]

    def drift(x):
        return jnp.concatenate([jnp.tile(-x[m - 3:m], n_f), grav(x), jnp.zeros(nq + 4)])

    def acc(i):
        return lambda x: jnp.zeros(n).at[m - 3 + i].set(1.0)

    def gyro(i):
        def f(x):
            moved = _turn(x[:m].reshape((-1, 3)), i)
            dq = 0.5 * Z.right_pure(x[m:m + 4], i) if gravity == "q" else _turn(x[m:m + 3].reshape((1, 3)), i)
            return jnp.concatenate([moved, dq, jnp.zeros(4)])
        return f

    fields = {f"A_{i + 1}": acc(i) for i in range(3)}
    fields.update({f"omega_{i + 1}": gyro(i) for i in range(3)})
    known, unknown = _inputs(fields, n_known)
    qc = slice(m + nq, n)
    outputs = {}
    for j in range(n_f):
        def cam(x, j=j):
            return Z.transpose_times(x[qc], x[3 * j:3 * j + 3])
        outputs[f"u{j + 1}"] = lambda x, cam=cam: cam(x)[0] / cam(x)[2]
        outputs[f"v{j + 1}"] = lambda x, cam=cam: cam(x)[1] / cam(x)[2]
    outputs["qc_norm"] = lambda x: jnp.sum(x[qc] ** 2)
    if gravity == "q":
        outputs["q_norm"] = lambda x: jnp.sum(x[m:m + 4] ** 2)
    if gravity == "G_known":
        outputs["G_norm"] = lambda x: jnp.sum(x[m:m + 3] ** 2)
    symmetries = {}
    if gravity == "q":
        symmetries["yaw_symmetry"] = lambda x: jnp.zeros(n).at[m:m + 4].set(0.5 * Z.left_pure(x[m:m + 4], 2))
    if n_known == 1:
        def internal(x):
            body = gyro(0)(x)[:m + nq]  # the accelerometer frame turning about e_1 ...
            return jnp.concatenate([body, -0.5 * Z.left_pure(x[qc], 0)])  # ... the camera not
        symmetries["internal_rotation"] = internal
    return uj.System(tuple(f"x{i}" for i in range(n)), outputs, known=known, unknown=unknown,
                     drift=drift, domain=_local_domain(n_f, gravity), symmetries=symmetries,
                     name=f"local_{gravity}:{n_known}")


def _local_domain(n_f, gravity):
    box = [(-1.0, 1.0), (-1.0, 1.0), (2.0, 4.0)] * n_f + [(-1.0, 1.0)] * 3
    box += [(0.8, 1.2)] + [(-0.15, 0.15)] * 3 if gravity == "q" else [(-3.0, 3.0), (-3.0, 3.0), (-10.5, -8.5)]
    box += [(0.8, 1.2)] + [(-0.15, 0.15)] * 3
    return {f"x{i}": b for i, b in enumerate(box)}


def build(formulation, n_f, case):
    """The System of ``formulation`` (:data:`FORMULATIONS`) for ``case`` (:data:`CASES`)."""
    n_known = CASES[case]
    if formulation == "global":
        return getattr(Z, case)(n_f)
    if formulation == "global_g":
        return global_g(n_f, n_known)
    if formulation == "global_offset":
        return global_offset(n_f, n_known)
    return local(n_f, n_known, formulation[len("local_"):])


def first_order(rep) -> int:
    """The first order (step) whose dimension is the report's final one."""
    return list(rep.dims).index(rep.dim)


def verdict(rep) -> str:
    """``exact`` (:attr:`Report.exact`), ``all observable`` (the EORC proved every state), or
    ``sufficient only``."""
    if rep.exact:
        return "exact"
    return "all observable" if rep.dim == rep.n else "sufficient only"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--features", type=int, nargs="+", default=[3, 4, 5])
    ap.add_argument("--formulations", nargs="+", default=list(FORMULATIONS), choices=FORMULATIONS)
    ap.add_argument("--k-max", type=int, default=6)
    ap.add_argument("--samples", type=int, default=256)
    args = ap.parse_args(argv)
    print("| formulation | features | case | n | dims per order | final dim | first order | verdict | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for formulation in args.formulations:
        for n_f in args.features:
            for case in CASES:
                system = build(formulation, n_f, case)
                t0 = time.perf_counter()
                rep = uj.analyze(system, samples=args.samples, k_max=args.k_max)
                dt = time.perf_counter() - t0
                print(f"| {formulation} | {n_f} | {case} | {system.n} | {list(rep.dims)} | {rep.dim} | "
                      f"{first_order(rep)} | {verdict(rep)} | {dt:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
