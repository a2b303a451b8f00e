# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "SIWR".
# SIWR cholera model (susceptible, infected, water, recovered): k I and S + R + I measured,
# no input.
import sympy as sym

S, I, W, R = sym.symbols("S I W R")
bi, gam, mu, bw, k, xi, a = sym.symbols("bi gam mu bw k xi a")

x = [[S], [I], [W], [R]]
h = [[k * I], [S + R + I]]
u = []
w = []
p = [[bi], [gam], [mu], [bw], [k], [xi], [a]]
f = [
    [-bi * S * I - S * mu - S * bw * W + R * a + mu],
    [bi * S * I - gam * I + S * bw * W - mu * I],
    [xi * I - xi * W],
    [gam * I - R * mu - R * a],
]

variables_locales = locals().copy()
