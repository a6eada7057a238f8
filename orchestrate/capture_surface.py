"""The surface of a capture: the final normal map integrated by the toolkit's one integrator (`scenes.surface`),
with the camera the photos' EXIF gives, and rendered under one light for the page (`scenes.renderer.shaded`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from scenes.images import write_picture

FOCAL_35MM_RANGE = (8.0, 2000.0)
"""35 mm-equivalent focal lengths (mm) a pinhole camera is made from: a fisheye's 8 mm already sees 140 deg across
the diagonal; a tag of 1 mm (a 2-px focal length) put the surface's points at depths from 0.5 to 750000 (sweep 40)."""
SHADED_PICTURE = "shaded.png"
"""The surface rendered under one light (`scenes.renderer.shaded`), beside the surface's files."""


def capture_camera(meta: dict, shape: tuple[int, int]):
    """(intrinsics or None, what report.json says): every photo's EXIF 35 mm-equivalent focal length, one value for
    all, gives a pinhole camera; anything else is orthographic."""
    from scenes.surface.inputs import intrinsics_from_35mm

    focals = {e.get("focal_35mm_mm") for e in meta.get("exposure", [])} or {None}
    if len(focals) == 1 and None not in focals:
        f = focals.pop()
        if not FOCAL_35MM_RANGE[0] <= f <= FOCAL_35MM_RANGE[1]:
            return None, (f"orthographic: the EXIF 35 mm-equivalent focal length {f:g} mm is outside the "
                          f"{FOCAL_35MM_RANGE[0]:g}-{FOCAL_35MM_RANGE[1]:g} mm of rectilinear lenses (a wrong tag)")
        intr = intrinsics_from_35mm(f, shape)
        return intr, f"perspective: EXIF 35 mm-equivalent focal length {f:g} mm, {intr.fx:.0f} px"
    why = "the photos disagree on it" if len(focals) > 1 else "the photos do not give one"
    return None, f"orthographic: no EXIF 35 mm-equivalent focal length ({why})"


def write_capture_surface(folder: Path, final: np.ndarray, mask: np.ndarray, meta: dict) -> dict:
    """Integrate the final map (`scenes.surface`) into `folder`: depth, mesh, report and a shaded picture; returns
    report.json's `surface`."""
    from scenes.renderer.shaded import shaded_surface
    from scenes.surface.integrate import integrate
    from scenes.surface.mesh import faces
    from scenes.surface.write import write_surface

    intr, camera = capture_camera(meta, mask.shape)
    # The integrator leaves out the equations of the few normals a predicted map may have facing away.
    n = np.asarray(final, np.float64)
    n = np.where(mask[..., None], n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12), 0.0)
    surface = integrate(n, mask, intr)
    folder.mkdir(parents=True, exist_ok=True)
    record = write_surface(surface, folder, ("ply",), {"camera": camera, "intrinsics": None if intr is None else
                                                       intr.matrix().tolist()})
    img = shaded_surface(surface.points(), faces(mask, surface.edge_cut_u, surface.edge_cut_v), mask.shape,
                         None if intr is None else intr.fx)
    write_picture(folder / SHADED_PICTURE, np.repeat(_display(img)[..., None], 3, axis=-1))
    return {"camera": camera, "folder": folder.name, "pixels": record["pixels"],
            "discontinuity_pixels": record["discontinuity_pixels"], "seconds": record["solver"]["seconds"]}


def _display(radiance: np.ndarray) -> np.ndarray:
    from scenes.colors import linear_to_srgb

    return (np.clip(linear_to_srgb(np.clip(radiance, 0, 1)), 0, 1) * 255).round().astype(np.uint8)


