"""The bake's one GPU stage: render the cube-map probes that glint.bake.cubemap planned.

Reads the bake directory written so far (manifest, meshes, light maps) and writes
`cubemaps/<i>.exr` per probe (format in bake/cubemap.py's docstring). It sits above
both the bake and the viewer because it needs the bake's plans and the viewer's renderer: the
bake's pipeline is handed `render_cubemaps` (glint.services.bake_scene does that), so the bake never
imports the renderer.

Batches: reading a frame back right after rendering it makes the CPU wait for the GPU, face after
face. Instead every face's radiance and depth are packed into one GPU buffer (`Texture.read_into`
a pixel-pack buffer, which queues the copy and returns), for all six faces of as many probes as
`BATCH_MIB` holds, and the buffer is read once per batch; radiance, distances and the files are
then made from it. The distance of a texel is viewer/camera.py `depth_distances` of the face's
depth, as the renderer's `read_distance`: the mean over the pixels of the texel
(bake/cubemap.py `supersample` per side) that hit something.

Processes: one GL context keeps about one core busy -- a software renderer (Mesa's llvmpipe)
processes vertices on the thread that issues the draw, and on a GPU the stage is the CPU's work
(each face's frame set up in Python, its depth turned into distances, the files compressed: issue
27's run gave 240 probes 21.7 s on an H200 with one context, where two cores of llvmpipe take 20-24 s
for the staircase's 290). So the probes are
shared out, PROBES_PER_TASK at a time, among `workers` processes (the bake's --jobs; GPU_PROCESSES at
most on a GPU), each with its
own EGL context and renderer (`ProbeWorker`, built once per process), started with spawn (a GL
context does not survive fork: parallel/executor.py LocalExecutor's start_method); each probe is
rendered alone, so the files are the same bytes whichever process renders it.

Local processes and a Dask cluster's workers are one code path (`_render_on_workers`): the executor's
`run` of `ProbeTask`s, each handled by `_probe_task` on the worker's state.

On a Dask cluster (`glint bake --scheduler`, parallel/executor.py DaskExecutor) the workers do not share
this machine's file system: the bake inputs the renderer reads (the bake directory written so far,
cube maps aside: manifest, meshes, light maps, textures) travel once to each worker as bytes
(`bake_inputs`), which unpacks them into a folder of its own and renders there as a local worker
process does (`ProbeWorker`, the same code), on a GL context of its own (EGL: a GPU driver, or Mesa's
llvmpipe); each task's files come back as bytes and this process puts them into the bake directory.
A probe is rendered alone, whichever task and worker it falls to, so the files are a local bake's bytes.
"""
from __future__ import annotations

import dataclasses
import math
import os
import shutil
import socket
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable

import numpy as np

from glint.bake.cubemap import (
    FACES,
    FAR_MARGIN,
    LOD_TRIANGLES_PER_PIXEL,
    NEAR_PER_FAR,
    SKY_DISTANCE,
    SMALL_OBJECT_TEXELS,
    SUPERSAMPLE,
    CubeMapPlan,
    supersample,
)
from glint.parallel.executor import TASKS_PER_WORKER, LocalExecutor
from glint.core.bake_dir import Bake
from glint.core.errors import GlintError
from glint.core.image_io import write_image
from glint.core.manifest import Manifest, Material
from glint.viewer.camera import ViewCamera, depth_distances
from glint.viewer.context import headless_context
from glint.viewer.cubemaps import finite_radiance, mip_chain, read_cubemap
from glint.viewer.gl import GL, describe, software_renderer
from glint.viewer.renderer import Renderer

BATCH_MIB = 64  # GPU pack buffer per batch: all six faces of at least one probe, however large
PROBES_PER_TASK = 8  # probes a worker process renders per task (several processes)
# Processes at most on a GPU: each holds the scene on the GPU (meshes, light maps, textures), and a
# workstation of 64 cores must not put 64 copies on a small card.
GPU_PROCESSES = 4


def diffuse_view(manifest: Manifest) -> Manifest:
    """The manifest as the cube-map renders see it: no lobes, no cube maps (bake/cubemap.py: the
    light-mapped scene, rendered diffuse)."""
    return dataclasses.replace(manifest, materials=[dataclasses.replace(m, lobes=[]) for m in manifest.materials],
                               objects=[dataclasses.replace(o, cubemap=None) for o in manifest.objects])


