"""The bake directory: the one contract between the bake and the viewer.

    manifest.json          versioned description (see `FORMAT_VERSION`): scene hash, per-stage
                           input hashes, settings, statistics, materials, lights, cameras, objects;
                           `scene.hash` is of the scene's content (bake/pipeline.py source_hash: no
                           path in it) and `scene.source` the absolute path, for information only: a
                           bake is up to date for the same content hash, settings and optional
                           `inputs.versions` (the stage versions; `inputs` also holds the sidecar's
                           content and per-object hashes, which only name what changed; absent in
                           older bake dirs, which stay readable: no version change), wherever it lies;
                           optional `statistics.last_bake`: what the bake that wrote it redid and
                           reused and why (core/skipped.py; absent in older bake dirs, which stay
                           readable: no version change); optional `statistics.ignored_features`:
                           {glTF feature: count} the loader ignored (Scene.ignored_features),
                           and `statistics.lightmaps.invalid_texels` of `texels` inside geometry;
                           optional `statistics.cluster`: where a bake on a Dask cluster ran and
                           what starting and feeding it cost (bake/executor.py DaskExecutor)
    meshes.npz             per object o<i>_*: positions, normals, uvs (texture), colors
                           (COLOR_0, optional), tangents (glTF TANGENT in world space, optional), lm_uv, lm_page, indices -- vertices already split along light-map chart seams
    lightmaps/page_<k>.exr irradiance E in W/m^2 (RGB) + A = 1 where baked, 0 where dilated;
                           half float unless a value does not fit
    lightmaps/back_<k>.exr the back sides of two-sided objects (the manifest's object entries say
                           `lightmap_back: true`), page by page at the same light-map coordinates:
                           E around -n, where the viewer sees a back face. Listed in the manifest's
                           optional `lightmaps_back` (absent or empty: no object has a back side;
                           older bake dirs lack it and stay readable: the front serves both sides)
    textures/emission_<i>.exr   emissive textures (glTF emissiveTexture, linear RGB; they multiply
                                the material's `emission`), manifest `emission_texture`
    textures/metallic_roughness_<i>.exr   glTF metallicRoughnessTexture (linear; G multiplies the
                                roughness of the material's `mr` lobes, B is the metallic M' per
                                texel: kd x (1 - M'), lobes' ks x M' or 1 - M'), manifest
                                `metallic_roughness_texture`; lobes carry `mr` ("metal", "dielectric")
    textures/normal_<i>.exr     normal maps (glTF normalTexture as stored, linear RGB in 0..1),
                                manifest `normal_texture` with `normal_scale`
    textures/anisotropy_<i>.exr anisotropy textures (KHR_materials_anisotropy, linear RGB),
                                manifest `anisotropy_texture`; `anisotropy_rotation` in radians
    textures/material_<i>.exr   base-colour textures (linear); RGBA, A the base colour alpha
                           (linear), for materials whose manifest entry has `alpha_mode` MASK or
                           BLEND (with `alpha_cutoff` and `alpha` = baseColorFactor[3]; entries
                           without `alpha_mode` are OPAQUE: older bake dirs stay readable)
    cubemaps/<i>.exr       a cube-map probe, i the index of the first object it serves (curved
                           and transmissive objects only; one probe may serve several objects
                           close together, bake/cubemap.py): RGBA, S wide and 6 S high, the faces +X, -X, +Y,
                           -Y, +Z, -Z stacked top to bottom, each with its first row at GL's
                           t = 0 and first column at s = 0 (glTexImage2D's order); RGB radiance,
                           A the distance in metres from the centre to the visible surface
                           (65504 for sky); half float unless a value does not fit. Each object's
                           manifest entry says `cubemap: {file, size, centre, bounding_planes:
                           [{point, normal, object}]}` of its probe (plus `shared_by`, the number
                           of objects, where more than one), or null; `stages.cubemaps` has each
                           probe's input hash by i

A bake is written into a temporary sibling directory and renamed into place, so an
interrupted bake never leaves a half-written result (`BakeDirWriter`).
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from glint.core.atomic import atomic_write_text
from glint.core.errors import GlintError
from glint.core.image_io import read_image, sample_bilinear

FORMAT_VERSION = 1
MANIFEST = "manifest.json"


def default_bake_dir(scene_path: Path, builtin: str | None = None) -> Path:
    """Built-in scenes bake into the user cache (the package may be read-only);
    a user's scene bakes beside its file, as NAME.bake/."""
    if builtin:
        root = Path(os.environ.get("GLINT_CACHE") or Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "glint")
        return root / f"{builtin}.bake"
    return scene_path.with_name(scene_path.stem + ".bake")


