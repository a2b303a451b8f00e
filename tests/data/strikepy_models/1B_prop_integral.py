# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "1B_prop_integral".
# Hormonal circuit with proportional-integral feedback: Karin et al., Mol. Syst. Biol. 2016;
# Fig. 1B of Villaverde & Banga, arXiv:1701.02562. x10 and u0 are known constants.
import sympy as sym

x1, x2, x3, x10 = sym.symbols("x1 x2 x3 x10")
uu, u0 = sym.symbols("uu u0")
p1, p2 = sym.symbols("p1 p2")

x = [[x1], [x2], [x3]]
h = [x1]
u = [uu]
p = [[p1], [p2]]
f = [[u0 + uu - p2 * x3 - p1 * x2], [x1 - x10], [x1 - x3]]

variables_locales = locals().copy()
