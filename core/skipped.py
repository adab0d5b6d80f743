"""What a bake did not do, and why: objects without a cube map, reused light maps and charts.

`glint bake` redoes only the stages whose inputs changed (bake/pipeline.py). Two things
say what it skipped:

- `cube_map_skips(manifest)`: per object whether it has a cube map, and if not why not --
  its material has no view-dependent lobe, it is a planar reflector (a mirror pass at run
  time instead, section 4.5), or the sidecar made it `diffuse`;
- `bake_record(...)`, kept as the manifest's `statistics.last_bake`: what the bake that
  wrote the directory redid and reused (unwrap, light maps, cube maps) and which changed
  inputs made it (`changed_inputs`, a comparison of the previous manifest with the new one).
  It is kept in the manifest because a later command (`glint capture`, `glint bench`) finds
  the bake up to date and did nothing itself; the statistics are outside the up-to-date
  comparison, and a bake dir written before the record existed reads as "not recorded".

`summary_line` is the line `glint bake` prints; viewer/skipping.py puts the same numbers into
`--stats` and the bench. Manifests are core/manifest.py's typed `Manifest`; the parts compared
as values (lobes, lights, cameras, ...) are compared as their JSON, as the bake writes them.
"""
from __future__ import annotations

from pathlib import Path

from glint.core.manifest import Manifest, Material

NO_LOBE = "no view-dependent lobe"
PLANAR = "planar: mirror pass instead"
DIFFUSE_ROLE = "role diffuse (sidecar): lobes not shown"
NOT_BAKED = "no cube map in the bake"
CUBE_MAP_REASONS = (NO_LOBE, PLANAR, DIFFUSE_ROLE, NOT_BAKED)


def cube_map_skips(manifest: Manifest) -> dict:
    """{"objects": n, "baked": k, "without": {reason: [object names]}} (every reason of
    CUBE_MAP_REASONS present, in that order)."""
    without: dict[str, list[str]] = {reason: [] for reason in CUBE_MAP_REASONS}
    baked = 0
    for obj in manifest.objects:
        if obj.cubemap is not None:
            baked += 1
        elif not manifest.material_of(obj).lobes:
            without[NO_LOBE].append(obj.name)
        elif obj.role == "planar":
            without[PLANAR].append(obj.name)
        elif obj.role == "diffuse":
            without[DIFFUSE_ROLE].append(obj.name)
        else:
            without[NOT_BAKED].append(obj.name)
    return {"objects": len(manifest.objects), "baked": baked, "without": without}


# -- what changed since the last bake ------------------------------------------------------------
def _by_name(entries) -> dict:
    return {e.name: e for e in entries}


def _lobes(material: Material, transmit: bool) -> list:
    return [lobe.to_dict() for lobe in material.lobes if (lobe.kind == "transmit") == transmit]


def _cubemap(obj) -> dict | None:
    return obj.cubemap.to_json() if obj.cubemap is not None else None


def _close(a, b, rel: float = 1e-9) -> bool:
    """Equal, floats within `rel` (a camera's or light's direction computed on another machine may
    differ in the last bit: that is no change)."""
    if isinstance(a, float) or isinstance(b, float):
        return (isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool)
                and abs(a - b) <= rel * max(abs(a), abs(b), 1e-300))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], rel) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_close(x, y, rel) for x, y in zip(a, b))
    return a == b


# TOML tables of the sidecar whose entries are named tables of their own ([objects."Box"], [cameras.Door]).
_NAMED_TABLES = ("materials", "objects", "cameras", "camera_paths")


