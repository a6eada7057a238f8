"""Fitted mode of the re-render check: explain a capture's images with a scene fitted around a normal map.

No scene description is needed. With the normal map held fixed (or optimised too, `validate.refine`):
1. geometry: the normal map is integrated to a height field inside the mask (`validate.heightfield`,
   orthographic) and loaded as a Mitsuba mesh; the camera looks down -z;
2. each mask pixel is shaded at its pixel centre on that surface, with its normal from the map and its
   own albedo, by Mitsuba's `diffuse` BSDF plus the specular lobe of a `principled` BSDF with a black
   base colour (global `roughness` and `specular`: the low-parameter lobe), evaluated through `bsdf.eval`; cast shadows come from Mitsuba ray tests
   against the mesh toward each light, ambient occlusion and one bounce of inter-reflection from
   cosine-distributed rays (`ao_rays` per pixel) whose hits are looked up in the previous render;
3. light (per image, `validate.lights`) and reflectance are fitted by Adam on a robust L1 loss with
   Dr.Jit automatic differentiation through the BSDF and the light model (`llvm_ad_rgb` on a CPU,
   `cuda_ad_rgb` on a GPU); visibility is recomputed (not differentiated) every `refresh_every` steps,
   and the albedo is solved in closed form (linear least squares) at the same time; the start is the
   closed-form Lambertian least-squares fit of `validate.lights.closed_form_directional`.

Score: rel_l1 = sum |render - input| / sum |input| over the mask pixels of all images (all channels), at
the fitting resolution. Reference levels: `noise_rel_l1` (the image noise estimated from the data), and
`floor_rel_l1`, the score the same fit (same budget, same seed) reaches with a normal map that carries no
information (constant (0, 0, 1), optionally also a silhouette-only map): a normal map scoring at or above
the floor explains nothing.
"""
from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field
from typing import Any, Callable

import numpy as np

from scenes.config import check_fields, option
from scenes.variant import jit_threads, require_ad_variant
from validate import heightfield
from validate.capture import Capture
from validate.lights import LIGHT_MODELS, closed_form_directional, point_start, report_lights

log = logging.getLogger(__name__)

Progress = Callable[[int, int, str], None]
"""progress(done, total, label)."""


@dataclass
class FitConfig:
    """Options of the scene fit (fitted mode)."""

    light_model: str = option("directional", choices=LIGHT_MODELS + ("auto",))
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
    downsample: int | None = option(None, minimum=1, default_text="from --max-pixels")
    """Force this downsampling factor."""
    floor_maps: tuple[str, ...] = option(("constant",), choices=("constant", "silhouette"))
    """No-information normal maps whose fitted residual is the floor, comma-separated."""
    seed: int = 0
    """Seed of every random choice (image batches, ray directions)."""
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
    for a, b, m in ((normals[:, :-1], normals[:, 1:], mask[:, :-1] & mask[:, 1:]), (normals[:-1], normals[1:], mask[:-1] & mask[1:])):
        angles.append(np.arccos(np.clip((a[m] * b[m]).sum(-1), -1.0, 1.0)))
    a = np.concatenate(angles)
    return float(np.clip(np.sqrt(np.median(a)), 0.05, 1.0)) if a.size else 0.05


def choose_downsample(mask: np.ndarray, max_pixels: int) -> int:
    """Smallest integer factor f such that the mask has at most max_pixels pixels after f x f boxes."""
    return max(1, int(np.ceil(np.sqrt(mask.sum() / max_pixels))))


def estimate_noise_rel_l1(images: np.ndarray, mask: np.ndarray) -> float:
    """Image noise as a relative L1 level: Immerkaer's Laplacian-difference estimate of the noise
    standard deviation sigma inside the (eroded) mask, turned into the mean absolute value of Gaussian
    noise sigma * sqrt(2 / pi), divided by the mean input over the mask. images (K, H, W, 3)."""
    from scipy.ndimage import binary_erosion, convolve

    kern = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float64)
    inner = binary_erosion(mask, iterations=2)
    if inner.sum() < 16:
        return float("nan")
    sig = []
    for im in images:
        for c in range(im.shape[2]):
            r = convolve(im[:, :, c].astype(np.float64), kern, mode="nearest")
            sig.append(np.sqrt(np.pi / 2) / 6.0 * np.median(np.abs(r[inner])) / 0.6745 * 0.7979)
    sigma = float(np.mean(sig))
    denom = float(np.abs(images[:, mask]).mean())
    return sigma * np.sqrt(2 / np.pi) / denom if denom > 0 else float("nan")


