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
// The including shader enables GL_EXT_shader_explicit_arithmetic_types_int8 (bytes of node
// words are read from 8-bit lanes), declares the two buffers before including this file and
// names them:
//   #define BVH_NODES <buffer array of uvec4>   e.g. scene_nodes.data
//   #define BVH_TRIS  <buffer array of uvec4>   the BvhTriangles (bvh_types.glsl), 3 words each
// and defines, anywhere in the file, the alpha-mask test for triangles whose flags have
// TRI_ALPHA_MASK set:
//   bool bvh_alpha_visible(uint bvh_primitive, vec2 barycentrics);
// A shader without alpha-masked materials can define it as `return true;`. Defining
// BVH_COOPERATIVE (with the subgroup basic, ballot, vote, shuffle, shuffle-relative and
// arithmetic extensions enabled) adds `bvh_test_pending_triangles_together`.

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

// The four bytes of `word` as floats, byte 0 first. With BVH_BYTES_FROM_INT8 the conversion
// reads the bytes from 8-bit lanes and needs no shift and mask per byte: 3 % more rays/s in the
// `raycast` kernel on an H100, but with it the path tracer gets 128 registers instead of 96
// and runs 5 % slower (NVIDIA's register allocation, measured in docs/RESULTS.md), so each
// kernel picks.
vec4 bvh_bytes(uint word) {
#ifdef BVH_BYTES_FROM_INT8
    return vec4(unpack8(word));
#else
    return vec4((uvec4(word) >> uvec4(0u, 8u, 16u, 24u)) & 0xffu);
#endif
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
        vec4 tmin_x = bvh_bytes(near_x) * adj_dir_inv.x + adj_origin.x;
        vec4 tmax_x = bvh_bytes(far_x) * adj_dir_inv.x + adj_origin.x;
        vec4 tmin_y = bvh_bytes(near_y) * adj_dir_inv.y + adj_origin.y;
        vec4 tmax_y = bvh_bytes(far_y) * adj_dir_inv.y + adj_origin.y;
        vec4 tmin_z = bvh_bytes(near_z) * adj_dir_inv.z + adj_origin.z;
        vec4 tmax_z = bvh_bytes(far_z) * adj_dir_inv.z + adj_origin.z;
        vec4 tmin = max(max(tmin_x, tmin_y), max(tmin_z, vec4(BVH_NODE_EPSILON)));
        vec4 tmax = min(min(tmax_x, tmax_y), min(tmax_z, vec4(ray.tmax)));
        bvec4 hit = lessThanEqual(tmin, tmax);
        uvec4 bits = uvec4(unpack8(child_bits4));
        uvec4 index = uvec4(unpack8(bit_index4));
        // Empty slots have child bits 0 and add nothing even when their (zero) box is hit.
        for (uint j = 0u; j < 4u; j++) {
            if (hit[j]) {
                hit_mask |= bits[j] << index[j];
            }
        }
    }
    return hit_mask;
}

// Triangle `prim` of the BVH-ordered array, as three 16-byte loads.
BvhTriangle bvh_load_triangle(uint prim) {
    uvec4 w0 = BVH_TRIS[3u * prim + 0u];
    uvec4 w1 = BVH_TRIS[3u * prim + 1u];
    uvec4 w2 = BVH_TRIS[3u * prim + 2u];
    return BvhTriangle(uintBitsToFloat(w0.xyz), w0.w, uintBitsToFloat(w1.xyz), w1.w, uintBitsToFloat(w2.xyz), w2.w);
}

// Ray against a loaded triangle including the alpha mask; returns t or -1.
float bvh_test_triangle(BvhTriangle tri, uint prim, BvhRay ray, out vec2 bary) {
    float t = bvh_intersect_triangle(tri, ray, bary);
    if (t >= 0.0 && (tri.flags & TRI_ALPHA_MASK) != 0u && !bvh_alpha_visible(prim, bary)) {
        return -1.0;
    }
    return t;
}

