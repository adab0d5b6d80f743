"""Light-map charts: every object of the scene unwrapped into one xatlas atlas.

Texel density is in texels per world metre: the objects go to xatlas scaled to
texel units (`PackOptions.texels_per_unit` = 1), so its absolute tolerances mean the
same at any scene scale (a 1 mm scene in metres lost whole objects). Charts are packed
with `padding` empty texels between them (plus xatlas's one-texel bilinear
border), on one page when they fit in `max_page_size` squared and on several
equal pages otherwise.

Coordinate convention (the one every stage and the viewer share): texel
(row y, column x) of a page image array `[H, W]` has its centre at
`uv = ((x + 0.5) / W, (y + 0.5) / H)`. There is no vertical flip: row 0 is
v = 0, which is the row OpenGL's `glTexImage2D` uploads first, so the arrays go
to the GPU as they are and a shader's `texture(lightmap, uv)` reads texel
(y, x) at that centre. This is also xatlas's own convention (its UVs are in
texels, texel x spanning [x, x + 1]).

Every xatlas option is set explicitly (nothing inherited from a library default
that could change between versions), and xatlas is deterministic for the same
input: the same objects and settings give byte-identical charts.
"""
from __future__ import annotations

import math
import multiprocessing as mp
import os
from dataclasses import dataclass

import numpy as np
import xatlas

from glint.core.errors import GlintError, WarningKind, warn
from glint.core.signals import deferred_signals, quiet_child

# More pages than this means the density is far too high for the scene: refuse
# rather than spend minutes packing and gigabytes baking.
MAX_PAGES = 16
# An object smaller than this many texels in total is unwrapped as if it were
# larger, so that it still gets a few texels per chart (a 1 cm knob at 16
# texels/m would otherwise get a fraction of one texel).
MIN_OBJECT_TEXELS = 64.0
# Fraction of a page xatlas fills, below what it fills in practice (docs/BAKE.md, "Light-map pages
# (xatlas)"); used only to refuse hopeless densities before running xatlas.
EXPECTED_UTILISATION = 0.7
# Per object, so summarised in one line (glint.core.errors.WarningKind).
LOW_DENSITY = WarningKind("{n} objects got fewer texels/m than asked for: one of their charts is larger "
                          "than a light-map page; raise max_page_size or lower texels_per_metre")


@dataclass
class ObjectCharts:
    """One object's light-map parametrisation (xatlas splits vertices on chart seams).

    Triangles xatlas could not chart (zero area; the loader drops those first)
    get uv (0, 0) on page 0 and no texels.
    """

    vmapping: np.ndarray  # (N',) int64: index of the object's original vertex for each new vertex
    indices: np.ndarray  # (M, 3) int64 into the new vertices (same triangle order as the object's indices)
    uv: np.ndarray  # (N', 2) float32 light-map coordinates in [0,1] of its page
    page: np.ndarray  # (N',) int32 atlas page of each vertex (all three vertices of a triangle share one)


@dataclass
class Atlas:
    objects: list[ObjectCharts]  # aligned with the input objects
    width: int  # every page has this size
    height: int
    pages: int
    texels_per_metre: float
    padding: int


def _chart_options():
    o = xatlas.ChartOptions()
    # xatlas 0.0.11 defaults, pinned.
    o.max_chart_area = 0.0  # no limit
    o.max_boundary_length = 0.0  # no limit
    o.normal_deviation_weight = 2.0
    o.roundness_weight = 0.01
    o.straightness_weight = 6.0
    o.normal_seam_weight = 4.0  # hard edges (split normals) become chart seams
    o.texture_seam_weight = 0.5
    o.max_cost = 2.0
    o.max_iterations = 1
    o.use_input_mesh_uvs = False
    o.fix_winding = False
    return o


