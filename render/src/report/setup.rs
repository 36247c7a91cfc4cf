//! What a light field's pixels depend on, as `render.json` and `reference.json` record it under
//! `setup`: the scene (by content), the camera of the written views, whether it stood still,
//! the layout, spacing, focus, resolution, lights and path depth. `compare` and
//! `bench --reference` read it beside both sides and refuse to compare runs that differ in any
//! of these ([`differences`]), since their figures would measure the difference in settings
//! rather than the error of the method.

use std::path::Path;

use anyhow::{Context as _, Result};
use parallax_graph::LightField;
use parallax_scene::{Camera, Scene, Sky};
use serde::{Deserialize, Serialize};

/// The camera of the written views (the light field's rig camera).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraSetup {
    pub eye: [f64; 3],
    pub forward: [f64; 3],
    pub up: [f64; 3],
    pub yfov_deg: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SunSetup {
    pub to_sun: [f64; 3],
    pub irradiance: [f64; 3],
    pub angular_radius_deg: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SkySetup {
    Constant([f64; 3]),
    Gradient { zenith: [f64; 3], horizon: [f64; 3], ground: [f64; 3] },
}

impl CameraSetup {
    pub fn of(camera: &Camera) -> Self {
        CameraSetup {
            eye: camera.eye.to_array().map(tidy),
            forward: camera.forward.to_array().map(tidy),
            up: camera.up.to_array().map(tidy),
            yfov_deg: tidy(camera.yfov.to_degrees()),
        }
    }
}

/// See the module docs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Setup {
    /// `--scene` as given (a path that is not UTF-8 with U+FFFD for what is not).
    pub scene: String,
    /// `default`, or the scene file's FNV-1a hash and size: what the comparison checks, so two
    /// paths to the same file agree.
    pub scene_hash: String,
    pub camera: CameraSetup,
    /// The camera did not move over the frames (`--motion none`, or a single frame).
    pub still: bool,
    /// `--lf` in its CLI spelling: multiscopic, nelf or COLSxROWS.
    pub lf: String,
    pub spacing_m: f64,
    pub focus_m: f64,
    pub resolution: [u32; 2],
    pub sun: Option<SunSetup>,
    pub sky: SkySetup,
    pub max_depth: u32,
}

/// The scene file's name, FNV-1a hash and size (`default` for the built-in scene). Buffers and
/// textures a glTF refers to are not hashed.
pub fn scene_fingerprint(spec: &Path) -> Result<String> {
    if spec == Path::new("default") {
        return Ok("default".into());
    }
    let bytes = parallax_scene::input::read_bounded(spec, parallax_scene::input::SCENE_FILE_LIMIT, "glTF scene")
        .map_err(|e| crate::error::input_error("--scene", spec, e))?;
    let hash = bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3));
    let name = spec.file_name().map_or(spec.to_string_lossy(), |n| n.to_string_lossy());
    Ok(format!("{name} (fnv1a {hash:016x}, {} bytes)", bytes.len()))
}

impl Setup {
    /// The setup of `lf`'s views of `scene` (its lights as the run set them), seen from `camera`,
    /// `spacing` the spacing in effect (`None`: the preset's, 1 mm).
    pub fn new(
        spec: &Path,
        scene: &Scene,
        camera: &Camera,
        still: bool,
        (lf, spacing): (&LightField, Option<f64>),
        max_depth: u32,
    ) -> Result<Self> {
        let sky = match scene.sky() {
            Sky::Constant(c) => SkySetup::Constant(c.to_array().map(tidy)),
            Sky::Gradient { zenith, horizon, ground } => SkySetup::Gradient {
                zenith: zenith.to_array().map(tidy),
                horizon: horizon.to_array().map(tidy),
                ground: ground.to_array().map(tidy),
            },
        };
        Ok(Setup {
            scene: spec.to_string_lossy().into_owned(),
            scene_hash: scene_fingerprint(spec)?,
            camera: CameraSetup::of(camera),
            still,
            lf: lf.name.clone(),
            spacing_m: spacing.unwrap_or(parallax_graph::lightfield::DEFAULT_SPACING),
            focus_m: lf.rig.focus_distance,
            resolution: [lf.width, lf.height],
            sun: scene.sun.map(|s| SunSetup {
                to_sun: s.to_sun.to_array().map(tidy),
                irradiance: s.irradiance.to_array().map(tidy),
                angular_radius_deg: tidy(s.angular_radius.to_degrees()),
            }),
            sky,
            max_depth,
        })
    }
}

