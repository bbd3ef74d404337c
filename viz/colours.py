"""One colour per method, the same in the recording and in every figure.

Ground truth keeps grey (observed) and green (future); methods take the colours of a
colour-blind-aware palette (matplotlib's tab10 without its grey and green, then further tones),
in the run's order.
"""

from __future__ import annotations

OBSERVED = (150, 150, 150)
FUTURE = (40, 170, 60)
PALETTE_NAMES = (  # matplotlib's tab10, then tab20's light tones and four of tab20b
    ((31, 119, 180), "blue"),
    ((255, 127, 14), "orange"),
    ((148, 103, 189), "purple"),
    ((214, 39, 40), "red"),
    ((140, 86, 75), "brown"),
    ((227, 119, 194), "pink"),
    ((188, 189, 34), "olive"),
    ((23, 190, 207), "cyan"),
    ((57, 59, 121), "navy"),
    ((140, 109, 49), "ochre"),
    ((132, 60, 57), "maroon"),
    ((123, 65, 115), "plum"),
    ((174, 199, 232), "light blue"),
    ((255, 187, 120), "light orange"),
    ((197, 176, 213), "light purple"),
    ((255, 152, 150), "light red"),
    ((196, 156, 148), "light brown"),
    ((247, 182, 210), "light pink"),
    ((219, 219, 141), "light olive"),
    ((158, 218, 229), "light cyan"),
)
PALETTE = tuple(rgb for rgb, _ in PALETTE_NAMES)
NAMES = tuple(name for _, name in PALETTE_NAMES)


def method_colour(index: int) -> tuple[int, int, int]:
    """The colour of the run's ``index``-th method: twenty distinct ones, enough for every
    registered method at once (``--methods all``); the palette repeats after that."""
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
