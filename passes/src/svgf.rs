//! The `svgf` passes: spatiotemporal variance-guided filtering (after Schied et al.,
//! *Spatiotemporal Variance-Guided Filtering*, HPG 2017) of a view's `radiance` into `denoised`,
//! declared by [`declare_svgf`] as a chain of seven passes over the view's G-buffer:
//!
//! 1. `svgf_history` (shaders/svgf_history.comp): last frame's colour and moments history
//!    (history reads) copied into this frame's images. History reads see only the instance's
//!    own rows; reprojection reaches [`HISTORY_REACH`] rows: the copies are read with that
//!    halo. An instance that
//!    covers its whole view records nothing: the temporal pass reads that history itself.
//! 2. `svgf_temporal`: illumination (radiance / albedo) and the moments of its luminance
//!    accumulated through `motion` with an exponential moving average (α = 0.2, 1/n while the
//!    history is shorter); disoccluded pixels (depth or normal differ from the previous frame's)
//!    restart. While the view's camera is still, instead, the exact running mean of every frame
//!    since the last change (motion, a cut, a new plan), with its frame count per pixel in the
//!    accumulation history (`svgf_accum`, `svgf_accum_m2`): a still light field converges to
//!    the reference, and what follows a change is bit for bit a fresh start; the variance is
//!    then that of the mean. No sample is clamped (the shader says why). In the same pass, the variance of the illumination luminance from the moments, or
//!    a 7×7 spatial estimate while the history is shorter than 4 frames; and the G-buffer packed
//!    for the à-trous passes: one guide texel (depth, depth gradient, octahedral normal) and the
//!    effective albedo in half floats.
//! 3. `svgf_atrous_1` … `svgf_atrous_5`: à-trous iterations (steps 1, 2, 4, 8, 16; 3×3 taps) with
//!    symmetric edge-stopping on depth, normal and illumination luminance; the first one's
//!    illumination is the colour history (`svgf_color`), the last one writes `denoised`. The
//!    first, the middle and the last iterations run shaders of their own, compiled from one
//!    source (shaders/svgf_atrous.glsl), each with only its own work and constant tile sizes.
//!
//! The à-trous iterations exchange illumination between neighbours so that radiance is
//! conserved: the view's radiance sum after each iteration is the sum before it, whatever the
//! textures, depth edges, image borders and weights (shaders/svgf_atrous.glsl). With the
//! temporal average this makes the per-channel mean of `denoised` exactly the running average of
//! the path-traced input's: no bias in the mean. The normalised filter it replaces moved a
//! channel's mean by up to 13 % on Sponza (docs/PIPELINE.md, SVGF).
//!
//! Every pass with a footprint reads its rows and the footprint's reach around them
//! (`read_halo`: the temporal pass's G-buffer, radiance and history through `motion`, the à-trous
//! passes' taps), so a view split into row bands over devices gives the same pixels as one
//! device. The à-trous passes run in phase tiles
//! ([`phase_groups`]): a workgroup owns 8×8 pixels `step` apart and reads their taps into
//! shared memory once. Pixels without a hit (depth 0) keep their radiance; every output is
//! finite (inputs are sanitised, every division is guarded).

use std::sync::Arc;

use crate::shaders::{self, SvgfPush};
use parallax_backend::{InstanceId, KernelGraph, PassInstance, PassKernel, Recorder, Shader};
use parallax_graph::{Format, Handle, HistorySlot, Image, ReadSlot, Role, WriteSlot};

