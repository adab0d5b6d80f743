"""Directional albedo of glTF materials: the specification's BRDF against glint's mapping (issue 24).

    python3 -m glint.bench.measure_gltf_albedo [--out docs/bench/gltf-albedo/] [--name before] [--n 65536]

For every material of a grid (roughness 0 ... 1, metallic 0 and 1, three base colours) and view
angle (0 ... 85 deg) it prints and writes (NAME.json, NAME.md under --out) the directional albedo
of the glTF 2.0 BRDF (core/gltf_brdf.py, the reference written from the spec) and of the kd + lobes
that a mapping makes of the same material (by default glint's current one,
glint.bake.material_mapping.map_pbr): kd (a Lambertian kd/pi reflects kd) plus each reflect lobe's
ks times its albedo (glint.core.bsdf.lobe_albedo), and their relative difference. Both are
reflection only (the grid has no transmission). `glint_albedo` takes the mapping as an argument,
so a fitted mapping is measured the same way.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from glint.bake.material_mapping import GltfPbr, map_pbr
from glint.bench.report import write_json
from glint.core.atomic import atomic_write_text
from glint.core.bsdf import lobe_albedo
from glint.core.gltf_brdf import GltfMaterialParams, directional_albedo

ROUGHNESS = (0.0, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0)
METALLIC = (0.0, 1.0)
COLOURS = {"grey 0.9": (0.9, 0.9, 0.9), "orange (0.8, 0.5, 0.2)": (0.8, 0.5, 0.2), "grey 0.2": (0.2, 0.2, 0.2)}
THETA_DEG = (0, 15, 30, 45, 60, 70, 75, 80, 85)
COMMAND = "python3 -m glint.bench.measure_gltf_albedo"
SAMPLES = 1 << 16  # reference samples per angle: 4x core/gltf_brdf.py's default, within 0.01 % of 2^19

# A mapping: glTF parameters -> (kd (3,), lobes (glint.core.scene.Lobe list), emission (3,)).
Mapping = Callable[[GltfPbr], tuple]


@dataclass(frozen=True)
class AlbedoRow:
    """One material at one view angle: RGB albedos and the relative difference of their means."""

    colour: str
    base_color: tuple[float, float, float]
    metallic: float
    roughness: float
    theta_deg: float
    reference: tuple[float, float, float]   # core/gltf_brdf.py
    glint: tuple[float, float, float]       # the mapping's kd + lobes
    relative_difference: float              # (mean(glint) - mean(reference)) / mean(reference)


def view_directions(theta_deg) -> np.ndarray:
    t = np.radians(np.asarray(theta_deg, float))
    return np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)


def glint_albedo(pbr: GltfPbr, theta_deg, mapping: Mapping = map_pbr) -> np.ndarray:
    """Directional albedo (reflection) of the kd + lobes `mapping` makes of `pbr`, RGB per angle."""
    kd, lobes, _ = mapping(pbr)
    wo = view_directions(theta_deg)
    total = np.broadcast_to(np.asarray(kd, float), wo.shape).copy()  # Lambert: kd / pi reflects kd
    for lobe in lobes:
        if lobe.kind != "reflect":
            continue
        a = lobe_albedo(wo, lobe.mx, lobe.my, lobe.r0, lobe.alpha, "reflect")
        total += np.asarray(lobe.ks, float) * a[..., None]
    return total


def reference_albedo(params: GltfMaterialParams, theta_deg, n: int = SAMPLES) -> np.ndarray:
    """Directional albedo (reflection) of the glTF BRDF, RGB per angle."""
    return directional_albedo(params, np.radians(np.asarray(theta_deg, float)), n=n)


def measure(mapping: Mapping = map_pbr, n: int = SAMPLES, roughness=ROUGHNESS, metallic=METALLIC,
            colours=COLOURS, theta_deg=THETA_DEG, progress=print) -> list[AlbedoRow]:
    rows = []
    for colour, base in colours.items():
        for m in metallic:
            for r in roughness:
                ref = reference_albedo(GltfMaterialParams(base_color=base, metallic=m, roughness=r), theta_deg, n)
                ours = glint_albedo(GltfPbr(base_color=base, metallic=m, roughness=r), theta_deg, mapping)
                for t, a, b in zip(theta_deg, ref, ours):
                    rel = (b.mean() - a.mean()) / a.mean()
                    rows.append(AlbedoRow(colour, tuple(base), m, r, float(t), tuple(map(float, a)),
                                          tuple(map(float, b)), float(rel)))
                if progress:
                    progress(f"{colour:24s} metallic {m:.0f} roughness {r:4.2f}: "
                             + " ".join(f"{x.relative_difference * 100:+6.1f}%" for x in rows[-len(theta_deg):]))
    return rows


def commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                             cwd=Path(__file__).resolve().parent, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain"], capture_output=True, text=True,
                               cwd=Path(__file__).resolve().parent).stdout.strip()
        return out + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def markdown(rows: list[AlbedoRow], title: str, command: str, revision: str, n: int) -> str:
    """Tables per (colour, metallic): rows roughness, columns view angle; cells reference / glint
    (mean of RGB) and the relative difference."""
    thetas = sorted({r.theta_deg for r in rows})
    lines = [f"# {title}", "",
             f"Commit {revision}; `{command}`. Reference: core/gltf_brdf.py (glTF 2.0 Appendix B, "
             f"{n} Sobol samples per angle, converged within 0.03 %); glint: kd + the reflect lobes' albedo "
             "(core/bsdf.py lobe_albedo) of the mapping's lobes. Cells: reference / glint (glint - "
             "reference, relative), mean of RGB, reflection only.", ""]
    worst = max(rows, key=lambda r: abs(r.relative_difference))
    lines += [f"Largest difference: {worst.relative_difference * 100:+.1f} % ({worst.colour}, metallic "
              f"{worst.metallic:.0f}, roughness {worst.roughness}, {worst.theta_deg:.0f} deg).", ""]
    groups = {}
    for r in rows:
        groups.setdefault((r.colour, r.metallic), []).append(r)
    for (colour, metallic), group in groups.items():
        kind = "metal" if metallic == 1 else "dielectric"
        lines += [f"## {kind} (metallic {metallic:.0f}), base colour {colour}", "",
                  "| roughness | " + " | ".join(f"{t:.0f} deg" for t in thetas) + " |",
                  "|---|" + "---|" * len(thetas)]
        for rough in sorted({r.roughness for r in group}):
            cells = {r.theta_deg: r for r in group if r.roughness == rough}
            lines.append(f"| {rough:g} | " + " | ".join(
                f"{np.mean(cells[t].reference):.3f} / {np.mean(cells[t].glint):.3f} "
                f"({cells[t].relative_difference * 100:+.0f} %)"
                for t in thetas) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="folder for NAME.json and NAME.md (default: print only)")
    ap.add_argument("--name", default="before", help="file name stem (default: before)")
    ap.add_argument("--n", type=int, default=SAMPLES, help=f"reference samples per angle (default {SAMPLES})")
    args = ap.parse_args(argv)
    if args.n < 256:
        ap.error("--n must be at least 256")
    rows = measure(n=args.n)
    command = " ".join([COMMAND] + (argv if argv is not None else sys.argv[1:]))
    revision = commit()
    title = f"Directional albedo: glTF BRDF against glint's mapping ({args.name})"
    text = markdown(rows, title, command, revision, args.n)
    print(text.split("\n## ")[0])
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        write_json(args.out / f"{args.name}.json", {"command": command, "commit": revision, "n": args.n,
                                                     "rows": [asdict(r) for r in rows]})
        atomic_write_text(args.out / f"{args.name}.md", text + "\n")
        print(f"wrote {args.out / (args.name + '.json')} and {args.out / (args.name + '.md')}")


if __name__ == "__main__":
    main()
