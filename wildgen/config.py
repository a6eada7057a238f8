"""The resolved configuration of a dataset run (recorded in manifest.json)."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

LIGHT_FAMILIES = ("directional", "point", "near_area", "hdri", "mixed")
MATERIAL_CLASSES = ("diffuse", "specular", "metallic")
VARIANTS = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
"""Mitsuba variants the scenes are built for (RGB colours, `--variant auto` picks the first usable one)."""
MAX_ENTROPY = 8.0
"""Largest entropy (bits) of the visible normals' 16 x 16 histogram: log2(256)."""


@dataclass
class GenConfig:
    """Everything that determines a dataset; with the same values the same files come out."""

    lights: list[str] = field(default_factory=lambda: ["near_area"])
    """Light families, cycled across objects (object i gets lights[i % len(lights)])."""
    objects: int = 4
    """Number of objects to render."""
    images: int = 10
    """Images per object (PS-Wild: 10)."""
    width: int = 128
    """Image width in pixels."""
    height: int = 128
    """Image height in pixels."""
    spp: int = 64
    """Samples per pixel of the path-traced images (PS-Wild: 256)."""
    bounces: int = 10
    """Indirect bounces as in the paper; Mitsuba max_depth = bounces + 2."""
    camera: str = "orthographic"
    """'orthographic' (the model's assumption) or 'perspective'."""
    seed: int = 0
    """Root seed: object i draws from (seed, i) only, whatever the order or worker."""
    materials: str = "any"
    """Material class: diffuse, specular, metallic or any (uniform over the three)."""
    assets: str | None = None
    """Optional folder with hdri/, meshes/, textures/; without it everything is procedural."""
    shapes: str = "any"
    """'procedural', 'mesh' (needs assets) or 'any' (meshes half of the time when assets have them)."""
    entropy_threshold: float = 4.0
    """Minimum Shannon entropy (bits) of the visible normals' histogram for a pose to be kept."""
    pose_tries: int = 20
    """Random poses tried per shape before the shape is dropped."""
    shape_tries: int = 3
    """Shapes tried per object before the object is skipped."""
    margin: float = 0.04
    """Free border around the object's outline, as a fraction of the half image size."""
    exposure_percentile: float = 99.0
    """Percentile of the masked pixel values that the exposure maps to `exposure_level`."""
    exposure_level: float = 0.8
    """Target linear value of that percentile (headroom below 1 limits clipping)."""
    gt_spp: int = 16
    """Samples per pixel of the ground-truth pass."""
    texture_resolution: int = 256
    """Side of procedural texture images."""
    env_width: int = 256
    """Width of procedural environment maps."""
    variant: str | None = None
    """Mitsuba variant (None: chosen automatically at run time and recorded in the manifest)."""
    max_backfacing: float = 0.1
    """Largest share of ground-truth normals inside the mask that may face away from the camera; an object
    above it (e.g. a mesh with coincident opposite faces) is rejected and recorded with its reason."""

    def to_dict(self) -> dict:
        return asdict(self)

    def validate(self) -> "GenConfig":
        unknown = [f for f in self.lights if f not in LIGHT_FAMILIES]
        if not self.lights or unknown:
            raise ValueError(f"--lights: unknown family {unknown or self.lights!r}, expected from {', '.join(LIGHT_FAMILIES)}")
        for name in ("objects", "images", "width", "height", "spp", "gt_spp", "pose_tries", "shape_tries"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise ValueError(f"--{name.replace('_', '-')}: expected a positive integer, got {v!r}")
        if not isinstance(self.bounces, int) or self.bounces < 0:
            raise ValueError(f"--bounces: expected a non-negative integer, got {self.bounces!r}")
        if self.camera not in ("orthographic", "perspective"):
            raise ValueError(f"--camera: unknown camera {self.camera!r}, expected orthographic or perspective")
        if self.materials not in MATERIAL_CLASSES + ("any",):
            raise ValueError(f"--materials: unknown class {self.materials!r}, expected diffuse, specular, metallic or any")
        if self.shapes not in ("procedural", "mesh", "any"):
            raise ValueError(f"--shapes: unknown value {self.shapes!r}, expected procedural, mesh or any")
        if not 0 <= self.margin < 1:
            raise ValueError(f"--margin: expected 0 <= margin < 1, got {self.margin!r}")
        if not 0 < self.exposure_percentile <= 100 or not 0 < self.exposure_level <= 1:
            raise ValueError("--exposure-percentile / --exposure-level: expected (0, 100] and (0, 1]")
        if self.seed < 0:
            raise ValueError(f"--seed: expected a non-negative integer, got {self.seed!r}")
        t = self.entropy_threshold
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) or not 0 <= t <= MAX_ENTROPY:
            raise ValueError(f"--entropy-threshold: expected a number from 0 to {MAX_ENTROPY:g} bits (the entropy of a "
                             f"16 x 16 histogram), got {t!r}")
        if self.variant is not None and self.variant not in VARIANTS:
            raise ValueError(f"--variant: {self.variant!r} is not supported, expected auto or one of {', '.join(VARIANTS)} "
                             "(the scenes use RGB colours)")
        if not 0 <= self.max_backfacing <= 1:
            raise ValueError(f"max_backfacing: expected a share from 0 to 1, got {self.max_backfacing!r}")
        return self

    def memory_per_object(self) -> int:
        """Bytes one worker needs to render one object of this configuration (a conservative estimate:
        interpreter, Mitsuba and Dr.Jit ~350 MB, film and ground-truth buffers ~450 B per pixel, each
        image's float radiance and its conversions 48 B per pixel, the path tracer's wavefront 16 B per
        sample), measured on llvm_ad_rgb (1024 x 1024, 2 images: 0.8 GB peak)."""
        pixels = self.width * self.height
        return int(350e6 + pixels * (450 + 48 * self.images) + pixels * max(self.spp, self.gt_spp) * 16)
