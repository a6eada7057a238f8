"""`python -m orchestrate.surface`: a normal map -> depth map and mesh (the toolkit's one integrator,
`scenes.surface`).

Usage:
    python -m orchestrate.surface --normals normal.png --mask mask.png [--intrinsics K.txt | --focal-px F] --out DIR

writes DIR/depth.npy and depth.exr ((H, W) float32 depth along the optical axis, NaN outside the mask, up to one
global scale), DIR/mesh.ply (one vertex per mask pixel, no triangle across a depth discontinuity; --mesh ply,obj,glb
for more), DIR/discontinuities.png and DIR/report.json. Without intrinsics the camera is orthographic.
"""
from __future__ import annotations

import sys
import time
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.options import REQUIRED, Command, check_fields, comma_list, option
from scenes.cli.outputs import check_listed, check_output_folder, claim_outputs, output_lock

BYTES_PER_PIXEL = 1300
"""Peak memory of the integrator per mask pixel (measured: about 1.0-1.2 kB from 0.1 to 1.6 million pixels,
`bench/bench_surface.py`), plus `BYTES_PER_IMAGE_PIXEL` for every pixel of the map."""
BYTES_PER_IMAGE_PIXEL = 64
SECONDS_PER_MPIXEL = 40.0
"""Upper bound of the integrator's time per million mask pixels on 2 cores (measured: 23 us a pixel on DiLiGenT cat,
8 us on a 1.6-million-pixel sphere)."""


@dataclass
class SurfaceOptions:
    """The command line of orchestrate.surface."""

    normals: str = REQUIRED
    """Normal map (.png/.tif 16- or 8-bit (n + 1) / 2, .exr, .npy, .mat) in the camera frame x right, y up, z toward
    the camera."""
    mask: str | None = None
    """Mask image of the same size (the object non-zero). Default: the pixels where the normal map is not zero."""
    intrinsics: str | None = None
    """Perspective camera: a text file of the 3 x 3 matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels
    (np.savetxt). Neither this nor --focal-px: orthographic."""
    focal_px: float | None = None
    """Perspective camera of this focal length in pixels, the principal point at the image centre."""
    out: str = REQUIRED
    """Output folder."""
    mesh: Annotated[tuple[str, ...], comma_list(metavar="FMT[,FMT...]", container=tuple)] = ("ply",)
    """Mesh formats written (ply, obj, glb)."""
    k: float = option(2.0, minimum=0.0)
    """Sharpness of the discontinuity weights (0: one smooth surface, no discontinuities)."""
    overwrite: bool = False
    """Replace this command's files of an earlier run in --out (its meshes of formats not written now are removed;
    nothing else is touched)."""

    def validate(self) -> "SurfaceOptions":
        from scenes.surface.mesh import MESH_FORMATS

        check_fields(self)
        if self.intrinsics is not None and self.focal_px is not None:
            raise UsageError("--intrinsics and --focal-px: give one camera, not both")
        bad = [f for f in self.mesh if f not in MESH_FORMATS]
        if bad or not self.mesh:
            raise UsageError(f"--mesh: {','.join(self.mesh)!r}; expected one or more of {', '.join(MESH_FORMATS)}")
        check_output_folder(self.out)
        return self


COMMAND = Command(SurfaceOptions, prog="python -m orchestrate.surface",
                  description="Integrate a normal map into a depth map and a mesh, keeping depth discontinuities.")


