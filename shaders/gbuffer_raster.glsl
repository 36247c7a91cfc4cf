// What the two stages of the raster G-buffer pass (parallax_passes::GbufferRasterKernel) share:
// the push constants and the varyings' meaning. Vertices are pulled from the uploaded scene's
// BVH-ordered triangles by buffer address (no vertex input): vertex 3 t + k is corner k of
// triangle t, so one non-indexed draw of 3 × triangles covers the scene, and the fragment
// stage knows its triangle (flat) and its barycentrics (perspective-correct), as a ray hit
// would.

#ifndef GBUFFER_RASTER_GLSL
#define GBUFFER_RASTER_GLSL

#extension GL_EXT_buffer_reference : require

#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "frame_block.glsl"
#include "pt_types.glsl"

// 64 bytes; parallax_passes::shaders::GbufferRasterPush, generated from this block.
layout(push_constant, std430) uniform GbufferRasterPush {
    SceneRefs scene;
    FrameBlock frame; // the frame block section: views[view].current is this view's camera
    uint view;
    uint pad;
} pc;

#endif
