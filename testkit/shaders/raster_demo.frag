#version 460
// Test raster pass: the near quad is a constant colour, the far one the fill pattern of
// the pixel (in framebuffer coordinates, so any row band renders the same values).
#include "bindless.glsl"
#include "pattern.glsl"

layout(location = 0) flat in uint instance;
layout(location = 0) out vec4 color;

void main() {
    uvec2 p = uvec2(gl_FragCoord.xy);
    color = instance == 0u ? vec4(0.25, 0.5, 0.75, 1.0) : fill_pattern(p.x, p.y, pc.view);
}
