"""`glint bake`: scene file -> bake directory, redoing only the stages whose inputs changed.

Stages and what invalidates them (bake/hashing.py):
    unwrap + texels   geometry, texel density, padding
    light maps        the above + transport (kd, lobes, emission, glass, lights, sky, samples)
    cube maps         one hash per probe: the light maps + its first object, face size, centre,
                      hidden objects (bake/cubemap.py; probe settings shape the plan, not a hash)
    manifest          everything else (roles, cameras, bounding planes): rewritten
"""
from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable
from urllib.parse import unquote

import numpy as np
from tqdm import tqdm

from glint.bake import hashing
from glint.bake.cubemap import CubeMapPlan, ProbeRules, budget_statistics, plan_cubemaps
from glint.parallel.executor import executor_for
from glint.bake.lightmap import bake_lightmaps, two_sided_objects, warn_texels
from glint.bake.settings import PROBE_SETTINGS, BakeSettings
from glint.bake.texels import rasterize_texels
from glint.bake.unwrap import Atlas, ObjectCharts, unwrap
from glint.bake.sidecar import parse_toml, read_sidecar_text, sidecar_path
from glint.core.bake_dir import FORMAT_VERSION, BakeDirWriter, load_meshes, read_model, save_meshes, write_json
from glint.core.errors import GlintError
from glint.core.geometry import plane_of
from glint.core.image_io import write_image
from glint.core.manifest import (Atlas as AtlasEntry, Camera, CameraPath, CubeMapEntry, DirectionalLight, Lights,
                                 Manifest, Material, ObjectEntry, Plane, PointLight, Sampler, SceneInfo, Sky,
                                 SpotLight, Statistics, Volume, lobe_from_json)
from glint.core.scene import Scene
from glint.core.skipped import bake_record, missing_reason, stale_reason


@dataclass
class BakeReport:
    bake_dir: Path
    status: str  # "up-to-date" | "manifest" | "cubemaps" | "lightmaps" | "full"
    model: Manifest
    redone: list[str] = field(default_factory=list)

    @property
    def manifest(self) -> dict:
        """The manifest as written (JSON; for tests and the modules not yet reading `model`)."""
        return self.model.to_json()

    @property
    def summary(self) -> str:
        stats = self.model.statistics
        if self.status == "up-to-date":
            return f"{self.bake_dir}: up to date, nothing to do"
        if self.status == "manifest":
            return f"{self.bake_dir}: light maps up to date; manifest updated (materials, roles or cameras)"
        cm = stats.cubemaps
        cubes = (f"{cm['rendered']} of {cm['count']} cube maps in {cm['seconds']:.1f} s"
                 + (f" ({probe_line(cm)})" if "probes" in cm else "") if cm.get("rendered") else "")
        if self.status == "cubemaps":
            return f"{self.bake_dir}: light maps up to date; rendered {cubes}"
        lm = stats.lightmaps
        cluster = stats.cluster
        where = f" on the Dask cluster {cluster['scheduler']} ({cluster['workers']} workers)" if cluster else ""
        moved = (f" ({lm['moved_texels']} moved out of geometry, {lm['invalid_texels']} invalid"
                 + (f", {lm['refined_texels']} refined" if lm.get("refined_texels") else "")
                 + (f" ({lm['enclosed_texels']} in cavities)" if lm.get("enclosed_texels") else "") + ")"
                 if "moved_texels" in lm else "")
        return (f"{self.bake_dir}: baked {', '.join(self.redone)} — {lm['texels']} texels{moved}, "
                f"{lm['rays'] / 1e6:.1f} M rays in {lm['seconds']:.1f} s "
                f"({lm['rays_per_second'] / 1e6:.2f} M rays/s)" + (f"; {cubes}" if cubes else "") + where)


def probe_line(cm: dict) -> str:
    """"3 probes for 333 objects, 1.7 MiB, faces 32: 2, 64: 1" from the cube-map statistics."""
    sizes = ", ".join(f"{size}: {n}" for size, n in cm.get("face_sizes", {}).items())
    return f"{cm['probes']} probes for {cm['objects']} objects, {cm['mib']:.1f} MiB, faces {sizes}"