/// An f32 as the f64 of its shortest decimal form, so JSON shows 0.15 rather than
/// 0.15000000596046448.
fn tidy(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(x as f64)
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-5 * a.abs().max(b.abs()).max(1.0)
}

fn close3(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(&b).all(|(x, y)| close(*x, *y))
}

fn show3(v: [f64; 3]) -> String {
    format!("({}, {}, {})", v[0], v[1], v[2])
}

fn lights(s: &Setup) -> String {
    let sun = match &s.sun {
        Some(sun) => {
            format!("sun towards {} at {}, {}°", show3(sun.to_sun), show3(sun.irradiance), sun.angular_radius_deg)
        }
        None => "no sun".into(),
    };
    let sky = match s.sky {
        SkySetup::Constant(c) => format!("sky {}", show3(c)),
        SkySetup::Gradient { zenith, horizon, ground } => {
            format!("sky gradient {} / {} / {}", show3(zenith), show3(horizon), show3(ground))
        }
    };
    format!("{sun}, {sky}")
}

fn camera(c: &CameraSetup) -> String {
    format!("eye {} forward {} up {} yfov {}°", show3(c.eye), show3(c.forward), show3(c.up), c.yfov_deg)
}

fn same_lights(a: &Setup, b: &Setup) -> bool {
    let sun = match (&a.sun, &b.sun) {
        (None, None) => true,
        (Some(x), Some(y)) => {
            close3(x.to_sun, y.to_sun)
                && close3(x.irradiance, y.irradiance)
                && close(x.angular_radius_deg, y.angular_radius_deg)
        }
        _ => false,
    };
    let sky = match (a.sky, b.sky) {
        (SkySetup::Constant(x), SkySetup::Constant(y)) => close3(x, y),
        (
            SkySetup::Gradient { zenith: z1, horizon: h1, ground: g1 },
            SkySetup::Gradient { zenith: z2, horizon: h2, ground: g2 },
        ) => close3(z1, z2) && close3(h1, h2) && close3(g1, g2),
        _ => false,
    };
    sun && sky
}

/// Each setting in which `test` differs from `reference`, as `name: test's vs reference's`.
pub fn differences(test: &Setup, reference: &Setup) -> Vec<String> {
    let mut out = Vec::new();
    let mut differ = |name: &str, same: bool, a: String, b: String| {
        if !same {
            out.push(format!("{name}: {a} vs {b}"));
        }
    };
    differ("scene", test.scene_hash == reference.scene_hash, test.scene_hash.clone(), reference.scene_hash.clone());
    let (c, d) = (&test.camera, &reference.camera);
    let same_camera =
        close3(c.eye, d.eye) && close3(c.forward, d.forward) && close3(c.up, d.up) && close(c.yfov_deg, d.yfov_deg);
    differ("camera", same_camera, camera(c), camera(d));
    let still = |s: bool| if s { "still" } else { "moving (--motion dolly or animation)" }.to_string();
    differ("still", test.still == reference.still, still(test.still), still(reference.still));
    differ("layout", test.lf == reference.lf, test.lf.clone(), reference.lf.clone());
    let same_f64 = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0);
    differ(
        "spacing",
        same_f64(test.spacing_m, reference.spacing_m),
        format!("{} m", test.spacing_m),
        format!("{} m", reference.spacing_m),
    );
    differ(
        "focus",
        same_f64(test.focus_m, reference.focus_m),
        format!("{} m", test.focus_m),
        format!("{} m", reference.focus_m),
    );
    let res = |r: [u32; 2]| format!("{}x{}", r[0], r[1]);
    differ("resolution", test.resolution == reference.resolution, res(test.resolution), res(reference.resolution));
    differ("lights", same_lights(test, reference), lights(test), lights(reference));
    differ(
        "max depth",
        test.max_depth == reference.max_depth,
        test.max_depth.to_string(),
        reference.max_depth.to_string(),
    );
    out
}

