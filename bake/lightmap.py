"""Light-map stage: texel samples -> irradiance by path tracing -> invalid texels -> dilation -> denoise.

Stores irradiance E, not radiance, so kd can still change at run time:
diffuse radiance = kd / pi * E (Eq. 4.1).

Two sides. A texel of an object whose material is two-sided (glTF doubleSided, or thin
transmissive: `Material.two_sided`) is baked twice, once around its normal n for the front
page and once around -n for a back page at the same light-map coordinates; the viewer reads
the back page where it sees the back face. A double-sided surface is then lit on the side
that is seen, whichever way its normals point. Single-sided objects have no back side (their
back face is black, as in Mitsuba), and their texels on the back pages stay empty.

Texel order, which fixes each texel's random numbers (bake/irradiance.py): every front texel
first, page by page, row-major, then the back texels in the same order, so adding back sides
leaves the front pages' samples as they were.

Seams: after denoising, the border texels of charts that meet on a continuous surface are
stitched (bake/seams.py) and the texels around them filled again.

Sample points: each side's sample is first moved out of meshes that cover it (bake/sample_points.py:
a moulding through the ceiling, a sofa on the floor; double-sided or not). This sample pass (and
finding the samples in cavities, below) runs on the workers tile by tile before the tracing
(`_sample_tile`; on this machine's processes when the tracing goes to a Dask cluster), each texel on
its own, so its result does not depend on the tiles either.

Adaptive sampling (issue 25). A texel's first `samples` paths give their mean and, from the sum of
their luminance squared, their standard deviation. A texel whose paths' deviation is over SELECT_CV
x max(their mean, FLOOR_SHARE x the median lit texel's; black corners are not flagged) is flagged: a
few of its paths found light through a narrow gap with a huge weight. The
texels next to a flagged one (the 3 x 3 around it, the same object and side) then get
`adaptive_samples` x `samples` paths in all, the paths that follow their first ones in their own
sequences (bake/irradiance.py refine_irradiance), in a second round of tasks; every path weighs the
same. A texel's own paths never decide how many it gets (its own flag does not count), so its
estimate stays unbiased: the number is independent of its paths. A rule by the texel's own error
(refine while it is over a target) averages to less than the plain estimator where rare paths carry
the light: -16 to -90 % at living-room's former fireflies (bench/measure_fireflies.py --bias,
docs/BAKE.md "Fireflies"). The price: a firefly with no flagged neighbour would stay, so texels whose
samples are enclosed (bake/sample_points.py `enclosed`: every direction meets a surface within 8
texels, half a metre at preview, under a sofa, behind books) get more paths whatever their
neighbours: the cavities where light comes only through narrow openings. That choice is the geometry's alone, so it
is unbiased too.

Invalid texels: those whose own hemisphere rays hit the back of single-sided surfaces more
often than `backface_threshold` (inside walls, under boxes), and those whose covered sample has no
free position in its footprint; dilation fills them from their valid neighbours, of their own
object first. Unlit texels: surface points that no light reached on any side they were
baked for (E = 0 exactly). Both are counted per object for the bake's statistics and warning.
"""
from __future__ import annotations

import time
from contextlib import nullcontext
from dataclasses import dataclass

import numpy as np

from glint.bake.alpha import Coverage, cut_out_texels
from glint.bake.denoise import denoise_lightmap
from glint.bake.dilate import dilate
from glint.parallel.cpus import usable_cpus
from glint.parallel.executor import TASKS_PER_WORKER, LocalExecutor, executor_for
from glint.bake.irradiance import compute_irradiance, mean_irradiance, refine_irradiance, relative_error
from glint.bake.lights import luminance
from glint.bake.raytrace import RayTracer
from glint.bake.sample_points import adjust_samples, enclosed
from glint.bake.seams import stitch
from glint.bake.texels import TexelPage
from glint.core.errors import warn
from glint.core.scene import Scene

