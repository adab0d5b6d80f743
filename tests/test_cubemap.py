"""bake/cubemap.py: per-object cube maps (section 4.4.1), baked through `glint bake`'s pipeline.

Expected values are independent of the code under test: the texture look-up is the OpenGL
specification's face-selection rule (table 8.19) written out here in numpy, colours are the
emissions put into the scene (walls of kd = 0: radiance = emission exactly), distances come
from ray-plane and ray-box intersections, and face sizes from the rule's numbers by hand.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from conftest import FAST, quad, write_room

from glint.scenes.generate import LAMBERT  # a Lambertian glTF material: the tests' expected kd is the base colour
from glint import services
from glint.bake import pipeline
from glint.bake.cubemap import SKY_DISTANCE, automatic_size
from glint.bake.gltf_loader import load_scene
from glint.bake.settings import resolve_settings
from glint.core.bsdf import M_MIN
from glint.core.errors import GlintError
from glint.core.image_io import HALF_MAX, read_image
from glint.core.scene import Lobe, Material, Object
from glint.scenes.gltf_writer import GltfWriter
from glint.services import bake_scene

# An open-topped 2 x 2 x 2 m box of emissive walls (kd = 0), lit by nothing else, with two
# curved boxes (emissive too, with a lobe) floating inside; a constant sky above.
WALLS = {  # name: (centre, u, v, emission); the quads face into the room
    "Floor": ((0, 0, 0), (1, 0, 0), (0, 0, -1), (0.2, 0.2, 0.2)),
    "Back": ((0, 1, -1), (1, 0, 0), (0, 1, 0), (1.0, 0.0, 0.0)),
    "Front": ((0, 1, 1), (-1, 0, 0), (0, 1, 0), (0.0, 1.0, 0.0)),
    "Left": ((-1, 1, 0), (0, 0, -1), (0, 1, 0), (0.0, 0.0, 1.0)),
    "Right": ((1, 1, 0), (0, 0, 1), (0, 1, 0), (1.0, 1.0, 0.0)),
}
SKY = (0.25, 0.5, 0.75)
BOXES = {  # name: (centre, half extents, emission)
    "A": ((0.3, 0.8, -0.2), (0.1, 0.1, 0.1), (0.0, 1.0, 1.0)),
    "B": ((-0.4, 0.6, 0.35), (0.15, 0.1, 0.1), (1.0, 0.0, 1.0)),
}
LOBE = {"kind": "reflect", "ks": [1, 1, 1], "mx": 0.05, "my": 0.05, "r0": 0.04}


def write_box_room(path, sidecar="", lobes=None):
    w = GltfWriter()
    for name, (c, u, v, e) in WALLS.items():
        m = w.add_material(name, base_color=(0, 0, 0), emissive=e, extensions=LAMBERT)
        p, i = quad(c, u, v)
        w.add_node(name, mesh=w.add_mesh(name, p, i, m, normals=np.tile(np.cross(u, v), (4, 1))))
    for name, (c, half, e) in BOXES.items():
        m = w.add_material(f"Mat{name}", base_color=(0, 0, 0), emissive=e, extensions=LAMBERT,
                           extras={"glint": {"lobes": [(lobes or {}).get(name, LOBE)]}})
        box = trimesh.creation.box(extents=2 * np.array(half))
        w.add_node(name, mesh=w.add_mesh(name, box.vertices, box.faces, m, normals=box.vertex_normals),
                   translation=c)
    path.parent.mkdir(parents=True, exist_ok=True)
    w.write(path)
    path.with_name(path.stem + ".glint.toml").write_text(f"[sky]\nradiance = {list(SKY)}\n" + sidecar)
    return path


def bake(path, out, **overrides):
    scene = load_scene(path)
    return bake_scene(scene, resolve_settings(scene.bake_settings, **{**FAST, **overrides}), out, progress=False)


def cube_faces(out, entry):
    image = read_image(out / entry["file"])
    size = entry["size"]
    assert image.shape == (6 * size, size, 4)
    return image.reshape(6, size, size, 4)


# -- the OpenGL rule, written out from the specification -------------------------------------------
def gl_face_coordinates(d):
    """texture(samplerCube, d): face index (+X, -X, +Y, -Y, +Z, -Z) and (s, t) in [0, 1]."""
    x, y, z = d.T
    ax, ay, az = np.abs(d).T
    face = np.where((ax >= ay) & (ax >= az), np.where(x > 0, 0, 1),
                    np.where(ay >= az, np.where(y > 0, 2, 3), np.where(z > 0, 4, 5)))
    sc = np.choose(face, [-z, z, x, x, x, -x])
    tc = np.choose(face, [-y, -y, z, -z, -y, -y])
    ma = np.choose(face, [ax, ax, ay, ay, az, az])
    return face, (sc / ma + 1) / 2, (tc / ma + 1) / 2


def gl_direction(face, s, t):
    """The inverse: the direction through (s, t) of a face."""
    sc, tc = 2 * s - 1, 2 * t - 1
    one = np.ones_like(sc)
    d = np.choose(face[:, None], [np.stack(v, -1) for v in (
        (one, -tc, -sc), (-one, -tc, sc), (sc, one, tc), (sc, -one, -tc), (sc, -tc, one), (-sc, -tc, -one))])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def first_hit(origin, d, hidden):
    """(surface name or "sky", distance) along unit rays d from origin: the room's walls (the
    floor included) and the boxes not in `hidden`, by ray-plane and slab intersections."""
    best = np.full(len(d), np.inf)
    name = np.full(len(d), "sky", dtype=object)
    planes = {"Floor": (1, 0.0), "Back": (2, -1.0), "Front": (2, 1.0), "Left": (0, -1.0), "Right": (0, 1.0)}
    for wall, (axis, at) in planes.items():
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (at - origin[axis]) / d[:, axis]
            p = origin + t[:, None] * d
        inside = (t > 0) & np.all(np.abs(p[:, [0, 2]]) <= 1 + 1e-9, axis=1) & (p[:, 1] <= 2) & (p[:, 1] >= -1e-9)
        closer = inside & (t < best)
        best[closer], name[closer] = t[closer], wall
    for box, (c, half, _) in BOXES.items():
        if box in hidden:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (np.asarray(c) - half - origin) / d
            t2 = (np.asarray(c) + half - origin) / d
        near, far = np.minimum(t1, t2).max(axis=1), np.maximum(t1, t2).min(axis=1)
        closer = (near <= far) & (near > 0) & (near < best)
        best[closer], name[closer] = near[closer], box
    return name, best


@pytest.fixture(scope="module")
def box_room_bake(tmp_path_factory):
    root = tmp_path_factory.mktemp("cubes")
    path = write_box_room(root / "room.glb", '[objects."A"]\ncubemap_size = 64\n')
    report = bake(path, root / "room.bake")
    return root / "room.bake", report.manifest


@pytest.mark.parametrize("name", ["A", "B"])
def test_faces_follow_the_gl_convention_with_colour_and_distance(box_room_bake, name):
    """Each direction's texel, found by the GL face rule, shows the surface the ray from the
    centre meets first, in its colour, with the analytic distance in alpha; the object itself
    is absent, the other box present, the sky (open top) at SKY_DISTANCE."""
    check_faces(*box_room_bake, name, ((0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)))


def test_large_faces_take_one_sample_per_texel(tmp_path):
    """A face over SUPERSAMPLED_FACE_MAX (B's, 512) is rendered at one sample per texel: the same
    colours and the distance at the texel's centre (bake/cubemap.py `supersample`). Deliberate bug
    tried: the renderer left at 2 x 2 samples for it (glint/cubemap_stage.py not setting
    `renderer.supersample`): 36.9 % of the checked distances off by more than 0.15 %."""
    path = write_box_room(tmp_path / "room.glb", '[objects."B"]\ncubemap_size = 512\n')
    report = bake(path, tmp_path / "room.bake")
    check_faces(tmp_path / "room.bake", report.manifest, "B", ((0.5, 0.5),))


def check_faces(out, manifest, name, samples):
    """The texel checks of the test above; `samples`: the (s, t) offsets within a texel that the
    stage renders, whose mean distance the texel holds."""
    entry = next(o for o in manifest["objects"] if o["name"] == name)["cubemap"]
    faces = cube_faces(out, entry)
    size = entry["size"]
    centre = np.array(BOXES[name][0])
    np.testing.assert_allclose(entry["centre"], centre, atol=1e-6)

    d = np.random.default_rng(1).normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    face, s, t = gl_face_coordinates(d)
    i, j = np.clip((s * size).astype(int), 0, size - 1), np.clip((t * size).astype(int), 0, size - 1)
    texel = faces[face, j, i]
    # The texel's centre, corners and 2 x 2 supersamples: keep texels that see one surface
    # throughout; the expected distance is the mean over the supersamples (module docstring).
    hit, _ = first_hit(centre, gl_direction(face, (i + 0.5) / size, (j + 0.5) / size), hidden={name})
    same = np.ones(len(d), bool)
    for ds, dt in ((0, 0), (1, 0), (0, 1), (1, 1)):
        corner, _ = first_hit(centre, gl_direction(face, (i + ds) / size, (j + dt) / size), hidden={name})
        same &= corner == hit
    distance = np.zeros(len(d))
    for ds, dt in samples:
        sub, along = first_hit(centre, gl_direction(face, (i + ds) / size, (j + dt) / size), hidden={name})
        same &= sub == hit
        distance += along / len(samples)
    assert same.mean() > 0.8

    colours = {**{k: v[3] for k, v in WALLS.items()}, **{k: v[2] for k, v in BOXES.items()}, "sky": SKY}
    expected = np.array([colours[h] for h in hit])
    np.testing.assert_allclose(texel[same, :3], expected[same], rtol=2e-3, atol=2e-3)
    seen = {h for h in hit[same]}
    assert name not in seen and seen >= {"Floor", "Back", "Front", "Left", "Right", "sky"}
    assert ({"A", "B"} - {name}) <= seen  # the other box is in this map

    surface = same & (hit != "sky")
    np.testing.assert_allclose(texel[surface, 3], distance[surface], rtol=1.5e-3)
    np.testing.assert_array_equal(texel[same & (hit == "sky"), 3], SKY_DISTANCE)


def test_manifest_entries_and_file_format(box_room_bake):
    out, manifest = box_room_bake
    on_disk = json.loads((out / "manifest.json").read_text())
    cubes = {o["name"]: o["cubemap"] for o in on_disk["objects"]}
    assert {k for k, v in cubes.items() if v} == {"A", "B"}  # walls and floor are diffuse: none
    assert cubes["A"]["file"] == f"cubemaps/{[o['name'] for o in on_disk['objects']].index('A')}.exr"
    assert cubes["A"]["size"] == 64  # the sidecar's cubemap_size
    # B: m = 0.05 -> theta_thresh = atan(sqrt(ln 100) 0.05) = 0.107 rad, pi / 0.107 = 29.4 -> 32;
    # its size needs 400 x 0.41 m = 165 -> the lobe decides
    assert cubes["B"]["size"] == 32
    assert sorted(p.name for p in (out / "cubemaps").iterdir()) == sorted(
        v["file"].split("/")[1] for v in cubes.values() if v)
    assert set(on_disk["stages"]["cubemaps"]) == {v["file"].split("/")[1][:-4] for v in cubes.values() if v}
    stats = on_disk["statistics"]["cubemaps"]
    assert stats["count"] == 2 and stats["rendered"] == 2 and stats["seconds"] > 0
    import OpenImageIO as oiio

    spec = oiio.ImageInput.open(str(out / cubes["A"]["file"])).spec()
    assert spec.format == oiio.HALF and list(spec.channelnames) == ["R", "G", "B", "A"]


def test_diffuse_and_planar_objects_get_no_cube_map(tmp_path, monkeypatch):
    """The conftest room with a glossy floor: the floor is planar, the rest diffuse."""
    path = write_room(tmp_path / "room.glb", floor_lobes=[LOBE])

    def no_render(*a, **k):
        raise AssertionError("no cube map to render")

    monkeypatch.setattr(services, "render_cubemaps", no_render)
    out = tmp_path / "room.bake"
    report = bake(path, out)
    roles = {o["name"]: o["role"] for o in report.manifest["objects"]}
    assert roles["Floor"] == "planar" and set(roles.values()) == {"planar", "diffuse"}
    assert all(o["cubemap"] is None for o in report.manifest["objects"])
    assert report.manifest["stages"]["cubemaps"] == {}
    assert report.manifest["statistics"]["cubemaps"]["count"] == 0
    assert not (out / "cubemaps").exists()


def test_very_bright_emitter_gives_float_file_without_inf(tmp_path):
    """A 1e5 W/(m^2 sr) lamp: the map is written in float32 (1e5 > 65504), finite, and the
    lamp's direction shows its radiance."""
    path = write_room(tmp_path / "room.glb", light=1e5, sidecar='[objects."Box"]\nrole = "curved"\n')
    out = tmp_path / "room.bake"
    report = bake(path, out)
    entry = next(o for o in report.manifest["objects"] if o["name"] == "Box")["cubemap"]
    faces = cube_faces(out, entry)
    assert np.all(np.isfinite(faces))
    import OpenImageIO as oiio

    assert oiio.ImageInput.open(str(out / entry["file"])).spec().format == oiio.FLOAT
    to_lamp = np.array([0.0, 1.99, 0.0]) - np.array(entry["centre"])
    face, s, t = gl_face_coordinates((to_lamp / np.linalg.norm(to_lamp))[None])
    size = entry["size"]
    radiance = faces[face[0], int(t[0] * size), int(s[0] * size), :3]
    assert np.all(radiance >= 1e5) and np.all(radiance < 1.1e5)  # emission + kd/pi E of the lamp
    assert faces[..., :3].max() > HALF_MAX


def test_rebake_renders_only_the_cube_maps_whose_inputs_changed(tmp_path, monkeypatch):
    path = write_box_room(tmp_path / "room.glb")
    out = tmp_path / "room.bake"
    first = bake(path, out)
    index = {o["name"]: i for i, o in enumerate(first.manifest["objects"])}
    files = {n: out / f"cubemaps/{index[n]}.exr" for n in ("A", "B")}
    before = {n: (f.read_bytes(), f.stat().st_mtime_ns) for n, f in files.items()}

    rendered = []
    real = services.render_cubemaps

    def recording(bake_dir, plans, progress=None, workers=1, cluster=None):
        rendered.extend(p.name for p in plans)
        return real(bake_dir, plans, progress, workers, cluster)

    def no_lightmaps(*a, **k):
        raise AssertionError("light maps were re-baked")

    monkeypatch.setattr(services, "render_cubemaps", recording)
    monkeypatch.setattr(pipeline, "_bake_geometry_and_lightmaps", no_lightmaps)
    assert bake(path, out).status == "up-to-date" and rendered == []

    # A's face size is set to 256 (sidecar; a lobe edit would re-bake the light maps, whose light the
    # bake's paths now carry off the lobes, and so every cube map): A only is rendered
    write_box_room(path, sidecar='[objects."A"]\ncubemap_size = 256\n')
    report = bake(path, out)
    assert report.status == "cubemaps" and rendered == ["A"]
    assert next(o for o in report.manifest["objects"] if o["name"] == "A")["cubemap"]["size"] == 256
    assert (files["B"].read_bytes(), files["B"].stat().st_mtime_ns) == before["B"]
    assert files["A"].read_bytes() != before["A"][0]

    # B's bounding planes change (not an input of its pixels): manifest only
    rendered.clear()
    write_box_room(path, sidecar='[objects."A"]\ncubemap_size = 256\n[objects."B"]\nbounding_planes = false\n')
    assert bake(path, out).status == "manifest" and rendered == []
    assert (files["B"].read_bytes(), files["B"].stat().st_mtime_ns) == before["B"]


def test_automatic_size_rule():
    """S = next power of two of min(pi / theta_thresh, 400 x diagonal), clamped to [32, 512]."""
    def obj(half):
        p = np.array([[-half, -half, -half], [half, half, half]], float)
        return Object("o", p, np.zeros((2, 3), np.float32), np.zeros((0, 3), np.int64), 0)

    def mat(*ms):
        return Material("m", lobes=[Lobe("reflect", mx=a, my=b) for a, b in ms])

    big, small = obj(1.0), obj(0.05)  # diagonals 3.46 m and 0.173 m
    # m = 0.03: theta = atan(2.146 x 0.03) = 0.0643 -> pi / theta = 48.9 -> 64
    assert automatic_size(big, mat((0.03, 0.03))) == 64
    # the narrowest lobe and the narrower axis count: my = 0.01 -> theta = 0.02146 -> 146 -> 256
    assert automatic_size(big, mat((0.3, 0.3), (0.5, 0.01))) == 256
    # a mirror is limited by the object's size: 400 x 0.173 = 69 -> 128; a big one by the clamp
    assert automatic_size(small, mat((M_MIN, M_MIN))) == 128
    assert automatic_size(big, mat((0.0, 0.0))) == 512
    # a broad lobe: m = 0.5 -> theta = 0.821 -> 3.8 -> the minimum, 32
    assert automatic_size(big, mat((0.5, 0.5))) == 32
    # a curved role without lobes (sidecar): the size rule alone
    assert automatic_size(small, mat()) == 128


@pytest.mark.parametrize("value, words", [("100", "power of two"), ("2", "from 4"), ('"big"', "power of two"),
                                          ("8192", "to 4096")])
def test_bad_cubemap_size_is_a_clear_error(tmp_path, value, words):
    path = write_box_room(tmp_path / "room.glb", f'[objects."A"]\ncubemap_size = {value}\n')
    with pytest.raises(GlintError, match=words):
        load_scene(path)


@pytest.mark.parametrize("light", [8.0, 1e5])
def test_the_viewers_cube_map_arrays_hold_the_files_texels(tmp_path, light):
    """Level 0 of the viewer's cube-map array (read back from GL) holds the probe's file texel for
    texel: a half-float file (light 8) in an RGBA16F class, read as half floats without a float32
    copy; a float32 file (light 1e5 > 65504) in an RGBA32F class. The expected texels are the file's,
    read by OpenImageIO directly; each coarser level the 2 x 2 box mean of the one above. Catches a
    class made half float for a value above 65504 (Inf on the GPU), a half-float file read through
    the wrong type, faces or layers out of place when the class is filled, and a MIP level made from
    the wrong level or texels (shaders/cube_mips.comp)."""
    import OpenImageIO as oiio

    from glint.core.bake_dir import Bake
    from glint.viewer.context import headless_context
    from glint.viewer.cubemaps import CubeMaps
    from glint.viewer.gl import GL

    path = write_room(tmp_path / "room.glb", light=light, sidecar='[objects."Box"]\nrole = "curved"\n')
    out = tmp_path / "room.bake"
    entry = next(o for o in bake(path, out).manifest["objects"] if o["name"] == "Box")["cubemap"]
    file = oiio.ImageInput.open(str(out / entry["file"]))
    half = file.spec().format == oiio.HALF
    assert half == (light < 1e4)
    texels = np.asarray(file.read_image("float"), np.float32)
    file.close()
    size = entry["size"]
    expected = np.ones((6, size, size, 4), np.float32)
    expected[..., :texels.shape[-1]] = texels.reshape(6, size, size, -1)

    ctx = headless_context()
    try:
        cubes = CubeMaps(ctx, Bake(out))
        (cls,) = cubes.classes
        assert cls.dtype == ("f2" if half else "f4") and cls.size == size
        level0 = GL(ctx).read_cube_array(cls.glo, 0, np.empty((1, 6, size, size, 4), np.float32), "the probe")
        np.testing.assert_array_equal(level0[0], expected)
        assert np.isfinite(level0).all()
        # Every coarser level is the 2 x 2 box mean of the level above as the GPU holds it (float64
        # here), within an ulp of the class's format (GL rounds to nearest or towards zero).
        finer = level0[0].astype(np.float64)
        for level in range(1, cls.levels):
            s = size >> level
            got = GL(ctx).read_cube_array(cls.glo, level, np.empty((1, 6, s, s, 4), np.float32), "a level")[0]
            want = finer.reshape(6, s, 2, s, 2, 4).mean(axis=(2, 4))
            relative = 1.01 * 2.0 ** -10 if half else 4 * 2.0 ** -24  # GL may round to half by truncation
            assert np.all(np.abs(got - want) <= relative * np.abs(want) + 2.0 ** -25), f"level {level}"
            finer = got.astype(np.float64)
        assert level == int(np.log2(size)) and got.shape[1] == 1
        cubes.release()
    finally:
        ctx.release()
