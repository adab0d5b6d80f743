"""The background re-bake of the light maps after a material edit (`glint view`).

The light maps store irradiance E (Eq. 4.1: diffuse radiance = kd / pi x E), so a surface's own
kd shows at once without them; but every surface's kd, emission and lobes change the light that
reaches all the others (the bake's paths scatter by the whole BSDF, bake/irradiance.py). A
`Rebaker` re-bakes the light maps of an existing bake directory for edited materials in ONE
background worker process (parallel/background.py: spawned, not forked, since the viewer's process
holds an OpenGL context and threads; an edit is a request, a newer one makes the running pass stale),
so the viewer keeps its frame rate while the bake's own integrator runs:

- The worker loads the scene once (or is handed one), reads the bake's atlas and meshes
  (`pipeline.read_atlas`: no re-unwrap) and rasterises the texels once, then waits for edits.
- An edit is the list of the manifest's material entries (`Bake.model.materials` as JSON: name,
  kd, emission, lobes, ...) as the viewer's panel holds them. The entries that differ from the
  bake's are checked exactly as the sidecar's [materials] tables (bake/material_mapping.py
  `parse_material_override`, one-line GlintError naming the key) and applied as the loader applies
  a sidecar override (`apply_override`), only the keys that differ.
- Progressive passes (`pass_samples`): FIRST_SAMPLES paths per texel first, then PASS_GROWTH times
  more each pass, the last at the bake's own sample count. Each pass is a complete bake of the
  light maps (`bake_lightmaps`: the same texel order, seeds, dilation and denoiser as `glint bake`)
  at that sample count, delivered as whole front and back pages, (H, W, 4) float32 as the bake
  directory stores them (RGB = E, A = 1 where path traced). Every pass uses the bake's own seed,
  so a pass is deterministic (the same edit gives the same bytes), and the last pass equals the
  light maps `glint bake --force` makes of the edited sidecar, bit for bit before the EXR's half-
  float rounding (tests/test_rebake.py). Passes are independent estimates, not accumulated: the
  price is the earlier passes' samples, 1/PASS_GROWTH + 1/PASS_GROWTH^2 + ... = 1/3 more work.
- A newer edit cancels the running pass (checked after every tile of bake/lightmap.py TILE
  texels) and restarts from the newest materials; `poll()` never returns pages of an older edit
  once a newer one was made.

- Cube maps follow (`probes`, given by the command layer: glint/cubemap_stage.py ProbeRefresher,
  which needs the viewer's renderer, so the bake never imports it): after the first and the last
  pass the worker renders the bake's probes again (the same plans, bake/cubemap.py
  `plan_cubemaps` of the unedited scene, checked against the manifest's hashes) from the edited
  materials and that pass's pages, and delivers each probe's faces as their MIP chain
  (`poll_probes`). The last pass's probes are what `glint bake --force` of the edited sidecar
  renders (tests/test_probe_refresh.py). Only the first and the last: each refresh renders every probe
  (the bake's whole cube-map stage), and a probe shows the light maps blurred, where the middle
  passes' lower noise does not show. A probe's size and its sharing stay the bake's (an edit that
  changes them, e.g. a rougher lobe, takes `glint bake`).

- The first pass shown (`poll()`; `Update.front` stays the raw pass): an 8-path pass is far
  noisier than the light maps it replaces (living room, draft: 5.7 % relative RMS error against
  the converged re-bake, where the light before a sofa edit is 0.7 % off). The worker also bakes
  the first pass of the state the window last showed converged (the bake's own while the user
  looks around before the first edit; later ones are kept, FIRST_PASSES), on the same paths (the
  bake's seed): the difference of the two is the edit's change with most of the noise cancelled.
  Smoothed within each object (`smoothed_difference`, SMOOTH_TEXELS) it is added to that state's
  converged pages (0.5 % there; docs/VIEWER.md). Later passes are shown as they come.
- Undo, redo and revert: a state whose re-bake finished in this run (its last pass, and its last
  pass's probes) is kept (`BakedState`, the newest CACHE_BYTES' worth), and so is the bake's own
  (its directory's pages, and its probes through `baked_probes` once a refresh replaced them): an
  edit that returns to one of them gets its pages and probes on the next poll(), and the worker
  only stops its running pass; nothing is re-baked.

The worker runs at a lower priority (os.nice NICE): on a machine without a GPU (llvmpipe) it
competes with the renderer for the same cores, and the frame rate matters more than the
re-bake's speed.
"""
from __future__ import annotations

