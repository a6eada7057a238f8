"""report.html of `orchestrate.capture`: one self-contained page a person reads without the code (every picture
embedded as a PNG data URL, the styles inline): the verdict in words, what to improve in the capture, a
contact sheet of the photos, the mask (alone and over the photos) and the light variation, the normal map (before
and after refinement where it was refined), the re-render residual of the physical check, and the details."""
from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

import numpy as np

HEADER_RGB = (31, 78, 121)
"""The colour of the page's title band (tests find the page in a screenshot by it)."""


def _png_data(bgr: np.ndarray) -> str:
    import cv2

    ok, data = cv2.imencode(".png", bgr)
    if not ok:
        raise ValueError("report.html: a picture could not be encoded")
    return "data:image/png;base64," + base64.b64encode(data.tobytes()).decode("ascii")


def _file_data(path: Path) -> str | None:
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii") if path.is_file() else None


def contact_sheet(images: np.ndarray, names: list[str], most: int = 12, width: int = 160) -> np.ndarray:
    """Up to `most` photos side by side (sRGB for display, each scaled to the capture's bright level), BGR."""
    import cv2

    from scenes.colors import linear_to_srgb

    pick = np.unique(np.linspace(0, len(images) - 1, min(most, len(images))).round().astype(int))
    # every 4th row and column of every photo: the same level within display precision, and a 96-photo 1024 px
    # capture no longer spends 30 s in one percentile holding the interpreter (no progress line meanwhile)
    level = max(float(np.percentile(images[:, ::4, ::4], 99.5)), 1e-6)
    h = max(1, round(images.shape[1] * width / images.shape[2]))
    tiles = []
    for i in pick:
        shown = (np.clip(linear_to_srgb(np.clip(images[i] / level, 0, 1)), 0, 1) * 255).astype(np.uint8)
        tile = cv2.resize(shown[..., ::-1], (width, h), interpolation=cv2.INTER_AREA)
        cv2.putText(tile, names[i][:22], (4, h - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(tile)
    cols = min(6, len(tiles))
    rows = [np.concatenate(tiles[r:r + cols] + [np.zeros_like(tiles[0])] * (cols - len(tiles[r:r + cols])), axis=1)
            for r in range(0, len(tiles), cols)]
    return np.concatenate(rows, axis=0)


MASK_TINT_BGR = (0, 140, 255)
"""The colour of the mask overlay's outline and tint (orange)."""


def mask_overlay(images: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """BGR picture of the mask over the photos: each pixel's brightest value across the photos (sRGB, scaled to the
    capture's bright level: the object whole, whichever photo lights each part), the mask tinted and outlined, so
    that a person sees at once whether it follows the object."""
    import cv2

    from scenes.colors import linear_to_srgb

    bright = images.max(axis=0).mean(axis=-1)
    gray = (linear_to_srgb(bright / max(float(np.percentile(bright, 99.5)), 1e-6)) * 255).astype(np.uint8)
    picture = np.repeat(gray[..., None], 3, axis=-1).astype(np.float32)
    tint = np.array(MASK_TINT_BGR, np.float32)
    picture[mask] = 0.7 * picture[mask] + 0.3 * tint
    width = max(1, round(min(mask.shape) / 256))  # the outline stays visible where the page shrinks a large photo
    edge = mask & ~(cv2.erode(mask.astype(np.uint8), np.ones((2 * width + 1,) * 2, np.uint8)) > 0)
    picture[edge] = tint
    return picture.round().astype(np.uint8)


def _figure(title: str, src: str | None, caption: str) -> str:
    if src is None:
        return ""
    return (f'<figure><img src="{src}" alt="{html.escape(title)}"><figcaption><b>{html.escape(title)}</b>: '
            f"{html.escape(caption)}</figcaption></figure>")


def write_page(path: Path, report: dict[str, Any], pictures: dict[str, str | None]) -> None:
    """Write report.html from report.json's content and the pictures (name -> data URL or None)."""
    from scenes.files import atomic_write_text

    v = report["verdict"]
    warnings = "".join(f"<li><b>{html.escape(w['code'])}</b>: {html.escape(w['message'])}</li>"
                       for w in report["warnings"]) or "<li>none: the capture looks usable</li>"
    judge = ("yes" if v["images_can_judge"] else "no") + f" ({html.escape(str(v.get('why') or ''))})"
    units = v.get("residual_in_noise_units")
    residual = "-" if units is None else f"{units:.1f}"
    refined = ("yes" if v["refined"] else "no") + f": {html.escape(str(v.get('refinement')))}"
    n = report["normals"]
    normal_map = (f"{html.escape(n['frame'])} ({html.escape(n['convention'])}); "
                  f"{html.escape(n['encoding'])}")
    variation = _figure("Light variation", pictures.get("light_variation"),
                        "how much each pixel changes across the photos (bright: a lot); the object should stand out")
    final_map = _figure("Final normal map", pictures.get("normals"),
                        "colour = (n + 1) / 2: red right, green up, blue toward the camera")
    residual_figure = _figure("Re-render residual", pictures.get("check_figure"),
                              "the photos, their re-rendering with the fitted light and the model's map (the check "
                              "judges the model's map, before any refinement: its figures are that map's), and the "
                              "relative residual")
    e = report.get("expected_error_deg")
    expected = (f"how far off each normal is expected to be (degrees, 0 to 45); object mean {e['mean']:.1f} deg, 80 % "
                f"interval {e['interval_80'][0]:.1f}-{e['interval_80'][1]:.1f} deg; of {e['map']}" if e else "")
    r, g, b = HEADER_RGB
    body = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Normal map of {html.escape(report["input"]["folder"])}</title>
<style>
body {{ font-family: sans-serif; margin: 0; color: #222; }}
header {{ background: rgb({r},{g},{b}); color: white; padding: 18px 24px; }}
main {{ padding: 8px 24px 40px; max-width: 1200px; }}
figure {{ display: inline-block; margin: 8px 16px 8px 0; vertical-align: top; max-width: 100%; }}
figure img {{ max-width: 100%; min-width: 192px; image-rendering: pixelated; border: 1px solid #ccc; }}
figcaption {{ font-size: 0.9em; max-width: 520px; }}
.verdict {{ font-size: 1.15em; background: #eef3f8; padding: 12px 16px; border-left: 6px solid rgb({r},{g},{b}); }}
table {{ border-collapse: collapse; }} td, th {{ border: 1px solid #ccc; padding: 4px 8px; text-align: left; }}
</style></head><body>
<header><h1>Normal map of {html.escape(Path(report["input"]["folder"]).name)}</h1>
{report["input"]["images"]} photos, {report["input"]["size"][1]} x {report["input"]["size"][0]} px</header>
<main>
<h2>Verdict</h2>
<p class="verdict"><b>{html.escape(v.get("headline", ""))}</b></p>
<p>{html.escape(v["summary"])}</p>
<table>
<tr><th>Can the images judge this capture?</th><td>{judge}</td></tr>
<tr><th>Share of the object the fitted light explains</th><td>{_pct(v.get("explained_fraction"))}</td></tr>
<tr><th>Residual of the final map, in units of the image noise</th><td>{residual}</td></tr>
<tr><th>Refined</th><td>{refined}</td></tr>
<tr><th>Normal map</th><td>{normal_map}</td></tr>
</table>
<h2>What to improve in the capture</h2>
<ul>{warnings}</ul>
<h2>The photos</h2>
{_figure("Photos", pictures.get("contact_sheet"), "a sample of the inputs, shown in sRGB")}
{_figure("Mask", pictures.get("mask"), report["mask"]["method"])}
{_figure("Mask over the photos", pictures.get("mask_overlay"), "the mask tinted and outlined in orange over each "
         "pixel's brightest value across the photos: the outline should follow the object")}
{variation}
<h2>The normal map</h2>
{final_map}
{_figure("Expected error", pictures.get("expected_error"), expected)}
{_figure("The model's map before refinement", pictures.get("model_normals"), "shown where the map was refined")}
{_figure("The surface", pictures.get("surface"), _surface_caption(report.get("surface")))}
<h2>The physical check</h2>
{residual_figure}
{_figure("Explained", pictures.get("explained"), "where the fitted light explains the photos (the judged part)")}
<h2>Details</h2>
<table>
<tr><th>Timings (s)</th><td>{html.escape(", ".join(f"{k} {t:.1f}" for k, t in report["timings"].items()))}</td></tr>
<tr><th>Peak memory</th><td>{report["peak_memory_mib"]:.0f} MiB</td></tr>
<tr><th>Full report</th><td>report.json; the check's and the refinement's own reports under check/ and refine/</td></tr>
</table>
</main></body></html>
"""
    atomic_write_text(path, body)


def _surface_caption(surface: dict | None) -> str:
    if not surface:
        return ""
    return (f"the final map integrated into a surface ({surface['camera']}) and rendered under one light from the "
            f"upper left; {surface['discontinuity_pixels']} pixels beside a depth jump; depth map and mesh in surface/")


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{x:.0%}"


def pictures(out: Path, name: str, images: np.ndarray, names: list[str], mask: np.ndarray, final: np.ndarray,
             model: np.ndarray, refined: bool) -> dict[str, str | None]:
    """The pictures of the page, as data URLs."""
    from scenes.images import normal_visual

    return {"contact_sheet": _png_data(contact_sheet(images, names)),
            "mask": _png_data(np.where(mask, 255, 0).astype(np.uint8)),
            "mask_overlay": _file_data(out / "mask_overlay.png"),
            "light_variation": _file_data(out / "light_variation.png"),
            "normals": _png_data(normal_visual(final)[..., ::-1]),  # RGB -> OpenCV's BGR
            "model_normals": _png_data(normal_visual(model)[..., ::-1]) if refined else None,
            "expected_error": _file_data(out / "expected_error.png"),
            "check_figure": _file_data(out / "check" / name / "figure.png"),
            "explained": _file_data(out / "check" / name / "explained.png"),
            "surface": _file_data(out / "surface" / "shaded.png")}