// Traversal state of the one ray an invocation is tracing. Module-scope (Private) variables so
// that `bvh_traverse` (a ray to completion) and ray-scheduling kernels that interleave many
// rays per invocation (bvh_raycast.glsl) step through the same code.
BvhRay bvh_ray;
BvhHit bvh_hit;
bool bvh_any_hit; // stop at the first accepted triangle (shadow rays)
uint bvh_oct_inv4;
uvec2 bvh_stack[BVH_STACK_SIZE];
int bvh_sp;
uvec2 bvh_node_group;      // x: first child node, y: hit children (high byte) | imask
uvec2 bvh_primitive_group; // x: first triangle, y: triangles left to test (low 24 bits)

void bvh_begin(BvhRay ray, bool any_hit) {
    bvh_ray = ray;
    bvh_hit.primitive = 0xffffffffu;
    bvh_hit.t = ray.tmax;
    bvh_hit.barycentrics = vec2(0.0);
    bvh_any_hit = any_hit;
    bvh_oct_inv4 = bvh_octant_inv4(ray.dir);
    bvh_sp = 0;
    bvh_node_group = uvec2(0u, 0x80000000u);
    bvh_primitive_group = uvec2(0u);
}

// Tests a loaded triangle and keeps it if it is the closest so far. Returns true when that
// ends the traversal (an any-hit query found something).
bool bvh_consider(BvhTriangle tri, uint prim) {
    vec2 bary;
    float t = bvh_test_triangle(tri, prim, bvh_ray, bary);
    if (t >= 0.0 && t < bvh_ray.tmax) {
        bvh_hit.primitive = prim;
        bvh_hit.t = t;
        bvh_hit.barycentrics = bary;
        bvh_ray.tmax = t;
        return bvh_any_hit;
    }
    return false;
}

// Tests the triangles the last node test found, one after the other, highest bit first.
// Returns true when that ends the traversal (an any-hit query found something).
bool bvh_test_pending_triangles() {
    while (bvh_primitive_group.y != 0u) {
        uint local = uint(findMSB(bvh_primitive_group.y));
        bvh_primitive_group.y &= ~(1u << local);
        uint prim = bvh_primitive_group.x + local;
        if (bvh_consider(bvh_load_triangle(prim), prim)) {
            bvh_primitive_group.y = 0u;
            return true;
        }
    }
    return false;
}

const uint BVH_NO_NODE = 0xffffffffu;

// Takes the child node of highest priority out of the current group (pushing the rest of the
// group); BVH_NO_NODE when the group holds no node.
uint bvh_next_node() {
    if ((bvh_node_group.y & 0xff000000u) == 0u) {
        bvh_node_group = uvec2(0u);
        return BVH_NO_NODE;
    }
    uint hits_imask = bvh_node_group.y;
    uint child_index_offset = uint(findMSB(hits_imask));
    uint child_index_base = bvh_node_group.x;
    bvh_node_group.y &= ~(1u << child_index_offset);
    if ((bvh_node_group.y & 0xff000000u) != 0u) {
        // obvhs's StackStack overwrites the top entry when full; do the same.
        if (bvh_sp < BVH_STACK_SIZE) {
            bvh_stack[bvh_sp++] = bvh_node_group;
        } else {
            bvh_stack[BVH_STACK_SIZE - 1] = bvh_node_group;
        }
    }
    uint slot_index = (child_index_offset - 24u) ^ (bvh_oct_inv4 & 0xffu);
    uint relative_index = uint(bitCount(hits_imask & ~(0xffffffffu << slot_index)));
    return child_index_base + relative_index;
}

// Tests the ray against the children of a loaded node: its hit internal children become the
// node group, its hit triangles the pending triangles.
void bvh_enter_node(uvec4 d0, uvec4 d1, uvec4 dx, uvec4 dy, uvec4 dz) {
    uint hitmask = bvh_intersect_node(d0, d1, dx, dy, dz, bvh_ray, bvh_oct_inv4);
    bvh_node_group = uvec2(d1.x, (hitmask & 0xff000000u) | bvh_byte(d0.w, 3u));
    bvh_primitive_group = uvec2(d1.y, hitmask & 0x00ffffffu);
}

// Pops the next group when nothing is pending. Returns false once the ray is finished.
bool bvh_pop_if_idle() {
    if (bvh_primitive_group.y == 0u && (bvh_node_group.y & 0xff000000u) == 0u) {
        if (bvh_sp == 0) {
            return false;
        }
        bvh_node_group = bvh_stack[--bvh_sp];
    }
    return true;
}

