// Subsampled hole filling (parallax_passes::hole_subsample, `--hole-fill subsampled`): what
// compact_holes_subsampled.comp (which hole pixels are traced) and hole_reconstruct.comp (the
// untraced ones from their traced neighbours) must agree on, bit for bit: the per-pixel flags
// and the G-buffer similarity that decides both where a traced neighbour may stand in for a
// pixel and how much it weighs.
#ifndef PARALLAX_HOLE_SUBSAMPLE_GLSL
#define PARALLAX_HOLE_SUBSAMPLE_GLSL

// The `hole_sampling` image (R32u), written by compact_holes_subsampled.comp over its band.
const uint HOLE_NONE = 0u;          // not a hole
const uint HOLE_TRACED = 1u;        // a hole pixel path traced this frame
const uint HOLE_RECONSTRUCTED = 2u; // a hole pixel reconstructed from traced neighbours

// Two hit points are one smooth surface where their shading normals are within ~26° and each
// lies within 2 % of the pixel's depth of the other's tangent plane (a plane distance, not a
// depth difference, so a slanted floor stays one surface); a silhouette or a crease is not.
const float HOLE_SIMILAR_COS = 0.9;
const float HOLE_PLANE_TOLERANCE = 0.02;

// How much traced neighbour q (position_depth, normal) may stand in for pixel p; 0 where it may
// not. Either without a hit (w = 0) is never similar. Where similar the weight is at least
// 0.9^8 / 2 = 0.215, so a pixel with a similar traced neighbour always has a positive sum.
float hole_similarity(vec4 position_p, vec3 normal_p, vec4 position_q, vec3 normal_q) {
    if (position_p.w <= 0.0 || position_q.w <= 0.0) {
        return 0.0;
    }
    float cos_normals = dot(normal_p, normal_q);
    vec3 offset = position_q.xyz - position_p.xyz;
    float tolerance = HOLE_PLANE_TOLERANCE * position_p.w;
    float plane = max(abs(dot(normal_p, offset)), abs(dot(normal_q, offset)));
    if (cos_normals < HOLE_SIMILAR_COS || !(plane <= tolerance)) {
        return 0.0;
    }
    float c2 = cos_normals * cos_normals;
    float c4 = c2 * c2;
    return c4 * c4 * (1.0 - 0.5 * plane / tolerance);
}

#endif
