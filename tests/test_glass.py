"""Glass solids (KHR_materials_transmission + KHR_materials_volume, core/volume.py): the bake lets
light through both interfaces with the absorption inside; the viewer shows a closed glass bottle
clear, as Mitsuba 3's two-interface `dielectric` does."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import trimesh

from glint.bake.gltf_loader import load_scene
from glint.bake.irradiance import compute_irradiance
from glint.bake.raytrace import RayTracer
from glint.scenes.gltf_writer import GltfWriter

IOR = 1.5


def glass_extensions(thickness: float, attenuation_distance: float | None = None, color=(1, 1, 1)) -> dict:
    volume = {"thicknessFactor": thickness}
    if attenuation_distance is not None:
        volume.update(attenuationDistance=attenuation_distance, attenuationColor=list(color))
    return {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": IOR},
            "KHR_materials_volume": volume}


def write_pane(path: Path, *, thickness: float, sun_deg: float, color) -> Path:
    """A 1.6 x 1.6 m glass slab `thickness` thick, 1 m above a black floor, under a sun `sun_deg`
    from the zenith (towards +x) of 1 W/m^2 (683 lux); attenuationDistance = thickness. The floor is
    black so that no light it reflects comes back off the pane's reflection lobe (the bake's paths
    scatter by it): the floor's irradiance is then the sun's through the slab alone."""
    w = GltfWriter()
    floor = w.add_material("Floor", base_color=(0.0, 0.0, 0.0), roughness=1.0)
    glass = w.add_material("Glass", base_color=(1, 1, 1), roughness=0.0,
                           extensions=glass_extensions(thickness, thickness, color))
    w.add_quads({"Floor": ((0, 0, 0), (2, 0, 0), (0, 0, -2), floor)}, normals=True)
    box = trimesh.creation.box((1.6, thickness, 1.6))
    w.add_node("Pane", mesh=w.add_mesh("Pane", box.vertices, box.faces, glass), translation=(0, 1, 0))
    a = math.radians(sun_deg)
    turn = trimesh.geometry.align_vectors([0, 0, -1], [math.sin(a), -math.cos(a), 0])  # lights shine along -Z
    q = trimesh.transformations.quaternion_from_matrix(turn)
    w.add_node("Sun", light=w.add_light("Sun", "directional", intensity=683.0), rotation=[*q[1:], q[0]])
    w.write(path)
    return path


def test_bake_through_solid_glass_pane_matches_slab_formula(tmp_path):
    """Irradiance on the floor in the pane's shadow, lit through a 2 cm solid-glass pane (ior 1.5,
    attenuationColor (0.5, 0.7, 0.9) at attenuationDistance 2 cm) by a sun 40 degrees from the
    zenith, against the analytic slab: E = cos(40) (1 - F)^2 a / (1 - F^2 a^2), F the exact Fresnel
    reflectance at 40 degrees, a = attenuationColor^(1 / cos theta_t) the absorption along the
    refracted path. Bound 1 % per channel (measured 0.03 / 0.09 / 0.16 %: the slab's internal
    reflections, which the bake leaves out).

    Deliberate bugs this catches (tried): the volume read as a thin surface (as before: two
    Schlick interfaces, no absorption) gives 0.705 in every channel against 0.324 / 0.471 / 0.622
    (+118 % in red); the absorption over the straight distance the ray crossed (h.t, without the
    slab's c / cos_t) gives red 0.282 (-12.9 %); the absorption applied at the entry face too (over
    the 1.3 m from the floor) gives 0: the room behind the pane goes dark."""
    color = np.array([0.5, 0.7, 0.9])
    scene = load_scene(write_pane(tmp_path / "pane.glb", thickness=0.02, sun_deg=40.0, color=color))
    glass = next(m for m in scene.materials if m.name == "Glass")
    assert glass.has_volume and glass.ior == IOR and glass.thickness == 0.02
    # floor points whose ray to the sun (40 deg towards -x) crosses the pane's top and bottom faces
    points = np.array([[x, 0.0, z] for x in (0.5, 0.85, 1.2) for z in (-0.4, 0.3)])
    result = compute_irradiance(scene, RayTracer(scene), points, np.tile([0.0, 1.0, 0.0], (len(points), 1)), 16)

    c = math.cos(math.radians(40.0))
    ct = math.sqrt(1.0 - (1.0 - c * c) / IOR ** 2)  # Snell
    F = 0.5 * (((c - IOR * ct) / (c + IOR * ct)) ** 2 + ((IOR * c - ct) / (IOR * c + ct)) ** 2)  # s, p
    a = color ** (1.0 / ct)  # attenuationColor per attenuationDistance (= thickness), along the refracted path
    expected = c * (1 - F) ** 2 * a / (1 - F * F * a * a)
    error = np.abs(result.irradiance / expected - 1.0)
    print("irradiance", result.irradiance.mean(axis=0), "analytic", expected, "error", error.max(axis=0))
    assert error.max() <= 0.01


EYE, TARGET, FOV, SIZE = (0.0, 0.25, 0.8), (0.0, 0.2, 0.0), 30.0, 64
WALL = 0.004


def bottle_mesh(wall: float, sections: int = 48) -> trimesh.Trimesh:
    """A sealed glass bottle 42 cm tall, 20 cm across, walls `wall` thick: the body of revolution of
    its outer profile (r, y) and, inside it, the cavity's (faces turned into the cavity)."""
    outer = [(0.0, 0.0), (0.09, 0.0), (0.1, 0.01), (0.1, 0.22), (0.085, 0.27), (0.045, 0.31), (0.032, 0.34),
             (0.032, 0.42), (0.0, 0.42)]
    inner = [(0.0, 0.42 - wall), (0.032 - wall, 0.42 - wall), (0.032 - wall, 0.34), (0.045 - wall, 0.31),
             (0.085 - wall, 0.27), (0.1 - wall, 0.22), (0.1 - wall, 0.01 + wall), (0.09 - wall, wall), (0.0, wall)]
    profile = np.array(outer + inner + outer[:1])
    mesh = trimesh.creation.revolve(profile, sections=sections)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))  # profile y -> +Y
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def write_bottle(path: Path) -> Path:
    """The bottle (ior 1.5, clear, thicknessFactor = its wall) on a grey floor before a backdrop of
    orange and blue stripes 5 cm wide, 35 cm behind it, under a constant sky of radiance 1."""
    from glint.scenes.gltf_writer import quad

    w = GltfWriter()
    floor = w.add_material("Floor", base_color=(0.6, 0.6, 0.6), roughness=1.0)
    stripes = np.zeros((4, 64, 3), np.uint8)
    stripes[:, (np.arange(64) // 8) % 2 == 0] = (230, 120, 30)
    stripes[:, (np.arange(64) // 8) % 2 == 1] = (40, 90, 200)
    back = w.add_material("Backdrop", base_color=(1, 1, 1), roughness=1.0, base_color_texture=stripes)
    glass = w.add_material("Glass", base_color=(1, 1, 1), roughness=0.0, extensions=glass_extensions(WALL))
    w.add_quads({"Floor": ((0, 0, 0), (1.0, 0, 0), (0, 0, -1.0), floor)}, normals=True)
    positions, indices = quad((0, 0.5, -0.35), (0.6, 0, 0), (0, 0.5, 0))
    uvs = np.stack([(positions[:, 0] + 0.6) / 1.2 * 3, 1 - positions[:, 1]], axis=1)
    w.add_node("Backdrop", mesh=w.add_mesh("Backdrop", positions, indices, back,
                                           normals=np.tile([0, 0, 1.0], (4, 1)), uvs=uvs))
    m = bottle_mesh(WALL)
    w.add_node("Bottle", mesh=w.add_mesh("Bottle", m.vertices, m.faces, glass, normals=m.vertex_normals))
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text("[sky]\nradiance = 1.0\n")
    return path


def bottle_pixels(scene, sub: int = 4) -> np.ndarray:
    """(SIZE, SIZE) bool: pixels all of whose sub x sub rays meet the bottle first (Embree), eroded by one."""
    from scipy import ndimage

    eye, target = np.array(EYE), np.array(TARGET)
    f = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(f, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    t = math.tan(math.radians(FOV) / 2)
    s = (np.arange(SIZE * sub) + 0.5) / (SIZE * sub) * 2 - 1
    x, y = np.meshgrid(s, -s)
    d = (f + x[..., None] * t * right + y[..., None] * t * up).reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1)[:, None]
    hits = RayTracer(scene).intersect(np.tile(eye, (len(d), 1)), d)
    bottle = [o.name for o in scene.objects].index("Bottle")
    ids = np.where(hits.prim >= 0, hits.object, -1).reshape(SIZE, sub, SIZE, sub).transpose(0, 2, 1, 3)
    return ndimage.binary_erosion(np.all(ids.reshape(SIZE, SIZE, -1) == bottle, axis=-1))


def test_glass_bottle_against_mitsuba(tmp_path):
    """The thin-walled bottle, `glint capture --converge 8` at 64 x 64 against Mitsuba 3 (the scene
    through bench/mitsuba_scene.py: the glass as its two-interface `dielectric`, 32 spp): the mean
    luminance over the bottle's pixels. Measured ratio glint / Mitsuba: 0.50 -- glint's bottle is
    still too dark (docs/SCENES.md, "Glass solids": the reflections of the three inner interfaces
    and ~20 % of the transmitted light are missing); the bound, 0.4, holds that and fails an opaque
    bottle.

    Deliberate bug this catches (tried): no transmission through the volume (volume.glsl's weight
    0: only the outer reflection) gives 0.074."""
    import mitsuba as mi

    from glint.bench import mitsuba_scene
    from glint.cli import main
    from glint.core.image_io import read_image
    from glint.viewer.camera import ViewCamera

    path = write_bottle(tmp_path / "bottle.glb")
    out = tmp_path / "bottle.exr"
    assert main(["capture", str(path), "-o", str(out), "--size", f"{SIZE}x{SIZE}", "--eye", ",".join(map(str, EYE)),
                 "--target", ",".join(map(str, TARGET)), "--fov", str(FOV), "-q", "draft", "--samples", "32",
                 "--texels-per-metre", "32", "--converge", "8", "--bake-dir", str(tmp_path / "bottle.bake")]) == 0
    image = read_image(out)[..., :3].astype(np.float64)

    mi.set_variant("scalar_rgb")
    scene = load_scene(path)
    eye = np.array(EYE)
    forward = (np.array(TARGET) - eye) / np.linalg.norm(np.array(TARGET) - eye)
    camera = ViewCamera(eye=eye, forward=forward, up=np.array([0.0, 1.0, 0.0]), yfov=math.radians(FOV),
                        znear=0.01, zfar=100.0)
    scene_dict, _ = mitsuba_scene.convert(scene, [mitsuba_scene.sensor_dict(camera, SIZE, SIZE, spp=32)])
    glass = next(m for m in scene.materials if m.name == "Glass")
    assert mitsuba_scene.bsdf_dict(glass)["type"] == "dielectric" and glass.ior == IOR
    reference = mitsuba_scene.render(mi.load_dict(scene_dict)).astype(np.float64)

    mask = bottle_pixels(scene)
    assert mask.sum() >= 800
    lum = np.array([0.2126, 0.7152, 0.0722])
    ratio = float((image[mask] @ lum).mean() / (reference[mask] @ lum).mean())
    print(f"bottle: {mask.sum()} px, mean luminance glint / Mitsuba {ratio:.3f}")
    assert ratio >= 0.4
