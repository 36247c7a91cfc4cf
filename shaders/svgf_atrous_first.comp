#version 460
#extension GL_EXT_control_flow_attributes : require
// SVGF, the first à-trous iteration (`svgf_atrous_1`): blurs the variance, writes the colour history; shaders/svgf_atrous.glsl says what an iteration does.
#define SVGF_ATROUS_FIRST 1
#define SVGF_ATROUS_LAST 0
#include "svgf_atrous.glsl"
