// The viewing camera in a compute pass (viewer/camera.py `ray_basis`): the ray through NDC
// (x, y) is cam_forward + x cam_right + y cam_up, with right and up already scaled by the
// tangents of the half fields of view.

uniform vec3 eye;
uniform vec3 cam_forward;
uniform vec3 cam_right;
uniform vec3 cam_up;
uniform float znear;
uniform float zfar;

// Unit direction of the ray through the centre of pixel p of an image of `size` pixels
// (GL orientation: row 0 at the bottom).
vec3 view_ray(ivec2 p, ivec2 size) {
    vec2 ndc = (vec2(p) + 0.5) / vec2(size) * 2.0 - 1.0;
    return normalize(cam_forward + ndc.x * cam_right + ndc.y * cam_up);  // |.| >= 1: never zero
}

// Distance along the view axis of a window depth d of the perspective projection
// (viewer/camera.py `projection_matrix`): z_eye = 2 n f / (f + n - z_ndc (f - n)), z_ndc = 2 d - 1.
float eye_depth(float d) {
    float z_ndc = 2.0 * d - 1.0;
    return 2.0 * znear * zfar / max(zfar + znear - z_ndc * (zfar - znear), 1e-30);
}
