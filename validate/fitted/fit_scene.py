"""The fitted scene of a capture: geometry and differentiable shading around a normal map (fitted mode).

No scene description is needed (see `validate.fitted.fit` for the optimiser and `validate.fitted.fit_report` for the
report):
1. geometry: the normal map is integrated to a height field inside the mask (`validate.fitted.heightfield`,
   orthographic) and loaded as a Mitsuba mesh; the camera looks down -z;
2. each mask pixel is shaded at its pixel centre on that surface, with its normal from the map and its
   own albedo, by Mitsuba's `diffuse` BSDF plus the specular lobe of a `principled` BSDF with a black
   base colour (global `roughness` and `specular`: the low-parameter lobe), evaluated through `bsdf.eval`;
   cast shadows come from Mitsuba ray tests against the mesh toward each light, ambient occlusion and one
   bounce of inter-reflection from cosine-distributed rays (`ao_rays` per pixel) whose hits are looked up
   in the previous render.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Callable, Literal

import numpy as np

from scenes.cli.options import arg, check_fields, comma_list, option
from scenes.renderer.variant import require_ad_variant
from validate.fitted import heightfield
from validate.fitted.light_models import LIGHT_MODELS, closed_form_directional, point_start
from validate.residuals import rel_l1_observations

Progress = Callable[[int, int, str], None]
"""progress(done, total, label)."""


@dataclass
class FitConfig:
    """Options of the scene fit (fitted mode)."""

    light_model: Literal[LIGHT_MODELS + ("auto",)] = "directional"
    """'directional' (+ ambient), 'point' (near point light + ambient), 'environment' (order-2 SH), or
    'auto': fit each with a third of the steps and keep the one with the lowest residual."""
    steps: int = option(120, minimum=0)
    """Adam steps on lights and specular lobe (and normals in refinement)."""
    batch_images: int = option(16, minimum=1)
    """Images per Adam step (a random subset, from `seed`)."""
    refresh_every: int = option(20, minimum=1)
    """Steps between recomputing shadows / inter-reflection and the closed-form albedo."""
    lr: float = option(0.02, above=0)
    """Adam learning rate (directions, log-irradiance, specular parameters)."""
    specular: bool = True
    """Fit the specular lobe (principled roughness and specular); off: Lambertian only."""
    shadows: bool = True
    """Cast shadows by ray tests against the integrated mesh (off: every light is visible)."""
    ao_rays: int = option(16, minimum=0)
    """Cosine-distributed rays per pixel for ambient occlusion and one inter-reflection bounce (0: off)."""
    interreflection: bool = True
    """Add one bounce of inter-reflection (needs ao_rays > 0)."""
    max_pixels: int = option(16000, minimum=1)
    """Fit at a downsampled resolution with at most this many mask pixels (box filter); reported."""
    downsample: Annotated[int | None, arg(help_behavior_hint="(default: from --max-pixels)")] = option(None, minimum=1)
    """Force this downsampling factor."""
    floor_maps: Annotated[tuple[str, ...], comma_list(str, container=tuple)] = option(
        ("constant",), choices=("constant", "silhouette"))
    """No-information normal maps whose fitted residual is the floor, comma-separated."""
    seed: int = 0
    """Seed of every random choice (image batches, ray directions)."""
    bas_relief: bool = True
    """Test whether the images separate the map from two of its generalized bas-relief transforms (report.json
    `ambiguity`, `validate.fitted.ambiguity`: two short extra fits, directional light model on trusted captures
    only)."""
    min_nz: float = option(0.15, above=0, below=1)
    """Smallest |n_z| used when integrating normals to heights (bounds silhouette slopes)."""

    def validate(self) -> "FitConfig":
        return check_fields(self)



def to_jit(tp, a: np.ndarray):
    """A Dr.Jit array of type `tp` (mi.Float, mi.UInt32, mi.Vector3f, ...) from a numpy array ((N,) or
    (N, C) for C components), copied into memory Dr.Jit owns. Arrays made straight from numpy memory keep
    its alignment, which ends up in the kernel code: random 16/32-byte alignment recompiled every kernel of
    every step (measured 0.15 s per step on a 32x32 sphere)."""
    import drjit as dr

    a = np.asarray(a)
    if a.ndim == 1:
        x = tp(np.ascontiguousarray(a))
    else:
        x = tp(*(np.ascontiguousarray(a[:, c]) for c in range(a.shape[1])))
    x = dr.copy(x)
    dr.eval(x)
    return x


def footprint_roughness(normals: np.ndarray, mask: np.ndarray) -> float:
    """Principled roughness whose GGX width (alpha = roughness^2, in radians) equals the median angle between
    neighbouring pixels' normals (H, W, 3) inside the mask: shading is evaluated at pixel centres, so a
    sharper lobe falls between them and its gradients blow up (measured: a 32x32 Lambertian sphere fitted
    roughness 0.05 and its light directions moved by 2 deg)."""
    angles = []
    for a, b, m in (
        (normals[:, :-1], normals[:, 1:], mask[:, :-1] & mask[:, 1:]),
        (normals[:-1], normals[1:], mask[:-1] & mask[1:]),
    ):
        angles.append(np.arccos(np.clip((a[m] * b[m]).sum(-1), -1.0, 1.0)))
    a = np.concatenate(angles)
    return float(np.clip(np.sqrt(np.median(a)), 0.05, 1.0)) if a.size else 0.05


def lambertian_start(fs: "FitScene") -> dict:
    """Closed-form Lambertian start for the scene's normals, saturated observations left out."""
    return closed_form_directional(fs.n_np, fs.images, exclude=None if fs.sat is None else fs.sat.any(-1))


