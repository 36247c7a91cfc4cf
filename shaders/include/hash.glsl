// Counter-based hashing: a value depends only on its inputs (pixel, view, ...), never on which
// device or in which order it was computed.
#ifndef PARALLAX_HASH_GLSL
#define PARALLAX_HASH_GLSL

// PCG output permutation (O'Neill), as a stateless hash of one 32-bit word.
uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

uint hash3(uint a, uint b, uint c) {
    return pcg_hash(a ^ pcg_hash(b ^ pcg_hash(c)));
}

#endif
