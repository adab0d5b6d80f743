"""Regenerates the committed Mitsuba 3 reference images in tests/data/ (run once; minutes).

    python3 tests/data/make_mitsuba_references.py

cornell_box_128.exr: mitsuba.cornell_box() exactly (its camera: fov 39.3077 deg on the
smaller axis, looking down -z from (0, 0, 3.9)), 128x128, box pixel filter (a
pixel's value is the mean over its area), path tracer with unlimited depth (the
bake's light maps have no depth limit either), 16384 samples per pixel, linear
RGB float32.
"""
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def cornell_box(size: int = 128, spp: int = 16384) -> np.ndarray:
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    scene = mi.cornell_box()
    scene["integrator"] = {"type": "path", "max_depth": -1, "rr_depth": 8}
    scene["sensor"]["film"].update({"width": size, "height": size, "rfilter": {"type": "box"}})
    scene["sensor"]["sampler"] = {"type": "independent", "sample_count": spp}
    return np.array(mi.render(mi.load_dict(scene), spp=spp), dtype=np.float32)


if __name__ == "__main__":
    from glint.core.image_io import write_image

    image = cornell_box()
    write_image(HERE / "cornell_box_128.exr", image, half=False)
    print("wrote", HERE / "cornell_box_128.exr", image.shape, float(image.mean()))
