"""Constants that Python and the GLSL share, defined once here.

viewer/shader_source.py injects every name of `glsl_constants()` into each shader as a
`#define`, so shaders/*.glsl use these values without restating them. The BSDF's numerical
guards (M_MIN, HZ_MIN, ...) live with the BSDF in core/bsdf.py and are injected the same way.
"""
from __future__ import annotations

HALF_MAX = 65504.0  # the largest half float: above it an RGBA16F texel or a half EXR cannot hold a value
XI1_BORDER = 0.01  # Eq. 4.10: the lobe border is where Eq. 4.6 is at xi1 = 0.01 (~99 % of the half vectors inside)
LOBE_TAN_MAX = 100.0  # Eq. 4.15 caps tan(alpha) here (alpha ~ 89.4 deg): wider lobes have no tangent-plane ellipse
# A planar object's pixel reads its plane's mirror buffer where its normal is within 10 degrees of the
# plane's (shaders/specular.glsl mirror_slot_at; bench/bench.py's region masks use the same test).
MIRROR_PLANE_COS = 0.985
# The G-buffer (shaders/gbuffer_layout.glsl; viewer/passes/gbuffer.py reads it back in numpy): the ids
# hold the material index in their low GB_ID_BITS bits and the object index above them; the frame
# target's flags word has GB_DARK_BIT set on the back of a single-sided material (it sends the viewer
# no light), GB_BITANGENT_NEGATIVE_BIT for a bitangent sign of -1, and GB_NORMAL_MAPPED_BIT where a
# normal map perturbed the normal: its pixels cannot tell by the normal whether they lie in their
# planar object's plane, so mirror_slot_at asks their position to lie within
# MIRROR_PLANE_DISTANCE x (the distance to the eye) of the plane instead.
GB_ID_BITS = 16
GB_DARK_BIT = 1 << 16
GB_NORMAL_MAPPED_BIT = 1 << 17
GB_BITANGENT_NEGATIVE_BIT = 1 << 18
MIRROR_PLANE_DISTANCE = 0.002
