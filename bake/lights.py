"""Light sources of the bake: sampling and evaluation, vectorised over many shading points.

Area lights: every triangle of an emissive material. One is chosen with probability
proportional to area x w, then a point uniformly on it, so the area density is
pdf_A = w / sum(area x w) on that triangle. w is luminance(emission) for an untextured
material; with an emissive texture (glTF 3.9.3: emission = factor x texture) it is the mean
luminance of factor x texture at EMISSION_PROBES fixed points of the triangle plus
EMISSION_FLOOR x the texture's brightest texel, so pdf_A > 0 wherever a texel can be non-zero
(which keeps the estimator unbiased: the emission itself is always evaluated at the sampled
point, `emission_at`). A triangle emits from its front (counter-clockwise) face only, unless
its material is double_sided.

Punctual lights (KHR_lights_punctual): point and spot lights give irradiance
I / d^2 x attenuation at normal incidence; the spot attenuation is the glTF
spec's smooth cone, squared:
    scale = 1 / max(0.001, cos(inner) - cos(outer)),  offset = -cos(outer) x scale
    att = clamp(dot(spot_dir, -l) x scale + offset, 0, 1)^2.
Directional lights give their irradiance on a surface facing them.

Sky: radiance from infinitely far away, a constant or an equirectangular map
(times `Sky.radiance`, a scale, default 1). The one direction <-> pixel mapping
(Y up, the one Blender uses once its Z-up world is exported as glTF Y-up, and
three.js's equirectangular map):
    u = 0.5 + atan2(z, x) / (2 pi)      column: x = u W   (u = 0.5 at +X, 0.75 at +Z, 0.25 at -Z, 0/1 at -X)
    v = acos(y) / pi                     row:    y = v H   (row 0 = straight up +Y, last row = down -Y)
    direction(u, v) = (sin(theta) cos(phi), cos(theta), sin(theta) sin(phi)),
                      theta = pi v, phi = 2 pi (u - 0.5).
Looking at the centre of the image you face +X with +Z to your right, so the
panorama reads unmirrored from inside. Pixel (i, j) is centred at
((j + 0.5) / W, (i + 0.5) / H); radiance is interpolated bilinearly (wrapping in u,
clamped in v), as Blender and Mitsuba do. Mitsuba's `envmap` puts u = 0 at -Z instead
(u_mitsuba = u - 0.25): give it `to_world = rotate([0, 1, 0], 90)` to match.
The map is importance-sampled by pixel: probability proportional to
luminance x sin(theta) (the pixel's solid angle), then uniformly in (u, v) inside it.
"""
from __future__ import annotations

import numpy as np

from glint.bake.raytrace import RayTracer
from glint.core.image_io import sample_texture
from glint.core.scene import Scene, Sky

LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance


def luminance(rgb) -> np.ndarray:
    # einsum, not `@`: a matrix product goes to BLAS, whose threads (as many as the machine's cores, in
    # every one of the bake's worker processes) fight over the cores for each path's luminance
    # (docs/BAKE.md, "Seen on 16 cores").
    return np.einsum("...c,c->...", np.asarray(rgb, np.float64), LUMA)


# -- equirectangular mapping (the one place it lives) --------------------------------------------
def equirect_uv(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions (N, 3) -> (u, v) in [0, 1], v = 0 straight up; see the module docstring."""
    u = 0.5 + np.arctan2(d[:, 2], d[:, 0]) / (2 * np.pi)
    v = np.arccos(np.clip(d[:, 1], -1.0, 1.0)) / np.pi
    return u, v


def equirect_direction(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(u, v) -> unit directions (N, 3); the inverse of `equirect_uv`."""
    theta = np.pi * v
    phi = 2 * np.pi * (u - 0.5)
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), np.cos(theta), s * np.sin(phi)], axis=1)


