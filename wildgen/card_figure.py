"""The dataset card's picture (stats.png), drawn with matplotlib from the numbers of `wildgen.card` (what
stats.json holds): a header and 3 x 3 panels, each an Axes whose title's first line names it. Visible normals
(n_x, n_y) and light directions (azimuth, elevation) are 2-D histograms with empty bins white and a colour bar;
the angle to the view axis, distances of near lights and exposures are histograms; light strengths a range
(min - max, median dot) per type on a log axis; lights per type and per image, and materials, detail and
light families, horizontal bars (each group scaled to its largest value, its numbers written beside); the
camera, sensor and levels a list of lines."""
from __future__ import annotations

import textwrap

import numpy as np

PANEL_W, PANEL_H, HEADER_H = 540, 400, 56
"""Pixels of one panel and of the header."""
GREY, BLUE = "0.43", "#1f77b4"
TITLES = ("Visible normals (n_x, n_y)", "Angle between normal and view axis", "Directions toward the lights",
          "Lights by type and per image", "Distance of near lights from the object centre", "Light strengths by type",
          "Exposure per image", "Materials, detail and light families", "Camera, sensor, levels")
"""The first line of each panel's title, in reading order."""


def _title(ax, title: str, subtitle: str = "") -> None:
    ax.set_title(title + ("\n" + subtitle if subtitle else ""), loc="left", fontsize=9)


def _note(ax, lines: list[str]) -> None:
    """Grey lines inside the plot area, top right."""
    ax.text(0.98, 0.96, "\n".join(lines), transform=ax.transAxes, ha="right", va="top", fontsize=8, color=GREY,
            bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.85})


def _heat(fig, ax, xedges, yedges, counts, unit: str) -> None:
    """counts[i, j]: x bin i, y bin j; empty bins white; a colour bar (0 to the largest count) in `unit`."""
    import matplotlib

    counts = np.asarray(counts, np.float64).T  # rows: y bins
    colours = matplotlib.colormaps["viridis"].with_extremes(bad="white")
    mesh = ax.pcolormesh(xedges, yedges, np.ma.masked_equal(counts, 0), cmap=colours, vmin=0.0,
                         vmax=max(float(counts.max()), 1.0))
    fig.colorbar(mesh, ax=ax, label=unit)


def _histogram(ax, edges, counts, xlabel: str, ylabel: str, log: bool = False) -> None:
    """Bars of `counts` between `edges` (with `log`: edges are log10 values, the axis is logarithmic)."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    edges = 10.0 ** np.asarray(edges) if log else np.asarray(edges)
    ax.bar(edges[:-1], counts, width=np.diff(edges), align="edge", color=BLUE)
    if log:
        ax.set_xscale("log")
        plain = FuncFormatter(lambda v, _: f"{v:.4g}")
        ax.xaxis.set_major_formatter(plain)
        ax.xaxis.set_minor_formatter(plain)
    ax.set_xlim(edges[0], edges[-1])
    ax.set_ylim(0, max(float(np.max(counts)), 1.0) * 1.25)  # room for the note above the bars
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set(xlabel=xlabel, ylabel=ylabel)


def _categories(ax, groups: list[tuple[str, list[tuple[str, float, str]]]]) -> None:
    """Horizontal bars: per group a grey header and rows (label, value, note written after the bar), each
    group's bars scaled to its largest value."""
    labels, y = [], 0
    for header, items in groups:
        labels.append((y, header, True))
        y -= 1
        top = max([v for _, v, _ in items] + [1e-12])
        for label, value, note in items:
            ax.barh(y, value / top, height=0.6, color=BLUE)
            ax.text(value / top + 0.02, y, note, va="center", fontsize=8)
            labels.append((y, label, False))
            y -= 1
    ax.set_yticks([p for p, _, _ in labels], [t for _, t, _ in labels], fontsize=8)
    for tick, (_, _, header) in zip(ax.get_yticklabels(), labels):
        if header:
            tick.set_color(GREY)
    ax.tick_params(axis="y", length=0)
    ax.set_xlim(0, 2.2)
    ax.set_ylim(y + 0.5, 0.5)
    ax.xaxis.set_visible(False)
    for side in ("top", "right", "bottom"):
        ax.spines[side].set_visible(False)


