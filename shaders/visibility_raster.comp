#version 460
// The `visibility_raster` pass's first dispatch (parallax_passes::visibility::
// VisibilityRasterKernel): every BVH triangle against one view's row band, without tracing.
// Each invocation takes one triangle, bounds the pixels whose centre rays can reach it (its
// projection through the view's camera, exactly the camera of pt_camera.glsl, widened by a
// pixel; visibility_raster.glsl), and tests those pixels' centre rays against it with the
// traversal's own triangle test (bvh_test_triangle: Moeller-Trumbore and the alpha mask), so
// coverage and distance are the traced first hit's bit for bit; the nearest triangle of each
// pixel is kept by a 64-bit atomicMax on its key (visibility.glsl).
//
// Boxes of more than LARGE_PIXELS pixels are not looped over by their own invocation: they are
// queued in workgroup memory. The workgroup then shares out each queued box's pixels, or, for a
// box of more than TILED_PIXELS, writes its tiles to the band's list for
// visibility_raster_tiles.comp (where the list is full, the workgroup tests it itself).
#extension GL_GOOGLE_include_directive : require
#include "visibility_raster.glsl"

const uint GROUP = 64u;
const uint LARGE_PIXELS = 64u;
// A queued box not tiled (tested by the workgroup).
const uint UNTILED = 0xffffffffu;

layout(local_size_x = 64) in;

shared uint large_count;
shared uint large_primitive[GROUP];
shared uvec4 large_box[GROUP];
// The first tile of each queued box in the band's list, or UNTILED.
shared uint large_first_tile[GROUP];

uint tiles_across(uvec4 box) {
    return (box.z - box.x + TILE - 1u) / TILE;
}

uint tile_count(uvec4 box) {
    return tiles_across(box) * ((box.w - box.y + TILE - 1u) / TILE);
}

// Reserves `n` tiles of the band's list; UNTILED where they do not fit. A compare-and-swap
// loop, so the count (the tile dispatch's size) never passes the capacity.
uint reserve_tiles(uint n) {
    uint count = atomicAdd(pc.tiles.count, 0u);
    while (count + n <= pc.tile_capacity) {
        uint seen = atomicCompSwap(pc.tiles.count, count, count + n);
        if (seen == count) {
            return count;
        }
        count = seen;
    }
    return UNTILED;
}

void main() {
    uint local = gl_LocalInvocationIndex;
    if (local == 0u) {
        large_count = 0u;
        if (gl_WorkGroupID.x == 0u && gl_WorkGroupID.y == 0u) {
            // The list's dispatch is count × 1 × 1; the reset left zeros.
            pc.tiles.groups_y = 1u;
            pc.tiles.groups_z = 1u;
        }
    }
    barrier();
    uint prim = (gl_WorkGroupID.y * pc.groups_x + gl_WorkGroupID.x) * GROUP + local;
    if (prim < pc.triangles) {
        BvhTriangle tri = bvh_load_triangle(prim);
        uvec4 box = pixel_box(tri);
        if (box.x < box.z && box.y < box.w) {
            uint area = (box.z - box.x) * (box.w - box.y);
            if (area > LARGE_PIXELS) {
                uint slot = atomicAdd(large_count, 1u);
                large_primitive[slot] = prim;
                large_box[slot] = box;
                large_first_tile[slot] = area > TILED_PIXELS ? reserve_tiles(tile_count(box)) : UNTILED;
            } else {
                for (uint y = box.y; y < box.w; y++) {
                    for (uint x = box.x; x < box.z; x++) {
                        test_pixel(tri, prim, x, y);
                    }
                }
            }
        }
    }
    barrier();
    uint large = large_count;
    for (uint k = 0u; k < large; k++) {
        uint p = large_primitive[k];
        uvec4 box = large_box[k];
        uint first_tile = large_first_tile[k];
        if (first_tile != UNTILED) {
            uint across = tiles_across(box);
            uint n = tile_count(box);
            for (uint i = local; i < n; i += GROUP) {
                uvec2 start = box.xy + TILE * uvec2(i % across, i / across);
                uvec2 end = min(start + TILE, box.zw);
                pc.tiles.tile[first_tile + i] = uvec4(p, start.x | (start.y << 16), end.x | (end.y << 16), 0u);
            }
            continue;
        }
        BvhTriangle tri = bvh_load_triangle(p);
        uint box_width = box.z - box.x;
        uint area = box_width * (box.w - box.y);
        for (uint i = local; i < area; i += GROUP) {
            test_pixel(tri, p, box.x + i % box_width, box.y + i / box_width);
        }
    }
}
