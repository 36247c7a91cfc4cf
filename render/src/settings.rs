//! What a render runs, as plain values: [`RenderSettings`] holds every setting `parallax render`
//! takes (the command line builds it from its flags), and [`RenderExtension`] what a user crate
//! adds to the standard pipeline.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Result;
use glam::Vec3;
use parallax_accuracy::exposure::Exposure;
use parallax_backend::{Barriers, DeviceSelection, LinkKind, ShaderLibrary, Timing};
use parallax_graph::{LayoutSpec, LightField, Rig};
use parallax_passes::LightFieldRenderer;
use parallax_passes::camera::rig_of;
use parallax_passes::pipeline::{PipelineBuilder, PipelineHandles};
use parallax_scene::Camera;

use crate::compile::{DotDetail, PipelineSettings};
use crate::outputs::Sink;
use crate::report::images::QuiltShape;
use crate::scene::SceneSettings;

/// A render: the scene, the light field, the devices, the pipeline, the frames and the outputs.
/// [`Default`] is what `parallax render` runs without flags.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub scene: SceneSettings,
    pub light_field: LightFieldSettings,
    pub devices: DeviceSelection,
    pub pipeline: PipelineSettings,
    /// Samples per pixel of path tracing (sources, holes, or every view).
    pub spp: u32,
    /// Maximum number of scattering events per path.
    pub max_depth: u32,
    /// Measured frames.
    pub frames: u32,
    /// Frames submitted before the host waits for the oldest.
    pub frames_in_flight: u32,
    /// Frames rendered before measuring, at the first measured frame's camera.
    pub warmup: u32,
    /// How the rig and the scene move over the measured frames.
    pub motion: MotionRequest,
    /// Also write the views of every N-th measured frame to frame_FFFFF/ under `out_dir`.
    pub save_every: Option<u32>,
    /// The folder of the views, the contact sheet, viewer.html and render.json.
    pub out_dir: PathBuf,
    /// Exposure of the pictures: automatic (on the host) or a multiplier (the GPU's tonemap).
    pub exposure: Exposure,
    /// An animated PNG sweeping through the views of the middle row.
    pub wiggle: Option<PathBuf>,
    /// The hole mask, albedo, normal and depth in every view's EXR.
    pub layers: bool,
    /// A Looking Glass quilt of the views.
    pub quilt: Option<QuiltShape>,
    pub barriers: Barriers,
    pub timing: Timing,
    /// How devices exchange data (None: the best each pair offers).
    pub link: Option<LinkKind>,
    /// A Chrome trace-event JSON of the measured frames.
    pub trace: Option<Sink>,
    /// The schedule drawn for Graphviz.
    pub dot: Option<Sink>,
    pub dot_detail: DotDetail,
    /// Under mpirun: how long rank 0 waits for a word from another rank.
    pub rank_timeout: Duration,
    /// render.json's `run`: these settings as a run file, in the caller's spelling (the
    /// command line's flags), so the run can be repeated; null where the caller has none.
    pub run: serde_json::Value,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            scene: SceneSettings::default(),
            light_field: LightFieldSettings {
                layout: LayoutSettings { lf: LayoutSpec::Grid { cols: 8, rows: 4 }, spacing: None, resolution: None },
                focus: None,
            },
            devices: DeviceSelection::Gpus(1),
            pipeline: PipelineSettings::default(),
            spp: 1,
            max_depth: 6,
            frames: 1,
            frames_in_flight: 2,
            warmup: 1,
            motion: MotionRequest::Auto,
            save_every: None,
            out_dir: PathBuf::from("out/lightfield"),
            exposure: Exposure::Auto,
            wiggle: None,
            layers: false,
            quilt: None,
            barriers: Barriers::Tracked,
            timing: Timing::PerStage,
            link: None,
            trace: None,
            dot: None,
            dot_detail: DotDetail::Auto,
            rank_timeout: Duration::from_secs(600),
            run: serde_json::Value::Null,
        }
    }
}

impl RenderSettings {
    /// The exposure the GPU's tonemap pass runs at: a fixed exposure, or 1 under `auto`
    /// (whose pictures are tonemapped on the host).
    pub fn tonemap_exposure(&self) -> f32 {
        crate::report::pictures::gpu_exposure(self.exposure)
    }
}

/// `every-op` or `tracked`, as render.json spells the barriers.
pub fn barriers_name(barriers: Barriers) -> &'static str {
    match barriers {
        Barriers::EveryOp => "every-op",
        Barriers::Tracked => "tracked",
    }
}

/// `per-op` or `per-stage`, as render.json spells what the timestamps time.
pub fn timing_name(timing: Timing) -> &'static str {
    match timing {
        Timing::PerOp => "per-op",
        Timing::PerStage => "per-stage",
    }
}

/// How the rig moves over the measured frames, as asked for (resolved against the scene when
/// the render is planned).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionRequest {
    /// The scene's glTF animation when it has one (its camera's only when no camera is
    /// placed; its moving meshes in any case); else still.
    Auto,
    /// Still: every frame at the first frame's camera, meshes posed at t = 0.
    None,
    /// A smooth sideways dolly across 10 % of the scene; meshes posed at t = 0.
    Dolly,
    /// The scene's glTF animation (camera and moving meshes), spread over the measured frames.
    Animation,
}

/// The light field's layout, spacing and per-view resolution: all a plan depends on.
#[derive(Clone, Debug)]
pub struct LayoutSettings {
    pub lf: LayoutSpec,
    /// Metres between neighbouring views (None: the preset's, or a grid's default).
    pub spacing: Option<f64>,
    /// Per-view width and height (None: the preset's).
    pub resolution: Option<(u32, u32)>,
}

