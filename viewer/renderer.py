"""The renderer: one class for the window and for headless captures.

    renderer = Renderer(ctx, Bake(path), supersample=2)
    renderer.render(camera, 1280, 720)
    renderer.read_linear()     # (720, 1280, 3) float32 radiance, row 0 = top of the image
    renderer.read_srgb()       # (720, 1280, 3) uint8, tone-mapped
    renderer.read_distance()   # (720, 1280) float32 metres from the eye to the visible surface
    renderer.display_texture   # RGBA8 texture (GL orientation) a window blits to the screen
    renderer.stats             # GPU ms per pass, what was drawn and skipped

It draws into its own textures and never touches the default framebuffer, so it
does not care whether a window or nothing at all is on the other side; the
framebuffer bound before `render` is bound again after it.

Per frame (docs/VIEWER.md, "Passes"): mirror passes of the planar reflectors in view
(section 4.5.1, viewer/passes/mirror.py: at most `mirror_budget` per frame, at
the render size) -> G-buffer raster pass at N times the output size (N =
supersample) -> occlusion queries of the reflectors (read by a later frame) ->
shading in compute -> resolve (N x N box mean; skipped for N = 1) -> tone map.
`read_linear` is the resolved radiance before exposure and tone mapping:
physical radiance, comparable with a path tracer's image. `stats["mirror"]` says
which reflectors got a pass and why the others did not.

Specular light (section 4.4) depends on the frame's mode:

    renderer.render(camera, w, h)                    # "walkthrough": regular lobe patterns
    renderer.render(camera, w, h, mode="converge")   # one still-camera frame (viewer/progressive.py)
    renderer.render(camera, w, h, mode="auto")       # the window: converge while the view stands still

A "converge" frame adds quasi-random samples to the running mean of the frames
before it (same camera, size, supersampling, exposure and hidden objects; any
change starts over) and shows that mean; the G-buffer of a standing view is drawn
once.
"""
from __future__ import annotations

import time
from collections import deque
from statistics import median

import moderngl
import numpy as np

from glint.core.errors import GlintError
from glint.viewer.camera import ViewCamera, depth_distances
from glint.viewer.draw_list import DrawList
from glint.viewer.gl import check_context, describe, max_texture_size, software_renderer
from glint.viewer.gpu_scene import GpuScene, shader_defines
from glint.viewer.passes.gbuffer import GBufferPass
from glint.viewer.passes.mirror import MIRROR_RESOLUTIONS, MirrorPasses, mirror_defines
from glint.viewer.passes.resolve import ResolvePass
from glint.viewer.passes.shading import ShadingPass, scene_units
from glint.viewer.passes.tonemap import TonemapPass
from glint.viewer.progressive import DEFAULT_MAX_FRAMES, DEFAULT_SAMPLES_PER_FRAME, Progressive
from glint.viewer.reflectors import DEFAULT_BUDGET
from glint.viewer.split_sum import SplitSum
from glint.viewer.timing import PassTimer

MAX_SUPERSAMPLE = 8
MODES = ("walkthrough", "converge", "auto")
# -- the product's walkthrough and the comparison methods --------------------------------------------
# The product estimates lobes with the thesis' regular patterns (Eq. 4.10-4.17), their weighted mean of the
# radiance normalised by the lobe's directional albedo (viewer/lobe_albedo.py; Eq. 4.25's normalisation
# was biased, more so with Kurt's alpha): the defaults, what `glint view` shows. The others are comparison methods, for `glint bench --methods`
# and `glint capture --walkthrough-method / --weights` (docs/BENCHMARKS.md): Colbert and Krivanek's
# filtered importance sampling with as many samples, the split-sum prefiltered cube maps of game
# engines (viewer/split_sum.py; prefiltered when the renderer is made, stats["split_sum"]["prefilter_ms"])
# and the thesis' Eq. 4.25 and 4.24 weights (viewer/passes/shading.py WEIGHTS). They stay here, not in bench/: each is a
# variant of the specular pass (shaders/specular.glsl) that only the renderer can run.
WALKTHROUGH_METHODS = {"patterns": "SPECULAR_PATTERNS", "filtered-importance": "SPECULAR_FILTERED_IS",
                       "split-sum": "SPECULAR_SPLIT_SUM"}
