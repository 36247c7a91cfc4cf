//! The scene, light-field and path options that `render`, `reference` and `trace` share,
//! declared once and flattened into each command's arguments with `#[command(flatten)]` (as
//! [`DeviceArgs`](crate::options::DeviceArgs) is). The field names are the clap ids, which
//! `conflicts_with = "sun"` and `bench`'s `value_source("...")` checks refer to.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use glam::Vec3;
use parallax_graph::{LayoutSpec, LightField, Rig};
use parallax_passes::camera::rig_of;
use parallax_scene::gltf_budget::MemoryLimit;
use parallax_scene::input::UriPolicy;
use parallax_scene::{Camera, LoadOptions, Scene, Sky, Sun, default_scene, load_gltf_with};

use crate::options::{
    CameraArg, Resolution, parse_camera_arg, parse_focus, parse_layout, parse_resolution, parse_sky, parse_spacing,
    parse_sun,
};

/// `--scene`, `--camera` and the light that replaces the scene's own.
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// glTF file (.gltf/.glb) or `default` for the embedded default scene.
    #[arg(long, default_value = "default")]
    pub scene: PathBuf,
    /// The camera `eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z,yfov_degrees` (of a
    /// light field: the rig, its centre); without it the scene's first camera (or one framing the
    /// whole scene).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_camera_arg)]
    pub camera: Option<CameraArg>,
    /// Sun as `to_sun_x,to_sun_y,to_sun_z,irradiance[,angular_radius_degrees]` (irradiance
    /// 0..=1e6); replaces the scene's sun.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_sun)]
    pub sun: Option<Sun>,
    /// Remove the scene's sun.
    #[arg(long, conflicts_with = "sun")]
    pub no_sun: bool,
    /// Constant sky radiance `r,g,b`, or a gradient `zenith_rgb,horizon_rgb,ground_rgb` (9
    /// values), each 0..=1e6.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_sky)]
    pub sky: Option<Sky>,
    /// Let the scene's buffer and image URIs name files outside its folder (`../`, absolute
    /// paths, `file:` URIs); without it such a scene is refused.
    #[arg(long)]
    pub allow_outside_files: bool,
}

impl SceneArgs {
    /// Loads `--scene` and applies `--sun`, `--no-sun` and `--sky` to it.
    pub fn load(&self) -> Result<Scene> {
        let mut scene = load_scene_arg(&self.scene, self.allow_outside_files)?;
        self.light(&mut scene);
        Ok(scene)
    }

    /// Applies `--sun`, `--no-sun` and `--sky` to `scene`; a scene left with no light at all
    /// (and no `--sky`) gets [`DEFAULT_ENVIRONMENT`].
    pub fn light(&self, scene: &mut Scene) {
        if let Some(sun) = self.sun {
            scene.sun = Some(sun);
        }
        if self.no_sun {
            scene.sun = None;
        }
        if let Some(sky) = self.sky {
            scene.sky = Some(sky);
        }
        light_if_unlit(scene, self.sky.is_some());
    }

    /// Every file `scene` (loaded by [`SceneArgs::load`]) was read from, by the flag that named
    /// it: what no output may overwrite ([`parallax_render::outputs::check_inputs`]).
    pub fn inputs<'a>(&self, scene: &'a Scene) -> Vec<(&'static str, &'a std::path::Path)> {
        scene.sources.iter().map(|s| ("--scene", s.path.as_path())).collect()
    }

    /// `--camera`, else the scene's first camera (or one framing the whole scene).
    pub fn camera_or_default(&self, scene: &Scene) -> Camera {
        self.camera.map_or_else(|| scene.default_camera(), |c| c.camera)
    }
}

/// How `--scene` is loaded: `--allow-outside-files`, and the memory the process may still take
/// (the loader refuses a scene whose estimate is larger, before building it).
pub fn load_options(allow_outside_files: bool) -> LoadOptions {
    let memory =
        parallax_render::outputs::host::budget().memory.map(|m| MemoryLimit { bytes: m.bytes, bound: m.bound });
    LoadOptions { uris: uri_policy(allow_outside_files), memory }
}

