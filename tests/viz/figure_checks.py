"""Checks that a drawn matplotlib figure reads: ``problems(fig)`` lists, in words, every

(a) pair of texts whose glyph boxes overlap (tick labels, titles, axis labels, annotations, legend
    texts, the figure's own texts; a rotated text as its rotated box);
(b) legend whose box covers a data artist: a line's vertex or segment, a scatter's point, a bar,
    an image, in display coordinates;
(c) text that leaves the figure, or an annotation that leaves its axes;
(d) pair of panels showing the same quantity (the same axis label) on different scales (log
    beside linear).

``assert_reads(fig)`` fails with that list. Texts with nothing to show (empty, invisible, a tick
label the axis does not draw) are left out."""

from __future__ import annotations

import itertools

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PathCollection
from matplotlib.image import AxesImage
from matplotlib.patches import Patch
from matplotlib.text import Text
from matplotlib.transforms import Bbox

TOLERANCE = 0.5   # pixels: boxes that merely touch do not overlap


def _drawn_tick_labels(fig) -> tuple[set[int], set[int]]:
    """ids of every tick label, and of those the axes draw (ticks within the view, label on)."""
    every, drawn = set(), set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                every |= {id(tick.label1), id(tick.label2)}
            if ax.axison:
                for tick in axis._update_ticks():   # the ticks the axis draws (within its view)
                    drawn |= {id(t) for t in (tick.label1, tick.label2) if t.get_visible() and tick.get_visible()}
    return every, drawn


def _shown(text: Text) -> bool:
    """Whether a text is drawn: visible, non-empty, and every ancestor up to its axes visible."""
    if not text.get_visible() or not text.get_text().strip():
        return False
    ax = text.axes
    return ax is None or (ax.get_visible() and (ax.axison or text in ax.texts or text is ax.title))


def texts(fig) -> list[Text]:
    """Every text the figure draws."""
    every, drawn = _drawn_tick_labels(fig)
    out = []
    for t in fig.findobj(Text):
        if id(t) in every and id(t) not in drawn:
            continue
        if _shown(t):
            out.append(t)
    return list(dict.fromkeys(out))


def _corners(text: Text, renderer) -> np.ndarray:
    """(4, 2) display corners of a text's rotated box: the unrotated size, turned by its rotation
    about the centre of its (axis-aligned) window extent, which is the rotated box's centre."""
    box = Text.get_window_extent(text, renderer)   # an annotation's own would hold its arrow
    angle = np.radians(text.get_rotation())
    if abs(np.sin(2 * angle)) < 1e-9:
        return np.array([[box.x0, box.y0], [box.x1, box.y0], [box.x1, box.y1], [box.x0, box.y1]])
    flat = Text(0, 0, text.get_text(), fontproperties=text.get_fontproperties(), linespacing=text.get_linespacing())
    flat.set_figure(text.figure)
    size = flat.get_window_extent(renderer)
    half = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [size.width / 2, size.height / 2]
    turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    return half @ turn.T + [(box.x0 + box.x1) / 2, (box.y0 + box.y1) / 2]


def _separated(p: np.ndarray, q: np.ndarray) -> bool:
    """Whether two convex polygons (k, 2) are apart by more than ``TOLERANCE`` along some edge normal."""
    for poly in (p, q):
        edges = np.roll(poly, -1, axis=0) - poly
        for normal in np.column_stack([-edges[:, 1], edges[:, 0]]):
            norm = np.hypot(*normal)
            if norm == 0:
                continue
            a, b = p @ normal / norm, q @ normal / norm
            if a.max() <= b.min() + TOLERANCE or b.max() <= a.min() + TOLERANCE:
                return True
    return False


def _name(text: Text) -> str:
    where = f" in {text.axes.get_title()!r}" if text.axes is not None and text.axes.get_title() else ""
    return f"{text.get_text()!r}{where}"


def _overlapping_texts(fig, renderer) -> list[str]:
    shown = [(t, _corners(t, renderer)) for t in texts(fig)]
    return [f"text {_name(a)} overlaps text {_name(b)}" for (a, pa), (b, pb) in itertools.combinations(shown, 2)
            if not _separated(pa, pb)]


