# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "C2M_2outputs".
# The two-compartment model of C2M.py with both compartments measured.
import sympy as sym

x1, x2, x3, x4, x5, x6 = sym.symbols("x1 x2 x3 x4 x5 x6")
u1 = sym.Symbol("u1")

x = [[x1], [x2]]
h = [x1, x2]
u = [u1]
p = [[x3], [x4], [x5], [x6]]
f = [[-(x3 + x4) * x1 + x5 * x2 + x6 * u1], [x4 * x1 - x5 * x2]]

variables_locales = locals().copy()