def sidecar_changes(old: dict | None, new: dict | None) -> list[str]:
    """The sidecar's change between two manifests' `inputs.sidecar` ({file, content} or None), e.g.
    ["sidecar room.glint.toml changed: [bake] samples, [cameras.Door]"]; [] when the same."""
    old_content, new_content = (old or {}).get("content") or {}, (new or {}).get("content") or {}
    if bool(old) == bool(new) and old_content == new_content:  # both absent, or the same tables
        return []
    keys = []
    for table in sorted(set(old_content) | set(new_content), key=lambda t: (t not in new_content, t)):
        a, b = old_content.get(table), new_content.get(table)
        if a == b:
            continue
        if not (isinstance(a, dict) or isinstance(b, dict)):
            keys.append(table)
            continue
        a, b = a if isinstance(a, dict) else {}, b if isinstance(b, dict) else {}
        changed = [k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
        if table in _NAMED_TABLES:  # [objects.Box] role where the entry changed, [cameras.Door] where it came or went
            for k in changed:
                x, y = a.get(k), b.get(k)
                inner = sorted(n for n in set(x) | set(y) if x.get(n) != y.get(n)) \
                    if isinstance(x, dict) and isinstance(y, dict) else []
                keys.append(f"[{table}.{k}]" + (" " + " ".join(inner) if inner else ""))
        else:
            keys.append(f"[{table}] " + " ".join(changed) if changed else f"[{table}]")
    name = (new or old)["file"]
    what = "appeared" if not old else "disappeared" if not new else "changed"
    if what == "changed" and old["file"] != new["file"]:
        name = f"{old['file']} -> {new['file']}"
    return [f"sidecar {name} {what}" + (f" ({_phrase(keys)})" if keys else "")]


# What each entry of the manifest's `inputs.versions` (bake/hashing.py stage_versions) is, in a stale line.
VERSION_NAMES = {"format": "bake format", "geometry": "unwrap version", "transport": "light-map integrator version",
                 "cubemap": "cube-map renderer version", "gltf_table": "glTF material fit table"}


def version_changes(old: Manifest, new: Manifest) -> list[str]:
    """glint's stage versions that differ between two manifests' `inputs.versions`, e.g.
    ["light-map integrator version 2 -> 3"]; [] when the same or when `old` records none."""
    a, b = (old.inputs or {}).get("versions"), (new.inputs or {}).get("versions") or {}
    if a is None:
        return []
    return [f"{VERSION_NAMES.get(k, k)} {a.get(k)} -> {v}" for k, v in b.items() if a.get(k) != v]


def changed_inputs(old: Manifest, new: Manifest) -> dict[str, list[str]]:
    """The inputs that differ between two manifests, by the stage they invalidate (bake/hashing.py):
    {"files": [...], "geometry": [...], "light maps": [...], "manifest": [...]}, each a list of short
    phrases such as "sidecar room.glint.toml changed ([bake] samples)", "positions of Box",
    "kd of Floor" or "cameras". "files" names what changed in the scene's files (the sidecar's
    tables and keys, each object's content) besides what the stages name."""
    out: dict[str, list[str]] = {"files": [], "geometry": [], "light maps": [], "manifest": []}
    old_inputs, new_inputs = old.inputs or {}, new.inputs or {}
    if old.inputs is not None:
        out["files"] += sidecar_changes(old_inputs.get("sidecar"), new_inputs.get("sidecar"))
    old_objects_c, new_objects_c = old_inputs.get("objects"), new_inputs.get("objects") or {}
    if old_objects_c is not None:
        added = [n for n in new_objects_c if n not in old_objects_c]
        removed = [n for n in old_objects_c if n not in new_objects_c]
        if added:
            out["geometry"].append("objects added: " + _phrase(added))
        if removed:
            out["geometry"].append("objects removed: " + _phrase(removed))
        for name, hashes in new_objects_c.items():
            o = old_objects_c.get(name)
            what = [k for k, v in hashes.items() if o is not None and o.get(k) != v]
            if what:
                out["geometry" if set(what) - {"uvs"} else "light maps"].append(f"{', '.join(what)} of {name}")
    if old.stages.get("geometry") != new.stages["geometry"] and not out["geometry"]:
        out["geometry"].append("geometry or light-map resolution")
    old_settings = old.settings
    changed = [f"{k} {old_settings.get(k)} -> {v}" for k, v in new.settings.items()
               if k != "quality" and not _close(old_settings.get(k), v)]
    if changed:
        out["light maps"].append("bake settings (" + ", ".join(changed) + ")")
    old_materials, new_materials = _by_name(old.materials), _by_name(new.materials)
    if set(old_materials) != set(new_materials):
        out["light maps"].append("materials added or removed")
    for name, m in new_materials.items():
        o = old_materials.get(name)
        if o is None:
            continue
        for key, what in (("kd", "kd"), ("emission", "emission"), ("double_sided", "sides"),
                          ("kd_texture", "kd texture")):
            if not _close(getattr(o, key), getattr(m, key)):
                out["light maps"].append(f"{what} of {name}")
        if not _close(_lobes(o, True), _lobes(m, True)):
            out["light maps"].append(f"glass lobes of {name}")
        if not _close(_lobes(o, False), _lobes(m, False)):  # the bake's paths scatter by them (bake/scatter.py)
            out["light maps"].append(f"lobes of {name}")
    old_objects, old_names = _by_name(old.objects), [m.name for m in old.materials]
    for name, obj in _by_name(new.objects).items():
        o = old_objects.get(name)
        if o is None:
            continue
        k = int(o.material)
        if (old_names[k] if k < len(old_names) else None) != new.material_of(obj).name:
            out["light maps"].append(f"material of {name}")
        if o.role != obj.role:
            out["manifest"].append(f"role of {name}")
        elif not _close(_cubemap(o), _cubemap(obj)):
            out["manifest"].append(f"cube map of {name}")  # size, centre or bounding planes
    old_json, new_json = old.description_json(), new.description_json()
    for key, what in (("lights", "lights"), ("sky", "sky")):
        if not _close(old_json[key], new_json[key]):
            out["light maps"].append(what)
    for key, what in (("cameras", "cameras"), ("camera_paths", "camera paths")):
        if not _close(old_json[key], new_json[key]):
            out["manifest"].append(what)
    return out


def _phrase(items: list[str], limit: int = 3) -> str:
    return ", ".join(items[:limit]) + (f" and {len(items) - limit} more" if len(items) > limit else "")


def missing_reason(missing) -> str:
    """Why a bake whose inputs did not change is redone: the files of it that were gone."""
    return "files missing: " + _phrase(sorted(missing))


def stale_reason(old: Manifest, new: Manifest) -> str:
    """One phrase of why a bake with manifest `old` is redone for `new`, e.g.
    "changed: kd of Floor, bake settings (samples 32 -> 128)", "changed: sidecar room.glint.toml
    appeared ([objects.Box])" or "made by an older glint (light-map integrator version 2 -> 3)".
    "made by an older glint" only where glint's stage versions differ, or the old manifest records
    none and nothing else differs."""
    changes = changed_inputs(old, new)
    items = changes["files"] + changes["geometry"] + changes["light maps"] + changes["manifest"]
    versions = version_changes(old, new)
    if not items and not versions:
        if old.inputs is None:
            versions = ["its manifest records no stage versions"]
        elif old.scene.hash != new.scene.hash:
            items = [f"scene file {Path(new.scene.source or new.scene.name).name} (nothing the bake reads)"]
    parts = ([f"made by an older glint ({', '.join(versions)})"] if versions else []) + (
        ["changed: " + _phrase(items)] if items else [])
    return "; ".join(parts) or "changed: nothing found (bake with --force to redo it)"


def bake_record(status: str, old: Manifest | None, new: Manifest, cube_maps: dict, *, forced: bool = False,
                missing: tuple[str, ...] = ()) -> dict:
    """What the bake that writes `new` did and why (after `old`, the previous manifest or None);
    `status` as bake/pipeline.py's BakeReport, `cube_maps` its cube-map statistics, `missing` the old
    bake's files that were gone."""
    changes = changed_inputs(old, new) if old is not None else {"files": [], "geometry": [], "light maps": [], "manifest": []}
    if old is None:
        why = "--force" if forced else "no earlier bake of this format"
    elif missing and not any(changes.values()):
        why = missing_reason(missing)
    elif status == "full":
        why = "geometry changed"
    elif status == "lightmaps":
        why = ("changed: " + _phrase(changes["light maps"])) if changes["light maps"] else "diffuse inputs changed"
    elif changes["manifest"]:
        why = "only " + _phrase(changes["manifest"]) + " changed"
    elif status == "cubemaps":  # e.g. a new cube-map renderer version (bake/hashing.py CUBEMAP_VERSION)
        why = "only the cube maps' inputs changed"
    else:
        why = "only the manifest changed"
    return {
        "status": status,
        "unwrap": "redone" if status == "full" else "reused",
        "light_maps": "re-baked" if status in ("full", "lightmaps") else "reused",
        "why": why,
        "changed": changes["files"] + changes["geometry"] + changes["light maps"] + changes["manifest"],
        "cube_maps_rendered": int(cube_maps.get("rendered", 0)),
        "cube_maps_reused": int(cube_maps.get("reused", 0)),
    }


def summary_line(manifest: Manifest, status: str) -> str | None:
    """One line of what a bake skipped, e.g. "skipped: 34 of 39 objects need no cube map
    (30 no view-dependent lobe, 4 planar: mirror pass instead); light maps and unwrap reused
    (only cameras changed); cube maps: 0 rendered, 5 reused". None for an up-to-date
    bake (its summary says it did nothing)."""
    if status == "up-to-date":
        return None
    cubes = cube_map_skips(manifest)
    missing = sum(len(names) for names in cubes["without"].values())
    reasons = ", ".join(f"{len(names)} {reason}" for reason, names in cubes["without"].items() if names)
    parts = [f"{missing} of {cubes['objects']} objects need no cube map" + (f" ({reasons})" if reasons else "")]
    record = manifest.statistics.last_bake
    if record is not None:
        if record["light_maps"] == "reused":
            parts.append(f"light maps and unwrap reused ({record['why']})")
        elif record["unwrap"] == "reused":
            parts.append(f"unwrap reused; light maps re-baked ({record['why']})")
        else:
            parts.append(f"nothing reused ({record['why']})")
        if record["cube_maps_rendered"] or record["cube_maps_reused"]:
            parts.append(f"cube maps: {record['cube_maps_rendered']} rendered, {record['cube_maps_reused']} reused")
    return "skipped: " + "; ".join(parts)
