"""Region labels that never overlap (issue 29 item 1): "R1", "R2", ... beside each region, on a
leader line, each label placed where its drawn box meets no other label and stays inside the
plot; a region whose label finds no free place is left unlabelled in the picture (it is still
in the numbered list of the report's table).

:func:`place_labels` works on a matplotlib axes (PNG summary, PDF), measuring every label with
matplotlib's own text extents; :func:`free_labels` decides the same for labels whose size is
estimated (the HTML report's 3D view, drawn by the browser).
"""

from __future__ import annotations

import numpy as np

__all__ = ["OFFSETS", "place_labels", "free_labels", "boxes_overlap"]

#: where a label may sit relative to its region, in points (x right, y up): close first, then
#: farther out on a longer leader line
OFFSETS = tuple((dx * r, dy * r) for r in (1.0, 2.2, 3.6)
                for dx, dy in ((7, 7), (7, -17), (-27, 7), (-27, -17), (0, 14), (0, -24),
                               (14, 0), (-34, 0)))


def boxes_overlap(a, b, pad: float = 0.0) -> bool:
    """Whether boxes ``a`` and ``b`` (x0, y0, x1, y1) intersect, with ``pad`` around each.

    >>> boxes_overlap((0, 0, 1, 1), (2, 2, 3, 3)), boxes_overlap((0, 0, 1, 1), (0.5, 0.5, 2, 2))
    (False, True)
    """
    return not (a[2] + pad <= b[0] - pad or b[2] + pad <= a[0] - pad
                or a[3] + pad <= b[1] - pad or b[3] + pad <= a[1] - pad)


def place_labels(ax, anchors, texts, *, fontsize: float = 8.5, pad: float = 1.5):
    """Annotate ``ax`` with ``texts[i]`` at data point ``anchors[i]``, in order (most severe
    first), each at the first of :data:`OFFSETS` where its box overlaps no label placed before
    and lies inside the axes.

    Call it once the axes' limits are final (after every scatter; it draws the figure once to
    settle the limits and the aspect).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    anchors : (N, 2) array_like
        Data coordinates of the regions.
    texts : sequence of str
    fontsize : float
    pad : float
        Pixels kept free around each label.

    Returns
    -------
    list of (int, matplotlib.text.Annotation)
        The labels placed, with the index of their anchor; the others were left out.
    """
    fig = ax.figure
    if fig.canvas is None or not hasattr(fig.canvas, "get_renderer"):
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)
    fig.canvas.draw()                           # final limits (autoscale) and aspect
    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    taken, placed = [], []
    for i, ((x, y), text) in enumerate(zip(np.asarray(anchors, float), texts)):
        px, py = ax.transData.transform((x, y))
        if not (np.isfinite(px) and np.isfinite(py)) or not frame.contains(px, py):
            continue
        for dx, dy in OFFSETS:
            ann = ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset points",
                              fontsize=fontsize, weight="bold", va="bottom", ha="left",
                              bbox=dict(boxstyle="square,pad=0.1", fc="white", ec="none",
                                        alpha=0.75),
                              arrowprops=dict(arrowstyle="-", color="black", linewidth=0.6,
                                              shrinkA=0, shrinkB=0))
            box = _text_box(ann, renderer)
            inside = (box[0] >= frame.x0 and box[2] <= frame.x1 and box[1] >= frame.y0
                      and box[3] <= frame.y1)
            if inside and not any(boxes_overlap(box, t, pad) for t in taken):
                taken.append(box)
                placed.append((i, ann))
                break
            ann.remove()
    return placed


def _text_box(ann, renderer):
    """The drawn box of a label's text and its background (not its leader line)."""
    from matplotlib.text import Text

    ann.update_positions(renderer)              # where the offset puts the text
    bb = Text.get_window_extent(ann, renderer)
    patch = ann.get_bbox_patch()
    if patch is not None:
        ann.update_bbox_position_size(renderer)
        pb = patch.get_window_extent(renderer)
        bb = bb.union([bb, pb])
    return (bb.x0, bb.y0, bb.x1, bb.y1)


def free_labels(xy, widths, height: float, *, pad: float = 2.0):
    """Which labels to draw where each is estimated to be ``widths[i]`` by ``height`` (pixels)
    with its lower-left corner at ``xy[i]`` (pixels), in order: a label that would meet one
    kept before is dropped.

    >>> free_labels([(0, 0), (5, 2), (40, 0)], [20, 20, 20], 10)
    [0, 2]
    """
    kept, boxes = [], []
    for i, ((x, y), w) in enumerate(zip(np.asarray(xy, float), widths)):
        box = (x, y, x + w, y + height)
        if np.all(np.isfinite(box)) and not any(boxes_overlap(box, b, pad) for b in boxes):
            kept.append(i)
            boxes.append(box)
    return kept
