// One triangle that covers the viewport, made from gl_VertexID alone (no vertex buffer):
// corners (-1,-1), (3,-1), (-1,3) in clip space; uv is 0..1 across the viewport. With FAR_PLANE
// defined it lies on the far plane (depth 1).

out vec2 uv;

void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);  // (0,0), (2,0), (0,2)
    uv = p;
#ifdef FAR_PLANE
    gl_Position = vec4(p * 2.0 - 1.0, 1.0, 1.0);  // depth 1: behind everything drawn (mirror_sky.frag)
#else
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
#endif
}
