# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "Bolie".
# J.W. Bolie, "Coefficients of normal blood glucose regulation", J. Appl. Physiol. 16(5), 1961.
import sympy as sym

q1, q2 = sym.symbols("q1 q2")
delta = sym.Symbol("delta")
p1, p2, p3, p4, Vp = sym.symbols("p1 p2 p3 p4 Vp")

x = [[q1], [q2]]
h = [q1 / Vp]
u = [delta]
p = [[p1], [p2], [p3], [p4], [Vp]]
f = [[p1 * q1 - p2 * q2 + delta], [p3 * q2 + p4 * q1]]

variables_locales = locals().copy()
