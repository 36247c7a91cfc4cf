#version 460
// SVGF, step 1 (`svgf_temporal`): temporal accumulation and variance estimate in one pass. It
// accumulates illumination (radiance / albedo) and the first two moments of its luminance
// through `motion`, estimates the variance that steers the à-trous iterations, and packs what
// they read of the G-buffer.
//   radiance, albedo, normal, position: own pixel and, for short histories, the 7×7 around it
//   (depth also the 4 neighbours, for the gradient); motion: own pixel
//   in0 `svgf_prev_color` (illumination rgb, length), in1 `svgf_prev_moments` (m1, m2, depth,
//   packed normal): the taps through `motion`, at most HISTORY_REACH rows from the pixel; for an
//   instance over its whole view, the history `svgf_color` and `svgf_moments` themselves (the
//   same texels)
//   out0 `svgf_variance`: (illumination rgb, variance)
//   out1 `svgf_moments`: (m1, m2, linear depth, packed normal), read as history next frame
//   out2 `svgf_guide`: (linear depth, depth gradient x, y, packed normal)
//   out3 `svgf_albedo`: (effective albedo rgb, history length)
//   in2 `svgf_accum` history (mean illumination rgb, frame count n), in3 `svgf_accum_m2` history
//   (mean squared illumination luminance): own pixel only
//   out4 `svgf_accum`, out5 `svgf_accum_m2`: the same, read as history next frame
// Accumulation: while the view's camera is still (this frame's camera is last frame's, bit for
// bit, and history is valid: no cut, no new plan) each pixel's illumination is the exact running
// mean of every frame since the last change, weight 1/n with n the frames since then, stored per
// pixel; so a still light field converges to the path-traced reference instead of to an
// exponential average. A still camera reprojects every pixel onto itself, so the mean is read at
// the pixel's own texel (own rows: a band over devices reads what one device would). A frame
// that is not still (motion, a cut, a new plan, the first frame) restarts the mean with its own
// sample (n = 1), so what follows a change depends on nothing before it: bit for bit
// what a fresh start gives. Such a frame shows today's exponential blend through `motion`. The
// variance that steers the à-trous iterations is then that of the mean, σ² / n from the
// accumulated moments (times MIN_LENGTH, so that at MIN_LENGTH frames it is the per-sample
// variance the filter is tuned for): it shrinks as n grows, the edge-stopping tightens and the
// filter backs off, so the picture approaches the reference rather than a filtered image.
// Fireflies: no sample is clamped. Clamps against the pixel's own temporal statistics, tried
// and measured with passes/tests/lavapipe_svgf_mean.rs (worst frame of 30, a channel's mean):
// a sample moving the value by at most K standard errors of it (bound μ + K σ √n on the running
// mean) lowered the default scene by 0.97 / 0.82 / 0.65 % (K = 3 / 4 / 6) and Sponza at 96×54
// by 7.8 % (K = 4); by at most one sample standard deviation (μ + σ n) 1.1 % and 8.7 %. At 1 spp a pixel's first bright sample has
// no variance before it to be measured against, and on Sponza such rare paths (sun through the
// arcades) carry a large share of the light. Instead the second moment accumulates every sample,
// so a bright one raises its pixel's variance and the energy-conserving à-trous iterations
// spread it over its neighbours: no energy is lost, and the mean stays exact.
// Temporal: the previous frame is sampled bilinearly at the motion vector; a tap counts only if
// it is inside the image, had history, and saw the same surface (depth against the gradient,
// normal within ~25°), and lies within HISTORY_REACH rows of the pixel: a surface that moved
// further in one frame restarts, as a disocclusion does. The bound is what lets a band of rows
// on one device receive only the history rows around it (a halo) instead of whole views, and it
// holds on every device count, so a band reads what one device would. Blending in illumination keeps a texture from being smeared by the
// bilinear taps. Without any valid tap the pixel restarts (length 1). Exponential moving average
// (Schied: α = 0.2 for colour and moments), 1/n while the history is shorter than 1/α frames.
// Variance: from the temporal moments with 4 frames of history or more; with fewer it is
// estimated spatially (Schied §4.2) from this frame's illumination luminance of a 7×7
// neighbourhood weighted by depth, normal and luminance (Schied uses the neighbours' temporal
// moments, which would need a pass of their own), times 4 / length so the first frames are
// filtered harder. The illumination stays the pixel's own: Schied also replaces it by the
// neighbourhood's bilateral mean, a filter that does not conserve energy (at depth edges, image
// borders, next to dark albedo) on the very frames with the least history; the energy-conserving
// à-trous iterations do that smoothing instead. A workgroup with short histories reads its
// 14×14 neighbourhood into shared memory once.
// Pixels without a hit keep their radiance (variance 0, length 0), on a still camera its running
// mean (in `svgf_accum` too); their guide depth is 0, which every later pass skips, and the à-trous
// iterations pass that texel through (pass_through in svgf_atrous.glsl): measured on the default
// scene at 32×24, the error after 64 still frames is 1.1e-3 with it against 2.2e-3 when the last
// iteration wrote each frame's own radiance.
#include "svgf.glsl"