def _normals(fig, ax, stats: dict) -> None:
    from matplotlib.patches import Circle

    n = stats["normals"]
    _title(ax, TITLES[0], f"{n['pixels']} mask pixels of {stats['objects']} objects; camera frame, +y up")
    h = n["nx_ny_histogram"]
    _heat(fig, ax, h["nx_edges"], h["ny_edges"], h["counts"], "pixels")
    ax.add_patch(Circle((0, 0), 1.0, fill=False, color=GREY))
    ax.set(xlim=(-1, 1), ylim=(-1, 1), aspect="equal", xlabel="n_x (right)", ylabel="n_y (up)")


def _angle(fig, ax, stats: dict) -> None:
    a = stats["normals"]["angle_to_view_axis_deg"]
    counts, edges = np.asarray(a["counts"]), np.asarray(a["edges"])
    beyond = int(counts[edges[:-1] >= 90].sum())
    _title(ax, TITLES[1], "0 = facing the camera, 90 = seen edge-on")
    _histogram(ax, edges, counts, "angle to the view axis (degrees)", "pixels")
    ax.set_xlim(0, 90 if beyond == 0 else 180)
    notes = [f"min {a['min']:.1f}, median {a['median']:.1f}, max {a['max']:.1f} deg"] if a["median"] is not None else []
    _note(ax, notes + ([f"{beyond} pixels beyond 90 deg"] if beyond else []))


def _directions(fig, ax, stats: dict) -> None:
    d = stats["lights"]["directions"]
    _title(ax, TITLES[2], f"{d['lights']} lights, camera frame; environment / uniform lights have none "
                          f"({d['without_direction']})")
    _heat(fig, ax, d["azimuth_edges"], d["elevation_edges"], d["counts"], "lights")
    ax.set(xlim=(-180, 180), ylim=(-90, 90), xticks=[-180, -90, 0, 90, 180], yticks=[-90, -45, 0, 45, 90],
           xlabel="azimuth (degrees; 0 = right, 90 = up)", ylabel="elevation (90 = from the camera)")


def _lights_per_image(fig, ax, stats: dict) -> None:
    per_type, images = stats["lights"]["per_type"], stats["images"]
    items = []
    for t, e in per_type.items():
        present = [int(k) for k in e["per_image"] if int(k) > 0]
        if present:
            span = f"{min(present)}-{max(present)}" if min(present) < max(present) else f"{min(present)}"
            note = f"{e['lights']} in {e['images_with']}/{images} images, {span} per image"
        else:
            note = "none"
        items.append((t, float(e["lights"]), note))
    totals = [(f"{k} light{'s' if k != '1' else ''}", float(n), f"{n} image{'s' if n != 1 else ''}")
              for k, n in stats["lights"]["per_image"].items()]
    _title(ax, TITLES[3], f"{stats['lights']['total']} lights in {images} images")
    _categories(ax, [("light type: lights in all images", items), ("lights in one image", totals)])


def _distance(fig, ax, stats: dict) -> None:
    d = stats["lights"]["distances"]
    _title(ax, TITLES[4], f"{d['count']} {' / '.join(d['types']) or 'point / area'} lights")
    if d["count"] == 0:
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no point or area lights in this dataset", ha="center", color=GREY)
        return
    _histogram(ax, d["edges"], d["counts"], f"distance ({d['unit']})", "lights")
    _note(ax, [f"min {d['min']:.3g}, median {d['median']:.3g}, max {d['max']:.3g}"])


def _strength(fig, ax, stats: dict) -> None:
    """Per light type the range (min to max) and median of its strength on a log axis."""
    s = stats["lights"]["strength"]
    _title(ax, TITLES[5], "min - max, dot at the median; each type in its own unit")
    ax.set_xscale("log")
    rows = list(s.items())
    for k, (t, e) in enumerate(rows):
        y = len(rows) - k
        if e["max"] <= 0:
            ax.text(0.02, y, "all zero", transform=ax.get_yaxis_transform(), va="center", color=GREY)
            continue
        low = e["min"] if e["min"] > 0 else e["max"]
        ax.hlines(y, low, e["max"], color=BLUE, linewidth=3)
        if e["median"] > 0:
            ax.plot([e["median"]], [y], "o", color="black")
        ax.annotate(f"n={e['count']}", (e["max"], y), xytext=(6, 6), textcoords="offset points", fontsize=8,
                    color=GREY)
    ax.set_yticks(range(len(rows), 0, -1), [f"{t} ({e['field']})" for t, e in rows], fontsize=8)
    ax.set_ylim(0, len(rows) + 1)
    ax.set_xlabel("strength (log scale)")