/// `--scene`: `default` (the embedded scene) or a glTF file, whose path may be any the OS takes
/// (UTF-8 or not). An error names the flag, and the path once.
pub fn load_scene_arg(scene: &Path, allow_outside_files: bool) -> Result<Scene> {
    if scene == Path::new("default") {
        return Ok(default_scene());
    }
    load_gltf_with(scene, load_options(allow_outside_files))
        .map_err(|e| crate::options::input_error("--scene", scene, e))
}

/// `--allow-outside-files` as the loader's URI policy.
pub fn uri_policy(allow_outside_files: bool) -> UriPolicy {
    if allow_outside_files { UriPolicy::Anywhere } else { UriPolicy::InsideSceneFolder }
}

/// The sky a scene without any light gets, as a glTF viewer gives such a scene a neutral
/// environment: white overhead fading to 0.8 grey at the horizon, a 0.3 grey ground (radiance
/// per channel; README "Path tracing a view").
pub const DEFAULT_ENVIRONMENT: Sky =
    Sky::Gradient { zenith: Vec3::splat(1.0), horizon: Vec3::splat(0.8), ground: Vec3::splat(0.3) };

/// Without any light every pixel is black, which no one asks for by leaving the light out (Fox,
/// CesiumMan and Sponza carry none): such a scene is lit by [`DEFAULT_ENVIRONMENT`], and the
/// run says so. A black `--sky` given on purpose is kept, with a warning.
fn light_if_unlit(scene: &mut Scene, sky_given: bool) {
    if scene.has_light() {
        return;
    }
    if sky_given {
        tracing::warn!(
            "scene '{}' has no light (no sun, punctual light or emissive material, and a black --sky): the image \
             will be black; add --sun or a brighter --sky",
            scene.name
        );
        return;
    }
    scene.sky = Some(DEFAULT_ENVIRONMENT);
    tracing::info!(
        "scene '{}' has no light (no sun, sky, punctual light or emissive material): lit by the default environment \
         (sky zenith 1,1,1, horizon 0.8,0.8,0.8, ground 0.3,0.3,0.3); --sun or --sky choose another",
        scene.name
    );
}

/// The light field's layout, spacing and per-view resolution: all a plan depends on (`plan`
/// takes these alone).
#[derive(Args, Debug, Clone)]
pub struct LayoutArgs {
    /// Light-field layout: multiscopic, nelf or WxH (at most 4096 views).
    #[arg(long, default_value = "8x4", value_parser = parse_layout)]
    pub lf: LayoutSpec,
    /// Spacing between neighbouring views in metres (default: the paper's 0.001 for multiscopic
    /// and nelf; for a WxH grid, one that moves a point at half the focus distance by 2 % of the
    /// view's height across the grid, so its parallax is visible whatever the scene's size).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_spacing)]
    pub spacing: Option<f64>,
    /// Per-view resolution WxH (default: the preset's, 512x512 for grids).
    #[arg(long, value_name = "WxH", value_parser = parse_resolution)]
    pub resolution: Option<Resolution>,
}

/// How far a grid's default spacing moves a point at half the focus distance from the first
/// view to the last of the grid's wider side, as a fraction of the view's height: 10 pixels at
/// 512 high, 4 at 192, so a viewer of the grid sees depth; relative to the picture, so the rig
/// does not change with `--resolution`.
pub const GRID_PARALLAX: f64 = 0.02;

impl LayoutArgs {
    /// The light field of `--lf`, `--spacing` and `--resolution` on `rig` (a grid without
    /// `--spacing` spaced for that rig: [`LayoutArgs::spacing_on`]).
    pub fn with_rig(&self, rig: Rig) -> Result<LightField> {
        let spacing = self.spacing_on(&rig);
        self.with_rig_spaced(rig, spacing)
    }

    /// The light field of `--lf` and `--resolution` on `rig`, its views `spacing` apart (None:
    /// the preset's).
    pub fn with_rig_spaced(&self, rig: Rig, spacing: Option<f64>) -> Result<LightField> {
        Ok(LightField::new(self.lf, spacing, self.resolution.map(Resolution::pair), rig)?)
    }

    /// `--spacing`, else for a grid the spacing that moves a point at half the rig's focus
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
#[derive(Args, Debug, Clone)]
pub struct LightFieldArgs {
    #[command(flatten)]
    pub layout: LayoutArgs,
    /// Distance of the zero-disparity plane from the rig camera (default: to the scene centre).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_focus)]
    pub focus: Option<f64>,
}

impl LightFieldArgs {
    /// The light field of `--lf`, `--spacing` and `--resolution` on `rig` (`--focus` is not
    /// applied: the rig has its focus distance).
    pub fn with_rig(&self, rig: Rig) -> Result<LightField> {
        self.layout.with_rig(rig)
    }

