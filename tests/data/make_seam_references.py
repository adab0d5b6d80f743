"""Regenerates tests/data/seam_interior_reference.npz, Mitsuba 3's irradiance at the seam strips'
points of tests/seam_scenes.py's interior (run once; 23 minutes on this shared 2-core machine):

    python3 tests/data/make_seam_references.py [SPP [OUT.npz]]

The scene is written by seam_scenes.write_interior, loaded by glint's loader and converted by
bench/mitsuba_scene.py (its own BSDFs, two-sided materials as Mitsuba's two_sided); irradiance by
bench/mitsuba_reference.py's patch-and-radiancemeter method, SPP samples per point, unlimited depth.
Stored: for each strip (SEAMS, then THICK_WALL_INTERIOR) `<name>/points` (blocks, 12, 3) and
`<name>/E` (blocks, 12, 3); `spp`.
"""
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
SPP = int(sys.argv[1]) if len(sys.argv) > 1 else 4096


def main() -> None:
    import seam_scenes as S
    from glint.bake.gltf_loader import load_scene
    from glint.bench.mitsuba_reference import scene_irradiance

    with tempfile.TemporaryDirectory() as tmp:
        scene = load_scene(S.write_interior(Path(tmp) / "interior.glb"))
    out = {"spp": np.array(SPP)}
    for strip in (*S.SEAMS, S.THICK_WALL_INTERIOR):
        points, normal = S.block_points(strip)
        flat = points.reshape(-1, 3)
        E = scene_irradiance(scene, flat, np.tile(normal, (len(flat), 1)), spp=SPP)
        out[f"{strip.name}/points"] = points.astype(np.float32)
        out[f"{strip.name}/E"] = E.reshape(points.shape).astype(np.float32)
        print(strip.name, points.shape[0], "blocks, mean E", E.mean(), flush=True)
    np.savez_compressed(sys.argv[2] if len(sys.argv) > 2 else HERE / "seam_interior_reference.npz", **out)


if __name__ == "__main__":
    main()
