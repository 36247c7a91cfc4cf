// What the two G-buffer kernels that find a pixel's centre-ray hit share: turning that hit into
// the G-buffer's texels. gbuffer_trace.comp finds the hit by traversal, visibility_resolve.comp
// by reading the visibility buffer's triangle and intersecting the same ray with it (same
// intersection code), so where both see one triangle they write the same bits.
//
// Expects, before inclusion, a push-constant block `pc` with the image indices position_depth,
// normal_metallic, albedo_roughness, motion, first_hit (NO_IMAGE: not written), the view index
// `view` and the frame block `block`, and `params` (this view's TraceParams) named; pt_trace.glsl
// or pt_scene.glsl + pt_surface.glsl included (surface_point).

#ifndef GBUFFER_STORE_GLSL
#define GBUFFER_STORE_GLSL

const uint NO_IMAGE = 0xffffffffu;

// Writes pixel (x, y)'s G-buffer texels for the centre ray (eye, dir) and its closest hit `hit`
// (primitive 0xffffffff: a miss): zeros and no motion on a miss, else the surface as the path
// tracer's first hit records it and where it was in the previous frame.
void gbuffer_store(uint x, uint y, vec3 eye, vec3 dir, BvhHit hit) {
    ivec2 at = ivec2(x, y);
    vec2 previous_pixel = vec2(-1.0);
    if (pc.first_hit != NO_IMAGE) {
        imageStore(uimages[pc.first_hit], at, uvec4(hit.primitive));
    }
    if (hit.primitive == 0xffffffffu) {
        imageStore(images[pc.position_depth], at, vec4(0.0));
        imageStore(images[pc.normal_metallic], at, vec4(0.0));
        imageStore(images[pc.albedo_roughness], at, vec4(0.0));
        imageStore(images[pc.motion], at, vec4(previous_pixel, 0.0, 0.0));
        return;
    }
    SurfacePoint sp = surface_point(hit.primitive, hit.barycentrics, hit.t, eye, dir);
    imageStore(images[pc.position_depth], at, vec4(sp.position, dot(sp.position - eye, params.forward.xyz)));
    imageStore(images[pc.normal_metallic], at, vec4(sp.normal, sp.metallic));
    imageStore(images[pc.albedo_roughness], at, vec4(sp.base_color, sp.roughness));
    if (frame.history_valid != 0u) {
        vec4 clip = pc.block.views[pc.view].previous.view_proj * vec4(sp.position, 1.0);
        if (clip.w > 0.0) {
            vec2 prev_ndc = clip.xy / clip.w;
            vec2 size = vec2(params.dims.xy);
            vec2 pixel = vec2((prev_ndc.x + 1.0) * 0.5 * size.x, (1.0 - prev_ndc.y) * 0.5 * size.y);
            if (all(greaterThanEqual(pixel, vec2(0.0))) && all(lessThan(pixel, size))) {
                previous_pixel = pixel;
            }
        }
    }
    imageStore(images[pc.motion], at, vec4(previous_pixel, 0.0, 0.0));
}

#endif
