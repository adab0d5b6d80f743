"""The packed G-buffer (shaders/gbuffer_layout.glsl): what the raster pass writes, the shading
passes (gbuffer_read.glsl) and the numpy twin (viewer/passes/gbuffer.py `oct_decode`) read back."""
from __future__ import annotations

import numpy as np

from glint.bench import glsl_eval
from glint.viewer.passes.gbuffer import oct_decode


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles of rows, accurate for small ones too (arccos of a float32 dot product is not)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))


def unit_vectors(n: int = 4000) -> np.ndarray:
    rng = np.random.default_rng(3)
    v = rng.normal(size=(n, 3))
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [1, -1, -1e-7]], float)
    v = np.vstack([axes, v])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_octahedral_normals_round_trip_and_the_numpy_twin_agrees():
    """Unit vectors packed as the G-buffer packs normals (octahedral, 2 x snorm16) come back within
    1e-4 rad; numpy's `oct_decode` of the packed words equals the shader's gb_oct_decode.

    Deliberate bugs this catches (tried): the lower hemisphere's fold without the sign (1.0 -
    abs(n.yx)): 3.14 rad off; the numpy twin reading the halves swapped: differs from the shader."""
    v = unit_vectors()
    out = glsl_eval.evaluate("gbuffer_layout.glsl", "uint word = packSnorm2x16(gb_oct_encode(v));\n"
                             "w = uintBitsToFloat(word);\nd = gb_oct_decode(unpackSnorm2x16(word));",
                             inputs={"v": v}, outputs={"w": 1, "d": 3})
    words = np.ascontiguousarray(out["w"], np.float32).view(np.uint32)
    angle = angle_between(out["d"], v)
    assert angle.max() < 1e-4, angle.max()
    np.testing.assert_allclose(oct_decode(words), out["d"], atol=2e-6)


def test_frame_packing_keeps_flags_strength_and_metallic_roughness():
    """gb_pack_frame's words decoded as gbuffer_read.glsl decodes them: the flags, the tangent's
    length (the anisotropy strength) to 1/65535, its direction to 1e-4 rad, g and M' to 1/65535.

    Deliberate bug this catches (tried): the strength packed into the high half, where the flags
    are: the dark flag set on rows that are not dark."""
    rng = np.random.default_rng(5)
    n = 600
    normal, tangent = unit_vectors(n)[:n], unit_vectors(n)[n // 2: n // 2 + n]
    tangent = tangent[:n] if len(tangent) >= n else np.resize(tangent, (n, 3))
    s = rng.choice([0.0, 0.3, 1.0], n)
    flags = rng.integers(0, 2, (n, 3)).astype(float)
    mr = rng.random((n, 2))
    body = ("uvec4 f = gb_pack_frame(normal, tangent * s, flags.z > 0.5 ? -1.0 : 1.0, flags.x > 0.5, flags.y > 0.5, mr);\n"
            "dark = (f.z & GB_DARK_BIT) != 0u ? 1.0 : 0.0;\n"
            "mapped = (f.z & GB_NORMAL_MAPPED_BIT) != 0u ? 1.0 : 0.0;\n"
            "negative = (f.z & GB_BITANGENT_NEGATIVE_BIT) != 0u ? 1.0 : 0.0;\n"
            "strength = unpackUnorm2x16(f.z & 0xFFFFu).x;\n"
            "direction = gb_oct_decode(unpackSnorm2x16(f.y));\n"
            "out_mr = unpackUnorm2x16(f.w);")
    out = glsl_eval.evaluate("gbuffer_layout.glsl", body,
                             inputs={"normal": normal, "tangent": tangent, "s": s, "flags": flags, "mr": mr},
                             outputs={"dark": 1, "mapped": 1, "negative": 1, "strength": 1, "direction": 3, "out_mr": 2})
    np.testing.assert_array_equal(out["dark"], flags[:, 0])
    np.testing.assert_array_equal(out["mapped"], flags[:, 1])
    np.testing.assert_array_equal(out["negative"], flags[:, 2])
    np.testing.assert_allclose(out["strength"], s, atol=1.0 / 65535)
    has = s > 0
    angle = angle_between(out["direction"][has], tangent[has])
    assert angle.max() < 1e-4
    np.testing.assert_allclose(out["out_mr"], mr, atol=1.0 / 65535)
