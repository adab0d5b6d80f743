"""Checks and repairs of loaded scene data, and the value checks of the sidecar.

Two kinds of problem:
- fatal (`GlintError`, one line naming the file/object and the fix): non-finite
  vertex positions, no triangle meshes, no light at all;
- recoverable (a warning, printed once and kept in `Scene.warnings`): degenerate
  triangles are dropped, missing or zero-length normals are computed. Those that
  repeat per object or material have a kind and are summarised in one line per kind
  (glint.core.errors.summarised; `--verbose` lists each).
"""
from __future__ import annotations

import math

import numpy as np

from glint.core.errors import GlintError, WarningKind, warn
from glint.core.geometry import face_cross

# A triangle is degenerate when its area is below this fraction of the square of
# its object's bounding-box diagonal (1e-12 * (10 m)^2 = 1e-10 m^2), or when two of
# its corners are the same vertex. Such triangles have no normal and no texels.
DEGENERATE_AREA = 1e-12
# Coordinates farther from the origin than this (metres, world space) are refused: float32 positions
# there are 0.06 m apart and a light map of such a scene would need astronomically many pages; a
# scene this large is a unit mistake (centimetres or millimetres exported as metres, or a stray vertex).
MAX_COORDINATE = 1e6
# Per material, so summarised in one line (glint.core.errors.WarningKind).
BRIGHT_KD = WarningKind("{n} materials have kd above 1 (a surface that would create light); clamped to 1")
BRIGHT_KS = WarningKind("{n} materials have a lobe whose ks is above 1 (it would reflect more light than "
                        "it receives); clamped to 1")


def add_warning(warnings: list[str], message: str, kind: WarningKind | None = None,
                subject: str | None = None, **how) -> None:
    """Print a recoverable problem once (summarised with others of its `kind`) and keep it
    (for `Scene.warnings`); `kind`, `subject` and `how` as for glint.core.errors.warn."""
    warn(message, kind, subject, **how)
    warnings.append(message)


def check_finite_positions(name: str, positions: np.ndarray, source: str) -> None:
    """NaN/Inf positions cannot be repaired meaningfully: name the object and stop."""
    bad = ~np.isfinite(positions).all(axis=1)
    if bad.any():
        raise GlintError(
            f"{source}: object '{name}' has {int(bad.sum())} vertex position(s) that are "
            f"NaN or infinite (first at vertex {int(np.argmax(bad))}); fix or remove it "
            f"in the modelling tool and export again")


def check_extent(name: str, positions: np.ndarray, source: str) -> None:
    """Coordinates beyond MAX_COORDINATE: name the object, its bounding box and the limit, and stop."""
    if len(positions) and float(np.abs(positions).max()) > MAX_COORDINATE:
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        box = ", ".join(f"{a:.3g}..{b:.3g}" for a, b in zip(lo, hi))
        raise GlintError(
            f"{source}: object '{name}' reaches {float(np.abs(positions).max()):.3g} m from the origin "
            f"(bounding box x, y, z: {box} m); glint takes coordinates within {MAX_COORDINATE:.0e} m: "
            f"check the export's units and scale, or remove stray vertices")


