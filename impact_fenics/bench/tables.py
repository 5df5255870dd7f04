"""Printing: the tables of the parts and the closing headline figures."""
from __future__ import annotations


def format_table(title: str, headers: list, rows: list) -> str:
    """A blank line, the title, then right-aligned columns indented by two spaces."""
    cells = [[str(c) for c in r] for r in rows]
    widths = [max(len(str(h)), *(len(r[i]) for r in cells)) if cells else len(str(h))
              for i, h in enumerate(headers)]
    lines = [f"\n{title}", "  " + "  ".join(str(h).rjust(w) for h, w in zip(headers, widths))]
    lines += ["  " + "  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cells]
    return "\n".join(lines)


def summary_lines(res: dict) -> list[str]:
    """A few headline figures of a run's results."""
    lines = []
    st = res.get("step")
    if st and "ns_per_dof" in st:
        r = st["ratio_to_matmult"]
        lines.append(f"step = {r['step']:.2f} x MatMult, Simulation loop = {r['simulation']:.2f} x"
                     + (f", SciPy in place = {r['scipy_inplace']:.2f} x" if "scipy_inplace" in r else ""))
    sm = res.get("stream")
    serial = res["meta"]["ranks"] == 1
    if st and "ns_per_dof" in st and sm and serial:
        floor = st["step_bytes_per_dof"] / sm["best_gbs"]
        lines.append(f"bandwidth floor of the step at {st['n_dofs']:,} dofs: "
                     f"{st['step_bytes_per_dof']:.0f} B/dof / {sm['best_gbs']:.1f} GB/s = "
                     f"{floor:.2f} ns/dof; measured {st['ns_per_dof']['step']:.2f} ns/dof "
                     f"({st['ns_per_dof']['step'] / floor:.1f} x the floor)")
    sc = res.get("scaling")
    if sc and sm and serial:
        big = sc[-1]
        floor = big["step_bytes_per_dof"] / sm["best_gbs"]
        lines.append(f"at {big['n_dofs']:,} dofs: step {big['ns_per_dof']['step']:.2f} ns/dof, "
                     f"{big['ns_per_dof']['step'] / floor:.1f} x the bandwidth floor {floor:.2f} ns/dof")
    rk = res.get("ranks")
    if rk and "speedup" in rk:
        sp = ", ".join(f"{s['n_dofs']:,}: {s['speedup']['step']:.2f}" for s in rk["speedup"])
        lines.append(f"2-rank speed-up of the step: {sp}; triad bandwidth ratio "
                     f"{rk['bandwidth_ratio']['waxpy_triad']:.2f}")
    return lines
