"""The model's view of an object folder: `PSObject` (images, mask, ground truth, lights) and `GroundTruth`.

Every layout (ours, official UniPS / SDM-UniPS, DiLiGenT) is read by the one reader,
`scenes.folder.layouts.read_folder`, whose table and rules this module only repackages; see that module for the
files of each layout. Images are returned raw, as the camera recorded them (the UniPS papers' protocol
for uncalibrated methods: a model never sees the calibration); DiLiGenT's intensity file is returned as
``light_intensities`` for calibrated methods, which divide by them (`unips.baselines`).

Images are linear in [0, 1] (16-bit / 65535, 8-bit / 255, EXR as is; 8-bit JPEGs are not linearised: the
official loaders do not either). Everything is RGB and in the camera frame x right, y up, z toward the
camera (DiLiGenT uses the same frame: the least-squares baseline reproducing the published errors
confirms it).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scenes.folder.layouts import EXPECTED, LAYOUTS, FolderData, find_object_folders, read_folder

log = logging.getLogger(__name__)
__all__ = ["EXPECTED", "LAYOUTS", "GroundTruth", "PSObject", "find_objects", "load_ground_truth", "load_object",
           "object_from_folder"]


@dataclass
class PSObject:
    """One photometric-stereo object: K images of a static scene under changing lighting."""

    name: str  # folder name minus a trailing ".data" (e.g. "foo.data" -> "foo", "ballPNG" -> "ballPNG")
    images: np.ndarray  # (K, H, W, 3) float32, linear RGB
    mask: np.ndarray  # (H, W) bool, True on the object
    normals: np.ndarray | None  # (H, W, 3) float32 ground truth, unit inside mask, 0 outside; None if absent
    light_family: str | None  # "directional" | "point" | "near_area" | "hdri" | "mixed"; None if unknown
    light_directions: np.ndarray | None  # (K, 3) unit vectors toward the light (camera frame); directional only
    light_intensities: np.ndarray | None  # (K, 3) RGB intensity of each light as seen in `images`
    path: Path  # the object folder
    layout: str  # one of LAYOUTS
    image_names: list[str] = field(default_factory=list)  # file names of the K images, in order
    meta: dict[str, Any] = field(default_factory=dict)  # layout-specific extras (e.g. raw intensities)
    level: int | None = None  # complexity level of a generated scene (scene.json `level`); None if unknown

    @property
    def num_images(self) -> int:
        return int(self.images.shape[0])


def find_objects(path: str | Path, arg: str = "path") -> list[Path]:
    """The object folders at ``path``: itself if it is one, else its sorted subfolders that are."""
    return find_object_folders(path, arg)


def _f32(x: np.ndarray | None) -> np.ndarray | None:
    return None if x is None else np.asarray(x, np.float32)


def load_object(
    path: str | Path, max_images: int | None = None, layout: str | None = None, arg: str = "path"
) -> PSObject:
    """Load one object folder (`scenes.folder.layouts.read_folder`).

    max_images: keep the first K images in the folder's order (natural sort of names, or DiLiGenT's
    filenames.txt); deterministic. layout: force ``"ours"``, ``"unips"`` or ``"diligent"``.
    """
    return object_from_folder(read_folder(path, max_images=max_images, layout=layout, arg=arg))


def object_from_folder(fd: FolderData) -> PSObject:
    """The `PSObject` of what the one reader returned for a folder (`read_folder`, or a decoded shard sample)."""
    meta: dict[str, Any] = {}
    if fd.layout == "diligent":
        meta["light_intensities_file"] = fd.lights.intensities
    obj = PSObject(name=fd.name, images=fd.images, mask=fd.mask, normals=fd.normals, light_family=fd.lights.family,
                   light_directions=_f32(fd.lights.directions), light_intensities=_f32(fd.lights.intensities),
                   path=fd.path, layout=fd.layout, image_names=fd.image_names, meta=meta, level=fd.lights.level)
    log.debug("loaded %s (%s): %d images %dx%d", fd.path, fd.layout, obj.num_images, fd.shape[1], fd.shape[0])
    return obj


@dataclass
class GroundTruth:
    """What evaluation needs from an object folder, read without loading every image."""

    name: str  # object name (folder name minus a trailing ".data")
    mask: np.ndarray  # (H, W) bool
    normals: np.ndarray | None  # (H, W, 3) float32, unit inside mask; None when the folder has none
    light_family: str | None  # from scene.json ("ours"), "directional" for DiLiGenT, else None
    path: Path  # the object folder
    layout: str  # one of LAYOUTS


GT_AWAY_SHARE = 0.5
"""The largest share of a ground truth's mask pixels whose normal may face away from the camera (n_z < 0). A
perspective camera sees normals that face slightly away near the silhouette, so not zero; a map with more is in
another frame (z into the scene) or no normal map at all (an all-zero image decodes to (-1, -1, -1) / sqrt 3)."""


def load_ground_truth(path: str | Path, layout: str | None = None, arg: str = "path") -> GroundTruth:
    """Mask, ground-truth normals and light family of an object folder (reads one image for its size). Normals
    that mostly face away from the camera (`GT_AWAY_SHARE`) are refused: every prediction would be scored against
    them."""
    fd = read_folder(path, layout=layout, images=False, arg=arg)
    if fd.normals is not None and fd.mask.any():
        away = float((fd.normals[fd.mask][:, 2] < 0).mean())
        if away > GT_AWAY_SHARE:
            raise ValueError(f"{arg}: the ground-truth normals of {fd.path} face away from the camera on "
                             f"{100 * away:.0f}% of the mask (at most {100 * GT_AWAY_SHARE:.0f}% may); expected the "
                             "camera frame x right, y up, z toward the camera (a black normal image, no normal map "
                             "at all, reads so too)")
    return GroundTruth(name=fd.name, mask=fd.mask, normals=fd.normals, light_family=fd.lights.family,
                       path=fd.path, layout=fd.layout)
