"""One colour per method, the same in the recording and in every figure.

Ground truth keeps grey (observed) and green (future); methods take the colours of a
colour-blind-aware palette (matplotlib's tab10 without its grey and green), in the run's order.
"""

from __future__ import annotations

OBSERVED = (150, 150, 150)
FUTURE = (40, 170, 60)
PALETTE = (
    (31, 119, 180),  # blue
    (255, 127, 14),  # orange
    (148, 103, 189),  # purple
    (214, 39, 40),  # red
    (140, 86, 75),  # brown
    (227, 119, 194),  # pink
    (188, 189, 34),  # olive
    (23, 190, 207),  # cyan
)
NAMES = ("blue", "orange", "purple", "red", "brown", "pink", "olive", "cyan")


def method_colour(index: int) -> tuple[int, int, int]:
    """The colour of the run's ``index``-th method (the palette repeats after eight)."""
    return PALETTE[index % len(PALETTE)]


def colour_name(index: int) -> str:
    return NAMES[index % len(NAMES)]


def as_matplotlib(rgb: tuple[int, int, int]) -> tuple[float, float, float]:
    return tuple(c / 255 for c in rgb)


def legend_markdown(methods: list[str]) -> str:
    """The legend of the scene views, as a text document."""
    rows = [f"- **{m}**: {colour_name(i)}" for i, m in enumerate(methods)]
    return (
        "## Legend\n\nObserved history: grey. True future: green. Predictions, one colour per "
        "method (the faint lines are the K samples, the thick one the best of K):\n\n"
        + "\n".join(rows)
        + "\n"
    )