/// Slot name of the result (Rgba32f linear radiance, docs/PIPELINE.md).
pub const DENOISED: &str = "denoised";
/// Colour history: the first à-trous iteration's illumination (rgb) and history length.
pub const SVGF_COLOR: &str = "svgf_color";
/// Moments history: (m1, m2) of the illumination luminance, linear depth, packed normal.
pub const SVGF_MOMENTS: &str = "svgf_moments";
/// The temporal pass's output and the à-trous input: (illumination rgb, variance).
pub const SVGF_VARIANCE: &str = "svgf_variance";
/// Accumulation history: the running mean of the illumination (rgb) since the camera last
/// changed, and the number of frames in it.
pub const SVGF_ACCUM: &str = "svgf_accum";
/// Accumulation history: the running mean of the squared illumination luminance.
pub const SVGF_ACCUM_M2: &str = "svgf_accum_m2";
/// Tap spacing of the à-trous iterations, in pixels: powers of two (shaders/svgf.glsl divides by
/// a step with shifts), at least two of them (the first and the last iteration run shaders of
/// their own, shaders/svgf_atrous.glsl).
pub const ATROUS_STEPS: [u32; 5] = [1, 2, 4, 8, 16];
const _: () = {
    assert!(ATROUS_STEPS.len() >= 2);
    let mut i = 0;
    while i < ATROUS_STEPS.len() {
        assert!(ATROUS_STEPS[i].is_power_of_two());
        i += 1;
    }
};

// This frame's copies of the history ([`Stage::History`]) and the intermediate images.
const PREV_COLOR: &str = "svgf_prev_color";
const PREV_MOMENTS: &str = "svgf_prev_moments";
const GUIDE: &str = "svgf_guide";
const EFFECTIVE_ALBEDO: &str = "svgf_albedo";
const ATROUS: &str = "svgf_atrous";

/// Rows the temporal pass's spatial variance estimate reaches above and below a pixel (`RADIUS`
/// in shaders/svgf_temporal.comp: a (2·3 + 1)² window); its depth gradient reaches one.
const TEMPORAL_RADIUS: u32 = 3;

/// Rows a history tap through `motion` may lie from its pixel (`HISTORY_REACH` in
/// shaders/svgf_temporal.comp): farther history restarts the pixel. 16 rows a frame is a
/// surface crossing the image's height in well under a second at 30 Hz on today's views; what
/// moves faster has little history worth keeping. It bounds the history copies of a band to a
/// halo of this many rows.
pub const HISTORY_REACH: u32 = 16;

/// `SvgfPush::flags`: the temporal pass has the frame block's cameras (`block`, `view`).
const CAMERAS: u32 = 4;

/// The G-buffer and radiance of the views to denoise (formats: docs/PIPELINE.md).
pub struct SvgfInputs<'a> {
    pub radiance: &'a Handle<Image>,
    pub albedo_roughness: &'a Handle<Image>,
    pub normal_metallic: &'a Handle<Image>,
    pub position_depth: &'a Handle<Image>,
    pub motion: &'a Handle<Image>,
}

