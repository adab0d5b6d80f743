"""The lobes' directional albedo on the GPU: the table of the walkthrough's albedo-normalised estimate
(shaders/lobe_sampling.glsl, the default) and of the split-sum comparison (viewer/split_sum.py).

Why a table. The walkthrough's regular pattern used the thesis' Eq. 4.25, sum w v L / sum w with
w = f cos and v = f cos / p: under uniform light it reads sum f^2 cos^2 / p / sum f cos, which is not
the lobe's directional albedo A = int f cos dw but leans towards the samples of large v. Kurt's
alpha puts (cos_i cos_o)^-alpha into f and not into the pdf of Eq. 4.9, so v grows towards the
horizon and the bias with alpha: the fitted glTF lobes (alpha near 1/2) read 6 % (metal, roughness
0.3) and 12 % (dielectric, roughness 0.4) too bright at 74.5 degrees in a white furnace (issue 24).
The default estimate (`ESTIMATORS["albedo"]`) is instead, per lobe,

    L_lobe(v) = A(v) x sum w L / sum w,   w = p cos(theta_i),

the split sum's normalisation (Karis 2013) applied to the pattern: the pattern's weighted mean of the
incident radiance times the albedo of this view, exact under uniform light at every angle, with the
pattern's weighting of the light kept otherwise. The weights p cos are Eq. 4.24's (there times v):
measured in bench/measure_lobe_patterns.py's numpy model (16 spherical-Gaussian environments x 6
views of 0-82 degrees x 6 lobes: the fitted glTF metals of roughness 0.3, 0.5, dielectrics of 0.25,
0.4, an alpha = 0 lobe of m = 0.1 and an anisotropic line; docs/BENCHMARKS.md, "Issue 24: the
walkthrough's albedo normalisation") they gave the smallest error against the lobe's integral, median 6.0 %,
90th percentile 85 %, against f cos (8.6 %, 96 %), v = f cos / p (9.8 %, 138 %) and Eq. 4.25
itself (9.1 %, 97 %). Samples below the horizon are dropped from the mean; A already holds the
horizon's loss. A pixel whose samples all fall below it gets 0, as with Eq. 4.25.

Layout. Per distinct lobe (mx, my, r0, alpha, kind) a layer of LUT_COS x LUT_PHI albedos by
glint.core.bsdf.lobe_albedo (ALBEDO_SAMPLES quasi-random importance samples, without ks) on
sqrt(cos theta_v) x view azimuth in [0, pi/2] (the lobe is symmetric under x -> -x and y -> -y),
read bilinearly; lobes with equal parameters share their layers, and each layer is computed once per
process (`_LAYERS`, up to CACHE_LAYERS of them: a material edit computes only what it changed, and
`glint bench`'s many renderers of one scene the table once); isotropic ones for one azimuth. Cost
(`albedo_ms` in renderer.stats["lobe_albedo"], when the renderer is made; measured on the shared
2-core machine at load 7, docs/BENCHMARKS.md "Issue 24: the walkthrough's albedo normalisation"): 0.1 s for
the many-objects rooms' one metal lobe, 0.6 s for planar-classes (4 lobes), 4.1-4.5 s for
living-room and material-classes (9 and 6 lobes, anisotropic ones 8 azimuths each); the bake's
cube-map renders have no lobes (glint/cubemap_stage.py diffuse_view) and pay nothing.

Lobes whose width varies per texel (shaders/specular.glsl `lobe_at_pixel`):
- a metallic-roughness texture (Lobe.mr; bake/material_mapping.py): m' = max(m g^2, M_MIN), g the
  texel's roughness factor in [0, 1], the anisotropy strength kept. Such a lobe gets
  ROUGHNESS_NODES layers at g = 0, 1/20, ..., 1, interpolated linearly in g by the shader
  (`AXIS_ROUGHNESS`); within 0.41 % of the exact albedo midway between the nodes for fitted glTF
  lobes (metal roughness 0.5 and 0.8, dielectric 0.3, each row's lobes) at views up to 80 degrees,
  against 0.66 % with 17 nodes and 1.16 % with 13 (the tail lobe of the rough rows, m up to 1,
  changes fastest near g = 0.2), 0.97 % with 9 for one-lobe rows (tests/test_lobe_albedo.py). Its
  cost: 21 tables instead of one.
- KHR_materials_anisotropy's texture: mx' = my + (mx - my) s^2, s the texel's strength in [0, 1]:
  ANISOTROPY_NODES layers over s (`AXIS_ANISOTROPY`; their accuracy between nodes is not measured).
- both at once: the factor's table only, without the LOBE_ALBEDO_EXACT flag: the walkthrough keeps
  Eq. 4.25 for that lobe (LOBE_ALBEDO_INEXACT compiled in: viewer/gpu_materials.py albedo_defines;
  split-sum reads the factor's albedo, as it did for every lobe before), as a table over (g, s)
  would cost ROUGHNESS_NODES x ANISOTROPY_NODES anisotropic tables (seconds).
The texel's ks (ks M' or ks (1 - M')) multiplies the estimate outside the table, as ks always does.

    table = LobeAlbedo(ctx, gl)
    table.update(lobe_table, lobe_mr, anisotropy_textured)   # GpuMaterials._upload, after every edit
    table.bind()              # rows and values: LOBE_ALBEDO_BINDING, LOBE_ALBEDO_TABLE_BINDING
    table.describe()          # albedo_ms, layers, ... (renderer.stats["lobe_albedo"])
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import moderngl
import numpy as np

from glint.core import bsdf
from glint.viewer.gl_bindings import LOBE_ALBEDO_BINDING, LOBE_ALBEDO_TABLE_BINDING

LUT_COS, LUT_PHI = 32, 8  # albedo grid: sqrt(cos theta_v) x view azimuth in [0, pi/2]
ALBEDO_SAMPLES = 4096     # per albedo (glint.core.bsdf.lobe_albedo)
ROUGHNESS_NODES = 21      # g = 0 .. 1 for lobes that follow a metallic-roughness texture
ANISOTROPY_NODES = 5      # s = 0 .. 1 for lobes of a material with an anisotropy texture
CACHE_LAYERS = 4096       # layers kept per process (1 KiB each: 4 MiB)
# shaders/lobe_albedo.glsl: what the row's z says about the layers (defines of the same names)
AXES = {"LOBE_ALBEDO_AXIS_NONE": 0, "LOBE_ALBEDO_AXIS_ROUGHNESS": 1, "LOBE_ALBEDO_AXIS_ANISOTROPY": 2}
FLAGS = {"LOBE_ALBEDO_EXACT": 1, "LOBE_ALBEDO_ISOTROPIC": 2}  # bits of the row's w
MAX_LAYERS = 1 << 16      # layers uploaded at most (64 MiB)
# shaders/lobe_sampling.glsl: the walkthrough's pattern estimators (viewer/passes/shading.py WEIGHTS)
ESTIMATORS = {"albedo": "ESTIMATE_ALBEDO", "eq4.25": "ESTIMATE_EQ_4_25", "eq4.24": "ESTIMATE_EQ_4_24"}


@dataclass(frozen=True)
class LobeKey:
    """What a lobe's albedo depends on (not ks)."""
    mx: float
    my: float
    r0: float
    alpha: float
    kind: str  # "reflect" or "transmit"


