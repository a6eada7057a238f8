"""The resolved configuration of a dataset run (recorded in manifest.json)."""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Annotated, Literal

from scenes.camera_sensor import SENSORS
from scenes.cli.options import CommaList, Repeatable, arg, auto_is_none, check_fields, option
from scenes.description import MAX_BOUNCES
from scenes.renderer.variant import PREFERENCE as VARIANTS
from wildgen.light_families import LIGHT_FAMILIES

MATERIAL_CLASSES = ("diffuse", "specular", "metallic")
PROCEDURAL_KINDS = ("blob", "superquadric", "bumpy_sphere", "torus")
"""Procedural shapes the generator draws (`scenes.procedural`)."""
PRESET_NAMES = ("diligent", "phone-flash", "light-stage", "display")
"""The names of the capture presets (`wildgen.presets.PRESETS`, which builds them as `GenConfig` instances
and checks that it holds exactly these), in the order of --help."""
LEVEL_NUMBERS = (1, 2, 3, 4, 5)
"""The complexity levels (`wildgen.levels.LEVELS`, likewise checked), simplest first."""
MAX_ENTROPY = 8.0
"""Largest entropy (bits) of the visible normals' 16 x 16 histogram: log2(256)."""


MAX_ASPECT = 8
"""The longer side of the images at most this many times the shorter (the object is framed in the shorter)."""


