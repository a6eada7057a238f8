"""A Mitsuba BSDF that replaces the shading normal of camera-visible points by a predicted normal map.

`predicted_normal` wraps the object's BSDF the way Mitsuba's `normalmap` does: it builds a shading frame
from the new normal, evaluates / samples the nested BSDF in that frame, transforms the sampled direction
back, and rejects directions whose side flips between the two frames (`cos(wo) * cos(wo') > 0`).

Which normal: a surface point is projected through the scene camera to continuous pixel coordinates; if
the camera sees it, its normal is the bilinear interpolation of the predicted (camera-frame, converted to
world) normals of the surrounding in-mask pixels. Visibility is a depth test against a depth map of
`supersample x supersample` ray casts per pixel, with a tolerance that grows with the surface slope
(capped), plus a facing test: the path must arrive on the side of the surface that faces the camera.
Points the camera does not see keep their own shading normal, so cast shadows and inter-reflections off
hidden parts stay physical. A `normalmap` material is handled by `wrapper_for` (see there).

Arrays (normal map, depth map, mode) are registered in `traverse`: change them through `mi.traverse`
parameters (see `NormalSwap`), which does not recompile kernels. Mode 0 passes every call through
unchanged (bit-identical to the unwrapped BSDF), mode 1 swaps the normals.

Needs a JIT variant (llvm_* or cuda_*): a Python BSDF in a scalar variant would run Python per ray.
"""
from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass
from typing import Annotated, Any, Callable

import numpy as np

from scenes.cli.options import NotOnCommandLine, check_fields, option
from scenes.renderer.variant import require_jit_variant
from validate.known.projection import CameraProjection

log = logging.getLogger(__name__)

PLUGIN_NAME = "predicted_normal"
MODE_PASSTHROUGH = 0
MODE_PREDICTED = 1
_PARAM_NORMALS = "pred_normals"
_PARAM_DEPTH = "pred_depth"
_PARAM_MODE = "pred_mode"
_CLASSES: dict[str, type] = {}


@dataclass
class VisibilityConfig:
    """How a surface point is judged visible from the camera."""

    supersample: int = option(2, minimum=1, maximum=16)
    """Depth-map ray casts per pixel side (2 = 2x2 per pixel; at most 16: the casts grow with its square)."""
    base_tolerance: Annotated[float, NotOnCommandLine] = option(0.5, minimum=0)
    """Depth tolerance at normal incidence, in depth-map texels (world size of a pixel / supersample)."""
    slope_factor: Annotated[float, NotOnCommandLine] = option(1.5, minimum=0)
    """Extra tolerance per unit of tan(angle between surface normal and view direction), in texels."""
    max_tan: Annotated[float, NotOnCommandLine] = option(6.0, minimum=0)
    """Cap of that tangent (about 80 deg): steeper points would otherwise accept hidden surfaces behind them."""

    def validate(self) -> "VisibilityConfig":
        return check_fields(self)


def register() -> type:
    """Register the `predicted_normal` BSDF for the current variant (idempotent); returns its class."""
    mi = require_jit_variant()
    variant = mi.variant()
    if variant not in _CLASSES:
        cls = _make_class()
        mi.register_bsdf(PLUGIN_NAME, lambda props: cls(props))
        _CLASSES[variant] = cls
    return _CLASSES[variant]


