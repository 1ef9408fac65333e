#version 330 core
// Draw pass, geometry stage: the projected Gaussian's quad (its 3-sigma ellipse's box along its own axes) as a
// 4-vertex triangle strip; Gaussians culled by the projection pass (zero axes) emit nothing.

layout(points) in;
layout(triangle_strip, max_vertices = 4) out;

uniform vec2 u_target_size;  // framebuffer size in pixels

in vec2 g_center[];
in vec4 g_conic[];
in vec4 g_axes[];
in vec3 g_rgb[];

flat out vec2 v_center;
flat out vec3 v_conic;
flat out vec4 v_color;    // rgb, opacity

void main() {
    if (g_axes[0] == vec4(0.0)) return;
    const vec2 corners[4] = vec2[4](vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(-1.0, 1.0), vec2(1.0, 1.0));
    for (int k = 0; k < 4; ++k) {
        vec2 pixel = g_center[0] + corners[k].x * g_axes[0].xy + corners[k].y * g_axes[0].zw;
        v_center = g_center[0];
        v_conic = g_conic[0].xyz;
        v_color = vec4(g_rgb[0], g_conic[0].w);
        // Pixels (y down) to NDC (y up): row 0 of the image is the top of the framebuffer.
        gl_Position = vec4(pixel.x / u_target_size.x * 2.0 - 1.0, 1.0 - pixel.y / u_target_size.y * 2.0, 0.0, 1.0);
        EmitVertex();
    }
    EndPrimitive();
}
