"""Observability rank condition (Hermann-Krener), no unknown input.

Algorithm 1 of Martinelli 2017 (002)::

    Omega_0 = span{dh_1, ..., dh_p}
    Omega_m = Omega_{m-1} + sum_{v in {f0, f_1, ..., f_mu}} L_v Omega_{m-1}

stopped at the first m with ``Omega_m = Omega_{m-1}`` (m <= n - 1, Isidori Lemma 1.9.x).
Only Lie derivatives of the generators kept at the previous step are formed: if
``d c = sum_i a_i d k_i`` then ``L_v d c`` lies in the span of the ``d k_i`` and
``L_v d k_i``, so pruned candidates never need differentiating.
"""

from .context import Context


def run_orc(ctx: Context, field_labels, *, max_steps=None, start_nodes=None):
    """Run the ORC recursion on ``ctx``.

    Args:
        ctx: the analysis context (samples, builder, codistribution).
        field_labels: labels of the fields along which to differentiate (``f0`` and the
            known inputs, as in ``System.fields()``).
        max_steps: optional cap on m.
        start_nodes: generators of Omega_0 (default: the outputs).

    Returns:
        ``(history, stop_reason)``.
    """
    fields = [ctx.field_node(lbl) for lbl in field_labels]
    start = ctx.output_nodes() if start_nodes is None else list(start_nodes)
    frontier = ctx.absorb(start)
    history = [ctx.step(0, frontier)]
    m = 0
    n = ctx.system.n
    while True:
        if ctx.dim >= n:
            return history, f"full rank {n} at m={m}"
        if max_steps is not None and m >= max_steps:
            return history, f"max_order={max_steps} reached before convergence"
        m += 1
        frontier = ctx.absorb_lie(frontier, fields)
        history.append(ctx.step(m, frontier))
        if not frontier:
            return history, f"Omega_{m} = Omega_{m - 1}"