def source_hash(scene: Scene, *, edits: bool = True) -> str:
    """Hash of the scene's content, the one thing besides the settings and glint's stage versions that
    decides whether a bake is up to date (bake_scene): the glTF file's bytes and those of the files it
    names (buffers, images), the sidecar's content as TOML reads it (comments, layout and key order are
    not content; no sidecar is an empty one), the sky map's bytes and (unless `edits` is False) the
    `--set` edits. No path enters it: a bake moves between folders, installs and machines."""
    h = hashlib.sha256(b"glint-scene-content-2")
    for data in _scene_files(scene):
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    h.update(json.dumps(sidecar_content(scene), sort_keys=True).encode())
    if edits and scene.edits:  # only then: unedited scenes keep the hashes of existing bakes
        h.update(json.dumps(list(scene.edits)).encode())
    return h.hexdigest()[:32]


def _scene_files(scene: Scene):
    """The bytes of the glTF file, of the files its buffers and images name by relative URI, and of
    the sky map: everything on disk the scene's content comes from besides the sidecar."""
    if scene.source is None or not Path(scene.source).is_file():
        return
    path = Path(scene.source)
    data = path.read_bytes()
    yield data
    tree = None
    try:
        if data[:4] == b"glTF":
            length = int.from_bytes(data[12:16], "little")
            tree = json.loads(data[20:20 + length])
        else:
            tree = json.loads(data)
    except (ValueError, UnicodeDecodeError):
        tree = None
    for item in [*(tree or {}).get("buffers", []), *(tree or {}).get("images", [])] if isinstance(tree, dict) else []:
        uri = item.get("uri") if isinstance(item, dict) else None
        if isinstance(uri, str) and not uri.startswith("data:"):
            file = path.parent / unquote(uri)
            yield file.read_bytes() if file.is_file() else b""
    if scene.sky is not None and scene.sky.source and Path(scene.sky.source).is_file():
        yield Path(scene.sky.source).read_bytes()


def sidecar_content(scene: Scene) -> dict:
    """The sidecar's tables as TOML reads them ({} without one), JSON-ready: what the bake reads of it."""
    path = scene.sidecar if scene.sidecar is not None else (sidecar_path(scene.source) if scene.source else None)
    text = read_sidecar_text(Path(path)) if path is not None else None
    if text is None:
        return {}
    return json.loads(json.dumps(parse_toml(text, Path(path)), sort_keys=True, default=str))


def bake_inputs(scene: Scene) -> dict:
    """The manifest's `inputs`: glint's stage versions (bake/hashing.py), the sidecar's content and
    per-object content hashes. The versions decide, with the scene's hash and the settings, whether
    a bake is up to date; the rest only names what changed (core/skipped.py stale_reason)."""
    path = scene.sidecar if scene.sidecar is not None else (sidecar_path(scene.source) if scene.source else None)
    content = sidecar_content(scene)
    side = {"file": Path(path).name, "content": content} if path is not None and Path(path).is_file() else None
    return {"versions": hashing.stage_versions(), "sidecar": side,
            "objects": {obj.name: hashing.object_hashes(obj) for obj in scene.objects}}


