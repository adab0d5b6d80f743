// Copies a texture onto the viewport: the tone-mapped frame onto the window, or the
// overlay's text (blended by the caller). Both images are already sRGB-encoded 8-bit, so
// this is a plain copy; the window's framebuffer does no sRGB conversion of its own.

in vec2 uv;
out vec4 colour;

layout(binding = BLIT_UNIT) uniform sampler2D image;
uniform bool opaque;  // the frame: alpha 1 so a compositing window manager shows no see-through

void main() {
    colour = texture(image, uv);
    if (opaque)
        colour.a = 1.0;
}