class FitScene:
    """The Mitsuba scene and the differentiable shading of one capture at the fitting resolution.

    Arrays: P mask pixels (row-major), K images. `images` (K, P, 3) float32 numpy; Dr.Jit parameters live
    in `self.params` (dict name -> Dr.Jit array) and are optimised in place.

    Saturated observations (`saturated`, (K, H, W, 3) bool, see `validate.capture.Capture.saturated`) are
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
        self.bsdf_black = mi.load_dict({"type": "principled", "base_color": {"type": "rgb", "value": 0.0}, "roughness": 0.5, "specular": 0.5})
        self.bp_black = mi.traverse(self.bsdf_black)
        self.normals = to_jit(mi.Vector3f, self.n_np.astype(np.float32))
        self.albedo_np = np.full((self.p, 3), 0.5)
        self.vis = None  # (K * P,) visibility of the main light
        self.ao = np.ones(self.p)
        self.hits = None  # (P, R) pixel index hit by each AO ray, -1 = miss
        self.indirect = np.zeros((self.k, self.p, 3))  # incident one-bounce radiance (K, P, 3), times albedo in the model
        self.params: dict[str, Any] = {}
        self.dirty = True
        """The numpy inputs changed since the last `upload`."""
        self.lobe = [0.5, 0.5]
        """Principled (roughness, specular), global."""
        self.min_roughness = footprint_roughness(normals, mask)
        """Smallest roughness searched: a lobe sharper than a pixel's normal footprint aliases."""

    # ---------------------------------------------------------------------------------------- scene
    def _build_scene(self) -> None:
        from scenes.mitsuba_build import make_mesh
        from scenes.procedural import MeshData

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
        """Dr.Jit parameters from a closed-form start (see validate.lights.closed_form_directional)."""
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
            pos, inten, self.albedo_np = point_start(self.n_np, self.pos_np, self.images, start, None if self.sat is None else self.sat.any(-1))
            p["pos"] = f(pos)
            p["log_e"] = f(np.log(inten))
        if self.model in ("directional", "point"):
            p["log_a"] = f(np.log(np.maximum(A, 1e-3 * E.mean())))
        else:
            # A directional light of irradiance E along d has SH radiance coefficients E * Y(d); a constant
            # ambient radiance A has L_00 = A / Y_00. Irradiance = sum_j W_j L_j Y_j(n) (Ramamoorthi-Hanrahan).
            from validate.lights import sh_basis

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
            for cand in ([best[0] * 0.7, best[1]], [best[0] / 0.7, best[1]], [best[0], best[1] * 0.6], [best[0], min(best[1] / 0.6 + 0.02, 1.0)]):
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
        images `batch` (numpy indices or a Dr.Jit UInt32 array): render = albedo * D + S (validate.lights).
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
            from validate.lights import SH_BAND_WEIGHT as W

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
                Ss.append(np.array(S, np.float64).T.reshape(len(part), self.p, 3) if self.model != "environment" else np.zeros((len(part), self.p, 3)))
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
        return rel_l1_pixels(render, self.images[idx], None if self.sat is None else self.sat[idx])

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


@dataclass
class FitResult:
    """What a fit produced (all at the fitting resolution)."""

    rel_l1: float
    """Score: relative L1 of the fitted render over the mask, all images."""
    per_image_rel_l1: list[float]
    """The same per image."""
    render: np.ndarray
    """(K, P, 3) fitted render of the mask pixels."""
    albedo: np.ndarray
    """(P, 3) fitted albedo."""
    lights: list[list[dict]]
    """report.json `lights`."""
    light_params: dict
    """Fitted light arrays (numpy), see validate.lights.report_lights."""
    specular: dict
    """{'roughness': r, 'specular': s} of the principled lobe."""
    model: str
    """Light model used."""
    seconds: float
    """Wall time of the fit."""
    loss_history: list[float] = field(default_factory=list)
    """Training loss every refresh."""


