//! The scene, light-field and path options that `render`, `reference` and `trace` share,
//! declared once and flattened into each command's arguments with `#[command(flatten)]` (as
//! [`DeviceArgs`](crate::options::DeviceArgs) is). The field names are the clap ids, which
//! `conflicts_with = "sun"` and `bench`'s `value_source("...")` checks refer to.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use parallax_graph::{LayoutSpec, LightField, Rig};
use parallax_render::scene::SceneSettings;
use parallax_render::settings::{LayoutSettings, LightFieldSettings};
use parallax_scene::{Scene, Sky, Sun};

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
    /// The scene these flags name, as the library loads it.
    pub fn settings(&self) -> SceneSettings {
        SceneSettings {
            path: self.scene.clone(),
            camera: self.camera.map(|c| c.camera),
            sun: self.sun,
            no_sun: self.no_sun,
            sky: self.sky,
            allow_outside_files: self.allow_outside_files,
        }
    }

    /// Loads `--scene` and applies `--sun`, `--no-sun` and `--sky` to it.
    pub fn load(&self) -> Result<Scene> {
        self.settings().load()
    }
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

impl LayoutArgs {
    /// The layout these flags give.
    pub fn settings(&self) -> LayoutSettings {
        LayoutSettings { lf: self.lf, spacing: self.spacing, resolution: self.resolution.map(Resolution::pair) }
    }

    /// The light field of `--lf`, `--spacing` (or a grid's default) and `--resolution` on `rig`.
    pub fn with_rig(&self, rig: Rig) -> Result<LightField> {
        self.settings().with_rig(rig)
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
    /// The light field's layout and focus these flags give.
    pub fn settings(&self) -> LightFieldSettings {
        LightFieldSettings { layout: self.layout.settings(), focus: self.focus }
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