/// The setup recorded beside `path` (a light-field folder, or an EXR in one): its
/// `render.json`, else its `reference.json`. `Ok(None)` with the reason when there is none to
/// read; an error when the file is there but unreadable.
pub fn setup_beside(path: &Path) -> Result<std::result::Result<Setup, String>> {
    let folder = if path.is_dir() { path } else { path.parent().unwrap_or(Path::new(".")) };
    let folder = if folder.as_os_str().is_empty() { Path::new(".") } else { folder };
    // Whatever is there under the name is read as every input is: a FIFO or a 1 GB file is
    // refused by name, not waited on or read whole.
    let Some(json_path) = ["render.json", "reference.json"].iter().map(|n| folder.join(n)).find(|p| p.exists()) else {
        return Ok(Err(format!("no render.json or reference.json in {}", folder.display())));
    };
    let bytes = parallax_scene::input::read_bounded(&json_path, parallax_scene::input::TEXT_FILE_LIMIT, "JSON file")?;
    let json: serde_json::Value =
        serde_json::from_slice(&bytes).with_context(|| format!("{} is not JSON", json_path.display()))?;
    match json.get("setup") {
        None => Ok(Err(format!("{} has no `setup` (an older parallax wrote it)", json_path.display()))),
        Some(setup) => Ok(Ok(serde_json::from_value(setup.clone())
            .with_context(|| format!("{}: `setup` is not what parallax writes", json_path.display()))?)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> Setup {
        Setup {
            scene: "default".into(),
            scene_hash: "default".into(),
            camera: CameraSetup {
                eye: [0.0, 1.0, 4.0],
                forward: [0.0, 0.0, -1.0],
                up: [0.0, 1.0, 0.0],
                yfov_deg: 45.0,
            },
            still: true,
            lf: "4x2".into(),
            spacing_m: 0.001,
            focus_m: 4.0,
            resolution: [32, 24],
            sun: None,
            sky: SkySetup::Constant([0.5, 0.6, 0.8]),
            max_depth: 6,
        }
    }

    #[test]
    fn each_differing_setting_is_named() {
        let a = setup();
        assert!(differences(&a, &a).is_empty());
        let mut b = a.clone();
        b.camera.eye[0] += 1e-7;
        assert!(differences(&a, &b).is_empty(), "rounding is not a difference");
        b.camera.eye[0] = 0.5;
        b.still = false;
        b.lf = "8x4".into();
        b.spacing_m = 0.002;
        b.focus_m = 3.0;
        b.resolution = [16, 12];
        b.sun = Some(SunSetup { to_sun: [0.0, 1.0, 0.0], irradiance: [5.0; 3], angular_radius_deg: 0.27 });
        b.max_depth = 2;
        b.scene_hash = "box.gltf (fnv1a 0123456789abcdef, 10 bytes)".into();
        let names: Vec<String> = differences(&b, &a).iter().map(|d| d.split(':').next().unwrap().to_string()).collect();
        assert_eq!(
            names,
            ["scene", "camera", "still", "layout", "spacing", "focus", "resolution", "lights", "max depth"]
        );
        let d = differences(&b, &a);
        assert_eq!(d[2], "still: moving (--motion dolly or animation) vs still");
        assert_eq!(d[6], "resolution: 16x12 vs 32x24");
        assert!(
            d[7].starts_with("lights: sun towards (0, 1, 0)") && d[7].ends_with("no sun, sky (0.5, 0.6, 0.8)"),
            "{}",
            d[7]
        );
        let mut c = a.clone();
        c.sky = SkySetup::Gradient { zenith: [1.0; 3], horizon: [0.5; 3], ground: [0.0; 3] };
        assert_eq!(differences(&c, &a).len(), 1);
    }

    #[test]
    fn the_setup_round_trips_through_json() {
        let a = setup();
        let json = serde_json::to_value(&a).unwrap();
        assert_eq!(json["sky"]["constant"], serde_json::json!([0.5, 0.6, 0.8]));
        assert_eq!(json["resolution"], serde_json::json!([32, 24]));
        assert_eq!(serde_json::from_value::<Setup>(json).unwrap(), a);
    }

    #[test]
    fn a_folder_without_a_sidecar_says_so() {
        let dir = tempfile::tempdir().unwrap();
        assert!(setup_beside(dir.path()).unwrap().unwrap_err().contains("no render.json or reference.json"));
        std::fs::write(dir.path().join("render.json"), "{}").unwrap();
        assert!(setup_beside(dir.path()).unwrap().unwrap_err().contains("has no `setup`"));
        std::fs::write(dir.path().join("render.json"), serde_json::json!({ "setup": setup() }).to_string()).unwrap();
        assert_eq!(setup_beside(&dir.path().join("view_000.exr")).unwrap().unwrap(), setup());
        std::fs::write(dir.path().join("render.json"), "{").unwrap();
        assert!(setup_beside(dir.path()).is_err());
    }
}