def face_bytes(size: int) -> tuple[int, int]:
    """Bytes of one face's resolved radiance (RGBA32F, size^2) and depth (float32, supersampled)."""
    return 16 * size ** 2, 4 * (supersample(size) * size) ** 2


def batches(plans: list[CubeMapPlan], limit: int = BATCH_MIB * 2 ** 20) -> list[list[CubeMapPlan]]:
    """Consecutive plans in groups whose six faces fit in `limit` bytes (a larger probe alone)."""
    out, current, used = [], [], 0
    for plan in plans:
        need = 6 * sum(face_bytes(plan.size))
        if current and used + need > limit:
            out.append(current)
            current, used = [], 0
        current.append(plan)
        used += need
    return out + [current] if current else out


def render_cubemaps(bake_dir: Path, plans: list[CubeMapPlan],
                    progress: Callable[[], None] | None = None, workers: int = 1, cluster=None) -> dict:
    """Render `plans` from the bake in `bake_dir` (manifest, meshes and light maps written) into
    its cubemaps/ folder, batch by batch; returns statistics (seconds, batches, processes, device).
    With `workers` > 1 the probes are shared out among that many processes (GPU_PROCESSES at most on
    a GPU), each with its own GL context (see the module docstring), PROBES_PER_TASK at least each.
    `cluster`: a Dask cluster's executor (parallel/executor.py DaskExecutor), whose workers render them
    instead (`workers` is then unused). Processes and a cluster's workers are the same code path: an
    executor's (`_render_on_workers`)."""
    t0 = time.perf_counter()
    if cluster is not None:
        return {**_render_on_workers(cluster, bake_dir, plans, progress), "seconds": round(time.perf_counter() - t0, 3),
                "batches": len(batches(plans))}
    ctx = headless_context()
    try:
        device = describe(ctx)
        groups = batches(plans)
        processes = probe_processes(int(workers), len(plans), software_renderer(ctx))
        if processes <= 1:
            _render_groups(ctx, bake_dir, groups, progress)
    finally:
        ctx.release()
    if processes > 1:
        with LocalExecutor(processes, start_method="spawn") as local:  # a GL context does not survive fork
            _render_on_workers(local, bake_dir, plans, progress)
    return {"seconds": round(time.perf_counter() - t0, 3), "batches": len(groups), "processes": max(processes, 1),
            "device": device}


