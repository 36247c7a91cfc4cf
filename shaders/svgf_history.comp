#version 460
// SVGF, step 0 (`svgf_history`): last frame's history as this frame's images. History reads
// only see the instance's own rows (history stays on the device that wrote it), but
// reprojection through motion may land on any row; copying the history into this frame's
// images lets the temporal pass read them whole, so a view split into row bands over devices
// reprojects across band borders exactly like a whole view.
//   in0: history `svgf_color` (illumination rgb after the first à-trous iteration, length)
//   in1: history `svgf_moments` (m1, m2, linear depth, packed normal)
//   out0 `svgf_prev_color`, out1 `svgf_prev_moments`: the same texels
// With history invalid (first frame, a reset) everything is 0 (length 0: nothing to reuse), so
// what the history halves held before never reaches the output.
#include "svgf.glsl"

void main() {
    ivec2 p = svgf_pixel();
    if (p.x < 0) {
        return;
    }
    vec4 color = vec4(0.0);
    vec4 moments = vec4(0.0);
    if (frame.history_valid != 0u) {
        color = imageLoad(images[pc.in0], p);
        moments = imageLoad(images[pc.in1], p);
    }
    imageStore(images[pc.out0], p, color);
    imageStore(images[pc.out1], p, moments);
}
