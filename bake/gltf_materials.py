"""glTF materials, textures, images and samplers -> glint `Material`s.

Reads each material's textures (glTF 3.9: base colour, emissive, metallic-roughness, normal; and
KHR_materials_anisotropy's), their images (PNG/JPEG from a bufferView, a `data:` URI or a file,
decoded within bake/texture_image.py's limits; each decoded once, converted once per encoding) and
samplers (glTF 5.26), and hands them to bake/material_mapping.py, which maps the glTF material to
glint's model. Records per material the one texture coordinate set (with its KHR_texture_transform)
that its primitives' uvs are read with (`MaterialReader.uv_set`); a primitive without a material
gets "default" (`MaterialReader.default`).
"""
from __future__ import annotations

import base64
import urllib.parse
from functools import partial

import numpy as np
from PIL import UnidentifiedImageError

from glint.bake.gltf_container import GltfDocument, numbers
from glint.bake.material_mapping import apply_override, material_from_gltf
from glint.bake.texture_image import (
    MAX_DECODE_PIXELS,
    MAX_TEXTURE_PIXELS,
    MAX_TEXTURE_SIDE,
    ImageRefused,
    decode_texture,
)
from glint.bake.validate import add_warning
from glint.core.errors import WarningKind, one_line
from glint.core.scene import Material, Scene

# Warnings that repeat per material or image: one summary line each (glint.core.errors.WarningKind).
NO_IMAGE = WarningKind("{n} materials' base colour textures have no PNG/JPEG source; ignored")
UNREADABLE = WarningKind("{n} base colour images cannot be read; their materials use "
                         "baseColorFactor only")
LARGE_IMAGE = WarningKind(f"{{n}} images are larger than glint keeps ({MAX_TEXTURE_PIXELS / 1e6:.1f} Mpx, "
                          f"{MAX_TEXTURE_SIDE} a side); downscaled")
HUGE_IMAGE = WarningKind(f"{{n}} images declare more pixels than glint decodes ({MAX_DECODE_PIXELS / 1e6:.0f} Mpx); "
                         "not read, their materials go without them")
SHARED_UVS = WarningKind("{n} materials' emissive, metallic-roughness, normal or anisotropy textures "
                         "use another texture coordinate set than their base colour textures; the base "
                         "colour's is used")
_WRAP_MODES = {10497: "REPEAT", 33071: "CLAMP_TO_EDGE", 33648: "MIRRORED_REPEAT"}  # glTF 5.26
_NEAREST = 9728


