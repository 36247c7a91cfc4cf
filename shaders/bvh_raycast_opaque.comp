#version 460
// The `raycast` kernel for opaque, untextured geometry (see bvh_raycast.glsl): what the
// rays/s benchmark measures.
#define PT_SCENE_NO_TEXTURES
#include "bvh_raycast.glsl"