/// Declares the SVGF passes (see the module docs) for every view of `role` (every view, or the
/// sources alone when the pipeline denoises in sample space) and returns the `denoised` handle
/// (Rgba32f; not exported). The inputs are read in their current versions.
pub fn declare_svgf(graph: &mut KernelGraph, role: Role, inputs: &SvgfInputs<'_>) -> Handle<Image> {
    let mut color = graph.image(SVGF_COLOR, Format::Rgba32f);
    let mut moments = graph.image(SVGF_MOMENTS, Format::Rgba32f);
    let mut prev_color = graph.image(PREV_COLOR, Format::Rgba32f);
    let mut prev_moments = graph.image(PREV_MOMENTS, Format::Rgba32f);
    let mut guide = graph.image(GUIDE, Format::Rgba32f);
    // Albedo in [0, 1] (plus a floor) weighs and remodulates: half floats' 2^-11 is plenty.
    let mut albedo = graph.image(EFFECTIVE_ALBEDO, Format::Rgba16f);
    let mut variance = graph.image(SVGF_VARIANCE, Format::Rgba32f);
    let mut accum = graph.image(SVGF_ACCUM, Format::Rgba32f);
    let mut accum_m2 = graph.image(SVGF_ACCUM_M2, Format::R32f);
    let mut atrous = graph.image(ATROUS, Format::Rgba32f);
    let mut denoised = graph.image(DENOISED, Format::Rgba32f);

    let mut pass = graph.pass("svgf_history", role);
    let history = Stage::History {
        color: pass.read_history_slot(&color),
        moments: pass.read_history_slot(&moments),
        prev_color: pass.write_slot(&mut prev_color),
        prev_moments: pass.write_slot(&mut prev_moments),
    };
    pass.kernel(Arc::new(SvgfKernel(history))).add();
    // The G-buffer and radiance around the band: the depth gradient reads one row away, the
    // spatial variance estimate `TEMPORAL_RADIUS` rows. The colour and moments copies
    // `HISTORY_REACH` rows: the shader drops taps through `motion` farther away. The history directly where
    // an instance covers its whole view (the copy is then skipped), the copies where it is a band.
    let mut pass = graph.pass("svgf_temporal", role);
    let temporal = Stage::Temporal(TemporalSlots {
        history_color: pass.read_history_slot(&color),
        history_moments: pass.read_history_slot(&moments),
        radiance: pass.read_halo_slot(inputs.radiance, TEMPORAL_RADIUS),
        albedo: pass.read_halo_slot(inputs.albedo_roughness, TEMPORAL_RADIUS),
        normal: pass.read_halo_slot(inputs.normal_metallic, TEMPORAL_RADIUS),
        position: pass.read_halo_slot(inputs.position_depth, TEMPORAL_RADIUS),
        motion: pass.read_slot(inputs.motion),
        prev_color: pass.read_halo_slot(&prev_color, HISTORY_REACH),
        prev_moments: pass.read_halo_slot(&prev_moments, HISTORY_REACH),
        variance: pass.write_slot(&mut variance),
        moments: pass.write_slot(&mut moments),
        guide: pass.write_slot(&mut guide),
        effective_albedo: pass.write_slot(&mut albedo),
        // Read at the pixel's own texel only (a still camera reprojects onto itself).
        history_accum: pass.read_history_slot(&accum),
        history_accum_m2: pass.read_history_slot(&accum_m2),
        accum: pass.write_slot(&mut accum),
        accum_m2: pass.write_slot(&mut accum_m2),
    });
    pass.kernel(Arc::new(SvgfKernel(temporal))).add();
    for (i, &step) in ATROUS_STEPS.iter().enumerate() {
        let name = format!("svgf_atrous_{}", i + 1);
        let (first, last) = (i == 0, i + 1 == ATROUS_STEPS.len());
        let mut pass = graph.pass(&name, role);
        // The 3×3 taps reach one step away, the first iteration's 3×3 variance blur one more
        // (svgf_atrous.glsl).
        let reach = step * if first { 2 } else { 1 };
        let input = pass.read_halo_slot(if first { &variance } else { &atrous }, reach);
        let guide_slot = pass.read_halo_slot(&guide, reach);
        let albedo_slot = pass.read_halo_slot(&albedo, reach);
        let (radiance, output, color) = if last {
            (Some(pass.read_slot(inputs.radiance)), pass.write_slot(&mut denoised), None)
        } else if first {
            (None, pass.write_slot(&mut atrous), Some(pass.write_slot(&mut color)))
        } else {
            (None, pass.write_slot(&mut atrous), None)
        };
        let stage = Stage::Atrous { step, input, guide: guide_slot, albedo: albedo_slot, output, color, radiance };
        pass.kernel(Arc::new(SvgfKernel(stage))).add();
    }
    denoised
}

/// Workgroups of a pass in the phase-tiled layout of `step` over rows `[y0, y1)` of a view
/// `width` wide (`svgf_tile_base` in shaders/svgf.glsl): for each of the step² phases, 8×8
/// tiles of that phase's subgrid. Rows are counted from `y0 / step` on every phase, so a band
/// covers each of its rows exactly once, whatever its bounds. Step 1 is the plain 8×8 tiling.
pub fn phase_groups(step: u32, width: u32, y0: u32, y1: u32) -> [u32; 3] {
    let columns = width.div_ceil(step);
    let rows = y1.div_ceil(step) - y0 / step;
    [step * columns.div_ceil(8), (step * rows.div_ceil(8)).max(1), 1]
}

