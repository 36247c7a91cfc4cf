#version 460
// The `hole_temporal` pass (parallax_passes::hole_denoise): under `--denoise samples` the
// denoiser ran on the sources before reprojection, so a target's reprojected pixels arrive
// denoised and only its hole pixels carry fresh, noisy samples. This pass runs on exactly those:
// one invocation per entry of the band's hole list (dispatched indirectly on the list's own
// header), so its cost follows the holes, not the view.
//
// While the view's camera is still (this frame's camera is last frame's, bit for bit, with
// valid history) a hole pixel becomes the exact running mean of its samples since the camera
// last changed, as SVGF's still-camera accumulation makes every pixel (svgf_temporal.comp): a
// still light field's holes converge to the path-traced reference. The mean is read at the
// pixel's own texel (a still camera reprojects onto itself), so a row band reads only its own
// rows and bands over several devices give one device's bits. Any other frame (motion, a cut,
// a new plan, the first) restarts the mean with the frame's own sample: what follows a change
// depends on nothing before it.
//
// The history is written at hole pixels only, so its other texels hold whatever an older frame
// left there: each texel carries the frame it was written in (`stamp`, the frame index mod
// 2^24 as a float, exact), and only last frame's is used. On a still camera with still
// geometry a hole stays a hole, so that is always the case; a pixel that became a hole while
// the camera stood (an animated mesh moved) restarts instead of picking up a stale mean.
// Pixels are sanitised as SVGF sanitises them: NaN, Inf and negatives become 0.
//
// Under subsampled hole filling (`--hole-fill subsampled`) the pass runs a second time over the
// band's `hole_reconstruct_list` with `carry` set: those pixels were not traced this frame, so
// their radiance is no sample; their mean of the frames they were traced in is carried into
// this frame's history unchanged (hole_reconstruct.comp shows it), or restarts with no frames.
#extension GL_EXT_buffer_reference : require
#define PARALLAX_CUSTOM_PUSH_CONSTANTS
#include "bindless.glsl"
#include "frame_block.glsl"
#include "pixel_list.glsl"

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer HoleList {
    uint groups_x;
    uint groups_y;
    uint groups_z;
    uint count;
    uint data[];
};

// 48 bytes; parallax_passes::shaders::HoleTemporalPush, generated from this block.
layout(push_constant, std430) uniform HoleTemporalPush {
    HoleList list;    // the band's section of `hole_list`
    FrameBlock block; // the cameras that tell a still one
    uint radiance;    // Rgba32f, read and written in place at the listed pixels
    uint accum_in;    // `hole_accum` history: (mean rgb, frames n)
    uint stamp_in;    // `hole_stamp` history: the frame each texel was written in
    uint accum_out;
    uint stamp_out;
    uint view;
    uint carry;       // 1: the listed pixels were reconstructed, not traced (see above)
    uint pad;
} pc;

layout(local_size_x = 64) in;

const float MAX_VALUE = 1e8;
const uint STAMP_MASK = 0xffffffu; // frame indices below 2^24 are exact in a float

vec3 sanitize(vec3 v) {
    bvec3 bad = bvec3(isnan(v).x || isinf(v).x, isnan(v).y || isinf(v).y, isnan(v).z || isinf(v).z);
    return clamp(mix(v, vec3(0.0), bad), vec3(0.0), vec3(MAX_VALUE));
}

bool camera_still() {
    if (frame.history_valid == 0u) {
        return false;
    }
    ViewCameras cameras = pc.block.views[pc.view];
    return cameras.current.view_proj == cameras.previous.view_proj;
}

void main() {
    uint entry = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * PIXEL_LIST_GROUP
        + gl_LocalInvocationID.x;
    if (entry >= pc.list.count) {
        return;
    }
    uint packed = pc.list.data[entry];
    ivec2 p = ivec2(packed & 0xffffu, packed >> 16u);
    vec4 texel = imageLoad(images[pc.radiance], p);
    vec3 sample_ = sanitize(texel.rgb);
    vec4 previous = vec4(0.0);
    if (camera_still()) {
        float last_frame = float((frame.frame_index - 1u) & STAMP_MASK);
        if (imageLoad(images[pc.stamp_in], p).x == last_frame) {
            previous = imageLoad(images[pc.accum_in], p);
        }
    }
    // Written so that a NaN history restarts too.
    bool accumulating = previous.a >= 1.0;
    if (pc.carry != 0u) {
        imageStore(images[pc.accum_out], p, accumulating ? previous : vec4(0.0));
        imageStore(images[pc.stamp_out], p, vec4(float(frame.frame_index & STAMP_MASK)));
        return;
    }
    float n = accumulating ? previous.a + 1.0 : 1.0;
    vec3 mean = accumulating ? previous.rgb + (sample_ - previous.rgb) / n : sample_;
    imageStore(images[pc.accum_out], p, vec4(mean, n));
    imageStore(images[pc.stamp_out], p, vec4(float(frame.frame_index & STAMP_MASK)));
    imageStore(images[pc.radiance], p, vec4(mean, texel.a));
}