_LAYERS: dict[LobeKey, np.ndarray] = {}  # every LobeAlbedo's layers, by key (module docstring)


def lut_views() -> np.ndarray:
    """(LUT_COS, LUT_PHI, 3) unit view directions of the grid's nodes (local frame): row i at
    sqrt(cos theta) = i / (LUT_COS - 1), column j at phi = j / (LUT_PHI - 1) pi / 2."""
    cos = (np.arange(LUT_COS) / (LUT_COS - 1)) ** 2
    phi = np.arange(LUT_PHI) / (LUT_PHI - 1) * (np.pi / 2)
    c, p = np.meshgrid(cos, phi, indexing="ij")
    s = np.sqrt(np.maximum(1.0 - c * c, 0.0))
    return np.stack([s * np.cos(p), s * np.sin(p), c], axis=-1)


def albedo_layer(key: LobeKey, samples: int = ALBEDO_SAMPLES) -> np.ndarray:
    """(LUT_COS, LUT_PHI) float32: the lobe's directional albedo (without ks) at the grid's views,
    finite and >= 0."""
    views = lut_views()
    iso = max(key.mx, bsdf.M_MIN) == max(key.my, bsdf.M_MIN)
    a = bsdf.lobe_albedo(views[:, :1] if iso else views, key.mx, key.my, key.r0, key.alpha, key.kind, n=samples)
    a = np.broadcast_to(np.nan_to_num(a, nan=0.0, posinf=0.0, neginf=0.0), (LUT_COS, LUT_PHI))
    return np.maximum(a, 0.0).astype(np.float32)


