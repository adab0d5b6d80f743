// Cube maps (section 4.4.1) and their bounding planes, as viewer/cubemaps.py binds them: one
// samplerCubeArray per face-size class (CUBE_CLASSES comes in as a define), and per object a row
// saying which class and layer hold its probe (its own map or one shared with objects nearby,
// bake/cubemap.py), the probe's centre and its bounding planes.

#include "common.glsl"

struct CubeObject {
    vec4 centre;    // xyz: the projection centre of the object's probe (its box centre, or its cluster's)
    ivec4 info;     // x: size class (-1: no cube map), y: layer, z: first bounding plane, w: plane count
    vec4 extent;    // glass solids (volume.glsl): xyz half extents of the oriented box, w: thickness (m)
    vec4 volume;    // glass solids: rgb absorption sigma_a (1/m), a: ior; a = 0: not a solid
    vec4 box[3];    // glass solids: xyz the oriented box's axes (unit), w their centre's coordinates
};

struct BoundingPlane {
    vec4 point;     // xyz: a point of the plane
    vec4 normal;    // xyz: unit normal
};

layout(std430, binding = CUBE_OBJECT_BINDING) readonly buffer CubeObjectBuffer { CubeObject cube_objects[]; };
layout(std430, binding = BOUNDING_PLANE_BINDING) readonly buffer BoundingPlaneBuffer {
    BoundingPlane bounding_planes[];
};

// Class k on texture unit CUBE_FIRST_UNIT + k, fixed in the shader (a define from Python) rather
// than set as a uniform: Mesa's llvmpipe (22.3) ignored sampler uniforms set for cube-map arrays.
layout(binding = CUBE_FIRST_UNIT) uniform samplerCubeArray cube_maps[CUBE_CLASSES];
uniform float cube_face_size[CUBE_CLASSES];  // texels per face side, per class

// CUBE_OBJECTS (viewer/cubemaps.py): 0 where no object has a cube map, a constant false here.
bool has_cube_map(CubeObject c) {
    return CUBE_OBJECTS != 0 && c.info.x >= 0;
}

float cube_map_face_size(CubeObject c) {
    float size = 1.0;
    for (int k = 0; k < CUBE_CLASSES; ++k)  // a loop index is dynamically uniform: legal array index
        if (k == c.info.x)
            size = cube_face_size[k];
    return size;
}

// Radiance of the object's cube map along `dir` (any length but zero) at MIP level `lod`.
vec3 cube_radiance(CubeObject c, vec3 dir, float lod) {
    vec3 L = vec3(0.0);
    for (int k = 0; k < CUBE_CLASSES; ++k)
        if (k == c.info.x)
            L = textureLod(cube_maps[k], vec4(dir, float(c.info.y)), lod).rgb;
    return L;
}

// Look-up direction of the ray p + t d (t > 0) by the bounding-plane approximation (section 4.4.1,
// Fig. 4.5): the ray is intersected with the object's bounding planes, and the nearest hit h is
// looked up from the projection centre, h - centre. Without a hit (no planes, a ray parallel to
// them or pointing away) it is the plain direction d, as if the scene were infinitely far away.
vec3 bounding_plane_direction(CubeObject c, vec3 p, vec3 d) {
    float nearest = 3.0e38;
    for (int k = 0; k < c.info.w; ++k) {
        BoundingPlane plane = bounding_planes[c.info.z + k];
        float along = dot(d, plane.normal.xyz);
        float t = dot(plane.point.xyz - p, plane.normal.xyz) / along;  // +-inf or NaN when parallel
        if (abs(along) > 1e-8 && t > 0.0 && t < nearest)
            nearest = t;
    }
    if (nearest >= 3.0e38)
        return d;
    // A hit at the centre itself has no direction: keep d.
    return safe_normalize(p + nearest * d - c.centre.xyz, d);
}
