//! A render: a light field of a scene through the paper's reconstruction pipeline (G-buffer,
//! path tracing of the sources, reprojection of the targets, hole filling, SVGF, tonemapping)
//! or with every view path traced, over N devices under any of the three schemes, for F
//! frames of a still camera, a dolly or the scene's glTF animation (its camera, and its
//! skinned or node-animated meshes posed at each frame's time).
//! Writes the last frame's views (EXR, linear radiance after denoising; PNG at one exposure for
//! the whole light field), the contact sheet, `viewer.html` (the views in a browser, with
//! parallax), an optional Looking Glass quilt and wiggle, and render.json with the paper's
//! Table 1 / Table 4 measures and the `setup` that comparisons check.
//!
//! Three rooms: [`prepare`] (settings, outputs and work checked, the pipeline compiled, the scene
//! loaded), [`frames`] (devices, executor, the frame loop) and [`report`] (read-back, outputs,
//! render.json); [`ranked`] runs them as one rank of several under mpirun. A user crate runs
//! all three over its own stages with [`run`].

mod faults;
mod frames;
mod posing;
pub mod prepare;
#[cfg(feature = "mpi")]
mod ranked;
mod report;
mod view_files;

use anyhow::Result;
#[cfg(not(feature = "mpi"))]
use anyhow::bail;
use parallax_passes::pipeline::PipelineBuilder;

use crate::settings::{RenderExtension, RenderSettings};
use frames::render_frames;
use prepare::RenderJob;
use report::write_outputs;

/// A render of `settings` over the standard pipeline extended by `extension`: prepare, frames,
/// report. Under mpirun (the `mpi` feature) this process renders its rank's part.
pub fn run(settings: &RenderSettings, mut extension: RenderExtension) -> Result<()> {
    // Without MPI every rank of mpirun would render the whole light field into the same folder.
    #[cfg(not(feature = "mpi"))]
    if let Some(ranks) = crate::ranks::launched_ranks().filter(|&n| n > 1) {
        bail!(
            "started as one of {ranks} MPI ranks, but this parallax was built without MPI, so each rank would render \
             the whole light field alone: build it with cargo build --release --features mpi"
        );
    }
    #[cfg(feature = "mpi")]
    if let Some(ranked) = crate::ranks::mpi::with_cluster(|c| c.map(|c| ranked::run(settings, &mut extension, c))) {
        return ranked;
    }
    let identity = |builder: PipelineBuilder| builder;
    let extend: &dyn Fn(PipelineBuilder) -> PipelineBuilder = extension.stages.as_deref().unwrap_or(&identity);
    let devices = settings.devices.count() as u32;
    let mut job = RenderJob::prepare(settings, extend, devices, true)?;
    let rendered = render_frames(settings, &mut job, &mut extension, None)?;
    write_outputs(settings, &job, rendered)
}