def _make_class() -> type:
    """Define the BSDF class against the current variant's `mi.BSDF` (the base class is per variant)."""
    # Over 80 lines on purpose: the body is one class (its methods are Mitsuba's BSDF interface), defined here
    # because its base class exists only once a variant is set.
    import drjit as dr
    import mitsuba as mi

    class PredictedNormalBSDF(mi.BSDF):
        """Nested BSDF evaluated in the frame of the predicted normal at camera-visible points."""

        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            children = {name: obj for name, obj in props.objects() if isinstance(obj, mi.BSDF)}
            if "bsdf" not in children or set(children) - {"bsdf", "inner"}:
                raise ValueError(
                    f"{PLUGIN_NAME}: expected a nested 'bsdf' (and optionally 'inner'), got {sorted(children)}"
                )
            self.nested = children["bsdf"]  # the object's own BSDF, used where the normal is not swapped
            self.inner = children.get("inner")  # the BSDF inside a normalmap, which takes the swapped frame
            self.camera = CameraProjection(**json.loads(props["camera"]))
            self.visibility = VisibilityConfig(**json.loads(props["visibility"])).validate()
            self.m_components = [self.nested.flags(i) for i in range(self.nested.component_count())]
            self.m_flags = self.nested.m_flags
            w, h, ss = self.camera.width, self.camera.height, self.visibility.supersample
            self.normals = dr.zeros(mi.Float, h * w * 3)  # (H, W, 3) world-frame normals; 0 = no prediction
            self.depth = dr.full(mi.Float, dr.inf, h * ss * w * ss)  # (H*ss, W*ss) camera depth; inf = miss
            self.mode = dr.opaque(mi.UInt32, MODE_PASSTHROUGH)

        # --- where the new normal comes from ------------------------------------------------------
        def lookup(self, p: Any, ng: Any, wi_world: Any, active: Any = True) -> tuple[Any, Any, Any]:
            """(visible, has_prediction, world normal) for points p with geometric normal ng, reached from
            direction wi_world. Ignores the mode (tests call it directly)."""
            cam, vis = self.camera, self.visibility
            w, h, ss = cam.width, cam.height, vis.supersample
            origin = mi.Point3f(*cam.origin)
            right, up, fwd = mi.Vector3f(*cam.right), mi.Vector3f(*cam.up), mi.Vector3f(*cam.forward)
            d = p - origin
            cx, cy, z = dr.dot(d, right), dr.dot(d, up), dr.dot(d, fwd)
            if cam.kind == "orthographic":
                hw = mi.Float(cam.half_width)
                to_cam = -fwd
            else:
                hw = cam.half_width * z
                to_cam = dr.normalize(-d)
            u = (cx / hw + 1.0) * (0.5 * w)
            v = (1.0 - cy / (hw * cam.aspect)) * (0.5 * h)
            inside = active & (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)

            # Depth test with a slope-dependent tolerance, plus facing: the path arrives on the camera's side.
            cos_v = dr.dot(ng, to_cam)
            facing = (cos_v * dr.dot(ng, wi_world)) > 0
            ix = dr.clip(mi.Int32(dr.floor(u * ss)), 0, w * ss - 1)
            iy = dr.clip(mi.Int32(dr.floor(v * ss)), 0, h * ss - 1)
            zmap = dr.gather(mi.Float, self.depth, mi.UInt32(iy * (w * ss) + ix), inside)
            a = dr.abs(cos_v)
            tan_v = dr.minimum(dr.safe_sqrt(1.0 - a * a) / dr.maximum(a, 1e-6), vis.max_tan)
            texel = 2.0 * hw / (w * ss)
            tol = texel * (vis.base_tolerance + vis.slope_factor * tan_v)
            visible = inside & facing & (z <= zmap + tol)

            # Bilinear interpolation over the in-mask pixels around (u, v); pixel centres at (j+.5, i+.5).
            x, y = u - 0.5, v - 0.5
            x0, y0 = dr.floor(x), dr.floor(y)
            fx, fy = x - x0, y - y0
            xi0, yi0 = mi.Int32(x0), mi.Int32(y0)
            acc = dr.zeros(mi.Vector3f)
            wsum = dr.zeros(mi.Float)
            for dx, dy, wk in (
                (0, 0, (1 - fx) * (1 - fy)),
                (1, 0, fx * (1 - fy)),
                (0, 1, (1 - fx) * fy),
                (1, 1, fx * fy),
            ):
                xi, yi = xi0 + dx, yi0 + dy
                ok = visible & (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
                nk = dr.gather(mi.Vector3f, self.normals, mi.UInt32(dr.select(ok, yi * w + xi, 0)), ok)
                wk = dr.select(ok & (dr.squared_norm(nk) > 0.25), wk, 0.0)
                acc += wk * nk
                wsum += wk
            has = visible & (wsum > 1e-4) & (dr.squared_norm(acc) > 1e-12)
            return visible, has, dr.normalize(acc)

        def _frame(self, si: Any, active: Any) -> tuple[Any, Any]:
            """(use, frame): where to swap, and the shading frame to use (si.sh_frame where not swapped)."""
            wi_world = si.to_world(si.wi)
            _, has, n = self.lookup(si.p, si.n, wi_world, active)
            use = has & (self.mode == MODE_PREDICTED)
            # Tangent by Gram-Schmidt from the current one, so the frame equals sh_frame for n = sh_frame.n.
            s = si.sh_frame.s - n * dr.dot(n, si.sh_frame.s)
            ls = dr.norm(s)
            s_fallback, _ = mi.coordinate_system(n)
            s = dr.select(ls > 1e-4, s / dr.maximum(ls, 1e-12), s_fallback)
            frame = mi.Frame3f(s, dr.cross(n, s), n)
            return use, dr.select(use, frame, si.sh_frame)

        def _perturbed(self, si: Any, active: Any) -> tuple[Any, Any]:
            use, frame = self._frame(si, active)
            psi = mi.SurfaceInteraction3f(si)
            psi.sh_frame = frame
            psi.wi = dr.select(use, frame.to_local(si.to_world(si.wi)), si.wi)
            return use, psi

        def _wo(self, si: Any, psi: Any, use: Any, wo: Any) -> tuple[Any, Any]:
            """wo in the perturbed frame, and whether its side agrees in both frames."""
            wo_p = dr.select(use, psi.sh_frame.to_local(si.to_world(wo)), wo)
            ok = ~use | (mi.Frame3f.cos_theta(wo) * mi.Frame3f.cos_theta(wo_p) > 0)
            return wo_p, ok

        # --- BSDF interface -------------------------------------------------------------------------
        # Without `inner`, the nested BSDF gets the perturbed interaction where `use` holds and the
        # untouched one elsewhere (passthrough is bit-identical). With `inner` (the nested BSDF is a
        # `normalmap`, whose shading frame is not a world frame), swapped points call `inner` and the
        # others call the nested BSDF unchanged.
        def sample(self, ctx, si, sample1, sample2, active=True):
            use, psi = self._perturbed(si, active)
            target = self.nested if self.inner is None else self.inner
            bs, weight = target.sample(ctx, psi, sample1, sample2, active if self.inner is None else active & use)
            wo_local = si.to_local(psi.sh_frame.to_world(bs.wo))
            ok = ~use | (mi.Frame3f.cos_theta(bs.wo) * mi.Frame3f.cos_theta(wo_local) > 0)
            bs.wo = dr.select(use, wo_local, bs.wo)
            weight = dr.select(ok, weight, 0.0)
            if self.inner is None:
                return bs, weight
            bs_own, weight_own = self.nested.sample(ctx, si, sample1, sample2, active & ~use)
            return dr.select(use, bs, bs_own), dr.select(use, weight, weight_own)

        def _at_predicted(self, method, ctx, si, wo, active):
            """`method` ('eval' or 'pdf') of the material at the predicted normal where it is used, of the
            nested material elsewhere; zero where wo crosses the predicted surface."""
            use, psi = self._perturbed(si, active)
            wo_p, ok = self._wo(si, psi, use, wo)
            nested = getattr(self.nested, method)
            if self.inner is None:
                return dr.select(ok, nested(ctx, psi, wo_p, active & ok), 0.0)
            value = dr.select(ok, getattr(self.inner, method)(ctx, psi, wo_p, active & use & ok), 0.0)
            return dr.select(use, value, nested(ctx, si, wo, active & ~use))

        def eval(self, ctx, si, wo, active=True):
            return self._at_predicted("eval", ctx, si, wo, active)

        def pdf(self, ctx, si, wo, active=True):
            return self._at_predicted("pdf", ctx, si, wo, active)

        def eval_pdf(self, ctx, si, wo, active=True):
            use, psi = self._perturbed(si, active)
            wo_p, ok = self._wo(si, psi, use, wo)
            if self.inner is None:
                value, pdf = self.nested.eval_pdf(ctx, psi, wo_p, active & ok)
                return dr.select(ok, value, 0.0), dr.select(ok, pdf, 0.0)
            value, pdf = self.inner.eval_pdf(ctx, psi, wo_p, active & use & ok)
            value_own, pdf_own = self.nested.eval_pdf(ctx, si, wo, active & ~use)
            return (
                dr.select(use, dr.select(ok, value, 0.0), value_own),
                dr.select(use, dr.select(ok, pdf, 0.0), pdf_own),
            )

        def traverse(self, callback):
            callback.put(_PARAM_NORMALS, self.normals, mi.ParamFlags.Differentiable)
            callback.put(_PARAM_DEPTH, self.depth, mi.ParamFlags.NonDifferentiable)
            callback.put(_PARAM_MODE, self.mode, mi.ParamFlags.NonDifferentiable)
            callback.put_object("bsdf", self.nested, mi.ParamFlags.Differentiable)
            if self.inner is not None:
                callback.put_object("inner", self.inner, mi.ParamFlags.Differentiable)

        def parameters_changed(self, keys):
            # Keep the arrays opaque: a literal would be baked into (and recompile) every kernel.
            dr.make_opaque(self.normals, self.depth, self.mode)

        def to_string(self):
            cam = self.camera
            return (
                f"PredictedNormalBSDF[camera={cam.kind} {cam.width}x{cam.height}, "
                f"supersample={self.visibility.supersample}, nested={self.nested}]"
            )

    return PredictedNormalBSDF


def wrapper_for(camera: CameraProjection, visibility: VisibilityConfig | None = None) -> Callable[[dict], dict]:
    """`bsdf_wrapper` for `scenes.renderer.build.build_scene`.

    A `normalmap` BSDF stays whole for hidden points (they keep the normal-mapped normal); visible points
    use a second instance of its *inner* BSDF with the predicted normal, which replaces the whole shading
    normal. (Mitsuba's normalmap hands its nested BSDF a shading frame expressed relative to the original
    one, not in world space, so the wrapper cannot sit inside it.)
    """
    register()
    vis = (visibility or VisibilityConfig()).validate()
    cam_json, vis_json = json.dumps(camera.to_dict()), json.dumps(asdict(vis))

    def wrap(bsdf: dict) -> dict:
        wrapped = {"type": PLUGIN_NAME, "bsdf": bsdf, "camera": cam_json, "visibility": vis_json}
        if isinstance(bsdf, dict) and bsdf.get("type") == "normalmap":
            wrapped["inner"] = dict(bsdf["bsdf"])
        return wrapped

    return wrap


@dataclass
class NormalSwap:
    """Handle on the wrapper inside a built scene: sets its normal map, depth map and mode through
    `mi.traverse` (no recompilation)."""

    params: Any
    """The scene's `mi.traverse` parameters (BuiltScene.params)."""
    prefix: str
    """Parameter-name prefix of the wrapper, e.g. 'object.bsdf.'."""
    camera: CameraProjection
    visibility: VisibilityConfig

    @classmethod
    def attach(cls, params: Any, camera: CameraProjection, visibility: VisibilityConfig | None = None) -> "NormalSwap":
        keys = [k for k in params.keys() if k.endswith("." + _PARAM_MODE) or k == _PARAM_MODE]
        if len(keys) != 1:
            raise ValueError(f"scene: expected exactly one {PLUGIN_NAME} BSDF, found {len(keys)} ({keys})")
        return cls(
            params=params,
            prefix=keys[0][: -len(_PARAM_MODE)],
            camera=camera,
            visibility=(visibility or VisibilityConfig()),
        )

    def set_mode(self, mode: int) -> None:
        import drjit as dr
        import mitsuba as mi

        if mode not in (MODE_PASSTHROUGH, MODE_PREDICTED):
            raise ValueError(f"mode: expected {MODE_PASSTHROUGH} or {MODE_PREDICTED}, got {mode!r}")
        self.params[self.prefix + _PARAM_MODE] = dr.opaque(mi.UInt32, int(mode))
        self.params.update()

    def set_normals(self, normals_cam: np.ndarray, valid: np.ndarray) -> None:
        """Camera-frame normals (H, W, 3) used where `valid` (H, W) is true; unit length expected there."""
        import mitsuba as mi

        h, w = self.camera.height, self.camera.width
        if normals_cam.shape != (h, w, 3) or valid.shape != (h, w):
            raise ValueError(
                f"normals: expected shapes ({h}, {w}, 3) and ({h}, {w}), got {normals_cam.shape} and {valid.shape}"
            )
        n_world = np.asarray(normals_cam, np.float64) @ self.camera.rotation  # rows: n_world = R.T @ n_cam
        n_world = np.where(valid[..., None], n_world, 0.0).astype(np.float32)
        self.params[self.prefix + _PARAM_NORMALS] = mi.Float(np.ascontiguousarray(n_world).ravel())
        self.params.update()

    def set_depth(self, depth: np.ndarray) -> None:
        """Depth map (H*ss, W*ss) along the viewing direction, inf where the ray misses."""
        import mitsuba as mi

        ss = self.visibility.supersample
        shape = (self.camera.height * ss, self.camera.width * ss)
        if depth.shape != shape:
            raise ValueError(f"depth: expected shape {shape}, got {depth.shape}")
        self.params[self.prefix + _PARAM_DEPTH] = mi.Float(np.ascontiguousarray(depth, np.float32).ravel())
        self.params.update()


def depth_map(scene: Any, camera: CameraProjection, supersample: int) -> np.ndarray:
    """(H*ss, W*ss) float32 depth along the viewing direction of the first hit of rays through the
    sub-pixel centres; inf where the ray misses. Traces `scene` as it is (park area lights first)."""
    mi = require_jit_variant()

    ss = supersample
    hs, ws = camera.height * ss, camera.width * ss
    jj, ii = np.meshgrid((np.arange(ws) + 0.5) / ss, (np.arange(hs) + 0.5) / ss)
    origins, dirs = camera.rays(jj.ravel(), ii.ravel())
    ray = mi.Ray3f(
        mi.Point3f(np.ascontiguousarray(origins.T, np.float32)), mi.Vector3f(np.ascontiguousarray(dirs.T, np.float32))
    )
    si = scene.ray_intersect(ray)
    t = np.array(si.t, np.float64)
    hit = np.array(si.is_valid(), bool) & np.isfinite(t)
    z = t * (dirs @ np.asarray(camera.forward))
    return np.where(hit, z, np.inf).astype(np.float32).reshape(hs, ws)
