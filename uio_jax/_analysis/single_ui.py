"""Single unknown input, no drift: Martinelli's analytic observable codistribution.

System ``xdot = sum_i f_i(x) u_i + g(x) w``, outputs ``h``. With ``L_g^1 = L_g h != 0``
(Definition 5 of 004; Algorithms 2-3 of 002)::

    phi^i_0 = f_i,        phi^i_m = [phi^i_{m-1}, g] / L_g^1
    Omega_0 = span{dh (all outputs)}
    Omega_m = Omega_{m-1} + sum_i L_{f_i} Omega_{m-1} + L_{g/L_g^1} Omega_{m-1}
              + sum_i span{d L_{phi^i_{m-1}} h}

Convergence (Lemma 1 of 002; Theorem 2 of 004):

* if every ``phi^i_1`` vanishes, or ``L_{phi^i_j} L_g^1 = 0`` for every j up to where the
  distribution of the ``phi^i_j`` stops growing (Lemma 1), then ``m' = 0``;
* otherwise ``tau = L_g^2 h / (L_g^1)^2`` and ``m'`` = first m with ``d tau in Omega_m``;
* ``m*`` = first ``m >= m'`` with ``Omega_{m+1} = Omega_m``; ``Omega* = Omega_{m*}``.

**Correction to the papers' stopping rule** (implemented, reported as ``m_star`` next to
the literal ``m_star_paper``): the induction in the proof of Theorem 2 of 004 uses eq. 25,
valid for ``j >= 2``, so a stop at ``m* = 0`` is not justified; we require ``m* >= 1``
unless every ``phi^i_1`` vanishes identically. Counterexample to the literal rule:
``x0' = u + x1 w, x1' = x0 x2 u, x2' = 0, y = x0`` gives ``tau = 0``, ``m' = 0`` and
``Omega_1 = Omega_0 = span{dx0}``, but ``L_{phi_1} h = x0 x2 / x1`` is observable and
``dim Omega_2 = 2``.

**L_g h = 0 for every output** (section 7 of 004, step 1 of 003): the outputs and their
Lie derivatives along the known fields are observable while their ``L_g`` vanishes; we
build them level by level (an ORC along the known fields, pruned) until a kept function
``h~`` has ``L_g h~ != 0``, keep every differential found so far in Omega and run the
recursion with ``h~`` in place of h. Steps are numbered as in the paper (11.1.2: Omega_1 =
span{dr, dh~}). If no such function exists, the unknown input does not affect the outputs
and the result is the ORC of the known fields.

Functions that "vanish identically" are decided at the sampled states with the relative
threshold ``ZERO_ROW_RTOL`` against the natural scale of the product (e.g. ``|dh||g|``
for ``L_g h``), by majority, and the fraction is reported.
"""

import dataclasses

import numpy as np

from .._errors import OptionError
from .context import Context
from .rank import ZERO_ROW_RTOL


#: Bound on the number of recursion steps beyond the start (Lemma 8 of 004: m' <= 2n + 2).
def _step_cap(n):
    return 2 * n + 3


def check_applicable(system):
    """Raise OptionError when ``method='single_ui'`` does not apply to ``system``."""
    if len(system.unknown) != 1:
        raise OptionError(
            f"method 'single_ui' needs exactly one unknown input, got {len(system.unknown)}; "
            "use method='eorc' (or 'auto')"
        )
    if system.drift is not None:
        raise OptionError(
            "method 'single_ui' is stated by the papers for systems without drift; treating "
            "the drift as a known field with input 1 gives wrong answers. Use method='eorc' "
            "(or 'auto')"
        )


