// CWBVH traversal (Ylitie, Karras, Laine, "Efficient Incoherent Ray Traversal on GPUs Through
// Compressed Wide BVHs", HPG 2017) over obvhs 0.4 `CwBvhNode`s, uploaded as they are.
//
// A transcription of obvhs's `traverse!` macro and `CwBvhNode::intersect_ray`, so that the GPU
// visits the same nodes and tests the same triangles as the CPU reference (parallax-scene
// `SceneBvh`). Node layout (80 bytes = uvec4 d[5], std430 stride 80):
//   d[0].xyz  node AABB min p (f32 bits)       d[0].w  bytes e.x, e.y, e.z, imask
//   d[1].x    child_base_idx                   d[1].y  primitive_base_idx
//   d[1].zw   child_meta[0..4], child_meta[4..8]
//   d[2]      child_min_x[0..4], [4..8], child_max_x[0..4], [4..8]; d[3] y; d[4] z
//
// The including shader declares the two buffers before including this file and names them:
//   #define BVH_NODES <buffer array of uvec4>   e.g. scene_nodes.data
//   #define BVH_TRIS  <buffer array of BvhTriangle (bvh_types.glsl)>
// and defines, anywhere in the file, the alpha-mask test for triangles whose flags have
// TRI_ALPHA_MASK set:
//   bool bvh_alpha_visible(uint bvh_primitive, vec2 barycentrics);
// A shader without alpha-masked materials can define it as `return true;`.

#ifndef BVH_TRAVERSE_GLSL
#define BVH_TRAVERSE_GLSL

#include "bvh_types.glsl"


#ifndef BVH_STACK_SIZE
#define BVH_STACK_SIZE 32
#endif

// obvhs's fixed near distance for node tests (it ignores ray tmin there).
const float BVH_NODE_EPSILON = 0.0001;
const float F32_EPSILON = 1.1920929e-07;

bool bvh_alpha_visible(uint bvh_primitive, vec2 barycentrics);

struct BvhRay {
    vec3 origin;
    vec3 dir;
    vec3 inv_dir;
    float tmin;
    float tmax;
};

struct BvhHit {
    uint primitive; // index into the BVH-ordered triangle array; 0xffffffff = miss
    float t;
    vec2 barycentrics; // weights of v1 and v2
};

// obvhs::ray::safe_inverse: tiny components map to +-1/EPSILON (Rust signum: -0.0 -> -1).
float bvh_safe_inverse(float x) {
    if (abs(x) <= F32_EPSILON) {
        return ((floatBitsToUint(x) & 0x80000000u) != 0u ? -1.0 : 1.0) / F32_EPSILON;
    }
    return 1.0 / x;
}

BvhRay bvh_make_ray(vec3 origin, vec3 dir, float tmin, float tmax) {
    BvhRay r;
    r.origin = origin;
    r.dir = dir;
    r.inv_dir = vec3(bvh_safe_inverse(dir.x), bvh_safe_inverse(dir.y), bvh_safe_inverse(dir.z));
    r.tmin = tmin;
    r.tmax = tmax;
    return r;
}

// Moeller-Trumbore exactly as parallax_scene::bvh::intersect_triangle (two-sided, sign-bit
// inside test). Returns t, or -1 on a miss; writes the barycentrics of v1 and v2.
// `precise` forbids fused multiply-adds, which the CPU (x86 SSE, no FMA) does not use either;
// without it near-ties between coplanar triangles can resolve differently on the GPU.
float bvh_intersect_triangle(BvhTriangle tri, BvhRay ray, out vec2 bary) {
    precise vec3 e1 = tri.v0 - tri.v1;
    precise vec3 e2 = tri.v2 - tri.v0;
    precise vec3 n = cross(e1, e2);
    precise vec3 c = tri.v0 - ray.origin;
    precise vec3 r = cross(ray.dir, c);
    precise float inv_det = 1.0 / dot(n, ray.dir);
    precise float u = dot(r, e2) * inv_det;
    precise float v = dot(r, e1) * inv_det;
    precise float w = 1.0 - u - v;
    bary = vec2(u, v);
    bool outside = ((floatBitsToUint(u) | floatBitsToUint(v) | floatBitsToUint(w)) & 0x80000000u) != 0u;
    if (inv_det == 0.0 || isinf(inv_det) || isnan(inv_det) || outside) {
        return -1.0;
    }
    precise float t = dot(n, c) * inv_det;
    return (t >= ray.tmin && t <= ray.tmax) ? t : -1.0;
}