def describe(scene: Scene, cubemaps: list[CubeMapPlan] = ()) -> dict:
    """The part of the manifest the viewer reads besides the light maps: the `Manifest` fields objects,
    materials, lights, sky, cameras and camera_paths (core/manifest.py)."""

    def vec(v):
        return [float(x) for x in np.asarray(v).ravel()]

    objects = []
    cubes = {k: CubeMapEntry.from_json(plan.manifest_entry()) for plan in cubemaps for k in plan.members}
    two = two_sided_objects(scene)
    for i, obj in enumerate(scene.objects):
        plane = Plane(*map(vec, plane_of(obj))) if obj.role == "planar" else None
        objects.append(ObjectEntry(name=obj.name, material=obj.material, role=obj.role,
                                   bounds=[vec(b) for b in obj.bounds], triangles=int(len(obj.indices)),
                                   lightmap_back=bool(two[i]), plane=plane, cubemap=cubes.get(i)))
    materials = [Material(name=m.name, kd=vec(m.kd), emission=vec(m.emission), double_sided=bool(m.double_sided),
                          lobes=[lobe_from_json(lobe.to_dict()) for lobe in m.lobes],
                          kd_texture=f"textures/material_{i}.exr" if m.kd_texture is not None else None,
                          **_emission_entry(m, i), **_metallic_roughness_entry(m, i), **_sampler_entry(m),
                          **_coverage_entry(m), **_volume_entry(m), **_surface_detail_entry(m, i), gltf=m.gltf)
                 for i, m in enumerate(scene.materials)]
    lights = Lights(
        point=[PointLight(l.name, vec(l.position), vec(l.intensity)) for l in scene.point_lights],
        spot=[SpotLight(l.name, vec(l.position), vec(l.direction), vec(l.intensity), float(l.inner_cone),
                        float(l.outer_cone)) for l in scene.spot_lights],
        directional=[DirectionalLight(l.name, vec(l.direction), vec(l.irradiance)) for l in scene.directional_lights],
    )
    sky = None
    if scene.sky is not None:
        sky = Sky(radiance=vec(scene.sky.radiance), map="sky.exr" if scene.sky.map is not None else None)
    cameras = [Camera(name=c.name, eye=vec(c.eye), forward=vec(c.forward), up=vec(c.up), yfov=float(c.yfov),
                      aspect=None if c.aspect is None else float(c.aspect), znear=float(c.znear), zfar=float(c.zfar))
               for c in scene.cameras]
    paths = [CameraPath.from_json({"name": p.name, "keys": p.keys}) for p in scene.camera_paths]
    return {"objects": objects, "materials": materials, "lights": lights, "sky": sky,
            "cameras": cameras, "camera_paths": paths}


def _probe_settings(settings: BakeSettings) -> dict:
    """The probe settings that differ from the defaults (so that a later command reusing this bake
    keeps them, glint.services), nothing otherwise: other bakes' manifests stay as they were."""
    default = BakeSettings()
    return {k: getattr(settings, k) for k in PROBE_SETTINGS if getattr(settings, k) != getattr(default, k)}


def _emission_entry(m, i: int) -> dict:
    """`emission_texture` (glTF emissiveTexture, linear) where the material has one; nothing
    otherwise, so other manifests stay as they were."""
    if m.emission_texture is None:
        return {}
    return {"emission_texture": f"textures/emission_{i}.exr"}


def _metallic_roughness_entry(m, i: int) -> dict:
    """`metallic_roughness_texture` (G roughness multiplier, B metallic M', linear) where the
    material has one; nothing otherwise, so other manifests stay as they were."""
    if m.metallic_roughness_texture is None:
        return {}
    return {"metallic_roughness_texture": f"textures/metallic_roughness_{i}.exr"}


def _surface_detail_entry(m, i: int) -> dict:
    """The normal map (`normal_texture`, `normal_scale`) and the anisotropy direction
    (`anisotropy_rotation`, `anisotropy_texture`) where a material has them; nothing otherwise,
    so other manifests stay as they were."""
    out = {}
    if m.normal_texture is not None:
        out.update(normal_texture=f"textures/normal_{i}.exr", normal_scale=float(m.normal_scale))
    if m.anisotropy_rotation:
        out["anisotropy_rotation"] = float(m.anisotropy_rotation)
    if m.anisotropy_texture is not None:
        out["anisotropy_texture"] = f"textures/anisotropy_{i}.exr"
    return out