    /// The light field whose rig is `camera`, focused at `--focus` or else at the depth of
    /// `centre` (the scene's centre) along the view.
    pub fn around(&self, camera: &Camera, centre: Vec3) -> Result<LightField> {
        self.with_rig(self.rig_around(camera, centre))
    }

    /// The rig of [`LightFieldArgs::around`].
    pub fn rig_around(&self, camera: &Camera, centre: Vec3) -> Rig {
        rig_of(camera, centre, self.focus)
    }
}

/// `--max-depth`, the same for every tracer.
#[derive(Args, Debug, Clone)]
pub struct DepthArgs {
    /// Maximum number of scattering events per path (0..=1024).
    #[arg(long, allow_negative_numbers = true, default_value_t = 6, value_parser = clap::value_parser!(u32).range(0..=1024))]
    pub max_depth: u32,
}

#[cfg(test)]
mod tests {
    use clap::{Args, Command};

    /// Each command's arguments, with the shared ones flattened in, form a valid clap command
    /// (no id declared twice, every `conflicts_with` names an argument).
    #[test]
    fn commands_with_the_shared_options_are_valid() {
        <crate::cmd_plan::PlanArgs as Args>::augment_args(Command::new("plan")).debug_assert();
        <crate::cmd_render::RenderArgs as Args>::augment_args(Command::new("render")).debug_assert();
        <crate::cmd_reference::ReferenceArgs as Args>::augment_args(Command::new("reference")).debug_assert();
        <crate::cmd_trace::TraceArgs as Args>::augment_args(Command::new("trace")).debug_assert();
    }

    /// A grid without --spacing is spaced so that a point at half the focus distance moves
    /// GRID_PARALLAX of the view's height from the first to the last view of its wider side
    /// (3.84 pixels at 256x192); the presets keep the paper's 1 mm and an explicit --spacing wins.
    #[test]
    fn a_grid_default_spacing_gives_visible_parallax() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            layout: super::LayoutArgs,
        }
        let layout = |words: &[&str]| Cli::try_parse_from([&["x"][..], words].concat()).unwrap().layout;
        let rig = parallax_graph::Rig { focus_distance: 4.0, ..Default::default() };
        let grid = layout(&["--lf", "8x4", "--resolution", "256x192"]);
        let spacing = grid.spacing_on(&rig).unwrap();
        let focal_px = 96.0 / (22.5f64.to_radians()).tan();
        let shift = |z: f64| 7.0 * spacing * focal_px * (1.0 / z - 1.0 / rig.focus_distance);
        assert!((shift(2.0) - 3.84).abs() < 1e-9, "{}", shift(2.0));
        let larger = layout(&["--lf", "8x4", "--resolution", "512x512"]);
        assert_eq!(larger.spacing_on(&rig), Some(spacing), "the rig does not change with the resolution");
        let lf = grid.with_rig(rig).unwrap();
        assert!((lf.positions[1].x - lf.positions[0].x - spacing).abs() < 1e-12);
        assert_eq!(layout(&["--lf", "nelf"]).spacing_on(&rig), None);
        assert_eq!(layout(&["--lf", "multiscopic"]).spacing_on(&rig), None);
        assert_eq!(layout(&["--lf", "8x4", "--spacing", "0.05"]).spacing_on(&rig), Some(0.05));
    }

    /// `--sky` takes values starting with '-' in every command, so the value's own check names
    /// the problem.
    #[test]
    fn a_negative_sky_reaches_the_sky_parser() {
        for augment in [
            <crate::cmd_render::RenderArgs as Args>::augment_args,
            <crate::cmd_reference::ReferenceArgs as Args>::augment_args,
            <crate::cmd_trace::TraceArgs as Args>::augment_args,
        ] {
            let e =
                augment(Command::new("c").no_binary_name(true)).try_get_matches_from(["--sky", "-1,0,0"]).unwrap_err();
            assert!(e.to_string().contains("radiance -1 is outside 0..=1e6"), "{e}");
        }
    }
}
