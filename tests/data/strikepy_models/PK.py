# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "PK".
# Four-compartment pharmacokinetic model, dose u1 into compartment 1, compartments 2 and 3
# measured with unknown gains s2, s3.
import sympy as sym

x1, x2, x3, x4 = sym.symbols("x1 x2 x3 x4")
k1, k2, k3, k4, k5, k6, k7, s2, s3 = sym.symbols("k1 k2 k3 k4 k5 k6 k7 s2 s3")
u1 = sym.Symbol("u1")

x = [[x1], [x2], [x3], [x4]]
h = [[s2 * x2], [s3 * x3]]
u = [u1]
w = []
p = [[k1], [k2], [k3], [k4], [k5], [k6], [k7], [s2], [s3]]
f = [
    [u1 - (k1 + k2) * x1],
    [k1 * x1 - (k3 + k6 + k7) * x2 + k5 * x4],
    [k2 * x1 + k3 * x2 - k4 * x3],
    [k6 * x2 - k5 * x4],
]

variables_locales = locals().copy()