def _sampler_entry(m) -> dict:
    """A textured material's glTF sampler as `kd_sampler` {wrap_s, wrap_t, mag_filter}, where it is
    not the default (REPEAT, LINEAR); nothing otherwise, so other manifests stay as they were."""
    if all(t is None for t in (m.kd_texture, m.emission_texture, m.metallic_roughness_texture,
                               m.normal_texture, m.anisotropy_texture)) or (
            tuple(m.kd_wrap) == ("REPEAT", "REPEAT") and not m.kd_nearest):
        return {}
    return {"kd_sampler": Sampler(wrap_s=m.kd_wrap[0], wrap_t=m.kd_wrap[1],
                                  mag_filter="NEAREST" if m.kd_nearest else "LINEAR")}


def _coverage_entry(m) -> dict:
    """A MASK or BLEND material's `alpha_mode`, `alpha_cutoff` and `alpha` (baseColorFactor[3]);
    nothing for opaque ones, whose manifest entries stay as they were (readers default to OPAQUE)."""
    if not m.has_coverage:
        return {}
    return {"alpha_mode": m.alpha_mode, "alpha_cutoff": float(m.alpha_cutoff), "alpha": float(m.alpha)}


def _volume_entry(m) -> dict:
    """A glass solid's `volume` {ior, thickness, absorption (sigma_a, 1/m)} (core/volume.py); nothing
    for other materials, whose manifest entries stay as they were (readers take them as thin)."""
    if not m.has_volume:
        return {}
    return {"volume": Volume(ior=float(m.ior), thickness=float(m.thickness),
                             absorption=[float(x) for x in m.absorption])}


# Renders cube-map plans into a bake directory written so far; returns statistics
# (glint/cubemap_stage.py render_cubemaps: it needs the viewer's renderer, so the bake is handed it).
CubeMapRenderer = Callable[..., dict]


