#version 460
#extension GL_EXT_control_flow_attributes : require
// SVGF, the last à-trous iteration (`svgf_atrous_5`): writes `denoised`; shaders/svgf_atrous.glsl says what an iteration does.
#define SVGF_ATROUS_FIRST 0
#define SVGF_ATROUS_LAST 1
#include "svgf_atrous.glsl"
