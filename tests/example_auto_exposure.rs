//! The `auto_exposure` example runs through `render`'s frame loop on lavapipe: two logical
//! devices, a 2×2 light field of 32×32, two frames. Its GPU exposure equals the host's
//! log-average of the read-back radiance to within 0.1 % (f32 sums over 16 tiles a view on the
//! GPU, f64 on the host), the display images follow the tonemap curve at that exposure to
//! within one 8-bit step, and `render`'s outputs are all there.

#[allow(dead_code)]
#[path = "../examples/auto_exposure.rs"]
mod auto_exposure;

use std::sync::{Arc, Mutex};

use clap::Parser;

/// Relative difference allowed between the GPU's exposure and the host's.
const EXPOSURE_TOLERANCE: f32 = 1e-3;

#[test]
fn the_gpu_exposure_matches_the_host_log_average_and_feeds_tonemap() {
    let out = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("example_auto_exposure");
    for scheme in ["multi-source", "fine-all"] {
        let dir = out.join(scheme);
        let args = [
            "render",
            "--lf",
            "2x2",
            "--resolution",
            "32x32",
            "--spacing",
            "0.05",
            "--fake-devices",
            "2",
            "--scheme",
            scheme,
            "--frames",
            "2",
            "--spp",
            "2",
            "--exposure",
            "1.5",
        ];
        let cli = auto_exposure::Cli::try_parse_from(args.iter().copied().chain(["--out-dir", dir.to_str().unwrap()]))
            .unwrap();
        let settings = cli.settings();
        let check = Arc::new(Mutex::new(auto_exposure::ExposureCheck::default()));
        let extension = auto_exposure::extension(settings.tonemap_exposure(), check.clone()).unwrap();
        parallax_render::job::run(&settings, extension).unwrap_or_else(|e| panic!("{scheme}: {e:#}"));
        let check = *check.lock().unwrap();
        let relative = (check.gpu - check.host).abs() / check.host;
        assert!(relative < EXPOSURE_TOLERANCE, "{scheme}: GPU {} vs host {}", check.gpu, check.host);
        assert!(check.gpu != 1.0, "{scheme}: the scene is lit, so the exposure is measured");
        assert!(check.display_steps <= 1, "{scheme}: display {} steps off the curve", check.display_steps);
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("render.json")).unwrap()).unwrap();
        assert_eq!(json["layout"]["views"], 4);
        assert!(dir.join("view_003.png").is_file() && dir.join("lightfield.png").is_file());
    }
}