// Tests the child node of highest priority in the current group (pushing the rest); call it
// once the pending triangles are tested. A node whose hit children are all leaves leaves an
// empty group behind, and the pop for it can only happen after its triangles: doing that pop
// here, before the node test, lets this step still test a node. Popping only at the end of a
// step (as before) cost such a lane a whole step without a node test, 8 % of the rays/s on
// Sponza (docs/RESULTS.md). The visiting order, and so every result, is the same either way.
// Pops again when the node left nothing pending. Returns false once the ray is finished.
bool bvh_visit_node() {
    if (!bvh_pop_if_idle()) {
        return false;
    }
    uint node = bvh_next_node();
    // Always a node when the triangles were tested first; the check keeps a caller that did
    // not from reading past the node buffer.
    if (node != BVH_NO_NODE) {
        bvh_enter_node(BVH_NODES[5u * node + 0u], BVH_NODES[5u * node + 1u], BVH_NODES[5u * node + 2u],
                       BVH_NODES[5u * node + 3u], BVH_NODES[5u * node + 4u]);
    }
    return bvh_pop_if_idle();
}

// One iteration of the traversal loop: the pending triangles, then one child node (popping a
// new group first if the current one is used up), then a pop when nothing is left. Returns
// false once the ray is finished (its result is `bvh_hit`).
bool bvh_step() {
    return !bvh_test_pending_triangles() && bvh_visit_node();
}

#ifdef BVH_COOPERATIVE
// Position of the n-th highest set bit of `mask` (n = 0: findMSB).
uint bvh_nth_highest_bit(uint mask, uint n) {
    uint p = 0u;
    for (uint step = 16u; step > 0u; step >>= 1u) {
        if (uint(bitCount(mask >> (p + step))) > n) {
            p += step;
        }
    }
    return p;
}