# The MIP footprint of each pattern look-up in a cube map or mirror buffer (shaders/specular.glsl): the lobe's
# second moment less the pattern's spread for reflection lobes and the thesis' share A / n of the
# lobe's 99 % ellipse (Eq. 4.16) for transmission lobes (the default; viewer/lobe_patterns.py,
# "Footprint"), A / n for all lobes, or the second moment for all lobes.
FOOTPRINTS = {"moment": 0, "thesis": 1, "moment-all": 2}
# How the G-buffer and the mirror passes are made, by name (glint capture --gbuffer, the measurement
# tools) -> Renderer(visibility=...): as the renderer picks, rasterised, through a visibility buffer.
GBUFFER_WAYS = {"auto": None, "raster": False, "visibility": True}


class Renderer:
    def __init__(self, ctx: moderngl.Context, bake, supersample: int = 1, exposure: float = 0.0, *,
                 lobe_samples: int | None = None, weights: str = "albedo", walkthrough: str = "patterns",
                 samples_per_frame: int = DEFAULT_SAMPLES_PER_FRAME, max_frames: int = DEFAULT_MAX_FRAMES,
                 blend_frames: int = 0, mirror_budget: int = DEFAULT_BUDGET, planar_pattern: str = "auto",
                 footprint: str = "moment", timing: bool = True, small_objects: float = 0.0,
                 display: bool = True, lod: float = 0.0, visibility: bool | None = None,
                 mirror_scissor: bool = False, mirror_resolution: float = 1.0):
        """lobe_samples: samples of every lobe's walkthrough pattern (None: chosen per lobe from its
        width); weights: "albedo" (the default), "eq4.25" or "eq4.24" (the walkthrough's estimator); walkthrough: a key of
        WALKTHROUGH_METHODS (anything but the defaults is a comparison method, above); samples_per_frame, max_frames, blend_frames: the still camera's
        (viewer/progressive.py); mirror_budget: mirror passes per frame at most (planar
        reflectors, viewer/reflectors.py; 0: none, planar objects show their diffuse part);
        planar_pattern: "auto", "ring" or "multi_ring", the walkthrough pattern of isotropic lobes
        on planar reflectors (viewer/gpu_materials.py; "auto" is the multi-ring); footprint: a key of
        FOOTPRINTS, the filter of each pattern look-up in a cube map; timing: False times no pass
        (viewer/timing.py "off": no glFinish between passes on a software renderer; stats then
        has no per-pass times); small_objects: the G-buffer leaves out objects (not emitters) whose
        bounding sphere projects to a radius under this many output pixels (0: none; the bake's
        cube-map renders, where such an object covers under a texel); display: False skips the tone
        map (no display_texture or read_srgb: for renderers read with read_linear only); lod: > 0
        uploads levels of detail (viewer/lod.py) and draws each object in the G-buffer at the
        coarsest that keeps `lod` triangles per G-buffer pixel it covers (0: every object whole;
        the bake's cube-map renders, whose texels are larger than most triangles); visibility: the
        G-buffer through a visibility buffer (viewer/passes/gbuffer.py; None: unless the renderer is
        a software one, where it is no faster: docs/VIEWER.md; never with `lod`); mirror_scissor: each
        mirror pass rasterises only the rectangle its look-ups are estimated to reach (an experiment,
        off by default: viewer/passes/mirror.py); mirror_resolution: the mirror buffers' size as a
        fraction of the render's, 1 (the default), 0.5 or 0.25 (faster passes, reflections less sharp:
        docs/VIEWER.md, "Mirror buffers at a lower resolution")."""
        check_context(ctx)
        if walkthrough not in WALKTHROUGH_METHODS:
            raise GlintError(f"unknown walkthrough method {walkthrough!r}; use one of {', '.join(WALKTHROUGH_METHODS)}")
        if footprint not in FOOTPRINTS:
            raise GlintError(f"unknown look-up footprint {footprint!r}; use one of {', '.join(FOOTPRINTS)}")
        self.ctx = ctx
        self.bake = bake
        self.supersample = supersample
        self.exposure = float(exposure)  # EV: the tone-mapped image is scaled by 2^exposure
        self.lod = max(float(lod), 0.0)
        self.scene = GpuScene(ctx, bake, planar_pattern=planar_pattern, lod=self.lod > 0)
        if lobe_samples is not None:
            self.scene.set_lobe_samples(lobe_samples)
        if not (isinstance(mirror_budget, (int, np.integer)) and mirror_budget >= 0):
            raise GlintError(f"the mirror-pass budget must be a whole number of at least 0 (got {mirror_budget!r})")
        if mirror_resolution not in MIRROR_RESOLUTIONS:
            raise GlintError(f"the mirror buffers' resolution must be one of "
                             f"{', '.join(map(str, MIRROR_RESOLUTIONS))} (got {mirror_resolution!r})")
        mirror_unit = scene_units(self.scene)["MIRROR_RADIANCE_UNIT"]
        defines = {**shader_defines(), **mirror_defines(mirror_unit)}
        self.draws = DrawList(ctx, self.scene, defines)
        if visibility is None:
            visibility = not software_renderer(ctx)
        self.gbuffer = GBufferPass(ctx, self.scene, self.draws, defines, visibility=visibility)
        self.mirror = MirrorPasses(ctx, self.scene, bake, self.draws, defines, budget=int(mirror_budget),
                                   visibility=self.gbuffer.visibility, scissor=mirror_scissor,
                                   resolution=mirror_resolution)
        self.mirror.set_units(mirror_unit)
        self.split_sum = SplitSum(ctx, self.scene) if walkthrough == "split-sum" else None
        self.shading = ShadingPass(ctx, self.scene, defines, weights=weights, mirror=self.mirror,
                                   split_sum=self.split_sum, footprint=FOOTPRINTS[footprint])
        self.resolve = ResolvePass(ctx, defines)
        self.tonemap = TonemapPass(ctx, defines)
        self.progressive = Progressive(ctx, defines, samples_per_frame=samples_per_frame, max_frames=max_frames,
                                       blend_frames=blend_frames)
        self.weights = weights
        self.walkthrough = walkthrough
        self.timer = PassTimer(ctx, method=None if timing else "off")
        self.small_objects = max(float(small_objects), 0.0)
        self.display = bool(display)
        self.cpu_ms: deque = deque(maxlen=self.timer.history)  # wall time of each render() call
        self.size: tuple[int, int] | None = None
        self.mode: str | None = None  # of the last frame: "walkthrough" or "converge"
        self._last_key = None  # view of the last frame, for mode="auto"
        self._walkthrough_key = None  # view of the walkthrough image in _linear, while it is one
        self._has_base = False  # the still camera fades from that image
        self._gbuffer_key = None  # view the G-buffer holds
        self._linear: moderngl.Texture | None = None
        self._display: moderngl.Texture | None = None
        self._view: tuple[ViewCamera, float] | None = None  # camera and aspect of the last frame
        self._device = describe(ctx)

    @property
    def supersample(self) -> int:
        return self._supersample

    @supersample.setter
    def supersample(self, n: int) -> None:
        if not (isinstance(n, (int, np.integer)) and 1 <= n <= MAX_SUPERSAMPLE):
            raise GlintError(f"supersampling must be a whole number from 1 to {MAX_SUPERSAMPLE} (got {n!r})")
        self._supersample = int(n)

    def check_size(self, width: int, height: int) -> None:
        """GlintError unless width x height (times the supersampling) can be rendered here."""
        if not (int(width) == width and int(height) == height and width >= 1 and height >= 1):
            raise GlintError(f"bad image size {width}x{height}: width and height must be at least 1")
        limit = max_texture_size(self.ctx)
        n = self.supersample
        if max(width, height) * n > limit:
            raise GlintError(f"image size {width}x{height} with supersampling {n} needs "
                             f"{width * n}x{height * n} pixels; this OpenGL allows at most {limit} "
                             "per side: use a smaller size or --supersample")

    def render(self, camera: ViewCamera, width: int, height: int, hidden_objects=(),
               mode: str = "walkthrough") -> None:
        """Render one frame of `camera` at width x height output pixels, leaving out the
        objects whose manifest index is in `hidden_objects` (the bake's cube maps, section 4.4.1);
        `mode` is one of MODES (see the module docstring)."""
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, not {mode!r}")
        start = time.perf_counter()
        try:
            self._render(camera, width, height, hidden_objects, mode)
        finally:
            self.cpu_ms.append((time.perf_counter() - start) * 1e3)

    def _render(self, camera: ViewCamera, width: int, height: int, hidden_objects, mode: str) -> None:
        self.check_size(width, height)
        hidden = tuple(sorted(set(int(i) for i in hidden_objects)))
        key = (Progressive.view_key(camera, (width, height), self.supersample, self.exposure), hidden)
        if mode == "auto":  # the window: refine while the view stands still
            mode = "converge" if key == self._last_key else "walkthrough"
        self._last_key = key
        if mode == "walkthrough":
            self.progressive.invalidate()
            self._frame(camera, width, height, hidden, WALKTHROUGH_METHODS[self.walkthrough], key)
            self._walkthrough_key = key
            return
        progressive = self.progressive
        restarted = progressive.begin(key)
        if progressive.converged or (not restarted and not self.shading.has_specular):
            return  # the image is final (without specular light the first frame is exact)
        if restarted:  # fade from the walkthrough image of this very view, when there is one
            self._has_base = progressive.blend_frames > 0 and self._walkthrough_key == key
            if self._has_base:
                progressive.keep_base(self._linear)
        self._walkthrough_key = None
        first, count = progressive.samples()
        self._frame(camera, width, height, hidden, "SPECULAR_QMC", key, qmc=(first, count),
                    blend=progressive.blend(self._has_base))

    def _frame(self, camera: ViewCamera, width: int, height: int, hidden: tuple, specular: str, key, *,
               qmc=(0, 0), blend: float | None = None) -> None:
        """One frame: G-buffer (a still-camera frame skips it when it holds this view `key`
        already), shading with the specular mode `specular` (viewer/passes/shading.py
        SPECULAR_MODES), resolve, the still camera's accumulation when `blend` (the weight of
        the mean) is given, tone map. A walkthrough frame always costs a whole frame."""
        ctx, n, timer = self.ctx, self.supersample, self.timer
        aspect = width / height
        full = (width * n, height * n)
        self.gbuffer.resize(full)
        self.shading.resize(full)
        self.mirror.resize(full)
        previous = ctx.fbo  # after resizing, which may have deleted our own bound framebuffer
        timer.start_frame()
        if blend is None or key != self._gbuffer_key:
            # A still camera keeps the mirror buffers with the G-buffer: both depend on the view only.
            mirror = self.mirror
            if mirror.active:
                plan = mirror.plan(camera, aspect, hidden)
                mirror.run(plan, camera, aspect, hidden, timer)
            with timer("gbuffer"):
                self.gbuffer.run(camera, aspect, hidden, min_radius_ndc=2.0 * self.small_objects / height,
                                 triangles_per_pixel=self.lod)
            if mirror.active and plan.queries:
                with timer("occlusion_queries"):
                    mirror.query_occlusion(plan, self.gbuffer.fbo, camera, aspect)
            self._gbuffer_key = key
        with timer("shading"):
            linear = self.shading.run(self.gbuffer.targets, camera, aspect)
        if self.shading.has_specular:
            with timer("specular"):
                linear = self.shading.run_specular(self.gbuffer.targets, camera, aspect, mode=specular,
                                                   qmc_first=qmc[0], qmc_count=qmc[1])
        if n > 1:
            with timer("resolve"):
                linear = self.resolve.run(linear, n)
        if blend is not None:
            with timer("accumulate"):
                linear = self.progressive.add(linear, blend)
        if self.display:
            with timer("tonemap"):
                self._display = self.tonemap.run(linear, self.exposure)
        self._linear = linear
        self._view = (camera, aspect)
        self.size = (width, height)
        self.mode = "walkthrough" if blend is None else "converge"
        if previous is not None:  # a standalone context has none bound
            previous.use()

    # -- live material edits ---------------------------------------------------------------------
    def set_material(self, index: int, material) -> None:
        """Show material `index` as the typed `material` (core/manifest.py Material) from the next frame on
        (GpuScene.set_material checks it: GlintError for values it cannot show). The G-buffer
        holds kd/pi E and the mirror buffers kd and emission, so both are drawn again; the next
        `mode="auto"` frame is a walkthrough frame of the new material and the still-camera
        refinement starts over from it."""
        self.scene.set_material(index, material)
        self.mirror.set_material(index, self.scene.materials[index])  # the guard band follows the lobes
        self.shading.update_specular(self.scene)
        self.invalidate()

    def invalidate(self) -> None:
        """Forget every image of earlier frames: the next frame draws the G-buffer and mirror buffers
        again, and a still camera refines from scratch (after one walkthrough frame in mode "auto")."""
        self.progressive.invalidate()
        self._last_key = self._walkthrough_key = self._gbuffer_key = None
        self._has_base = False

    def pick(self, x: float, y: float) -> tuple[int, int] | None:
        """(object, material) seen at output pixel (x, y) of the last frame, x from the left and y
        from the top (window coordinates), or None where no object is (sky, outside). Reads one
        G-buffer pixel (the centre supersample of that output pixel)."""
        if self.size is None or not (0 <= x < self.size[0] and 0 <= y < self.size[1]):
            return None
        n = self.supersample
        return self.gbuffer.pick(int(x) * n + n // 2, (self.size[1] - 1 - int(y)) * n + n // 2)

    def replace_lightmaps(self, front: list, back: list) -> None:
        """New light-map pages for the bake's atlas (GpuScene.replace_lightmaps); the next frame
        draws with them: the G-buffer a still camera keeps (its diffuse is kd / pi x E) and the
        running mean are redone."""
        self.scene.replace_lightmaps(front, back)
        self._gbuffer_key = None
        self.progressive.invalidate()

    def replace_probes(self, probes: dict) -> None:
        """New radiance for cube-map probes, {bake file: its faces' MIP chain} (CubeMaps.replace; a
        re-bake after a material edit re-renders them, glint/cubemap_stage.py ProbeRefresher); the
        split-sum arrays of the classes they are in are prefiltered again, and the still camera's
        running mean starts over."""
        classes = {self.scene.cubemaps.replace(file, chain) for file, chain in probes.items()}
        if self.split_sum is not None:
            for k in sorted(classes):
                self.split_sum.refresh(self.scene.cubemaps, k)
        if classes:
            self.invalidate()

    # -- results ---------------------------------------------------------------------------------
    def _require_frame(self) -> None:
        if self._linear is None:
            raise RuntimeError("nothing rendered yet: call render() first")

    def _require_display(self) -> None:
        self._require_frame()
        if self._display is None:
            raise RuntimeError("this renderer makes no display image (Renderer(display=False))")

    def read_linear(self) -> np.ndarray:
        """(H, W, 3) float32 linear radiance after the resolve; row 0 is the top of the image."""
        self._require_frame()
        w, h = self._linear.size
        data = np.frombuffer(self._linear.read(alignment=1), np.float32).reshape(h, w, 4)
        return np.ascontiguousarray(data[::-1, :, :3])

    def read_srgb(self) -> np.ndarray:
        """(H, W, 3) uint8 tone-mapped sRGB; row 0 is the top of the image."""
        self._require_display()
        w, h = self._display.size
        data = np.frombuffer(self._display.read(alignment=1), np.uint8).reshape(h, w, 4)
        return np.ascontiguousarray(data[::-1, :, :3])

    def read_distance(self) -> np.ndarray:
        """(H, W) float32 distance in metres from the eye to the visible surface, the mean over the
        pixel's N x N supersamples that hit one; inf where only sky shows. Row 0 is the top.

        From the depth buffer (viewer/camera.py `depth_distances`)."""
        self._require_frame()
        camera, aspect = self._view
        depth = self.gbuffer.targets["depth"]
        w, h = depth.size
        d = np.frombuffer(depth.read(alignment=1), np.float32).reshape(h, w)
        mean = depth_distances(d, camera, aspect, w // self.size[0], np.inf)
        return np.ascontiguousarray(mean[::-1], np.float32)

    @property
    def display_texture(self) -> moderngl.Texture:
        """The last frame, tone-mapped: RGBA8, GL orientation (row 0 at the bottom), sRGB-encoded
        already (blit it to a framebuffer without GL_FRAMEBUFFER_SRGB)."""
        self._require_display()
        return self._display

    @property
    def stats(self) -> dict:
        """GPU ms per pass (last frame and median of recent ones), what was drawn and skipped."""
        drawn = self.draws.record(GBufferPass.REGION) if self.size else {}
        skipped: dict = {"objects_outside_view": list(drawn.get("objects_culled", [])),
                         "objects_without_triangles": list(drawn.get("objects_empty", []))}
        if drawn.get("objects_hidden"):
            skipped["objects_hidden"] = list(drawn["objects_hidden"])
        if drawn.get("objects_too_small"):
            skipped["objects_too_small"] = list(drawn["objects_too_small"])
        if self.supersample == 1:
            skipped["resolve"] = "supersample 1: the shaded image is the output"
        specular = self._specular_stats()
        if not specular["materials_with_lobes"]:
            skipped["specular"] = "no material has view-dependent lobes: no specular work at all"
        elif specular["tiles_skipped"]:
            skipped["specular_tiles"] = (f"{specular['tiles_skipped']} of "
                                         f"{specular['tiles_skipped'] + specular['tiles_with_lobes']} tiles "
                                         "have no view-dependent pixels and skipped the specular code")
        if specular["objects_without_cube_map"]:
            skipped["lobes_without_cube_map"] = (
                "objects with lobes but neither a cube map nor a planar reflector's mirror pass show "
                "their diffuse part only: " + ", ".join(specular["objects_without_cube_map"]))
        mirror = self._mirror_stats()
        planar_off = mirror.get("planar_without_pass", {})
        if planar_off.get("no_specular"):
            skipped["planar_specular"] = ("planar reflectors whose plane got no mirror pass this frame "
                                          "(see mirror.skipped_reflectors) show their diffuse part only: "
                                          + ", ".join(planar_off["no_specular"]))
        size = list(self.size) if self.size else None
        gpu_median = self.timer.median_ms  # reads the last frame's queries first
        return {
            "device": self._device,
            "size": size,
            "render_size": [s * self.supersample for s in size] if size else None,
            "supersample": self.supersample,
            "exposure": self.exposure,
            "gpu_ms": dict(self.timer.last_ms),
            "gpu_ms_median": gpu_median,
            # The render() call as the program sees it: Python and the GL driver (on a software
            # renderer the driver's part includes the work a GPU would do; see viewer/timing.py).
            "cpu_ms": {"last": round(self.cpu_ms[-1], 3) if self.cpu_ms else None,
                       "median": round(median(self.cpu_ms), 3) if self.cpu_ms else None},
            "frames_timed": self.timer.frames,
            "timing": self.timer.description,
            "objects": len(self.scene.objects),
            "objects_drawn": drawn.get("objects_drawn", 0),
            "triangles": drawn.get("triangles", 0),
            "triangles_in_scene": self.scene.triangles,
            "lightmap_format": "RGBA16F" if self.scene.lightmap_dtype == "f2" else "RGBA32F",
            "gbuffer": "visibility" if self.gbuffer.visibility else "raster",
            "skipped": skipped,
            "specular": specular,
            "mirror": mirror,
            "lobe_albedo": self.scene.material_buffers.albedo.describe(),
            **({"split_sum": self.split_sum.describe()} if self.split_sum is not None else {}),
        }

    def _mirror_stats(self) -> dict:
        """The planar reflectors' mirror passes of the last frame (viewer/passes/mirror.py)."""
        manifest, scene = self.bake.model, self.scene
        lobed = {i: o.name for i, o in enumerate(manifest.objects)
                 if scene.materials[o.material].get("lobes")}  # as edited: dicts (material editing)
        cube_mapped = {i for i in lobed if scene.cubemaps.has_cubemap(i)}
        return self.mirror.stats(lobed, cube_mapped)

    def _specular_stats(self) -> dict:
        """The specular work of the last frame (reads the shading pass's counters: waits for the GPU)."""
        manifest, scene = self.bake.model, self.scene
        materials = scene.materials  # as edited (set_material): dicts (material editing)
        lobed = [i for i, m in enumerate(materials) if m.get("lobes")]
        counts = (self.shading.specular_counts() if self.size else
                  {"pixels": 0, "tiles": 0, "tiles_skipped": 0, "lookups": 0, "mirror_lookups": 0})
        planar = {i for i, _ in self.mirror.objects} if self.mirror.active else set()
        lobes, k = [], 0
        for m in materials:
            for j, _ in enumerate(m.get("lobes") or []):
                lobes.append({"material": m["name"], "lobe": j, **scene.lobe_patterns[k]})
                k += 1
        mode = self.mode
        if mode == "converge":
            mode = "converged" if self.progressive.converged else "converging"
        return {
            "mode": mode,
            "walkthrough": self.walkthrough,
            "weights": self.weights,
            "materials_with_lobes": len(lobed),
            "objects_without_cube_map": [o.name for i, o in enumerate(manifest.objects)
                                         if o.material in lobed and not scene.cubemaps.has_cubemap(i)
                                         and i not in planar],
            "pixels_with_lobes": counts["pixels"],
            "tiles_with_lobes": counts["tiles"],
            "tiles_skipped": counts["tiles_skipped"],
            "cube_map_lookups": counts["lookups"],
            "mirror_buffer_lookups": counts.get("mirror_lookups", 0),
            "lookups_per_pixel_with_lobes": ((counts["lookups"] + counts.get("mirror_lookups", 0)) / counts["pixels"]
                                             if counts["pixels"] else 0.0),
            "samples_per_lobe": lobes,
            "cube_maps_bound": self.shading.cube_maps_bound,
            "cube_map_classes": scene.cubemaps.describe(),
            "cube_map_memory": scene.cubemaps.memory(),  # probes, MiB, driver's free MiB (viewer/cubemaps.py)
            "progressive": self.progressive.describe(),
        }

    def release(self) -> None:
        for part in (self.gbuffer, self.mirror, self.draws, self.shading, self.resolve, self.tonemap,
                     self.progressive, self.split_sum, self.scene, self.timer):
            if part is not None:
                part.release()
        self._linear = self._display = None

    def __enter__(self) -> "Renderer":
        return self

    def __exit__(self, *exc) -> None:
        self.release()
