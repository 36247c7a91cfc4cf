#version 460
// The `firefly_bound` pass (parallax_passes::firefly, shaders/firefly.glsl): per pixel with a
// hit, the bound of its neighbourhood (mean + k standard deviations of its neighbours'
// luminance, itself excluded, so a firefly does not raise its own bound, times sqrt(n) on a
// still camera's n-th frame); over it, the pixel's share image holds (excess rgb / receivers,
// kept fraction), else (0, 0, 0, 1).
#include "firefly.glsl"

// Whether this view's camera is last frame's, bit for bit, with valid history: the frame joins
// SVGF's running mean (the same test as svgf_temporal.comp's).
bool camera_still() {
    if (frame.history_valid == 0u || (pc.flags & FIREFLY_CAMERAS) == 0u) {
        return false;
    }
    ViewCameras cameras = pc.block.views[pc.view];
    return cameras.current.view_proj == cameras.previous.view_proj;
}

// The window's inputs per tile texel: whether it has a hit, and if so its luminance (computed
// once per texel rather than once per tap; the same expression, so the same bits).
shared bool tile_hit[FIREFLY_TILE_TEXELS];
shared float tile_luminance[FIREFLY_TILE_TEXELS];

void load_tile() {
    for (uint i = gl_LocalInvocationIndex; i < FIREFLY_TILE_TEXELS; i += gl_WorkGroupSize.x * gl_WorkGroupSize.y) {
        ivec2 q = firefly_tile_texel(i);
        bool hit = firefly_tile_readable(q) && firefly_hit(q);
        tile_hit[i] = hit;
        // Radiance is read only where there is a hit, as the taps did.
        tile_luminance[i] = hit ? firefly_luminance(imageLoad(images[pc.radiance], q).rgb) : 0.0;
    }
    barrier();
}

void main() {
    // Every invocation helps load the tile before any may leave.
    load_tile();
    ivec2 p = ivec2(gl_GlobalInvocationID.x, pc.y0 + gl_GlobalInvocationID.y);
    if (p.x >= int(pc.width) || p.y >= int(pc.y1)) {
        return;
    }
    float n = camera_still() ? imageLoad(images[pc.frames_before], p).x + 1.0 : 1.0;
    imageStore(images[pc.frames], p, vec4(n));
    vec4 result = vec4(0.0, 0.0, 0.0, 1.0);
    vec3 rgb = imageLoad(images[pc.radiance], p).rgb;
    float l = firefly_luminance(rgb);
    // Non-finite or negative radiance is left to the denoiser's sanitising, never spread.
    bool judged = tile_hit[firefly_tile_index(p)] && !isnan(l) && !isinf(l) && all(greaterThanEqual(rgb, vec3(0.0)));
    if (judged) {
        uint receivers = 0u;
        uint counted = 0u;
        // Welford's running mean and sum of squared deviations: a flat neighbourhood gets a
        // deviation of 0, where E[l²] - E[l]² would leave rounding noise of its size.
        float mean = 0.0;
        float m2 = 0.0;
        for (int dy = -FIREFLY_RADIUS; dy <= FIREFLY_RADIUS; ++dy) {
            for (int dx = -FIREFLY_RADIUS; dx <= FIREFLY_RADIUS; ++dx) {
                ivec2 q = p + ivec2(dx, dy);
                if ((dx == 0 && dy == 0) || !firefly_in_view(q) || !tile_hit[firefly_tile_index(q)]) {
                    continue;
                }
                receivers += 1u;
                float lq = tile_luminance[firefly_tile_index(q)];
                if (!isnan(lq) && !isinf(lq)) {
                    counted += 1u;
                    float d = lq - mean;
                    mean += d / float(counted);
                    m2 += d * (lq - mean);
                }
            }
        }
        if (counted >= pc.min_neighbours) {
            float sigma = sqrt(max(m2 / float(counted), 0.0));
            float bound = mean + pc.k * sqrt(n) * sigma;
            if (l > bound) {
                float kept = bound / l;
                result = vec4(rgb * (1.0 - kept) / float(receivers), kept);
            }
        }
    }
    imageStore(images[pc.share], p, result);
}
