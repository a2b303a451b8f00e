# Re-typed for uio_jax's tests (not a copy; see README.md): StrikePy 1.0 model "BIG_known_input".
# beta-IG model of Topp et al., J. Theor. Biol. 2000 (Karin et al., Mol. Syst. Biol. 2016), as
# analysed by Massonis, Banga & Villaverde (2020), with a known input.
import sympy as sym

G, beta, I = sym.symbols("G beta I")
inputs = sym.Symbol("inputs")
p1, si, gamma, c, alpha = sym.symbols("p1 si gamma c alpha")

x = [[G], [beta], [I]]
h = [G]
u = [inputs]
p = [[p1], [si], [gamma], [c], [alpha]]

muplus = 0.021 / (24 * 60)  # known constants: turnover of functional mass
muminus = 0.025 / (24 * 60)
rhoG = G**2 / (alpha**2 + G**2)
lambdaplus = muplus / (1 + (8.4 / G) ** 1.7)
lambdaminus = muminus / (1 + (G / 4.8) ** 8.5)

f = [[inputs - (c + si * I) * G], [beta * (lambdaplus - lambdaminus)], [p1 * beta * rhoG - gamma * I]]

variables_locales = locals().copy()
