"""The report's pages as boxes in points: text wrapped by its measured width, never past its box.

Every piece of text the report draws from a record (an id as typed, a
station's name, a reason) goes through :func:`fit_text`: it is wrapped at
spaces (a word wider than the box is broken inside), set smaller when it
needs more lines than its box has, and only then shortened with an
ellipsis. Widths are measured with the font the PDF embeds (matplotlib's
TextToPath, the same advance widths a PDF reader uses), so what fits here
fits on paper; ``tests/records/test_report_layout.py`` reads every word's
box back from report.pdf and holds the page to that.

Positions are in points from the page's top-left corner, y downwards, as a
page is read; :class:`Page` turns them into matplotlib's figure fractions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.textpath import text_to_path

PAGE_WIDTH_PT, PAGE_HEIGHT_PT = 595.28, 841.89  # A4 portrait
MARGIN_PT = 42.5  # 15 mm: the layout's own margin (the test holds every word 10 mm inside the paper's edge)
CONTENT_WIDTH_PT = PAGE_WIDTH_PT - 2 * MARGIN_PT
ELLIPSIS = "\u2026"
_WIDTH_SLACK = 0.985  # measured widths agree with the PDF's to 0.1 %: 1.5 % spare
_ASCENT, _DESCENT = 0.74, 0.27  # a PDF reader's box of a line, in font sizes above and below its baseline
GREY = "0.35"


def line_pitch_pt(size_pt: float) -> float:
    """Baseline to baseline: the reader's boxes of two lines (one font size tall each) at least 3 pt apart."""
    return size_pt * 1.15 + 3.0


def first_baseline_pt(top_pt: float, size_pt: float) -> float:
    """The baseline of a line whose box starts at ``top_pt``."""
    return top_pt + _ASCENT * size_pt


def block_height_pt(lines: int, size_pt: float) -> float:
    """Height of ``lines`` lines from the top of the first box to the bottom of the last."""
    return (lines - 1) * line_pitch_pt(size_pt) + (_ASCENT + _DESCENT) * size_pt if lines else 0.0


@lru_cache(maxsize=8192)
def text_width_pt(text: str, size_pt: float, bold: bool = False, mono: bool = False) -> float:
    """Width of ``text`` as the PDF sets it (no formula parsing: ids are drawn as typed)."""
    prop = FontProperties(family="monospace" if mono else "sans-serif", size=size_pt,
                          weight="bold" if bold else "normal")
    width, _, _ = text_to_path.get_text_width_height_descent(text, prop, ismath=False)
    return float(width)


@dataclass(frozen=True)
class Fitted:
    """Text fitted into a box: its lines, the size they are set at, and whether it had to be shortened."""

    lines: tuple[str, ...]
    size_pt: float
    shortened: bool = False

    @property
    def height_pt(self) -> float:
        """From the top of the first line's box to the bottom of the last's."""
        return block_height_pt(len(self.lines), self.size_pt)


def fit_text(text: str, width_pt: float, size_pt: float, *, max_lines: int = 1, min_size_pt: float | None = None,
             bold: bool = False, mono: bool = False) -> Fitted:
    """Fit ``text`` into ``max_lines`` lines of ``width_pt``.

    Parameters
    ----------
    text : str
        As the record holds it; runs of spaces are set as one.
    width_pt : float
        The box's width.
    size_pt : float
        The font size wanted.
    max_lines : int
        The most lines the box has room for.
    min_size_pt : float, optional
        Set the text smaller, down to this size, before shortening it (default: never smaller).
    bold, mono : bool
        Bold; a fixed-width font (digests).

    Returns
    -------
    Fitted
        Wrapped at spaces, a word wider than the box broken inside; at the
        smallest size that still needs more lines, the last line ends in an
        ellipsis.
    """
    size = size_pt
    while True:
        lines = wrap_to_width(text, width_pt, size, bold=bold, mono=mono)
        if len(lines) <= max_lines:
            return Fitted(tuple(lines), size)
        smaller = round(size - 0.5, 2)
        if min_size_pt is None or smaller < min_size_pt - 1e-9:
            break
        size = smaller
    # the last line holds as much of the rest as fits before the ellipsis (not just the line the wrap made)
    pieces = _wrap(text, width_pt, size, bold, mono)
    rest = "".join(separator + line for line, separator in pieces[max_lines - 1:]).strip()
    kept = [line for line, _ in pieces[:max_lines - 1]]
    kept.append(_with_ellipsis(rest, width_pt, size, bold, mono))
    return Fitted(tuple(kept), size, shortened=True)