const float ALPHA_COLOR = 0.2;
const float ALPHA_MOMENTS = 0.2;
// History lengths are capped: beyond 1/α they change nothing but must not grow without bound.
// (The accumulated frame count is not: its 1/n weight is what makes the mean exact.)
const float MAX_LENGTH = 64.0;
// Reprojection tolerances: depth within this many gradient steps plus this fraction of depth;
// normals within acos(MIN_NORMAL_DOT).
const float DEPTH_GRADIENT_STEPS = 2.0;
const float DEPTH_RELATIVE = 0.02;
const float MIN_NORMAL_DOT = 0.9;
// The spatial variance estimate: below this history length, over (2 RADIUS + 1)², with
// luminance edge-stopping σ_l (Schied's reference code: 10), on illumination luminance.
const float MIN_LENGTH = 4.0;
const int RADIUS = 3;
// Rows a history tap through `motion` may lie from its pixel (parallax_passes::svgf::HISTORY_REACH).
const int HISTORY_REACH = 16;
const int TILE = 8 + 2 * RADIUS;
const float SIGMA_L_SPATIAL = 10.0;

shared vec4 tile_geometry[TILE * TILE]; // normal xyz, depth (0: no hit or outside)
shared float tile_luminance[TILE * TILE];
shared uint any_short;

// What the temporal step leaves for the variance estimate.
struct Temporal {
    vec3 illumination;
    float length_;
    vec2 moments;
};

// One axis of the screen-space depth gradient at a pixel of depth z > 0, from the depths of its
// neighbours before and after it along the axis (0 off the image, see neighbour_depth): of the
// forward and backward differences, the smaller in magnitude, so that a depth edge on one side
// does not inflate it; a side without a hit (or off the image) is not used.
float depth_slope(float z, float before, float after) {
    float best = 0.0;
    bool found = false;
    // Written so that NaN fails too.
    if (before > 0.0) {
        best = -(before - z);
        found = true;
    }
    if (after > 0.0) {
        float d = after - z;
        if (!found || abs(d) < abs(best)) {
            best = d;
        }
    }
    return best;
}

// The depth at q, 0 off the image (no hit).
float neighbour_depth(ivec2 q) {
    return svgf_inside(q) ? imageLoad(images[pc.position], q).w : 0.0;
}

// Illumination luminance of this frame's sample at q (a pixel with a hit).
float sample_luminance(vec3 radiance_texel, vec3 albedo_texel) {
    vec3 radiance = svgf_sanitize(radiance_texel);
    vec3 albedo = svgf_effective_albedo(albedo_texel);
    return min(svgf_illumination_luminance(radiance, albedo), MAX_VALUE);
}

// Whether this view's camera is last frame's, bit for bit, with valid history: the frame
// continues the accumulation.
// Without cameras (a graph run without a frame block) no frame is still.
bool camera_still() {
    if (frame.history_valid == 0u || (pc.flags & SVGF_CAMERAS) == 0u) {
        return false;
    }
    ViewCameras cameras = pc.block.views[pc.view];
    return cameras.current.view_proj == cameras.previous.view_proj;
}

// The running mean of pixel p after this frame's sample (illumination, luminance l) on a still
// camera, from its accumulation history `previous` (mean, n) and mean squared luminance
// `previous_m2`; albedo is the pixel's effective albedo (the same every still frame).
Temporal accumulate_still(vec3 illumination, float l, vec4 previous, float previous_m2, vec3 albedo) {
    float n = previous.a + 1.0;
    vec3 mean = previous.rgb + (illumination - previous.rgb) / n;
    float m2 = previous_m2 + (min(l * l, MAX_VALUE) - previous_m2) / n;
    return Temporal(mean, n, vec2(svgf_illumination_luminance(albedo * mean, albedo), m2));
}

