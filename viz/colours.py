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


def mix(rgb: tuple[int, int, int], other: tuple[int, int, int], share: float):
    """``rgb`` moved ``share`` of the way to ``other`` (0: itself, 1: other)."""
    return tuple(round(c + share * (o - c)) for c, o in zip(rgb, other, strict=True))


def faint(rgb: tuple[int, int, int]) -> tuple[int, int, int]:
    """A sample line's colour: the method's, two thirds of the way to white. The viewer draws
    lines opaque whatever their alpha, so faintness has to be in the colour itself."""
    return mix(rgb, (255, 255, 255), 0.65)


def task_shade(rgb: tuple[int, int, int], index: int, count: int) -> tuple[int, int, int]:
    """The ``index``-th of ``count`` tasks' shade of a method's colour: from darker (the first
    task) to lighter (the last), so one method's task curves stay its own yet apart."""
    share = index / (count - 1) if count > 1 else 0.5
    return mix(mix(rgb, (0, 0, 0), 0.45), (255, 255, 255), 0.6 * share)


def as_matplotlib(rgb: tuple[int, int, int]) -> tuple[float, float, float]:
    return tuple(c / 255 for c in rgb)


def legend_markdown(methods: list[str], tasks: list[str] | None = None) -> str:
    """The legend of the scene views and the curves (which draw none of their own), as a text
    document."""
    rows = [f"- **{m}**: {colour_name(i)}" for i, m in enumerate(methods)]
    order = f" ({', '.join(tasks)})" if tasks else ""
    return (
        "## Legend\n\nObserved history: grey. True future: green. Predictions, one colour per "
        "method (the thin pale lines are the K samples, the thick one the best of K; the "
        "truth is drawn above them). The grey bar in each scene is its scale in metres. "
        f"Curves: one shade of its method's colour per task, from dark (the first task) to "
        f"light (the last){order}; hover over a curve for its name:\n\n" + "\n".join(rows) + "\n"
    )