/// Which SVGF shader a pass runs, and the slots its declaration returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    History {
        color: HistorySlot,
        moments: HistorySlot,
        prev_color: WriteSlot,
        prev_moments: WriteSlot,
    },
    Temporal(TemporalSlots),
    /// `color` (the colour history) is written by the first iteration only, `radiance` (to
    /// remodulate) read by the last only.
    Atrous {
        step: u32,
        input: ReadSlot,
        guide: ReadSlot,
        albedo: ReadSlot,
        output: WriteSlot,
        color: Option<WriteSlot>,
        radiance: Option<ReadSlot>,
    },
}

/// The slots of `svgf_temporal`: last frame's histories, the G-buffer and radiance, this
/// frame's history copies, and its six outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct TemporalSlots {
    history_color: HistorySlot,
    history_moments: HistorySlot,
    radiance: ReadSlot,
    albedo: ReadSlot,
    normal: ReadSlot,
    position: ReadSlot,
    motion: ReadSlot,
    prev_color: ReadSlot,
    prev_moments: ReadSlot,
    variance: WriteSlot,
    moments: WriteSlot,
    guide: WriteSlot,
    effective_albedo: WriteSlot,
    history_accum: HistorySlot,
    history_accum_m2: HistorySlot,
    accum: WriteSlot,
    accum_m2: WriteSlot,
}

impl Stage {
    /// The first and the last à-trous iteration have shaders of their own (shaders/svgf_atrous.glsl):
    /// the first writes the colour history, the last `denoised`.
    fn shader(&self) -> Shader<SvgfPush> {
        match self {
            Stage::History { .. } => shaders::SVGF_HISTORY,
            Stage::Temporal(_) => shaders::SVGF_TEMPORAL,
            Stage::Atrous { color: Some(_), .. } => shaders::SVGF_ATROUS_FIRST,
            Stage::Atrous { radiance: Some(_), .. } => shaders::SVGF_ATROUS_LAST,
            Stage::Atrous { .. } => shaders::SVGF_ATROUS,
        }
    }

    /// A write of the stage: every write covers the instance's band of one view's image.
    fn band(&self) -> WriteSlot {
        match self {
            Stage::History { prev_color, .. } => *prev_color,
            Stage::Temporal(slots) => slots.variance,
            Stage::Atrous { output, .. } => *output,
        }
    }
}

/// Records one SVGF pass instance over its row band.
struct SvgfKernel(Stage);