def bake_scene(scene: Scene, settings: BakeSettings, bake_dir: Path, *, force: bool = False,
               progress: bool = True, render_cubemaps: CubeMapRenderer | None = None,
               worker_modules: tuple[str, ...] = (), announce: Callable[[str], None] | None = None,
               seed: Path | None = None) -> BakeReport:
    """Bake `scene` into `bake_dir`, redoing only the stages whose inputs changed.

    `seed`: a bake directory to start from when `bake_dir` holds none (an edited scene's bake
    starts from the unedited one, bake/edits.py): its unchanged stages are carried over, by hard
    link, as from a previous bake in `bake_dir`, and the seed itself is left as it was.

    `render_cubemaps` renders the cube maps that need rendering (glint.services.bake_scene passes
    glint.cubemap_stage.render_cubemaps); a scene that needs a new cube map without one is an error.
    `worker_modules`: the modules `render_cubemaps` runs on a `local:N` cluster's workers, which they
    import before its tasks arrive (named by the caller, which knows them: the bake names no module
    above it).
    `announce(why)` is called once, before any work, when an existing bake is to be redone in part
    (why: the changed inputs, as glint.core.skipped.stale_reason words them).
    """
    old = None if force else read_model(bake_dir)
    old_dir = bake_dir
    if old is None and not force and seed is not None:
        old, old_dir = read_model(seed), seed
    geometry = hashing.geometry_hash(scene, settings)
    transport = hashing.transport_hash(scene, settings, geometry)
    rules = ProbeRules.of(settings)
    cubemaps = plan_cubemaps(scene, transport, rules)
    manifest = Manifest(
        format="glint-bake", version=FORMAT_VERSION,
        scene=SceneInfo(name=scene.name, source=str(scene.source) if scene.source else None, hash=source_hash(scene)),
        settings={**settings.transport_dict(), "quality": settings.quality, **_probe_settings(settings)},
        stages={"geometry": geometry, "lightmaps": transport,
                "cubemaps": {str(plan.index): plan.hash for plan in cubemaps}},
        inputs=bake_inputs(scene),
        **describe(scene, cubemaps),
    )
    # Up to date: the same scene content, settings and stage versions, whatever the paths and the
    # machine (derived floats may differ there in the last bit: they decide nothing here).
    # A file of the old bake gone (deleted by hand) is made again, with what depends on it.
    missing = missing_files(old, old_dir) if old is not None else set()
    if old is not None and old_dir == bake_dir and same_inputs(old, manifest) and not missing:
        return BakeReport(bake_dir, "up-to-date", old)

    reuse_geometry = old is not None and old.stages.get("geometry") == geometry and "meshes.npz" not in missing
    reuse_lightmaps = (reuse_geometry and old.stages.get("lightmaps") == transport
                       and not missing.intersection(old.lightmaps + old.lightmaps_back))
    if reuse_lightmaps:
        manifest = replace(manifest, atlas=old.atlas, lightmaps=old.lightmaps, lightmaps_back=old.lightmaps_back,
                           statistics=Statistics(dict(old.statistics.data)))

    if old is not None and announce is not None:
        announce(missing_reason(missing) if missing and same_inputs(old, manifest) else stale_reason(old, manifest))
    executor = executor_for(settings)
    probes_to_render = _to_render(cubemaps, old, old_dir)
    if not reuse_lightmaps or probes_to_render:
        # a remote scheduler is reached now, before anything is written; a local:N cluster starts in
        # the background while the scene is unwrapped, its workers with the light maps' module imported,
        # and the cube maps' where there are cube maps to render
        cube_maps = tuple(worker_modules) if probes_to_render and render_cubemaps else ()
        executor.start(modules=(bake_lightmaps.__module__, *cube_maps))
    with executor, BakeDirWriter(bake_dir) as out:
        _write_textures(scene, out.path)
        if reuse_lightmaps:
            out.reuse(old_dir, "meshes.npz")
            for name in old.lightmaps + old.lightmaps_back:
                out.reuse(old_dir, name)
            status, redone = "manifest", []
        else:
            manifest = replace(manifest, **_bake_geometry_and_lightmaps(scene, settings, out.path, progress,
                                                                       old_dir if reuse_geometry else None, executor))
            status, redone = ("lightmaps", ["light maps"]) if reuse_geometry else ("full", ["unwrap", "light maps"])
        stats = manifest.statistics.data  # filled in below, in this order (the manifest's key order)
        stats["cubemaps"] = {**_cubemaps(cubemaps, old, old_dir, out, manifest, progress,
                                         settings.workers, render_cubemaps, executor),
                             **budget_statistics(cubemaps, rules)}
        if stats["cubemaps"]["rendered"]:
            status = "cubemaps" if status == "manifest" else status
            redone.append("cube maps")
        # Where the bake ran, when on a cluster: its workers and what starting and feeding them cost.
        stats.pop("cluster", None)
        if executor.distributed and executor.statistics["workers"]:  # connected: work was done there
            stats["cluster"] = dict(executor.statistics)
        # What the viewer will show wrong because the loader ignored it (glint.services.fidelity_line).
        stats["ignored_features"] = dict(scene.ignored_features)
        # What this bake redid and reused, for later commands that find it up to date (core/skipped.py).
        stats["last_bake"] = bake_record(status, old, manifest, stats["cubemaps"], forced=force,
                                         missing=tuple(missing))
        write_json(out.path / "manifest.json", manifest.to_json())
        out.commit()
    return BakeReport(bake_dir, status, manifest, redone)


def same_inputs(old: Manifest, new: Manifest) -> bool:
    """Whether the bake of manifest `old` is up to date for `new`: the same scene content (`scene.hash`,
    source_hash), settings and stage versions (`inputs.versions`). A manifest written before it
    recorded them (no `inputs`) is up to date when its stages and description equal `new`'s, as before."""
    if old.inputs is None:  # the stages (which decide atlas and light maps) and the description
        was, now = old.to_json(), json.loads(json.dumps(new.to_json()))
        return all(was.get(k) == v for k, v in now.items() if k not in ("scene", "inputs", "atlas", "lightmaps",
                                                                        "lightmaps_back", "statistics")) \
            and old.scene.name == new.scene.name
    return (old.scene.hash == new.scene.hash
            and old.settings == json.loads(json.dumps(new.settings))
            and (old.inputs or {}).get("versions") == new.inputs["versions"])


