#version 460
// SVGF, step 0 (`svgf_history`): last frame's history as this frame's images. History reads
// only see the instance's own rows (history stays on the device that wrote it), but
// reprojection through motion may land on any row; copying the history into this frame's
// images lets the temporal pass read them whole, so a view split into row bands over devices
// reprojects across band borders exactly like a whole view.
//   in0: history `svgf_color` (filtered illumination rgb)
//   in1: history `svgf_moments` (m1, m2, history length)
//   in2: history `position_depth`, in3: history `normal_metallic`
//   out0 `svgf_prev_color`: (illumination rgb, history length)
//   out1 `svgf_prev_moments`: (m1, m2, linear depth, 0)
//   out2 `svgf_prev_normal`: (normal xyz, 0)
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
    vec4 normal = vec4(0.0);
    if (frame.history_valid != 0u) {
        vec4 c = imageLoad(images[pc.in0], p);
        vec4 m = imageLoad(images[pc.in1], p);
        color = vec4(c.rgb, m.z);
        moments = vec4(m.xy, imageLoad(images[pc.in2], p).w, 0.0);
        normal = vec4(imageLoad(images[pc.in3], p).xyz, 0.0);
    }
    imageStore(images[pc.out0], p, color);
    imageStore(images[pc.out1], p, moments);
    imageStore(images[pc.out2], p, normal);
}
