//! Defaults a person expects (issue 28): each surprise a new user met, with a test of the new
//! default. A placed camera stays put, an unlit scene is lit by the stated default environment,
//! `-q` prints no stage table, a trace may go into the `--out-dir` render creates, `compare
//! --json -` writes JSON on stdout. GPU parts on lavapipe, at tiny sizes.

mod common;

use common::{parallax_in, scratch, write_gltf};

use parallax_accuracy::RgbImage;

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Fox, CesiumMan and Sponza carry no light: they are lit by the default environment, which
/// the run names, instead of a black image with exit 0. A black `--sky` given on purpose stays
/// black, with a warning.
#[test]
fn an_unlit_scene_gets_the_default_environment() {
    let dir = scratch("defaults", "unlit");
    let dark = write_gltf(&dir, "dark", &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], r#"[{"mesh":0}]"#, "");
    let trace = |extra: &[&str]| {
        let scene = dark.to_str().unwrap();
        let args = [&["trace", "--cpu", "--resolution", "8x8", "--spp", "2", "--scene", scene][..], extra].concat();
        parallax_in(&dir, &args)
    };
    let out = trace(&["--out", "lit.exr"]);
    let log = stderr(&out);
    assert!(out.status.success(), "{log}");
    assert!(
        log.contains("scene 'dark' has no light")
            && log
                .contains("lit by the default environment (sky zenith 1,1,1, horizon 0.8,0.8,0.8, ground 0.3,0.3,0.3)")
            && !log.contains("warning"),
        "{log}"
    );
    let lit = RgbImage::read_exr(&dir.join("lit.exr")).unwrap();
    assert!(lit.pixels.iter().all(|p| p.iter().all(|&c| c > 0.0)), "every pixel sees the sky or a lit surface");

    let out = trace(&["--sky", "0,0,0", "--out", "black.exr"]);
    let log = stderr(&out);
    assert!(out.status.success(), "{log}");
    assert!(log.contains("warning: scene 'dark' has no light") && log.contains("and a black --sky"), "{log}");
    let black = RgbImage::read_exr(&dir.join("black.exr")).unwrap();
    assert!(black.pixels.iter().all(|p| *p == [0.0; 3]));
}

/// `render --camera … --frames 2` keeps the camera where it was put (render.json says
/// `motion: none`, the setup is still, so `compare` with a still reference agrees); `-q` prints
/// the results but no stage table; `--trace tr/trace.json` is accepted although `tr` is made by
/// the run; `compare --json -` writes the JSON on stdout and the table on stderr.
#[test]
fn a_placed_camera_stays_put_and_quiet_runs_print_results_only() {
    let dir = scratch("defaults", "camera");
    let camera = "0,1,4.5,0,1,0,0,1,0,45";
    let out = parallax_in(
        &dir,
        &[
            "-q",
            "render",
            "--lf",
            "2x1",
            "--resolution",
            "8x8",
            "--fake-devices",
            "1",
            "--camera",
            camera,
            "--frames",
            "2",
            "--out-dir",
            "tr",
            "--trace",
            "tr/trace.json",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("rendered 2 views") && !stdout.contains("| stage |"), "{stdout}");
    assert!(dir.join("tr/trace.json").is_file());
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("tr/render.json")).unwrap()).unwrap();
    assert_eq!(json["motion"], "none");
    assert_eq!(json["still"], true);
    assert_eq!(json["setup"]["camera"], json["camera"], "the last frame's camera is the first's");

    let cmp = parallax_in(&dir, &["compare", "tr", "tr", "--json", "-"]);
    assert!(cmp.status.success(), "{}", stderr(&cmp));
    let json: serde_json::Value = serde_json::from_slice(&cmp.stdout).expect("stdout is the JSON alone");
    assert_eq!(json["comparison"]["overall"]["flip"], 0.0);
    assert!(stderr(&cmp).contains("| **all** | 2 views |"), "the table goes to stderr");
}

/// A quilt is one horizontal sweep: NELF's two eye blocks are refused before any frame, naming
/// the reason (exit 2), and an unknown quilt shape lists the Looking Glass presets.
#[test]
fn a_nelf_quilt_is_refused_before_any_work() {
    let dir = scratch("defaults", "quilt");
    let out = parallax_in(&dir, &["render", "--lf", "nelf", "--resolution", "8x8", "--quilt", "go"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--quilt: NELF's views are two 6x6 blocks"), "{}", stderr(&out));
    assert!(!dir.join("out").exists(), "nothing was written");
    let out = parallax_in(&dir, &["render", "--quilt", "huge"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("go (11x6), portrait (8x6), 16in (7x7), 65in (8x9)"), "{}", stderr(&out));
}
