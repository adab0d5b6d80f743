"""The `skipping` section: how much of a frame's and a bake's work was skipped, and why.

    section = skipping_section(renderer.stats, bake.model, bake_status=report.status)

One fixed shape (every key always present), built only here, for `glint capture --stats`,
`glint bench` (bench.json per camera, a table in bench.md) and the window's overlay line:

    specular     tiles in the frame, tiles dispatched (with view-dependent pixels), tiles
                 skipped; pixels with lobes against all pixels -- at the render size (the
                 supersampled one), as the shading pass's 8 x 8 tiles are
                 (viewer/passes/shading.py)
    mirror       planar reflectors, passes run, reflectors skipped per reason
                 (viewer/reflectors.py SkipReason; "budget 0" where the budget turned the
                 passes off), reflectors merged into another's pass (same plane)
    cube_maps    objects, cube maps baked, objects without one per reason (core/skipped.py); the bake's
                 probes (shared cube maps), their MiB, face sizes and budget
    bake         this command's bake step, and what the bake that wrote the directory redid
                 and reused and why (manifest statistics.last_bake; null for older bake dirs)

A skipped amount is `{"count", "of", "fraction", "reason"}` (with "names" where objects are
named); the fraction is count / of, 0 when there is nothing to count.
"""
from __future__ import annotations

from glint.core.manifest import Manifest
from glint.core.skipped import DIFFUSE_ROLE, NO_LOBE, NOT_BAKED, PLANAR, cube_map_skips
from glint.viewer.reflectors import SkipReason

BUDGET_OFF = "budget 0"
MIRROR_REASONS = {
    SkipReason.OUTSIDE_FRUSTUM.value: "no part of it in the view frustum (behind the camera counts)",
    SkipReason.BACK_FACING.value: "the eye is behind its plane (or in it)",
    SkipReason.OCCLUDED.value: "hidden behind other objects in an earlier frame's occlusion query",
    SkipReason.OVER_BUDGET.value: "more planes in view than the mirror-pass budget",
    BUDGET_OFF: "--mirror-budget 0: no mirror passes at all",
}
CUBE_MAP_REASONS = {
    NO_LOBE: "diffuse material: the light map is all of its light",
    PLANAR: "planar reflector: reads a mirror pass at run time (section 4.5)",
    DIFFUSE_ROLE: "the sidecar made it diffuse",
    NOT_BAKED: "curved or transmissive, yet the bake has no cube map for it",
}
BAKE_STATUS = {
    "up-to-date": "nothing: up to date",
    "manifest": "manifest only (light maps, unwrap and cube maps reused)",
    "cubemaps": "cube maps only (light maps and unwrap reused)",
    "lightmaps": "light maps (unwrap reused)",
    "full": "everything",
}


def skipped(count: int, of: int, reason: str, names=None) -> dict:
    """One skipped amount."""
    out = {"count": int(count), "of": int(of), "fraction": round(count / of, 4) if of else 0.0, "reason": reason}
    if names is not None:
        out["names"] = list(names)
    return out


def specular_part(stats: dict) -> dict:
    spec = stats["specular"]
    tiles = spec["tiles_with_lobes"] + spec["tiles_skipped"]
    w, h = stats["render_size"] or (0, 0)
    dispatched = spec["tiles_with_lobes"] > 0
    reason = ("no pixel of the tile needs specular light (no lobe, no cube map or mirror pass, or a dark back face)"
              if dispatched or spec["materials_with_lobes"] else "no material has view-dependent lobes")
    return {
        "tiles": tiles,
        "tiles_dispatched": spec["tiles_with_lobes"],
        "tiles_skipped": skipped(spec["tiles_skipped"], tiles, reason),
        "pixels": w * h,
        "pixels_with_lobes": spec["pixels_with_lobes"],
        "pixels_without_lobes": skipped(w * h - spec["pixels_with_lobes"], w * h, "diffuse shading only"),
        "dispatch": "ran" if dispatched else "skipped: " + reason,
    }


def mirror_part(stats: dict) -> dict:
    m = stats["mirror"]
    reflectors = m["reflectors"]
    names = dict(m.get("skipped_reflectors") or {})
    counts = {reason: len(names.get(reason, [])) for reason in MIRROR_REASONS}
    if m["layers"] == 0 and m["budget"] == 0 and reflectors:
        counts[BUDGET_OFF] = reflectors
    in_passes = m.get("reflectors_in_passes", 0)
    return {
        "reflectors": reflectors,
        "passes_run": m.get("passes_run", 0),
        "reflectors_in_passes": in_passes,
        "merged": skipped(in_passes - m.get("passes_run", 0), in_passes,
                          "shares a plane with another reflector: one pass for both"),
        "skipped": {reason: skipped(counts[reason], reflectors, why, names.get(reason, []))
                    for reason, why in MIRROR_REASONS.items()},
        "budget": m["budget"],
    }


