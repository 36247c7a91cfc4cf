#version 460
// The `raycast` kernel with the scene's textures and alpha masks (see bvh_raycast.glsl).
#include "bvh_raycast.glsl"
