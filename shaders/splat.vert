#version 330 core
// Draw pass, vertex stage: one point per projected Gaussian (splat_project.vert wrote centre, conic, opacity and
// the quad's half axes, in back-to-front order); fetches the colour. splat.geom expands the point into its quad.
// (One non-instanced draw of points: llvmpipe pays a fixed cost per instance, which made an instanced quad per
// Gaussian cost ~75 ms for 40k Gaussians even at 200x150 pixels.)

uniform sampler2D u_color;   // rgb, - (one texel per Gaussian, 4096 per row)
uniform sampler2D u_select;  // selected region: r = 1 for a selected Gaussian (read only when u_highlight is 1)
uniform int u_highlight;     // 1: dim the Gaussians outside the selection (the studio's region tool is on)
uniform int u_tex_width;
uniform int u_projected_rgb; // 1: the colour is the projection pass's (view-dependent SH), not u_color's


in vec2 in_center;    // means2d in framebuffer pixels, y down
in vec4 in_conic;     // inverse 2D covariance (a, b, c), opacity
in vec4 in_axes;      // major * extent, minor * extent (pixels); zero = culled
in vec3 in_rgb;       // the projection pass's SH colour
in int in_index;      // Gaussian index (for its colour)

out vec2 g_center;
out vec4 g_conic;
out vec4 g_axes;
out vec3 g_rgb;

void main() {
    g_center = in_center;
    g_conic = in_conic;
    g_axes = in_axes;
    ivec2 texel = ivec2(in_index % u_tex_width, in_index / u_tex_width);
    g_rgb = u_projected_rgb == 1 ? in_rgb : texelFetch(u_color, texel, 0).rgb;
    if (u_highlight == 1) {
        bool selected = texelFetch(u_select, texel, 0).r > 0.5;
        g_rgb = selected ? g_rgb : g_rgb * 0.4;  // the selection as it is (its style stays visible), the rest dim
    }
    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);  // unused: the geometry stage places the corners
}
