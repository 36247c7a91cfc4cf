#version 460
// The `firefly_spread` pass (parallax_passes::firefly, shaders/firefly.glsl): a pixel with a
// hit keeps its kept fraction and gathers the shares of the donors within FIREFLY_RADIUS
// (each donor counted this pixel among its receivers: both have a hit); pixels without a hit
// neither give nor receive. In place: each invocation reads and writes its own texel only.
#include "firefly.glsl"

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.x, pc.y0 + gl_GlobalInvocationID.y);
    if (p.x >= int(pc.width) || p.y >= int(pc.y1) || !firefly_hit(p)) {
        return;
    }
    vec4 own = imageLoad(images[pc.radiance], p);
    float kept = imageLoad(images[pc.share], p).a;
    vec3 gathered = vec3(0.0);
    for (int dy = -FIREFLY_RADIUS; dy <= FIREFLY_RADIUS; ++dy) {
        for (int dx = -FIREFLY_RADIUS; dx <= FIREFLY_RADIUS; ++dx) {
            ivec2 q = p + ivec2(dx, dy);
            if ((dx != 0 || dy != 0) && firefly_in_view(q)) {
                gathered += imageLoad(images[pc.share], q).rgb;
            }
        }
    }
    // A pixel that is no donor keeps everything (kept = 1): its own value is unchanged bit for
    // bit where nothing around it gave.
    vec3 rgb = kept < 1.0 ? own.rgb * kept : own.rgb;
    imageStore(images[pc.radiance], p, vec4(rgb + gathered, own.a));
}
