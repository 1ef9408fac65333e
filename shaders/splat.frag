#version 330 core
// Gaussian falloff and 3DGS alpha rules; output is premultiplied colour for back-to-front blending
// with (ONE, ONE_MINUS_SRC_ALPHA): image = sum c_i a_i T_i + T_final * background.

uniform vec2 u_target_size;

flat in vec2 v_center;
flat in vec3 v_conic;
flat in vec4 v_color;

out vec4 f_color;

void main() {
    // gl_FragCoord is (col + 0.5, row_from_bottom + 0.5); the image pixel centre with y down is:
    vec2 pixel = vec2(gl_FragCoord.x, u_target_size.y - gl_FragCoord.y);
    vec2 d = pixel - v_center;
    float power = -0.5 * (v_conic.x * d.x * d.x + v_conic.z * d.y * d.y) - v_conic.y * d.x * d.y;
    if (power > 0.0) discard;
    float alpha = min(0.99, v_color.a * exp(power));
    if (alpha < 1.0 / 255.0) discard;
    f_color = vec4(v_color.rgb * alpha, alpha);
}
