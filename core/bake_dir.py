"""The bake directory: the one contract between the bake and the viewer.

The manifest's schema and its defaults are core/manifest.py's `Manifest` (the bake writes its
`to_json()`, readers take `Bake.model`); what follows describes the files and the fields' meaning.

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
                           what starting and feeding it cost (parallel/executor.py DaskExecutor)
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
interrupted bake never leaves a half-written result (`BakeDirWriter`). glint writes, replaces or
removes only a directory that is a glint bake (its manifest says `format: glint-bake`, any
version) holding nothing but a bake's files, or one that is empty or absent; anything else is
refused (`check_bake_target`), by the commands before any work and by the writer itself.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np

from glint.core.atomic import atomic_write_text, dead_leftovers
from glint.core.errors import GlintError
from glint.core.image_io import read_image, sample_bilinear
from glint.core.manifest import Manifest
from glint.core.signals import deferred_signals

FORMAT_VERSION = 1
MANIFEST = "manifest.json"
# What a bake directory holds (any version): its top-level entries, and in its folders .exr files only
BAKE_FILES = {MANIFEST, "meshes.npz", "sky.exr"}
BAKE_FOLDERS = {"lightmaps", "textures", "cubemaps"}


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
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    # the version gate, on the JSON: another version's fields need not fit the model
    if data.get("format") != "glint-bake" or data.get("version") != FORMAT_VERSION:
        return None
    return data


def read_model(bake_dir: Path) -> Manifest | None:
    """`read_manifest` as the typed model (core/manifest.py)."""
    manifest = read_manifest(bake_dir)
    return None if manifest is None else Manifest.from_json(manifest)


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


def _names(names: list[str]) -> str:
    """"a", "a and b", "a, b and 3 more"."""
    names = sorted(names)
    shown = names[:2]
    rest = len(names) - len(shown)
    if rest:
        return f"{', '.join(shown)} and {rest} more"
    return " and ".join(shown)


def _foreign(bake_dir: Path) -> list[str]:
    """The entries of a glint bake directory that no bake writes (relative names)."""
    out = []
    for entry in os.scandir(bake_dir):
        if entry.name in BAKE_FOLDERS and entry.is_dir(follow_symlinks=False):
            out += [f"{entry.name}/{e.name}" for e in os.scandir(entry.path)
                    if not (e.name.endswith(".exr") and e.is_file(follow_symlinks=False))]
        elif not (entry.name in BAKE_FILES and entry.is_file(follow_symlinks=False)):
            out.append(entry.name)
    return out


def is_bake(path: Path) -> bool:
    """Whether `path` holds a glint bake's manifest, of any version."""
    try:
        return json.loads((Path(path) / MANIFEST).read_text()).get("format") == "glint-bake"
    except (OSError, ValueError, AttributeError):
        return False


def check_bake_target(target: Path, option: str | None = None) -> None:
    """A one-line GlintError unless a bake may write `target`: absent, an empty directory, or a glint
    bake directory (any version) that holds nothing but a bake's files. `option` (e.g. "-o") is named
    in the advice."""
    target = Path(target)
    advice = f"give a new or empty directory{f' with {option}' if option else ''}"
    if target.name in ("", ".", ".."):
        raise GlintError(f"{option + ' ' if option else ''}{target}: a bake replaces its directory as a whole, "
                         f"so it needs a directory of its own; {advice}, e.g. room.bake")
    if target.is_symlink() and not target.exists():
        raise GlintError(f"{target} is a broken symbolic link; {advice}")
    if not target.exists():
        return
    if not target.is_dir():
        raise GlintError(f"{target} is a file, not a bake directory; {advice}")
    real, cwd = target.resolve(), Path.cwd().resolve()
    if real == cwd or real in cwd.parents:
        raise GlintError(f"{target} holds the current directory, which a bake would replace; {advice}")
    try:
        names = os.listdir(target)
        foreign = _foreign(target) if is_bake(target) else None
    except OSError as e:
        raise GlintError(f"cannot read {target}: {e.strerror or e}") from e
    if not names:
        return
    if foreign is None:
        raise GlintError(f"{target} is not a glint bake directory (it holds {_names(names)}); {advice}")
    if foreign:
        raise GlintError(f"{target} is a glint bake directory but also holds {_names(foreign)}, which a new bake "
                         f"would delete; move {'it' if len(foreign) == 1 else 'them'} out, or {advice}")