def wrap_to_width(text: str, width_pt: float, size_pt: float, *, bold: bool = False,
                  mono: bool = False) -> list[str]:
    """Greedy wrap at spaces by measured width; a word wider than the box is broken inside (after a hyphen,
    slash, comma or underscore when there is one in the part that fits)."""
    return [line for line, _ in _wrap(text, width_pt, size_pt, bold, mono)]


def _wrap(text: str, width_pt: float, size_pt: float, bold: bool, mono: bool) -> list[tuple[str, str]]:
    """The lines, each with what stood before it in the text: a space, or nothing inside a broken word."""
    room = width_pt * _WIDTH_SLACK

    def fits(piece: str) -> bool:
        return text_width_pt(piece, size_pt, bold, mono) <= room

    lines: list[tuple[str, str]] = []
    current, separator = "", ""
    for word in text.split() or ["-"]:
        candidate = f"{current} {word}" if current else word
        if fits(candidate):
            current = candidate
            continue
        if current:
            lines.append((current, separator))
            separator = " "
        while not fits(word):
            head = _longest_fitting_head(word, fits)
            lines.append((word[:head], separator))
            word, separator = word[head:], ""
        current = word
    lines.append((current, separator))
    return lines


def _longest_fitting_head(word: str, fits: Callable[[str], bool], at_breaks: bool = True) -> int:
    """How many leading characters of ``word`` to put on a line (at least one, so wrapping always ends).

    ``fits(word)`` is false; with ``at_breaks``, the head ends after a hyphen, slash, comma, underscore or dot
    when one falls in its second half.
    """
    low, high = 1, len(word)  # fits(word[:low]) assumed (one character), not fits(word[:high])
    while high - low > 1:
        middle = (low + high) // 2
        if fits(word[:middle]):
            low = middle
        else:
            high = middle
    if not at_breaks:
        return low
    breaks = [n + 1 for n, char in enumerate(word[:low]) if char in "-/,_." and n + 1 < low]
    return breaks[-1] if breaks and breaks[-1] >= low // 2 else low


def _with_ellipsis(text: str, width_pt: float, size_pt: float, bold: bool, mono: bool) -> str:
    """The longest head of ``text`` that fits with an ellipsis after it."""
    room = width_pt * _WIDTH_SLACK
    head = _longest_fitting_head(text + " ", lambda piece: text_width_pt(piece.rstrip() + ELLIPSIS, size_pt, bold,
                                                                          mono) <= room, at_breaks=False)
    return text[:head].rstrip() + ELLIPSIS


class Page:
    """An A4 page drawn on in points from its top-left corner, y downwards."""

    def __init__(self) -> None:
        self.figure = Figure(figsize=(PAGE_WIDTH_PT / 72, PAGE_HEIGHT_PT / 72))

    def _xy(self, x_pt: float, y_pt: float) -> tuple[float, float]:
        return x_pt / PAGE_WIDTH_PT, 1.0 - y_pt / PAGE_HEIGHT_PT

    def text(self, x_pt: float, baseline_pt: float, text: str, size_pt: float, *, bold: bool = False,
             mono: bool = False, colour: str = "black", align: str = "left") -> None:
        """One line of text, as given (no formula parsing: a '$' in an id is a '$')."""
        x, y = self._xy(x_pt, baseline_pt)
        self.figure.text(x, y, text, fontsize=size_pt, weight="bold" if bold else "normal",
                         family="monospace" if mono else "sans-serif", color=colour, ha=align, va="baseline",
                         parse_math=False)

    def lines(self, x_pt: float, top_pt: float, fitted: Fitted, *, bold: bool = False, mono: bool = False,
              colour: str = "black", align: str = "left") -> float:
        """Draw fitted lines, each a text of its own at a measured pitch; return the bottom of the last line."""
        baseline = first_baseline_pt(top_pt, fitted.size_pt)
        for line in fitted.lines:
            self.text(x_pt, baseline, line, fitted.size_pt, bold=bold, mono=mono, colour=colour, align=align)
            baseline += line_pitch_pt(fitted.size_pt)
        return top_pt + fitted.height_pt

    def paragraph(self, x_pt: float, top_pt: float, text: str, width_pt: float, size_pt: float, *,
                  max_lines: int = 3, bold: bool = False, colour: str = "black") -> float:
        """Fit ``text`` into ``width_pt`` and draw it; return the bottom of its last line."""
        return self.lines(x_pt, top_pt, fit_text(text, width_pt, size_pt, max_lines=max_lines, bold=bold),
                          bold=bold, colour=colour)

    def rule(self, y_pt: float, x0_pt: float = MARGIN_PT, x1_pt: float = PAGE_WIDTH_PT - MARGIN_PT,
             colour: str = "0.6") -> None:
        """A thin horizontal line across the content."""
        (x0, y), (x1, _) = self._xy(x0_pt, y_pt), self._xy(x1_pt, y_pt)
        self.figure.add_artist(Line2D([x0, x1], [y, y], lw=0.6, color=colour))

    def box(self, x_pt: float, top_pt: float, width_pt: float, height_pt: float, colour: str) -> None:
        """A filled rectangle (the verdict's badge)."""
        x, y = self._xy(x_pt, top_pt + height_pt)
        self.figure.add_artist(Rectangle((x, y), width_pt / PAGE_WIDTH_PT, height_pt / PAGE_HEIGHT_PT,
                                         transform=self.figure.transFigure, facecolor=colour, edgecolor="none"))

    def axes(self, x_pt: float, top_pt: float, width_pt: float, height_pt: float) -> Axes:
        """Axes whose plotting area is exactly this box (ticks and labels are drawn outside it)."""
        x, y = self._xy(x_pt, top_pt + height_pt)
        return self.figure.add_axes((x, y, width_pt / PAGE_WIDTH_PT, height_pt / PAGE_HEIGHT_PT))


