"""The report's figures (matplotlib, files only): IQM curves with their CI bands, and the maze with
AuxSS's start-state probabilities painted on the candidate demo states.

`curves_figure` and `maze_figure` return a figure; `save_figure` writes it as a palette PNG (and a PDF
when asked), each atomically and with no date in it, so the same data gives the same bytes.
"""

from __future__ import annotations

import dataclasses
import io
import math
from pathlib import Path

import numpy as np

from lava_bridge_mj.eval.analysis.aggregate import Curve, Group, RunRecord
from lava_bridge_mj.eval.analysis.report_groups import STANDARD_DEMOS, is_offline

METRIC_TITLES = {"train_return": "training return", "success_p0": "success from p0 (ID)",
                 "success_ood": "success from ood (OOD)"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only, never a window
    import matplotlib.pyplot as plt

    return plt


def _style(groups: list[Group]) -> dict[str, dict]:
    """Colour by method (the same in every figure), line style by demo set, then by variant."""
    from lava_bridge_mj.eval.training.config import METHODS

    plt = _pyplot()
    palette = plt.get_cmap("tab10").colors
    variant_styles = (":", "-.", (0, (5, 1, 1, 1)))
    order = {method: i for i, method in enumerate(METHODS)}
    styles, seen = {}, {}
    for group in groups:
        index = order.get(group.method, len(order))
        key = (group.method, group.demos)
        variant = seen.get(key, 0)
        seen[key] = variant + 1
        base = "-" if group.demos == STANDARD_DEMOS else "--"
        styles[group.label] = {"color": palette[index % len(palette)],
                               "linestyle": base if variant == 0 else variant_styles[(variant - 1) % 3]}
    return styles


def _legend_label(group: Group) -> str:
    suffix = ", gradient steps" if is_offline(group) else ""
    return f"{group.label} (n={len(group.runs)}{suffix})"


def curves_figure(groups: list[Group], curves: dict[str, dict[str, Curve]], title: str):
    """Three panels (training return, success from p0, from ood): IQM lines with CI bands per group."""
    plt = _pyplot()
    styles = _style(groups)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    for ax, metric in zip(axes, ("train_return", "success_p0", "success_ood")):
        for group in groups:
            curve, style = curves[group.label][metric], styles[group.label]
            ax.plot(curve.steps, curve.iqm, label=_legend_label(group), linewidth=1.8, **style)
            ax.fill_between(curve.steps, curve.low, curve.high, color=style["color"], alpha=0.18, linewidth=0)
        ax.set_title(METRIC_TITLES[metric])
        ax.set_xlabel("steps")
        ax.grid(alpha=0.3)
        if metric.startswith("success"):
            ax.set_ylim(-0.03, 1.03)
            ax.set_ylabel("task completion rate (IQM)")
        else:
            # the sparse return is 1 at the goal and 0 otherwise: a fixed 0-1 axis, so that a wobble of
            # 0.02 on a short run does not read as a steep drop; wider only for rewards that leave it
            values = np.concatenate([np.ravel(getattr(curves[g.label][metric], part))
                                     for g in groups for part in ("iqm", "low", "high")])
            values = values[np.isfinite(values)]
            low, high = (min(0.0, values.min()), max(1.0, values.max())) if values.size else (0.0, 1.0)
            margin = 0.03 * (high - low)
            ax.set_ylim(low - margin, high + margin)
            ax.set_ylabel("mean episode return (IQM)")
    handles, labels = axes[0].get_legend_handles_labels()
    columns = max(1, min(4, len(labels), 190 // (max(map(len, labels)) + 8)))  # about 190 characters fit a row
    fig.legend(handles, labels, loc="outside lower center", ncol=columns, fontsize=8, frameon=False)
    fig.suptitle(title)
    return fig


def draw_maze(ax, layout) -> None:
    """The maze from above: floor, outer walls, lava pits, goal, p0 blobs (green), ood spots (blue)."""
    from matplotlib.patches import Circle, Rectangle

    def box(b, **style):
        ax.add_patch(Rectangle((b.x - b.half_x, b.y - b.half_y), 2 * b.half_x, 2 * b.half_y, **style))

    hx, hy = layout.half_extent
    ax.add_patch(Rectangle((-hx, -hy), 2 * hx, 2 * hy, facecolor="#f2efe8", edgecolor="none", zorder=0))
    for wall in layout.walls.values():
        box(wall, facecolor="#4d4d4d", edgecolor="none", zorder=1)
    for pit in layout.lava_pits.values():
        box(pit, facecolor="#e8571e", edgecolor="none", zorder=1, label="lava")
    for disc in layout.p0_blobs:
        ax.add_patch(Circle(disc[:2], disc.radius, facecolor="#2ca02c", alpha=0.55, zorder=2, label="p0"))
    for disc in layout.ood_spots:
        ax.add_patch(Circle(disc[:2], disc.radius, facecolor="#1f5fd0", alpha=0.55, zorder=2, label="ood"))
    ax.add_patch(Circle(layout.goal, layout.goal_radius, facecolor="none", edgecolor="#b30000", linewidth=2, zorder=2))
    ax.plot(*layout.goal, marker="x", color="#b30000", markersize=8, zorder=2, label="goal")
    t = layout.wall_thickness
    ax.set_xlim(-hx - t, hx + t)
    ax.set_ylim(-hy - t, hy + t)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def _all_equal(values: np.ndarray) -> bool:
    """Positive `values` equal up to float rounding (1/3 * 3 need not be exactly 1)."""
    return values.max() <= values.min() * (1 + 1e-9)


def maze_figure(layout, states: np.ndarray | None, weights: list[tuple[float, float, np.ndarray]], caption: str):
    """The maze with the candidate states, then one panel per (step, p0 success, probabilities) with the
    probabilities painted on the states, relative to uniform (1 = uniform sampling)."""
    plt = _pyplot()
    from matplotlib.colors import LogNorm

    rows = 1 + math.ceil(len(weights) / 2)
    fig = plt.figure(figsize=(12, 2.7 * rows + 0.6), constrained_layout=True)
    grid = fig.add_gridspec(rows, 2)
    top = fig.add_subplot(grid[0, :])
    draw_maze(top, layout)
    if states is not None:
        top.scatter(states[:, 0], states[:, 1], s=9, color="black", zorder=3, label="demo states")
    handles, labels = top.get_legend_handles_labels()
    unique = dict(zip(labels, handles))
    top.legend(unique.values(), unique.keys(), loc="upper center", bbox_to_anchor=(0.5, -0.02), ncol=5, fontsize=8,
               frameon=False)
    top.set_title(caption, fontsize=10)
    if weights:
        relative = [p * len(p) for _, _, p in weights]
        positive = np.concatenate(relative)
        positive = positive[positive > 0]
        # a colour scale only where the probabilities differ: a panel whose strategy starts every episode
        # from p0 has none, and the reverse curriculum's few starts are often equally likely (one per demo
        # episode), which a collapsed scale would dress up as a gradient; a panel of equal ones says so
        varied = positive.size > 0 and not _all_equal(positive)
        norm = LogNorm(vmin=positive.min(), vmax=positive.max()) if varied else None
        points = None
        for i, ((step, success, _), rel) in enumerate(zip(weights, relative)):
            ax = fig.add_subplot(grid[1 + i // 2, i % 2])
            draw_maze(ax, layout)
            title = f"step {step:,.0f} (p0 success {success:.2f})"
            drawn = rel > 0
            if not drawn.all():
                # a sparse strategy (the reverse curriculum: one state per demo episode) or none at all:
                # the states it never starts from as small grey dots, so the few it does stand out
                ax.scatter(states[~drawn, 0], states[~drawn, 1], s=4, color="#9a9a9a", zorder=3, edgecolors="none")
                if not drawn.any():
                    title += ": every start from p0"
            if drawn.any() and _all_equal(rel[drawn]):
                title += ": one start state" if drawn.sum() == 1 else f": {drawn.sum()} equally likely start states"
            if drawn.any():
                order = np.flatnonzero(drawn)[np.argsort(rel[drawn])]  # the most likely starts drawn last, on top
                colours = (dict(c=np.clip(rel[order], norm.vmin, None), cmap="viridis", norm=norm) if varied
                           else dict(color="#3b528b"))
                drawn_points = ax.scatter(states[order, 0], states[order, 1], s=14 if drawn.all() else 40,
                                          zorder=3 if drawn.all() else 4,
                                          edgecolors="none" if drawn.all() else "black", **colours)
                points = drawn_points if varied else points
            ax.set_title(title, fontsize=9)
        if points is not None:
            fig.colorbar(points, ax=fig.axes[1:], shrink=0.8,
                         label="start probability x number of states (1 = uniform)")
    return fig


DPI = 130
"""Pixels per inch of the PNG figures."""
PALETTE_COLOURS = 256
"""Most colours of a PNG figure: its lines, bands and their antialiased edges fit, in about a quarter of full
colour's bytes."""


def png_bytes(fig) -> bytes:
    """The figure as a palette PNG (at most `PALETTE_COLOURS` colours) with no text chunk in it: the same
    figure gives the same bytes."""
    from PIL import Image

    rendered = io.BytesIO()
    fig.savefig(rendered, format="png", dpi=DPI)
    rendered.seek(0)
    # maximum coverage keeps every line's colour within a few levels of its own, and the quantizer maps each
    # pixel to its nearest palette entry without dithering, so lines stay crisp; Pillow writes no text chunk
    image = Image.open(rendered).convert("RGB").quantize(PALETTE_COLOURS, method=Image.Quantize.MAXCOVERAGE)
    written = io.BytesIO()
    image.save(written, format="PNG", optimize=True)
    return written.getvalue()


def save_figure(fig, out: Path, name: str, pdf: bool = False) -> list[Path]:
    """`name`.png in `out` (`png_bytes`) and, with `pdf`, `name`.pdf, each written atomically."""
    from lava_bridge_mj.eval.training.atomic import atomic_write

    png = out / f"{name}.png"
    data = png_bytes(fig)
    atomic_write(png, lambda f: f.write(data))
    paths = [png]
    if pdf:
        # no creation date in the PDF: the same data must give the same bytes, or every `make report`
        # shows every figure as changed
        path = out / f"{name}.pdf"
        atomic_write(path, lambda f: fig.savefig(f, format="pdf", dpi=DPI, metadata={"CreationDate": None}))
        paths.append(path)
    _pyplot().close(fig)
    return paths


def maze_layout(run: RunRecord):
    """The maze of the run's env settings; ValueError naming its config.json when they make none."""
    import lava_bridge_mj

    fields = {f.name for f in dataclasses.fields(lava_bridge_mj.Layout)}
    env = run.config.get("env", {})
    try:  # the task's layout with any layout field the run's env settings change
        return dataclasses.replace(lava_bridge_mj.task_layout(run.task), **{k: v for k, v in env.items() if k in fields})
    except (AttributeError, TypeError, ValueError) as error:
        raise ValueError(f"{run.path / 'config.json'}: its env settings make no maze ({error})") from None
