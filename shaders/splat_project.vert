#version 330 core
// Projection pass (transform feedback, one invocation per Gaussian, in back-to-front order): the same EWA
// projection as gstyle_core.raster (3DGS maths): Jacobian of the perspective projection at the mean with x/z, y/z
// clamped to the field of view widened by 30 %, +0.3 px^2 on the 2D covariance diagonal, 3-sigma cut-off.
// Pixel convention (OpenCV, as gsplat): means2d = (fx X/Z + cx, fy Y/Z + cy), image y down.
// The draw pass (splat.vert) only places the 4 corners of each projected splat's quad; colours stay out of this
// pass, so streamed colours and the compare view's second colour layer reuse one projection.

uniform sampler2D u_geom0;   // mean.xyz, opacity
uniform sampler2D u_geom1;   // columns of M = R S (rotation times scales): Sigma_3D = M M^T
uniform sampler2D u_geom2;
uniform sampler2D u_geom3;
uniform int u_tex_width;
uniform mat4 u_world_to_cam;  // OpenCV axes, column-major as uploaded
uniform vec4 u_intrinsics;    // fx, fy, cx, cy
uniform vec2 u_image_size;    // width, height in pixels (of the camera)
uniform vec2 u_viewport_origin;  // pixel offset of the camera image in the framebuffer (x right, y down)
uniform float u_near;

in int in_index;      // Gaussian index, in back-to-front order

out vec2 out_center;   // means2d in framebuffer pixels, y down
out vec4 out_conic;    // inverse 2D covariance (a, b, c), opacity
out vec4 out_axes;     // the quad's half axes in pixels: major * extent, minor * extent; zero = culled

const float LOW_PASS = 0.3;
const float FOV_MARGIN = 0.3;

ivec2 texel(int i) { return ivec2(i % u_tex_width, i / u_tex_width); }

void cull() {
    out_center = vec2(0.0); out_conic = vec4(0.0); out_axes = vec4(0.0);
}

void main() {
    vec4 g0 = texelFetch(u_geom0, texel(in_index), 0);
    vec4 g1 = texelFetch(u_geom1, texel(in_index), 0);
    vec4 g2 = texelFetch(u_geom2, texel(in_index), 0);
    vec4 g3 = texelFetch(u_geom3, texel(in_index), 0);
    vec3 p = (u_world_to_cam * vec4(g0.xyz, 1.0)).xyz;
    if (!(p.z > u_near)) { cull(); return; }

    float fx = u_intrinsics.x, fy = u_intrinsics.y, cx = u_intrinsics.z, cy = u_intrinsics.w;
    float w = u_image_size.x, h = u_image_size.y;
    float tan_x = 0.5 * w / fx, tan_y = 0.5 * h / fy;
    float tx = p.z * clamp(p.x / p.z, -(cx / fx + FOV_MARGIN * tan_x), (w - cx) / fx + FOV_MARGIN * tan_x);
    float ty = p.z * clamp(p.y / p.z, -(cy / fy + FOV_MARGIN * tan_y), (h - cy) / fy + FOV_MARGIN * tan_y);
    float inv_z = 1.0 / p.z;
    // J (2x3) written as column-major mat3x2 in GLSL: columns = d/dX, d/dY, d/dZ.
    mat3x2 J = mat3x2(fx * inv_z, 0.0,
                      0.0, fy * inv_z,
                      -fx * tx * inv_z * inv_z, -fy * ty * inv_z * inv_z);
    mat3 W = mat3(u_world_to_cam);
    mat3x2 G = J * W * mat3(g1.xyz, g2.xyz, g3.xyz);   // Sigma_2D = G G^T
    vec3 gx = vec3(G[0].x, G[1].x, G[2].x);
    vec3 gy = vec3(G[0].y, G[1].y, G[2].y);
    float a = dot(gx, gx) + LOW_PASS;
    float b = dot(gx, gy);
    float c = dot(gy, gy) + LOW_PASS;
    // det = |gx x gy|^2 + dilation terms: positive and free of cancellation (as the torch rasterizer).
    vec3 cr = cross(gx, gy);
    float det = dot(cr, cr) + LOW_PASS * (a + c) - LOW_PASS * LOW_PASS;
    if (!(det > 0.0)) { cull(); return; }
    float mid = 0.5 * (a + c);
    float spread = sqrt(max(mid * mid - det, 0.1));
    float lambda_major = mid + spread;
    float lambda_minor = max(mid - spread, LOW_PASS);
    // 3-sigma cut-off. The quad is the 3-sigma ellipse's bounding box along its own axes (fewer fragments than
    // the axis-aligned square of half-side ceil(3 sqrt(lambda_major)) for elongated splats), clipped to that square.
    vec2 major = abs(b) > 1e-12 ? normalize(vec2(b, lambda_major - a))
                                : (a >= c ? vec2(1.0, 0.0) : vec2(0.0, 1.0));
    vec2 minor = vec2(-major.y, major.x);
    float radius = ceil(3.0 * sqrt(lambda_major));
    vec2 half_extent = min(vec2(3.0 * sqrt(lambda_major), 3.0 * sqrt(lambda_minor)) + 0.5, vec2(radius));
    // splat.frag discards alpha = opacity * exp(-t^2 / (2 lambda)) < 1/255, i.e. beyond t = sqrt(2 ln(255 opacity)
    // lambda) along an axis: the quad need not reach further (same image, fewer fragments for faint splats; the
    // minimum-size splats of a reduced-resolution frame made it fill-bound).
    if (!(g0.w * 255.0 >= 1.0)) { cull(); return; }
    float reach = sqrt(2.0 * log(255.0 * g0.w));
    half_extent = min(half_extent, reach * vec2(sqrt(lambda_major), sqrt(lambda_minor)) + 0.01);

    out_center = vec2(fx * p.x * inv_z + cx, fy * p.y * inv_z + cy) + u_viewport_origin;
    out_conic = vec4(vec3(c, -b, a) / det, g0.w);
    out_axes = vec4(half_extent.x * major, half_extent.y * minor);
}
