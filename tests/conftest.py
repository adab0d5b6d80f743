"""Shared fixtures: small glTF scenes written with scenes/gltf_writer.py."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from glint.scenes.gltf_writer import GltfWriter, quad, room_faces  # noqa: F401 (tests import quad from here)
from glint.viewer.context import headless_context


def write_room(path: Path, *, kd=(0.7, 0.7, 0.7), floor_lobes=None, light=8.0, box_height=0.5,
               sidecar: str | None = None, double_sided=()) -> Path:
    """A closed 2 x 2 x 2 m room (faces inwards), a ceiling light, a box on the floor; the materials
    named in `double_sided` ("Wall", "Floor", "Lamp") are glTF doubleSided."""
    w = GltfWriter()
    wall = w.add_material("Wall", base_color=kd, roughness=1.0, double_sided="Wall" in double_sided)
    extras = None if floor_lobes is None else {"glint": {"lobes": floor_lobes}}
    floor = w.add_material("Floor", base_color=kd, roughness=1.0, extras=extras, double_sided="Floor" in double_sided)
    lamp = w.add_material("Lamp", base_color=(0.8, 0.8, 0.8), emissive=(1, 1, 1), emissive_strength=light,
                          double_sided="Lamp" in double_sided)
    w.add_quads({**room_faces(1.0, 2.0, wall, floor), "Lamp": ((0, 1.99, 0), (0.25, 0, 0), (0, 0, 0.25), lamp)})
    h = box_height / 2
    box = np.array([[x, y, z] for x in (-.3, .3) for y in (0, 2 * h) for z in (-.3, .3)], float)
    import trimesh

    hull = trimesh.convex.convex_hull(box)
    w.add_node("Box", mesh=w.add_mesh("Box", hull.vertices, hull.faces, wall), translation=(0.55, 0.0, 0.55))
    w.add_node("Camera", camera=w.add_camera("Camera", 1.0), translation=(0, 1, 0.9))
    path = Path(path)
    w.write(path)
    if sidecar is not None:
        path.with_name(path.stem + ".glint.toml").write_text(sidecar)
    return path


@pytest.fixture
def room(tmp_path) -> Path:
    return write_room(tmp_path / "room.glb")


FAST = {"quality": "draft", "samples": 8, "texels_per_metre": 6.0, "denoise": False}


@pytest.fixture(scope="module")
def ctx():
    """One headless GL context (EGL; llvmpipe without a GPU) per test module."""
    context = headless_context()
    yield context
    context.release()


# Lines on stderr that a failing command may print before its one error line: warnings, and
# what a bake it started will look like wrong (glint.services.fidelity_line).
NOT_ERRORS = ("glint: warning:", "glint: the scene will look wrong where:")


def error_of(capsys, code):
    """The one line `glint: ...` a failed command printed (exit 2, no traceback)."""
    err = capsys.readouterr().err.strip().splitlines()
    lines = [line for line in err if not line.startswith(NOT_ERRORS)]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("glint: "), err
    assert "Traceback" not in "\n".join(err)
    return lines[0]


def capture_front(scene, size: int, eye, fov: float) -> np.ndarray:
    """Linear RGB of `glint capture` of `scene` from `eye` towards (0, 1, 0) (vertical field of view
    `fov` degrees), size x size, supersample 2, on a small draft bake beside the scene file."""
    from glint.cli import main
    from glint.core.image_io import read_image

    out = Path(scene).with_suffix(".exr")
    assert main(["capture", str(scene), "-o", str(out), "--size", f"{size}x{size}", "--eye",
                 ",".join(map(str, eye)), "--target", "0,1,0", "--fov", str(fov), "-q", "draft", "--samples", "16",
                 "--texels-per-metre", "8", "--no-denoise", "--bake-dir", str(Path(scene).with_suffix(".bake"))]) == 0
    return read_image(out)[..., :3]