PROBE_KEYS = ("probes", "shared_probes", "mib", "face_sizes", "budget")


def cube_map_part(manifest: Manifest) -> dict:
    cubes = cube_map_skips(manifest)
    n = cubes["objects"]
    without = {reason: skipped(len(names), n, CUBE_MAP_REASONS[reason], names)
               for reason, names in cubes["without"].items()}
    stats = manifest.statistics.cubemaps
    probes = {k: stats[k] for k in PROBE_KEYS if k in stats}  # the bake's probes and budget (bake/cubemap.py)
    return {"objects": n, "baked": cubes["baked"],
            "without": skipped(n - cubes["baked"], n, "see without_by_reason"),
            "without_by_reason": without, **({"probes": probes} if probes else {})}


def bake_part(manifest: Manifest, bake_status: str | None) -> dict:
    record = manifest.statistics.last_bake
    return {
        "this_command": None if bake_status is None else {"status": bake_status,
                                                          "redone": BAKE_STATUS.get(bake_status, bake_status)},
        "last_bake": record,
        "note": None if record is not None else "not recorded: the bake dir predates statistics.last_bake",
    }


def frame_section(stats: dict) -> dict:
    """The parts that change frame by frame (renderer.stats)."""
    return {"specular": specular_part(stats), "mirror": mirror_part(stats)}


def bake_section(manifest: Manifest, bake_status: str | None = None) -> dict:
    """The parts that come from the bake: `manifest` and `bake_status`, the status of the bake step
    the command itself ran (BakeReport.status; None: it ran none)."""
    return {"cube_maps": cube_map_part(manifest), "bake": bake_part(manifest, bake_status)}


def skipping_section(stats: dict, manifest: Manifest, bake_status: str | None = None) -> dict:
    """The whole section: the frame of `stats` (renderer.stats) and the bake (`bake_section`)."""
    return {**frame_section(stats), **bake_section(manifest, bake_status)}


def one_line(section: dict) -> str:
    """A short line for the overlay and the bench table."""
    s, m = section["specular"], section["mirror"]
    mirror_skipped = sum(v["count"] for v in m["skipped"].values())
    return (f"skipped: {s['tiles_skipped']['count']}/{s['tiles']} specular tiles, "
            f"{mirror_skipped}/{m['reflectors']} mirror reflectors ({m['passes_run']} passes)")


def markdown_table(sections: dict[str, dict]) -> str:
    """{camera: section} as a Markdown table (bench.md)."""
    rows = ["| camera | specular tiles skipped | pixels with lobes | mirror passes run | reflectors skipped "
            "(reason) | reflectors merged |", "|---|---:|---:|---:|---|---:|"]
    for camera, sec in sections.items():
        s, m = sec["specular"], sec["mirror"]
        why = ", ".join(f"{v['count']} {reason}" for reason, v in m["skipped"].items() if v["count"]) or "none"
        rows.append(f"| {camera} | {s['tiles_skipped']['count']} of {s['tiles']} "
                    f"({100 * s['tiles_skipped']['fraction']:.0f}%) | {s['pixels_with_lobes']} of {s['pixels']} "
                    f"({100 * (1 - s['pixels_without_lobes']['fraction']):.0f}%) | {m['passes_run']} | {why} | "
                    f"{m['merged']['count']} |")
    first = next(iter(sections.values()), None)
    if first is None:
        return ""
    c, b = first["cube_maps"], first["bake"]
    reasons = ", ".join(f"{v['count']} {r}" for r, v in c["without_by_reason"].items() if v["count"])
    last = b["last_bake"]
    bake = (f"last bake: unwrap {last['unwrap']}, light maps {last['light_maps']} ({last['why']}), "
            f"cube maps {last['cube_maps_rendered']} rendered / {last['cube_maps_reused']} reused"
            if last else "last bake: " + b["note"])
    return ("\n".join(rows) + f"\n\nCube maps: {c['baked']} of {c['objects']} objects"
            + (f"; none needed for {reasons}" if reasons else "") + f". {bake}.\n")
