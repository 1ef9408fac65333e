#version 330 core
// Full-rectangle quad for showing an image (e.g. a ground-truth view) in a pixel rectangle of the target.
uniform vec4 u_rect;          // x, y (top-left, y down), width, height in target pixels
uniform vec2 u_target_size;
in vec2 in_corner;            // (-1,-1) .. (1,1)
out vec2 v_uv;
void main() {
    vec2 t = in_corner * 0.5 + 0.5;            // 0..1, y down in image space
    vec2 pixel = u_rect.xy + t * u_rect.zw;
    v_uv = vec2(t.x, t.y);                     // texture row 0 = top row of the image
    gl_Position = vec4(pixel.x / u_target_size.x * 2.0 - 1.0, 1.0 - pixel.y / u_target_size.y * 2.0, 0.0, 1.0);
}
