//! The light-field pipeline of the paper (Table 1 stages) declared as a graph. The same
//! declaration serves all three schemes: only the plan's sources and placement differ, which is
//! what makes the comparison side by side fair.

use crate::builder::{Graph, Handle, Image, Role};
use crate::schedule::Format;

/// Handles of the standard pipeline, for callers that attach kernels or add passes.
pub struct StandardPipeline {
    pub position: Handle<Image>,
    pub normal: Handle<Image>,
    pub albedo: Handle<Image>,
    pub radiance: Handle<Image>,
    pub holes: Handle<Image>,
    pub denoised: Handle<Image>,
    pub display: Handle<Image>,
}

/// Pass names, in declaration order (the stage numbers of the paper's Table 1).
pub const STAGES: [&str; 6] = ["gbuffer", "path_trace", "reproject", "hole_fill", "denoise", "tonemap"];

/// Declares: G-buffer for every view (stage 3), path tracing of sources (2), reprojection of
/// targets from their sources (4), hole filling (5), SVGF-style denoising with history (6, 8),
/// tonemapping (7); the display image is exported and so gathered to device 0 (9).
pub fn declare_standard_pipeline(g: &mut Graph) -> StandardPipeline {
    let mut position = g.image("position", Format::Rgba32f);
    let mut normal = g.image("normal", Format::Rgba16f);
    let mut albedo = g.image("albedo", Format::Rgba8);
    let mut radiance = g.image("radiance", Format::Rgba32f);
    let mut holes = g.image("holes", Format::R32u);
    let mut denoised = g.image("denoised", Format::Rgba16f);
    let mut display = g.image("display", Format::Rgba8);

    g.pass("gbuffer", Role::All).write(&mut position).write(&mut normal).write(&mut albedo).record();
    g.pass("path_trace", Role::Sources).write(&mut radiance).record();
    g.pass("reproject", Role::Targets)
        .read(&position)
        .read(&normal)
        .read_sources(&position)
        .read_sources(&normal)
        .read_sources(&radiance)
        .write(&mut radiance)
        .write(&mut holes)
        .record();
    g.pass("hole_fill", Role::Targets)
        .read(&holes)
        .read(&position)
        .read(&normal)
        .read(&radiance)
        .write(&mut radiance)
        .record();
    g.pass("denoise", Role::All)
        .read(&radiance)
        .read(&position)
        .read(&normal)
        .read(&albedo)
        .read_history(&position)
        .read_history(&normal)
        .read_history(&denoised)
        .write(&mut denoised)
        .record();
    g.pass("tonemap", Role::All).read(&denoised).write(&mut display).record();
    g.export(&display);
    StandardPipeline { position, normal, albedo, radiance, holes, denoised, display }
}
