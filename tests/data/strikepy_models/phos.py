# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "phos".
# Phosphorylation/dephosphorylation cycle: six species, x2 and x3 measured, no input.
import sympy as sym

x1, x2, x3, x4, x5, x6 = sym.symbols("x1 x2 x3 x4 x5 x6")
k1, k2, k3, k4, k5, k6 = sym.symbols("k1 k2 k3 k4 k5 k6")

x = [[x1], [x2], [x3], [x4], [x5], [x6]]
h = [[x2], [x3]]
u = []
w = []
p = [[k1], [k2], [k3], [k4], [k5], [k6]]
f = [
    [k4 * x6 + k2 * x4 - k1 * x1 * x2],
    [k3 * x4 + k2 * x4 + k1 * x1 * x2],
    [k5 * x6 + k3 * x4 - k6 * x5 * x3],
    [-k3 * x4 - k2 * x4 + k1 * x1 * x2],
    [k5 * x6 + k4 * x6 - k6 * x5 * x3],
    [-k5 * x6 - k4 * x6 + k6 * x5 * x3],
]

variables_locales = locals().copy()