def load_inputs(args: SurfaceOptions):
    """(normals, mask, intrinsics or None, camera note), every input checked."""
    import numpy as np

    from scenes.images import read_mask, read_normals
    from scenes.surface.inputs import check_facing, check_mask, check_normals, focal_intrinsics, read_intrinsics

    normals = read_normals(args.normals, "--normals")
    shape = normals.shape[:2]
    if args.mask is not None:
        try:
            mask = read_mask(args.mask)
        except (ValueError, FileNotFoundError) as exc:  # the reader's messages name the file, not the flag
            raise type(exc)(f"--mask: {exc}") from None
        mask = check_mask(mask, shape, f"--mask {args.mask!r}")  # the file, not only the flag
    else:
        where = f"--normals {args.normals!r} (its non-zero pixels, no --mask)"
        mask = check_mask(np.abs(normals).sum(-1) > 0, shape, where)
    normals = check_normals(normals, mask, f"--normals {args.normals!r}")  # the file, not only the flag
    if args.intrinsics is not None:
        intr, camera = read_intrinsics(args.intrinsics, shape), f"perspective, --intrinsics {args.intrinsics}"
    elif args.focal_px is not None:
        intr, camera = focal_intrinsics(args.focal_px, shape), f"perspective, --focal-px {args.focal_px:g}"
    else:
        intr, camera = None, "orthographic (no --intrinsics or --focal-px)"
    check_facing(normals, mask, intr, f"--normals {args.normals!r}")
    return normals, mask, intr, camera


def main(argv: list[str] | None = None) -> int:
    """The command; --out is held for the length of the run (`scenes.cli.outputs.output_lock`)."""
    with ExitStack() as held:
        return _main(argv, held)


def _main(argv: list[str] | None, held: ExitStack) -> int:
    from scenes.cli.limits import check_memory
    from scenes.surface.integrate import IntegrationConfig, integrate
    from scenes.surface.mesh import MESH_FORMATS
    from scenes.surface.write import REPORT_KEYS, SURFACE_MESH, surface_outputs, write_surface

    try:
        args = COMMAND.parse(argv).validate()
        held.enter_context(output_lock(args.out, inputs={"--normals": args.normals, "--mask": args.mask,
                                                         "--intrinsics": args.intrinsics}))
        t0 = time.perf_counter()
        normals, mask, intr, camera = load_inputs(args)
        pixels = int(mask.sum())
        check_memory(BYTES_PER_PIXEL * pixels + BYTES_PER_IMAGE_PIXEL * mask.size, "--normals/--mask",
                     f"integrating {pixels} pixels", "integrate a smaller map or a smaller mask")
        earlier = Path(args.out) / "report.json"
        claim_outputs(surface_outputs(args.out, args.mesh), args.overwrite, owner="orchestrate.surface",
                      marker=earlier, signed={earlier: REPORT_KEYS})
        stale: list[Path] = []
        if earlier.exists():  # a mesh the earlier run did not write, beside its report: the user's
            listed = check_listed([Path(args.out) / f"{SURFACE_MESH}.{f}" for f in args.mesh], earlier, "meshes",
                                  "orchestrate.surface")
            # its meshes of formats this run does not write: removed once this run's are written (a stale mesh
            # beside a report that no longer lists it); only names of ours, never a name read from the file as is
            stale = [Path(args.out) / f"{SURFACE_MESH}.{f}" for f in MESH_FORMATS
                     if f not in args.mesh and f"{SURFACE_MESH}.{f}" in listed]
        print(f"integrating {pixels} pixels ({camera}) ...", flush=True)
        surface = integrate(normals, mask, intr, IntegrationConfig(k=args.k))
    except (*INPUT_ERRORS, OSError) as exc:
        return report_error(exc)
    record = {"normals": str(args.normals), "mask": args.mask or "the normal map's non-zero pixels",
              "camera": camera, "intrinsics": intr.matrix().tolist() if intr is not None else None,
              "depth_units": ("pixel widths, offset arbitrary (nearest point at max(H, W))" if intr is None else
                              "unit median depth of every connected part (one global scale is unknown)"),
              "k": args.k, "seconds_total": round(time.perf_counter() - t0, 2)}
    import resource

    record["peak_memory_mib"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)  # the process's
    try:
        report = write_surface(surface, args.out, args.mesh, record)
        for path in stale:
            path.unlink(missing_ok=True)
    except OSError as exc:
        return report_error(exc)
    s = report["solver"]
    print(f"surface of {report['pixels']} pixels in {s['seconds']:.1f} s ({s['iterations']} iterations, "
          f"{report['discontinuity_pixels']} pixels at a depth jump, {s['parts']} part(s)); wrote "
          f"{', '.join(p.name for p in surface_outputs(args.out, args.mesh))} in {args.out}")
    return 0


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    sys.exit(run_supervised("orchestrate.surface", main))