def single_ui_report(ctx: Context, *, why="", max_order=None):
    """Run the single-unknown-input analysis on ``ctx`` and build the Report."""
    system = ctx.system
    check_applicable(system)
    b = ctx.builder
    (g_label,) = tuple(system.unknown)
    g = ctx.field_node(g_label)
    fs = [ctx.field_node(lbl) for lbl in system.known]
    notes = [why] if why else []

    history, h_tilde, offset, fraction = _choose_output(ctx, fs, g)
    if h_tilde is None:
        notes.append(
            f"the unknown input {g_label!r} does not affect the outputs (L_g vanishes on the "
            "outputs and on all their Lie derivatives along the known fields): the result is "
            "the ORC of the known fields"
        )
        details = {"unknown_input_affects_outputs": False}
        return ctx.report("single_ui", history, "ORC of the known fields converged",
                          notes=notes, details=details)

    Lg1 = b.lie(g, h_tilde)
    g_scaled = b.scaled(g, Lg1, label=f"{g_label}/L_g^1")
    tau = b.ratio(b.lie(g, Lg1), Lg1, 2, label="tau")
    phis = list(fs)  # phi^i_0 = f_i
    phi_next = [b.scaled(b.bracket(p, g), Lg1, label=f"phi^{p.label}_1") for p in phis]
    phi1_vanish = _fields_vanish(ctx, phi_next, fs, g, Lg1)

    rule = "tau"
    if phi1_vanish:
        rule = "all phi^i_1 vanish (Lemma 1)"
    elif _lemma1_holds(ctx, fs, g, Lg1):
        rule = "Lemma 1"
    m_prime = 0 if rule != "tau" else None

    details = {
        "unknown_input_affects_outputs": True,
        "output": h_tilde.label,
        "L_g^1": Lg1.label,
        "relative_degree": offset + 1,
        "lg1_nonzero_fraction": fraction,
        "phi1_vanish": phi1_vanish,
        "convergence_rule": rule,
    }

    def tau_in(m_fresh):
        nonlocal m_prime
        if m_prime is None and ctx.contains_nodes([tau])[0]:
            m_prime = m_fresh
        return m_prime is not None

    if rule == "tau":  # Omega_start is the last history entry (the chosen output's level)
        history[-1] = dataclasses.replace(history[-1], extra={"tau_in_omega": tau_in(0)})

    frontier = list(ctx.codist.nodes)  # L_{g/L} of every earlier generator is new
    dims = [ctx.dim]
    m_star = m_star_paper = None
    reason = None
    cap = _step_cap(system.n)
    m = 0
    while True:
        if ctx.dim >= system.n and m_prime is not None:
            m_star = m if m_star is None else m_star
            m_star_paper = m if m_star_paper is None else m_star_paper
            reason = f"full rank {system.n} at m={m + offset}"
            break
        if max_order is not None and m + offset >= max_order:
            reason = f"max_order={max_order} reached before convergence"
            break
        if m >= cap:
            reason = f"no convergence certified within {cap} steps"
            notes.append("d tau never entered Omega within the step bound (Lemma 8 of 004); "
                         "the codistribution may be incomplete")
            break
        m += 1
        cand_nodes, cand_grads = [], []
        blocks = [(frontier, fs + [g_scaled])]
        # phi-terms: phi^i_0 = f_i repeats L_{f_i} h~ (h~ is in Omega_0), and when every
        # phi^i_1 vanishes so do all later phi^i_m: only m >= 2 with live phis adds terms
        if m >= 2 and not phi1_vanish:
            blocks.append(([h_tilde], phis))
        for phis_block, fields in blocks:
            nodes, grads = ctx.lie_block(phis_block, fields)
            cand_nodes += nodes
            cand_grads.append(grads)
        added = ctx.absorb(cand_nodes, np.concatenate(cand_grads, axis=1))
        frontier = added
        dims.append(ctx.dim)
        extra = {} if rule != "tau" else {"tau_in_omega": tau_in(m)}
        history.append(ctx.step(m + offset, added, **extra))
        # phi^i_m for the next step
        phis = [b.scaled(b.bracket(p, g), Lg1, label=f"phi^{f.label}_{m}")
                for p, f in zip(phis, fs)]
        if m_prime is None:
            continue
        # Omega_m = Omega_{m-1} (dims equal) means Omega_{(m-1)+1} = Omega_{m-1}
        if dims[-1] == dims[-2] and m - 1 >= m_prime:
            if m_star_paper is None:
                m_star_paper = m - 1
            if m - 1 >= 1 or phi1_vanish:
                m_star = m - 1
                reason = f"Omega_{m + offset} = Omega_{m - 1 + offset} with m >= m'"
                break

    if m_star is not None:
        details["m_prime"] = m_prime + offset
        details["m_star"] = m_star + offset
        details["m_star_paper"] = (m_star_paper + offset) if m_star_paper is not None else None
        if m_star_paper is not None and m_star_paper != m_star:
            notes.append(
                f"the papers' stopping rule would stop at m*={m_star_paper + offset}; the "
                f"corrected rule (m* >= 1 unless every phi^i_1 vanishes) continued to "
                f"m*={m_star + offset}"
            )
    else:
        details["m_prime"] = None if m_prime is None else m_prime + offset
        details["m_star"] = None
    return ctx.report("single_ui", history, reason, notes=notes, details=details)


