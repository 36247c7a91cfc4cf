//! Test kernels (shaders in this crate's `shaders/`), with CPU references that compute
//! bit-identical values. They plug into the executor through [`PassKernel`] like any user
//! kernel; real passes (path tracing, ...) live in the passes crate.

use std::sync::Arc;

use crate::ids::{self, FillBufferParams, WeightedFillParams};
use parallax_backend::{
    BackendError, Draw, Format, HistorySlot, InstanceId, KernelGraph, PassInstance, PassKernel, PassParams, ReadSlot,
    Recorder, Result, SourcesSlot, WriteSlot,
};
use parallax_graph::{Handle, PassBuilder, Role};

/// Declares pass `name` for the views of `role` with one write, of `target`, and attaches the
/// kernel `bind` makes from that write's slot; the caller records it (after `side_effect()`,
/// say). What every single-write kernel below is declared with.
pub fn declare_writer<'g, R, K: PassKernel + 'static>(
    graph: &'g mut KernelGraph,
    name: &str,
    role: Role,
    target: &mut Handle<R>,
    bind: impl FnOnce(WriteSlot) -> K,
) -> PassBuilder<'g, Arc<dyn PassKernel>> {
    let mut pass = graph.pass(name, role);
    let kernel = bind(pass.write_slot(target));
    pass.kernel(Arc::new(kernel))
}

/// Writes the deterministic pattern of `fill.comp` into its `out` write over the instance's rows.
pub struct FillKernel {
    pub out: WriteSlot,
}

impl PassKernel for FillKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> Result<()> {
        let params = rec.row_params(pass, pass.write(self.out)?.alloc)?;
        rec.dispatch_rows(ids::FILL, params)
    }
}

/// Reprojection-shaped gather (`shift_blend.comp`): `out = 0.5 * own + 0.5 * source` shifted by
/// [`shift_of_view`] columns, where `source` is the first source view's image (the graph's
/// `read_sources`), which is what makes the planner insert cross-device copies; further source
/// reads are declared but not sampled. A view without sources (a source view) blends with
/// itself.
pub struct ShiftBlendKernel {
    pub own: ReadSlot,
    pub sources: SourcesSlot,
    pub out: WriteSlot,
}

impl PassKernel for ShiftBlendKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> Result<()> {
        let dst = pass.write(self.out)?.alloc;
        let own = pass.read(self.own)?.alloc;
        let other = pass.sources(self.sources)?.next().map_or(own, |source| source.alloc);
        let base = rec.row_params(pass, dst)?;
        let params = PassParams {
            src0: rec.image(own)?,
            src1: rec.image(other)?,
            param: shift_of_view(pass.view.0, base.width),
            ..base
        };
        rec.dispatch_rows(ids::SHIFT_BLEND, params)
    }
}

/// Raster demo (this crate's `raster_demo.{vert,frag}`): renders into its `gbuffer` write over
/// the instance's rows a near quad (left half, constant [`RASTER_NEAR_COLOR`]) drawn before a far
/// full-image quad (the fill pattern), with the depth test against its `depth` write (a
/// `Depth32f` resource, cleared first; afterwards it holds [`RASTER_NEAR_DEPTH`] on the left
/// half and [`RASTER_FAR_DEPTH`] on the right).
pub struct RasterDemoKernel {
    pub gbuffer: WriteSlot,
    pub depth: WriteSlot,
}

/// Colour of the near quad of [`RasterDemoKernel`].
pub const RASTER_NEAR_COLOR: [f32; 4] = [0.25, 0.5, 0.75, 1.0];
/// Depths of the near and far quads of [`RasterDemoKernel`].
pub const RASTER_NEAR_DEPTH: f32 = 0.25;
pub const RASTER_FAR_DEPTH: f32 = 0.75;

impl PassKernel for RasterDemoKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> Result<()> {
        let (gbuffer, depth) = (pass.write(self.gbuffer)?, pass.write(self.depth)?);
        let params = PassParams {
            view: pass.view.0,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width: rec.resource(gbuffer.alloc).width,
            ..Default::default()
        };
        rec.draw(
            &Draw {
                vertex_shader: ids::RASTER_DEMO_VERT,
                fragment_shader: ids::RASTER_DEMO_FRAG,
                color_targets: &[gbuffer.alloc],
                depth_target: Some(depth.alloc),
                clear: true,
                rows: pass.region,
                vertex_count: 6,
                instance_count: 2,
            },
            &params,
        )
    }
}