def read_manifest(bake_dir: Path) -> dict | None:
    """The manifest of an existing bake, or None when there is none or it is unreadable/old."""
    path = Path(bake_dir) / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if manifest.get("format") != "glint-bake" or manifest.get("version") != FORMAT_VERSION:
        return None
    return manifest


def write_json(path: Path, data: dict) -> None:
    atomic_write_text(path, json.dumps(data, indent=1, sort_keys=False))


def save_meshes(path: Path, meshes: list[dict]) -> None:
    arrays = {f"o{i}_{k}": v for i, mesh in enumerate(meshes) for k, v in mesh.items() if v is not None}
    with open(path, "wb") as f:
        np.savez_compressed(f, **arrays)


def load_meshes(path: Path, count: int) -> list[dict]:
    with np.load(path) as data:
        meshes = [{} for _ in range(count)]
        for key in data.files:
            i, name = key[1:].split("_", 1)
            meshes[int(i)][name] = data[key]
    return meshes


class BakeDirWriter:
    """Write a bake into a temporary directory; `commit()` swaps it into place.

    Leaving the `with` block without commit (an error, Ctrl-C) deletes the
    temporary directory and leaves any previous bake untouched.
    """

    def __init__(self, target: Path):
        self.target = Path(target)
        self.path: Path | None = None

    def __enter__(self) -> "BakeDirWriter":
        parent = self.target.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
            self.path = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.", suffix=".tmp", dir=parent))
        except OSError as e:
            raise GlintError(f"cannot create the bake directory in {parent}: {e.strerror}") from e
        (self.path / "lightmaps").mkdir()
        (self.path / "textures").mkdir()
        return self

    def reuse(self, old_dir: Path, relative: str) -> None:
        """Carry a file of the previous bake over unchanged (hard link when possible)."""
        src, dst = Path(old_dir) / relative, self.path / relative
        dst.parent.mkdir(parents=True, exist_ok=True)
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)

    def commit(self) -> None:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(self.path, 0o777 & ~umask)  # mkdtemp made it private; a bake dir is an ordinary folder
        old = None
        if self.target.exists():
            old = self.target.with_name(f".{self.target.name}.old-{os.getpid()}")
            os.rename(self.target, old)
        try:
            os.rename(self.path, self.target)
        except OSError:
            if old is not None:
                os.rename(old, self.target)  # put the previous bake back
            raise
        self.path = None
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)

    def __exit__(self, *exc) -> None:
        if self.path is not None:
            shutil.rmtree(self.path, ignore_errors=True)
            self.path = None


class Bake:
    """A bake directory read back: manifest, meshes and light-map pages (for the viewer and tests)."""

    def __init__(self, bake_dir: Path):
        self.path = Path(bake_dir)
        manifest = read_manifest(self.path)
        if manifest is None:
            raise GlintError(f"{self.path}: not a glint bake directory (or made by another version); run `glint bake`")
        self.manifest = manifest
        self.meshes = load_meshes(self.path / "meshes.npz", len(manifest["objects"]))
        self._pages: dict[tuple[int, bool], np.ndarray] = {}

    @property
    def back_pages(self) -> list[str]:
        """The back-side pages' files (empty: no object has a back side)."""
        return list(self.manifest.get("lightmaps_back") or [])

    def has_back(self, obj: int) -> bool:
        """Whether object `obj` has its own back-side light map (else its back face reads the front's)."""
        return bool(self.back_pages) and bool(self.manifest["objects"][obj].get("lightmap_back"))

    def lightmap(self, page: int, back: bool = False) -> np.ndarray:
        """(H, W, 4) float32: irradiance RGB and A = 1 where path traced; `back`: the back sides' page."""
        key = (page, bool(back))
        if key not in self._pages:
            files = self.back_pages if back else self.manifest["lightmaps"]
            self._pages[key] = read_image(self.path / files[page])
        return self._pages[key]

    def irradiance(self, obj: int, triangles: np.ndarray, barycentric: np.ndarray,
                   back: bool = False) -> np.ndarray:
        """Bilinear light-map look-up at points given by triangle index and barycentrics (K, 3)
        of object `obj` -- what the viewer's texture unit does (GL_LINEAR, clamp to edge). `back`:
        the irradiance on the back side, as the viewer reads it for a back face (the front's where
        the object has no back side)."""

        back = back and self.has_back(obj)
        mesh = self.meshes[obj]
        corners = mesh["indices"][np.asarray(triangles)].astype(np.int64)  # (K, 3)
        uv = np.einsum("kj,kjc->kc", barycentric, mesh["lm_uv"][corners])
        pages = mesh["lm_page"][corners[:, 0]]
        out = np.zeros((len(uv), 3), np.float32)
        for page in np.unique(pages):
            sel = pages == page
            out[sel] = sample_bilinear(self.lightmap(int(page), back)[..., :3], uv[sel])
        return out
