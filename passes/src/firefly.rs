//! Firefly suppression that keeps energy (shaders/firefly.glsl): two passes between the
//! complete 1-spp radiance (after path tracing, reprojection and hole filling) and the
//! denoiser, declared by [`declare_firefly_suppression`].
//!
//! 1. `firefly_bound` (shaders/firefly_bound.comp): per pixel with a hit, a bound from its 5×5
//!    neighbourhood, the pixel itself excluded: mean + [`FIREFLY_K`]·√n standard deviations of
//!    the neighbours' luminance, n the frames of the still camera's running mean this frame joins
//!    (1 after motion, a cut or a new plan; counted per pixel in the `firefly_frames` history, by
//!    the test SVGF's accumulation makes). A pixel over it keeps `bound / luminance` of its radiance (hue
//!    unchanged) and offers the rest in equal shares to its neighbours with a hit (the
//!    `firefly_share` image).
//! 2. `firefly_spread` (shaders/firefly_spread.comp): every pixel with a hit keeps its kept
//!    fraction and adds the shares of the donors around it, in place in `radiance`.
//!
//! Both read their 5×5 windows from a shared-memory tile per 8×8 workgroup (the group's pixels
//! and a 2-px apron, each texel loaded once: hit flags and luminance, or shares), then sum in
//! the same order as a tap per read would: the tile changes the memory traffic, not the bits.
//!
//! Why the bias is bounded: the neighbour relation is symmetric, so every share lands exactly
//! once and a view's per-channel sum is unchanged (to f32 rounding; image borders and sky
//! pixels included, they neither give nor receive). A pixel's expected value moves by the
//! shares it receives minus the excess it gives; where the expected radiance is the same over
//! the 5×5 window these cancel, so only pixels near an edge or gradient of the expected excess
//! move, by at most the difference of the expected excess across their window, and the excess
//! stays within 2 px of where it was sampled. On a still camera the bound grows as √n: a sample
//! may move the running mean of n frames by at most [`FIREFLY_K`] neighbourhood deviations over
//! √n (that mean's standard error), so suppression fades as the mean converges, and what it
//! moved in the first frames weighs 1/n in the mean: a still picture converges to the
//! unsuppressed one. A global clamp, and the clamps against the pixel's
//! own temporal statistics tried before, threw the excess away: 0.65–8.7 % of a channel's mean
//! (docs/RESULTS.md).
//!
//! Off ([`FireflyMode::Keep`]) declares nothing: the pipeline is exactly the one before.

use std::sync::Arc;

use crate::shaders::{self, FireflyPush};
use parallax_backend::{BackendError, InstanceId, KernelGraph, PassInstance, PassKernel, Recorder};
use parallax_graph::{Format, Handle, HistorySlot, Image, ReadSlot, Role, WriteSlot};

/// Pass name of the bound and share pass.
pub const FIREFLY_BOUND: &str = "firefly_bound";
/// Pass name of the gather.
pub const FIREFLY_SPREAD: &str = "firefly_spread";
/// Slot of the shares: (excess rgb / receivers, kept fraction), Rgba32f.
pub const FIREFLY_SHARE: &str = "firefly_share";
/// Slot of n, the frames of the still camera's running mean (R32f, a history).
pub const FIREFLY_FRAMES: &str = "firefly_frames";
/// Standard deviations of the neighbours' luminance above their mean that a pixel may reach on
/// a moving camera (times √n on the n-th still frame).
pub const FIREFLY_K: f32 = 3.0;
/// Neighbours with a hit (of 24) a pixel needs to be judged: fewer give no usable deviation
/// (a thin object against the sky), and the pixel is left alone.
pub const FIREFLY_MIN_NEIGHBOURS: u32 = 8;
/// Rows the 5×5 window reaches above and below a pixel (`FIREFLY_RADIUS` in firefly.glsl).
const RADIUS: u32 = 2;

/// Whether the pipeline suppresses fireflies before denoising.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FireflyMode {
    /// Energy-conserving neighbourhood suppression (this module).
    Suppress,
    /// The radiance as traced.
    Keep,
}

