//! The light-field pipelines as graphs (docs/PIPELINE.md): the paper's reconstruction
//! (`Reproject`: G-buffer → path trace sources → reproject targets → hole filling → SVGF →
//! tonemap) and the baseline that path traces every view (`PathTrace`), declared once and
//! placed by any of the three schemes. What differs between the schemes is only the plan's
//! sources and placement, which is what makes the comparison side by side fair.

use std::sync::Arc;

use parallax_backend::KernelGraph;
use parallax_graph::{Format, Handle, Image, Role};

use crate::error::Result;
use crate::gbuffer::{Gbuffer, declare_gbuffer, declare_gbuffer_rasterised};
use crate::holes::declare_hole_fill;
use crate::path_trace::{PATH_TRACE, PathTraceKernel};
use crate::reproject::{ReprojectionTolerances, declare_reproject};
use crate::svgf::{DENOISED, SvgfInputs, declare_svgf};
use crate::tonemap::declare_tonemap;

/// Which pipeline renders the light field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum PipelineKind {
    /// The paper's: only sources are path traced, targets are reprojected and their holes filled.
    Reproject,
    /// The baseline: every view path traced.
    PathTrace,
}

/// Where the G-buffer comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum GbufferSource {
    /// First hits of each pixel's centre ray (the fast way on compute GPUs such as the H200).
    FirstHits,
    /// Rasterised (the paper's way; fast on GPUs with fixed-function raster), motion vectors
    /// from a compute pass.
    Raster,
}

/// What a pipeline declaration needs to know.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineConfig {
    pub kind: PipelineKind,
    pub gbuffer: GbufferSource,
    pub tolerances: ReprojectionTolerances,
    /// SVGF between the radiance and the tonemapper.
    pub denoise: bool,
    /// Exposure of the tonemapper (finite, > 0).
    pub exposure: f32,
}

/// Handles of a declared pipeline, for callers that read layers back or add passes.
pub struct PipelineHandles {
    pub gbuffer: Gbuffer,
    /// Linear radiance before denoising (targets: reprojected, then their holes path traced).
    pub radiance: Handle<Image>,
    /// Targets' hole masks (`Reproject` only).
    pub holes: Option<Handle<Image>>,
    /// Linear radiance after denoising (`denoise` only).
    pub denoised: Option<Handle<Image>>,
    /// Slot of the final linear radiance: `denoised`, or `radiance` without denoising.
    pub linear_slot: &'static str,
    /// The tonemapped RGBA8 image of every view (not exported: the caller decides).
    pub display: Handle<Image>,
}

/// Declares `path_trace` for every view of `role`, writing only `radiance`.
pub fn declare_path_trace(graph: &mut KernelGraph, role: Role, radiance: &mut Handle<Image>) {
    let mut pass = graph.pass(PATH_TRACE, role);
    let kernel = PathTraceKernel::new(pass.write_slot(radiance));
    pass.kernel(Arc::new(kernel)).record();
}

/// Declares the pipeline of `config`; nothing is exported (the caller exports what it reads).
pub fn declare_pipeline(graph: &mut KernelGraph, config: &PipelineConfig) -> Result<PipelineHandles> {
    let gbuffer = match config.gbuffer {
        GbufferSource::FirstHits => declare_gbuffer(graph),
        GbufferSource::Raster => declare_gbuffer_rasterised(graph),
    };
    let mut radiance = graph.image("radiance", Format::Rgba32f);
    let holes = match config.kind {
        PipelineKind::PathTrace => {
            declare_path_trace(graph, Role::All, &mut radiance);
            None
        }
        PipelineKind::Reproject => {
            declare_path_trace(graph, Role::Sources, &mut radiance);
            let holes = declare_reproject(graph, &gbuffer, &mut radiance, config.tolerances)?;
            declare_hole_fill(graph, &holes, &mut radiance);
            Some(holes)
        }
    };
    let denoised = config.denoise.then(|| {
        let inputs = SvgfInputs {
            radiance: &radiance,
            albedo_roughness: &gbuffer.albedo_roughness,
            normal_metallic: &gbuffer.normal_metallic,
            position_depth: &gbuffer.position_depth,
            motion: &gbuffer.motion,
        };
        declare_svgf(graph, &inputs)
    });
    let display = declare_tonemap(graph, denoised.as_ref().unwrap_or(&radiance), config.exposure)?;
    let linear_slot = if denoised.is_some() { DENOISED } else { "radiance" };
    Ok(PipelineHandles { gbuffer, radiance, holes, denoised, linear_slot, display })
}
