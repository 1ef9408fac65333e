#version 330 core
// One instanced quad per Gaussian. Same EWA projection as gstyle_core.raster (3DGS maths):
// Jacobian of the perspective projection at the mean with x/z, y/z clamped to the field of view widened by
// 30 %, +0.3 px^2 on the 2D covariance diagonal, 3-sigma cut-off (quad = the 3-sigma ellipse's oriented box).
// Pixel convention (OpenCV, as gsplat): means2d = (fx X/Z + cx, fy Y/Z + cy), image y down.

uniform sampler2D u_geom0;   // mean.xyz, opacity
uniform sampler2D u_geom1;   // columns of M = R S (rotation times scales): Sigma_3D = M M^T
uniform sampler2D u_geom2;
uniform sampler2D u_geom3;
uniform sampler2D u_color;   // rgb, -
uniform int u_tex_width;
uniform mat4 u_world_to_cam;  // OpenCV axes, column-major as uploaded
uniform vec4 u_intrinsics;    // fx, fy, cx, cy
uniform vec2 u_image_size;    // width, height in pixels (of the camera)
uniform vec2 u_viewport_origin;  // pixel offset of the camera image in the framebuffer (x right, y down)
uniform vec2 u_target_size;   // framebuffer size in pixels
uniform float u_near;

in vec2 in_corner;    // (-1,-1) .. (1,1)
in int in_index;      // Gaussian index, per instance, in back-to-front order

flat out vec2 v_center;   // means2d in framebuffer pixels, y down
flat out vec3 v_conic;    // inverse 2D covariance (a, b, c)
flat out vec4 v_color;    // rgb, opacity
out vec2 v_pixel;         // framebuffer pixel position of this corner, y down

const float LOW_PASS = 0.3;
const float FOV_MARGIN = 0.3;

ivec2 texel(int i) { return ivec2(i % u_tex_width, i / u_tex_width); }

void cull() {
    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // outside the clip volume
    v_center = vec2(0.0); v_conic = vec3(0.0); v_color = vec4(0.0); v_pixel = vec2(0.0);
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

    vec2 center = vec2(fx * p.x * inv_z + cx, fy * p.y * inv_z + cy) + u_viewport_origin;
    vec2 pixel = center + in_corner.x * half_extent.x * major + in_corner.y * half_extent.y * minor;
    v_center = center;
    v_conic = vec3(c, -b, a) / det;
    v_color = vec4(texelFetch(u_color, texel(in_index), 0).rgb, g0.w);
    v_pixel = pixel;
    // Pixels (y down) to NDC (y up): row 0 of the image is the top of the framebuffer.
    vec2 ndc = vec2(pixel.x / u_target_size.x * 2.0 - 1.0, 1.0 - pixel.y / u_target_size.y * 2.0);
    gl_Position = vec4(ndc, 0.0, 1.0);
}