import contextlib
import io
import json
import time
from collections import OrderedDict
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from glint.bake.cubemap import CubeMapPlan, ProbeRules, plan_cubemaps
from glint.bake.hashing import geometry_hash
from glint.bake.lightmap import bake_lightmaps
from glint.bake.material_mapping import OVERRIDE_KEYS, apply_override, override_table, parse_material_override
from glint.bake.pipeline import read_atlas
from glint.bake.settings import BakeSettings
from glint.bake.texels import rasterize_texels
from glint.core.bake_dir import Bake, read_model
from glint.core.errors import GlintError
from glint.core.manifest import Manifest
from glint.core.scene import Scene
from glint.parallel.background import BackgroundWorker, Inbox

FIRST_SAMPLES = 8  # paths per texel of the first pass: seconds on the living room (docs/VIEWER.md)
PASS_GROWTH = 4  # samples of a pass over the one before: each pass halves the noise
NICE = 10  # the worker's niceness: the viewer's frames come first
STOP_SECONDS = 5.0  # close(): how long the worker may take to stop before it is terminated
CACHE_BYTES = 512 * 2**20  # the re-baked states kept for undo / redo / revert: the newest, as many as fit
SMOOTH_TEXELS = 3.0  # the first pass's change is smoothed with a Gaussian of this sigma, within each object
FIRST_PASSES = 4  # first passes the worker keeps per state, to difference the next edits' against


