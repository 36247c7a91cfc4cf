// Swaps channel pairs, halves them and adds a quarter of the view index. A power-of-two scale
// is exact, so there is one rounding with or without a fused multiply-add: the CPU reference
// of the test matches bit for bit.
vec4 scale_swap(vec4 v, uint view) {
    return v.yxwz * 0.5 + vec4(float(view) * 0.25);
}