// The exponentially blended illumination and moments of pixel p (depth z > 0, normal n) from
// this frame's radiance and the previous frame's history through `motion`.
Temporal blend(ivec2 p, float z, vec3 n, vec2 gradient, vec3 radiance, vec3 albedo, vec2 motion) {
    float l = min(svgf_illumination_luminance(radiance, albedo), MAX_VALUE);
    float tolerance = DEPTH_GRADIENT_STEPS * (abs(gradient.x) + abs(gradient.y)) + DEPTH_RELATIVE * z;
    // Motion is in pixels of the previous frame with centres at i + 0.5.
    vec3 prev_illum = vec3(0.0);
    vec2 prev_moments = vec2(0.0);
    float prev_length = 0.0;
    float weight_sum = 0.0;
    // Invalid history (first frame, a reset) has nothing to reuse: the copies are 0 then, the
    // history itself is what the other half held before.
    if (frame.history_valid != 0u && motion.x >= 0.0 && motion.y >= 0.0 && !any(isnan(motion))
        && !any(isinf(motion))) {
        vec2 at = motion - 0.5;
        ivec2 base = ivec2(floor(at));
        vec2 f = at - vec2(base);
        for (int k = 0; k < 4; k++) {
            ivec2 o = ivec2(k & 1, k >> 1);
            float w = (o.x == 1 ? f.x : 1.0 - f.x) * (o.y == 1 ? f.y : 1.0 - f.y);
            ivec2 q = base + o;
            // Zero-weight taps are skipped, so a pixel centre reads exactly one texel.
            if (w <= 0.0 || !svgf_inside(q) || abs(q.y - p.y) > HISTORY_REACH) {
                continue;
            }
            vec4 pcol = imageLoad(images[pc.in0], q);
            vec4 pm = imageLoad(images[pc.in1], q);
            if (pcol.a < 1.0 || !(pm.z > 0.0) || abs(pm.z - z) > tolerance
                || dot(svgf_unpack_normal(pm.w), n) < MIN_NORMAL_DOT) {
                continue;
            }
            prev_illum += w * pcol.rgb;
            prev_moments += w * pm.xy;
            prev_length += w * pcol.a;
            weight_sum += w;
        }
    }
    Temporal t = Temporal(min(radiance / albedo, vec3(MAX_VALUE)), 1.0, vec2(l, l * l));
    if (weight_sum > 1e-3) {
        t.length_ = min(prev_length / weight_sum + 1.0, MAX_LENGTH);
        t.illumination = mix(prev_illum / weight_sum, t.illumination, max(ALPHA_COLOR, 1.0 / t.length_));
        t.moments = mix(prev_moments / weight_sum, t.moments, max(ALPHA_MOMENTS, 1.0 / t.length_));
    }
    return t;
}

// An entry's four texels are requested together, whether it has a hit or not (the normal and
// samples of an entry without one are then dropped): one wait for memory an entry, not two.
void load_tile(ivec2 origin) {
    for (uint e = gl_LocalInvocationIndex; e < uint(TILE * TILE); e += 64u) {
        ivec2 q = origin + ivec2(int(e % uint(TILE)), int(e / uint(TILE)));
        float zq = 0.0;
        vec3 normal = vec3(0.0);
        vec3 radiance = vec3(0.0);
        vec3 albedo = vec3(0.0);
        if (svgf_inside(q)) {
            zq = imageLoad(images[pc.position], q).w;
            normal = imageLoad(images[pc.normal], q).xyz;
            radiance = imageLoad(images[pc.radiance], q).rgb;
            albedo = imageLoad(images[pc.albedo], q).rgb;
        }
        bool hit = zq > 0.0;
        tile_geometry[e] = vec4(hit ? normal : vec3(0.0), hit ? zq : 0.0);
        tile_luminance[e] = hit ? sample_luminance(radiance, albedo) : 0.0;
    }
}

// Schied's spatial variance estimate for pixel p of the workgroup (tile centre c).
float spatial_variance(int c, Temporal t, vec2 gradient) {
    vec4 centre = tile_geometry[c];
    float l = t.moments.x;
    // The centre counts with weight 1 whatever its normal, so the sums never vanish.
    vec2 moment_sum = t.moments;
    float weight_sum = 1.0;
    for (int dy = -RADIUS; dy <= RADIUS; dy++) {
        for (int dx = -RADIUS; dx <= RADIUS; dx++) {
            int e = c + dy * TILE + dx;
            vec4 q = tile_geometry[e];
            if ((dx == 0 && dy == 0) || !(q.w > 0.0)) {
                continue;
            }
            float lq = tile_luminance[e];
            float w = svgf_geometry_weight(centre.w, q.w, gradient, gradient, centre.xyz, q.xyz, vec2(dx, dy))
                * exp(-abs(l - lq) / SIGMA_L_SPATIAL);
            moment_sum += w * vec2(lq, lq * lq);
            weight_sum += w;
        }
    }
    moment_sum /= weight_sum;
    return max(0.0, moment_sum.y - moment_sum.x * moment_sum.x) * (MIN_LENGTH / max(t.length_, 1.0));
}

