//! parallax-testkit: what Parallax's GPU tests share and the library does not ship.
//!
//! * [`kernels`]: small kernels with CPU references that compute bit-identical values (a fill
//!   pattern, a reprojection-shaped gather, a raster demo, buffer and mask fills, an
//!   accumulation over history).
//! * [`plans`]: execution plans laid out by hand the way the graph compiler lays out a schedule,
//!   so the executor can be tested (and fault-injected) without the graph crate.
//! * [`shaders`] / [`options`]: the kernels' SPIR-V (`shaders/`, compiled by this crate's
//!   build.rs through parallax-glsl), which the executor finds through `ExecOptions::shaders`;
//!   [`ids`]: their push-constant structs and typed ids, generated from the same SPIR-V.
//! * [`lavapipe_context`]: the logical devices a test runs on.

pub mod kernels;
pub mod plans;

/// The push-constant struct of every test kernel's block and a [`parallax_backend::Shader`]
/// id per kernel (`ids::FILL`), written by the build from the SPIR-V.
pub mod ids {
    parallax_backend::shader_bindings!();
}

use parallax_backend::{Context, ContextDesc, DeviceSelection, ExecOptions, ShaderLibrary, Validation};

/// The SPIR-V of every kernel in `shaders/`, by file stem (`fill`, `shift_blend`, ...).
pub fn shaders() -> ShaderLibrary {
    // build.rs wrote the table from glslc's output, which glslc checked; a defect here is a
    // broken build, not an input error.
    parallax_backend::include_shaders!().expect("build.rs embeds valid SPIR-V")
}

/// Default executor options with [`shaders`] as the user library.
pub fn options() -> ExecOptions {
    ExecOptions { shaders: shaders(), ..ExecOptions::default() }
}

/// `devices` logical devices on the first physical one (lavapipe in CI) under Khronos validation,
/// with synchronisation validation too when there is one device.
pub fn lavapipe_context(devices: usize) -> Context {
    let validation = if devices == 1 { Validation::CoreAndSync } else { Validation::Core };
    Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(devices), validation })
        .expect("a Vulkan device (apt-get install mesa-vulkan-drivers) and validation layers")
}
