#version 330 core
// Projection pass (transform feedback, one invocation per Gaussian, in back-to-front order): the same EWA
// projection as gstyle_core.raster (3DGS maths): Jacobian of the perspective projection at the mean with x/z, y/z
// clamped to the field of view widened by 30 %, +0.3 px^2 on the 2D covariance diagonal, 3-sigma cut-off.
// Pixel convention (OpenCV, as gsplat): means2d = (fx X/Z + cx, fy Y/Z + cy), image y down.
// The draw pass (splat.vert) only places the 4 corners of each projected splat's quad; colours stay out of this
// pass (streamed colours and the compare view's second colour layer reuse one projection), except the original
// scene's view-dependent colour: with SH coefficients (uploaded once) it is evaluated here, once per camera, with
// gstyle_core/raster/sh.py's conventions (3DGS order and constants, +0.5, clamp at 0).

// Geometry textures (one texel per Gaussian). Sigma_3D = M M^T with M = R S (rotation times scales).
uniform sampler2D u_geom0;   // mean.xyz, opacity (float32 in both layouts)
#ifdef COMPACT_GEOMETRY
uniform sampler2D u_geom1;   // unit quaternion w, x, y, z (half floats)
uniform sampler2D u_geom2;   // scales times 2^k (half floats), -
uniform float u_scale_unit;  // 2^-k: the scene's power of two that keeps the scales in half precision's normal range
#else
uniform sampler2D u_geom1;   // the three columns of M (float32)
uniform sampler2D u_geom2;
uniform sampler2D u_geom3;
#endif
uniform int u_tex_width;
uniform mat4 u_world_to_cam;  // OpenCV axes, column-major as uploaded
uniform vec4 u_intrinsics;    // fx, fy, cx, cy
uniform vec2 u_image_size;    // width, height in pixels (of the camera)
uniform vec2 u_viewport_origin;  // pixel offset of the camera image in the framebuffer (x right, y down)
uniform float u_near;
uniform sampler2DArray u_sh;  // SH coefficients, coefficient-major (c0.rgb c1.rgb ...): layer j = floats 4j..4j+3
uniform int u_sh_degree;      // 1-3 (the SH_COLOUR variant)
uniform vec3 u_camera_pos;    // world position of the camera (view direction = mean - camera)

in int in_index;      // Gaussian index, in back-to-front order

out vec2 out_center;   // means2d in framebuffer pixels, y down
out vec4 out_conic;    // inverse 2D covariance (a, b, c), opacity
out vec4 out_axes;     // the quad's half axes in pixels: major * extent, minor * extent; zero = culled
#ifdef SH_COLOUR
out vec3 out_rgb;      // view-dependent colour from SH (only in the variant for a scene with SH)
#endif

const float LOW_PASS = 0.3;
const float FOV_MARGIN = 0.3;

ivec2 texel(int i) { return ivec2(i % u_tex_width, i / u_tex_width); }

void cull() {
    out_center = vec2(0.0); out_conic = vec4(0.0); out_axes = vec4(0.0);
#ifdef SH_COLOUR
    out_rgb = vec3(0.0);
#endif
}

const float C0 = 0.28209479177387814;
const float C1 = 0.4886025119029199;
const float C2[5] = float[5](1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792,
                             0.5462742152960396);
const float C3[7] = float[7](-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
                             -0.4570457994644658, 1.445305721320277, -0.5900435899266435);

// The SH basis (3DGS order) at unit direction d, degree 0-3; unused entries are zero.
void sh_basis(vec3 d, int degree, out float b[16]) {
    float x = d.x, y = d.y, z = d.z;
    for (int k = 0; k < 16; ++k) b[k] = 0.0;
    b[0] = C0;
    if (degree >= 1) { b[1] = -C1 * y; b[2] = C1 * z; b[3] = -C1 * x; }
    if (degree >= 2) {
        float xx = x * x, yy = y * y, zz = z * z;
        b[4] = C2[0] * x * y; b[5] = C2[1] * y * z; b[6] = C2[2] * (2.0 * zz - xx - yy);
        b[7] = C2[3] * x * z; b[8] = C2[4] * (xx - yy);
        if (degree >= 3) {
            b[9] = C3[0] * y * (3.0 * xx - yy); b[10] = C3[1] * x * y * z; b[11] = C3[2] * y * (4.0 * zz - xx - yy);
            b[12] = C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy); b[13] = C3[4] * x * (4.0 * zz - xx - yy);
            b[14] = C3[5] * z * (xx - yy); b[15] = C3[6] * x * (xx - 3.0 * yy);
        }
    }
}

// max(0, sum_k basis_k(dir) coeff_k + 0.5) of Gaussian i seen from u_camera_pos (sh.py's eval_sh_colors).
vec3 sh_colour(int i, vec3 mean) {
    int count = (u_sh_degree + 1) * (u_sh_degree + 1);
    float c[48];
    for (int j = 0; j < (3 * count + 3) / 4; ++j) {
        vec4 t = texelFetch(u_sh, ivec3(texel(i), j), 0);
        c[4 * j] = t.x; c[4 * j + 1] = t.y; c[4 * j + 2] = t.z; c[4 * j + 3] = t.w;
    }
    vec3 offset = mean - u_camera_pos;
    vec3 dir = offset / sqrt(max(dot(offset, offset), 1e-24));
    float b[16];
    sh_basis(dir, u_sh_degree, b);
    vec3 rgb = vec3(0.5);
    for (int k = 0; k < count; ++k) rgb += b[k] * vec3(c[3 * k], c[3 * k + 1], c[3 * k + 2]);
    return max(rgb, vec3(0.0));
}

// M = R S of Gaussian i (R from the quaternion as gstyle_core's rotation_matrices, in the compact layout).
mat3 cov_factor(int i) {
#ifdef COMPACT_GEOMETRY
    vec4 q = texelFetch(u_geom1, texel(i), 0);
    q /= max(length(q), 1e-12);  // renormalised after the rounding to half floats
    float w = q.x, x = q.y, y = q.z, z = q.w;
    vec3 s = texelFetch(u_geom2, texel(i), 0).xyz * u_scale_unit;
    return mat3(vec3(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)) * s.x,
                vec3(2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x)) * s.y,
                vec3(2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)) * s.z);
#else
    return mat3(texelFetch(u_geom1, texel(i), 0).xyz, texelFetch(u_geom2, texel(i), 0).xyz,
                texelFetch(u_geom3, texel(i), 0).xyz);
#endif
}

void main() {
    vec4 g0 = texelFetch(u_geom0, texel(in_index), 0);
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
    mat3x2 G = J * W * cov_factor(in_index);   // Sigma_2D = G G^T
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
#ifdef SH_COLOUR
    out_rgb = sh_colour(in_index, g0.xyz);
#endif
}