def pass_samples(samples: int) -> list[int]:
    """Paths per texel of each pass, the last `samples` (the bake's): e.g. 128 -> [8, 32, 128]."""
    out = [max(int(samples), 1)]
    while out[0] > FIRST_SAMPLES:
        out.insert(0, max(FIRST_SAMPLES, out[0] // PASS_GROWTH))
    return out


def bake_settings(manifest: Manifest) -> BakeSettings:
    """The settings the bake directory was made with (its manifest's `settings`), in one process."""
    names = {f.name for f in fields(BakeSettings)}
    return replace(BakeSettings(), **{k: v for k, v in manifest.settings.items() if k in names}, jobs=1)


def material_overrides(materials: list[dict], baked: list[dict]) -> dict[int, dict]:
    """Material index -> parsed override (bake/material_mapping.py) for every entry of `materials`
    whose kd, emission or lobes differ from the bake's entry `baked`; only the keys that differ.
    Checked as the sidecar is: a GlintError names the material and key."""
    if len(materials) != len(baked):
        raise GlintError(f"edited materials: {len(materials)} entries for the bake's {len(baked)}")
    out = {}
    for i, (entry, old) in enumerate(zip(materials, baked)):
        if not isinstance(entry, dict) or entry.get("name", old["name"]) != old["name"]:
            raise GlintError(f"edited materials: entry {i} is not material '{old['name']}'")
        new, before = override_table(entry), override_table(old)
        changed = [k for k in OVERRIDE_KEYS if k in new and new[k] != before.get(k)]
        if changed:
            warnings: list[str] = []  # unknown keys: the panel's, not the user's; nothing to warn of
            out[i] = parse_material_override({k: new[k] for k in changed}, f"material '{old['name']}'", warnings)
    return out


def edited_scene(scene: Scene, overrides: dict[int, dict]) -> Scene:
    """A copy of `scene` whose materials `overrides` names are changed as a sidecar override
    changes them (the loader's `apply_override`); `scene` itself is left as it was."""
    materials = list(scene.materials)
    for i, override in overrides.items():
        materials[i] = apply_override(replace(materials[i]), override)
    return replace(scene, materials=materials)


@dataclass
class Update:
    """One delivered pass: whole light-map pages and where the re-bake stands."""

    front: list[np.ndarray]  # (H, W, 4) float32 per page, as the bake directory's lightmaps/page_<k>.exr
    back: list[np.ndarray]  # the back sides' pages (lightmaps/back_<k>.exr); empty without two-sided objects
    generation: int  # which edit (1 for the first edit of this Rebaker)
    index: int  # pass, from 0
    passes: int
    samples: int  # paths per texel of this pass
    seconds: float  # since the edit was made
    # the first pass's change against the first pass of the state the window last showed converged
    # (`base`): smoothed (front, back) RGB differences, added to that state's pages (module docstring)
    difference: tuple[list[np.ndarray], list[np.ndarray]] | None = None
    base: str | None = None  # state_key of that state

    @property
    def final(self) -> bool:
        return self.index == self.passes - 1


@dataclass
class ProbeUpdate:
    """One re-rendered cube-map probe (after pass `index` of edit `generation`)."""

    file: str  # the bake's file of the probe (manifest objects' `cubemap.file`): which probe
    chain: list[np.ndarray]  # its faces' MIP chain, (6, S, S, 4) first, half float where it fits (mip_chain)
    generation: int
    index: int
    seconds: float  # since the edit was made


@dataclass
class BakedState:
    """A set of materials whose re-bake finished in this run (or the bake's own): its last pass's
    pages and probes, shown again at once when an undo, redo or revert returns to it."""

    update: Update  # the last pass
    probes: dict[str, list[np.ndarray]]  # {probe file: MIP chain} of the last pass (empty: none re-rendered)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in [*self.update.front, *self.update.back, *(c for cs in self.probes.values() for c in cs)])


def state_key(materials: list[dict]) -> str:
    """The cache's key of a list of material entries: equal entries, equal keys."""
    return json.dumps(materials, sort_keys=True, separators=(",", ":"))


class _Cancelled(Exception):
    pass


def bake_probes(scene: Scene, manifest: Manifest, settings: BakeSettings) -> list[CubeMapPlan]:
    """The probes of the bake directory whose `manifest` was baked from `scene` with `settings`:
    bake/cubemap.py plans them again (the scene as baked, not as edited), and only the plans whose
    hash is the manifest's (its stages.cubemaps) are kept."""
    hashes = manifest.stages.get("cubemaps", {})
    plans = plan_cubemaps(scene, manifest.stages["lightmaps"], ProbeRules.of(settings)) if hashes else []
    return [plan for plan in plans if hashes.get(str(plan.index)) == plan.hash]


def smoothed_difference(new: list[np.ndarray], old: list[np.ndarray], objects: list[np.ndarray],
                        sigma: float = SMOOTH_TEXELS) -> list[np.ndarray]:
    """(H, W, 3) float32 per page: new - old (RGB of (H, W, 4) pages), smoothed by a Gaussian of
    `sigma` texels within each object's texels (normalised convolution: a chart never takes the
    change of the object beside it in the atlas); 0 where no object is."""
    from scipy import ndimage

    out = []
    for a, b, ids in zip(new, old, objects):
        diff = (a[..., :3] - b[..., :3]).astype(np.float32)
        smooth = np.zeros_like(diff)
        pad = int(np.ceil(3 * sigma))
        for obj in np.unique(ids[ids >= 0]):
            rows, cols = np.nonzero(ids == obj)
            y0, y1 = max(rows.min() - pad, 0), min(rows.max() + pad + 1, ids.shape[0])
            x0, x1 = max(cols.min() - pad, 0), min(cols.max() + pad + 1, ids.shape[1])
            mask = (ids[y0:y1, x0:x1] == obj).astype(np.float32)
            weight = ndimage.gaussian_filter(mask, sigma, mode="constant")
            for c in range(3):
                blurred = ndimage.gaussian_filter(diff[y0:y1, x0:x1, c] * mask, sigma, mode="constant")
                smooth[y0:y1, x0:x1, c] += np.where(mask > 0, blurred / np.maximum(weight, 1e-6), 0.0)
        out.append(smooth)
    return out


def _prepare(source, bake_dir: Path, edits=()):
    """In the worker: the scene (a path loaded with the run's `--set` edits), the bake's settings
    and manifest, and its texel pages."""
    with contextlib.redirect_stderr(io.StringIO()):  # the viewer's process printed the loader's warnings
        if isinstance(source, Scene):
            scene = source
        else:
            from glint.bake.gltf_loader import load_scene  # the worker's only use of the loader

            scene = load_scene(Path(source), list(edits))
    manifest = read_model(bake_dir)
    if manifest is None:
        raise GlintError(f"{bake_dir}: not a glint bake directory (or made by another version); run `glint bake`")
    settings = bake_settings(manifest)
    if geometry_hash(scene, settings) != manifest.stages.get("geometry"):
        raise GlintError(f"{bake_dir}: made from other geometry than {scene.name}; run `glint bake`")
    pages = rasterize_texels(scene.objects, read_atlas(bake_dir, len(scene.objects)))
    return scene, settings, manifest, pages


def _worker(inbox: Inbox, source, bake_dir: Path, schedule: list[int] | None, edits=(), probes=None,
            baked_key: str | None = None) -> None:
    """The worker process (parallel/background.py): prepare once, then one progressive re-bake per
    edit (module docstring)."""
    try:
        start = time.perf_counter()
        scene, settings, manifest, pages = _prepare(source, Path(bake_dir), edits)
        schedule = schedule or pass_samples(settings.samples)
        plans = bake_probes(scene, manifest, settings) if probes is not None else []
        inbox.send(("ready", 0, {"seconds": time.perf_counter() - start, "schedule": schedule,
                                 "texels": int(sum((p.object >= 0).sum() for p in pages)), "probes": len(plans)}))
    except Exception as e:  # noqa: BLE001 -- reported to the viewer as one line, never a traceback
        inbox.send(("error", 0, _one_line(e)))
        return
    refresher = None  # made at the first edit's probes: a GL context, the diffuse view
    first_passes: OrderedDict[str, tuple[list, list]] = OrderedDict()  # state key -> its first pass's pages
    objects = [page.object for page in pages]

    def first_pass(key: str, overrides: dict, check) -> tuple[list, list]:
        if key not in first_passes:
            first_passes[key] = bake_lightmaps(edited_scene(scene, overrides), pages,
                                               replace(settings, samples=schedule[0]), progress=check).rgba()
            while len(first_passes) > FIRST_PASSES:
                first_passes.popitem(last=False)
        first_passes.move_to_end(key)
        return first_passes[key]

    if baked_key is not None and len(schedule) > 1:
        def before_any_edit(_texels=0):
            if inbox.stale(0):  # an edit came: it goes first (the bake's first pass is made with it)
                raise _Cancelled

        with contextlib.suppress(_Cancelled):  # while the user looks around, before the first edit
            first_pass(baked_key, {}, before_any_edit)
    while (request := inbox.next()) is not None:
        generation, payload = request
        if payload is None:  # a state the viewer keeps (undo, redo, revert): the request only stopped the pass
            continue
        overrides, materials, made, key, base = payload

        def check(_texels=0, generation=generation):
            if inbox.stale(generation):
                raise _Cancelled

        try:
            edited = edited_scene(scene, overrides)
            for k, samples in enumerate(schedule):
                if k == 0 and len(schedule) > 1:
                    front, back = first_pass(key, overrides, check)
                else:
                    front, back = bake_lightmaps(edited, pages, replace(settings, samples=samples),
                                                 progress=check).rgba()
                difference = None
                if k == 0 and len(schedule) > 1 and base is not None:
                    # the same paths (the bake's seed) through the materials before: their difference
                    # is the edit's change with most of the pass's noise cancelled
                    base_front, base_back = first_pass(base[0], base[1], check)
                    difference = (smoothed_difference(front, base_front, objects),
                                  smoothed_difference(back, base_back, objects))
                inbox.send(("pass", generation, Update(front, back, generation, k, len(schedule), samples,
                                                       time.time() - made, difference,
                                                       None if base is None else base[0])))
                check()
                if plans and refresher is not False and k in (0, len(schedule) - 1):
                    refresher = _refresh_probes(probes, refresher, bake_dir, plans, materials, front, back,
                                                inbox, generation, k, made, check)
        except _Cancelled:
            inbox.send(("cancelled", generation, None))
        except Exception as e:  # noqa: BLE001
            inbox.send(("error", generation, _one_line(e)))
    if refresher:
        refresher.release()


def _refresh_probes(factory, refresher, bake_dir, plans, materials, front, back, inbox: Inbox, generation: int,
                    index: int, made: float, check):
    """Render `plans` again for pass `index` (module docstring) and deliver each probe; returns the
    refresher to keep, or False when it failed (reported once; the light maps go on without it)."""
    def deliver(plan, chain):
        inbox.send(("probe", generation, ProbeUpdate(plan.file, chain, generation, index, time.time() - made)))

    try:
        refresher = refresher or factory(Path(bake_dir))
        refresher.render(plans, materials, front, back, deliver, check)
    except _Cancelled:
        raise
    except Exception as e:  # noqa: BLE001 -- e.g. no EGL: the cube maps keep the bake's light
        inbox.send(("probe-error", generation, _one_line(e)))
        return False
    inbox.send(("probes", generation, (index, time.time() - made)))
    return refresher


def _one_line(e: Exception) -> str:
    text = " ".join(str(e).split())
    return text if isinstance(e, GlintError) else f"{type(e).__name__}: {text}"


class Rebaker:
    """Re-bakes the light maps of `bake_dir` in a worker process whenever `edit` is called.

        rebaker = Rebaker(scene_path, bake_dir)   # or a Scene as the bake loaded it
        rebaker.edit(materials)                   # manifest material entries, some changed
        update = rebaker.poll()                   # each frame: None, or the newest pass's pages
        rebaker.close()

    `schedule`: paths per texel of each pass (default `pass_samples` of the bake's samples);
    `nice`: the worker's niceness (default NICE; 0: as urgent as the viewer); `edits`: the run's
    `--set` assignments (bake/edits.py), applied when the worker loads a scene path, so that a
    re-bake keeps what the command line changed besides the materials (a sky, the lights);
    `probes`: a picklable factory, probes(bake_dir) -> an object with `render(plans, materials,
    front, back, deliver, check)` and `release()` (glint/cubemap_stage.py ProbeRefresher), for
    cube maps that follow the edits (module docstring; `poll_probes`); None: they keep the bake's;
    `baked_probes(bake_dir)` -> {probe file: MIP chain} of the bake directory's own probes, for a
    return to the bake's materials after a refresh (glint/cubemap_stage.py `baked_probe_chains`).
    """

    def __init__(self, scene: Scene | str | Path, bake_dir: Path, *, schedule: list[int] | None = None,
                 nice: int = NICE, edits=(), probes=None, baked_probes=None):
        self.bake_dir = Path(bake_dir)
        manifest = read_model(self.bake_dir)
        if manifest is None:
            raise GlintError(f"{self.bake_dir}: not a glint bake directory (or made by another version); "
                             "run `glint bake`")
        self.baked = [m.to_json() for m in manifest.materials]  # as the edits come: material entries (JSON)
        self.schedule = list(schedule or pass_samples(bake_settings(manifest).samples))
        self._worker = BackgroundWorker(_worker, (scene, self.bake_dir, self.schedule, tuple(edits), probes,
                                                  state_key(self.baked)),
                                        name="glint-rebake", nice=nice, stop_seconds=STOP_SECONDS)
        self.generation = 0
        self.ready: dict | None = None  # the worker's set-up: seconds, schedule, texels, probes
        self.last: Update | None = None  # the newest pass delivered for the newest edit
        self.error: str | None = None
        self.probe_error: str | None = None  # why the cube maps do not follow (the light maps still do)
        self.probes_done: tuple[int, float] | None = None  # (pass, seconds) of the newest edit's last refresh
        self.probes_in = 0  # probes delivered for the newest edit's newest refreshed pass
        self.cancelled = 0  # passes abandoned for a newer edit
        self.dropped = 0  # passes of older edits that arrived after a newer edit (never returned)
        self._edited_at = 0.0
        self._pages: Update | None = None  # the newest pass not yet taken by poll()
        self._probes: dict[str, ProbeUpdate] = {}  # probes not yet taken by poll_probes()
        self._probe_pass = -1
        # States already re-baked in this run (module docstring, "Undo"), the newest last; the
        # bake's own state is read from its directory when first returned to (`baked_probes`).
        self._cache: OrderedDict[str, BakedState] = OrderedDict()
        self._baked_key = state_key(self.baked)
        self._baked_probes = baked_probes
        self._key: str | None = None  # the newest edit's state
        self._final_probes: dict[str, list[np.ndarray]] = {}  # the newest edit's last pass's probes
        self._probes_replaced = False  # whether any probe was re-rendered in this run
        self.from_cache = False  # the newest edit's pages came from the cache
        self._base = self._baked_key  # the state whose last pass the window shows (or last showed) converged
        self._overrides: dict[str, dict] = {self._baked_key: {}}  # state key -> its overrides
        self.cache_hits = 0

    # -- the viewer's side -------------------------------------------------------------------------
    def edit(self, materials: list[dict]) -> None:
        """Re-bake for these material entries (the whole list, in the manifest's order); cancels the
        re-bake of an earlier edit. A GlintError (naming the material and key) for a bad value."""
        overrides = material_overrides(materials, self.baked)
        self._edited_at = time.time()
        self.last, self.error, self._pages = None, None, None
        self.probes_done, self.probes_in, self._probes, self._probe_pass = None, 0, {}, -1
        self._key, self._final_probes = state_key(materials), {}
        cached = self._cached(self._key)
        self.from_cache = cached is not None
        if cached is None:
            self._overrides[self._key] = overrides
            base = (self._base, self._overrides[self._base]) if self._base in self._overrides else None
            self.generation = self._worker.request((overrides, [dict(m) for m in materials], self._edited_at,
                                                    self._key, base))
            return
        # A state re-baked before: its pages and probes at once; the request only stops a running pass.
        self.generation = self._worker.request(None)
        self.cache_hits += 1
        self._pages = self.last = replace(cached.update, generation=self.generation, seconds=0.0,
                                          difference=None, base=None)
        self._base = self._key
        self._probes = {file: ProbeUpdate(file, chain, self.generation, self.last.index, 0.0)
                        for file, chain in cached.probes.items()}
        self._probe_pass, self.probes_in = self.last.index, len(self._probes)
        self.probes_done = (self.last.index, 0.0)

    def _cached(self, key: str) -> BakedState | None:
        """The state `key` if it was re-baked in this run, or the bake's own (read from its directory)."""
        if key in self._cache:
            self._cache.move_to_end(key)
            state = self._cache[key]
            if key == self._baked_key and not state.probes and self._probes_replaced and self._baked_probes:
                # kept before any refresh (as the first pass's base): the bake's probes are needed now
                state.probes = self._baked_probes(self.bake_dir)
            return state
        if key != self._baked_key:
            return None
        bake = Bake(self.bake_dir)  # its pages as the viewer loaded them
        front = [bake.lightmap(k) for k in range(len(bake.model.lightmaps))]
        back = [bake.lightmap(k, back=True) for k in range(len(bake.back_pages))]
        n = len(self.schedule)
        # the bake's cube maps only where a refresh replaced them (and a reader was given)
        probes = self._baked_probes(self.bake_dir) if self._probes_replaced and self._baked_probes else {}
        state = BakedState(Update(front, back, 0, n - 1, n, self.schedule[-1], 0.0), probes)
        self._keep(key, state)
        return state

    def _shown(self, update: Update) -> Update:
        """What the window shows of a pass: the last pass as it is; the first pass, where the
        worker sent its change against the base state's first pass, as that change (smoothed)
        added to the base state's converged pages (module docstring); else the pass itself."""
        base = self._cache.get(update.base) if update.base is not None else None
        if base is None and update.base == self._baked_key:
            base = self._cached(self._baked_key)
        if update.final or update.difference is None or base is None:
            return update

        def add(pages, differences):
            return [np.concatenate([np.maximum(p[..., :3] + d, 0.0), p[..., 3:]], axis=-1).astype(np.float32)
                    for p, d in zip(pages, differences)]

        return replace(update, front=add(base.update.front, update.difference[0]),
                       back=add(base.update.back, update.difference[1]))

    def _keep(self, key: str, state: BakedState) -> None:
        self._cache[key] = state
        self._cache.move_to_end(key)
        while len(self._cache) > 1 and sum(s.nbytes for s in self._cache.values()) > CACHE_BYTES:
            self._cache.popitem(last=False)

    def poll(self) -> tuple[list[np.ndarray], list[np.ndarray]] | None:
        """Never blocks: None, or (front, back) pages of the newest pass of the newest edit that
        arrived since the last call (older edits' passes are dropped)."""
        self._drain()
        newest, self._pages = self._pages, None
        return None if newest is None else (newest.front, newest.back)

    def poll_probes(self) -> dict[str, list[np.ndarray]] | None:
        """Never blocks: None, or {probe file: its faces' MIP chain} of the probes of the newest
        edit re-rendered since the last call (CubeMaps.replace takes them)."""
        self._drain()
        probes, self._probes = self._probes, {}
        return {file: update.chain for file, update in probes.items()} or None

    def _drain(self) -> None:
        """Every message of the worker so far, sorted into what poll() and poll_probes() return."""
        for kind, generation, payload in self._worker.messages():
            if kind == "ready":
                self.ready = payload
            elif kind == "cancelled":
                self.cancelled += 1
            elif kind == "error" and generation in (0, self.generation):
                self.error = payload
            elif kind == "probe-error":
                self.probe_error = payload
            elif generation != self.generation:
                self.dropped += kind == "pass"
            elif kind == "pass":
                self.last = payload
                self._pages = self._shown(payload)
                if payload.final:
                    self._base = self._key
            elif kind == "probe":
                if payload.index != self._probe_pass:
                    self._probe_pass, self.probes_in = payload.index, 0
                self._probes[payload.file] = payload
                self.probes_in += 1
                self._probes_replaced = True
                if payload.index == len(self.schedule) - 1:
                    self._final_probes[payload.file] = payload.chain
            elif kind == "probes":
                self.probes_done = payload
        if self.done and not self.from_cache and self.error is None and self._key not in self._cache:
            self._keep(self._key, BakedState(self.last, dict(self._final_probes)))

    @property
    def done(self) -> bool:
        """The newest edit's last pass is in, and its probes (when the bake has any and they can be
        rendered) too."""
        if self.last is None or not self.last.final:
            return False
        return not self._probe_count or self.probe_error is not None or self._probes_final

    @property
    def _probe_count(self) -> int:
        """The bake's probes the worker re-renders (0 before it is ready, or without probes)."""
        return (self.ready or {}).get("probes", 0)

    @property
    def _probes_final(self) -> bool:
        """The newest edit's probes of its last pass are all in."""
        return self.probes_done is not None and self.probes_done[0] == len(self.schedule) - 1

    @property
    def status(self) -> str | None:
        """The overlay's line: where the re-bake stands (None before any edit)."""
        if self.error is not None:
            return f"re-bake failed: {self.error}"
        if self.generation == 0:
            return None
        if self.from_cache:
            return "light maps and cube maps as baked before for these materials (no re-bake)"
        n = len(self.schedule)
        if self.last is not None and self.last.final:
            line = f"light maps re-baked: {self.last.samples} paths/texel in {self.last.seconds:.1f} s"
            if self.probe_error is not None:
                return f"{line}; cube maps not re-rendered: {self.probe_error}"
            if self._probe_count and self._probes_final:
                return f"{line}, cube maps in {self.probes_done[1]:.1f} s"
            if self._probe_count:
                done = self.probes_in if self._probe_pass == n - 1 else 0
                return f"{line}; re-rendering cube maps: {done} of {self._probe_count}"
            return line
        done = 0 if self.last is None else self.last.index + 1
        return (f"re-baking light maps: pass {done + 1} of {n} ({self.schedule[done]} paths/texel), "
                f"{time.time() - self._edited_at:.1f} s")

    def wait(self, timeout: float = 600.0, poll_interval: float = 0.02) -> list[Update]:
        """Every pass delivered for the newest edit until its last (tests, bench); a GlintError on
        the worker's error or after `timeout` seconds."""
        out, deadline = [], time.monotonic() + timeout
        while not (out and out[-1].final):
            if self.poll() is not None:
                out.append(self.last)
            elif self.error is not None:
                raise GlintError(f"re-bake failed: {self.error}")
            elif time.monotonic() > deadline or not self._worker.alive():
                raise GlintError(f"re-bake: no final pass after {timeout:.0f} s")
            else:
                time.sleep(poll_interval)
        return out

    def close(self) -> None:
        """Stop the worker (at once if it is between passes; terminated after STOP_SECONDS)."""
        self._worker.close()

    def __enter__(self) -> "Rebaker":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