@dataclass
class GenConfig:
    """Everything that determines a dataset; with the same values the same files come out."""

    preset: Literal[PRESET_NAMES] | None = None
    """Capture preset (`wildgen.presets.PRESETS`): sets --lights, --images, --width, --height, --camera and
    --sensor to imitate a kind of rig (DiLiGenT's LED grid, a phone with flash, a light stage, a screen); flags
    given explicitly keep their values. Recorded in the manifest's configuration."""
    level: int | None = option(None, minimum=LEVEL_NUMBERS[0], maximum=LEVEL_NUMBERS[-1])
    """Complexity level (`wildgen.levels.LEVELS`, 1 simple to 5 complex): sets --shapes, --shape-kinds,
    --materials, --lights, --detail and --cluster (flags given explicitly keep their values); recorded in each
    scene.json as `level` for `unips.train --curriculum`."""
    lights: Annotated[list[str], CommaList, Repeatable, arg(metavar="{" + ",".join(LIGHT_FAMILIES) + "}")] = option(
        default_factory=lambda: ["near_area"], choices=tuple(LIGHT_FAMILIES))
    """Light families (keys of `wildgen.light_families.LIGHT_FAMILIES`), cycled across objects (object i gets
    lights[i % len(lights)]); repeatable or comma-separated."""
    objects: int = option(4, minimum=1)
    """Number of objects to render."""
    sensor: Literal[tuple(SENSORS)] = "ideal"
    """Camera sensor preset (`scenes.camera_sensor.SENSORS`) that turns each image's radiance into its PNG:
    `ideal` writes the linear 16-bit rendering; the others add noise, black level, response, bit depth, vignetting,
    mosaic."""
    images: int = option(10, minimum=1)
    """Images per object (PS-Wild: 10)."""
    width: int = option(128, minimum=8, maximum=8192)
    """Image width in pixels (8 to 8192: an object needs pixels to be kept)."""
    height: int = option(128, minimum=8, maximum=8192)
    """Image height in pixels (8 to 8192; the longer side at most `MAX_ASPECT` times the shorter)."""
    spp: int = option(64, minimum=1)
    """Samples per pixel of the path-traced images (PS-Wild: 256)."""
    bounces: int = option(10, minimum=0, maximum=MAX_BOUNCES)
    """Indirect bounces as in the paper; Mitsuba max_depth = bounces + 2 (a 32-bit integer)."""
    camera: Literal["orthographic", "perspective"] = "orthographic"
    """'orthographic' (the model's assumption) or 'perspective'."""
    focal: Annotated[str | None, arg(metavar="A-B", help_behavior_hint="(default: a fixed 30 deg field of view)")] = (
        None
    )
    """With --camera perspective: 35 mm-equivalent focal lengths (mm) drawn per object, log-uniform in [A, B]
    (e.g. 15-300: wide angle to telephoto); the camera distance follows so that the object fills the frame.
    Recorded as camera.focal_mm and camera.fov in scene.json; aux/view.exr holds the per-pixel view directions."""
    seed: int = option(0, minimum=0)
    """Root seed: object i draws from (seed, i) only, whatever the order or worker."""
    materials: Literal[MATERIAL_CLASSES + ("any",)] = "any"
    """Material class: diffuse, specular, metallic or any (uniform over the three)."""
    assets: Annotated[str | None, arg(metavar="DIR")] = None
    """Optional folder with hdri/, meshes/, textures/; without it everything is procedural."""
    cluster: Annotated[str | None, arg(metavar="A-B", help_behavior_hint="(default: one object per scene)")] = None
    """Objects per scene, drawn uniformly in [A, B] (at most 8): shapes slid together until they touch, then pressed a
    little, so that cast shadows and inter-reflections between them appear; one material and one mesh for the whole
    cluster (scene.json `parts`), aux/instances.png holds the 16-bit id of the object at each pixel (0: background).
    The fill-the-frame and entropy rules apply to the cluster as a whole."""
    detail: Annotated[
        float | None, arg(metavar="P", help_behavior_hint="(default: texture sets' own normal maps only)")
    ] = option(None, minimum=0, maximum=1)
    """Fraction P of objects given normal-mapped surface detail (`scenes.detail`: bumps, scratches, fabric,
    stone; or the texture set's own normal map when it has one); the others get none. Drawn from a stream of
    its own, so an object is the same with or without detail. Every object with a normal map also gets
    normal_base.tif, the normals of its geometry without the detail."""
    floor: Annotated[float | None, arg(metavar="P", help_behavior_hint="(default: none)")] = option(
        None, minimum=0, maximum=1)
    """Fraction P of objects standing on a flat textured surface seen around them (a table, a cushion; tilted
    20-70 deg toward the camera, up to a backdrop), lit by the same lights and never in the mask or the ground
    truth; the others on black. Drawn from a stream of its own, so an object is the same with or without it. With
    the default --margin the object fills the frame: give a larger one (e.g. 0.6) to see the floor."""
    detail_strength: Annotated[str, arg(metavar="A-B")] = "5-25"
    """Tilt of the procedural detail normals (their 95th percentile), degrees, drawn uniformly in [A, B] per
    detailed object. Above about 25 deg Mitsuba's normal map shades more pixels near the silhouette black
    (docs/generator.md, "Surface detail")."""
    shapes: Literal["procedural", "mesh", "any"] = "any"
    """'procedural', 'mesh' (needs assets) or 'any' (meshes half of the time when assets have them)."""
    shape_kinds: Annotated[list[str], CommaList, arg(metavar="KIND")] = option(
        default_factory=lambda: list(PROCEDURAL_KINDS), choices=PROCEDURAL_KINDS)
    """Procedural shape kinds drawn from (comma-separated): blob, superquadric (always convex), bumpy_sphere,
    torus."""
    entropy_threshold: float = option(4.0, minimum=0, maximum=MAX_ENTROPY)
    """Minimum Shannon entropy (bits) of the visible normals' histogram for a pose to be kept."""
    pose_tries: int = option(20, minimum=1)
    """Random poses tried per shape before the shape is dropped."""
    shape_tries: int = option(3, minimum=1)
    """Shapes tried per object before the object is skipped."""
    margin: float = option(0.04, minimum=0, below=1)
    """Free border around the object's outline, as a fraction of the half image size."""
    exposure_percentile: float = option(99.0, above=0, maximum=100)
    """Percentile of the masked pixel values that the exposure maps to `exposure_level`."""
    exposure_level: float = option(0.8, above=0, maximum=1)
    """Target linear value of that percentile (headroom below 1 limits clipping)."""
    gt_spp: int = option(16, minimum=1)
    """Samples per pixel of the ground-truth pass."""
    texture_resolution: int = option(256, minimum=1, maximum=4096)
    """Side of procedural texture images (at most 4096: some are made at twice the side, in float64)."""
    env_width: int = option(256, minimum=8, maximum=8192)
    """Width of procedural environment maps (8 to 8192; the height is half of it)."""
    variant: Annotated[str | None, auto_is_none("VARIANT"), arg(help_behavior_hint="(default: auto)")] = None
    """Mitsuba variant: 'auto' (None: cuda_ad_rgb, else llvm_ad_rgb, else scalar_rgb, the first usable one,
    chosen at run time and recorded in the manifest) or one of those three."""
    max_backfacing: float = option(0.1, minimum=0, maximum=1)
    """Largest share of ground-truth normals inside the mask that may face away from the camera; an object
    above it (e.g. a mesh with coincident opposite faces) is rejected and recorded with its reason."""

    def to_dict(self) -> dict:
        return asdict(self)

    def validate(self) -> "GenConfig":
        """Raise ValueError naming the first bad field as its flag."""
        unknown = [f for f in self.lights if f not in LIGHT_FAMILIES]
        if not self.lights or unknown:
            raise ValueError(
                f"--lights: unknown family {', '.join(map(repr, unknown)) or repr(','.join(self.lights))}, "
                "expected from "
                f"{', '.join(LIGHT_FAMILIES)}"
            )
        check_fields(self)
        if max(self.width, self.height) > MAX_ASPECT * min(self.width, self.height):
            raise ValueError(f"--height: {self.width}x{self.height} (--width x --height) is more than {MAX_ASPECT} "
                             "times longer one way than the other; the object would fill a sliver of the frame")
        self.detail_strength_range()
        if self.cluster is not None:
            self.cluster_range()
        if self.focal is not None:  # (it acts only with a perspective camera: wildgen.make's Needs says so)
            self.focal_range()
        if self.variant is not None and self.variant not in VARIANTS:
            raise ValueError(
                f"--variant: {self.variant!r} is not supported, expected auto or one of {', '.join(VARIANTS)} "
                "(the scenes use RGB colours)"
            )
        return self

    def focal_range(self) -> tuple[float, float]:
        """(A, B) of `focal`, checked: 1 <= A <= B <= 5000 mm."""
        from scenes.checks import parse_range

        return parse_range(self.focal, "--focal", 1.0, 5000.0, "focal lengths in mm, e.g. 15-300")

    def cluster_range(self) -> tuple[int, int]:
        """(A, B) of `cluster`, checked: 1 <= A <= B <= 8 objects."""
        from scenes.checks import parse_range

        return parse_range(self.cluster, "--cluster", 1, 8, "whole numbers of objects, e.g. 2-4", integer=True)

    def detail_strength_range(self) -> tuple[float, float]:
        """(A, B) of `detail_strength`, checked: 0 <= A <= B <= 60 degrees."""
        from scenes.checks import parse_range

        return parse_range(self.detail_strength, "--detail-strength", 0.0, 60.0, "tilts in degrees, e.g. 5-25")

    def memory_per_object(self) -> int:
        """Bytes one worker needs to render one object of this configuration (a conservative estimate:
        interpreter, Mitsuba and Dr.Jit ~350 MB, film and ground-truth buffers ~450 B per pixel, each
        image's float radiance and its conversions 48 B per pixel, the path tracer's wavefront 16 B per
        sample), measured on llvm_ad_rgb (1024 x 1024, 2 images: 0.8 GB peak)."""
        pixels = self.width * self.height
        return int(350e6 + pixels * (450 + 48 * self.images) + pixels * max(self.spp, self.gt_spp) * 16)
