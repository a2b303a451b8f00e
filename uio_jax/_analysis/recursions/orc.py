"""Observability rank condition (Hermann-Krener), no unknown input.

Algorithm 1 of Martinelli 2017 (002)::

    Omega_0 = span{dh_1, ..., dh_p}
    Omega_m = Omega_{m-1} + sum_{v in {f0, f_1, ..., f_mu}} L_v Omega_{m-1}

stopped at the first m with ``Omega_m = Omega_{m-1}`` (m <= n - 1, Isidori Lemma 1.9.x).
Only Lie derivatives of the generators kept at the previous step are formed: if
``d c = sum_i a_i d k_i`` then ``L_v d c`` lies in the span of the ``d k_i`` and
``L_v d k_i``, so pruned candidates never need differentiating.
"""

from ..decisions.context import Context
from .driver import Cap, Recursion, StopReason, iterate


class Orc(Recursion):
    """The ORC as a :class:`~uio_jax._analysis.recursions.driver.Recursion`.

    ``frontier``: the generators kept at the last step (the only ones whose Lie derivatives
    can add to the span).

    Args:
        ctx: the analysis context (samples, builder, codistribution on ``R^n``).
        field_nodes: the fields ``v`` (Nodes of ``x -> (n,)``) of the recursion.
        start: scalar Nodes whose differentials generate Omega_0.
    """

    def __init__(self, ctx: Context, field_nodes, start):
        self.ctx, self.fields, self.start = ctx, list(field_nodes), list(start)
        self.frontier = []

    def init(self):
        """Omega_0 = span{d start}."""
        self.frontier = self.ctx.absorb(self.start)
        return self.ctx.step(0, self.frontier)

    def step(self, m):
        """Omega_m = Omega_{m-1} + sum_v span{d L_v c : c in frontier}."""
        self.frontier = self.ctx.absorb_lie(self.frontier, self.fields)
        return self.ctx.step(m, self.frontier)

    def terminate(self, m, history):
        """Converged (the last step added nothing), else full rank ``n``."""
        n = self.ctx.system.n
        if m > 0 and not self.frontier:
            return StopReason.CONVERGED.stop(m=m, prev=m - 1)
        if self.ctx.dim >= n:
            return StopReason.FULL_RANK.stop(n=n, m=m)
        return None


def run_orc(ctx: Context, field_labels, *, max_steps=None):
    """Run the ORC recursion on ``ctx``.

    Args:
        ctx: the analysis context (samples, builder, codistribution).
        field_labels: labels of the fields along which to differentiate (``f0`` and the
            known inputs, as in ``System.fields()``).
        max_steps: optional cap on m (``max_order``); without it the driver's cap is ``n``,
            which the ORC never reaches (each step that does not stop it raises the rank).

    Returns:
        ``(history, stop)``: one Step per m = 0..M (``Step.dim = dim Omega_m``) and the
        :class:`~uio_jax._analysis.recursions.driver.Stop` (its StopReason member and values).
    """
    fields = [ctx.field_node(lbl) for lbl in field_labels]
    n = ctx.system.n
    cap = Cap(n, StopReason.STEP_CAP.stop(cap=n)) if max_steps is None else \
        Cap(max_steps, StopReason.MAX_ORDER.stop(max_order=max_steps))
    out = iterate(Orc(ctx, fields, ctx.output_nodes()), cap=cap)
    return out.history, out.stop