def _choose_output(ctx, fs, g):
    """Pick the function ``h~`` with ``L_g h~ != 0`` (an output, else a Lie derivative).

    Returns:
        ``(history, h_tilde or None, level, fraction)``: the history of the levels built
        (Omega_0 .. Omega_level), the chosen function, its level (the paper's index offset)
        and the fraction of samples where ``L_g h~`` is non-zero.
    """
    outs = ctx.output_nodes()
    frontier = ctx.absorb(outs)
    history = [ctx.step(0, frontier)]
    candidates = outs  # every output may be chosen (first in order wins)
    level = 0
    while True:
        for node in candidates:
            nonzero, fraction = _lie_nonzero(ctx, node, g)
            if nonzero:
                return history, node, level, fraction
        if not frontier or ctx.dim >= ctx.system.n and level > 0 and not fs:
            return history, None, level, 0.0
        level += 1
        frontier = ctx.absorb_lie(frontier, fs)
        history.append(ctx.step(level, frontier))
        if not frontier:
            return history, None, level, 0.0
        candidates = frontier


def _lie_nonzero(ctx, node, g):
    """Is ``L_g node`` not identically zero? (majority of samples, relative threshold)."""
    lg = ctx.builder.lie(g, node)
    val, gval = ctx.builder.values([lg, g], ctx.xs)
    grad = ctx.gradients([node])[:, 0]
    scale = np.linalg.norm(grad, axis=-1) * np.linalg.norm(gval, axis=-1)
    ok = ctx.codist.valid & np.isfinite(val) & np.isfinite(scale)
    nonzero = np.abs(val) > ZERO_ROW_RTOL * scale
    frac = float(nonzero[ok].mean()) if ok.any() else 0.0
    return frac > 0.5, frac


def _fields_vanish(ctx, phis, fs, g, Lg1):
    """Do all fields ``phi^i_1 = [f_i, g] / L_g^1`` vanish identically?

    Compared with their natural scale ``(|f_i| + |g|) / |L_g^1|``, by majority of samples.
    """
    vals = ctx.builder.values(list(phis) + list(fs) + [g, Lg1], ctx.xs)
    k = len(phis)
    gnorm = np.linalg.norm(vals[2 * k], axis=-1)
    lg = np.abs(vals[2 * k + 1])
    for v, f in zip(vals[:k], vals[k : 2 * k]):
        ref = (np.linalg.norm(f, axis=-1) + gnorm) / lg
        ok = ctx.codist.valid & np.isfinite(v).all(axis=-1) & np.isfinite(ref)
        zero = np.linalg.norm(v, axis=-1) <= ZERO_ROW_RTOL * ref
        if not (ok.any() and zero[ok].mean() > 0.5):
            return False
    return True


def _lemma1_holds(ctx, fs, g, Lg1):
    """Lemma 1 of 002: ``L_{phi^i_j} L_g^1 = 0`` for j = 0..m_i (Lambda^i converged at m_i)."""
    b = ctx.builder
    n = ctx.system.n
    dlg = ctx.gradients([Lg1])[:, 0]
    dlg_norm = np.linalg.norm(dlg, axis=-1)
    for f in fs:
        phi = f
        basis_rank = 0
        vectors = []
        for j in range(n):
            v = b.values([phi], ctx.xs)[0]
            lie = np.einsum("si,si->s", dlg, v)
            ok = ctx.codist.valid & np.isfinite(lie)
            scale = dlg_norm * np.linalg.norm(v, axis=-1)
            if not (np.abs(lie[ok]) <= ZERO_ROW_RTOL * scale[ok]).mean() > 0.5:
                return False
            vectors.append(v)
            rank = _vector_rank(np.stack(vectors, axis=1), ctx.codist.valid)
            if rank == basis_rank:  # Lambda_j = Lambda_{j-1}: converged
                break
            basis_rank = rank
            phi = b.scaled(b.bracket(phi, g), Lg1, label=f"phi^{f.label}_{j + 1}")
    return True


def _vector_rank(vectors, valid):
    """Generic rank of sampled vector fields ``(S, k, n)`` (majority of per-sample ranks)."""
    v = np.where(np.isfinite(vectors), vectors, 0.0)[valid]
    norms = np.linalg.norm(v, axis=-1, keepdims=True)
    ref = norms.max(axis=1, keepdims=True)
    keep = norms > ZERO_ROW_RTOL * ref
    unit = np.where(keep, v / np.where(keep, norms, 1.0), 0.0)
    s = np.linalg.svd(unit, compute_uv=False)
    ranks = (s > 1e-8 * np.maximum(s[:, :1], 1e-300)).sum(axis=1)
    return int(np.bincount(ranks).argmax())