@dataclass(frozen=True)
class Rows:
    """Label and value rows fitted to their columns, ready to draw: their height is known before they are."""

    rows: tuple[tuple[Fitted, Fitted, bool], ...]  # label, value, value in a fixed-width font
    label_width_pt: float
    size_pt: float

    def _shift(self, value: Fitted) -> float:
        """How far a value set smaller moves down, so that its first baseline sits on its label's."""
        return _ASCENT * (self.size_pt - value.size_pt)

    @property
    def height_pt(self) -> float:
        """From the top of the first row to the bottom of the last."""
        heights = [max(label.height_pt, self._shift(value) + value.height_pt) for label, value, _ in self.rows]
        return sum(heights) + row_gap_pt(self.size_pt) * max(len(heights) - 1, 0)

    def draw(self, page: Page, x_pt: float, top_pt: float) -> float:
        """Draw the rows from ``top_pt`` down; return the bottom of the last."""
        y = top_pt
        for label, value, mono in self.rows:
            page.lines(x_pt, y, label, bold=True)
            page.lines(x_pt + self.label_width_pt, y + self._shift(value), value, mono=mono)
            y += max(label.height_pt, self._shift(value) + value.height_pt) + row_gap_pt(self.size_pt)
        return y - row_gap_pt(self.size_pt) if self.rows else y


def fit_rows(rows: list[tuple[str, str]], *, label_width_pt: float, value_width_pt: float, size_pt: float,
             max_lines: int = 3, min_size_pt: float | None = None,
             mono_labels: frozenset[str] = frozenset()) -> Rows:
    """Fit label and value rows: each row as tall as its longer side, the next row below it.

    A value that needs more than ``max_lines`` lines is set smaller (down to
    ``min_size_pt``), then shortened; a wrapped value never reaches the
    next label.
    """
    return Rows(tuple((fit_text(label, label_width_pt - 4.0, size_pt, max_lines=2, bold=True),
                       fit_text(value, value_width_pt, size_pt, max_lines=max_lines, min_size_pt=min_size_pt,
                                mono=label in mono_labels), label in mono_labels)
                      for label, value in rows), label_width_pt, size_pt)


def key_value_rows(page: Page, x_pt: float, top_pt: float, rows: list[tuple[str, str]], *, label_width_pt: float,
                   value_width_pt: float, size_pt: float, max_lines: int = 3, min_size_pt: float | None = None,
                   mono_labels: frozenset[str] = frozenset()) -> float:
    """Fit (:func:`fit_rows`) and draw label and value rows; return the bottom of the last."""
    return fit_rows(rows, label_width_pt=label_width_pt, value_width_pt=value_width_pt, size_pt=size_pt,
                    max_lines=max_lines, min_size_pt=min_size_pt, mono_labels=mono_labels).draw(page, x_pt, top_pt)


def row_gap_pt(size_pt: float) -> float:
    """The space between two rows, more than between a row's own lines."""
    return 0.45 * size_pt + 3.0