def roughness_variant(mx: float, my: float, g: float) -> tuple[float, float]:
    """(mx', my') of a metallic-roughness texel of roughness factor g (shaders/specular.glsl
    lobe_at_pixel): m' = max(m g^2, M_MIN), the anisotropy strength a^2 = (mx - my) / (1 - my) kept."""
    a2 = float(np.clip((mx - my) / (1.0 - my), 0.0, 1.0)) if my < 1.0 else 0.0
    m = max(my * g * g, bsdf.M_MIN)
    return m + (1.0 - m) * a2, m


def anisotropy_variant(mx: float, my: float, s: float) -> tuple[float, float]:
    """(mx', my') at an anisotropy-texture texel of strength s (lobe_at_pixel): mx' = my + (mx - my) s^2."""
    return my + (mx - my) * s * s, my


def lobe_keys(row, axis: int) -> list[LobeKey]:
    """The layers' keys of one LOBE_DTYPE row with its axis (AXES): one, or one per node."""
    mx, my, r0, alpha = (float(x) for x in row["shape"])
    kind = "transmit" if int(round(float(row["ks"][3]))) == 1 else "reflect"
    if axis == AXES["LOBE_ALBEDO_AXIS_ROUGHNESS"]:
        shapes = [roughness_variant(mx, my, g) for g in np.linspace(0.0, 1.0, ROUGHNESS_NODES)]
    elif axis == AXES["LOBE_ALBEDO_AXIS_ANISOTROPY"]:
        shapes = [anisotropy_variant(mx, my, s) for s in np.linspace(0.0, 1.0, ANISOTROPY_NODES)]
    else:
        shapes = [(mx, my)]
    return [LobeKey(float(x), float(y), r0, alpha, kind) for x, y in shapes]