class MaterialReader:
    """The materials of one glTF document and the sidecar's material settings (bake/sidecar.py)."""

    def __init__(self, doc: GltfDocument, side, warnings: list[str]):
        self.doc, self.side, self.warnings = doc, side, warnings
        self.warn = partial(add_warning, warnings)
        self.names: set[str] = set()  # every material's name, "default" once it is used
        # image -> pixels as stored; (image, srgb) -> pixels as a material reads them
        self._images: dict = {}
        self._uv_sets: dict[int, tuple[int, np.ndarray | None]] = {}
        self._samplers: dict[int, tuple[tuple[str, str], bool]] = {}
        self._default_material: int | None = None

    def read(self) -> list[Material]:
        """Every glTF material as a glint Material (bake/material_mapping.py), in glTF order."""
        side = self.side
        out = []
        for i, gm in enumerate(self.doc.table("materials")):
            name = gm.get("name") or f"material{i}"
            self.names.add(name)
            rgba = self._base_color_texture(gm, name, i)
            emissive = self._shared_uv_texture(gm.get("emissiveTexture"), "emissiveTexture", name, i)
            # Metallic-roughness (glTF 3.9.2), normal (3.9.3) and anisotropy textures are linear data.
            metallic_roughness = self._shared_uv_texture(
                gm.get("pbrMetallicRoughness", {}).get("metallicRoughnessTexture"),
                "metallicRoughnessTexture", name, i, srgb=False)
            normal = self._shared_uv_texture(gm.get("normalTexture"), "normalTexture", name, i, srgb=False)
            anisotropy = self._shared_uv_texture(
                gm.get("extensions", {}).get("KHR_materials_anisotropy", {}).get("anisotropyTexture"),
                "anisotropyTexture", name, i, srgb=False)
            wrap, nearest = self._samplers.get(i, (("REPEAT", "REPEAT"), False))
            out.append(material_from_gltf(
                gm, name, kd_texture=None if rgba is None else np.ascontiguousarray(rgba[..., :3]),
                emission_texture=None if emissive is None else np.ascontiguousarray(emissive[..., :3]),
                alpha_texture=None if rgba is None else np.ascontiguousarray(rgba[..., 3]),
                metallic_roughness_texture=metallic_roughness,
                normal_texture=None if normal is None else np.ascontiguousarray(normal[..., :3]),
                anisotropy_texture=None if anisotropy is None else np.ascontiguousarray(anisotropy[..., :3]),
                diffuse_roughness=side.diffuse_roughness, override=side.materials.get(name),
                warnings=self.warnings, source=self.doc.source))
            # The base colour's sampler; not in material_from_gltf, which sees no textures' JSON.
            out[-1].kd_wrap, out[-1].kd_nearest = wrap, nearest
        return out

    def uv_set(self, material) -> tuple[int, np.ndarray | None]:
        """(texture coordinate set, KHR_texture_transform matrix or None) that the primitives of
        glTF material `material` (an index, or None) read their uvs with: set 0 untransformed
        where the material has no texture."""
        return self._uv_sets.get(material, (0, None)) if isinstance(material, int) else (0, None)

    def default(self, scene: Scene) -> int:
        """Index of the material for primitives without one (added on first use)."""
        if self._default_material is None:
            mat = Material(name="default")
            override = self.side.materials.get("default")
            if override:
                apply_override(mat, override)
            self.names.add("default")
            scene.materials.append(mat)
            self._default_material = len(scene.materials) - 1
        return self._default_material

    def _base_color_texture(self, gm: dict, name: str, index: int) -> np.ndarray | None:
        """(H, W, 4) float32: linear RGB and alpha, or None. Records in self._uv_sets[index] the
        texture coordinate set and KHR_texture_transform matrix its primitives' uvs get."""
        info = gm.get("pbrMetallicRoughness", {}).get("baseColorTexture")
        if info is None:
            return None
        where = f"{self.doc.source}: material '{name}'"
        texcoord, matrix = _uv_set(info, where)
        self._uv_sets[index] = (texcoord, matrix)
        tex = self.doc.item("textures", info.get("index"), f"material '{name}' baseColorTexture")
        self._samplers[index] = self._sampler(tex)
        return self._texture_image(tex, "base colour", name, where)

    def _shared_uv_texture(self, info, key: str, name: str, index: int,
                           srgb: bool = True) -> np.ndarray | None:
        """(H, W, 4) float32 of a material texture that shares the object's one uv set: the
        emissiveTexture (glTF 3.9.3: sRGB, multiplies emissiveFactor), the metallicRoughnessTexture,
        the normalTexture and the anisotropyTexture (linear: `srgb` False), or None. It is looked
        up with the base colour's uv set and sampler, the one set an object keeps; when it names
        another set (or transform), that is warned and the base colour's is used. Without a base colour texture
        the first of these textures gives the object its set and sampler."""
        if not isinstance(info, dict):
            return None
        where = f"{self.doc.source}: material '{name}'"
        texcoord, matrix = _uv_set(info, where)
        tex = self.doc.item("textures", info.get("index"), f"material '{name}' {key}")
        if index not in self._uv_sets:
            self._uv_sets[index] = (texcoord, matrix)
            self._samplers[index] = self._sampler(tex)
        else:
            base_set, base_matrix = self._uv_sets[index]
            if base_set != texcoord or not np.array_equal(
                    np.eye(3) if base_matrix is None else base_matrix,
                    np.eye(3) if matrix is None else matrix):
                self.warn(f"{where}: {key} uses another texture coordinate set or "
                          "transform than the base colour texture; the base colour's is used",
                          SHARED_UVS, name)
        return self._texture_image(tex, key, name, where, srgb)

    def _texture_image(self, tex: dict, what: str, name: str, where: str,
                       srgb: bool = True) -> np.ndarray | None:
        """The decoded image of a glTF texture, or None with a warning; `srgb`: the colour is
        sRGB-encoded and decoded to linear (alpha is always linear). Each image is decoded once, and
        converted once per encoding, however many materials use it."""
        source = tex.get("source")
        if source is None:
            self.warn(f"{where}: {what} texture has no PNG/JPEG source; ignored",
                      NO_IMAGE, name, ignored=["textures without a PNG/JPEG source"])
            return None
        if (source, srgb) not in self._images:
            if source not in self._images:
                self._images[source] = self._decode_image(source, where)  # uint8
            rgba = self._images[source]
            if rgba is not None:
                # Colour sRGB-encoded or not, alpha linear (glTF 3.9.2 baseColorTexture): 8-bit values
                # through tables of their 256 values, the formula's bits at a fraction of its time.
                rgba = np.stack([(SRGB8_TABLE if srgb and c < 3 else LINEAR8_TABLE)[rgba[..., c]]
                                 for c in range(4)], axis=-1)
            self._images[source, srgb] = rgba
        return self._images[source, srgb]

    def _sampler(self, tex: dict) -> tuple[tuple[str, str], bool]:
        """The texture's glTF sampler: ((wrapS, wrapT), magFilter is NEAREST). glTF 5.26: without
        a sampler, or without a wrap, REPEAT; without magFilter, the client's choice (LINEAR).
        minFilter is not read (the viewer mip-maps)."""
        samplers = self.doc.json.get("samplers", [])
        sampler = {}
        if isinstance(tex.get("sampler"), int) and 0 <= tex["sampler"] < len(samplers):
            # A broken sampler reference is not worth stopping for: the defaults.
            sampler = samplers[tex["sampler"]] if isinstance(samplers[tex["sampler"]], dict) else {}
        wrap = tuple(_WRAP_MODES.get(sampler.get(k), "REPEAT") for k in ("wrapS", "wrapT"))
        return wrap, sampler.get("magFilter") == _NEAREST

    def _decode_image(self, index: int, where: str) -> np.ndarray | None:
        """(H, W, 4) uint8 of image `index`, within bake/texture_image.py's limits (a warning when
        shrunk), or None with a warning when it cannot be read or declares too many pixels to decode."""
        image = self.doc.item("images", index, f"{where} texture")
        name = _image_name(image, index)
        try:
            if "bufferView" in image:
                view = self.doc.item("bufferViews", image["bufferView"], f"image {index}")
                buffer = self.doc.buffers[self.doc.index(view.get("buffer"), len(self.doc.buffers),
                                                      f"image {index}", "buffer")]
                start = view.get("byteOffset", 0)
                data = buffer[start:start + view["byteLength"]]
            else:
                uri = image["uri"]
                if uri.startswith("data:"):
                    data = base64.b64decode(uri.split(",", 1)[1])
                else:
                    file = self.doc.path.parent / urllib.parse.unquote(uri)
                    if not file.is_file():  # nor a device (/dev/zero) or a folder
                        raise FileNotFoundError(f"no file {file}")
                    data = file.read_bytes()
            rgba, declared, kept = decode_texture(data)
        except ImageRefused as refused:
            w, h = refused.size
            self.warn(f"{where}: image '{name}' declares {w}x{h} pixels, more than glint decodes "
                      f"({MAX_DECODE_PIXELS / 1e6:.0f} Mpx); not read, the material goes without it",
                      HUGE_IMAGE, name, detail=f"{w}x{h}", ignored=["images too large to decode"])
            return None
        except Exception as err:  # any unreadable image: warn and fall back to the factor
            reason = ("not an image Pillow reads" if isinstance(err, UnidentifiedImageError)
                      else f"{type(err).__name__}: {one_line(err)}")
            self.warn(f"{where}: cannot read base colour texture (image {index}: {reason}); "
                      "using baseColorFactor only", UNREADABLE, name,
                      ignored=["unreadable base colour images"])
            return None
        if kept != declared:
            self.warn(f"{where}: image '{name}' is {declared[0]}x{declared[1]} pixels, more than glint keeps "
                      f"({MAX_TEXTURE_PIXELS / 1e6:.1f} Mpx, {MAX_TEXTURE_SIDE} a side); downscaled to "
                      f"{kept[0]}x{kept[1]}", LARGE_IMAGE, name,
                      detail=f"{declared[0]}x{declared[1]} -> {kept[0]}x{kept[1]}")
        return rgba


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function, inverted (IEC 61966-2-1)."""
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


# float32 of the 256 values of an 8-bit channel: k / 255, and that decoded from sRGB
LINEAR8_TABLE = np.arange(256, dtype=np.float32) / np.float32(255.0)
SRGB8_TABLE = srgb_to_linear(LINEAR8_TABLE)


def _uv_set(info: dict, where: str) -> tuple[int, np.ndarray | None]:
    """(texture coordinate set, KHR_texture_transform matrix or None) of a glTF textureInfo; the
    extension's own texCoord overrides the textureInfo's (KHR_texture_transform)."""
    texcoord, matrix = _texcoord(info.get("texCoord", 0)), None
    transform = info.get("extensions", {}).get("KHR_texture_transform")
    if isinstance(transform, dict):
        texcoord = _texcoord(transform.get("texCoord", texcoord))
        matrix = texture_transform_matrix(transform, where)
    return texcoord, matrix


def _texcoord(value) -> int:
    """A textureInfo texCoord (a set index >= 0); anything else reads set 0."""
    return value if isinstance(value, int) and not isinstance(value, bool) and value >= 0 else 0


def texture_transform_matrix(ext: dict, where: str = "KHR_texture_transform") -> np.ndarray:
    """The 3x3 matrix of KHR_texture_transform: uv' = (T R S) (u, v, 1).

    T translates by `offset`, S scales by `scale`, and R rotates by `rotation` radians,
    counter-clockwise in the image (v grows downwards): u' = cos u + sin v,
    v' = -sin u + cos v. That is the extension's example: offset (0, 1), rotation pi/2,
    scale 0.5 reads "only the lower left quadrant of the source image, rotated clockwise
    90 degrees" (KHR_texture_transform README, Example JSON).
    """
    offset = numbers(ext.get("offset", [0.0, 0.0]), 2, f"{where} KHR_texture_transform offset")
    scale = numbers(ext.get("scale", [1.0, 1.0]), 2, f"{where} KHR_texture_transform scale")
    rotation = float(numbers([ext.get("rotation", 0.0)], 1,
                             f"{where} KHR_texture_transform rotation")[0])
    c, s = np.cos(rotation), np.sin(rotation)
    t = np.array([[1.0, 0.0, offset[0]], [0.0, 1.0, offset[1]], [0.0, 0.0, 1.0]])
    r = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return t @ r @ np.diag([scale[0], scale[1], 1.0])



def _image_name(image: dict, index: int) -> str:
    """How a summary names an image: its name, else its file (not a data: URI), else its index."""
    uri = image.get("uri", "")
    return image.get("name") or (uri if uri and not uri.startswith("data:") else f"image {index}")
