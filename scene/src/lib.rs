//! Parallax scenes: everything about *what* is rendered, with no GPU API in sight.
//!
//! - [`load_gltf`]: glTF 2.0 import into a flat, world-space [`Scene`];
//!   [`default_scene()`] builds the embedded scene used when no file is given;
//!   [`Scene::pose_at`] poses skinned and node-animated meshes at a time of the file's animation
//!   ([`posing`]).
//! - [`SceneBvh`]: an obvhs CWBVH over all triangles plus CPU traversal; [`gpu`] lays the same
//!   BVH and scene out for storage buffers (traversed by `shaders/bvh_traverse.glsl`).
//! - [`CpuTracer`]: the reference path tracer (NEE + MIS, Lambert + GGX, counter-based RNG).
//!   `shaders/pt_trace.glsl` is its GPU twin; [`gpu::GpuTraceParams`] and [`gpu::GpuPixel`]
//!   are its parameter and output layouts. No Vulkan here: parallax-passes uploads the
//!   [`gpu::GpuScene`] and runs the shaders (its lavapipe tests compare them with this crate).
//! - [`output`]: EXR per view and a PNG contact sheet; [`metrics`]: MSE, PSNR, means.
//!
//! ```
//! use parallax_scene::{default_scene, CpuTracer, PixelSet, SceneBvh, TraceSettings, View};
//! let scene = default_scene();
//! let bvh = SceneBvh::build(&scene);
//! let tracer = CpuTracer::new(&scene, &bvh);
//! let view = View { camera: scene.default_camera(), width: 8, height: 6, index: 0 };
//! let (pixels, stats) = tracer
//!     .trace(&view, &TraceSettings::default(), &PixelSet::Rows { start: 2, end: 4 }, &|_| {})
//!     .unwrap();
//! assert_eq!(pixels.len(), 16);
//! assert_eq!(stats.non_finite_samples, 0);
//! ```

pub mod animation;
pub mod bsdf;
pub mod builder;
pub mod bvh;
mod bvh_coincident;
pub mod camera;
pub mod default_scene;
pub mod error;
mod gltf_animation;
pub mod gltf_budget;
pub mod gltf_import;
mod gltf_primitive;
pub mod gpu;
pub mod input;
pub mod lights;
pub mod limits;
pub mod metrics;
pub mod model;
pub mod output;
pub mod posing;
pub mod pt;
pub mod rng;
pub mod shading;

pub use builder::SceneBuilder;
pub use bvh::{BvhQuality, Hit, SceneBvh};
pub use camera::Camera;
pub use default_scene::{default_lighting, default_scene, white_furnace_scene};
pub use error::SceneError;
pub use gltf_import::{LoadOptions, load_gltf, load_gltf_bytes, load_gltf_bytes_with, load_gltf_with};
pub use limits::{MAX_COORDINATE, MAX_EMISSION};
pub use model::{AlphaMode, Bounds, Material, PunctualKind, PunctualLight, Scene, Sky, Sun, Texture};
pub use pt::{CpuTracer, Frame, PixelSample, PixelSet, TraceSettings, TraceStats, View};

/// Loads a scene: `"default"` is the embedded default scene, anything else a glTF path.
pub fn load_scene(spec: &str) -> Result<Scene, SceneError> {
    load_scene_with(spec, LoadOptions::default())
}

/// [`load_scene`] with `options` for a glTF file.
pub fn load_scene_with(spec: &str, options: LoadOptions) -> Result<Scene, SceneError> {
    if spec == "default" { Ok(default_scene()) } else { load_gltf_with(spec, options) }
}

/// docs/UPSTREAM.md's reproduction of obvhs's panic runs as a doctest: the day a new obvhs builds
/// that BVH, it fails, and the note and Parallax's guard against such coordinates can go.
#[cfg(doctest)]
#[doc = include_str!("../../docs/UPSTREAM.md")]
pub struct UpstreamReproductions;