def remove_dead_temporaries(target: Path) -> None:
    """Remove what a killed bake of `target` left beside it (BakeDirWriter's `.NAME.<pid>.<random>.tmp`,
    exactly that pattern, once process pid is gone), and put back or remove its `.NAME.old-<pid>` (the
    previous bake a commit set aside: back in place when the target is missing, else removed)."""
    target = Path(target)
    name = re.escape(target.name)
    temporary = re.compile(rf"\.{name}\.(\d+)\.[a-z0-9_]{{8}}\.tmp")  # tempfile.mkdtemp's 8 characters
    aside = re.compile(rf"\.{name}\.old-(\d+)")
    for entry, match in dead_leftovers(target, temporary, aside):
        if not entry.is_dir(follow_symlinks=False):
            continue
        if match.re is aside and not os.path.lexists(target) and is_bake(Path(entry.path)):
            os.rename(entry.path, target)  # the previous bake, set aside by a cut commit
        elif match.re is temporary or is_bake(Path(entry.path)):
            shutil.rmtree(entry.path, ignore_errors=True)


class BakeDirWriter:
    """Write a bake into a temporary directory; `commit()` swaps it into place.

    Leaving the `with` block without commit (an error, Ctrl-C, SIGTERM) deletes the temporary
    directory and leaves any previous bake untouched. The target must be absent, empty or a bake
    (`check_bake_target`): checked on entering and again at the commit. The temporary directory is
    the target's sibling `.NAME.<pid>.<random>.tmp`; the ones a killed bake (SIGKILL) left are
    removed on entering, once their process is gone, as is its `.NAME.old-<pid>` (the previous bake
    set aside by a commit: put back in place when the commit was cut between its two renames).
    """

    def __init__(self, target: Path):
        target = Path(target)
        # a symbolic link to a bake directory: the directory is replaced, the link stays
        self.target = target.resolve() if target.is_symlink() and target.exists() else target
        self.path: Path | None = None

    def __enter__(self) -> "BakeDirWriter":
        check_bake_target(self.target)
        parent = self.target.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
            remove_dead_temporaries(self.target)
            self.path = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.{os.getpid()}.", suffix=".tmp", dir=parent))
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
        with deferred_signals():  # neither rename without the other
            check_bake_target(self.target)  # the last guard: what is there now may have changed since
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
    """A bake directory read back: manifest (`model`, core/manifest.py), meshes and light-map pages
    (for the viewer and tests)."""

    def __init__(self, bake_dir: Path):
        self.path = Path(bake_dir)
        model = read_model(self.path)
        if model is None:
            raise GlintError(f"{self.path}: not a glint bake directory (or made by another version); run `glint bake`")
        self.model = model
        self.meshes = load_meshes(self.path / "meshes.npz", len(model.objects))
        self._pages: dict[tuple[int, bool], np.ndarray] = {}

    @property
    def manifest(self) -> dict:
        """The manifest as JSON (a fresh dict, `model.to_json()`): for tests and the modules not yet
        reading `model`; setting it replaces the model."""
        return self.model.to_json()

    @manifest.setter
    def manifest(self, value: dict) -> None:
        self.model = Manifest.from_json(value)

    @property
    def back_pages(self) -> list[str]:
        """The back-side pages' files (empty: no object has a back side)."""
        return list(self.model.lightmaps_back)

    def has_back(self, obj: int) -> bool:
        """Whether object `obj` has its own back-side light map (else its back face reads the front's)."""
        return self.model.has_back(obj)

    def lightmap(self, page: int, back: bool = False) -> np.ndarray:
        """(H, W, 4) float32: irradiance RGB and A = 1 where path traced; `back`: the back sides' page."""
        key = (page, bool(back))
        if key not in self._pages:
            files = self.back_pages if back else self.model.lightmaps
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
