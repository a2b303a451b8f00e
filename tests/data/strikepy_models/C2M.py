# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "C2M".
# Two-compartment linear model (Villaverde, Evans, Chappell & Banga, IEEE Control Syst. Lett.
# 3(2), 2019): x3 = k1e, x4 = k12, x5 = k21, x6 = b are the unknown parameters.
import sympy as sym

x1, x2, x3, x4, x5, x6 = sym.symbols("x1 x2 x3 x4 x5 x6")
u1 = sym.Symbol("u1")

x = [[x1], [x2]]
h = [x1]
u = [u1]
w = []
p = [[x3], [x4], [x5], [x6]]
f = [[-(x3 + x4) * x1 + x5 * x2 + x6 * u1], [x4 * x1 - x5 * x2]]

variables_locales = locals().copy()