void main() {
    ivec2 p = svgf_pixel();
    bool still = camera_still();
    // What the pixel reads at its own texel, its neighbours' depths (the gradient) and, on a
    // still camera, its accumulation history, all requested before any is used, hit or not:
    // the pass waits for memory once here and once for the history through `motion`, where
    // reading each where it is used (after the depth told a hit, then after the motion) waited
    // three or four times. A pixel without a hit uses its radiance and accumulation only; on a
    // still camera the motion is read only where the accumulation restarts (below).
    float z = 0.0;
    vec3 radiance = vec3(0.0);
    vec3 albedo_texel = vec3(0.0);
    vec3 n = vec3(0.0);
    vec2 motion = vec2(0.0);
    vec4 depths = vec4(0.0); // left, right, up, down
    vec4 previous = vec4(0.0);
    float previous_m2 = 0.0;
    if (p.x >= 0) {
        z = imageLoad(images[pc.position], p).w;
        radiance = svgf_sanitize(imageLoad(images[pc.radiance], p).rgb);
        albedo_texel = imageLoad(images[pc.albedo], p).rgb;
        n = imageLoad(images[pc.normal], p).xyz;
        if (!still) {
            motion = imageLoad(images[pc.motion], p).xy;
        }
        depths = vec4(neighbour_depth(p - ivec2(1, 0)), neighbour_depth(p + ivec2(1, 0)),
                      neighbour_depth(p - ivec2(0, 1)), neighbour_depth(p + ivec2(0, 1)));
        if (still) {
            previous = imageLoad(images[pc.in2], p);
            previous_m2 = imageLoad(images[pc.in3], p).x;
        }
    }
    bool hit = z > 0.0;
    Temporal t = Temporal(vec3(0.0), 0.0, vec2(0.0));
    vec2 gradient = vec2(0.0);
    bool accumulating = false;
    if (hit) {
        vec3 albedo = svgf_effective_albedo(albedo_texel);
        float packed_normal = svgf_pack_normal(n);
        gradient = vec2(depth_slope(z, depths.x, depths.y), depth_slope(z, depths.z, depths.w));
        vec3 illumination = min(radiance / albedo, vec3(MAX_VALUE));
        float l = min(svgf_illumination_luminance(radiance, albedo), MAX_VALUE);
        // Written so that NaN restarts too.
        accumulating = previous.a >= 1.0;
        if (accumulating) {
            t = accumulate_still(illumination, l, previous, previous_m2, albedo);
            imageStore(images[pc.out4], p, vec4(t.illumination, t.length_));
            imageStore(images[pc.out5], p, vec4(t.moments.y, 0.0, 0.0, 0.0));
        } else {
            if (still) {
                motion = imageLoad(images[pc.motion], p).xy;
            }
            t = blend(p, z, n, gradient, radiance, albedo, motion);
            imageStore(images[pc.out4], p, vec4(illumination, 1.0));
            imageStore(images[pc.out5], p, vec4(min(l * l, MAX_VALUE), 0.0, 0.0, 0.0));
        }
        imageStore(images[pc.out1], p, vec4(t.moments, z, packed_normal));
        imageStore(images[pc.out2], p, vec4(z, gradient, packed_normal));
        imageStore(images[pc.out3], p, vec4(albedo, min(t.length_, MAX_LENGTH)));
    } else if (p.x >= 0) {
        float frames = previous.a >= 1.0 ? previous.a + 1.0 : 1.0;
        radiance = previous.a >= 1.0 ? previous.rgb + (radiance - previous.rgb) / frames : radiance;
        imageStore(images[pc.out1], p, vec4(0.0));
        imageStore(images[pc.out2], p, vec4(0.0));
        imageStore(images[pc.out3], p, vec4(0.0));
        imageStore(images[pc.out4], p, vec4(radiance, frames));
        imageStore(images[pc.out5], p, vec4(0.0));
    }
    bool short_history = hit && t.length_ < MIN_LENGTH;
    if (gl_LocalInvocationIndex == 0u) {
        any_short = 0u;
    }
    barrier();
    if (short_history) {
        atomicOr(any_short, 1u);
    }
    barrier();
    if (any_short != 0u) {
        load_tile(svgf_tile_base(1u) - ivec2(RADIUS));
    }
    barrier();
    if (p.x < 0) {
        return;
    }
    if (!hit) {
        // No albedo to divide by: the radiance as is, on a still camera its running mean (the
        // à-trous iterations let it through).
        imageStore(images[pc.out0], p, vec4(radiance, 0.0));
        return;
    }
    float variance = max(0.0, t.moments.y - t.moments.x * t.moments.x);
    if (accumulating) {
        // The variance of the mean of n frames, at MIN_LENGTH frames the per-sample one.
        variance *= MIN_LENGTH / t.length_;
    }
    if (short_history) {
        int c = (int(gl_LocalInvocationID.y) + RADIUS) * TILE + int(gl_LocalInvocationID.x) + RADIUS;
        variance = spatial_variance(c, t, gradient);
    }
    imageStore(images[pc.out0], p, vec4(t.illumination, min(variance, MAX_VALUE)));
}
