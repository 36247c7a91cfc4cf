#version 460
#extension GL_EXT_control_flow_attributes : require
// SVGF, the middle à-trous iterations (`svgf_atrous_2` … `svgf_atrous_4`); shaders/svgf_atrous.glsl says what an iteration does.
#define SVGF_ATROUS_FIRST 0
#define SVGF_ATROUS_LAST 0
#include "svgf_atrous.glsl"
