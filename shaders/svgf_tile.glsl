// The shared-memory tile of the à-trous kernels: (SVGF_TILE)² entries of one phase of the step
// (svgf_tile_base in svgf.glsl) read once per workgroup. Define SVGF_TILE (the largest tile
// side the kernel loads) before including.
//   in0: (radiance rgb, variance), in1 `svgf_guide`, in2 `svgf_albedo`: whole view
#ifndef PARALLAX_SVGF_TILE_GLSL
#define PARALLAX_SVGF_TILE_GLSL

#include "svgf.glsl"

shared vec4 tile_radiance[SVGF_TILE * SVGF_TILE]; // radiance rgb, variance
shared vec4 tile_albedo[SVGF_TILE * SVGF_TILE];   // effective albedo rgb, illumination luminance
shared vec4 tile_guide[SVGF_TILE * SVGF_TILE];    // depth (0: no hit or outside), gradient x, y, unused
shared vec4 tile_normal[SVGF_TILE * SVGF_TILE];   // normal xyz, the variance the weights use

// Reads the size² entries origin + step * (i, j) (row-major); entries outside the image get
// depth 0, which every tap loop skips.
void svgf_load_tile(ivec2 origin, int step, int size) {
    for (uint e = gl_LocalInvocationIndex; e < uint(size * size); e += 64u) {
        ivec2 q = origin + step * ivec2(int(e % uint(size)), int(e / uint(size)));
        vec4 radiance = vec4(0.0);
        vec4 guide = vec4(0.0);
        vec3 albedo = vec3(1.0);
        if (svgf_inside(q)) {
            radiance = imageLoad(images[pc.in0], q);
            guide = imageLoad(images[pc.in1], q);
            albedo = imageLoad(images[pc.in2], q).rgb;
        }
        bool hit = guide.x > 0.0;
        tile_radiance[e] = radiance;
        tile_albedo[e] = vec4(albedo, hit ? svgf_illumination_luminance(radiance.rgb, albedo) : 0.0);
        tile_guide[e] = vec4(hit ? guide.x : 0.0, guide.yz, 0.0);
        tile_normal[e] = vec4(hit ? svgf_unpack_normal(guide.w) : vec3(0.0), radiance.a);
    }
}

// svgf_edge_weight of entries e and f, `offset` pixels apart.
float svgf_tile_weight(int e, int f, vec2 offset) {
    return svgf_edge_weight(tile_guide[e].x, tile_guide[f].x, tile_guide[e].yz, tile_guide[f].yz, tile_normal[e].xyz,
                            tile_normal[f].xyz, tile_albedo[e].w, tile_albedo[f].w, tile_normal[e].w,
                            tile_normal[f].w, offset);
}

// Where pixel p without a hit goes: on the last iteration its radiance, else its texel as is.
void svgf_pass_through(ivec2 p, vec4 texel) {
    if ((pc.flags & SVGF_LAST) != 0u) {
        vec4 radiance = imageLoad(images[pc.radiance], p);
        imageStore(images[pc.out0], p, vec4(svgf_sanitize(radiance.rgb), radiance.a));
    } else {
        imageStore(images[pc.out0], p, texel);
    }
}

#endif
