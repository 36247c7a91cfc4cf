#version 460
// The `firefly_spread` pass (parallax_passes::firefly, shaders/firefly.glsl): a pixel with a
// hit keeps its kept fraction and gathers the shares of the donors within FIREFLY_RADIUS
// (each donor counted this pixel among its receivers: both have a hit); pixels without a hit
// neither give nor receive. In place: each invocation reads and writes its own texel only.
#include "firefly.glsl"

// The shares of the tile's texels (the group's own kept fractions in .a).
shared vec4 tile_share[FIREFLY_TILE_TEXELS];

void load_tile() {
    for (uint i = gl_LocalInvocationIndex; i < FIREFLY_TILE_TEXELS; i += gl_WorkGroupSize.x * gl_WorkGroupSize.y) {
        ivec2 q = firefly_tile_texel(i);
        // Texels it may not read are never gathered (off the view, or past the halo of rows
        // no pixel of the band reaches).
        tile_share[i] = firefly_tile_readable(q) ? imageLoad(images[pc.share], q) : vec4(0.0);
    }
    barrier();
}

void main() {
    // Every invocation helps load the tile before any may leave.
    load_tile();
    ivec2 p = ivec2(gl_GlobalInvocationID.x, pc.y0 + gl_GlobalInvocationID.y);
    if (p.x >= int(pc.width) || p.y >= int(pc.y1) || !firefly_hit(p)) {
        return;
    }
    vec4 own = imageLoad(images[pc.radiance], p);
    float kept = tile_share[firefly_tile_index(p)].a;
    vec3 gathered = vec3(0.0);
    for (int dy = -FIREFLY_RADIUS; dy <= FIREFLY_RADIUS; ++dy) {
        for (int dx = -FIREFLY_RADIUS; dx <= FIREFLY_RADIUS; ++dx) {
            ivec2 q = p + ivec2(dx, dy);
            if ((dx != 0 || dy != 0) && firefly_in_view(q)) {
                gathered += tile_share[firefly_tile_index(q)].rgb;
            }
        }
    }
    // A pixel that is no donor keeps everything (kept = 1): its own value is unchanged bit for
    // bit where nothing around it gave.
    vec3 rgb = kept < 1.0 ? own.rgb * kept : own.rgb;
    imageStore(images[pc.radiance], p, vec4(rgb + gathered, own.a));
}