def _np_params(fs: FitScene) -> dict:
    out = {}
    for k, v in fs.params.items():
        if k == "sh":
            out["sh"] = np.stack([np.array(c, np.float64).T for c in v], 1)  # (K, 9, 3)
        else:
            out[k] = np.array(v, np.float64).T
    res = {}
    if "dir" in out:
        res["directions"] = out["dir"] / np.linalg.norm(out["dir"], axis=1, keepdims=True)
        res["irradiance"] = np.exp(out["log_e"])
    if "pos" in out:
        res["positions"] = out["pos"]
        res["intensity"] = np.exp(out["log_e"])
    if "log_a" in out:
        res["ambient"] = np.exp(out["log_a"])
    if "sh" in out:
        res["sh"] = out["sh"]
    return res


def _normalise_albedo(fs: FitScene, params: dict) -> dict:
    """Scale albedo so its mean is 0.5 and lights inversely (the scale is not observable)."""
    m = float(fs.albedo_np.mean())
    if m <= 0:
        return params
    s = 0.5 / m
    out = dict(params)
    for key in ("irradiance", "intensity", "ambient", "sh"):
        if key in out:
            out[key] = out[key] / s
    fs.albedo_np = fs.albedo_np * s
    return out


def run_fit(
    fs: FitScene,
    steps: int,
    optimise_normals: bool = False,
    regulariser: Callable[[Any], Any] | None = None,
    holdout: np.ndarray | None = None,
    on_eval: Callable[[int, float], bool] | None = None,
    progress: Progress | None = None,
    label: str = "fit",
    wide_lobe: bool | None = None,
) -> list[float]:
    """Adam on the scene parameters of `fs` (and its normals when `optimise_normals`), refreshing
    visibility, occlusion, inter-reflection and the closed-form albedo every `refresh_every` steps.
    wide_lobe: run the grid search of the lobe at the start (default: when the normals are held).

    holdout: image indices never used in a step; `on_eval(step, holdout_rel_l1)` is called at each refresh
    when given and may return True to stop early. Returns the training-loss history (one per refresh)."""
    mi, dr = fs.mi, fs.dr
    cfg = fs.config
    train = np.setdiff1d(np.arange(fs.k), holdout if holdout is not None else [])
    opt = mi.ad.Adam(lr=cfg.lr)
    for name, val in fs.param_list(optimise_normals):
        opt[name] = val
    history: list[float] = []

    def pull() -> None:
        for name, _ in fs.param_list(optimise_normals):
            if name.startswith("sh"):
                fs.params["sh"][int(name[2:])] = opt[name]
            elif name == "normals":
                fs.normals = opt[name]
            else:
                fs.params[name] = opt[name]

    def refresh(wide_lobe: bool = False) -> None:
        pull()
        if optimise_normals:
            fs.n_np = np.array(dr.normalize(fs.normals), np.float64).T
        fs.refresh_visibility()
        D, S = fs.render_np()
        fs.solve_albedo(D, S)
        fs.refresh_indirect(fs.albedo_np[None] * D + S)
        fs.search_lobe(fs.rng.choice(train, size=min(cfg.batch_images, len(train)), replace=False), wide=wide_lobe)

    # Every step's image batch, drawn now and kept on the device (a new array per step would recompile).
    bsize = min(cfg.batch_images, len(train))
    plan = to_jit(mi.UInt32, np.concatenate([fs.rng.choice(train, size=bsize, replace=False) for _ in range(max(steps, 1))]).astype(np.uint32))
    fs.refresh_occlusion()
    # The wide lobe search once per light fit, not while normals move (the lobe was fitted to the lights).
    refresh(wide_lobe=(not optimise_normals) if wide_lobe is None else wide_lobe)
    for step in range(steps):
        if step and step % cfg.refresh_every == 0:
            refresh()
            if on_eval is not None and holdout is not None and len(holdout):
                r = fs.render(holdout)
                stop = on_eval(step, fs.score(r, holdout))
                if stop:
                    break
        batch = dr.gather(mi.UInt32, plan, dr.arange(mi.UInt32, bsize) + dr.opaque(mi.UInt32, step * bsize))
        decay = 0.1 + 0.9 * 0.5 * (1 + np.cos(np.pi * step / max(steps, 1)))  # cosine decay to 10 %
        opt.set_learning_rate({name: cfg.lr * decay * (0.5 if name == "normals" else 1.0) for name, _ in fs.param_list(optimise_normals)})
        pull()
        loss = fs.loss(batch)
        total = loss + regulariser(opt["normals"]) if (regulariser is not None and optimise_normals) else loss
        dr.backward(total)
        opt.step()
        if step % cfg.refresh_every == 0:
            history.append(float(loss.array[0]) if hasattr(loss, "array") else float(loss[0]))
        if progress is not None:
            progress(step + 1, steps, label)
    pull()
    refresh()
    return history


