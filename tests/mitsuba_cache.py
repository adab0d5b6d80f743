"""Cached Mitsuba 3 references of the slow comparison tests (tests/data/mitsuba/NAME.npz).

A cached reference is the Mitsuba render that the test makes, saved as data: the same function
renders it, with the same inputs, so the reference stays independent of the code under test.
Stored with it is a key, the SHA-256 of everything that determines the render:

- the inputs the test hands to Mitsuba: the glint Scene that bench/mitsuba_scene.py converts (its
  objects, materials, lights and sky, every array bit for bit: what the test's glTF writer and the
  loader made of it), the sensor (camera, resolution, spp, seed), the points and normals of an
  irradiance reference, ...;
- the source text of the code that builds and renders the Mitsuba scene: the converter and the
  plugins (`converter()`, bench/mitsuba_reference.py where used), the constants of core/bsdf.py and
  bake/lights.py that the section 3.3 plugin reads, and the test's own reference function;
- the Mitsuba variant and the versions of Mitsuba and Dr.Jit.

A test whose key does not match the file (or without a file) renders with Mitsuba as before and
warns (StaleMitsubaReference: pytest's warnings summary) that the cache is stale, naming the command
that refreshes it (REFRESH). GLINT_MITSUBA_CACHE: unset, the cache is read when its key matches;
"render", it is ignored (every reference rendered, as if stale); "write", every reference is
rendered and written (what REFRESH runs). tests/data/README.md has the paragraph for users.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.metadata
import inspect
import json
import os
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parent / "data" / "mitsuba"
ENV = "GLINT_MITSUBA_CACHE"
REFRESH = "python3 tests/data/make_mitsuba_cache.py"
# The tests that read this cache (what REFRESH runs, with GLINT_MITSUBA_CACHE=write).
CACHED_TESTS = (
    "tests/test_glossy_vs_mitsuba.py::test_glossy_ball_matches_mitsuba",
    "tests/test_glossy_vs_mitsuba.py::test_glossy_floor_matches_mitsuba",
    "tests/test_roughness_texture.py::test_roughness_striped_metal_floor_matches_mitsuba",
    "tests/test_normal_map.py::test_normal_mapped_floor_matches_mitsuba",
    "tests/test_glass.py::test_glass_bottle_against_mitsuba",
    "tests/test_glass.py::test_solid_glass_sphere_against_mitsuba",
    "tests/test_bake_glossy_transport.py::test_metal_floor_room_irradiance_matches_mitsuba",
)
# What a glint Scene contributes to the Mitsuba scene (bench/mitsuba_scene.py `convert` reads these).
SCENE_FIELDS = ("objects", "materials", "point_lights", "spot_lights", "directional_lights", "sky")


class StaleMitsubaReference(UserWarning):
    """A cached reference did not match its test's Mitsuba inputs: the test rendered it."""


def converter():
    """The modules whose source determines a converted scene's render (bench/mitsuba_scene.py's
    `convert`, its plugins, the tangent frames its meshes carry)."""
    from glint.bench import mitsuba_bsdf, mitsuba_gltf_bsdf, mitsuba_scene
    from glint.viewer import tangent_frames

    return (mitsuba_scene, mitsuba_bsdf, mitsuba_gltf_bsdf, tangent_frames)


def converter_constants() -> dict:
    """The constants of other modules that the plugins read: core/bsdf.py's numerical guards
    (`ref.*` in bench/mitsuba_bsdf.py) and bake/lights.py's luminance weights (the plugin's
    sampling probabilities)."""
    from glint.bake import lights
    from glint.core import bsdf

    guards = {k: v for k, v in vars(bsdf).items() if k.isupper() and isinstance(v, (int, float))}
    return {"core.bsdf": guards, "bake.lights.LUMA": np.asarray(lights.LUMA)}


@functools.cache
def auto_variant() -> str:
    """The variant bench/mitsuba.py's choose_variant("auto") picks here (probed once per process:
    the choice depends on the machine, not on what ran before)."""
    from glint.bench.mitsuba import choose_variant

    return choose_variant("auto")["variant"]