class SkyLight:
    def __init__(self, sky: Sky):
        self.scale = np.asarray(sky.radiance, np.float64).reshape(3)
        self.map = None if sky.map is None else np.asarray(sky.map, np.float64)[..., :3]
        self.constant = self.map is None
        if self.map is None:
            return
        self.map = np.nan_to_num(np.maximum(self.map, 0.0), nan=0.0, posinf=0.0) * self.scale
        H, W = self.map.shape[:2]
        self.H, self.W = H, W
        sin_t = np.sin(np.pi * (np.arange(H) + 0.5) / H)
        weight = (luminance(self.map) * sin_t[:, None]).ravel()
        total = weight.sum()
        self.samplable = total > 0
        self.pixel_prob = weight / total if total > 0 else weight
        self.cdf = np.cumsum(self.pixel_prob)
        self.cdf[-1] = 1.0

    def radiance(self, d: np.ndarray) -> np.ndarray:
        """(N, 3) radiance arriving from unit directions d (bilinear in the map)."""
        if self.map is None:
            return np.broadcast_to(self.scale, (len(d), 3)).copy()
        u, v = equirect_uv(d)
        x = u * self.W - 0.5
        y = np.clip(v * self.H - 0.5, 0, self.H - 1)
        x0 = np.floor(x)
        y0 = np.minimum(np.floor(y), self.H - 2) if self.H > 1 else np.zeros_like(y)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        x0 = x0.astype(np.int64) % self.W
        x1 = (x0 + 1) % self.W
        y0 = y0.astype(np.int64)
        y1 = np.minimum(y0 + 1, self.H - 1)
        m = self.map
        return ((1 - fy) * ((1 - fx) * m[y0, x0] + fx * m[y0, x1])
                + fy * ((1 - fx) * m[y1, x0] + fx * m[y1, x1]))

    def pdf(self, d: np.ndarray) -> np.ndarray:
        """Solid-angle density of `sample` (map only): p_pixel x W H / (2 pi^2 sin(theta))."""
        u, v = equirect_uv(d)
        j = np.minimum((u * self.W).astype(np.int64), self.W - 1) % self.W
        i = np.minimum((v * self.H).astype(np.int64), self.H - 1)
        sin_t = np.sqrt(np.maximum(1.0 - d[:, 1] ** 2, 0.0))
        p = self.pixel_prob[i * self.W + j] * (self.W * self.H) / (2 * np.pi ** 2)
        return np.where(sin_t > 1e-7, p / np.maximum(sin_t, 1e-7), 0.0)

    def sample(self, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Directions by the luminance CDF (u1 picks the pixel and its column offset, u2 the row offset)."""
        k = np.minimum(np.searchsorted(self.cdf, u1, side="right"), len(self.cdf) - 1)
        lo = np.where(k > 0, self.cdf[k - 1], 0.0)
        frac = np.clip((u1 - lo) / np.maximum(self.pixel_prob[k], 1e-300), 0.0, 1.0 - 1e-12)
        i, j = np.divmod(k, self.W)
        d = equirect_direction((j + frac) / self.W, (i + u2) / self.H)
        return d, self.pdf(d)


# -- area lights ---------------------------------------------------------------------------------
EMISSION_PROBES = 8  # per side of the barycentric grid: 64 probes per triangle (36 distinct after folding)
EMISSION_FLOOR = 1e-3  # x the brightest texel: keeps pdf_A > 0 on triangles whose probes missed light


class AreaLights:
    """All triangles of emissive materials, sampled by area x (mean textured) luminance."""

    def __init__(self, scene: Scene, tracer: RayTracer):
        M = len(scene.materials)
        self.tracer = tracer
        emission = np.array([np.asarray(m.emission, np.float64).reshape(3) for m in scene.materials]
                            ).reshape(M, 3)
        emission = np.maximum(np.nan_to_num(emission, nan=0.0, posinf=0.0), 0.0)
        self.material_emission = emission  # (M, 3)
        self.material_two_sided = np.array([m.double_sided for m in scene.materials], bool)
        # emissive textures (linear RGB, >= 0) with the material's sampler, by material
        self.textures: dict[int, tuple[np.ndarray, tuple]] = {}
        for i, m in enumerate(scene.materials):
            if m.emission_texture is not None and np.any(emission[i] > 0):
                tex = np.maximum(np.nan_to_num(np.asarray(m.emission_texture, np.float64)[..., :3],
                                               nan=0.0, posinf=0.0), 0.0)
                self.textures[i] = (tex, (tuple(m.kd_wrap), bool(m.kd_nearest)))
        lum = luminance(emission) if M else np.zeros(0)
        tri_lum = lum[tracer.tri_material] if tracer.n_triangles else np.zeros(0)
        for m, (tex, _) in self.textures.items():
            tri = np.flatnonzero(tracer.tri_material == m) if tracer.n_triangles else np.zeros(0, int)
            if len(tri):
                tri_lum[tri] = self._mean_luminance(m, tri)
        weight = tracer.tri_area * tri_lum
        self.prims = np.nonzero(weight > 0)[0]
        total = weight.sum()
        self.count = len(self.prims)
        # pdf_A of a point on each triangle (0 for non-emitters), indexed by the tracer's prim
        self.tri_pdf_area = tri_lum / total if total > 0 else np.zeros_like(tri_lum)
        if not self.count:
            return
        w = weight[self.prims]
        self.prob = w / total
        self.cdf = np.cumsum(self.prob)
        self.cdf[-1] = 1.0
        self.p0 = tracer.tri_p0[self.prims]
        self.e1 = tracer.tri_e1[self.prims]
        self.e2 = tracer.tri_e2[self.prims]
        self.normal = tracer.tri_ng[self.prims]
        self.material = tracer.tri_material[self.prims]
        self.two_sided = self.material_two_sided[self.material]
        self.pdf_area = self.tri_pdf_area[self.prims]
        self.eps = tracer.tri_eps[self.prims]
        # one row per emitting triangle, gathered once per sample
        self._table = np.concatenate([self.p0, self.e1, self.e2, self.normal,
                                      self.two_sided[:, None], self.pdf_area[:, None], self.eps[:, None]], axis=1)

    def _mean_luminance(self, m: int, tri: np.ndarray) -> np.ndarray:
        """w of the module docstring for triangles `tri` of textured material m."""
        tex, sampler = self.textures[m]
        # EMISSION_PROBES x EMISSION_PROBES stratified points, folded into the triangle
        g = (np.arange(EMISSION_PROBES) + 0.5) / EMISSION_PROBES
        b1, b2 = (a.ravel() for a in np.meshgrid(g, g))
        fold = b1 + b2 > 1.0
        b1, b2 = np.where(fold, 1.0 - b1, b1), np.where(fold, 1.0 - b2, b2)
        k = len(b1)
        prim = np.repeat(tri, k)
        e = self.emission_at(np.full(len(prim), m), prim, np.tile(b1, len(tri)), np.tile(b2, len(tri)))
        mean = luminance(e).reshape(len(tri), k).mean(axis=1)
        brightest = float(luminance(self.material_emission[m] * tex.reshape(-1, 3)).max(initial=0.0))
        return mean + EMISSION_FLOOR * brightest

    def emission_at(self, mat: np.ndarray, prim: np.ndarray, b1: np.ndarray, b2: np.ndarray) -> np.ndarray:
        """(N, 3) emitted radiance at points (prim, barycentrics b1, b2) of materials mat: the
        factor, times the emissive texture at the point's uv where the material has one."""
        e = np.take(self.material_emission, mat, axis=0) if len(self.material_emission) \
            else np.zeros((len(mat), 3))
        for m, (tex, sampler) in self.textures.items():
            sel = np.flatnonzero(mat == m)
            if len(sel):
                uv = self.tracer.texcoords(prim[sel], b1[sel], b2[sel])
                e[sel] = e[sel] * sample_texture(tex, uv, *sampler)
        return e

    def sample(self, u1: np.ndarray, u2: np.ndarray):
        """Points on the emitters: u1 chooses the triangle (and, rescaled, one coordinate), u2 the other.

        Returns (position (N,3), unit normal (N,3), emission (N,3), two_sided (N,), pdf_A (N,),
        the triangle's ray offset eps (N,)).
        """
        k = np.minimum(np.searchsorted(self.cdf, u1, side="right"), self.count - 1)
        lo = np.where(k > 0, self.cdf[k - 1], 0.0)
        a = np.clip((u1 - lo) / self.prob[k], 0.0, 1.0)
        row = np.take(self._table, k, axis=0)
        # uniform on the triangle (Pharr et al.): b1 = 1 - sqrt(a), b2 = u2 sqrt(a); p = p0 + b1 e1 + b2 e2
        s = np.sqrt(a)
        bary = np.stack([np.ones(len(s)), 1.0 - s, u2 * s], axis=1)
        p = np.einsum("ij,ijk->ik", bary, row[:, :9].reshape(-1, 3, 3))
        Le = self.emission_at(self.material[k], self.prims[k], bary[:, 1], bary[:, 2])
        return p, row[:, 9:12], Le, row[:, 12] > 0, row[:, 13], row[:, 14]


# -- punctual and directional lights -------------------------------------------------------------
class DeltaLights:
    """Point, spot and directional lights: each gives one deterministic shadow ray per shading point."""

    def __init__(self, scene: Scene):
        pos, inten, axis, scale, offset = [], [], [], [], []
        for light in scene.point_lights:
            pos.append(light.position)
            inten.append(light.intensity)
            axis.append((0.0, 0.0, 0.0))
            scale.append(0.0)
            offset.append(1.0)  # attenuation 1 everywhere
        for light in scene.spot_lights:
            a = np.asarray(light.direction, np.float64)
            a = a / max(np.linalg.norm(a), 1e-30)
            ci, co = np.cos(light.inner_cone), np.cos(light.outer_cone)
            s = 1.0 / max(0.001, ci - co)
            pos.append(light.position)
            inten.append(light.intensity)
            axis.append(a)
            scale.append(s)
            offset.append(-co * s)
        self.positions = np.array(pos, np.float64).reshape(-1, 3)
        self.intensities = np.array(inten, np.float64).reshape(-1, 3)
        self.axes = np.array(axis, np.float64).reshape(-1, 3)
        self.scales = np.array(scale, np.float64)
        self.offsets = np.array(offset, np.float64)
        dirs = [np.asarray(d.direction, np.float64) for d in scene.directional_lights]
        self.dir_to_light = np.array([-d / max(np.linalg.norm(d), 1e-30) for d in dirs]).reshape(-1, 3)
        self.dir_irradiance = np.array([d.irradiance for d in scene.directional_lights],
                                       np.float64).reshape(-1, 3)

    @property
    def count(self) -> int:
        return len(self.positions) + len(self.dir_to_light)

    def evaluate(self, x: np.ndarray):
        """For each light, (l (N,3) unit direction to it, distance (N,) (inf for directional),
        E (N,3) irradiance on a surface facing it)."""
        out = []
        for i in range(len(self.positions)):
            v = self.positions[i] - x
            d2 = np.einsum("ij,ij->i", v, v)
            dist = np.sqrt(d2)
            l = v / np.maximum(dist, 1e-30)[:, None]
            inv_d2 = 1.0 / np.maximum(d2, 1e-30)
            if self.scales[i] > 0:  # spot cone (glTF): smooth between outer and inner cone, squared
                cd = -np.einsum("ij,j->i", l, self.axes[i])  # not BLAS (`luminance`)
                inv_d2 = inv_d2 * np.clip(cd * self.scales[i] + self.offsets[i], 0.0, 1.0) ** 2
            E = self.intensities[i] * inv_d2[:, None]
            out.append((l, dist, E))
        for i in range(len(self.dir_to_light)):
            n = len(x)
            out.append((np.broadcast_to(self.dir_to_light[i], (n, 3)), np.full(n, np.inf),
                        np.broadcast_to(self.dir_irradiance[i], (n, 3))))
        return out


class LightSet:
    """Everything that emits in a scene, prepared for sampling."""

    def __init__(self, scene: Scene, tracer: RayTracer):
        self.area = AreaLights(scene, tracer)
        self.delta = DeltaLights(scene)
        self.sky = None if scene.sky is None else SkyLight(scene.sky)
        if self.sky is not None and self.sky.constant and not np.any(self.sky.scale > 0):
            self.sky = None
