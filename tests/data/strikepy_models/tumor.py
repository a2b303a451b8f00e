# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "tumor".
# Tumour-targeting model with five compartments, x5 measured, no input; a, b, d are known
# constants.
import sympy as sym

x1, x2, x3, x4, x5 = sym.symbols("x1 x2 x3 x4 x5")
k3, k4, k5, k6, k7 = sym.symbols("k3 k4 k5 k6 k7")
a, b, d = sym.symbols("a b d")

x = [[x1], [x2], [x3], [x4], [x5]]
h = [x5]
u = []
w = []
p = [[k3], [k4], [k5], [k6], [k7]]
f = [
    [-(k3 + k7) * x1 + k4 * x2],
    [k3 * x1 - (k4 + a * k5 + b * d * k5) * x2 + k6 * x3 + k6 * x4 + k5 * x2 * x3 + k5 * x2 * x4],
    [a * k5 * x2 - k6 * x3 - k5 * x2 * x4],
    [b * d * k5 * x2 - k6 * x4 - k5 * x2 * x4],
    [k7 * x1],
]

variables_locales = locals().copy()
