"""The default layout of a run's recording (a Rerun blueprint) and what frames its views: per
task a grid of near-square scene panels and the rollout, each opening on its scene's extent,
beside the curves, the legend and the run card.
"""

from __future__ import annotations

import math

import numpy as np

from c2inet.lazy import lazy_module

rrb = lazy_module("rerun.blueprint")  # a run that does not record never loads Rerun

Bounds = tuple[float, float, float, float]  # x_min, x_max, y_min, y_max
SCENE_COLUMNS = 3  # the scenes and the rollout in a grid of near-square panels


def curve_views(methods: list[str]) -> list[tuple[str, list[str]]]:
    """(name, entity filters) of the curve views. Filters name each method: Rerun matches a
    trailing ``/**`` only, a ``*`` inside a path matches nothing."""
    losses = ("nll", "kl_c", "kl_z", "penalty")
    return [
        ("validation ADE (m) by epoch", [f"/curves/{m}/val_ade/**" for m in methods]),
        ("error matrix rows: ADE (m) by epoch", [f"/curves/{m}/matrix/ade/**" for m in methods]),
        ("training losses by epoch", [f"/curves/{m}/{loss}" for m in methods for loss in losses]),
    ]


def framed(origin: str, name: str, bounds: dict[str, Bounds]) -> rrb.Spatial2DView:
    """A 2-D view of ``origin`` opening on its ``bounds`` (the scene's extent with a margin),
    so no scene is cut at the panel's edges; the viewer's own framing where none is known."""
    box = bounds.get(origin)
    visual = None if box is None else rrb.VisualBounds2D(x_range=box[:2], y_range=box[2:])
    return rrb.Spatial2DView(origin=origin, name=name, visual_bounds=visual)


def extent(points: np.ndarray, margin: float = 0.08) -> Bounds:
    """The bounds of ``points`` (..., 2; NaN ignored), square, with ``margin`` of their size on
    every side (at least 1 m across)."""
    flat = points.reshape(-1, 2)
    flat = flat[np.isfinite(flat).all(1)]
    if not len(flat):  # nothing recorded: a metre around the origin
        return (-1.0, 1.0, -1.0, 1.0)
    low, high = flat.min(0), flat.max(0)
    centre, half = (low + high) / 2, max(float((high - low).max()) / 2, 0.5) * (1 + 2 * margin)
    return (centre[0] - half, centre[0] + half, centre[1] - half, centre[1] + half)


def scale_bar(box: Bounds) -> tuple[float, np.ndarray]:
    """A scale bar for a view of ``box``: a round length (1, 2 or 5 times a power of ten
    metres) of at most a quarter of its width, as a polyline with end ticks in its top-left
    corner (the viewer draws y downward), inside the margin ``extent`` leaves."""
    width = box[1] - box[0]
    power = 10 ** math.floor(math.log10(width / 4))
    length = max(m * power for m in (1, 2, 5) if m * power <= width / 4)
    x0, y0, tick = box[0] + 0.03 * width, box[2] + 0.03 * width, 0.012 * width
    corners = [(x0, y0 + tick), (x0, y0), (x0 + length, y0), (x0 + length, y0 + tick)]
    return length, np.array(corners)


def default_blueprint(
    tasks: list[str], methods: list[str], scenes: int, bounds: dict[str, Bounds] | None = None
) -> rrb.Blueprint:
    """Per task a tab: its sample scenes and its rollout in a grid of near-square panels, each
    framed on its ``bounds`` (origin -> extent), so a scene fills its panel; beside them the
    curves and diagnostics, then the legend and the run card. The viewer opens on the
    ``epoch`` timeline, where the curves live and every view shows the latest predictions."""
    bounds = bounds or {}
    tabs = [
        rrb.Grid(
            *(framed(f"/tasks/{task}/scenes/{k}", f"scene {k}", bounds) for k in range(scenes)),
            framed(f"/rollouts/{task}", "rollout", bounds),
            grid_columns=min(SCENE_COLUMNS, scenes + 1),
            name=task,
        )
        for task in tasks
    ]
    curves = curve_views(methods)
    # no legend inside the plots: with a curve per task and method it covers the curves wherever
    # it sits; the legend document beside them names the colours and shades instead
    no_legend = rrb.PlotLegend(visible=False)
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(*tabs),
            rrb.Vertical(
                rrb.Tabs(
                    *(
                        rrb.TimeSeriesView(
                            origin="/curves", contents=c, name=n, plot_legend=no_legend
                        )
                        for n, c in curves
                    ),
                    rrb.TimeSeriesView(origin="/diagnostics", name="diagnostics after each task"),
                ),
                rrb.Tabs(
                    rrb.TextDocumentView(origin="/legend", name="legend"),
                    rrb.TextDocumentView(origin="/run_card", name="run card"),
                ),
            ),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline="epoch", state="collapsed"),
        collapse_panels=True,
    )