// Ray octant, inverted and replicated in each byte (obvhs ray_get_octant_inv4).
uint bvh_octant_inv4(vec3 dir) {
    return (dir.x < 0.0 ? 0u : 0x04040404u) | (dir.y < 0.0 ? 0u : 0x02020202u) | (dir.z < 0.0 ? 0u : 0x01010101u);
}

uint bvh_byte(uint word, uint i) {
    return (word >> (8u * i)) & 0xffu;
}

// Child hit mask of a node: high byte = internal children in traversal-priority bit positions,
// low 24 bits = leaf triangles (CwBvhNode::intersect_ray_basic). Four children at a time: one
// uint of each 8-byte array holds a byte per child.
uint bvh_intersect_node(uvec4 d0, uvec4 d1, uvec4 dx, uvec4 dy, uvec4 dz, BvhRay ray, uint oct_inv4) {
    vec3 p = uintBitsToFloat(d0.xyz);
    vec3 extent = uintBitsToFloat(uvec3(bvh_byte(d0.w, 0u), bvh_byte(d0.w, 1u), bvh_byte(d0.w, 2u)) << 23);
    vec3 adj_dir_inv = extent * ray.inv_dir;
    vec3 adj_origin = (p - ray.origin) * ray.inv_dir;
    bool rdx = ray.dir.x < 0.0;
    bool rdy = ray.dir.y < 0.0;
    bool rdz = ray.dir.z < 0.0;
    const uvec4 shifts = uvec4(0u, 8u, 16u, 24u);
    uint hit_mask = 0u;
    for (uint w = 0u; w < 2u; w++) {
        uint meta4 = w == 0u ? d1.z : d1.w;
        uint inner4 = ((meta4 & (meta4 << 1u)) & 0x10101010u) >> 4u;
        uint bit_index4 = (meta4 ^ (oct_inv4 & (inner4 * 0xffu))) & 0x1f1f1f1fu;
        uint child_bits4 = (meta4 >> 5u) & 0x07070707u;
        // Near and far planes per axis: swap the min and max words by the ray's sign once.
        uint near_x = rdx ? dx[2u + w] : dx[w];
        uint far_x = rdx ? dx[w] : dx[2u + w];
        uint near_y = rdy ? dy[2u + w] : dy[w];
        uint far_y = rdy ? dy[w] : dy[2u + w];
        uint near_z = rdz ? dz[2u + w] : dz[w];
        uint far_z = rdz ? dz[w] : dz[2u + w];
        vec4 tmin_x = vec4((uvec4(near_x) >> shifts) & 0xffu) * adj_dir_inv.x + adj_origin.x;
        vec4 tmax_x = vec4((uvec4(far_x) >> shifts) & 0xffu) * adj_dir_inv.x + adj_origin.x;
        vec4 tmin_y = vec4((uvec4(near_y) >> shifts) & 0xffu) * adj_dir_inv.y + adj_origin.y;
        vec4 tmax_y = vec4((uvec4(far_y) >> shifts) & 0xffu) * adj_dir_inv.y + adj_origin.y;
        vec4 tmin_z = vec4((uvec4(near_z) >> shifts) & 0xffu) * adj_dir_inv.z + adj_origin.z;
        vec4 tmax_z = vec4((uvec4(far_z) >> shifts) & 0xffu) * adj_dir_inv.z + adj_origin.z;
        vec4 tmin = max(max(tmin_x, tmin_y), max(tmin_z, vec4(BVH_NODE_EPSILON)));
        vec4 tmax = min(min(tmax_x, tmax_y), min(tmax_z, vec4(ray.tmax)));
        bvec4 hit = lessThanEqual(tmin, tmax);
        uvec4 bits = (uvec4(child_bits4) >> shifts) & 7u;
        uvec4 index = (uvec4(bit_index4) >> shifts) & 0x1fu;
        // Empty slots have child bits 0 and add nothing even when their (zero) box is hit.
        for (uint j = 0u; j < 4u; j++) {
            if (hit[j]) {
                hit_mask |= bits[j] << index[j];
            }
        }
    }
    return hit_mask;
}

