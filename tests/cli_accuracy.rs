//! `parallax reference`, `compare` and `chart` end to end (GPU parts on lavapipe with
//! validation on, at tiny sizes).

mod common;

use common::scratch;

use std::path::Path;
use std::process::{Command, Output};

use parallax_accuracy::RgbImage;

fn parallax(args: &[&str], dirs: &[&Path]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_parallax"));
    cmd.env("PARALLAX_VALIDATION", "1").args(args);
    for d in dirs {
        cmd.arg(d);
    }
    cmd.output().unwrap()
}

fn ok(out: Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn fails(out: Output) -> String {
    assert!(!out.status.success(), "expected a failure; stdout {}", String::from_utf8_lossy(&out.stdout));
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

const SMALL: &[&str] = &["reference", "--lf", "2x1", "--resolution", "16x12", "--spacing", "0.05", "--chunk-spp", "4"];

fn reference(extra: &[&str], out: &Path) -> Output {
    parallax(&[SMALL, extra, &["--out-dir"]].concat(), &[out])
}

/// A run stopped after 2 of 4 chunks (on 2 devices) and resumed (on 1) equals an uninterrupted
/// run byte for byte: chunk k always has frame FRAME_BASE + k and the f64 sum adds chunks in
/// the same order. Stopping is a lower --spp target, the same code path as an interruption
/// between checkpoints (every chunk here: --checkpoint-secs 0).
#[test]
fn a_resumed_reference_equals_an_uninterrupted_one() {
    let dir = scratch("accuracy", "resume");
    let (straight, resumed) = (dir.join("straight"), dir.join("resumed"));
    ok(reference(&["--spp", "16", "--fake-devices", "1"], &straight));
    ok(reference(&["--spp", "8", "--fake-devices", "2", "--checkpoint-secs", "0"], &resumed));
    assert_eq!(json(&resumed.join("reference.json"))["spp"], 8);
    let log = reference(&["--spp", "16", "--fake-devices", "1"], &resumed);
    assert!(String::from_utf8_lossy(&log.stderr).contains("resuming"));
    ok(log);
    for v in 0..2 {
        let name = format!("view_{v:03}.exr");
        let (a, b) = (std::fs::read(straight.join(&name)).unwrap(), std::fs::read(resumed.join(&name)).unwrap());
        assert!(a == b, "{name} differs between the resumed and the uninterrupted reference");
    }
    let meta = json(&resumed.join("reference.json"));
    assert_eq!((meta["spp"].as_u64(), meta["chunks"].as_u64()), (Some(16), Some(4)));
    assert_eq!(meta["point"]["views"], 2);
    assert!(resumed.join("reference.png").is_file());

    // A different setting is refused, naming the flag; nothing is overwritten.
    let before = std::fs::read(resumed.join("reference.partial")).unwrap();
    let err = fails(reference(&["--spp", "32", "--max-depth", "3"], &resumed));
    assert!(err.contains("--max-depth 6") && err.contains("--max-depth 3"), "{err}");
    assert_eq!(std::fs::read(resumed.join("reference.partial")).unwrap(), before);
    let err = fails(reference(&["--spp", "10"], &dir.join("bad")));
    assert!(err.contains("--chunk-spp 4") && err.contains("--spp 12"), "{err}");
    assert!(!dir.join("bad").exists());
}

/// A real interruption: the run is killed (SIGKILL) after a checkpoint, then resumed; the result
/// equals an uninterrupted run of the same samples byte for byte. The killed run asks for more
/// samples than the test could wait for, so it is interrupted however late the kill comes on a
/// loaded machine; both runs then go to the first multiple of 64 spp past where it stopped.
#[test]
fn a_killed_reference_resumes_to_the_same_bytes() {
    let dir = scratch("accuracy", "kill");
    let (straight, killed) = (dir.join("straight"), dir.join("killed"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .args([SMALL, &["--spp", "1000000", "--fake-devices", "1", "--checkpoint-secs", "0", "--out-dir"]].concat())
        .arg(&killed)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let partial = killed.join("reference.partial");
    // A hang guard only: the first checkpoint comes within a second on an idle machine.
    let t = std::time::Instant::now();
    while !partial.exists() && t.elapsed().as_secs() < 300 {
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let reached = parallax_accuracy::Accumulator::load(&partial).unwrap().header.spp;
    assert!(reached > 0, "killed before its first checkpoint");
    let total = (reached / 64 + 1) * 64;
    let total_arg = total.to_string();
    ok(reference(&["--spp", &total_arg, "--fake-devices", "1"], &straight));
    let log = reference(&["--spp", &total_arg, "--fake-devices", "1"], &killed);
    assert!(String::from_utf8_lossy(&log.stderr).contains(&format!("resuming {} at {reached} spp", partial.display())));
    ok(log);
    for v in 0..2 {
        let name = format!("view_{v:03}.exr");
        let (a, b) = (std::fs::read(straight.join(&name)).unwrap(), std::fs::read(killed.join(&name)).unwrap());
        assert!(a == b, "{name}: killed at {reached} spp and resumed to {total} differs from the uninterrupted run");
    }
    let leftovers: Vec<_> = std::fs::read_dir(&killed)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left behind: {leftovers:?}");
}

fn mean_and_se(dir: &Path) -> ([f64; 3], [f64; 3]) {
    let meta = json(&dir.join("reference.json"));
    let read = |key: &str| [0, 1, 2].map(|c| meta[key][c].as_f64().unwrap());
    (read("mean_radiance"), read("standard_error"))
}

/// On the Cornell box (32×32, chunks of 64 spp): the 1024-spp mean is within 1 % of the
/// 4096-spp mean (the same run, resumed), and the CPU reference at 4096 spp agrees with the
/// GPU's within two combined standard errors per channel. (Both tracers draw the same random
/// numbers, so in practice they agree far more closely; measured figures in docs/RESULTS.md.)
#[test]
fn the_cornell_box_reference_converges_and_cpu_and_gpu_agree() {
    let dir = scratch("accuracy", "cornell");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/cornell_box/CornellBox-Original.gltf");
    let scene = scene.to_str().unwrap();
    let base = ["reference", "--scene", scene, "--lf", "1x1", "--resolution", "32x32", "--chunk-spp", "64"];
    let (gpu, cpu) = (dir.join("gpu"), dir.join("cpu"));
    ok(parallax(&[&base[..], &["--spp", "1024", "--fake-devices", "1", "--out-dir"]].concat(), &[&gpu]));
    let (m1024, _) = mean_and_se(&gpu);
    ok(parallax(&[&base[..], &["--spp", "4096", "--fake-devices", "1", "--out-dir"]].concat(), &[&gpu]));
    let (m4096, se_gpu) = mean_and_se(&gpu);
    for c in 0..3 {
        assert!(m4096[c] > 0.0);
        let rel = (m1024[c] - m4096[c]).abs() / m4096[c];
        assert!(rel < 0.01, "channel {c}: 1024 spp {} vs 4096 spp {} ({:.3} %)", m1024[c], m4096[c], rel * 100.0);
    }
    ok(parallax(&[&base[..], &["--spp", "4096", "--cpu", "--out-dir"]].concat(), &[&cpu]));
    let (m_cpu, se_cpu) = mean_and_se(&cpu);
    for c in 0..3 {
        let combined = (se_gpu[c].powi(2) + se_cpu[c].powi(2)).sqrt();
        assert!(combined.is_finite() && combined > 0.0);
        assert!(
            (m_cpu[c] - m4096[c]).abs() <= 2.0 * combined,
            "channel {c}: CPU {} ± {} vs GPU {} ± {}",
            m_cpu[c],
            se_cpu[c],
            m4096[c],
            se_gpu[c]
        );
    }
}

fn ramp(w: usize, h: usize, offset: f32) -> RgbImage {
    let px = (0..w * h).map(|i| [(i % w) as f32 / w as f32 + offset, (i / w) as f32 / h as f32, 0.25]).collect();
    RgbImage::new(w, h, px)
}

fn folder(dir: &Path, views: &[(u32, RgbImage)]) {
    std::fs::create_dir_all(dir).unwrap();
    for (v, img) in views {
        img.write_exr(&dir.join(format!("view_{v:03}.exr")), &[]).unwrap();
    }
}

#[test]
fn compare_of_folders_and_files() {
    let dir = scratch("accuracy", "compare");
    let (a, b) = (dir.join("a"), dir.join("b"));
    folder(&a, &[(0, ramp(20, 12, 0.0)), (1, ramp(20, 12, 0.1))]);
    folder(&b, &[(0, ramp(20, 12, 0.0)), (1, ramp(20, 12, 0.0))]);

    // Itself: infinite PSNR (the string "inf" in JSON), SSIM 1, FLIP 0.
    let j = dir.join("self.json");
    let table = ok(parallax(&["compare"], &[&a, &a, Path::new("--json"), &j]));
    assert!(table.contains("| **all** | 2 views | ∞ | ∞ | 1.00000 | 0.00000 |"), "{table}");
    let same = json(&j);
    assert_eq!(same["comparison"]["overall"]["psnr_linear_db"], "inf");
    assert_eq!(same["comparison"]["overall"]["ssim"], 1.0);
    assert_eq!(same["comparison"]["overall"]["flip"], 0.0);
    assert!(same["point"].get("psnr").is_none(), "an infinite PSNR is not a chart point");

    let j = dir.join("ab.json");
    let table = ok(parallax(&["compare", "--label", "ramp"], &[&a, &b, Path::new("--json"), &j]));
    assert!(table.contains("view_001.exr"), "{table}");
    let ab = json(&j);
    let views = ab["comparison"]["views"].as_array().unwrap();
    assert_eq!(views[0]["psnr_linear_db"], "inf");
    assert!(views[1]["psnr_linear_db"].as_f64().unwrap() < 40.0);
    assert!(ab["point"]["flip"].as_f64().unwrap() > 0.0);
    assert_eq!(ab["point"]["label"], "ramp");

    // The per-view error across the grid: view 0 (no error) black, view 1 (the worst) pale
    // yellow, one 80×48 cell each (the views' 5:3 aspect), a white gap between them.
    let grid = dir.join("grid.png");
    let log = parallax(&["compare"], &[&a, &b, Path::new("--error-grid"), &grid]);
    assert!(String::from_utf8_lossy(&log.stderr).contains("(pale yellow: mean FLIP"), "the scale is printed");
    ok(log);
    let grid = image::open(&grid).unwrap().to_rgb8();
    assert_eq!(grid.dimensions(), (2 * 80 + 2, 48));
    assert!(grid.get_pixel(40, 24).0.iter().all(|&c| c < 10), "{:?}", grid.get_pixel(40, 24));
    assert_eq!(grid.get_pixel(81, 24).0, [255, 255, 255]);
    assert!(grid.get_pixel(120, 24).0.iter().all(|&c| c > 180), "{:?}", grid.get_pixel(120, 24));

    // Single files.
    ok(parallax(&["compare"], &[&a.join("view_000.exr"), &b.join("view_000.exr")]));

    // Missing views, size mismatch, non-finite pixels, a folder against a file: clear errors.
    let c = dir.join("c");
    folder(&c, &[(0, ramp(20, 12, 0.0))]);
    let err = fails(parallax(&["compare"], &[&a, &c]));
    assert!(err.contains("missing") && err.contains("view_001.exr"), "{err}");
    let d = dir.join("d");
    folder(&d, &[(0, ramp(20, 10, 0.0)), (1, ramp(20, 12, 0.0))]);
    let err = fails(parallax(&["compare"], &[&a, &d]));
    assert!(err.contains("20x12") && err.contains("20x10"), "{err}");
    let mut nan = ramp(20, 12, 0.0);
    nan.pixels[3][0] = f32::NAN;
    nan.pixels[30][2] = f32::INFINITY;
    let e = dir.join("e");
    let mut nan1 = ramp(20, 12, 0.0);
    nan1.pixels[25][1] = f32::NEG_INFINITY;
    folder(&e, &[(0, nan), (1, nan1)]);
    let err = fails(parallax(&["compare"], &[&e, &b]));
    assert!(err.contains("3 pixel(s) with a non-finite channel"), "{err}");
    assert!(
        err.contains("view_000.exr: 2, first at (3, 0)") && err.contains("view_001.exr: 1, first at (5, 1)"),
        "{err}"
    );
    let err = fails(parallax(&["compare"], &[&a, &b.join("view_000.exr")]));
    assert!(err.contains("not one of each"), "{err}");
    let err = fails(parallax(&["compare"], &[&a, &dir.join("nothing")]));
    assert!(err.contains("does not exist"), "{err}");
}

/// render → reference → compare → chart, as a user would chain them.
#[test]
fn charts_from_render_reference_and_compare_outputs() {
    let dir = scratch("accuracy", "chart");
    let lf = ["--lf", "2x1", "--resolution", "16x12", "--spacing", "0.05"];
    let (render, refdir) = (dir.join("render"), dir.join("ref"));
    let trace = dir.join("trace.json");
    ok(parallax(
        &[&["render"], &lf[..], &["--spp", "2", "--fake-devices", "2", "--trace"]].concat(),
        &[&trace, Path::new("--out-dir"), &render],
    ));
    ok(parallax(&[&["reference"], &lf[..], &["--spp", "32", "--fake-devices", "1", "--out-dir"]].concat(), &[&refdir]));
    let cmp = dir.join("cmp.json");
    ok(parallax(&["compare"], &[&render, &refdir, Path::new("--json"), &cmp]));
    let point = &json(&cmp)["point"];
    assert!(point["frame_ms"].as_f64().unwrap() > 0.0 && point["flip"].as_f64().unwrap() > 0.0);
    assert_eq!((point["devices"].as_u64(), point["views"].as_u64()), (Some(2), Some(2)));

    let out = |name: &str| dir.join(name);
    ok(parallax(
        &["chart", "speed-accuracy"],
        &[&cmp, Path::new("-o"), &out("sa.svg"), Path::new("-o"), &out("sa.png")],
    ));
    ok(parallax(&["chart", "speed-accuracy", "--metric", "psnr"], &[&cmp, Path::new("-o"), &out("sa_psnr.svg")]));
    ok(parallax(&["chart", "scaling"], &[&render.join("render.json"), Path::new("-o"), &out("sc.png")]));
    ok(parallax(
        &["chart", "views"],
        &[&render.join("render.json"), &refdir.join("reference.json"), Path::new("-o"), &out("v.svg")],
    ));
    ok(parallax(&["chart", "timeline"], &[&trace, Path::new("-o"), &out("tl.svg"), Path::new("-o"), &out("tl.png")]));
    for png in ["sa.png", "sc.png", "tl.png"] {
        image::open(out(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
    }
    for svg in ["sa.svg", "sa_psnr.svg", "v.svg", "tl.svg"] {
        let text = std::fs::read_to_string(out(svg)).unwrap();
        assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"), "{svg}");
    }
    let err = fails(parallax(
        &["chart", "speed-accuracy"],
        &[&refdir.join("reference.json"), Path::new("-o"), &out("x.svg")],
    ));
    assert!(err.contains("no input point has"), "{err}");
    assert!(!out("x.svg").exists());
}

/// What a reference would cost is checked before anything is traced, allocated or written.
#[test]
fn an_unbounded_reference_is_refused_before_it_starts() {
    let dir = scratch("accuracy", "unbounded");
    let out = dir.join("never");
    let err = fails(parallax(
        &["reference", "--lf", "64x64", "--resolution", "4096x4096", "--spp", "4096", "--out-dir"],
        &[&out],
    ));
    assert!(err.contains("paths") && err.contains("--spp"), "{err}");
    assert!(!out.exists());
}

/// compare reads the settings beside both sides: a moving camera, another depth or other
/// lights against a still reference are refused naming each, unless --allow-mismatch; a
/// `render --still` of the reference's settings compares, at an exposure it reports, with a
/// FLIP error map laid out as the contact sheet.
#[test]
fn compare_refuses_runs_of_other_settings_and_maps_the_error() {
    let dir = scratch("accuracy", "mismatch");
    let refdir = dir.join("ref");
    ok(reference(&["--spp", "8", "--fake-devices", "1"], &refdir));
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let lf = ["render", "--lf", "2x1", "--resolution", "16x12", "--spacing", "0.05", "--spp", "2"];
        ok(parallax(&[&lf[..], extra, &["--out-dir"]].concat(), &[&out]));
        out
    };
    let moving = render("moving", &["--frames", "2", "--motion", "dolly"]);
    let err = fails(parallax(&["compare"], &[&moving, &refdir]));
    assert!(
        err.contains("still: moving (--motion dolly or animation) vs still") && err.contains("camera: eye"),
        "{err}"
    );
    assert!(err.contains("--allow-mismatch") && !err.contains("layout:"), "{err}");
    let allowed = parallax(&["compare", "--allow-mismatch"], &[&moving, &refdir]);
    assert!(String::from_utf8_lossy(&allowed.stderr).contains("although the settings differ"));
    ok(allowed);

    let other = render("other", &["--still", "--max-depth", "2", "--sun", "0,1,0,3"]);
    // Single views are checked by the sidecars of their folders.
    let err = fails(parallax(&["compare"], &[&other.join("view_000.exr"), &refdir.join("view_000.exr")]));
    assert!(err.contains("max depth: 2 vs 6") && err.contains("lights: sun towards (0, 1, 0)"), "{err}");
    assert!(!err.contains("still:") && !err.contains("camera:"), "{err}");

    let still = render("still", &["--still", "--frames", "2"]);
    let (auto, fixed, map) = (dir.join("auto.json"), dir.join("fixed.json"), dir.join("flip.png"));
    let table =
        ok(parallax(&["compare"], &[&still, &refdir, Path::new("--json"), &auto, Path::new("--flip-map"), &map]));
    let reference_json = json(&refdir.join("reference.json"));
    common::assert_typed_json("reference.json", &reference_json);
    common::assert_typed_json("compare --json", &json(&auto));
    common::assert_typed_json("render.json", &json(&still.join("render.json")));
    let auto = json(&auto)["comparison"].clone();
    assert_eq!(auto["exposure_mode"], "auto");
    assert!(table.contains(&format!("exposure {:.4}, auto", auto["exposure"].as_f64().unwrap())), "{table}");
    assert_eq!(reference_json["exposure_mode"], "auto");
    assert_eq!(auto["exposure"], reference_json["exposure"], "the reference's own automatic exposure");
    ok(parallax(&["compare", "--exposure", "16"], &[&still, &refdir, Path::new("--json"), &fixed]));
    let fixed = json(&fixed)["comparison"].clone();
    assert_eq!((fixed["exposure"].as_f64(), fixed["exposure_mode"].as_str()), (Some(16.0), Some("fixed")));
    assert_ne!(fixed["overall"]["flip"], auto["overall"]["flip"]);
    assert_eq!(fixed["overall"]["psnr_linear_db"], auto["overall"]["psnr_linear_db"], "linear figures ignore it");
    // Two 16x12 views side by side, 2 pixels apart; some error, none of it maximal.
    let map = image::open(&map).unwrap().to_rgb8();
    assert_eq!(map.dimensions(), (34, 12));
    assert!(map.pixels().any(|p| p.0 != [0, 0, 4]), "the error map is not all zero error");
}