class LobeAlbedo:
    """Every lobe's albedo layers, float32, one after the other in a storage buffer
    (LOBE_ALBEDO_TABLE_BINDING; `texture` is the name kept for it), and per lobe an ivec4 row (first
    layer, node count, axis, flags: LOBE_ALBEDO_EXACT where the table holds the texel's lobe,
    LOBE_ALBEDO_ISOTROPIC where its layers do not depend on the azimuth) in another
    (LOBE_ALBEDO_BINDING). A storage buffer and the shader's own bilinear interpolation rather than a
    texture array: on llvmpipe a texture fetch per lobe and pixel cost 8-23 % of the specular pass
    (docs/BENCHMARKS.md, "Issue 24: the walkthrough's albedo normalisation"), buffer loads do not."""

    def __init__(self, ctx: moderngl.Context, gl):
        self.ctx, self._gl = ctx, gl
        self.texture = self.rows = None
        self.albedo_ms = 0.0
        self.layers = 0
        self.computed = 0  # layers computed by the last update (the others came from the cache)

    def update(self, lobe_table: np.ndarray, lobe_mr, anisotropy_textured) -> None:
        """Build the table of the first len(lobe_mr) rows of lobe_table; lobe_mr: per lobe its LOBE_MR
        value (0: none), anisotropy_textured: per lobe whether its material has an anisotropy texture."""
        started = time.perf_counter()
        count = len(lobe_mr)
        rows = np.zeros((max(count, 1), 4), np.int32)
        layers: list[np.ndarray] = []
        index: dict[tuple, int] = {}  # a lobe's tuple of keys -> its first layer (equal lobes share)
        computed = 0
        for k in range(count):
            mr, aniso = bool(lobe_mr[k]), bool(anisotropy_textured[k])
            exact = not (mr and aniso)  # both: the factor's table, inexact (module docstring)
            axis = AXES["LOBE_ALBEDO_AXIS_ROUGHNESS" if mr and exact else "LOBE_ALBEDO_AXIS_ANISOTROPY"
                        if aniso and exact else "LOBE_ALBEDO_AXIS_NONE"]
            keys = tuple(lobe_keys(lobe_table[k], axis))
            if keys not in index:
                index[keys] = len(layers)
                for key in keys:
                    if key not in _LAYERS:
                        if len(_LAYERS) >= CACHE_LAYERS:
                            _LAYERS.pop(next(iter(_LAYERS)))  # the oldest
                        _LAYERS[key] = albedo_layer(key)
                        computed += 1
                    layers.append(_LAYERS[key])
            iso = all(max(key.mx, bsdf.M_MIN) == max(key.my, bsdf.M_MIN) for key in keys)
            rows[k] = (index[keys], len(keys), axis, FLAGS["LOBE_ALBEDO_EXACT"] * exact
                       + FLAGS["LOBE_ALBEDO_ISOTROPIC"] * iso)
        self.computed = computed
        self.layers = len(layers)
        lut = np.stack(layers) if layers else np.zeros((1, LUT_COS, LUT_PHI), np.float32)
        self.albedo_ms = (time.perf_counter() - started) * 1e3
        self._release()
        limit = MAX_LAYERS
        if len(lut) > limit:  # tens of thousands of distinct lobes: those past the limit read layer 0, inexact
            over = rows[:, 0] + rows[:, 1] > limit
            rows[over] = (0, 1, AXES["LOBE_ALBEDO_AXIS_NONE"], 0)  # inexact, any azimuth
            lut = lut[:limit]
        with self._gl.checked(f"upload the lobes' albedo table ({len(lut)} layers)"):
            self.texture = self.ctx.buffer(np.ascontiguousarray(lut, np.float32).tobytes())
            self.rows = self.ctx.buffer(rows.tobytes())
        self.table = lut
        self.lobe_rows = rows[:count]

    def defines(self) -> dict:
        """shaders/lobe_albedo.glsl's grid, axes and flags."""
        return {"LOBE_ALBEDO_COS": LUT_COS, "LOBE_ALBEDO_PHI": LUT_PHI, **AXES, **FLAGS}

    def bind(self) -> None:
        """The rows and the values (LOBE_ALBEDO_BINDING, LOBE_ALBEDO_TABLE_BINDING)."""
        self.texture.bind_to_storage_buffer(LOBE_ALBEDO_TABLE_BINDING)
        self.rows.bind_to_storage_buffer(LOBE_ALBEDO_BINDING)

    def describe(self) -> dict:
        return {"albedo_ms": round(self.albedo_ms, 3), "layers": self.layers, "computed": self.computed,
                "grid": [LUT_COS, LUT_PHI], "samples": ALBEDO_SAMPLES,
                "inexact": int(np.sum((self.lobe_rows[:, 3] & FLAGS["LOBE_ALBEDO_EXACT"]) == 0))
                if self.rows is not None else 0}

    def _release(self) -> None:
        for obj in (self.texture, self.rows):
            if obj is not None:
                obj.release()
        self.texture = self.rows = None

    def release(self) -> None:
        self._release()