// Ray against triangle `prim` including the alpha mask; returns t or -1.
float bvh_test_primitive(uint prim, BvhRay ray, out vec2 bary) {
    BvhTriangle tri = BVH_TRIS[prim];
    float t = bvh_intersect_triangle(tri, ray, bary);
    if (t >= 0.0 && (tri.flags & TRI_ALPHA_MASK) != 0u && !bvh_alpha_visible(prim, bary)) {
        return -1.0;
    }
    return t;
}

// Shared traversal loop. any_hit = true stops at the first accepted triangle (shadow rays).
BvhHit bvh_traverse(BvhRay ray, bool any_hit) {
    BvhHit hit;
    hit.primitive = 0xffffffffu;
    hit.t = ray.tmax;
    hit.barycentrics = vec2(0.0);

    uint oct_inv4 = bvh_octant_inv4(ray.dir);
    uvec2 stack[BVH_STACK_SIZE];
    int sp = 0;
    uvec2 current_group = uvec2(0u, 0x80000000u);
    uvec2 primitive_group = uvec2(0u);

    for (;;) {
        while (primitive_group.y != 0u) {
            uint local = uint(findMSB(primitive_group.y));
            primitive_group.y &= ~(1u << local);
            uint prim = primitive_group.x + local;
            vec2 bary;
            float t = bvh_test_primitive(prim, ray, bary);
            if (t >= 0.0 && t < ray.tmax) {
                hit.primitive = prim;
                hit.t = t;
                hit.barycentrics = bary;
                if (any_hit) {
                    return hit;
                }
                ray.tmax = t;
            }
        }
        primitive_group = uvec2(0u);

        if ((current_group.y & 0xff000000u) != 0u) {
            uint hits_imask = current_group.y;
            uint child_index_offset = uint(findMSB(hits_imask));
            uint child_index_base = current_group.x;
            current_group.y &= ~(1u << child_index_offset);
            if ((current_group.y & 0xff000000u) != 0u) {
                // obvhs's StackStack overwrites the top entry when full; do the same.
                if (sp < BVH_STACK_SIZE) {
                    stack[sp++] = current_group;
                } else {
                    stack[BVH_STACK_SIZE - 1] = current_group;
                }
            }
            uint slot_index = (child_index_offset - 24u) ^ (oct_inv4 & 0xffu);
            uint relative_index = uint(bitCount(hits_imask & ~(0xffffffffu << slot_index)));
            uint node = child_index_base + relative_index;

            uvec4 d0 = BVH_NODES[5u * node + 0u];
            uvec4 d1 = BVH_NODES[5u * node + 1u];
            uint hitmask = bvh_intersect_node(d0, d1, BVH_NODES[5u * node + 2u], BVH_NODES[5u * node + 3u],
                                              BVH_NODES[5u * node + 4u], ray, oct_inv4);
            current_group.x = d1.x;
            primitive_group.x = d1.y;
            current_group.y = (hitmask & 0xff000000u) | bvh_byte(d0.w, 3u);
            primitive_group.y = hitmask & 0x00ffffffu;
        } else {
            current_group = uvec2(0u);
        }

        if (primitive_group.y == 0u && (current_group.y & 0xff000000u) == 0u) {
            if (sp == 0) {
                break;
            }
            current_group = stack[--sp];
        }
    }
    return hit;
}

BvhHit bvh_closest_hit(BvhRay ray) {
    return bvh_traverse(ray, false);
}

bool bvh_occluded(BvhRay ray) {
    return bvh_traverse(ray, true).primitive != 0xffffffffu;
}

#endif