def rel_l1_pixels(render: np.ndarray, images: np.ndarray, saturated: np.ndarray | None = None) -> float:
    """sum |render - images| / sum |images| over (K, P, 3) arrays; where `saturated` (same shape, bool) the
    observation is a lower bound and only a render below it counts."""
    den = float(np.abs(images).sum())
    err = np.abs(render - images)
    if saturated is not None:
        err = np.where(saturated, np.maximum(images - render, 0), err)
    return float(err.sum() / den) if den > 0 else float("nan")


def _start(fs: FitScene) -> dict:
    """Closed-form Lambertian start for the scene's normals, saturated observations left out."""
    return closed_form_directional(fs.n_np, fs.images, exclude=None if fs.sat is None else fs.sat.any(-1))


def fit_normals(
    images: np.ndarray,
    mask: np.ndarray,
    normals: np.ndarray,
    config: FitConfig | None = None,
    progress: Progress | None = None,
    label: str = "fit",
    saturated: np.ndarray | None = None,
) -> FitResult:
    """Fit light and reflectance around a fixed normal map. images (K, H, W, 3), mask (H, W), normals
    (H, W, 3) unit inside the mask, saturated (K, H, W, 3) bool or None (censored observations, see
    `FitScene`), all at the fitting resolution (see `prepare`)."""
    config = (config or FitConfig()).validate()
    models = LIGHT_MODELS if config.light_model == "auto" else (config.light_model,)
    best: FitResult | None = None
    for model in models:
        t0 = time.perf_counter()
        steps = config.steps if len(models) == 1 else max(1, config.steps // 3)
        fs = FitScene(images, mask, normals, config, model, saturated)
        fs.init_params(_start(fs))
        hist = run_fit(fs, steps, progress=progress, label=f"{label} ({model})")
        render = fs.render()
        params = _normalise_albedo(fs, _np_params(fs))
        per = [fs.score(render[i : i + 1], [i]) for i in range(fs.k)]
        res = FitResult(
            rel_l1=fs.score(render),
            per_image_rel_l1=per,
            render=render.astype(np.float32),
            albedo=fs.albedo_np.astype(np.float32),
            lights=report_lights(model, params),
            light_params=params,
            specular={"roughness": float(fs.lobe[0]), "specular": float(fs.lobe[1])},
            model=model,
            seconds=time.perf_counter() - t0,
            loss_history=hist,
        )
        log.info("%s: model %s rel_l1 %.4f in %.1f s", label, model, res.rel_l1, res.seconds)
        if best is None or res.rel_l1 < best.rel_l1:
            best = res
        del fs
    assert best is not None
    return best


def no_information_maps(mask: np.ndarray, kinds: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Normal maps carrying no photometric information: 'constant' (0, 0, 1), 'silhouette' (from the mask)."""
    out = {}
    for k in kinds:
        if k == "constant":
            out[k] = np.where(mask[..., None], np.float32([0, 0, 1]), 0).astype(np.float32)
        else:
            out[k] = heightfield.silhouette_normals(mask)
    return out


def full_config_dict(config: FitConfig) -> dict:
    d = asdict(config)
    d["floor_maps"] = list(config.floor_maps)
    return d


def _scatter(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(K, P, 3) mask-pixel values -> (K, H, W, 3) images, 0 outside the mask."""
    out = np.zeros((values.shape[0],) + mask.shape + (3,), np.float32)
    out[:, mask] = values
    return out


def prepare(cap: Capture, normals: np.ndarray, config: FitConfig) -> tuple[Capture, np.ndarray, int]:
    """Downsample a capture and its normal map (H, W, 3) for fitting. Returns (capture, normals, factor)."""
    from validate.capture import downsample_capture, downsample_normals

    f = config.downsample or choose_downsample(cap.mask, config.max_pixels)
    small = downsample_capture(cap, f)
    n = downsample_normals(normals, small.mask, f)
    n = np.where(small.mask[..., None] & (np.linalg.norm(n, axis=-1, keepdims=True) < 0.5), np.float32([0, 0, 1]), n)
    return small, n.astype(np.float32), f


def rerender_fitted(
    folder: str,
    normals: str | np.ndarray,
    config: FitConfig | None = None,
    out_dir: str | None = None,
    progress: Progress | None = None,
    overwrite: bool = False,
) -> dict:
    """Fitted mode of the re-render check for one object folder (any layout); returns the report and
    writes `out_dir/<object>/report.json` and `figure.png` when out_dir is given."""
    import json
    from pathlib import Path

    from validate.capture import load_with_normals
    from validate.lights import angular_errors_deg, directions_of
    from scenes.objfolder import mean_angular_error as mae_deg
    from validate.metrics import relative_residual_map

    config = (config or FitConfig()).validate()
    mi = require_ad_variant()
    t0 = time.perf_counter()
    cap, full, source = load_with_normals(folder, normals)
    target = None
    if out_dir is not None:
        target = Path(out_dir) / cap.name
        if (target / "report.json").exists() and not overwrite:
            raise FileExistsError(f"--out: {str(target / 'report.json')!r} exists (pass --overwrite to replace it)")
    small, n_small, f = prepare(cap, full, config)
    res = fit_normals(small.images, small.mask, n_small, config, progress, "fit", small.saturated)
    floors = {}
    for kind, nmap in no_information_maps(small.mask, config.floor_maps).items():
        floors[kind] = fit_normals(small.images, small.mask, nmap, config, progress, f"floor ({kind})", small.saturated).rel_l1
    report: dict[str, Any] = {
        "mode": "fitted",
        "object": cap.name,
        "folder": str(cap.folder),
        "layout": cap.layout,
        "prediction": source,
        "images_count": int(cap.images.shape[0]),
        "image_names": cap.image_names,
        "mask_pixels": int(cap.mask.sum()),
        "rel_l1": res.rel_l1,
        "noise_rel_l1": finite(estimate_noise_rel_l1(small.images, small.mask)),
        "floor_rel_l1": min(floors.values()) if floors else None,
        "floors": floors,
        "mae_deg": mae_deg(n_small, small.normal_gt, small.mask) if small.normal_gt is not None else None,
        "light_model": res.model,
        "lights": res.lights,
        "specular": res.specular,
        "per_image_rel_l1": res.per_image_rel_l1,
        "fit_downsample": f,
        "fit_resolution": list(small.mask.shape),
        "fit_mask_pixels": int(small.mask.sum()),
        "saturated_fraction": saturated_fraction(small),
        "note": (f"fitted and scored at 1/{f} resolution ({small.mask.shape[1]}x{small.mask.shape[0]}, box filter)" if f > 1
                 else "fitted and scored at full resolution"),
        "config": full_config_dict(config),
        "variant": mi.variant(),
        "jit_threads": jit_threads(),
    }
    if small.light_directions is not None:
        err = angular_errors_deg(directions_of(res.model, res.light_params), small.light_directions)
        report["calibrated_light_error_deg"] = {"mean": float(err.mean()), "median": float(np.median(err)), "max": float(err.max())}
    report["timings"] = {"fit_s": res.seconds, "total_s": time.perf_counter() - t0}
    if target is not None:
        from scenes.objfolder import angular_error_deg, prediction_label
        from validate.figures import rerender_figure

        target.mkdir(parents=True, exist_ok=True)
        renders = _scatter(res.render, small.mask)
        k = renders.shape[0]
        rows = sorted(set(np.linspace(0, k - 1, min(k, 4)).round().astype(int).tolist()))
        rerender_figure(
            target / "figure.png", small.images, renders, small.mask, rows,
            relative_residual_map(renders, small.images, small.mask), None, n_small,
            title=f"{cap.name}, {prediction_label(source)} (fitted lights): rel_l1 {res.rel_l1:.4f}, "
            f"constant map {report['floor_rel_l1'] or float('nan'):.4f}"
            + (f", MAE {report['mae_deg']:.2f} deg" if report.get("mae_deg") is not None else ""),
            angular_error=None if small.normal_gt is None else angular_error_deg(n_small, small.normal_gt, small.mask),
        )
        (target / "report.json").write_text(json.dumps(report, indent=1, allow_nan=False))
    return report


def saturated_fraction(cap: Capture) -> float:
    """Fraction of the mask observations (images x pixels x channels) that are saturated (censored)."""
    if cap.saturated is None:
        return 0.0
    return float(cap.saturated[:, cap.mask].mean())


def finite(x: float | None) -> float | None:
    return float(x) if x is not None and np.isfinite(x) else None