def _pack_options(texels_per_unit: float, padding: int, page_size: int):
    o = xatlas.PackOptions()
    o.texels_per_unit = float(texels_per_unit)
    # A fixed page size lets xatlas open more pages when one is full; charts
    # are packed from the origin, so a single page is cropped afterwards.
    o.resolution = int(page_size)
    o.padding = int(padding)
    o.bilinear = True  # one more texel around each chart for bilinear look-ups
    o.blockAlign = False  # tighter packing; no block compression of light maps
    o.bruteForce = False  # xatlas's placement is seeded: still deterministic
    o.max_chart_size = 0  # charts larger than a page are scaled down by xatlas itself
    o.rotate_charts = True
    o.rotate_charts_to_axis = True
    o.create_image = False
    return o


def unwrap(objects, texels_per_metre: float, padding: int = 2, max_page_size: int = 2048) -> Atlas:
    """Charts for every object (list of `glint.core.scene.Object`) in one atlas of equal pages."""
    if not texels_per_metre > 0:
        raise GlintError(f"texels per metre must be positive (got {texels_per_metre})")
    if not objects:
        raise GlintError("nothing to unwrap: the scene has no triangle meshes")

    areas = np.array([o.area for o in objects], np.float64)
    texels = areas * texels_per_metre ** 2
    # Per-object up-scaling of tiny objects (density is then higher there).
    scale = np.sqrt(np.maximum(1.0, MIN_OBJECT_TEXELS / np.maximum(texels, 1e-30)))
    scale[texels <= 0] = 1.0
    needed = float((texels * scale ** 2).sum()) / EXPECTED_UTILISATION
    if needed > MAX_PAGES * max_page_size ** 2:
        raise GlintError(
            f"the light map would need about {needed / max_page_size ** 2:.0f} pages of "
            f"{max_page_size}x{max_page_size} texels at {texels_per_metre:g} texels/m "
            f"(scene surface {areas.sum():.1f} m^2, limit {MAX_PAGES} pages); "
            f"use a lower texels_per_metre (about {texels_per_metre * math.sqrt(MAX_PAGES * max_page_size ** 2 / needed):.1f})")

    # xatlas sees the objects in texel units (texels_per_unit = 1): its own area and length
    # tolerances are absolute, and dropped every triangle of a 1 mm sphere given in metres.
    meshes = [(np.ascontiguousarray(np.asarray(obj.positions, np.float64) * (s * texels_per_metre), np.float32),
               np.ascontiguousarray(obj.indices, np.uint32),
               np.ascontiguousarray(obj.normals, np.float32)) for obj, s in zip(objects, scale)]
    pages, page_w, page_h, raw = _isolated(_run_xatlas, meshes, 1.0, padding, max_page_size)
    if pages > MAX_PAGES:
        raise GlintError(f"the light map needs {pages} pages of {max_page_size}x{max_page_size} texels at "
                         f"{texels_per_metre:g} texels/m (limit {MAX_PAGES}); use a lower texels_per_metre")

    width, height = page_w, page_h
    if pages == 1:
        # xatlas packs from the origin: crop the page to what the charts use,
        # keeping the padding on the far sides, and round up to a multiple of 4
        # so RGB half-float rows stay 4-byte aligned for glTexImage2D.
        extent = np.max([r[2].max(axis=0) for r in raw if len(r[2])], axis=0)
        width = min(page_w, _round4(math.ceil(extent[0]) + padding + 1))
        height = min(page_h, _round4(math.ceil(extent[1]) + padding + 1))

    charts = []
    for (vmapping, indices, texel_uv, page), obj, s in zip(raw, objects, scale):
        uv = (texel_uv / (width, height)).astype(np.float32)
        charts.append(ObjectCharts(vmapping=vmapping, indices=indices, uv=uv, page=page))
        _check_density(obj, charts[-1], width, height, texels_per_metre * s)
    return Atlas(objects=charts, width=width, height=height, pages=pages,
                 texels_per_metre=float(texels_per_metre), padding=int(padding))