def _feed(h, x) -> None:
    """x into the hash h, canonically (types, shapes and every bit of arrays)."""
    from glint.core.scene import Scene, Sky

    if x is None or isinstance(x, (bool, int, str)):
        h.update(f"{type(x).__name__}:{x!r};".encode())
    elif isinstance(x, float):
        h.update(f"float:{x!r};".encode())  # repr round-trips: every bit
    elif isinstance(x, np.generic):
        h.update(f"np.{x.dtype.str}:".encode())
        _feed(h, x.item())
    elif isinstance(x, np.ndarray):
        if x.dtype == object:
            _feed(h, x.tolist())
            return
        a = np.ascontiguousarray(x)
        h.update(f"array:{a.dtype.str}:{a.shape}:".encode())
        h.update(a.tobytes())
    elif isinstance(x, (list, tuple)):
        h.update(f"{type(x).__name__}:{len(x)}[".encode())
        for v in x:
            _feed(h, v)
        h.update(b"]")
    elif isinstance(x, dict):
        h.update(f"dict:{len(x)}{{".encode())
        for k in sorted(x, key=str):
            _feed(h, str(k))
            _feed(h, x[k])
        h.update(b"}")
    elif isinstance(x, Scene):  # what the converter reads, not its file names
        _feed(h, {name: getattr(x, name) for name in SCENE_FIELDS})
    elif isinstance(x, Sky):
        _feed(h, {"radiance": x.radiance, "map": x.map})
    elif dataclasses.is_dataclass(x) and not isinstance(x, type):
        h.update(f"{type(x).__name__}(".encode())
        _feed(h, {f.name: getattr(x, f.name) for f in dataclasses.fields(x)})
        h.update(b")")
    elif type(x).__module__.startswith("mitsuba") and type(x).__name__.endswith("Transform4f"):
        h.update(b"transform:")  # mi.ScalarTransform4f (its class name depends on the variant)
        _feed(h, np.array(x.matrix, np.float64))
    elif inspect.ismodule(x) or inspect.isfunction(x) or inspect.isclass(x):
        _feed(h, f"{x.__module__ if not inspect.ismodule(x) else ''}:{x.__name__}")
        _feed(h, inspect.getsource(x))
    else:
        raise TypeError(f"mitsuba_cache: no canonical form for {type(x).__name__} (add one)")


def key(variant: str, code, inputs: dict) -> str:
    """The cache key: SHA-256 of the inputs, the source of `code` (modules, functions) and of the
    converter, the plugins' constants, the variant and the Mitsuba and Dr.Jit versions."""
    import mitsuba as mi

    h = hashlib.sha256()
    _feed(h, {"variant": variant, "mitsuba": mi.__version__, "drjit": importlib.metadata.version("drjit"),
              "converter": list(converter()), "constants": converter_constants(), "code": list(code),
              "inputs": inputs})
    return h.hexdigest()


def reference(name: str, render: Callable[[], np.ndarray], *, variant: str, code=(), **inputs) -> np.ndarray:
    """The reference `render()` returns, from DATA/`name`.npz when the key of (`variant`, `code`,
    `inputs`) matches the file's, else rendered (in `variant`, which this sets first) and, with
    GLINT_MITSUBA_CACHE=write, stored. `inputs`: everything `render` hands to Mitsuba that the
    sources in `code` and the converter do not fix (scene, sensor, spp, points, ...)."""
    import mitsuba as mi

    mode = os.environ.get(ENV, "")
    if mode not in ("", "render", "write"):
        raise ValueError(f"{ENV}={mode!r}: unset, 'render' or 'write'")
    mi.set_variant(variant)
    k = key(variant, code, inputs)
    path = DATA / f"{name}.npz"
    if mode == "":
        why = "no cached reference"
        if path.exists():
            with np.load(path) as f:
                if str(f["key"]) == k:
                    return f["reference"]
            why = "the cached reference is stale (its key is not that of this test's Mitsuba inputs)"
        warnings.warn(f"{path.relative_to(DATA.parents[2])}: {why}; rendered with Mitsuba instead "
                      f"(refresh: {REFRESH})", StaleMitsubaReference, stacklevel=2)
    out = render()
    if mode == "write":
        DATA.mkdir(parents=True, exist_ok=True)
        about = {"variant": variant, "mitsuba": mi.__version__, "drjit": importlib.metadata.version("drjit")}
        np.savez_compressed(path, reference=out, key=np.array(k), about=np.array(json.dumps(about)))
        print(f"wrote {path} {out.shape} {out.dtype}")
    return out
