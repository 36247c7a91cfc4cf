//! The bounds a scene's values must keep, which the loaders, poses and options check.

/// Largest world-space coordinate magnitude a scene may have. BVH builds and traversal multiply
/// coordinate differences (surface areas of bounds, edge cross products), and f32 overflows at
/// 3.4e38: the bounds of ±L have a surface area of 24·L², finite up to L ≈ 3.7e18, so ±1e18
/// keeps a margin (obvhs panics beyond it: docs/UPSTREAM.md).
pub const MAX_COORDINATE: f32 = 1e18;

/// The largest emission a scene may declare, per channel: an emissive material's radiance
/// (emissiveFactor × KHR_materials_emissive_strength) and a punctual light's intensity × colour.
/// The same bound as `--sun` and `--sky`: beyond it f32 sums on the GPU overflow to infinity.
pub const MAX_EMISSION: f32 = 1e6;
