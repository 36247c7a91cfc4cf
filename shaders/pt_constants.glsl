// Constants of the path tracer shared by kernels that include only part of it (the material
// model, the sky, reprojection's view-dependence bound). Twins: std::f32::consts and
// parallax_scene::bsdf's MIN_ALPHA.

#ifndef PT_CONSTANTS_GLSL
#define PT_CONSTANTS_GLSL

const float PI = 3.14159265358979;
const float TAU = 6.28318530717959;
const float INV_PI = 0.318309886183791;
// Smallest GGX alpha: keeps the distribution finite for roughness 0 (near-mirror).
const float MIN_ALPHA = 1e-3;

#endif