TILE = 2048  # texels per job: small enough for a smooth progress bar, big enough to amortise numpy
MIN_CLUSTER_TILE = 256  # texels per job at the least, on a cluster of many workers (tile_size)
# The bake warns when more than these shares of its texels are invalid, or of its surface unlit.
# Well-made scenes have 1.5-16 % invalid texels (contacts, furniture against walls, slivers such as
# books side by side; docs/BAKE.md has the figures) and a few per cent unlit; more means a scene problem (surfaces seen from behind or inside others, no light
# reaching a part of the scene).
INVALID_WARN_SHARE = 0.30
UNLIT_WARN_SHARE = 0.10
WARN_OBJECTS = 3  # objects the warning names
# Exposure: `glint capture` and `glint view` show radiance x 2^EV (default EV 0) through the ACES curve
# (viewer/passes/tonemap.py). A lit surface's typical radiance should be near middle grey; the bake warns
# when the median radiance kd/pi E of its lit texels lies more than DARK_STOPS below it (ACES then shows
# it below 6 % sRGB: nearly black) or BRIGHT_STOPS above it (above 99 %: white), and suggests an
# --exposure that brings it to middle grey. The built-in living-room's median lies 3.6 stops below
# (draft bake): dim, not black, so no warning.
MIDDLE_GREY = 0.18
# Adaptive sampling (module docstring): after the first pass a texel is flagged when the standard
# deviation of its paths' luminance is over SELECT_CV x max(their mean, FLOOR_SHARE x the median lit
# texel's); a texel with a flagged neighbour then gets settings.adaptive_samples x samples paths.
# SELECT_CV 8 is a relative standard error of 0.71 at preview's 128 paths (living-room's fireflies:
# 0.61-0.96), 1.41 at draft's 32 (above what 32 paths can show: draft is not refined) and 0.25 at
# final's 1024.
SELECT_CV = 8.0
# Texels whose samples lie in cavities (bake/sample_points.py `enclosed`) get this many times `samples`
# paths (at most adaptive_samples): enough for living-room's last firefly at preview; 4 removes no more
# fireflies there and made the wooden staircase's light maps 29 % slower (docs/BAKE.md "Fireflies").
ENCLOSED_SAMPLES = 2
FLOOR_SHARE = 0.05
DARK_STOPS, BRIGHT_STOPS = 4.0, 5.0