def missing_files(old: Manifest, old_dir: Path) -> set[str]:
    """The files the bake of manifest `old` holds (meshes, light maps, cube maps) that `old_dir` lacks."""
    names = ["meshes.npz", *old.lightmaps, *old.lightmaps_back]
    names += [entry.cubemap.file for entry in old.objects if entry.cubemap is not None]
    return {name for name in names if not (Path(old_dir) / name).is_file()}


def _to_render(plans: list[CubeMapPlan], old: Manifest | None, old_dir: Path) -> list[CubeMapPlan]:
    """The plans whose cube map the previous bake (`old`, its manifest, in `old_dir`) does not have."""
    old_hashes = old.stages.get("cubemaps", {}) if old is not None else {}
    return [plan for plan in plans
            if old_hashes.get(str(plan.index)) != plan.hash or not (Path(old_dir) / plan.file).is_file()]


def _cubemaps(plans: list[CubeMapPlan], old: Manifest | None, old_dir: Path, out: BakeDirWriter, manifest: Manifest,
              progress: bool, workers: int, render_cubemaps: CubeMapRenderer | None, executor) -> dict:
    """Carry over the cube maps whose inputs did not change, render the others (bake/cubemap.py) with
    `render_cubemaps`, on `workers` local processes or, when the bake's `executor` is a Dask cluster's,
    on its workers."""
    todo = _to_render(plans, old, old_dir)
    rendered = {plan.index for plan in todo}
    for plan in plans:
        if plan.index not in rendered:
            out.reuse(old_dir, plan.file)
    stats = {"count": len(plans), "rendered": len(todo), "reused": len(plans) - len(todo), "seconds": 0.0,
             "texels": int(sum(6 * p.size ** 2 for p in todo))}
    if todo:
        if render_cubemaps is None:
            raise GlintError(f"{len(todo)} cube map(s) to render but no cube-map renderer was given "
                             "(bake through glint.services.bake_scene)")
        write_json(out.path / "manifest.json", manifest.to_json())  # the renderer reads the bake written so far
        with tqdm(total=len(todo), desc="cube maps", unit="map", disable=not progress, leave=False) as bar:
            stats.update(render_cubemaps(out.path, todo, progress=bar.update, workers=workers,
                                         cluster=executor if executor.distributed else None))
        stats["seconds_per_cubemap"] = round(stats["seconds"] / len(todo), 3)
    return stats


def _write_textures(scene: Scene, path: Path) -> None:
    for i, m in enumerate(scene.materials):
        if m.kd_texture is not None and m.has_coverage and m.alpha_texture is not None:
            rgba = np.concatenate([m.kd_texture, m.alpha_texture[..., None]], axis=-1)
            write_image(path / "textures" / f"material_{i}.exr", rgba, channels=("R", "G", "B", "A"))
        elif m.kd_texture is not None:
            write_image(path / "textures" / f"material_{i}.exr", m.kd_texture)
        if m.emission_texture is not None:
            write_image(path / "textures" / f"emission_{i}.exr", m.emission_texture)
        for kind, texture in (("metallic_roughness", m.metallic_roughness_texture),
                              ("normal", m.normal_texture), ("anisotropy", m.anisotropy_texture)):
            if texture is not None:
                write_image(path / "textures" / f"{kind}_{i}.exr", texture)
    if scene.sky is not None and scene.sky.map is not None:
        write_image(path / "sky.exr", scene.sky.map, half=False)


