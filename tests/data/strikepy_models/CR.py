# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "CR".
# One state, no input: second-order decay observed through a saturating sensor.
import sympy as sym

x1 = sym.Symbol("x1")
k, s1, s2 = sym.symbols("k s1 s2")

x = [x1]
h = [s1 * x1 / (1 + s2 * x1)]
p = [[k], [s1], [s2]]
f = [-2 * x1 * x1 * k]

variables_locales = locals().copy()