/// CPU value of the raster demo at (x, y) of a `width`-wide image of `view`.
pub fn reference_raster(x: u32, y: u32, view: u32, width: u32) -> [f32; 4] {
    if x < width / 2 { RASTER_NEAR_COLOR } else { reference_fill(x, y, view) }
}

/// `out = fill_pattern * weights[view] + frame_data[0]` (`weighted_fill.comp`): reads the
/// global buffer `weights` (f32 per view) and the per-frame data (one f32), both by buffer
/// address.
pub struct WeightedFillKernel {
    pub out: WriteSlot,
}

impl PassKernel for WeightedFillKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> Result<()> {
        let dst = pass.write(self.out)?.alloc;
        let width = rec.resource(dst).width;
        let push = WeightedFillParams {
            dst: rec.image(dst)?,
            view: pass.view.0,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            pad: 0,
            weights: rec.buffer_address("weights")?,
            frame_data: rec.frame_data_address(),
        };
        rec.dispatch(ids::WEIGHTED_FILL, &push, [width.div_ceil(8), pass.region.len().div_ceil(8), 1])
    }
}

/// Writes `hash3(i, 0, view)` into every 32-bit word `i` of its `out` write, a per-view buffer
/// (`fill_buffer.comp`).
pub struct FillBufferKernel {
    pub out: WriteSlot,
}

impl PassKernel for FillBufferKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> Result<()> {
        let dst = pass.write(self.out)?.alloc;
        let words = rec.resource(dst).width;
        let push = FillBufferParams { view: pass.view.0, count: words, target: rec.buffer_of(dst)? };
        rec.dispatch(ids::FILL_BUFFER, &push, [words.div_ceil(64), 1, 1])
    }
}

/// CPU value of word `i` written by [`FillBufferKernel`] for `view`.
pub fn reference_buffer_word(i: u32, view: u32) -> u32 {
    hash3(i, 0, view)
}

/// Writes `hash3(x, y, view)` into its `out` write, an R32_UINT image (`fill_mask.comp`).
pub struct FillMaskKernel {
    pub out: WriteSlot,
}

impl PassKernel for FillMaskKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> Result<()> {
        let dst = pass.write(self.out)?.alloc;
        if rec.resource(dst).format != Format::R32u {
            return Err(BackendError::KernelMisuse {
                kernel: "fill_mask".into(),
                instance: Some(index),
                detail: format!("writes an R32Uint image, not {:?}", rec.resource(dst).format),
            });
        }
        let params = rec.row_params(pass, dst)?;
        rec.dispatch_rows(ids::FILL_MASK, params)
    }
}

/// CPU value of `fill_mask.comp` at pixel (x, y) of `view`.
pub fn reference_mask(x: u32, y: u32, view: u32) -> u32 {
    hash3(x, y, view)
}

/// `acc = history(acc) + frame index + 1` (`accumulate.comp`): `acc` is written and read as
/// history (last frame's final `acc`, zero when history is invalid).
pub struct AccumulateKernel {
    pub acc: WriteSlot,
    pub history: HistorySlot,
}

impl PassKernel for AccumulateKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> Result<()> {
        let (output, history) = (pass.write(self.acc)?, pass.history_read(self.history)?);
        let params = PassParams { src0: rec.image(history.alloc)?, ..rec.row_params(pass, output.alloc)? };
        rec.dispatch_rows(ids::ACCUMULATE, params)
    }
}

/// Column shift used by `shift_blend` for `view`.
pub fn shift_of_view(view: u32, width: u32) -> u32 {
    (3 + 5 * view) % width.max(1)
}

fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

fn hash3(a: u32, b: u32, c: u32) -> u32 {
    pcg_hash(a ^ pcg_hash(b ^ pcg_hash(c)))
}

/// CPU value of `fill.comp` (`fill_pattern` in this crate's shaders/include/pattern.glsl) at
/// pixel (x, y) of `view`.
pub fn reference_fill(x: u32, y: u32, view: u32) -> [f32; 4] {
    let h = hash3(x, y, view);
    [(h & 0xffff) as f32 / 65536.0, (h >> 16) as f32 / 65536.0, (view & 0xffff) as f32 / 65536.0, 65535.0 / 65536.0]
}

/// CPU value of `shift_blend.comp` at (x, y) of `view` reading `other_view`, both filled.
pub fn reference_shift_blend(x: u32, y: u32, view: u32, other_view: u32, width: u32) -> [f32; 4] {
    let own = reference_fill(x, y, view);
    let other = reference_fill((x + shift_of_view(view, width)) % width, y, other_view);
    std::array::from_fn(|i| 0.5 * own[i] + 0.5 * other[i])
}
