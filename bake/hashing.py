"""Content hashes of each bake stage's inputs: a re-bake redoes only what a change touches.

geometry   -> unwrap + texel positions (meshes.npz)
lightmaps  -> geometry + everything the transport reads: kd (and textures), every lobe (the bake's
              paths scatter by the whole BSDF, bake/scatter.py; glass lets light through),
              alpha coverage (MASK, BLEND), emission, lights, sky, transport settings.
              Roles and cameras are not in it: they only change the manifest, never a light map.
cubemaps   -> one hash per cube map: lightmaps + its object, face size, projection centre,
              the objects hidden in it and how it is rendered (bake/cubemap.py), so editing
              one object's lobes re-renders at most its own cube map (when its size changes).
              Bounding planes are not in it: they only change the manifest.
"""
from __future__ import annotations

import hashlib
import json

import numpy as np

from glint.core.bake_dir import FORMAT_VERSION
from glint.core.scene import Scene

# Bump when the integrator or the unwrap changes what they produce.
GEOMETRY_VERSION = 1
TRANSPORT_VERSION = 7  # 2: back sides of two-sided objects baked; back-face rule spares them; 3: paths scatter by the lobes; 4: samples inset from chart borders and moved out of covering geometry (bake/sample_points.py); 5: adaptive sampling (bake/lightmap.py); 6: sample probes pass cut-outs (bake/sample_points.py); 7: probes look past the facet they cross, moved samples avoid slots, samples in cavities get more paths
CUBEMAP_VERSION = 1  # bump when the renderer changes what a cube map's pixels are


class _Hasher:
    def __init__(self, tag: str):
        self._h = hashlib.sha256(tag.encode())

    def array(self, a) -> "_Hasher":
        a = np.ascontiguousarray(a)
        self._h.update(f"{a.dtype.str}{a.shape}".encode())
        self._h.update(a.tobytes())
        return self

    def value(self, v) -> "_Hasher":
        self._h.update(json.dumps(v, sort_keys=True, default=_jsonable).encode())
        return self

    def hexdigest(self) -> str:
        return self._h.hexdigest()[:32]


def _jsonable(v):
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return str(v)


def geometry_hash(scene: Scene, settings) -> str:
    h = _Hasher(f"geometry-v{GEOMETRY_VERSION}")
    h.value([settings.texels_per_metre, settings.padding, settings.max_page_size])
    for obj in scene.objects:
        h.value(obj.name).array(obj.positions).array(obj.normals).array(obj.indices)
        if obj.tangents is not None:  # only then: objects without keep the hashes of existing bakes
            h.array(obj.tangents)
    return h.hexdigest()


def transport_hash(scene: Scene, settings, geometry: str) -> str:
    h = _Hasher(f"transport-v{TRANSPORT_VERSION}").value(geometry).value(settings.transport_dict())
    for obj in scene.objects:
        h.value(obj.material)
        if obj.uvs is not None:
            h.array(obj.uvs)
        if obj.colors is not None:  # only then: objects without keep the hashes of existing bakes
            h.array(obj.colors)
    for m in scene.materials:
        h.value([m.kd, m.emission, m.double_sided, [lobe.to_dict() for lobe in m.lobes]])
        if m.emission_texture is not None:  # only then: existing bakes keep their hashes
            h.array(m.emission_texture)
        if m.metallic_roughness_texture is not None:  # its metallic scales kd per texel
            h.array(m.metallic_roughness_texture)
        if m.kd_texture is not None or m.emission_texture is not None or m.metallic_roughness_texture is not None:
            if m.kd_texture is not None:
                h.array(m.kd_texture)
            if tuple(m.kd_wrap) != ("REPEAT", "REPEAT") or m.kd_nearest:  # else existing bakes' hashes
                h.value(["sampler", list(m.kd_wrap), bool(m.kd_nearest)])
        if m.has_coverage:  # only then: opaque materials keep the hashes of existing bakes
            h.value(["alpha", m.alpha_mode, float(m.alpha_cutoff), float(m.alpha)])
            if m.alpha_texture is not None:
                h.array(m.alpha_texture)
        if m.has_volume:  # only then: thin materials keep the hashes of existing bakes
            h.value(["volume", float(m.ior), float(m.thickness), [float(x) for x in m.absorption]])
    for light in (*scene.point_lights, *scene.spot_lights, *scene.directional_lights):
        h.value(type(light).__name__).value({k: v for k, v in vars(light).items() if k != "name"})
    if scene.sky is not None:
        h.value(["sky", scene.sky.radiance])
        if scene.sky.map is not None:
            h.array(scene.sky.map)
    return h.hexdigest()


def cubemap_hash(transport: str, inputs: dict) -> str:
    """`inputs`: everything of one cube map besides the light-mapped scene (bake/cubemap.py)."""
    return _Hasher(f"cubemap-v{CUBEMAP_VERSION}").value(transport).value(inputs).hexdigest()


def stage_versions() -> dict:
    """The versions of what glint makes of the same inputs (the manifest's `inputs.versions`): a bake
    made with others is redone (the stage hashes include them too); core/skipped.py VERSION_NAMES
    names them."""
    return {"format": FORMAT_VERSION, "geometry": GEOMETRY_VERSION, "transport": TRANSPORT_VERSION,
            "cubemap": CUBEMAP_VERSION, "gltf_table": gltf_table_version()}


def gltf_table_version() -> str:
    """The shipped glTF fit table's content (bake/gltf_fit_table.py), short: a new table maps the same glTF
    file to other lobes, which the scene's content hash (the file's bytes) does not see, so a bake made
    with another table is not up to date (its manifest would keep the old lobes)."""
    from importlib import resources

    from glint.bake.gltf_fit_table import TABLE_FILE

    return hashlib.sha256(resources.files("glint.bake").joinpath(TABLE_FILE).read_bytes()).hexdigest()[:12]


def object_hashes(obj) -> dict:
    """Short hashes of one object's positions, normals, indices and texture coordinates, rounded to
    float32 first (a last-bit difference of the float64 transform seldom survives): they only name
    what changed in a stale bake's line (core/skipped.py), they decide nothing."""
    def short(a) -> str | None:
        if a is None:
            return None
        a = np.asarray(a)
        return _Hasher("").array(a.astype(np.float32) if a.dtype.kind == "f" else a.astype(np.int64)).hexdigest()[:12]
    return {"positions": short(obj.positions), "normals": short(obj.normals), "indices": short(obj.indices),
            "uvs": short(obj.uvs)}
