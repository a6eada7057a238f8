"""Physical check of predicted normals: re-render the known scene of each input image with the shading
normal of every camera-visible surface point replaced by the predicted one, and compare with the inputs.

Modules: `projection` (camera model shared by NumPy and Dr.Jit code), `normal_bsdf` (the Mitsuba BSDF
wrapper that swaps the normals), `io` (an object folder loaded for the check, on top of `scenes.folder.format`),
`perturb` (controlled normal errors for tests and benches), `metrics`, `figures`, and `rerender` (library + CLI).
"""
import scenes  # noqa: F401  (a clear error, not a traceback, outside the toolkit's environment)
