"""The mesh topology map (theory §13): nodes at their positions (or a layered layout by hop
distance to the gateway when the record has no positions), the routes' hops as arrows coloured
by their success (per period; per attempt under a slot budget), relays that break the design
alone (N − 1 mean-unstable) ringed in red and the bottleneck hop drawn thick. Pure function of
the typed record's ``mesh`` section (:class:`~kfcrit.analysis.mesh.section.MeshSection`)."""
from __future__ import annotations

import matplotlib
from matplotlib.figure import Figure

from kfcrit.analysis.mesh.section import MeshSection
from kfcrit.analysis.sections import AnalysisRecord
from kfcrit.records.contract import Verdict
from kfcrit.views.figures.style import FIG_RC, new_figure, present

ROLE_STYLE = {"sensor": ("o", "#2563eb"), "relay": ("D", "#f59e0b"), "gateway": ("s", "#111827")}


def layered_layout(mesh: MeshSection) -> dict[str, tuple[float, float]]:
    """Positions by hop count to the gateway along the routes (x) and order in the layer (y)."""
    depth: dict[str, int] = {}
    for r in mesh.routes:
        nodes = r.nodes
        for k, name in enumerate(nodes):
            depth[name] = max(depth.get(name, 0), len(nodes) - 1 - k)
    for n in mesh.nodes:
        depth.setdefault(n.name, 0)
    layers: dict[int, list[str]] = {}
    for n in mesh.nodes:
        layers.setdefault(depth[n.name], []).append(n.name)
    out = {}
    for d, names in layers.items():
        for i, name in enumerate(names):
            out[name] = (float(d), (len(names) - 1) / 2.0 - i)
    return out


def mesh_positions(mesh: MeshSection) -> tuple[dict[str, tuple[float, float]], bool]:
    """(positions, measured): the record's positions when every node has one, else layered."""
    nodes = mesh.nodes
    if nodes and all(isinstance(n.position_m, list) and len(n.position_m) >= 2 for n in nodes):
        return {n.name: (float(n.position_m[0]), float(n.position_m[1])) for n in nodes}, True
    return layered_layout(mesh), False


def _used_hops(mesh: MeshSection) -> set[str]:
    return {h for r in mesh.routes for h in r.hops}


def draw_mesh_topology(rec: AnalysisRecord) -> Figure | None:
    """The topology map (module docstring); None for a record without a mesh."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize

    mesh = rec.mesh
    if not present(mesh) or not mesh.nodes:
        return None
    pos, measured = mesh_positions(mesh)
    per_attempt = bool(mesh.slots_per_period)
    used = _used_hops(mesh)
    fatal = {f.element for f in mesh.failures
             if f.kind == "relay" and f.verdict is Verdict.MEAN_UNSTABLE}
    cmap, norm = colormaps["RdYlGn"], Normalize(0.0, 1.0)
    with matplotlib.rc_context(FIG_RC):
        fig, ax = new_figure(4.0)
        if measured:
            ax.set_aspect("equal", adjustable="datalim")
        for h in mesh.hops:
            (x0, y0), (x1, y1) = pos[h.source], pos[h.target]
            s = h.attempt_success if per_attempt else h.period_success
            thick = h.name == mesh.bottleneck
            ax.annotate("", (x1, y1), (x0, y0), zorder=2, arrowprops=dict(
                arrowstyle="-|>", color=cmap(norm(s)), lw=3.2 if thick else 1.6,
                linestyle="-" if h.name in used else ":", shrinkA=7, shrinkB=7))
            ax.annotate(f"{s:.3g}", ((x0 + x1) / 2, (y0 + y1) / 2), fontsize=6.5,
                        ha="center", va="center", color="#374151", zorder=3,
                        bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.8))
        arr = mesh.arrival_probability   # a plain dict[str, float] field of the schema
        for n in mesh.nodes:
            marker, color = ROLE_STYLE.get(n.role, ("o", "#6b7280"))
            x, y = pos[n.name]
            ax.scatter([x], [y], marker=marker, s=110, color=color, zorder=4,
                       edgecolors="#dc2626" if n.name in fatal else "white",
                       linewidths=2.2 if n.name in fatal else 0.8)
            label = n.name + (f"\na = {arr[n.name]:.6g}" if n.name in arr else "")
            ax.annotate(label, (x, y), xytext=(7, 5), textcoords="offset points", fontsize=7,
                        zorder=5)
        sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
        fig.colorbar(sm, ax=ax, shrink=0.8, label=("per-attempt" if per_attempt else
                                                   "per-period") + " hop success")
        if measured:
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
        else:
            ax.set_xlabel("hops to the gateway (no positions in the file: layered layout)")
            ax.set_yticks([])
            ax.set_xticks(sorted({round(p[0]) for p in pos.values()}))
        ax.margins(0.15)
        return fig