def probe_processes(workers: int, probes: int, software: bool) -> int:
    """How many processes render `probes` probes: `workers` at most (the bake's --jobs), PROBES_PER_TASK
    probes each at least, GPU_PROCESSES at most on a GPU (not `software`); 1 or 0: this process."""
    return min(workers, probes // PROBES_PER_TASK, probes if software else GPU_PROCESSES)


def _diffuse_renderer(ctx, bake_dir) -> Renderer:
    """The renderer the probes are rendered with: the bake's diffuse view, untimed, small objects left
    out, the others at their level of detail."""
    bake = Bake(bake_dir)
    bake.model = diffuse_view(bake.model)
    return Renderer(ctx, bake, supersample=SUPERSAMPLE, timing=False, small_objects=SMALL_OBJECT_TEXELS, display=False,
                    lod=LOD_TRIANGLES_PER_PIXEL)


def _render_groups(ctx, bake_dir, groups: list[list[CubeMapPlan]], progress, renderer: Renderer | None = None,
                   deliver: Callable[[CubeMapPlan, np.ndarray], None] | None = None) -> None:
    """Render the probes of `groups`, each group read back at once, and write each one's file (or
    hand its (6, S, S, 4) faces to `deliver`)."""
    own = renderer is None
    renderer = _diffuse_renderer(ctx, bake_dir) if own else renderer
    try:
        lo, hi = renderer.scene.bounds
        gl = GL(ctx)
        with gl.checked("allocate the cube maps' read-back buffer"):
            pack = ctx.buffer(reserve=max(6 * sum(face_bytes(p.size)) for g in groups for p in g)) if groups else None
        for group in groups:
            need = sum(6 * sum(face_bytes(p.size)) for p in group)
            if need > pack.size:
                with gl.checked(f"grow the cube maps' read-back buffer to {need / 2 ** 20:.0f} MiB"):
                    pack.orphan(need)
            offset = 0
            for plan in group:
                renderer.supersample = supersample(plan.size)
                offset = queue_faces(renderer, pack, offset, plan.centre, plan.size, plan.hidden,
                                     far=farthest(lo, hi, plan.centre))
            data = pack.read(size=need)  # one wait for the whole batch
            offset = 0
            for plan in group:
                faces, offset = unpack_faces(data, offset, plan.size, far=farthest(lo, hi, plan.centre))
                if deliver is None:
                    write_cubemap(Path(bake_dir) / plan.file, faces)
                else:
                    deliver(plan, faces)
                if progress is not None:
                    progress()
        if pack is not None:
            pack.release()
    finally:
        if own:
            renderer.release()


def baked_probe_chains(bake_dir: Path) -> dict[str, list[np.ndarray]]:
    """The bake directory's own probes, {file: MIP chain} (half float where it fits), as a re-bake
    delivers them: what bake/rebake.py's Rebaker shows again when the materials return to the
    bake's after a refresh replaced its probes (glint/services.py `background_rebake` hands it)."""
    files = sorted({o.cubemap.file for o in Bake(bake_dir).model.objects if o.cubemap is not None})
    return {file: mip_chain(read_cubemap(Path(bake_dir) / file), half=True) for file in files}


class ProbeRefresher:
    """The probes of a bake rendered again for edited materials and re-baked light maps, in the
    re-bake's worker process (bake/rebake.py hands each pass's pages; glint/view.py gives the
    Rebaker this class, so the bake never imports the renderer):

        refresher = ProbeRefresher(bake_dir)          # a headless context, the diffuse view
        refresher.render(plans, materials, front, back, deliver, check)

    The diffuse view of the bake (as the cube-map stage renders it) with the edited material
    entries (their lobes left out, as `diffuse_view`) and the new light-map pages; each probe is
    rendered as the stage renders it (`_render_groups`) and `deliver(plan, chain)` gets its faces'
    MIP chain (viewer/cubemaps.py `mip_chain`, half float where it fits: computed and converted
    here, not on the viewer's thread).
    `check()` is called before each batch (the re-bake's cancel: it raises)."""

    def __init__(self, bake_dir: Path):
        self.bake_dir = Path(bake_dir)
        self.ctx = headless_context()
        self.renderer = _diffuse_renderer(self.ctx, self.bake_dir)
        # what the renderer draws, as the material entries `render` is given (JSON: material editing's form)
        self.shown = [m.to_json() for m in diffuse_view(Bake(self.bake_dir).model).materials]

    def render(self, plans: list[CubeMapPlan], materials: list[dict], front: list, back: list,
               deliver: Callable[[CubeMapPlan, list[np.ndarray]], None], check: Callable[[], None]) -> None:
        for i, entry in enumerate(materials):
            diffuse = {**entry, "lobes": []}
            if diffuse != self.shown[i]:
                self.renderer.set_material(i, Material.from_json(diffuse))  # the renderer takes typed materials
                self.shown[i] = diffuse
        self.renderer.replace_lightmaps(front, back)
        for group in batches(plans):
            check()
            _render_groups(self.ctx, self.bake_dir, [group], None, self.renderer,
                           deliver=lambda plan, faces: deliver(plan, mip_chain(finite_radiance(faces), half=True)))

    def release(self) -> None:
        self.renderer.release()
        self.ctx.release()


@dataclasses.dataclass(frozen=True)
class ProbeTask:
    """One cube-map task: the probes a worker renders, each alone (so its file is the same bytes
    whichever task and worker it falls to)."""
    plans: tuple[CubeMapPlan, ...]


def probe_tasks(plans: list[CubeMapPlan], per_task: int = PROBES_PER_TASK) -> list[ProbeTask]:
    """The plans in tasks of `per_task` for worker processes: the largest faces first, so that the last
    tasks are short and the processes end together."""
    by_size = sorted(plans, key=lambda p: -p.size)
    return [ProbeTask(tuple(by_size[k:k + per_task])) for k in range(0, len(by_size), per_task)]


class ProbeWorker:
    """A worker process's GL context and the bake's diffuse renderer, made once: it renders a task's
    probes and writes their files into the bake directory it reads (the bake being written, for the
    local processes; a Dask worker's copy of its inputs, `ClusterProbeWorker`).
    llvmpipe rasterises on the drawing thread (LP_NUM_THREADS=0, unless the user set it): the
    processes already keep the cores busy, and its raster threads would only contend with them."""

    def __init__(self, bake_dir: str | Path):
        t0 = time.perf_counter()
        os.environ.setdefault("LP_NUM_THREADS", "0")  # read when the first context opens, just below
        self.bake_dir = Path(bake_dir)
        self.ctx = headless_context()
        self.device = describe(self.ctx)
        self.renderer = _diffuse_renderer(self.ctx, self.bake_dir)
        self.setup_seconds = time.perf_counter() - t0

    def render(self, plans: list[CubeMapPlan]) -> int:
        _render_groups(self.ctx, self.bake_dir, batches(plans), None, self.renderer)
        return len(plans)

    def render_task(self, task: ProbeTask) -> dict:
        """The task's probes written in place: no files to hand back (`ClusterProbeWorker.render_task`'s form)."""
        t0 = time.perf_counter()
        self.render(list(task.plans))
        return _task_result([], len(task.plans), self.device, t0, self.setup_seconds)

    def release(self) -> None:
        self.renderer.release()
        self.ctx.release()


def _task_result(files: list, probes: int, device: str, t0: float, setup_seconds: float) -> dict:
    """A task's result: its files as bytes {"files": [(path in the bake, bytes)]} (none where written in
    place), its probes, which process (host:pid) and device rendered them, in how many seconds, and the
    seconds the worker took to get ready."""
    return {"files": files, "probes": probes, "process": f"{socket.gethostname()}:{os.getpid()}", "device": device,
            "seconds": time.perf_counter() - t0, "setup_seconds": setup_seconds}


def _probe_task(worker: "ProbeWorker | ClusterProbeWorker", task: ProbeTask) -> dict:
    """One task on a worker, local process or Dask worker: `render_task`'s result."""
    return worker.render_task(task)


# -- on a Dask cluster --------------------------------------------------------------------------------
def bake_inputs(bake_dir: Path) -> dict[str, bytes]:
    """The files of the bake written so far that the probes' renderer reads, by path relative to the
    bake directory: all but the cube maps (the diffuse view draws none)."""
    bake_dir = Path(bake_dir)
    return {path.relative_to(bake_dir).as_posix(): path.read_bytes() for path in sorted(bake_dir.rglob("*"))
            if path.is_file() and path.relative_to(bake_dir).parts[0] != "cubemaps"}


class ClusterProbeWorker:
    """On a Dask worker: the bake inputs unpacked into a folder of its own, and a ProbeWorker over it on a
    thread of its own (a GL context is current on one thread; Dask may run tasks on any of its threads).
    `render` returns each probe's file as bytes, for the bake's own process to write."""

    def __init__(self, files: dict[str, bytes]):
        t0 = time.perf_counter()
        self.folder = Path(tempfile.mkdtemp(prefix="glint-probes-"))
        self.thread = ThreadPoolExecutor(1, thread_name_prefix="glint-gl")
        try:
            for name, data in files.items():
                (self.folder / name).parent.mkdir(parents=True, exist_ok=True)
                (self.folder / name).write_bytes(data)
            self.probes = self.thread.submit(ProbeWorker, self.folder).result()
            self.setup_seconds = time.perf_counter() - t0
        except GlintError as e:  # no EGL there: the message says what to install, and where
            self._remove()
            raise GlintError(f"on the Dask worker machine {socket.gethostname()}: {e}") from None
        except BaseException:
            self._remove()
            raise

    def render_task(self, task: ProbeTask) -> dict:
        """The task's result (`_task_result`), its probes' files as bytes."""
        t0 = time.perf_counter()
        self.thread.submit(self.probes.render, list(task.plans)).result()
        files = []
        for plan in task.plans:
            path = self.folder / plan.file
            files.append((plan.file, path.read_bytes()))
            path.unlink()
        return _task_result(files, len(task.plans), self.probes.device, t0, self.setup_seconds)

    def release(self) -> None:
        self.thread.submit(self.probes.release).result()
        self._remove()

    def _remove(self) -> None:
        self.thread.shutdown()
        shutil.rmtree(self.folder, ignore_errors=True)


def _render_on_workers(executor, bake_dir: Path, plans: list[CubeMapPlan], progress) -> dict:
    """The probes rendered by the executor's workers (parallel/executor.py), tasks of PROBES_PER_TASK: local
    processes (`ProbeWorker`, each writing its files into the bake), or a Dask cluster's workers
    (`ClusterProbeWorker` on their copy of the inputs, the files written here; tasks small enough that
    every worker thread gets several). On a cluster, statistics: the worker processes that rendered,
    their devices, the longest task and the longest a worker took to get ready (unpack the inputs, open
    its GL context, build the renderer)."""
    if executor.distributed:
        per_task = max(1, min(PROBES_PER_TASK, len(plans) // (TASKS_PER_WORKER * executor.workers())))
        setup, setup_args = ClusterProbeWorker, (bake_inputs(bake_dir),)
    else:
        per_task, setup, setup_args = PROBES_PER_TASK, ProbeWorker, (str(bake_dir),)
    processes, devices, longest, setup_max = set(), set(), 0.0, 0.0
    for _, task in executor.run(setup, setup_args, _probe_task, probe_tasks(plans, per_task)):
        processes.add(task["process"])
        devices.add(task["device"])
        longest, setup_max = max(longest, task["seconds"]), max(setup_max, task["setup_seconds"])
        for name, data in task["files"]:
            (Path(bake_dir) / name).parent.mkdir(parents=True, exist_ok=True)
            (Path(bake_dir) / name).write_bytes(data)
        for _ in range(task["probes"]):
            if progress is not None:
                progress()
    if not executor.distributed:
        return {}
    return {"processes": len(processes), "device": "; ".join(sorted(devices)), "cluster": executor.address,
            "task_seconds_max": round(longest, 3), "worker_setup_seconds_max": round(setup_max, 3)}


def farthest(lo, hi, centre) -> float:
    """Distance from `centre` to the farthest corner of the scene's box lo..hi (the faces' `far`)."""
    return max(float(np.linalg.norm(np.maximum(np.abs(lo - centre), np.abs(hi - centre)))), 1e-9)


def face_camera(centre, k: int, far: float) -> ViewCamera:
    """The 90-degree camera of face k (FACES) at `centre`, clip planes from `far` (bake/cubemap.py)."""
    _, forward, up = FACES[k]
    return ViewCamera(eye=centre, forward=forward, up=up, yfov=math.pi / 2,
                      znear=NEAR_PER_FAR * far, zfar=FAR_MARGIN * far)


def queue_faces(renderer, pack, offset: int, centre, size: int, hidden=(), *, far: float) -> int:
    """Render the six faces and queue their radiance and depth into the buffer `pack` from byte
    `offset` on (face by face: radiance, then depth, each bottom row first); returns the offset
    after them. Nothing is read back here."""
    colour, depth = face_bytes(size)
    for k in range(6):
        renderer.render(face_camera(centre, k, far), size, size, hidden_objects=hidden)
        linear, depth_texture = frame_textures(renderer)
        linear.read_into(pack, alignment=1, write_offset=offset)
        depth_texture.read_into(pack, alignment=1, write_offset=offset + colour)
        offset += colour + depth
    return offset


def frame_textures(renderer):
    """The renderer's last frame as textures: the resolved radiance (RGBA32F) and the G-buffer's
    depth (what `read_linear` and `read_distance` read)."""
    return renderer._linear, renderer.gbuffer.targets["depth"]


def unpack_faces(data: bytes, offset: int, size: int, *, far: float) -> tuple[np.ndarray, int]:
    """(6, S, S, 4) float32 radiance and distance of the six faces queued by `queue_faces` at
    `offset`, row 0 at t = 0 (GL order); and the offset after them."""
    colour, depth = face_bytes(size)
    faces = np.zeros((6, size, size, 4), np.float32)
    n = supersample(size) * size
    for k in range(6):
        faces[k, ..., :3] = np.frombuffer(data, np.float32, size * size * 4, offset).reshape(size, size, 4)[..., :3]
        d = np.frombuffer(data, np.float32, n * n, offset + colour).reshape(n, n)
        faces[k, ..., 3] = depth_distances(d, face_camera(np.zeros(3), k, far), 1.0, n // size, SKY_DISTANCE)
        offset += colour + depth
    return faces, offset


def write_cubemap(path: Path, faces: np.ndarray) -> str:
    """The six faces stacked vertically into one RGBA OpenEXR; returns "half" or "float"."""
    path.parent.mkdir(parents=True, exist_ok=True)
    size = faces.shape[1]
    return write_image(path, faces.reshape(6 * size, size, 4), channels=("R", "G", "B", "A"))
