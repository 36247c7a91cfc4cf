//! The scene of a render: loaded from a glTF file (or the embedded default scene), with the
//! camera, sun and sky that replace the scene's own.

use std::path::{Path, PathBuf};

use anyhow::Result;
use glam::Vec3;
use parallax_scene::gltf_budget::MemoryLimit;
use parallax_scene::input::UriPolicy;
use parallax_scene::{Camera, LoadOptions, Scene, Sky, Sun, default_scene, load_gltf_with};

/// The scene file and what replaces its own camera and light.
#[derive(Clone, Debug)]
pub struct SceneSettings {
    /// A glTF file (.gltf/.glb), or `default` for the embedded default scene.
    pub path: PathBuf,
    /// The camera (of a light field: the rig, its centre); None: the scene's first camera (or one
    /// framing the whole scene).
    pub camera: Option<Camera>,
    /// Replaces the scene's sun.
    pub sun: Option<Sun>,
    /// Removes the scene's sun.
    pub no_sun: bool,
    /// Replaces the scene's sky.
    pub sky: Option<Sky>,
    /// Lets the scene's buffer and image URIs name files outside its folder.
    pub allow_outside_files: bool,
}

impl Default for SceneSettings {
    /// The embedded default scene with its own camera and light.
    fn default() -> Self {
        SceneSettings {
            path: PathBuf::from("default"),
            camera: None,
            sun: None,
            no_sun: false,
            sky: None,
            allow_outside_files: false,
        }
    }
}

impl SceneSettings {
    /// Loads the scene and applies the sun and sky to it.
    pub fn load(&self) -> Result<Scene> {
        let mut scene = load_scene(&self.path, self.allow_outside_files)?;
        self.light(&mut scene);
        Ok(scene)
    }

    /// Applies the sun, `no_sun` and the sky to `scene`; a scene left with no light at all (and
    /// no sky given) gets [`DEFAULT_ENVIRONMENT`].
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

    /// Every file `scene` (loaded by [`SceneSettings::load`]) was read from, by the flag that
    /// named it: what no output may overwrite ([`crate::outputs::check_inputs`]).
    pub fn inputs<'a>(&self, scene: &'a Scene) -> Vec<(&'static str, &'a Path)> {
        scene.sources.iter().map(|s| ("--scene", s.path.as_path())).collect()
    }

    /// The camera given, else the scene's first camera (or one framing the whole scene).
    pub fn camera_or_default(&self, scene: &Scene) -> Camera {
        self.camera.unwrap_or_else(|| scene.default_camera())
    }
}

/// How `--scene` is loaded: `--allow-outside-files`, and the memory the process may still take
/// (the loader refuses a scene whose estimate is larger, before building it).
pub fn load_options(allow_outside_files: bool) -> LoadOptions {
    let memory = crate::outputs::host::budget().memory.map(|m| MemoryLimit { bytes: m.bytes, bound: m.bound });
    LoadOptions { uris: uri_policy(allow_outside_files), memory }
}

/// `--scene`: `default` (the embedded scene) or a glTF file, whose path may be any the OS takes
/// (UTF-8 or not). An error names the flag, and the path once.
pub fn load_scene(scene: &Path, allow_outside_files: bool) -> Result<Scene> {
    if scene == Path::new("default") {
        return Ok(default_scene());
    }
    load_gltf_with(scene, load_options(allow_outside_files)).map_err(|e| crate::error::input_error("--scene", scene, e))
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