def degenerate_triangles(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Boolean mask of zero-area triangles (repeated corner, or area below DEGENERATE_AREA)."""
    if len(indices) == 0:
        return np.zeros(0, bool)
    repeated = ((indices[:, 0] == indices[:, 1]) | (indices[:, 1] == indices[:, 2])
                | (indices[:, 0] == indices[:, 2]))
    used = positions[np.unique(indices)]
    diag2 = float(np.sum((used.max(axis=0) - used.min(axis=0)) ** 2))
    area = 0.5 * np.linalg.norm(face_cross(positions, indices), axis=1)
    return repeated | (area <= DEGENERATE_AREA * diag2)


def area_weighted_normals(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Vertex normals as the sum of adjacent face normals weighted by face area.

    The unnormalised cross product already carries the 2*area weight. Vertices
    used by no face get (0, 0, 0); callers replace those (see `repair_normals`).
    """
    cross = face_cross(positions, indices)
    corners = indices.reshape(-1)
    acc = np.stack([np.bincount(corners, weights=np.repeat(cross[:, k], 3),
                                minlength=len(positions)) for k in range(3)], axis=1)
    length = np.linalg.norm(acc, axis=1, keepdims=True)
    return np.divide(acc, length, out=np.zeros_like(acc), where=length > 0)


def repair_normals(normals: np.ndarray, positions: np.ndarray,
                   indices: np.ndarray) -> tuple[np.ndarray, int]:
    """Normalise vertex normals; replace zero-length or non-finite ones by the face normal.

    "The face normal" of a vertex shared by several faces is their area-weighted
    mean, which is exactly the face normal for a vertex of one face. Returns the
    unit normals (float32) and how many were replaced.
    """
    n = np.asarray(normals, np.float64)
    length = np.linalg.norm(n, axis=1)
    bad = ~np.isfinite(length) | (length < 1e-12)
    out = np.divide(n, length[:, None], out=np.zeros_like(n), where=~bad[:, None])
    replaced = int(bad.sum())
    if replaced:
        out[bad] = area_weighted_normals(positions, indices)[bad]
    # A vertex used by no triangle still needs a unit normal: any will do.
    unused = np.linalg.norm(out, axis=1) < 0.5
    out[unused] = (0.0, 1.0, 0.0)
    return out.astype(np.float32), replaced


def validate_scene(scene) -> None:
    """Scene-level checks after loading: something to bake, and some light to bake with."""
    source = scene.source.name if scene.source is not None else scene.name
    if not scene.objects:
        raise GlintError(f"{source}: contains no triangle meshes; export at least one "
                         f"mesh object (lines and points are not rendered)")
    for obj in scene.objects:
        check_finite_positions(obj.name, obj.positions, source)
        check_extent(obj.name, obj.positions, source)
        if not 0 <= obj.material < len(scene.materials):
            raise GlintError(f"{source}: object '{obj.name}' refers to missing material "
                             f"{obj.material}")
    for mat in scene.materials:
        values = [mat.kd, mat.emission] + [[*lobe.ks, lobe.mx, lobe.my] for lobe in mat.lobes]
        if not all(np.all(np.isfinite(np.asarray(v, np.float32))) for v in values):
            raise GlintError(f"{source}: material '{mat.name}' has values too large for "
                             f"32-bit floats (kd, emission or a lobe)")
        warn_above_one(mat, source, scene.warnings)
    for light in scene.point_lights + scene.spot_lights + scene.directional_lights:
        power = getattr(light, "intensity", getattr(light, "irradiance", None))
        if not np.all(np.isfinite(np.asarray(power, np.float32))):
            raise GlintError(f"{source}: light '{light.name}' is too bright for 32-bit floats")
    if not scene.has_light:
        sidecar = scene.source.with_suffix("").name + ".glint.toml" if scene.source else \
            "the sidecar"
        raise GlintError(
            f"{source}: the scene has no light; add one of: an emissive material "
            f"(emissiveFactor > 0), a KHR_lights_punctual point/spot/directional light "
            f"(Blender: export with 'Punctual Lights' on), or a [sky] table in {sidecar}")


def warn_above_one(mat, source: str, warnings: list[str]) -> None:
    """kd or a lobe's ks above 1 would create light: the bake and the viewer clamp them to 1; say so."""
    kd = float(np.max(mat.kd))
    if kd > 1:
        add_warning(warnings, f"{source}: material '{mat.name}' has kd {_rgb_text(mat.kd)} above 1 (a surface "
                              "that would create light); clamped to 1", BRIGHT_KD, mat.name, detail=f"{kd:g}")
    ks = max((float(np.max(lobe.ks)) for lobe in mat.lobes), default=0.0)
    if ks > 1:
        add_warning(warnings, f"{source}: material '{mat.name}' has a lobe with ks {ks:g} above 1 (it would "
                              "reflect more light than it receives); clamped to 1", BRIGHT_KS, mat.name,
                    detail=f"{ks:g}")


def _rgb_text(v) -> str:
    return "[" + ", ".join(f"{float(x):g}" for x in np.asarray(v).reshape(-1)) + "]"


# -- value checks for the sidecar and material extras ----------------------------------


def warn_unknown_keys(table: dict, known, name: str, prefix: str, w: list[str]) -> None:
    for key in table:
        if key not in known:
            add_warning(w, f"{name}: unknown key {prefix}{key!r} ignored "
                           f"(known: {', '.join(known)})")


def check_number(value, where: str, *, positive: bool = False,
                 minimum: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise GlintError(f"{where} must be a number, not {value!r}")
    if positive and value <= 0:
        raise GlintError(f"{where} must be positive, not {value!r}")
    if minimum is not None and value < minimum:
        raise GlintError(f"{where} must be at least {minimum}, not {value!r}")
    return float(value)


def check_vec3(value, where: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != 3:
        raise GlintError(f"{where} must be a list of 3 numbers, not {value!r}")
    return np.array([check_number(v, where) for v in value], np.float64)


def check_rgb(value, where: str, *, minimum: float | None = None) -> np.ndarray:
    """3 numbers, or 1 number meaning grey."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [value] * 3
    if not isinstance(value, list) or len(value) != 3:
        raise GlintError(f"{where} must be a number or a list of 3 numbers (RGB), not {value!r}")
    return np.array([check_number(v, where, minimum=minimum) for v in value], np.float32)