impl PassKernel for SvgfKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let stage = &self.0;
        let target = rec.resource(pass.write(stage.band())?.alloc);
        let (width, height) = (target.width, target.height);
        // The instance covers its whole view: its history reads see every row.
        let whole_view = pass.region.y0 == 0 && pass.region.y1 == height;
        let read = |rec: &Recorder<'_>, slot: ReadSlot| rec.image(pass.read(slot)?.alloc);
        let history = |rec: &Recorder<'_>, slot: HistorySlot| rec.image(pass.history_read(slot)?.alloc);
        let write = |rec: &Recorder<'_>, slot: WriteSlot| rec.image(pass.write(slot)?.alloc);
        // The SVGF shaders share one block and each SPIR-V module keeps all of its members, so
        // a stage's push carries them all; those it does not bind stay zero, and its shader reads
        // only the ones it binds.
        let mut push =
            SvgfPush { y0: pass.region.y0, y1: pass.region.y1, width, height, step: 1, ..bytemuck::Zeroable::zeroed() };
        match stage {
            // A whole view's history is all there: the temporal pass reads it directly.
            Stage::History { .. } if whole_view => return Ok(()),
            &Stage::History { color, moments, prev_color, prev_moments } => {
                push.in0 = history(rec, color)?;
                push.in1 = history(rec, moments)?;
                push.out0 = write(rec, prev_color)?;
                push.out1 = write(rec, prev_moments)?;
            }
            Stage::Temporal(slots) => {
                push.radiance = read(rec, slots.radiance)?;
                push.albedo = read(rec, slots.albedo)?;
                push.normal = read(rec, slots.normal)?;
                push.position = read(rec, slots.position)?;
                push.motion = read(rec, slots.motion)?;
                if whole_view {
                    push.in0 = history(rec, slots.history_color)?;
                    push.in1 = history(rec, slots.history_moments)?;
                } else {
                    push.in0 = read(rec, slots.prev_color)?;
                    push.in1 = read(rec, slots.prev_moments)?;
                }
                push.out0 = write(rec, slots.variance)?;
                push.out1 = write(rec, slots.moments)?;
                push.out2 = write(rec, slots.guide)?;
                push.out3 = write(rec, slots.effective_albedo)?;
                push.in2 = history(rec, slots.history_accum)?;
                push.in3 = history(rec, slots.history_accum_m2)?;
                push.out4 = write(rec, slots.accum)?;
                push.out5 = write(rec, slots.accum_m2)?;
                // A graph run without cameras (no frame block) cannot tell a still camera: it
                // blends every frame as a moving camera's.
                if let Ok(block) = rec.frame_block_address() {
                    push.view = pass.view.0;
                    push.block = block;
                    push.flags |= CAMERAS;
                }
            }
            &Stage::Atrous { step, input, guide, albedo, output, color, radiance } => {
                push.in0 = read(rec, input)?;
                push.in1 = read(rec, guide)?;
                push.in2 = read(rec, albedo)?;
                push.out0 = write(rec, output)?;
                push.step = step;
                if let Some(color) = color {
                    push.out1 = write(rec, color)?;
                }
                if let Some(radiance) = radiance {
                    push.radiance = read(rec, radiance)?;
                }
            }
        }
        let groups = phase_groups(push.step, width, pass.region.y0, pass.region.y1);
        rec.dispatch(stage.shader(), &push, groups)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `svgf_tile_base` of shaders/svgf.glsl, and the pixel of invocation (lx, ly) from it.
    fn phase_pixel(step: u32, y0: u32, group: (u32, u32), local: (u32, u32)) -> (u32, u32) {
        let (gx, gy) = group;
        let base = (gx % step + step * 8 * (gx / step), gy % step + step * (y0 / step + 8 * (gy / step)));
        (base.0 + step * local.0, base.1 + step * local.1)
    }

    /// The temporal pass's halo reads reach as far as its shader's window: a smaller halo would
    /// leave rows of a neighbouring band unread (stale) in a banded scheme.
    #[test]
    fn the_temporal_halo_is_the_shaders_window() {
        let source = include_str!("../../shaders/svgf_temporal.comp");
        assert!(
            source.contains(&format!("const int RADIUS = {TEMPORAL_RADIUS};")),
            "RADIUS in svgf_temporal.comp changed"
        );
        assert!(
            source.contains(&format!("const int HISTORY_REACH = {HISTORY_REACH};")),
            "HISTORY_REACH in svgf_temporal.comp changed"
        );
    }

    #[test]
    fn the_phase_tiles_of_a_band_cover_each_of_its_pixels_once() {
        let (width, height) = (37, 45);
        for step in ATROUS_STEPS {
            for (y0, y1) in [(0, height), (0, 15), (15, 30), (30, height), (7, 8), (13, 44)] {
                let mut count = vec![0u32; (width * height) as usize];
                let [gx, gy, gz] = phase_groups(step, width, y0, y1);
                assert_eq!(gz, 1);
                for group in (0..gx).flat_map(|x| (0..gy).map(move |y| (x, y))) {
                    for local in (0..8).flat_map(|x| (0..8).map(move |y| (x, y))) {
                        let (x, y) = phase_pixel(step, y0, group, local);
                        // What the shader's svgf_in_band test lets through.
                        if x < width && (y0..y1).contains(&y) {
                            count[(y * width + x) as usize] += 1;
                        }
                    }
                }
                for y in 0..height {
                    for x in 0..width {
                        let expected = u32::from((y0..y1).contains(&y));
                        assert_eq!(
                            count[(y * width + x) as usize],
                            expected,
                            "step {step}, rows {y0}..{y1}: ({x}, {y})"
                        );
                    }
                }
            }
        }
    }
}
