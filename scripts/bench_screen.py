"""How often the float64 screen disagrees with the exact answer, over the zoo.

Every rank decision of an analysis is a float64 vote at sampled states that is settled
again modulo p (or in mpmath where the model is not made rational). This counts, per model
and in total, the decisions made exactly, the weak votes settled again (escalations), and
the settled decisions whose answer differs from the float64 vote (a vote of "independent"
found dependent, or the reverse): the screen's disagreements. Models decided on the Taylor
route take no float64 vote at all (counted apart).

    python scripts/bench_screen.py [--samples 4096] [--only SUBSTRING]
"""

import argparse
import time


def disagreements(report) -> tuple[int, int]:
    """``(escalations, disagreements)`` of a report: settled decisions whose result is not
    the float64 vote's (the vote's first word)."""
    escalations = report.certificate.escalations
    differ = sum(1 for e in escalations if e.result.value in ("independent", "dependent")
                 and not e.float64.startswith(e.result.value))
    return len(escalations), differ


def main(argv=None):
    import uio_jax as uj

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=4096)
    ap.add_argument("--only", default="")
    args = ap.parse_args(argv)
    import snapshot_reports as snap  # a sibling script (the script's folder is on sys.path)
    totals = {"models": 0, "exact": 0, "escalated": 0, "disagree": 0, "taylor": 0}
    print("| model | decisions exact | escalated | float64 disagreed | arithmetic | s |")
    print("|---|---|---|---|---|---|")
    for entry in snap.zoo_entries():
        label = snap.snapshot_label(entry.label)
        if entry.system is None or args.only not in label:
            continue
        t0 = time.perf_counter()
        rep = uj.analyze(entry.system, samples=args.samples)
        seconds = time.perf_counter() - t0
        esc, differ = disagreements(rep)
        taylor = any("Taylor series" in note for note in rep.notes)
        totals["models"] += 1
        totals["exact"] += rep.certificate.exact_decisions
        totals["escalated"] += esc
        totals["disagree"] += differ
        totals["taylor"] += taylor
        print(f"| {label} | {rep.certificate.exact_decisions} | {esc} | {differ} | "
              f"{rep.certificate.arithmetic.name.lower()}{' (Taylor route)' if taylor else ''} | {seconds:.2f} |",
              flush=True)
    print(f"\n{totals['models']} models: {totals['exact']} decisions exact, {totals['escalated']} weak votes "
          f"settled again, {totals['disagree']} where the float64 vote was wrong; {totals['taylor']} on the "
          "Taylor route (no float64 vote)")


if __name__ == "__main__":
    main()
