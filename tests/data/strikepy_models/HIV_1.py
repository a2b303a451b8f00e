# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "HIV_1".
# HIV model with constant parameters: Miao, Xia, Perelson & Wu, "On identifiability of nonlinear
# ODE models and applications in viral dynamics", SIAM Review 53(1), 2011. x1 and x4 measured.
import sympy as sym

x1, x2, x3, x4 = sym.symbols("x1 x2 x3 x4")
b, c, d, q1, q2, k1, k2, w1, w2, s = sym.symbols("b c d q1 q2 k1 k2 w1 w2 s")

x = [[x1], [x2], [x3], [x4]]
h = [[x1], [x4]]
u = []
w = []
p = [[b], [c], [d], [q1], [q2], [k1], [k2], [w1], [w2], [s]]
f = [
    [-b * x1 * x4 - d * x1 + s],
    [b * q1 * x1 * x4 - k1 * x2 - w1 * x2],
    [b * q2 * x1 * x4 + k1 * x2 - w2 * x3],
    [-c * x4 + k2 * x3],
]

variables_locales = locals().copy()