@dataclass
class LightmapPages:
    irradiance: list[np.ndarray]  # (H, W, 3) float32 per page, dilated (and denoised)
    baked: list[np.ndarray]  # (H, W) bool: texels whose value was path traced (not dilated in)
    texels: int  # texels path traced (front and back sides)
    invalid: int  # of them, invalidated for seeing the back of single-sided surfaces
    rays: int
    # back sides of two-sided objects, page by page like `irradiance` and `baked` (empty lists: no
    # two-sided object in the scene)
    back_irradiance: list[np.ndarray]
    back_baked: list[np.ndarray]
    back_texels: int = 0  # of `texels`, back sides
    unlit: int = 0  # surface texels (front texels) of non-emissive objects that no light reached on any side
    invalid_by_object: np.ndarray | None = None  # (objects,) int64 invalid texels (both sides)
    unlit_by_object: np.ndarray | None = None  # (objects,) int64 unlit surface texels
    # median radiance kd/pi E (W/(m^2 sr), grey) of the lit surface texels of non-emissive objects; None: none lit
    median_radiance: float | None = None
    trace_seconds: float = 0.0  # the path tracing of the tiles (the stage's parallel part), wall clock
    tiles: int = 0  # tasks the texels were traced in
    moved: int = 0  # of `texels`, samples moved out of geometry that covered them (bake/sample_points.py)
    refined: int = 0  # of `texels`, given more paths by adaptive sampling
    refined_paths: int = 0  # the paths adaptive sampling added
    enclosed: int = 0  # of `refined`, chosen only because their samples lie in cavities (bake/sample_points.py)
    # wall-clock seconds of the stage's steps, in order: "tracer" (Embree's scene, here), "samples" (moved
    # out of covering geometry, cavities found: on the workers), "tiles" (the path tracing, on the workers),
    # "refine" (adaptive sampling: the texels chosen here, traced on the workers; trace_seconds is the
    # two together), "pages" (images, dilation, denoising, seams). Where a many-core machine's time
    # goes: "tracer" and "pages" run in this one process.
    phase_seconds: dict | None = None

    def rgba(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """(front, back) pages as the bake directory stores them (core/bake_dir.py): (H, W, 4) float32,
        RGB the irradiance, A = 1 where path traced."""
        return tuple([np.concatenate([image, baked[..., None].astype(np.float32)], axis=-1)
                      for image, baked in zip(images, masks)]
                     for images, masks in ((self.irradiance, self.baked), (self.back_irradiance, self.back_baked)))


def _setup_samples(scene: Scene, points: np.ndarray, normals: np.ndarray, sizes: np.ndarray, objects: np.ndarray,
                   cavities: bool):
    """A worker's state for the sample pass: the scene's tracer and alpha coverage, every texel's sample
    point, normal, world size and object; `cavities`: whether the pass also finds enclosed samples."""
    tracer = RayTracer(scene)
    return tracer, Coverage(scene, tracer), points, normals, sizes, objects, cavities


@dataclass(frozen=True)
class SampleTask:
    """The sample pass's task: the texels first..first + count of the worker's state."""
    first: int
    count: int


def _sample_tile(state, task: SampleTask):
    """The task's samples moved out of covering geometry (bake/sample_points.py adjust_samples: points,
    moved, invalid) and, where asked, which of the moved samples lie in cavities (`enclosed`). Per
    texel, so the result does not depend on the tasks."""
    tracer, coverage, points, normals, sizes, objects, cavities = state
    rows = slice(task.first, task.first + task.count)
    adjusted = adjust_samples(tracer, points[rows], normals[rows], sizes[rows], objects[rows], coverage)
    moved_points = adjusted.points.astype(points.dtype)  # as the tiles trace from them
    closed = (enclosed(tracer, moved_points, normals[rows], sizes[rows], coverage) if cavities
              else np.zeros(task.count, bool))
    return moved_points, adjusted.moved, adjusted.invalid, closed


def _setup(scene: Scene, points: np.ndarray, normals: np.ndarray):
    """A worker's state: the scene, its Embree tracer, and every texel's sample point and normal (sent
    once per worker; a task is then only its range of texels)."""
    return scene, RayTracer(scene), points, normals


@dataclass(frozen=True)
class TileTask:
    """One light-map task: the texels first..first + count of the worker's state, traced with `samples`
    paths each from the bake's `seed`, `max_depth` bounces at most."""
    first: int
    count: int
    samples: int
    seed: int
    max_depth: int


def _trace_tile(state, task: TileTask):
    """The sums of the paths' L and luminance squared, the back-face share and the ray count of the
    task's texels."""
    scene, tracer, points, normals = state
    first, count = task.first, task.count
    result = compute_irradiance(scene, tracer, points[first:first + count], normals[first:first + count], task.samples,
                                seed=task.seed, max_depth=task.max_depth, first_index=first)
    return result.total, result.square, result.backface, result.rays


@dataclass(frozen=True)
class RefineTask:
    """Adaptive sampling's task: more paths for the texels `texels` (global indices into the worker's
    state) from their sums so far (bake/irradiance.py refine_irradiance)."""
    texels: np.ndarray  # (k,) int64
    total: np.ndarray  # (k, 3) float64
    square: np.ndarray  # (k,) float64
    count: np.ndarray  # (k,) int64
    max_samples: int  # paths each texel ends with
    seed: int
    max_depth: int


def _refine_tile(state, task: RefineTask):
    """The task's texels' sums after refinement, and the rays it traced."""
    scene, tracer, points, normals = state
    total, square, count = task.total.copy(), task.square.copy(), task.count.copy()
    rays = tracer.rays
    refine_irradiance(scene, tracer, points[task.texels], normals[task.texels], task.texels.astype(np.uint64),
                      total, square, count, task.max_samples, task.seed, task.max_depth)
    return total, square, count, int(tracer.rays - rays)


def tile_size(texels: int, executor) -> int:
    """Texels per job: TILE, or on a cluster with more worker threads than TILE-sized jobs would keep
    busy (TASKS_PER_WORKER each), fewer, down to MIN_CLUSTER_TILE. A texel's random numbers come from its
    index, so the size never changes a result (bake/irradiance.py)."""
    if not executor.distributed:
        return TILE
    return max(MIN_CLUSTER_TILE, min(TILE, -(-texels // (TASKS_PER_WORKER * executor.workers()))))


def two_sided_objects(scene: Scene) -> np.ndarray:
    """(objects,) bool: which objects get a back side in the light maps."""
    return np.array([scene.material_of(o).two_sided for o in scene.objects], bool)


def emissive_objects(scene: Scene) -> np.ndarray:
    """(objects,) bool: which objects' material emits (emission above 0; an emissive texture multiplies it)."""
    return np.array([bool(np.max(m.emission) > 0) for m in map(scene.material_of, scene.objects)], bool)


def bake_lightmaps(scene: Scene, pages: list[TexelPage], settings, progress=None,
                   executor=None) -> LightmapPages:
    """The light maps of `pages`; the tiles traced by `executor` (parallel/executor.py: the bake's, which
    may be a Dask cluster; default: `settings`' own)."""
    two = two_sided_objects(scene)
    # Texels in the cut-out parts of MASK materials are never seen: not traced, left to dilation.
    covered = [(p.object >= 0) & ~_cut_out(scene, p) for p in pages]
    back_cover = back_cover_of(pages, covered, two)  # the back sides' texels, page by page
    objects = np.concatenate([p.object[c] for p, c in zip(pages, covered)]).astype(np.int64)
    points = np.concatenate([p.position[c] for p, c in zip(pages, covered)])
    normals = np.concatenate([p.normal[c] for p, c in zip(pages, covered)])
    sizes = np.concatenate([_sizes(p, settings)[c] for p, c in zip(pages, covered)])
    front = len(points)
    back = np.flatnonzero(two[objects]) if len(objects) else np.zeros(0, np.int64)
    # the back sides: the same points, around -n
    points = np.concatenate([points, points[back]])
    normals = np.concatenate([normals, -normals[back]])
    n = len(points)
    phases, clock = {}, time.perf_counter()

    def phase(name: str) -> None:  # the step that just ended
        nonlocal clock
        now = time.perf_counter()
        phases[name] = round(now - clock, 3)
        clock = now

    tracer = RayTracer(scene)  # this process's: the seams' probes (_stitched)
    phase("tracer")
    sizes = np.concatenate([sizes, sizes[back]])
    sample_object = np.concatenate([objects, objects[back]])  # each side's sample's object
    total = np.zeros((n, 3))
    square = np.zeros(n)
    paths = np.full(n, settings.samples, np.int64)
    backface = np.zeros(n, np.float32)
    rays = 0
    with executor_for(settings) if executor is None else nullcontext(executor) as tiles:
        tile = tile_size(n, tiles)
        # every side's sample moved out of geometry that covers it (bake/sample_points.py), and, for
        # adaptive sampling, the samples in cavities, where fireflies come from (module docstring,
        # "Adaptive sampling"): on the workers, tile by tile -- this machine's processes when the tiles
        # go to a Dask cluster, which would be sent the scene once more (the staircase's at preview:
        # 226 MiB) for a few seconds' work
        moved, invalid, closed = np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool)
        sample_tasks = [SampleTask(i, min(tile, n - i)) for i in range(0, n, tile)]
        setup = (scene, points, normals, sizes, sample_object, settings.adaptive_samples > 1)
        points = points.copy()
        here = LocalExecutor(usable_cpus()) if tiles.distributed else tiles
        for index, (q, m, bad, c) in here.run(_setup_samples, setup, _sample_tile, sample_tasks):
            rows = slice(sample_tasks[index].first, sample_tasks[index].first + sample_tasks[index].count)
            points[rows], moved[rows], invalid[rows], closed[rows] = q, m, bad, c
        phase("samples")
        t0 = time.perf_counter()
        tasks = [TileTask(i, min(tile, n - i), settings.samples, settings.seed, settings.max_depth)
                 for i in range(0, n, tile)]
        for index, (e, q, b, r) in tiles.run(_setup, (scene, points, normals), _trace_tile, tasks):
            start = index * tile
            total[start:start + len(e)] = e
            square[start:start + len(q)] = q
            backface[start:start + len(b)] = b
            rays += r
            if progress is not None:
                progress(len(e))
        phase("tiles")
        valid = (backface <= settings.backface_threshold) & ~invalid
        refined = cavity = np.zeros(0, np.int64)
        if settings.adaptive_samples > 1 and n:
            flagged = undersampled(pages, covered, back_cover, total, square, paths, valid)
            cavity = np.setdiff1d(np.flatnonzero(valid & closed), flagged)
            refined = np.union1d(flagged, cavity)
            more = []
            for group, factor in ((flagged, settings.adaptive_samples),
                                  (cavity, min(settings.adaptive_samples, ENCLOSED_SAMPLES))):
                # strided, so that neighbouring texels (a gap's whole row) spread over the tasks
                parts = min(len(group), len(tasks), TASKS_PER_WORKER * tiles.workers())
                more += [RefineTask(r, total[r], square[r], paths[r], settings.samples * factor, settings.seed,
                                    settings.max_depth) for r in (group[i::parts] for i in range(parts))]
            # no tasks, no run: a run of none would still build a worker state (a tracer) here
            results = tiles.run(_setup, (scene, points, normals), _refine_tile, more) if more else ()
            for index, (e, q, c, r) in results:
                rows = more[index].texels
                total[rows], square[rows], paths[rows] = e, q, c
                rays += r
    trace_seconds = time.perf_counter() - t0
    phase("refine")
    E = mean_irradiance(total, paths)

    irradiance, baked = _pages(pages, covered, E[:front], valid[:front], settings)
    irradiance = _stitched(tracer, irradiance, baked, pages, 1.0, settings)
    back_irradiance, back_baked = [], []
    if len(back):
        back_irradiance, back_baked = _pages(pages, back_cover, E[front:], valid[front:], settings)
        back_irradiance = _stitched(tracer, back_irradiance, back_baked, pages, -1.0, settings)

    phase("pages")
    # per object: invalid samples (either side); unlit surface texels (no side with light)
    count = len(scene.objects)
    invalid_by_object = np.bincount(sample_object[~valid], minlength=count)
    lit = E[:front].max(axis=1) > 0
    lit[back] |= E[front:].max(axis=1) > 0
    some_valid = valid[:front].copy()
    some_valid[back] |= valid[front:]
    # a texel invalid on every side is counted as invalid only; an emitter's texels are seen by their
    # emission, never black: not unlit
    emitting = emissive_objects(scene)[objects]
    unlit = ~lit & some_valid & ~emitting
    unlit_by_object = np.bincount(objects[unlit], minlength=count)
    median_radiance = _median_radiance(scene, objects, E[:front], lit & valid[:front] & ~emitting)
    return LightmapPages(irradiance, baked, n, int((~valid).sum()), rays, back_irradiance, back_baked,
                         back_texels=len(back), unlit=int(unlit.sum()), invalid_by_object=invalid_by_object,
                         unlit_by_object=unlit_by_object, median_radiance=median_radiance,
                         trace_seconds=trace_seconds, tiles=len(tasks), moved=int(moved.sum()),
                         refined=len(refined), refined_paths=int((paths - settings.samples).sum()),
                         enclosed=len(cavity), phase_seconds=phases)


def back_cover_of(pages: list[TexelPage], covered: list[np.ndarray], two: np.ndarray) -> list[np.ndarray]:
    """Per page, the texels that have a back side (those of two-sided objects among `covered`)."""
    return [c & two[np.maximum(p.object, 0)] for p, c in zip(pages, covered)]


def undersampled(pages: list[TexelPage], covered: list[np.ndarray], back_cover: list[np.ndarray],
                 total: np.ndarray, square: np.ndarray, count: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Adaptive sampling's choice after the first pass (module docstring): the indices of the valid
    texels with a flagged neighbour, a valid texel of the same object and side in the 3 x 3 around it
    (itself not counted) whose paths' coefficient of variation is over SELECT_CV."""
    Y = luminance(total) / count
    lit = valid & (Y > 0)
    floor = FLOOR_SHARE * float(np.median(Y[lit])) if lit.any() else 0.0
    # the paths' standard deviation over their mean: the standard error of the mean x sqrt(paths)
    flagged = valid & (relative_error(total, square, count, floor) * np.sqrt(count) > SELECT_CV)
    flags, same = _windows(pages, covered, back_cover, flagged.astype(np.float64), 3)
    flags[:, 4] = 0.0  # the texel itself: its own paths must not decide how many it gets
    return np.flatnonzero(valid & ((flags * same) > 0).any(axis=1))


def _windows(pages: list[TexelPage], covered: list[np.ndarray], back_cover: list[np.ndarray], values: np.ndarray,
             size: int) -> tuple[np.ndarray, np.ndarray]:
    """Per texel (in the stage's order: the front sides page by page, then the back sides), the
    `values` of the size x size texels around it, row-major (n, size^2), and which of them are texels
    of its object on the same side (n, size^2) bool."""
    n = len(values)
    out = np.zeros((n, size * size))
    same = np.zeros((n, size * size), bool)
    r = size // 2
    offset = 0
    for covers in (covered, back_cover):
        for page, cover in zip(pages, covers):
            ys, xs = np.nonzero(cover)
            k = len(ys)
            if not k:
                continue
            H, W = cover.shape
            image = np.zeros((H + 2 * r, W + 2 * r))
            label = np.full((H + 2 * r, W + 2 * r), -1, np.int64)
            image[ys + r, xs + r] = values[offset:offset + k]
            own = page.object[ys, xs]
            label[ys + r, xs + r] = own
            for i, (dy, dx) in enumerate(np.ndindex(size, size)):
                out[offset:offset + k, i] = image[ys + dy, xs + dx]
                same[offset:offset + k, i] = label[ys + dy, xs + dx] == own
            offset += k
    return out, same


def _stitched(tracer: RayTracer, images: list[np.ndarray], baked: list[np.ndarray], pages: list[TexelPage],
              sign: float, settings) -> list[np.ndarray]:
    """One side's pages with their seams stitched (bake/seams.py) and the texels that are not path
    traced filled again from the stitched ones."""
    grow = settings.padding + 2
    return [np.ascontiguousarray(dilate(image, mask, grow, page.object), dtype=np.float32)
            for image, mask, page in zip(stitch(tracer, images, baked, pages, sign), baked, pages)]


def _sizes(page: TexelPage, settings) -> np.ndarray:
    """(H, W) metres per texel: the page's own, or 1 / texels_per_metre for pages made without."""
    if page.size is not None:
        return page.size
    return np.full(page.object.shape, 1.0 / settings.texels_per_metre, np.float32)


def _median_radiance(scene: Scene, objects: np.ndarray, E: np.ndarray, texels: np.ndarray) -> float | None:
    """The median of kd/pi E (grey: the means of kd's and E's channels) over `texels` (a mask of the
    front texels; `objects`: each texel's object); None when it selects none."""
    if not texels.any():
        return None
    kd = np.array([float(np.mean(np.clip(scene.material_of(o).kd, 0.0, 1.0))) for o in scene.objects])
    return float(np.median(kd[objects[texels]] / np.pi * E[texels].mean(axis=1)))


def exposure_warning(median_radiance: float | None) -> str | None:
    """What to do when the default exposure shows the scene nearly black or white (module constants),
    with the --exposure (whole stops) that brings the median lit radiance to middle grey; None when fine."""
    if not median_radiance or median_radiance <= 0:
        return None
    stops = float(np.log2(MIDDLE_GREY / median_radiance))
    if -BRIGHT_STOPS <= stops <= DARK_STOPS:
        return None
    dark = stops > 0
    return (f"the scene will look {'nearly black' if dark else 'washed out'} at the default exposure: the median "
            f"radiance of its lit surfaces is {median_radiance:.3g} W/(m^2 sr), {abs(stops):.1f} stops "
            f"{'below' if dark else 'above'} middle grey ({MIDDLE_GREY}); view or capture it with --exposure "
            f"{round(stops):d}, or make the lights {'brighter' if dark else 'dimmer'} (glTF point and spot lights "
            "are in candela, directional ones in lux; docs/SCENES.md \"Lights\")")


def _pages(pages: list[TexelPage], covers: list[np.ndarray], E: np.ndarray, valid: np.ndarray, settings):
    """Per page: the texels `covers` selects, in row-major order, take the next rows of E and valid;
    then invalid and empty texels are filled (dilation) and the page denoised."""
    irradiance, baked = [], []
    offset = 0
    for page, cover in zip(pages, covers):
        count = int(cover.sum())
        image = np.zeros(page.object.shape + (3,), np.float32)
        mask = np.zeros(page.object.shape, bool)
        image[cover] = E[offset:offset + count]
        mask[cover] = valid[offset:offset + count]
        offset += count
        irradiance.append(_fill(image, mask, settings, page.object))
        baked.append(mask)
    return irradiance, baked


def texel_warnings(result: LightmapPages, scene: Scene) -> list[str]:
    """The bake's warnings about its texels: a large share inside geometry, or unlit."""
    names = [o.name for o in scene.objects]
    out = []
    surface = result.texels - result.back_texels
    for count, of, by_object, limit, what in (
            (result.invalid, result.texels, result.invalid_by_object, INVALID_WARN_SHARE,
             "are inside geometry (invalid: their rays hit the back of single-sided surfaces)"),
            (result.unlit, surface, result.unlit_by_object, UNLIT_WARN_SHARE,
             "are unlit (no light reaches them on any side)")):
        if not of or count <= limit * of or by_object is None:
            continue
        worst = [k for k in np.argsort(-by_object, kind="stable")[:WARN_OBJECTS] if by_object[k]]
        more = ", ..." if np.count_nonzero(by_object) > len(worst) else ""
        if worst and by_object[worst[0]] < 0.01 * count:  # spread thin: no object holds 1 % of them
            where = (f"spread over {np.count_nonzero(by_object)} objects, at most {by_object[worst[0]]} in one: "
                     + ", ".join(f"'{names[k]}'" for k in worst) + more)
        else:
            parts = [f"'{names[k]}' ({100 * by_object[k] / count:.0f} %{' of them' if i == 0 else ''})"
                     for i, k in enumerate(worst)]
            where = f"most in {', '.join(parts)}{more}"
        out.append(f"{100 * count / of:.0f} % of light-map texels ({count} of {of}) {what} — {where}")
    return out


def warn_texels(result: LightmapPages, scene: Scene) -> None:
    for message in texel_warnings(result, scene) + [exposure_warning(result.median_radiance)]:
        if message:
            warn(message)


def _cut_out(scene: Scene, page: TexelPage) -> np.ndarray:
    out = np.zeros(page.object.shape, bool)
    if page.texcoord is None or not any(m.alpha_mode == "MASK" for m in scene.materials):
        return out
    where = np.nonzero(page.object >= 0)
    out[where] = cut_out_texels(scene, page.object[where], page.texcoord[where].astype(np.float64))
    return out


def _fill(image: np.ndarray, valid: np.ndarray, settings, labels: np.ndarray | None = None) -> np.ndarray:
    """Dilate into invalid and empty texels (an invalid texel from its own object's, `labels`:
    bake/dilate.py), then denoise, then restore what dilation owns.

    Dilating first gives the denoiser no black chart borders to bleed in.
    """
    grow = settings.padding + 2
    image = dilate(image, valid, grow, labels)
    if settings.denoise and valid.any():
        image = dilate(np.where(valid[..., None], denoise_lightmap(image), 0.0), valid, grow, labels)
    return np.ascontiguousarray(image, dtype=np.float32)