def _run_xatlas(meshes, texels_per_unit: float, padding: int, page_size: int):
    """xatlas itself: (pages, page width, page height, per mesh (vmapping, indices, texel uv, page))."""
    atlas = xatlas.Atlas()
    for positions, indices, normals in meshes:
        # Only the parametrisation sees the scaled copy; translation is irrelevant to it.
        atlas.add_mesh(positions, indices, normals)
    atlas.generate(_chart_options(), _pack_options(texels_per_unit, padding, page_size))
    pages, page_w, page_h = int(atlas.atlas_count), int(atlas.width), int(atlas.height)
    raw = []
    for i in range(len(meshes)):
        vmapping, indices, uv = atlas.get_mesh(i)
        page, _chart = atlas.get_mesh_vertex_assignment(i)
        page = page.astype(np.int64)
        uncharted = (page < 0) | (page >= pages)  # xatlas marks dropped triangles' vertices with ~0u
        page[uncharted] = 0
        texel_uv = uv.astype(np.float64) * (page_w, page_h)  # back to xatlas's texel units
        texel_uv[uncharted] = 0.0
        raw.append((vmapping.astype(np.int64), indices.astype(np.int64).reshape(-1, 3),
                    texel_uv, page.astype(np.int32)))
    return pages, page_w, page_h, raw


XATLAS_TRIES = 3


def _isolated(fn, *args):
    """Run `fn(*args)` in a forked child and return its result.

    xatlas 0.0.11's multithreaded charting crashes now and then (a segfault inside
    Atlas.generate that the same input does not repeat: docs/BAKE.md, "Light-map pages (xatlas)");
    in a child the crash costs a retry, not the whole process.
    The result is deterministic, so a retry gives the same charts.
    """

    ctx = mp.get_context("fork")
    for attempt in range(XATLAS_TRIES):
        receive, send = ctx.Pipe(duplex=False)
        child = ctx.Process(target=_child, args=(os.getpid(), send, fn, args), daemon=True)
        with deferred_signals():  # until the child's quiet_child, a signal is the parent's
            child.start()
        send.close()
        try:
            ok, value = receive.recv()
        except EOFError:  # the child died without answering
            ok, value = None, None
        except BaseException:  # Ctrl-C, SIGTERM: the child stops too
            child.terminate()
            raise
        finally:
            receive.close()
            child.join()
        if ok:
            return value
        if ok is False:
            raise value
    raise GlintError(f"the light-map unwrap (xatlas) crashed {XATLAS_TRIES} times "
                     f"(last exit code {child.exitcode}); run the bake again")


def _child(parent: int, send, fn, args) -> None:
    quiet_child(parent)
    try:
        send.send((True, fn(*args)))
    except BaseException as e:  # report it to the parent, which raises it
        send.send((False, e))
    finally:
        send.close()


def _round4(n: int) -> int:
    return (n + 3) // 4 * 4


def achieved_density(obj, charts: ObjectCharts, width: int, height: int) -> float:
    """Texels per metre the object actually got: sqrt(texel area / world area)."""
    uv = charts.uv.astype(np.float64) * (width, height)
    t = uv[charts.indices]
    texel_area = 0.5 * np.abs(_cross2(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])).sum()
    return math.sqrt(texel_area / obj.area) if obj.area > 0 else 0.0


def _check_density(obj, charts: ObjectCharts, width: int, height: int, wanted: float) -> None:
    # xatlas shrinks a chart that does not fit on a page: say so instead of
    # silently baking a blurry object.
    got = achieved_density(obj, charts, width, height)
    if obj.area > 0 and got < 0.75 * wanted:
        warn(f"object '{obj.name}' got only {got:.1f} texels/m of the {wanted:g} asked for: "
             f"one of its charts is larger than a light-map page; raise max_page_size or lower texels_per_metre",
             LOW_DENSITY, obj.name, detail=f"{got:.1f} texels/m")


def _cross2(u, v):
    return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
