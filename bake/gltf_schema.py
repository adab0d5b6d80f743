"""The types of a glTF file's JSON, checked before the loader reads any of it (bake/gltf_loader.py).

The loader reads the JSON with `dict.get` and indexes lists; a value of another type than the
glTF 2.0 schema's (a string where an index goes, a number where an object goes) would otherwise
surface as a TypeError or AttributeError deep inside it. `check_types` walks the parts glint reads
and stops at the first value of a wrong type with one line naming where it is:
"scene.glb: malformed glTF: nodes[3].matrix[2] must be a number, not 'x'".

Only types are checked here; ranges (an index past its table, a negative count, a byteLength past
its buffer) are checked where the loader uses the value, which knows what a value may refer to.
Keys glint does not read are not checked (they are ignored whatever they hold), nor are `extras`.
"""
from __future__ import annotations

from glint.core.errors import GlintError

INT, NUM, STR, BOOL, DICT = "an integer", "a number", "a string", "true or false", "an object"


def _of(item):
    """A list of `item` (a leaf type above or a nested schema)."""
    return [item]


NUMS = _of(NUM)
_TEXTURE_TRANSFORM = {"offset": NUMS, "rotation": NUM, "scale": NUMS, "texCoord": INT}
_TEXTURE_INFO = {"index": INT, "texCoord": INT, "scale": NUM, "strength": NUM,
                 "extensions": {"KHR_texture_transform": _TEXTURE_TRANSFORM}}
# Material extensions: their textures are textureInfos, their factors numbers (material_mapping.py
# checks the values).
_MATERIAL_EXTENSIONS = {
    "KHR_materials_anisotropy": {"anisotropyStrength": NUM, "anisotropyRotation": NUM,
                                 "anisotropyTexture": _TEXTURE_INFO},
    "KHR_materials_emissive_strength": {"emissiveStrength": NUM},
    "KHR_materials_transmission": {"transmissionFactor": NUM, "transmissionTexture": _TEXTURE_INFO},
    "KHR_materials_ior": {"ior": NUM},
    "KHR_materials_specular": {"specularFactor": NUM, "specularColorFactor": NUMS,
                               "specularTexture": _TEXTURE_INFO, "specularColorTexture": _TEXTURE_INFO},
    "KHR_materials_clearcoat": {"clearcoatFactor": NUM, "clearcoatRoughnessFactor": NUM,
                                "clearcoatTexture": _TEXTURE_INFO, "clearcoatRoughnessTexture": _TEXTURE_INFO,
                                "clearcoatNormalTexture": _TEXTURE_INFO},
    "KHR_materials_volume": {"thicknessFactor": NUM, "attenuationDistance": NUM, "attenuationColor": NUMS,
                             "thicknessTexture": _TEXTURE_INFO},
}
_MESHOPT = {"buffer": INT, "byteOffset": INT, "byteLength": INT, "byteStride": INT, "count": INT,
            "mode": STR, "filter": STR}
_VIEW_REF = {"bufferView": INT, "byteOffset": INT, "componentType": INT}
SCHEMA = {
    "asset": {"version": STR},
    "scene": INT,
    "scenes": _of({"nodes": _of(INT), "name": STR}),
    "nodes": _of({"name": STR, "mesh": INT, "camera": INT, "skin": INT, "children": _of(INT),
                  "matrix": NUMS, "translation": NUMS, "rotation": NUMS, "scale": NUMS, "weights": NUMS,
                  "extensions": {"KHR_lights_punctual": {"light": INT}}}),
    "meshes": _of({"name": STR, "weights": NUMS, "primitives": _of({
        "attributes": {"*": INT}, "indices": INT, "material": INT, "mode": INT, "targets": _of(DICT),
        "extensions": {"KHR_draco_mesh_compression": {"bufferView": INT, "attributes": {"*": INT}}}})}),
    "accessors": _of({"bufferView": INT, "byteOffset": INT, "componentType": INT, "normalized": BOOL,
                      "count": INT, "type": STR, "sparse": {"count": INT, "indices": _VIEW_REF,
                                                            "values": _VIEW_REF}}),
    "bufferViews": _of({"buffer": INT, "byteOffset": INT, "byteLength": INT, "byteStride": INT,
                        "extensions": {"EXT_meshopt_compression": _MESHOPT, "KHR_meshopt_compression": _MESHOPT}}),
    "buffers": _of({"uri": STR, "byteLength": INT,
                    "extensions": {"EXT_meshopt_compression": {"fallback": BOOL},
                                   "KHR_meshopt_compression": {"fallback": BOOL}}}),
    "materials": _of({"name": STR, "pbrMetallicRoughness": {
        "baseColorFactor": NUMS, "baseColorTexture": _TEXTURE_INFO, "metallicFactor": NUM, "roughnessFactor": NUM,
        "metallicRoughnessTexture": _TEXTURE_INFO},
        "normalTexture": _TEXTURE_INFO, "occlusionTexture": _TEXTURE_INFO, "emissiveTexture": _TEXTURE_INFO,
        "emissiveFactor": NUMS, "alphaMode": STR, "alphaCutoff": NUM, "doubleSided": BOOL,
        "extensions": _MATERIAL_EXTENSIONS}),
    "textures": _of({"sampler": INT, "source": INT, "name": STR}),
    "images": _of({"uri": STR, "bufferView": INT, "mimeType": STR, "name": STR}),
    "samplers": _of({"magFilter": INT, "minFilter": INT, "wrapS": INT, "wrapT": INT}),
    "cameras": _of({"name": STR, "type": STR, "perspective": {"yfov": NUM, "znear": NUM, "zfar": NUM,
                                                              "aspectRatio": NUM},
                    "orthographic": DICT}),
    "animations": _of(DICT),
    "extensionsUsed": _of(STR),
    "extensionsRequired": _of(STR),
    "extensions": {"KHR_lights_punctual": {"lights": _of({
        "name": STR, "type": STR, "color": NUMS, "intensity": NUM, "range": NUM,
        "spot": {"innerConeAngle": NUM, "outerConeAngle": NUM}})}},
}


def _is(value, leaf: str) -> bool:
    if leaf == INT:
        return isinstance(value, int) and not isinstance(value, bool)
    if leaf == NUM:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if leaf == STR:
        return isinstance(value, str)
    if leaf == BOOL:
        return isinstance(value, bool)
    return isinstance(value, dict)


def check_types(tree: dict, source: str) -> None:
    """GlintError at the first value of `tree` (a glTF JSON object) whose type is not the schema's."""
    _check(tree, SCHEMA, "", source)


def _check(value, schema, where: str, source: str) -> None:
    if isinstance(schema, str):
        if not _is(value, schema):
            _fail(value, schema, where, source)
    elif isinstance(schema, list):
        if not isinstance(value, list):
            _fail(value, "a list", where, source)
        for i, item in enumerate(value):
            _check(item, schema[0], f"{where}[{i}]", source)
    else:
        if not isinstance(value, dict):
            _fail(value, DICT, where, source)
        for key, item in value.items():
            sub = schema.get(key, schema.get("*"))
            if key == "extensions" and sub is None:  # any extension's table is an object
                sub = {"*": DICT}
            if key == "extensions" and isinstance(sub, dict) and "*" not in sub:
                sub = {**sub, "*": DICT}
            if sub is not None:
                _check(item, sub, f"{where}.{key}" if where else key, source)


def _fail(value, expected: str, where: str, source: str):
    shown = repr(value)
    shown = shown if len(shown) <= 40 else shown[:37] + "..."
    raise GlintError(f"{source}: malformed glTF: {where or 'the JSON'} must be {expected}, not {shown}")