def _outside(fig, renderer) -> list[str]:
    width, height = fig.bbox.width, fig.bbox.height
    out = []
    for t in texts(fig):
        c = _corners(t, renderer)
        if c.min() < -TOLERANCE or c[:, 0].max() > width + TOLERANCE or c[:, 1].max() > height + TOLERANCE:
            out.append(f"text {_name(t)} leaves the figure")
    for ax in fig.axes:
        box = ax.bbox
        for t in ax.texts:
            if _shown(t):
                c = _corners(t, renderer)
                if (c[:, 0].min() < box.x0 - TOLERANCE or c[:, 0].max() > box.x1 + TOLERANCE
                        or c[:, 1].min() < box.y0 - TOLERANCE or c[:, 1].max() > box.y1 + TOLERANCE):
                    out.append(f"annotation {_name(t)} leaves its axes")
    return out


def _drawn_points(ax) -> np.ndarray:
    """(k, 2) display coordinates of an axes' data as drawn: every vertex of its lines and line
    collections and the points between them (sampled finely), every scatter point; clipped to the
    axes where the artist is."""
    out = []

    def add(xy: np.ndarray, clipped: bool) -> None:
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if len(xy) > 1:
            steps = np.linspace(0, 1, 25)[:, None, None]
            xy = (xy[:-1] + steps * (xy[1:] - xy[:-1])).reshape(-1, 2)
        if clipped:
            box = ax.bbox
            xy = xy[(xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1) & (xy[:, 1] >= box.y0) & (xy[:, 1] <= box.y1)]
        out.append(xy)

    for line in ax.lines:
        if line.get_visible() and len(line.get_xydata()):
            add(line.get_transform().transform(line.get_xydata()), line.get_clip_on())
    for coll in ax.collections:
        if not coll.get_visible():
            continue
        if isinstance(coll, LineCollection):
            for seg in coll.get_segments():
                if len(seg):
                    add(coll.get_transform().transform(seg), coll.get_clip_on())
        elif isinstance(coll, PathCollection) and len(coll.get_offsets()):
            for p in coll.get_offset_transform().transform(coll.get_offsets()):
                add(p[None], coll.get_clip_on())
    return np.concatenate(out) if out else np.zeros((0, 2))


def _inside(points: np.ndarray, box) -> bool:
    return bool(((points[:, 0] > box.x0 + TOLERANCE) & (points[:, 0] < box.x1 - TOLERANCE)
                 & (points[:, 1] > box.y0 + TOLERANCE) & (points[:, 1] < box.y1 - TOLERANCE)).any())


def _boxes(ax, renderer) -> list:
    """Window extents of an axes' bars, shaded spans and images."""
    artists = [p for p in ax.patches if isinstance(p, Patch)] + [i for i in ax.images if isinstance(i, AxesImage)]
    out = []
    for a in artists:
        if a.get_visible():
            box = a.get_window_extent(renderer)
            box = Bbox.intersection(box, ax.bbox) if a.get_clip_on() else box
            if box is not None:
                out.append(box)
    return out


def _covered_data(fig, renderer) -> list[str]:
    legends = [lg for lg in fig.legends] + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    out = []
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            if not ax.get_visible() or not ax.axison:
                continue
            if _inside(_drawn_points(ax), box):
                out.append(f"a legend covers the lines or points of {ax.get_title()!r}")
            for b in _boxes(ax, renderer):
                common = Bbox.intersection(b, box)
                if common is not None and common.width > TOLERANCE and common.height > TOLERANCE:
                    out.append(f"a legend covers a bar, span or image of {ax.get_title()!r}")
                    break
    return out


def _mixed_scales(fig) -> list[str]:
    out = []
    shown = [ax for ax in fig.axes if ax.get_visible() and ax.axison]
    for which in ("x", "y"):
        by_label: dict[str, set[str]] = {}
        for ax in shown:
            label = getattr(ax, f"get_{which}label")().strip()
            if label:
                by_label.setdefault(label, set()).add(getattr(ax, f"get_{which}scale")())
        out += [f"panels of {which} {label!r} mix {' and '.join(sorted(s))} scales"
                for label, s in by_label.items() if len(s) > 1]
    return out


def problems(fig) -> list[str]:
    """Every way ``fig`` fails to read (module docstring), in words; empty when it reads."""
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    return (_overlapping_texts(fig, renderer) + _covered_data(fig, renderer) + _outside(fig, renderer)
            + _mixed_scales(fig))


def assert_reads(fig) -> None:
    """Fail with every problem of ``fig`` (``problems``)."""
    found = problems(fig)
    assert not found, "the figure does not read:\n" + "\n".join(found)

