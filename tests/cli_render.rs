//! `parallax render` end to end on lavapipe with validation on: the reconstruction pipeline
//! writes every output and the measures of render.json; path tracing every view gives the same
//! bits on any number of devices under every scheme (the random numbers depend on pixel, view,
//! frame, sample and bounce, never on the device).

mod common;

use common::scratch;

use std::path::Path;
use std::process::Command;

fn render(out: &Path, args: &[&str]) {
    let status = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .env("PARALLAX_VALIDATION", "1")
        .args(["render", "--lf", "4x2", "--resolution", "16x12", "--spacing", "0.05", "--spp", "2"])
        .args(args)
        .arg("--out-dir")
        .arg(out)
        .output()
        .unwrap();
    assert!(status.status.success(), "{args:?}: {}", String::from_utf8_lossy(&status.stderr));
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn path_traced_views_are_identical_on_any_number_of_devices_and_schemes() {
    let dir = scratch("render", "devices");
    let reference = dir.join("one");
    render(&reference, &["--pipeline", "path-trace", "--fake-devices", "1", "--frames", "2"]);
    assert_eq!(json(&reference.join("render.json"))["plan"]["views"], 8);
    for (devices, scheme) in [("2", "multi-source"), ("2", "fine-all"), ("2", "fine-sources")] {
        let other = dir.join(format!("{devices}-{scheme}"));
        // Three frames in flight here, two (the default) for the reference: the same bits.
        let args = ["--pipeline", "path-trace", "--fake-devices", devices, "--scheme", scheme, "--frames", "2"];
        render(&other, &[&args[..], &["--frames-in-flight", "3"]].concat());
        let report = json(&other.join("render.json"));
        assert!(report["missing_pixels"].is_null(), "path tracing has no holes to count");
        let multi = scheme == "multi-source";
        assert_eq!(report["assign"].is_null(), !multi, "{scheme}: an assignment only where one groups views");
        for v in 0..8 {
            let name = format!("view_{v:03}.exr");
            let a = std::fs::read(reference.join(&name)).unwrap();
            let b = std::fs::read(other.join(&name)).unwrap();
            assert!(a == b, "{name} differs between 1 device and {devices} devices under {scheme}");
        }
    }
}

#[test]
fn the_reconstruction_pipeline_writes_views_sheet_quilt_and_its_measures() {
    let dir = scratch("render", "reproject");
    let out = dir.join("lf");
    render(&out, &["--fake-devices", "2", "--frames", "3", "--warmup", "1", "--quilt", "--layers"]);
    let report = json(&out.join("render.json"));
    common::assert_typed_json("render.json", &report);
    assert_eq!((report["layout"]["lf"].as_str(), report["layout"]["spacing_m"].as_f64()), (Some("4x2"), Some(0.05)));
    assert_eq!(report["assign"], "compact");
    assert_eq!(report["pipeline"], "reproject");
    assert_eq!(report["reprojection_tolerance"], 0.2, "the default tolerance");
    assert_eq!(report["frames"], 3);
    assert_eq!((&report["barriers"], &report["timestamps"]), (&"tracked".into(), &"per-stage".into()), "the defaults");
    let stages: Vec<&str> =
        report["timing"]["stages"].as_array().unwrap().iter().map(|s| s["stage"].as_str().unwrap()).collect();
    // Every stage, in the order the pipeline runs them (the paper's Table 1), not by name.
    let at = |stage: &str| stages.iter().position(|s| *s == stage);
    let order =
        ["gbuffer", "path_trace", "reproject", "compact_holes", "hole_fill", "svgf_temporal", "tonemap", "transfer"];
    for pair in order.windows(2) {
        let (a, b) = (at(pair[0]), at(pair[1]));
        assert!(a.is_some() && b.is_some() && a < b, "render.json times {} before {}: {stages:?}", pair[0], pair[1]);
    }
    assert_eq!(report["timing"]["frames"], 3, "warm-up frames are not measured");
    assert_eq!(report["timing"]["busy_fraction"].as_array().unwrap().len(), 2);
    assert_eq!(report["frames_in_flight"], 2, "the default");
    assert_eq!(report["timing"]["frame_gpu_ms"].as_array().unwrap().len(), 3);
    assert_eq!(report["timing"]["frame_gpu_ms_complete"], true);
    // Where the host's time goes: every figure present; 2 intervals between 3 frames.
    let host = &report["timing"]["host"];
    for figure in ["frame_interval", "prepare", "submit_cpu", "slot_wait", "gpu_gap"] {
        assert!(host[figure]["mean_ms"].as_f64().is_some_and(|ms| ms >= 0.0), "{figure}: {host}");
    }
    assert!(host["frame_interval"]["mean_ms"].as_f64().unwrap() > 0.0);
    assert!(host["late_frames"].as_u64().is_some_and(|late| late <= 2));
    // The start, step by step, on the host's clock: each step ends after the one before it (the
    // first frame is done only after the executor that ran it was built).
    let startup = &report["startup"];
    let steps = ["planned_ms", "scene_loaded_ms", "devices_ms", "executor_ms", "first_frame_ms"];
    let ends: Vec<f64> =
        steps.iter().map(|s| startup[*s].as_f64().unwrap_or_else(|| panic!("{s}: {startup}"))).collect();
    assert_eq!(startup.as_object().unwrap().len(), steps.len(), "{startup}");
    assert!(ends[0] >= 0.0 && ends.windows(2).all(|w| w[0] <= w[1]), "{startup}");
    // The resident set over the measured frames: at least the samples at their two ends.
    let memory = &report["host_memory"];
    assert!(memory["samples"].as_u64().is_some_and(|n| n >= 2), "{memory}");
    let (min, max) = (memory["min_bytes"].as_u64().unwrap(), memory["max_bytes"].as_u64().unwrap());
    assert!(0 < min && min <= max, "{memory}");
    // `--sources-per-set auto` by default: its choice and prediction beside the measures.
    assert_eq!(report["sources_per_set"], "auto");
    assert_eq!(report["plan"]["sources_auto"], true);
    let predicted = report["plan"]["sources_prediction"].as_array().unwrap();
    assert_eq!(predicted.len(), 2, "one prediction per set: {predicted:?}");
    let chosen: u64 = predicted.iter().map(|p| p["sources"].as_u64().unwrap()).sum();
    assert_eq!(chosen as usize, report["plan"]["sources"].as_array().unwrap().len());
    let missing = &report["missing_pixels"];
    assert_eq!(missing["per_view"].as_array().unwrap().len(), 6, "8 views, 2 sources");
    let overall = missing["overall"].as_f64().unwrap();
    assert!(overall > 0.0 && overall < 1.0, "{overall}");
    assert!(out.join("lightfield.png").is_file());
    // --layers also draws each view's depth, and each target's hole mask, as PNGs.
    assert!((0..8).all(|v| out.join(format!("view_{v:03}_depth.png")).is_file()));
    let holes = (0..8).filter(|v| out.join(format!("view_{v:03}_holes.png")).is_file()).count();
    assert!((1..8).contains(&holes), "targets only: {holes}");
    // The quilt sweeps the row through the rig centre (row 1 of 2: 4 views), 2x2 tiles.
    let quilt = image::open(out.join("lightfield_qs2x2a1.3333.png")).unwrap();
    assert_eq!((quilt.width(), quilt.height()), (2 * 16, 2 * 12));
    // --layers: the hole mask is a channel of every target's EXR.
    let target = missing["per_view"][0][0].as_u64().unwrap();
    let exr = out.join(format!("view_{target:03}.exr"));
    let (_, _, channels) = parallax_scene::output::read_exr_channels(&exr, &["R", "holes.Y", "depth.Z"]).unwrap();
    assert!(channels[1].iter().all(|&h| h == 0.0 || h == 1.0));
    assert!(channels[0].iter().all(|c| c.is_finite()));
}

/// A default run warms up one frame (frame 0 pays pipeline creation) and keeps the camera still;
/// its PNGs are at the automatic exposure, tonemapped on the host by the pass's CPU twin, and
/// equal to the GPU's own tonemap at that exposure within one level.
#[test]
fn defaults_warm_up_and_expose_the_light_field() {
    let dir = scratch("render", "defaults");
    let auto = dir.join("auto");
    render(&auto, &[]);
    let report = json(&auto.join("render.json"));
    common::assert_typed_json("render.json", &report);
    assert!(report["sky"]["gradient"]["zenith"].is_array() && report["sun"]["angular_radius_deg"].is_number());
    assert_eq!((report["warmup"].as_u64(), report["timing"]["frames"].as_u64()), (Some(1), Some(1)));
    assert_eq!((report["setup"]["still"].as_bool(), report["exposure_mode"].as_str()), (Some(true), Some("auto")));
    let exposure = report["exposure"].as_f64().unwrap();
    assert!(exposure > 0.0 && exposure != 1.0, "{exposure}");
    let fixed = dir.join("fixed");
    render(&fixed, &["--exposure", &format!("{exposure}")]);
    assert_eq!(json(&fixed.join("render.json"))["exposure_mode"], "fixed");
    for v in 0..8 {
        let name = format!("view_{v:03}.png");
        let host = image::open(auto.join(&name)).unwrap().to_rgb8();
        let gpu = image::open(fixed.join(&name)).unwrap().to_rgb8();
        let worst = host.as_raw().iter().zip(gpu.as_raw()).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
        assert!(worst <= 1, "{name}: host and GPU tonemaps differ by {worst} levels");
    }
    let help = std::process::Command::new(env!("CARGO_BIN_EXE_parallax")).arg("--help").output().unwrap();
    assert!(String::from_utf8_lossy(&help.stdout).contains("through the paper's reconstruction pipeline"));
}

/// The check the JSON tests rely on fails on what render.json used to hold.
#[test]
fn the_typed_json_check_catches_debug_strings() {
    for bad in [
        serde_json::json!({ "layout": { "spec": "Grid { cols: 4, rows: 2 }" } }),
        serde_json::json!({ "sky": "Constant(Vec3(0.5, 0.6, 0.8))" }),
        serde_json::json!({ "settings": { "--cpu": "false", "--sun": "None" } }),
        serde_json::json!({ "error": ["1.08e-3"] }),
    ] {
        let caught = std::panic::catch_unwind(|| common::assert_typed_json("test", &bad));
        assert!(caught.is_err(), "{bad} passed");
    }
    common::assert_typed_json("test", &serde_json::json!({ "psnr": "inf", "args": ["--spp", "4"], "lf": "4x2" }));
}

fn parallax(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_parallax")).env("PARALLAX_VALIDATION", "1").args(args).output().unwrap()
}

/// render.json given back with `--config` repeats the run bit for bit; a TOML run file with the
/// same keys works too, the command line winning over it; a key that is no flag is refused.
#[test]
fn a_run_file_repeats_the_run() {
    let dir = scratch("render", "config");
    let first = dir.join("first");
    let camera = ["--camera", "0.5,1,4,0,1,0,0,1,0,50", "--sky", "0.5,0.6,0.8", "--max-depth", "3"];
    render(&first, &[&["--pipeline", "path-trace", "--frames", "2", "--exposure", "2"][..], &camera].concat());
    let again = dir.join("again");
    let config = first.join("render.json");
    let out = parallax(&["render", "--config", config.to_str().unwrap(), "--out-dir", again.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (a, b) = (json(&first.join("render.json")), json(&again.join("render.json")));
    assert_eq!(a["run"], b["run"]);
    assert_eq!(a["setup"], b["setup"]);
    for v in 0..8 {
        let name = format!("view_{v:03}.exr");
        assert!(std::fs::read(first.join(&name)).unwrap() == std::fs::read(again.join(&name)).unwrap(), "{name}");
    }

    let toml = dir.join("run.toml");
    std::fs::write(&toml, "lf = \"2x1\"\nresolution = \"16x12\"\nspp = 2\nstill = true\nframes = 2\n").unwrap();
    let third = dir.join("third");
    let out = parallax(&[
        "-q",
        "render",
        "--config",
        toml.to_str().unwrap(),
        "--spp",
        "1",
        "--out-dir",
        third.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let c = json(&third.join("render.json"));
    assert_eq!(
        (c["spp"].as_u64(), c["layout"]["lf"].as_str(), c["still"].as_bool()),
        (Some(1), Some("2x1"), Some(true))
    );

    std::fs::write(&toml, "spps = 2\n").unwrap();
    let out = parallax(&["render", "--config", toml.to_str().unwrap(), "--out-dir", third.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--config") && stderr.contains("--spps"), "{stderr}");
}

/// Hole filling starts each hole's camera rays from the G-buffer's first hit (their traversals
/// bounded by the triangle the centre ray hit) and changes no bit: on 1 device and on 3 under
/// fine-all, every hole pixel of the reconstruction's radiance (no denoiser, fireflies kept)
/// equals the pixel of path tracing every view, 2 spp jittered, over frames 0 and 1.
#[test]
fn hole_pixels_keep_the_bits_of_path_tracing_every_view() {
    let dir = scratch("render", "holes");
    let shared = ["--no-denoise", "--fireflies", "keep", "--frames", "2"];
    let traced = dir.join("traced");
    render(&traced, &[&["--pipeline", "path-trace", "--fake-devices", "1"][..], &shared].concat());
    for devices in ["1", "3"] {
        let out = dir.join(format!("reproject-{devices}"));
        render(&out, &[&["--fake-devices", devices, "--scheme", "fine-all", "--layers"][..], &shared].concat());
        let report = json(&out.join("render.json"));
        let targets = report["missing_pixels"]["per_view"].as_array().unwrap().clone();
        let mut holes = 0;
        for target in targets {
            let name = format!("view_{:03}.exr", target[0].as_u64().unwrap());
            let read = |path: &Path, names: &[&str]| parallax_scene::output::read_exr_channels(path, names).unwrap().2;
            let filled = read(&out.join(&name), &["R", "G", "B", "holes.Y"]);
            let reference = read(&traced.join(&name), &["R", "G", "B"]);
            for i in (0..filled[3].len()).filter(|&i| filled[3][i] == 1.0) {
                holes += 1;
                for c in 0..3 {
                    assert_eq!(
                        filled[c][i].to_bits(),
                        reference[c][i].to_bits(),
                        "{devices} device(s), {name}: pixel {i}"
                    );
                }
            }
        }
        assert!(holes > 0, "{devices} device(s): the light field has holes to fill");
    }
}

/// `--denoise` picks where SVGF runs and render.json records it (its `run` too, so `--config`
/// repeats it); `--no-denoise` is `--denoise none`, and the two together are one usage error.
#[test]
fn the_denoiser_is_chosen_by_flag_and_recorded() {
    let dir = scratch("render", "denoiser");
    let samples = dir.join("samples");
    render(&samples, &["--denoise", "samples", "--frames", "2"]);
    let j = json(&samples.join("render.json"));
    assert_eq!((j["denoise"].as_str(), j["run"]["denoise"].as_str()), (Some("samples"), Some("samples")));
    let stages: Vec<&str> =
        j["timing"]["stages"].as_array().unwrap().iter().map(|s| s["stage"].as_str().unwrap()).collect();
    assert!(stages.contains(&"hole_temporal") && stages.contains(&"svgf_temporal"), "{stages:?}");

    let again = dir.join("again");
    let config = samples.join("render.json");
    let out = parallax(&["-q", "render", "--config", config.to_str().unwrap(), "--out-dir", again.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for v in 0..8 {
        let name = format!("view_{v:03}.exr");
        assert!(std::fs::read(samples.join(&name)).unwrap() == std::fs::read(again.join(&name)).unwrap(), "{name}");
    }

    let none = dir.join("none");
    render(&none, &["--no-denoise", "--frames", "1"]);
    assert_eq!(json(&none.join("render.json"))["denoise"].as_str(), Some("none"));

    let both = dir.join("both");
    let out = parallax(&["render", "--denoise", "samples", "--no-denoise", "--out-dir", both.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--denoise") && stderr.contains("--no-denoise"), "{stderr}");
    assert!(!both.exists(), "a refused run writes nothing");
}

/// `--hole-fill subsampled` runs the reconstruction and render.json records it (its `run` too,
/// so `--config` repeats it bit for bit); `full` is the default; a misspelt value is refused by
/// clap, naming the values.
#[test]
fn the_hole_filling_is_chosen_by_flag_and_recorded() {
    let dir = scratch("render", "hole_fill");
    let subsampled = dir.join("subsampled");
    render(&subsampled, &["--hole-fill", "subsampled", "--denoise", "samples", "--frames", "2"]);
    let j = json(&subsampled.join("render.json"));
    assert_eq!((j["hole_fill"].as_str(), j["run"]["hole_fill"].as_str()), (Some("subsampled"), Some("subsampled")));
    let stages: Vec<&str> =
        j["timing"]["stages"].as_array().unwrap().iter().map(|s| s["stage"].as_str().unwrap()).collect();
    assert!(stages.contains(&"hole_reconstruct") && stages.contains(&"hole_reconstruct_apply"), "{stages:?}");

    let again = dir.join("again");
    let config = subsampled.join("render.json");
    let out = parallax(&["-q", "render", "--config", config.to_str().unwrap(), "--out-dir", again.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for v in 0..8 {
        let name = format!("view_{v:03}.exr");
        assert!(std::fs::read(subsampled.join(&name)).unwrap() == std::fs::read(again.join(&name)).unwrap(), "{name}");
    }

    let full = dir.join("full");
    render(&full, &["--frames", "1"]);
    let j = json(&full.join("render.json"));
    assert_eq!((j["hole_fill"].as_str(), j["run"]["hole_fill"].as_str()), (Some("full"), Some("full")));

    let misspelt = dir.join("misspelt");
    let out = parallax(&["render", "--hole-fill", "subsample", "--out-dir", misspelt.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--hole-fill") && stderr.contains("full") && stderr.contains("subsampled"), "{stderr}");
    assert!(!misspelt.exists(), "a refused run writes nothing");
}
