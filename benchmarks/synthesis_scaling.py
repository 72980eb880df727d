"""The scaling benchmark: both schemes on grids refined k times, run where their
predicted peak memory fits, predicted beyond (:func:`bench_scaling`).
"""
from __future__ import annotations

from benchmarks.common import Row, available_ram_bytes, peak_bytes, total_ram_bytes
from benchmarks.synthesis_common import PACKAGE, SCALING, run_synthesis


def _pairs(name: str, k: int) -> tuple[int, int, int]:
    """(bins, actions, dimensions) of a problem refined k times, without building it."""
    ang, spd = 12 * k, 6 * k + 1
    return {"centralized": (ang * ang * spd * spd, 9, 4), "agent2": (ang * spd, 3, 2),
            "agent1": (ang * spd * ang * 3, 3, 4)}[name]


def bench_scaling(central=(1, 2), decentral=(1, 2), *, budget_fraction: float = 0.5,
                  estimate_to: int = 8) -> tuple[list[Row], list[dict]]:
    """Both schemes on grids refined k times, each built as :func:`core.synthesize` builds
    it (:data:`PACKAGE`: the centralized problem from the compiled RK4 over one theta1 slice
    and T factored along theta1; the agents' numpy RK4 and fixed-width tables): Q size,
    nnz, time, peak memory.

    The centralized problem runs for k in ``central``, the decentralized pair for k in
    ``decentral``, each only when its predicted peak memory fits ``budget_fraction`` of
    the memory available now. The prediction is each scheme's peak bytes per unit of its
    work measured on its largest run made (centralized: per state-action pair, as the
    factored table grows with the pairs; decentralized: per state-action pair x 2**d
    memberships); up to ``estimate_to`` the rows give each scheme's predicted need against
    the machine's RAM.
    """
    rows, records = [], []
    avail = available_ram_bytes() or total_ram_bytes() or 0
    ram = total_ram_bytes() or avail
    budget = budget_fraction * avail
    coeff = {}            # per scheme: peak bytes per unit of work, measured
    asked = {"centralized": set(central), "decentralized": set(decentral)}
    for k in range(1, max(max(central), max(decentral), estimate_to) + 1):
        for scheme, parts in (("centralized", ("centralized",)),
                              ("decentralized", ("agent2", "agent1"))):
            dims = [_pairs(p, k) for p in parts]
            q_size = sum(n * u for n, u, _ in dims)
            work = sum(n * u * (1 if scheme == "centralized" else 2 ** d) for n, u, d in dims)
            need = coeff[scheme] * work if scheme in coeff else None
            rec = {"k": k, "scheme": scheme, "q_size": q_size,
                   "bins": [n for n, _, _ in dims], "predicted_bytes": need}
            run = k in asked[scheme] and (need is None or need <= budget)
            if run:
                total, peak, nnz, sweeps = 0.0, 0, 0, 0
                for part in parts:
                    build, layout = PACKAGE[part]
                    mem, (problem, trans, result, t) = peak_bytes(
                        lambda build=build, layout=layout: run_synthesis(lambda: build(k), layout))
                    total += sum(t)
                    peak = max(peak, mem)
                    nnz += trans.nnz
                    sweeps = max(sweeps, result.iterations)
                    rec[f"{part}_seconds"] = t
                    rec[f"{part}_sweeps"] = result.iterations
                    del problem, trans, result
                coeff[scheme] = peak / work
                rec.update(seconds=total, peak_bytes=peak, nnz=nnz)
                note = f"{nnz:,} nnz, {sweeps} sweeps, peak {peak / 2**20:,.0f} MiB"
                rows.append(Row(SCALING, f"{scheme} {k}x bins: time", total, "s", note))
            elif need is not None:
                why = (f"over the {budget / 2**30:,.1f} GiB budget" if need > budget
                       else "not in this mode's grids")
                fits = "exceeds" if need > ram else "within"
                rows.append(Row(SCALING, f"{scheme} {k}x bins: predicted memory",
                                need / 2**20, "MiB",
                                f"not run ({why}); {fits} the machine's {ram / 2**30:,.1f} GiB"))
            rows.append(Row(SCALING, f"{scheme} {k}x bins: Q size", q_size, "values",
                            " + ".join(f"{n:,}x{u}" for n, u, _ in dims)))
            records.append(rec)
    return rows, records