// A subgroup tests the pending triangles of all its lanes' rays together: after a node test
// a lane has a few triangles (often none), so one lane after the other would leave most of
// the subgroup idle while each waits on its own triangle loads. Here the subgroup lists all
// (ray, triangle) pairs in lane order, each lane tests one pair per round against the owning
// lane's ray, and a segmented minimum of the distances hands each ray its closest hit: the
// triangle that `bvh_test_pending_triangles` would keep, bit for bit (same test, same tie
// rule: at equal distance the earlier triangle, highest bit first; a run's pairs sit in lane
// order, so the lowest lane holding the minimum is that triangle). An any-hit ray takes its
// first hit in that order. Shuffles are what this costs most (10 more per round: -6.5 % rays/s
// on an H100), so only distances travel; the winner's barycentrics come from testing it once
// more. Must be called by every lane of the subgroup (`tracing` false for lanes without a
// ray); when some lanes are missing (divergence) or subgroups are wider than 32, each lane
// falls back to its own loop. Returns true when this lane's ray ended.
bool bvh_test_pending_triangles_together(bool tracing) {
    if (gl_SubgroupSize > 32u || subgroupBallotBitCount(subgroupBallot(true)) != gl_SubgroupSize) {
        return tracing && bvh_test_pending_triangles();
    }
    uint mask = tracing ? bvh_primitive_group.y : 0u;
    uint count = uint(bitCount(mask));
    uint total = subgroupAdd(count);
    if (total == 0u) {
        return false;
    }
    uint offset = subgroupExclusiveAdd(count);
    uvec4 any_hit_lanes = subgroupBallot(tracing && bvh_any_hit);
    uint lane = gl_SubgroupInvocationID;
    uint size = gl_SubgroupSize;
    // This lane's ray as owner: the best pair so far (key = distance bits, then order).
    uint best_key = 0xffffffffu;
    uint best_order = 0xffffffffu;
    for (uint round_base = 0u; round_base < total; round_base += size) {
        uint k = round_base + lane;
        // Owner of pair k: the last lane whose first pair is at or before k.
        uint owner = 0u;
        for (uint step = size >> 1u; step > 0u; step >>= 1u) {
            uint probe = min(owner + step, size - 1u);
            if (subgroupShuffle(offset, probe) <= k && owner + step < size) {
                owner = probe;
            }
        }
        uint owner_offset = subgroupShuffle(offset, owner);
        uint owner_count = subgroupShuffle(count, owner);
        uint owner_mask = subgroupShuffle(mask, owner);
        uint owner_base = subgroupShuffle(bvh_primitive_group.x, owner);
        BvhRay ray;
        ray.origin = subgroupShuffle(bvh_ray.origin, owner);
        ray.dir = subgroupShuffle(bvh_ray.dir, owner);
        ray.tmin = subgroupShuffle(bvh_ray.tmin, owner);
        ray.tmax = subgroupShuffle(bvh_ray.tmax, owner);
        uint key = 0xffffffffu;
        if (k < total) {
            uint prim = owner_base + bvh_nth_highest_bit(owner_mask, k - owner_offset);
            vec2 bary;
            float t = bvh_test_triangle(bvh_load_triangle(prim), prim, ray, bary);
            if (t >= 0.0 && t < ray.tmax) {
                // Non-negative distances order like their bits; -0.0 (a hit at tmin = 0) sorts
                // first, as the loop's `t < tmax` would keep it.
                key = subgroupBallotBitExtract(any_hit_lanes, owner) ? 0u : floatBitsToUint(t) & 0x7fffffffu;
            }
        }
        // Segmented minimum over the lanes holding this owner's pairs: afterwards the first
        // lane of each run holds the run's minimum.
        uint last = min(owner_offset + owner_count, round_base + size) - 1u - round_base;
        uint run_min = key;
        for (uint d = 1u; d < size; d <<= 1u) {
            uint other = subgroupShuffleDown(run_min, d);
            if (lane + d <= last) {
                run_min = min(run_min, other);
            }
        }
        // (Shuffles stay outside conditions: a lane can only read lanes that run the shuffle.)
        uint owner_run_min = subgroupShuffle(run_min, max(owner_offset, round_base) - round_base);
        bool is_run_min = k < total && key != 0xffffffffu && key == owner_run_min;
        uint min_lanes = subgroupBallot(is_run_min).x;
        // As owner: this round's part of this lane's pairs sits in lanes first..end-1; the
        // lowest of them holding the run's minimum is the earliest such triangle.
        bool has_pairs = count > 0u && offset < round_base + size && offset + count > round_base;
        uint first = has_pairs ? max(offset, round_base) - round_base : lane;
        uint run_key = subgroupShuffle(run_min, first);
        if (has_pairs && run_key != 0xffffffffu) {
            uint end = min(offset + count, round_base + size) - round_base;
            uint run_lanes = (end == 32u ? 0xffffffffu : (1u << end) - 1u) & ~((1u << first) - 1u);
            uint run_order = uint(findLSB(min_lanes & run_lanes)) + round_base - offset;
            if (run_key < best_key || (run_key == best_key && run_order < best_order)) {
                best_key = run_key;
                best_order = run_order;
            }
        }
    }
    if (!tracing) {
        return false;
    }
    bvh_primitive_group.y = 0u;
    if (best_key == 0xffffffffu) {
        return false;
    }
    // The winner again, for its barycentrics and exact distance (the key drops the sign of a
    // zero, and an any-hit key holds no distance); the same test gives the same bits.
    uint prim = bvh_primitive_group.x + bvh_nth_highest_bit(mask, best_order);
    vec2 bary;
    bvh_hit.t = bvh_test_triangle(bvh_load_triangle(prim), prim, bvh_ray, bary);
    bvh_hit.primitive = prim;
    bvh_hit.barycentrics = bary;
    bvh_ray.tmax = bvh_hit.t;
    return bvh_any_hit;
}
#endif

// Traces `ray` to completion.
BvhHit bvh_traverse(BvhRay ray, bool any_hit) {
    bvh_begin(ray, any_hit);
    while (bvh_step()) {
    }
    return bvh_hit;
}

BvhHit bvh_closest_hit(BvhRay ray) {
    return bvh_traverse(ray, false);
}

bool bvh_occluded(BvhRay ray) {
    return bvh_traverse(ray, true).primitive != 0xffffffffu;
}


#endif
