"""Part 2c: node-to-segment contact time per step against the number of slave nodes.

Two thin structured strips of radius 1 m whose faces have n - 1 (slave, the
target) and about 2(n - 1)/3 (master, the striker) intervals: a non-nested 3:2
interface on which every slave shares master nodes with its neighbours. The
striker is pressed against the clamped target, so every constraint stays
closed. Each method runs node to segment (penalty, FILM by block pivoting on
the band of S, FILM dense up to the cap, DME), beside the same method node to
node on matching faces with n nodes (the reference of the goal "at most twice
node-to-node per constraint"). Phases as ContactSet's: detection (gather, gaps),
solve (the method), update (write back, ledger).
"""
from __future__ import annotations

from .. import loads, meshing
from ..bodies import Body, DeformableModel
from ..contact import DME, FILM, Penalty, pair_surfaces
from ..contact.segments import node_to_segment
from ..materials import STEEL
from ..simulation import Settings, Simulation
from .bar import BIG
from .contact import PHASES, _contact_run

NTS_METHODS = ("penalty", "film", "film_dense", "dme")


def _mesh(comm, n: int, matching: bool):
    h_target = 1.0 / (n - 1)
    h_striker = h_target if matching else 1.0 / max(1, round(2 * (n - 1) / 3))
    return meshing.coaxial_bars_sized(radius=1.0, striker_length=2 * h_striker,
                                      target_length=2 * h_target, h_striker=h_striker,
                                      h_target=h_target, structured=True, comm=comm)


def _sim(tmesh, method: str, steps: int, node_to_node: bool):
    m = {"penalty": lambda: Penalty("scaled"), "film": lambda: FILM("fast"),
         "film_dense": lambda: FILM("dense"), "dme": lambda: DME(0.0)}[method]()
    settings = Settings(cfl=0.9, n_steps=steps, output_every=BIG, history_every=1,
                        fields=False, out=None, quiet=True)
    model = DeformableModel(tmesh, [Body("striker", STEEL), Body("target", STEEL)])
    push = loads.SurfaceLoad(model, "striker_end", loads.Constant(50e6))
    sim = Simulation(model, settings, fixed=[model.facet_dofs("target_end", 1)], loads=[push])
    if node_to_node:
        sim.add_contact(pair_surfaces(model, "striker_contact", "target_contact"), m)
    else:
        sim.add_contact(node_to_segment(model, "target_contact", "striker_contact"), m)
    return sim


def part_nts(ctx) -> dict:
    mode = ctx.mode
    out, rows = [], []
    for n in mode.contact_ns:
        base = {}
        tm = _mesh(ctx.comm, n, matching=True)
        for method in ("penalty", "film", "dme"):
            base[method] = _contact_run(_sim(tm, method, mode.contact_steps, True), n, method,
                                        mode.contact_steps)
        del tm
        tm = _mesh(ctx.comm, n, matching=False)
        for method in NTS_METHODS:
            if method == "film_dense" and n > mode.dense_cap:
                continue
            steps = mode.dense_steps if method == "film_dense" else mode.contact_steps
            sim = _sim(tm, method, steps, False)
            rec = _contact_run(sim, n, method, steps)
            info = sim.contacts[0].method.info
            rec["iterations_max"] = info.get("iterations_max", 0)
            rec["iterations_mean"] = info.get("iterations_total", 0) / max(1, steps)
            rec["bandwidth"] = int(sim.contacts[0].bw)
            ref = base.get("film" if method == "film_dense" else method)
            rec["node_to_node_contact"] = ref["contact"]
            rec["ratio_to_node_to_node"] = rec["contact"] / ref["contact"]
            out.append(rec)
            rows.append([n, method, rec["n_dofs"], f"{rec['n_active_median']:.0f}"]
                        + [f"{1e6 * rec[k]:.1f}" for k in PHASES[:3] + ("contact",)]
                        + [f"{rec['contact_ns_per_constraint']:.0f}",
                           f"{rec['iterations_mean']:.2f}/{rec['iterations_max']}",
                           f"{1e6 * ref['contact']:.1f}", f"{rec['ratio_to_node_to_node']:.2f}"])
        del tm
    ctx.table("2c. Node-to-segment contact per step (3:2 non-nested faces, n slaves, all closed); "
              "medians in us; iterations of the pivoting mean/max; node to node on matching "
              "faces with the same method as the reference",
              ["n", "method", "dofs", "active", "detect", "solve", "update", "contact",
               "ns/slave", "iter", "n-t-n", "ratio"], rows)
    return {"rows": out, "dense_cap": mode.dense_cap}