def _bake_geometry_and_lightmaps(scene: Scene, settings: BakeSettings, path: Path, progress: bool,
                                 old_dir: Path | None, executor=None) -> dict:


    t0 = time.perf_counter()
    with tqdm(total=2, desc="unwrap", unit="step", disable=not progress, leave=False) as bar:
        atlas = _atlas(scene, settings, path, old_dir)
        bar.update()
        pages = rasterize_texels(scene.objects, atlas)
        bar.update()
    t1 = time.perf_counter()

    texels = int(sum((p.object >= 0).sum() for p in pages))
    with tqdm(total=texels, desc="light maps", unit="texel", disable=not progress, leave=False,
              smoothing=0.05) as bar:
        result = bake_lightmaps(scene, pages, settings, progress=bar.update, executor=executor)
    warn_texels(result, scene)
    names, back_names = [], []
    for images, stem, files in zip(result.rgba(), ("page", "back"), (names, back_names)):
        for k, rgba in enumerate(images):
            name = f"lightmaps/{stem}_{k}.exr"
            write_image(path / name, rgba, channels=("R", "G", "B", "A"))
            files.append(name)
    t2 = time.perf_counter()
    names_of = [o.name for o in scene.objects]

    def worst(counts) -> list:
        order = [k for k in np.argsort(-counts, kind="stable")[:5] if counts[k]]
        return [[names_of[k], int(counts[k])] for k in order]
    return {
        "atlas": AtlasEntry(width=atlas.width, height=atlas.height, pages=atlas.pages,
                            texels_per_metre=atlas.texels_per_metre, padding=atlas.padding),
        "lightmaps": names,
        "lightmaps_back": back_names,
        "statistics": Statistics({
            "unwrap": {"seconds": round(t1 - t0, 3), "reused": old_dir is not None,
                       "triangles": int(sum(len(o.indices) for o in scene.objects))},
            "lightmaps": {"seconds": round(t2 - t1, 3), "texels": result.texels, "back_texels": result.back_texels,
                          "invalid_texels": result.invalid, "moved_texels": result.moved,
                          "refined_texels": result.refined, "refined_paths": result.refined_paths,
                          "enclosed_texels": result.enclosed,
                          "unlit_texels": result.unlit,
                          "median_radiance": result.median_radiance,
                          "invalid_objects": worst(result.invalid_by_object),
                          "unlit_objects": worst(result.unlit_by_object),
                          "samples": settings.samples, "rays": int(result.rays),
                          "rays_per_second": float(result.rays / max(t2 - t1, 1e-9)),
                          "trace_seconds": round(result.trace_seconds, 3), "tiles": result.tiles,
                          "phase_seconds": result.phase_seconds or {}},
        }),
    }


def read_atlas(bake_dir: Path, count: int) -> Atlas:
    """The charts of an existing bake of `count` objects (its manifest's atlas and meshes.npz): what a
    bake whose geometry did not change reuses, and the background re-bake (bake/rebake.py) bakes into."""
    old = read_model(bake_dir).atlas
    meshes = load_meshes(Path(bake_dir) / "meshes.npz", count)
    charts = [ObjectCharts(vmapping=m["vmapping"].astype(np.int64), indices=m["indices"].astype(np.int64),
                           uv=m["lm_uv"], page=m["lm_page"]) for m in meshes]
    return Atlas(objects=charts, width=old.width, height=old.height, pages=old.pages,
                 texels_per_metre=old.texels_per_metre, padding=old.padding)


def _atlas(scene: Scene, settings: BakeSettings, path: Path, old_dir: Path | None):
    """Unwrap with xatlas, or, when the geometry did not change, read the charts of the last bake."""

    if old_dir is not None:
        atlas = read_atlas(old_dir, len(scene.objects))
    else:
        atlas = unwrap(scene.objects, settings.texels_per_metre, settings.padding, settings.max_page_size)
    meshes = []
    for obj, charts in zip(scene.objects, atlas.objects):
        v = charts.vmapping
        meshes.append({"positions": obj.positions[v].astype(np.float32), "normals": obj.normals[v].astype(np.float32),
                       "uvs": None if obj.uvs is None else obj.uvs[v].astype(np.float32),
                       "colors": None if obj.colors is None else obj.colors[v].astype(np.float32),
                       "tangents": None if obj.tangents is None else obj.tangents[v].astype(np.float32),
                       "lm_uv": charts.uv.astype(np.float32), "lm_page": charts.page.astype(np.int32),
                       "indices": charts.indices.astype(np.uint32), "vmapping": v.astype(np.int64)})
    save_meshes(path / "meshes.npz", meshes)
    return atlas
