// The scene's meshes read as storage buffers (viewer/gpu_meshes.py), for passes that fetch a triangle
// themselves (the visibility buffer's classification and resolve): the vertex buffer as 32-bit words
// (VERTEX_WORDS per vertex, fields at the VERTEX_* word offsets of VERTEX_DTYPE: vertex_defines()) and
// the index buffer of global vertex indices, three per triangle.

layout(std430, binding = VERTEX_BINDING) readonly buffer VertexWords { float vertex_words[]; };
layout(std430, binding = INDEX_BINDING) readonly buffer VertexIndices { uint vertex_indices[]; };

vec2 vertex2(uint v, int field) {
    uint w = v * uint(VERTEX_WORDS) + uint(field);
    return vec2(vertex_words[w], vertex_words[w + 1u]);
}

vec3 vertex3(uint v, int field) {
    uint w = v * uint(VERTEX_WORDS) + uint(field);
    return vec3(vertex_words[w], vertex_words[w + 1u], vertex_words[w + 2u]);
}

vec4 vertex4(uint v, int field) {
    uint w = v * uint(VERTEX_WORDS) + uint(field);
    return vec4(vertex_words[w], vertex_words[w + 1u], vertex_words[w + 2u], vertex_words[w + 3u]);
}

int vertex_int(uint v, int field) {
    return floatBitsToInt(vertex_words[v * uint(VERTEX_WORDS) + uint(field)]);
}

// The object a triangle of the index buffer belongs to: its first vertex's (every vertex carries its
// object's index).
int triangle_object(uint triangle) {
    return vertex_int(vertex_indices[3u * triangle], VERTEX_OBJECT);
}