def _exposure(fig, ax, stats: dict) -> None:
    e = stats["exposure"]
    _title(ax, TITLES[6], "factor applied to the radiance before the image is written")
    _histogram(ax, e["log10_edges"], e["counts"], "exposure (log scale)", "images", log=True)
    _note(ax, [f"min {e['min']:.3g}, median {e['median']:.3g}, max {e['max']:.3g}"])


def _materials(fig, ax, stats: dict) -> None:
    n = stats["objects"]
    groups = [(title, [(k, float(v), f"{v} ({100.0 * v / n:.0f}%)") for k, v in stats[key].items()])
              for title, key in (("material class", "materials"), ("surface detail", "detail"),
                                 ("light family", "light_families"))]
    _title(ax, TITLES[7], f"{n} objects")
    _categories(ax, groups)


def _capture_lines(stats: dict) -> list[tuple[str, str]]:
    """(label, value) lines of the camera, sensor and levels panel."""
    cam = stats["camera"]

    def listed(counts: dict) -> str:
        return ", ".join(f"{k}: {v}" for k, v in counts.items())

    def spread(s: dict, unit: str) -> str:
        if s["min"] == s["max"]:
            return f"{s['min']:.3g} {unit}".strip()
        return f"{s['min']:.3g} - {s['max']:.3g} {unit} (median {s['median']:.3g})"

    levels = stats["levels"]
    return [("camera", listed(cam["kinds"])),
            ("field of view", spread(cam["fov_deg"], "deg") if cam["fov_deg"]["count"] else "orthographic only"),
            ("focal length", cam["focal_mm"] if isinstance(cam["focal_mm"], str) else
             spread(cam["focal_mm"], "mm") + " (35 mm equiv.)"),
            ("resolution", listed(cam["resolutions"])),
            ("images per object", spread(cam["images_per_object"], "")),
            ("sensor", listed(stats["sensors"])),
            ("objects per scene", listed(stats["objects_per_scene"])),
            ("level", levels if isinstance(levels, str) else listed(levels["counts"])),
            ("objects read", str(stats["objects"])),
            ("could not be read",
             f"{len(stats['failed'])}" + (" (see stats.json 'failed')" if stats["failed"] else ""))]


def _capture(fig, ax, stats: dict) -> None:
    _title(ax, TITLES[8])
    ax.set_axis_off()
    y = 0.97
    for label, value in _capture_lines(stats):
        ax.text(0.0, y, label, transform=ax.transAxes, va="top", fontsize=9, color=GREY)
        wrapped = textwrap.wrap(str(value), 40) or [""]
        ax.text(0.38, y, "\n".join(wrapped), transform=ax.transAxes, va="top", fontsize=9, linespacing=1.5)
        y -= 0.075 * len(wrapped)


PANELS = (_normals, _angle, _directions, _lights_per_image, _distance, _strength, _exposure, _materials, _capture)


def draw_stats(stats: dict):
    """The dataset card as a matplotlib Figure (3 x 3 panels under a header) from stats.json's numbers."""
    from scenes.report.charts import new_figure

    fig = new_figure(3 * PANEL_W, HEADER_H + 3 * PANEL_H, layout="constrained")
    failed = f", {len(stats['failed'])} could not be read" if stats["failed"] else ""
    fig.suptitle(f"Dataset card: {stats['dataset']}\n{stats['objects']} objects{failed}, {stats['images']} images",
                 x=0.01, ha="left", fontsize=12)
    for draw, ax in zip(PANELS, fig.subplots(3, 3).ravel()):
        draw(fig, ax, stats)
    return fig