/// How far a grid's default spacing moves a point at half the focus distance from the first
/// view to the last of the grid's wider side, as a fraction of the view's height: 10 pixels at
/// 512 high, 4 at 192, so a viewer of the grid sees depth; relative to the picture, so the rig
/// does not change with the resolution.
pub const GRID_PARALLAX: f64 = 0.02;

impl LayoutSettings {
    /// The light field on `rig`, spaced as [`LayoutSettings::spacing_on`] says.
    pub fn with_rig(&self, rig: Rig) -> Result<LightField> {
        let spacing = self.spacing_on(&rig);
        self.with_rig_spaced(rig, spacing)
    }

    /// The light field on `rig`, its views `spacing` apart (None: the preset's).
    pub fn with_rig_spaced(&self, rig: Rig, spacing: Option<f64>) -> Result<LightField> {
        Ok(LightField::new(self.lf, spacing, self.resolution, rig)?)
    }

    /// The spacing given, else for a grid the spacing that moves a point at half the rig's focus
    /// distance by [`GRID_PARALLAX`] of the view's height across the grid's wider side (the
    /// paper's 1 mm moves the near edge of a room-sized scene half a pixel across 8 views: a
    /// still picture); None for the presets, which keep the paper's 1 mm. A point at depth z
    /// moves by `spacing · focal · |1/z − 1/focus|` between neighbours, `focal` the focal length
    /// in view heights, `1 / (2 tan(yfov / 2))`; at z = focus / 2 that is `spacing · focal / focus`.
    pub fn spacing_on(&self, rig: &Rig) -> Option<f64> {
        if self.spacing.is_some() {
            return self.spacing;
        }
        let LayoutSpec::Grid { cols, rows } = self.lf else { return None };
        let steps = cols.max(rows).saturating_sub(1).max(1) as f64;
        let focal = 0.5 / (0.5 * rig.yfov).tan();
        Some(GRID_PARALLAX * rig.focus_distance / (steps * focal))
    }
}

/// The light field's layout and the focus of its rig.
#[derive(Clone, Debug)]
pub struct LightFieldSettings {
    pub layout: LayoutSettings,
    /// Distance of the zero-disparity plane from the rig camera (None: to the scene centre).
    pub focus: Option<f64>,
}

impl LightFieldSettings {
    /// The light field on `rig` (the focus is not applied: the rig has its focus distance).
    pub fn with_rig(&self, rig: Rig) -> Result<LightField> {
        self.layout.with_rig(rig)
    }

    /// The light field whose rig is `camera`, focused at the focus given or else at the depth
    /// of `centre` (the scene's centre) along the view.
    pub fn around(&self, camera: &Camera, centre: Vec3) -> Result<LightField> {
        self.with_rig(self.rig_around(camera, centre))
    }

    /// The rig of [`LightFieldSettings::around`].
    pub fn rig_around(&self, camera: &Camera, centre: Vec3) -> Rig {
        rig_of(camera, centre, self.focus)
    }
}

/// Extends the pipeline a builder declares (a user crate's stages).
pub type ExtendPipeline = Box<dyn Fn(PipelineBuilder) -> PipelineBuilder>;
/// Looks at the renderer once the last frame is finished; the handles of the pipeline it runs
/// say where each layer is read back.
pub type AfterFrames = Box<dyn FnMut(&mut LightFieldRenderer, &PipelineHandles) -> Result<()>>;

/// What a user crate adds to a render: stages of its own in the standard pipeline, the shaders
/// they dispatch, and a look at the renderer after the last frame (before any output is
/// written). [`crate::job::run`] runs it with the frame loop, reports and outputs.
#[derive(Default)]
pub struct RenderExtension {
    /// Adds stages to (or replaces stages of) the pipeline the settings declare.
    pub stages: Option<ExtendPipeline>,
    /// The stages' kernels (`parallax_backend::include_shaders!()`), layered over the passes'
    /// (`parallax_passes::shader_library()`): a shader of the same name replaces a pass's.
    pub shaders: ShaderLibrary,
    /// Called once the last frame is finished, e.g. to read back a layer the stages made.
    pub after_frames: Option<AfterFrames>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid without a spacing is spaced so that a point at half the focus distance moves
    /// [`GRID_PARALLAX`] of the view's height from the first to the last view of its wider side
    /// (3.84 pixels at 256x192); the presets keep the paper's 1 mm and an explicit spacing wins.
    #[test]
    fn a_grid_default_spacing_gives_visible_parallax() {
        let layout = |lf: &str, resolution, spacing| LayoutSettings { lf: lf.parse().unwrap(), spacing, resolution };
        let rig = parallax_graph::Rig { focus_distance: 4.0, ..Default::default() };
        let grid = layout("8x4", Some((256, 192)), None);
        let spacing = grid.spacing_on(&rig).unwrap();
        let focal_px = 96.0 / (22.5f64.to_radians()).tan();
        let shift = |z: f64| 7.0 * spacing * focal_px * (1.0 / z - 1.0 / rig.focus_distance);
        assert!((shift(2.0) - 3.84).abs() < 1e-9, "{}", shift(2.0));
        let larger = layout("8x4", Some((512, 512)), None);
        assert_eq!(larger.spacing_on(&rig), Some(spacing), "the rig does not change with the resolution");
        let lf = grid.with_rig(rig).unwrap();
        assert!((lf.positions[1].x - lf.positions[0].x - spacing).abs() < 1e-12);
        assert_eq!(layout("nelf", None, None).spacing_on(&rig), None);
        assert_eq!(layout("multiscopic", None, None).spacing_on(&rig), None);
        assert_eq!(layout("8x4", None, Some(0.05)).spacing_on(&rig), Some(0.05));
    }
}