/// Declares the two passes for every view of `role`: reads `radiance` (Rgba32f) and `position_depth`
/// (w = 0: no hit) and leaves the suppressed radiance as `radiance`'s next version, in place.
pub fn declare_firefly_suppression(
    graph: &mut KernelGraph,
    role: Role,
    position_depth: &Handle<Image>,
    radiance: &mut Handle<Image>,
) {
    let mut share = graph.image(FIREFLY_SHARE, Format::Rgba32f);
    let mut frames = graph.image(FIREFLY_FRAMES, Format::R32f);
    let mut pass = graph.pass(FIREFLY_BOUND, role);
    let stage = Stage::Bound {
        radiance: pass.read_halo_slot(radiance, RADIUS),
        position: pass.read_halo_slot(position_depth, RADIUS),
        share: pass.write_slot(&mut share),
        // Read at the pixel's own texel only.
        frames_before: pass.read_history_slot(&frames),
        frames: pass.write_slot(&mut frames),
    };
    pass.kernel(Arc::new(FireflyKernel(stage))).add();
    let mut pass = graph.pass(FIREFLY_SPREAD, role);
    let position = pass.read_slot(position_depth);
    let share = pass.read_halo_slot(&share, RADIUS);
    let (_, radiance) = pass.modify_slot(radiance);
    pass.kernel(Arc::new(FireflyKernel(Stage::Spread { position, share, radiance }))).add();
}

/// `FireflyPush::flags`: `block` holds the frame's cameras.
const CAMERAS: u32 = 1;

/// Which shader a pass runs, and its slots.
#[derive(Clone, Copy, Debug)]
enum Stage {
    Bound {
        radiance: ReadSlot,
        position: ReadSlot,
        share: WriteSlot,
        frames_before: HistorySlot,
        frames: WriteSlot,
    },
    /// `radiance` is modified in place (its read is the slot's own).
    Spread {
        position: ReadSlot,
        share: ReadSlot,
        radiance: WriteSlot,
    },
}

struct FireflyKernel(Stage);

impl PassKernel for FireflyKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let (shader, written) = match self.0 {
            Stage::Bound { share, .. } => (shaders::FIREFLY_BOUND, share),
            Stage::Spread { radiance, .. } => (shaders::FIREFLY_SPREAD, radiance),
        };
        let target = rec.resource(pass.write(written)?.alloc);
        if target.format != Format::Rgba32f {
            return Err(BackendError::KernelMisuse {
                kernel: shader.name().into(),
                instance: Some(index),
                detail: format!("`{}` must be an Rgba32f image, not {:?}", target.name, target.format),
            });
        }
        let (width, height) = (target.width, target.height);
        let read = |slot: ReadSlot| rec.image(pass.read(slot)?.alloc);
        let write = |slot: WriteSlot| rec.image(pass.write(slot)?.alloc);
        let (radiance, position, share) = match self.0 {
            Stage::Bound { radiance, position, share, .. } => (read(radiance)?, read(position)?, write(share)?),
            Stage::Spread { position, share, radiance } => (write(radiance)?, read(position)?, read(share)?),
        };
        let mut push = FireflyPush {
            radiance,
            position,
            share,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            height,
            k: FIREFLY_K,
            min_neighbours: FIREFLY_MIN_NEIGHBOURS,
            ..bytemuck::Zeroable::zeroed()
        };
        if let Stage::Bound { frames_before, frames, .. } = self.0 {
            push.frames_before = rec.image(pass.history_read(frames_before)?.alloc)?;
            push.frames = write(frames)?;
            // A graph run without cameras (no frame block) cannot tell a still camera: every
            // frame is bounded as a first one.
            if let Ok(block) = rec.frame_block_address() {
                push.view = pass.view.0;
                push.block = block;
                push.flags = CAMERAS;
            }
        }
        let groups = [width.div_ceil(8), pass.region.len().div_ceil(8).max(1), 1];
        rec.dispatch(shader, &push, groups)
    }
}