class FitScene:
    """The Mitsuba scene and the differentiable shading of one capture at the fitting resolution.

    Arrays: P mask pixels (row-major), K images. `images` (K, P, 3) float32 numpy; Dr.Jit parameters live
    in `self.params` (dict name -> Dr.Jit array) and are optimised in place.

    Saturated observations (`saturated`, (K, H, W, 3) bool, see `validate.observations.Capture.saturated`) are
    censored: the true value is only known to be at least the stored one, so a render above it costs
    nothing, one below it costs the difference (in the loss and the score), and the closed-form albedo
    ignores them. Without this a sharp specular lobe is punished for exceeding clipped highlight cores.
    """

    def __init__(self, images: np.ndarray, mask: np.ndarray, normals: np.ndarray, config: FitConfig, model: str,
                 saturated: np.ndarray | None = None):
        self.mi = mi = require_ad_variant()
        import drjit as dr

        self.dr = dr
        self.config = config
        self.model = model
        self.mask = mask
        self.k = images.shape[0]
        self.images = images[:, mask].astype(np.float32)  # (K, P, 3)
        self.sat = None if saturated is None or not saturated[:, mask].any() else saturated[:, mask]  # (K, P, 3) bool
        self.p = int(mask.sum())
        self.rng = np.random.default_rng(config.seed)
        self.n_np = normals[mask].astype(np.float64)
        self.hf = heightfield.build(normals, mask, config.min_nz)
        self.pos_np = self.hf.positions.astype(np.float64)
        self._build_scene()
        # Diffuse part: Mitsuba's Lambertian `diffuse` (reflectance 1; the per-pixel albedo multiplies it).
        # Specular lobe: `principled` with a black base colour, i.e. its specular lobe alone. (The principled
        # diffuse lobe is not Lambertian: fitted to a Lambertian sphere it biased the light directions by ~1 deg.)
        self.bsdf_white = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}})
        self.bsdf_black = mi.load_dict(
            {"type": "principled", "base_color": {"type": "rgb", "value": 0.0}, "roughness": 0.5, "specular": 0.5}
        )
        self.bp_black = mi.traverse(self.bsdf_black)
        self.normals = to_jit(mi.Vector3f, self.n_np.astype(np.float32))
        self.albedo_np = np.full((self.p, 3), 0.5)
        self.vis = None  # (K * P,) visibility of the main light
        self.ao = np.ones(self.p)
        self.hits = None  # (P, R) pixel index hit by each AO ray, -1 = miss
        # incident one-bounce radiance (K, P, 3), times albedo in the model
        self.indirect = np.zeros((self.k, self.p, 3))
        self.params: dict[str, Any] = {}
        self.dirty = True
        """The numpy inputs changed since the last `upload`."""
        self.lobe = [0.5, 0.5]
        """Principled (roughness, specular), global."""
        self.min_roughness = footprint_roughness(normals, mask)
        """Smallest roughness searched: a lobe sharper than a pixel's normal footprint aliases."""

    # ---------------------------------------------------------------------------------------- scene
    def _build_scene(self) -> None:
        from scenes.procedural import MeshData
        from scenes.renderer.build import make_mesh

        mi = self.mi
        h, w = self.mask.shape
        ii, jj = np.nonzero(self.mask)
        uvs = np.stack([(jj + 0.5) / w, (ii + 0.5) / h], 1).astype(np.float32)
        data = MeshData(self.hf.positions, self.hf.faces, np.tile(np.float32([0, 0, 1]), (self.p, 1)), uvs)
        if len(self.hf.faces) == 0:
            raise ValueError("--data: the mask has no 2x2 block of pixels (too small to build a surface)")
        mesh = make_mesh("object", data, {"type": "diffuse"})
        self.scene = mi.load_dict({"type": "scene", "object": mesh})

    def _ray_test(self, origins: np.ndarray, dirs: np.ndarray, maxt: np.ndarray | None = None) -> np.ndarray:
        """(N,) bool: does the ray from origins (N, 3) along dirs (N, 3) hit the mesh (within maxt)?"""
        mi = self.mi
        ray = mi.Ray3f(to_jit(mi.Point3f, origins.astype(np.float32)), to_jit(mi.Vector3f, dirs.astype(np.float32)))
        if maxt is not None:
            ray.maxt = to_jit(mi.Float, maxt.astype(np.float32))
        return np.array(self.scene.ray_test(ray), bool)

    def _offset(self) -> float:
        return 1.5 * self.hf.pixel_size

    def light_dirs_np(self) -> tuple[np.ndarray, np.ndarray | None]:
        """(K, P, 3) or (K, 3) unit directions toward the main light, and distances (point lights)."""
        if self.model == "directional":
            d = np.array(self.params["dir"], np.float64).T if self.params else np.zeros((self.k, 3))
            return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12), None
        if self.model == "point":
            pos = np.array(self.params["pos"], np.float64).T
            v = pos[:, None, :] - self.pos_np[None]
            dist = np.linalg.norm(v, axis=-1)
            return v / np.maximum(dist[..., None], 1e-12), dist
        return None, None

    def refresh_visibility(self) -> None:
        """Cast shadows of the main light in every image (K * P ray tests, not differentiated)."""
        if self.model == "environment" or not self.config.shadows:
            self.vis = np.ones(self.k * self.p, np.float32)
            self.dirty = True
            return
        d, dist = self.light_dirs_np()
        vis = np.empty((self.k, self.p), np.float32)
        for i in range(self.k):
            di = d[i] if d.ndim == 3 else np.broadcast_to(d[i], (self.p, 3))
            origin = self.pos_np + di * self._offset()
            maxt = None if dist is None else np.maximum(dist[i] - self._offset(), 1e-4)
            vis[i] = ~self._ray_test(origin, di, maxt)
        self.vis = vis.reshape(-1)
        self.dirty = True

    def refresh_occlusion(self) -> None:
        """Ambient occlusion and the pixels hit by `ao_rays` cosine-distributed rays about each normal."""
        r = self.config.ao_rays
        if r == 0:
            self.ao, self.hits = np.ones(self.p), None
            self.dirty = True
            return
        n = self.n_np / np.linalg.norm(self.n_np, axis=1, keepdims=True)
        u1, u2 = self.rng.random((2, self.p, r))
        rad, phi = np.sqrt(u1), 2 * np.pi * u2
        local = np.stack([rad * np.cos(phi), rad * np.sin(phi), np.sqrt(np.maximum(1 - u1, 0))], -1)  # (P, R, 3)
        a = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        t1 = np.cross(n, a)
        t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
        t2 = np.cross(n, t1)
        dirs = local[..., :1] * t1[:, None] + local[..., 1:2] * t2[:, None] + local[..., 2:] * n[:, None]
        dirs = dirs.reshape(-1, 3)
        origins = np.repeat(self.pos_np, r, 0) + dirs * self._offset()
        mi = self.mi
        ray = mi.Ray3f(to_jit(mi.Point3f, origins.astype(np.float32)), to_jit(mi.Vector3f, dirs.astype(np.float32)))
        si = self.scene.ray_intersect(ray)
        valid = np.array(si.is_valid(), bool)
        uv = np.array(si.uv, np.float64).T if np.ndim(np.array(si.uv)) == 2 else np.zeros((len(valid), 2))
        h, w = self.mask.shape
        jj = np.clip(np.round(uv[:, 0] * w - 0.5).astype(np.int64), 0, w - 1)
        ii = np.clip(np.round(uv[:, 1] * h - 0.5).astype(np.int64), 0, h - 1)
        idx = np.where(valid, self.hf.pixel_index[ii, jj], -1)
        self.hits = idx.reshape(self.p, r)
        self.ao = (self.hits < 0).mean(1)
        self.dirty = True

    def refresh_indirect(self, render: np.ndarray) -> None:
        """One-bounce incident radiance from the previous render (K, P, 3): mean over the AO rays' hits."""
        if self.hits is None or not self.config.interreflection:
            return
        hit = self.hits >= 0
        idx = np.where(hit, self.hits, 0)
        w = hit[:, :, None].astype(np.float32) / self.hits.shape[1]
        out = np.empty((self.k, self.p, 3), np.float32)
        for i in range(self.k):  # per image: (P, R, 3) at a time keeps memory bounded
            out[i] = (render[i].astype(np.float32)[idx] * w).sum(1)
        self.indirect = out
        self.dirty = True

    # ---------------------------------------------------------------------------------------- params
    def init_params(self, start: dict) -> None:
        """Dr.Jit parameters from a closed-form start (see validate.fitted.light_models.closed_form_directional)."""
        mi = self.mi
        self.albedo_np = np.asarray(start["albedo"], np.float64)
        self.dirty = True
        E = np.maximum(np.asarray(start["irradiance"], np.float64), 1e-6)
        A = np.maximum(np.asarray(start["ambient"], np.float64), 0)
        f = lambda a: to_jit(mi.Vector3f, np.asarray(a, np.float32))  # noqa: E731  (K, 3) -> Vector3f of width K
        p: dict[str, Any] = {}
        if self.model == "directional":
            p["dir"] = f(start["directions"])
            p["log_e"] = f(np.log(E))
        elif self.model == "point":
            pos, inten, self.albedo_np = point_start(
                self.n_np, self.pos_np, self.images, start, None if self.sat is None else self.sat.any(-1)
            )
            p["pos"] = f(pos)
            p["log_e"] = f(np.log(inten))
        if self.model in ("directional", "point"):
            p["log_a"] = f(np.log(np.maximum(A, 1e-3 * E.mean())))
        else:
            # A directional light of irradiance E along d has SH radiance coefficients E * Y(d); a constant
            # ambient radiance A has L_00 = A / Y_00. Irradiance = sum_j W_j L_j Y_j(n) (Ramamoorthi-Hanrahan).
            from validate.fitted.light_models import sh_basis

            y = sh_basis(np.asarray(start["directions"]))  # (K, 9)
            coef = E[:, None, :] * y[:, :, None]  # (K, 9, 3)
            coef[:, 0, :] += A / 0.282095
            p["sh"] = [f(coef[:, j, :]) for j in range(9)]
        self.lobe = [0.5, 0.5 if self.config.specular else 0.0]
        self.params = p
        self._set_bsdf()

    def param_list(self, with_normals: bool) -> list[tuple[str, Any]]:
        names = [k for k in self.params if k != "sh"] + (["sh"] if "sh" in self.params else [])
        out = []
        for k in names:
            if k == "sh":
                out += [(f"sh{j}", v) for j, v in enumerate(self.params["sh"])]
            else:
                out.append((k, self.params[k]))
        if with_normals:
            out.append(("normals", self.normals))
        return out

    # ---------------------------------------------------------------------------------------- shading
    def _set_bsdf(self) -> None:
        """Write the global lobe (roughness, specular) into both principled BSDFs. They are not
        differentiated (width-1 gradients cost one reduction kernel per use inside the BSDF: 4 s per step
        instead of 0.3 s); `search_lobe` fits them by a grid and coordinate search instead."""
        rough = self.mi.Float(float(np.clip(self.lobe[0], self.min_roughness, 1.0)))
        spec = self.mi.Float(float(np.clip(self.lobe[1], 0.0, 1.0)))
        self.dr.make_opaque(rough, spec)  # opaque: a new value does not recompile the kernels
        self.bp_black["roughness.value"] = rough
        self.bp_black["specular"] = spec
        self.bp_black.update()

    LOBE_GRID = ((0.05, 0.08, 0.12, 0.18, 0.27, 0.4, 0.6, 1.0), (0.0, 0.03, 0.07, 0.15, 0.3, 0.6, 1.0))
    """(roughness, specular) values of the wide lobe search."""

    def _batch_score(self, batch: np.ndarray) -> float:
        """Censored rel_l1 of images `batch` with the albedo solved on those images alone (no gradients)."""
        D, S = self.render_np(batch)
        rho = self._albedo_ls(D, S, batch)
        return self.score(rho[None] * D + S, batch)

    def search_lobe(self, batch: np.ndarray, wide: bool = False) -> None:
        """Fit the global lobe (roughness, specular) on images `batch` without gradients: with `wide`, the
        best of the grid `LOBE_GRID` (albedo re-solved per candidate: a local search from a broad start
        never reaches the sharp lobe of a shiny object, measured on DiLiGenT ball), then one coordinate
        step on the loss."""
        if not self.config.specular or self.model == "environment":
            return
        dr = self.dr
        if wide:
            batch = np.asarray(batch)
            self.lobe = [0.5, 0.0]
            self._set_bsdf()
            none = self._batch_score(batch)
            scores = {}
            for r in self.LOBE_GRID[0]:
                for s_ in self.LOBE_GRID[1][1:]:
                    if r >= self.min_roughness:
                        self.lobe = [r, s_]
                        self._set_bsdf()
                        scores[(r, s_)] = self._batch_score(batch)
            best_lobe = min(scores, key=scores.get) if scores else None
            # A lobe must explain something: 0.5 % of the residual, not the noise of a few pixels.
            self.lobe = list(best_lobe) if best_lobe is not None and scores[best_lobe] < 0.995 * none else [0.5, 0.0]
            self._set_bsdf()
        best = list(self.lobe)
        with dr.suspend_grad():
            def score(lobe):
                self.lobe = lobe
                self._set_bsdf()
                return float(self.loss(batch).array[0])

            cur = score(best)
            for cand in (
                [best[0] * 0.7, best[1]],
                [best[0] / 0.7, best[1]],
                [best[0], best[1] * 0.6],
                [best[0], min(best[1] / 0.6 + 0.02, 1.0)],
            ):
                cand = [float(np.clip(cand[0], self.min_roughness, 1.0)), float(np.clip(cand[1], 0.0, 1.0))]
                v = score(cand)
                if v < cur:
                    cur, best = v, cand
        self.lobe = best
        self._set_bsdf()

    def upload(self) -> None:
        """Copy the per-lane inputs of `shade` to Dr.Jit once (after each refresh): inputs (K * P, 3),
        visibility (K * P), one-bounce radiance (K * P, 3), occlusion (P), positions (P, 3), albedo (P, 3).
        Steps then only gather from them, so every step runs the same compiled kernels."""
        mi = self.mi
        if self.vis is None:
            self.vis = np.ones(self.k * self.p, np.float32)
        self.dev = {
            "images": to_jit(mi.Vector3f, self.images.reshape(-1, 3)),
            "vis": to_jit(mi.Float, self.vis.astype(np.float32)),
            "ind": to_jit(mi.Vector3f, self.indirect.reshape(-1, 3).astype(np.float32)),
            "ao": to_jit(mi.Float, self.ao.astype(np.float32)),
            "pos": to_jit(mi.Point3f, self.pos_np.astype(np.float32)),
            "albedo": to_jit(mi.Vector3f, self.albedo_np.astype(np.float32)),
        }
        if self.sat is not None:
            self.dev["sat"] = to_jit(mi.Vector3f, self.sat.reshape(-1, 3).astype(np.float32))
        self.dirty = False

    def lanes(self, batch) -> tuple[Any, Any, int]:
        """(image index, pixel index) of each lane for a batch of images: a numpy array, or a Dr.Jit UInt32
        array of width B (kept on the device so that steps do not recompile)."""
        mi, dr = self.mi, self.dr
        if isinstance(batch, np.ndarray):
            batch = to_jit(mi.UInt32, batch.astype(np.uint32))
        b = dr.width(batch)
        lane = dr.arange(mi.UInt32, b * self.p)
        p_idx = lane % self.p
        k_idx = dr.gather(mi.UInt32, batch, lane // self.p)
        return k_idx, p_idx, b

    def shade(self, batch):
        """Differentiable D and S (each a Vector3f of width B * P, lane = image-in-batch * P + pixel) for the
        images `batch` (numpy indices or a Dr.Jit UInt32 array): render = albedo * D + S (validate.fitted.light_models).
        Also returns the lane -> image and lane -> pixel index arrays."""
        mi, dr = self.mi, self.dr
        if self.dirty:
            self.upload()
        k_idx, p_idx, b = self.lanes(batch)
        flat = k_idx * self.p + p_idx
        n = dr.normalize(dr.gather(mi.Vector3f, self.normals, p_idx))
        ao = dr.gather(mi.Float, self.dev["ao"], p_idx)
        ind = dr.gather(mi.Vector3f, self.dev["ind"], flat) if self.config.interreflection else mi.Vector3f(0)
        if self.model == "environment":
            from validate.fitted.light_models import SH_BAND_WEIGHT as W

            x, y, z = n.x, n.y, n.z
            basis = [0.282095 + 0 * x, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z,
                     0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)]
            irr = mi.Vector3f(0)
            for j in range(9):
                irr += float(W[j]) * dr.gather(mi.Vector3f, self.params["sh"][j], k_idx) * basis[j]
            D = dr.maximum(irr, 0) / dr.pi * ao + ind
            return D, mi.Vector3f(0), k_idx, p_idx
        pos = dr.gather(mi.Point3f, self.dev["pos"], p_idx)
        if self.model == "directional":
            l = dr.normalize(dr.gather(mi.Vector3f, self.params["dir"], k_idx))
            E = dr.exp(dr.gather(mi.Vector3f, self.params["log_e"], k_idx))
        else:
            v = dr.gather(mi.Vector3f, self.params["pos"], k_idx) - pos
            r2 = dr.squared_norm(v)
            l = v / dr.sqrt(r2)
            E = dr.exp(dr.gather(mi.Vector3f, self.params["log_e"], k_idx)) / r2
        amb = dr.exp(dr.gather(mi.Vector3f, self.params["log_a"], k_idx))
        vis = dr.gather(mi.Float, self.dev["vis"], flat)
        si = dr.zeros(mi.SurfaceInteraction3f, b * self.p)
        si.p = pos
        si.n = n
        si.sh_frame = mi.Frame3f(n)
        si.wi = si.sh_frame.to_local(mi.Vector3f(0, 0, 1))
        ctx = mi.BSDFContext()
        wo = si.sh_frame.to_local(l)
        fw = self.bsdf_white.eval(ctx, si, wo)
        fb = self.bsdf_black.eval(ctx, si, wo)
        D = fw * E * vis + amb * ao + ind
        S = fb * E * vis
        return D, S, k_idx, p_idx

    def render_np(self, batch: np.ndarray | None = None, chunk: int = 16) -> tuple[np.ndarray, np.ndarray]:
        """(D, S) as numpy (B, P, 3) for images `batch` (all by default), without gradients."""
        dr = self.dr
        batch = np.arange(self.k) if batch is None else np.asarray(batch)
        Ds, Ss = [], []
        with dr.suspend_grad():
            for s in range(0, len(batch), chunk):
                part = batch[s : s + chunk]
                D, S, _, _ = self.shade(part)
                Ds.append(np.array(D, np.float64).T.reshape(len(part), self.p, 3))
                Ss.append(np.array(S, np.float64).T.reshape(len(part), self.p, 3) if self.model != "environment"
                          else np.zeros((len(part), self.p, 3)))
        return np.concatenate(Ds), np.concatenate(Ss)

    def _albedo_ls(self, D: np.ndarray, S: np.ndarray, batch: np.ndarray | None = None) -> np.ndarray:
        """Per-pixel closed-form albedo (P, 3) minimising sum_k (albedo D + S - I)^2 over the unsaturated
        observations of images `batch` (all by default); D, S: (B, P, 3) renders of those images."""
        idx = np.arange(self.k) if batch is None else np.asarray(batch)
        obs = self.images[idx]
        w = 1.0 if self.sat is None else (~self.sat[idx]).astype(np.float64)
        return np.clip(((obs - S) * D * w).sum(0) / np.maximum((D * D * w).sum(0), 1e-12), 0.0, 10.0)

    def solve_albedo(self, D: np.ndarray, S: np.ndarray) -> None:
        """Closed-form albedo from renders D, S (K, P, 3) of all images (see `_albedo_ls`)."""
        self.albedo_np = self._albedo_ls(D, S)
        self.dirty = True

    def render(self, batch: np.ndarray | None = None) -> np.ndarray:
        D, S = self.render_np(batch)
        return self.albedo_np[None] * D + S

    def score(self, render: np.ndarray, batch: np.ndarray | None = None) -> float:
        """rel_l1 of a render (B, P, 3) of images `batch` (all by default), saturated observations censored."""
        idx = np.arange(self.k) if batch is None else np.asarray(batch)
        return rel_l1_observations(render, self.images[idx], saturated=None if self.sat is None else self.sat[idx])

    def loss(self, batch):
        """Robust L1 (Charbonnier) of the render of `batch` against the inputs, mean over lanes and channels."""
        mi, dr = self.mi, self.dr
        D, S, k_idx, p_idx = self.shade(batch)
        rho = dr.gather(mi.Vector3f, self.dev["albedo"], p_idx)
        flat = k_idx * self.p + p_idx
        diff = rho * D + S - dr.gather(mi.Vector3f, self.dev["images"], flat)
        if "sat" in self.dev:  # censored: rendering above a clipped observation is no error
            diff = diff - dr.gather(mi.Vector3f, self.dev["sat"], flat) * dr.maximum(diff, 0)
        eps = 1e-3 * float(np.abs(self.images).mean())
        err = dr.sqrt(diff * diff + eps * eps)
        return dr.mean(err.x + err.y + err.z) / 3.0
