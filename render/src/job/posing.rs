//! `render`'s moving geometry: when the run's motion is the glTF animation and the scene's meshes
//! move (skins, animated mesh nodes), each frame's time poses them ([`Scene::pose_at`]), the BVH
//! is built again over the posed triangles (obvhs, as the load builds it) and the new geometry
//! is uploaded before the frame's passes. Materials, textures and lights were uploaded once;
//! under any other motion the scene keeps the pose it was loaded in, t = 0.
//!
//! History with moving geometry: SVGF's temporal pass and the motion vectors follow the
//! camera only, so a moving surface reprojects its history from where the camera alone would
//! have taken it; the history's depth and normal tests drop what no longer matches, and the
//! rest lags by a frame (documented in README).
//!
//! [`Scene::pose_at`]: parallax_scene::Scene::pose_at

use std::time::Instant;

use anyhow::Result;
use parallax_backend::Summary;
use parallax_passes::LightFieldRenderer;
use parallax_scene::SceneBvh;
use parallax_scene::gpu::GpuScene;

use super::prepare::RenderJob;
use crate::report::stages::Spread;
use crate::settings::RenderSettings;

/// Poses the scene frame by frame and times it.
pub(super) struct Posing {
    /// The animation time of the geometry on the devices.
    shown: f32,
    pose_ms: Summary,
    bvh_ms: Summary,
    upload_ms: Summary,
    total_ms: Summary,
}

/// render.json's `geometry`: whether the meshes moved over the frames and what posing them cost
/// per frame that needed a new pose.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub(super) struct GeometryReport {
    /// The meshes were posed at each measured frame's time (the glTF animation ran and moves
    /// them); false: every frame shows the pose of t = 0.
    pub animated: bool,
    /// Frames whose time needed a new pose (every measured frame but the first, which shows
    /// the pose the scene was loaded in).
    pub posed_frames: u64,
    /// Per posed frame: posing the vertices, building the BVH, uploading the geometry (after
    /// waiting for the frames in flight), and the three together.
    pub pose: Spread,
    pub bvh: Spread,
    pub upload: Spread,
    pub total: Spread,
}

impl Posing {
    /// Posing for `job`: None unless its motion moves the scene's meshes. The scene was loaded
    /// posed at t = 0.
    pub fn of(job: &RenderJob) -> Option<Self> {
        job.motion.moves_geometry(&job.scene).then(|| Self {
            shown: 0.0,
            pose_ms: Summary::default(),
            bvh_ms: Summary::default(),
            upload_ms: Summary::default(),
            total_ms: Summary::default(),
        })
    }

    /// Poses `job.scene` at the time of frame `f` and uploads it, unless the devices already
    /// show that time (warm-up frames and the first measured frame show the loaded pose).
    ///
    /// Frames in flight: posing and the BVH build run on the host while the frames already
    /// submitted still run on the GPU; the upload then waits for all of them
    /// (`Executor::upload_buffer` finishes the frames in flight first), so no frame reads a
    /// buffer while it is overwritten. Double-buffering the geometry instead would need a
    /// second set of scene buffers per frame slot and their addresses in each frame's data — a
    /// backend change — to win back only the GPU's idle time during the copy of a few buffers.
    pub fn before_frame(
        &mut self,
        settings: &RenderSettings,
        job: &mut RenderJob,
        renderer: &mut LightFieldRenderer,
        f: u32,
    ) -> Result<()> {
        let t = job.time_at(settings, f);
        if t == self.shown {
            return Ok(());
        }
        let started = Instant::now();
        job.scene.pose_at(t)?;
        let posed = Instant::now();
        let bvh = SceneBvh::build(&job.scene);
        let built = Instant::now();
        renderer.upload_geometry(&GpuScene::new(&job.scene, &bvh))?;
        let uploaded = Instant::now();
        let ms = |from: Instant, to: Instant| (to - from).as_secs_f64() * 1e3;
        self.pose_ms.add(ms(started, posed));
        self.bvh_ms.add(ms(posed, built));
        self.upload_ms.add(ms(built, uploaded));
        self.total_ms.add(ms(started, uploaded));
        self.shown = t;
        Ok(())
    }

    pub fn report(&self) -> GeometryReport {
        GeometryReport {
            animated: true,
            posed_frames: self.total_ms.count(),
            pose: Spread::of(&self.pose_ms),
            bvh: Spread::of(&self.bvh_ms),
            upload: Spread::of(&self.upload_ms),
            total: Spread::of(&self.total_ms),
        }
    }
}
