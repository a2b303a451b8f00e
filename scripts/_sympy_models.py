"""Sympy versions of the zoo models, written independently of ``systems/`` (for the oracle).

Each model is a :class:`SympyModel`: state symbols, outputs (name -> expression), known and
unknown input fields (name -> column ``sympy.Matrix``), optional drift and the sampling box.
The equations are copied from the papers / the zoo docstrings, not translated from the JAX
code, so the sympy route is an independent check of the zoo as well.

``MODELS`` maps a zoo spec (``"systems/FILE.py:FUNCTION"``) to a function returning the model.
Only sympy is needed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import sympy as sp

#: Same boxes as ``uio_jax`` uses for states without a domain entry / for angles.
DEFAULT_BOX = (0.5, 1.5)
ANGLE_BOX = (-math.pi, math.pi)


@dataclass(frozen=True)
class SympyModel:
    """A control-affine model in sympy.

    Attributes:
        name: zoo spec it mirrors, e.g. ``"vehicle_wind:no_wind"``.
        states: state symbols, in the order of the zoo model.
        outputs: output name -> sympy expression of the states.
        known: known input name -> field (column Matrix of length n).
        unknown: unknown input name -> field.
        drift: optional drift field f0.
        domain: state name -> (lo, hi) box where random points are drawn.
    """

    name: str
    states: tuple
    outputs: dict
    known: dict
    unknown: dict = field(default_factory=dict)
    drift: sp.Matrix | None = None
    domain: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.states)

    def box(self, state) -> tuple[float, float]:
        return self.domain.get(str(state), DEFAULT_BOX)


def _col(*entries):
    return sp.Matrix([sp.sympify(e) for e in entries])


# --------------------------------------------------------------------------------------
# 3D vehicle in wind (seed 002, section III; zoo: systems/vehicle_wind.py)
# --------------------------------------------------------------------------------------

# Attitudes near the identity, so that the feature depth F_z stays away from 0.
_VEH_DOMAIN = {"x": (0.5, 1.5), "y": (0.5, 1.5), "z": (0.5, 1.5),
               "qt": (0.8, 1.2), "qx": (-0.3, 0.3), "qy": (-0.3, 0.3), "qz": (-0.3, 0.3)}


def _vehicle(wind: str) -> SympyModel:
    """wind: "none" (no wind), "known" (wind as a 7th known input) or "unknown"."""
    x, y, z, qt, qx, qy, qz = X = sp.symbols("x y z qt qx qy qz", real=True)
    # Rotation local -> global, homogeneous (quadratic) in q (eq. 6 of 002).
    R = sp.Matrix([
        [qt**2 + qx**2 - qy**2 - qz**2, 2 * (qx * qy - qt * qz), 2 * (qx * qz + qt * qy)],
        [2 * (qx * qy + qt * qz), qt**2 - qx**2 + qy**2 - qz**2, 2 * (qy * qz - qt * qx)],
        [2 * (qx * qz - qt * qy), 2 * (qy * qz + qt * qx), qt**2 - qx**2 - qy**2 + qz**2],
    ])
    half = sp.Rational(1, 2)
    known = {
        # q' = 1/2 q Omega_q (quaternion product with the pure quaternion Omega).
        "Omega_x": _col(0, 0, 0, -half * qx, half * qt, half * qz, -half * qy),
        "Omega_y": _col(0, 0, 0, -half * qy, -half * qz, half * qt, half * qx),
        "Omega_z": _col(0, 0, 0, -half * qz, half * qy, -half * qx, half * qt),
        # r' = q V_q q* : the columns of R.
        "V_x": _col(*R[:, 0], 0, 0, 0, 0),
        "V_y": _col(*R[:, 1], 0, 0, 0, 0),
        "V_z": _col(*R[:, 2], 0, 0, 0, 0),
    }
    wind_field = _col(0, 0, 1, 0, 0, 0, 0)
    # Feature (origin) in the local frame: R^T r, up to sign; camera ratios (eqs. 7-8).
    F = R.T * sp.Matrix([x, y, z])
    outputs = {"h_u": F[0] / F[2], "h_v": F[1] / F[2], "h_const": qt**2 + qx**2 + qy**2 + qz**2}
    unknown = {}
    if wind == "known":
        known["w"] = wind_field
    elif wind == "unknown":
        unknown["w"] = wind_field
    name = {"none": "no_wind", "known": "wind_known", "unknown": "wind_unknown"}[wind]
    return SympyModel(f"vehicle_wind:{name}", tuple(X), outputs, known, unknown,
                      domain=_VEH_DOMAIN)


# --------------------------------------------------------------------------------------
# Unicycle in polar coordinates (seed 004, section 11.1, eq. 35; zoo: unicycle_polar.py)
# --------------------------------------------------------------------------------------

def _unicycle_polar(output: str, unknown: str | None) -> SympyModel:
    r, phi, theta = X = sp.symbols("r phi theta", real=True)
    fields = {"v": _col(sp.cos(theta - phi), sp.sin(theta - phi) / r, 0),
              "omega": _col(0, 0, 1)}
    outputs = {"range": {"r": r}, "bearing": {"theta_minus_phi": theta - phi},
               "phi": {"phi": phi}}[output]
    known = {k: f for k, f in fields.items() if k != unknown}
    unk = {unknown: fields[unknown]} if unknown else {}
    name = f"{output}_{unknown}_unknown" if unknown else f"{output}_known"
    return SympyModel(f"unicycle_polar:{name}", tuple(X), outputs, known, unk,
                      domain={"r": (0.5, 2.0), "phi": ANGLE_BOX, "theta": ANGLE_BOX})


# --------------------------------------------------------------------------------------
# Unicycle with a disturbance along gamma (seed 003, eqs. 2.1 and 4.5; zoo:
# unicycle_disturbance.py)
# --------------------------------------------------------------------------------------

GAMMA = sp.Rational(7, 10) * sp.pi


def _unicycle_disturbance(output: str, disturbance: bool, gamma_known: bool,
                          name: str) -> SympyModel:
    xv, yv, theta = sp.symbols("xv yv theta", real=True)
    states = [xv, yv, theta]
    if gamma_known:
        gamma = GAMMA
    else:
        gamma = sp.Symbol("gamma", real=True)
        states.append(gamma)
    n = len(states)

    def pad(*e):
        return _col(*e, *([0] * (n - 3)))

    outputs = {
        "r2": {"r2": xv**2 + yv**2},
        "tan_beta": {"tan_beta": (yv - xv * sp.tan(theta)) / (xv + yv * sp.tan(theta))},
        "tan_phi": {"tan_phi": yv / xv},
    }[output]
    known = {"v": pad(sp.cos(theta), sp.sin(theta), 0), "omega": pad(0, 0, 1)}
    unknown = {"w": pad(sp.cos(gamma), sp.sin(gamma), 0)} if disturbance else {}
    domain = {"xv": (0.5, 1.5), "yv": (0.5, 1.5), "theta": ANGLE_BOX, "gamma": ANGLE_BOX}
    return SympyModel(f"unicycle_disturbance:{name}", tuple(states), outputs, known, unknown,
                      domain=domain)


# --------------------------------------------------------------------------------------
# Unicycle with a GPS (seed 004 section 11.2.1, eqs. 34, 36; zoo: systems/gps.py)
# --------------------------------------------------------------------------------------

def _gps(unknown: tuple, name: str) -> SympyModel:
    xv, yv, theta = X = sp.symbols("xv yv theta", real=True)
    fields = {"v": _col(sp.cos(theta), sp.sin(theta), 0), "omega": _col(0, 0, 1)}
    known = {k: f for k, f in fields.items() if k not in unknown}
    unk = {k: f for k, f in fields.items() if k in unknown}
    return SympyModel(f"gps:{name}", tuple(X), {"h_x": xv, "h_y": yv}, known, unk,
                      domain={"xv": (-2.0, 2.0), "yv": (-2.0, 2.0), "theta": ANGLE_BOX})


# --------------------------------------------------------------------------------------
# Registry
# --------------------------------------------------------------------------------------

MODELS = {
    "systems/vehicle_wind.py:no_wind": lambda: _vehicle("none"),
    "systems/vehicle_wind.py:wind_known": lambda: _vehicle("known"),
    "systems/vehicle_wind.py:wind_unknown": lambda: _vehicle("unknown"),
}
for _out in ("range", "bearing", "phi"):
    MODELS[f"systems/unicycle_polar.py:{_out}_known"] = (
        lambda o=_out: _unicycle_polar(o, None))
    for _unk in ("v", "omega"):
        MODELS[f"systems/unicycle_polar.py:{_out}_{_unk}_unknown"] = (
            lambda o=_out, u=_unk: _unicycle_polar(o, u))
for _out, _short in (("r2", "range"), ("tan_beta", "bearing"), ("tan_phi", "phi")):
    MODELS[f"systems/unicycle_disturbance.py:no_disturbance_{_short}"] = (
        lambda o=_out, s=_short: _unicycle_disturbance(o, False, True, f"no_disturbance_{s}"))
    MODELS[f"systems/unicycle_disturbance.py:gamma_known_{_short}"] = (
        lambda o=_out, s=_short: _unicycle_disturbance(o, True, True, f"gamma_known_{s}"))
    MODELS[f"systems/unicycle_disturbance.py:gamma_unknown_{_short}"] = (
        lambda o=_out, s=_short: _unicycle_disturbance(o, True, False, f"gamma_unknown_{s}"))


MODELS["systems/gps.py:inputs_known"] = lambda: _gps((), "inputs_known")
MODELS["systems/gps.py:inputs_unknown"] = lambda: _gps(("v", "omega"), "inputs_unknown")
MODELS["systems/gps.py:omega_unknown"] = lambda: _gps(("omega",), "omega_unknown")
MODELS["systems/gps.py:v_unknown"] = lambda: _gps(("v",), "v_unknown")


def get(spec: str) -> SympyModel:
    """The sympy model mirroring the zoo entry ``spec`` (``"systems/FILE.py:FUNCTION"``)."""
    try:
        return MODELS[spec]()
    except KeyError:
        raise KeyError(f"no sympy model for {spec!r}; known: {', '.join(sorted(MODELS))}") from None


# --------------------------------------------------------------------------------------
# Several unknown inputs, drift, UI extension (zoo: systems/multi_ui.py). Equations from
# TUIO6's initialize_system.m, 004 section 11.2.1 and the hand-made cases of the zoo file.
# --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class TimedSympyModel(SympyModel):
    """A :class:`SympyModel` whose fields/outputs may contain an explicit time symbol."""

    time: sp.Symbol | None = None


def _multi_ui(name: str) -> SympyModel:
    if name in ("tac2025", "guarded_full_rank"):
        x1, x2, x3, x4, x5 = sp.symbols("x1 x2 x3 x4 x5", real=True)
        drift = _col(x3, x5, 0, 0, 0)
        w1, w2 = _col(0, 1, x4, 0, 0), _col(0, 1, x4, x4, x5)
        if name == "tac2025":
            return SympyModel(f"multi_ui:{name}", (x1, x2, x3, x4, x5), {"y1": x1, "y2": x2}, {},
                              {"w1": w1, "w2": w2}, drift)
        return SympyModel(f"multi_ui:{name}", (x2, x3, x4, x5), {"y1": x3, "y2": x2}, {},
                          {"w1": w1[1:, :], "w2": w2[1:, :]}, drift[1:, :])
    if name == "hiv":
        Tu, Ti, V, lam, rho, delta, N, c = X = sp.symbols("T_u T_i V lambda rho delta N c", real=True)
        return SympyModel("multi_ui:hiv", X, {"V": V, "T_total": Tu + Ti}, {},
                          {"eta": _col(-Tu * V, Tu * V, 0, 0, 0, 0, 0, 0)},
                          _col(lam - rho * Tu, -delta * Ti, N * delta * Ti - c * V, 0, 0, 0, 0, 0))
    x1, x2, x3, x4 = sp.symbols("x1 x2 x3 x4", real=True)
    if name == "trivial_drift":
        return SympyModel("multi_ui:trivial_drift", (x1, x2), {"y": x1}, {}, {"w": _col(0, 1)}, _col(x2, 0))
    if name == "time_varying":
        t = sp.Symbol("t", real=True)
        return TimedSympyModel("multi_ui:time_varying", (x1, x2), {"y": x1 + t * x2}, {}, {"w": _col(0, 1)},
                               _col(1, 0), time=t)
    if name == "gps_inputs_unknown":
        m = _gps(("v", "omega"), name)
        return SympyModel(f"multi_ui:{name}", m.states, m.outputs, {}, m.unknown, None, m.domain)
    if name in ("extension_kept", "extension_dropped"):
        g2 = _col(0, 0, 0, 1) if name == "extension_kept" else _col(0, 0, 1, 0)
        return SympyModel(f"multi_ui:{name}", (x1, x2, x3, x4), {"y1": x1, "y2": x2}, {},
                          {"w1": _col(0, 1, x4, 0), "w2": g2}, _col(x3, 0, 0, 0))
    if name == "extension_two_kept":
        x5, x6 = sp.symbols("x5 x6", real=True)
        return SympyModel(f"multi_ui:{name}", (x1, x2, x3, x4, x5, x6), {"y1": x1, "y2": x2}, {},
                          {"w1": _col(0, 1, x4, 0, 0, 0), "w2": _col(0, 0, 0, 0, x6, 0), "w3": _col(0, 0, 0, 0, 0, 1)},
                          _col(x3, 0, 0, x5, 0, 0))
    if name in ("known_gain_smooth", "known_gain_switchable"):
        return SympyModel(f"multi_ui:{name}", (x1, x2), {"y": x1 + x2}, {"u": _col(x2, 0)}, {"w": _col(0, 1)})
    raise KeyError(name)


MULTI_UI = ("tac2025", "guarded_full_rank", "hiv", "trivial_drift", "time_varying", "gps_inputs_unknown",
            "extension_kept", "extension_dropped", "extension_two_kept", "known_gain_smooth",
            "known_gain_switchable")
for _name in MULTI_UI:
    MODELS[f"systems/multi_ui.py:{_name}"] = lambda nm=_name: _multi_ui(nm)
