//! `parallax bench` on lavapipe: a two-cell matrix runs end to end; the cell that cannot run
//! (more devices than views) is reported with its error and the other cell's figures, accuracy
//! against a reference included, are still written to bench.json with its documented fields.
//! A TOML matrix runs each cell once however many slices name it, and a bad file is refused,
//! naming the key, before any cell folder exists.

mod common;

use common::scratch;

use std::process::Command;

fn parallax(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_parallax")).env("PARALLAX_VALIDATION", "1").args(args).output().unwrap()
}

#[test]
fn a_matrix_reports_a_failed_cell_and_writes_the_others() {
    let dir = scratch("bench", "matrix");
    let (reference, out) = (dir.join("ref"), dir.join("bench"));
    let lf = ["--lf", "2x1", "--resolution", "16x12", "--spacing", "0.05"];
    let r = parallax(
        &[&["reference"], &lf[..], &["--spp", "16", "--fake-devices", "1", "--out-dir", reference.to_str().unwrap()]]
            .concat(),
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // A moving camera (asked for: bench cells are still by default) against a still reference:
    // refused after the first cell, naming the settings, before the others run.
    let moving = format!("--scene default {} --motion dolly", lf.join(" "));
    let run = |common: &str| {
        parallax(&[
            "bench",
            "--common",
            common,
            "--pipelines",
            "reproject",
            "--fake-devices",
            "1,3",
            "--frames",
            "2",
            "--warmup",
            "1",
            "--reference",
            reference.to_str().unwrap(),
            "--out-dir",
            out.to_str().unwrap(),
        ])
    };
    let b = run(&moving);
    let stderr = String::from_utf8_lossy(&b.stderr);
    assert_eq!(b.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("still: moving (--motion dolly or animation) vs still")
            && stderr.contains("camera: ")
            && stderr.contains("--allow-mismatch"),
        "{stderr}"
    );
    assert!(!out.join("reproject_multi-source_compact_k1_spp1_dnon_d3").exists(), "no cell ran after the refusal");
    let b = run(&format!("--scene default {}", lf.join(" ")));
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
    let cells = json["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 2);
    let (ok, failed) = (&cells[0], &cells[1]);
    assert_eq!(ok["ok"], true);
    for field in [
        "id",
        "args",
        "frame_ms",
        "views_per_s",
        "stages",
        "busy_fraction",
        "missing_pixels",
        "copy_bytes_per_frame",
        "flip",
        "psnr_db",
    ] {
        assert!(!ok[field].is_null(), "bench.json cells have `{field}`: {ok}");
    }
    assert!(ok["frame_ms"]["mean_ms"].as_f64().unwrap() > 0.0);
    // --common is one unnamed case; without --assignments the cell reports render's default.
    assert!(ok["case"].is_null());
    assert_eq!((ok["assignment"].as_str(), ok["views"].as_u64()), (Some("compact"), Some(2)));
    assert!(ok["flip"].as_f64().unwrap() > 0.0 && ok["flip"].as_f64().unwrap() < 1.0);
    assert_eq!(failed["ok"], false);
    assert!(failed["error"].as_str().unwrap().contains("exceeds the 2 views"), "{failed}");
    let points: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("points.json")).unwrap()).unwrap();
    assert_eq!(points["points"].as_array().unwrap().len(), 1, "a point per cell that ran");
    common::assert_typed_json("bench.json", &json);
    common::assert_typed_json("points.json", &points);
    let md = std::fs::read_to_string(out.join("bench.md")).unwrap();
    assert!(md.contains("failed") && md.contains(ok["id"].as_str().unwrap()));
}

#[test]
fn a_matrix_file_runs_each_cell_once_and_a_bad_one_nothing() {
    let dir = scratch("bench", "toml");
    let out = dir.join("bench");
    let case = "[[case]]\nname = \"tiny\"\nargs = \"--scene default --lf 2x1 --resolution 16x12 --spacing 0.05\"\n";
    // The second slice repeats the first's compact cell.
    let slices = "[[matrix]]\npipelines = [\"reproject\"]\nassignments = [\"round-robin\", \"compact\"]\nfake_devices = true\n\
                  [[matrix]]\npipelines = [\"reproject\"]\nassignments = [\"compact\"]\nfake_devices = true\n";
    let write = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    for (name, text, key) in [
        ("unknown_key.toml", format!("frames = 2\n{case}{slices}spps = [1]\n"), "spps"),
        ("unknown_case.toml", format!("{case}[[matrix]]\ncases = [\"huge\"]\n"), "cases: no [[case]] is named `huge`"),
        // A flag bench sets per cell would make every cell render other than its id says.
        (
            "bench_flag.toml",
            format!("{}{slices}", case.replace("--spacing 0.05", "--spacing 0.05 --no-denoise")),
            "gives --no-denoise, which bench sets per cell",
        ),
    ] {
        let path = write(name, &text);
        let b = parallax(&["bench", "--matrix", path.to_str().unwrap(), "--out-dir", out.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&b.stderr);
        assert!(!b.status.success() && stderr.contains(name) && stderr.contains(key), "{name}: {stderr}");
        assert!(!out.exists(), "{name}: nothing is created before the file is valid");
    }

    let path = write("good.toml", &format!("frames = 2\nwarmup = 1\n{case}{slices}"));
    let b = parallax(&["bench", "--matrix", path.to_str().unwrap(), "--out-dir", out.to_str().unwrap()]);
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
    assert_eq!((json["frames"].as_u64(), json["warmup"].as_u64()), (Some(2), Some(1)));
    let cells = json["cells"].as_array().unwrap();
    let ids: Vec<&str> = cells.iter().map(|c| c["id"].as_str().unwrap()).collect();
    assert_eq!(
        ids,
        [
            "tiny/reproject_multi-source_round-robin_k1_spp1_dnon_d1",
            "tiny/reproject_multi-source_compact_k1_spp1_dnon_d1"
        ],
        "the repeated cell runs once"
    );
    for (c, assignment) in cells.iter().zip(["round-robin", "compact"]) {
        assert_eq!(c["ok"], true, "{c}");
        assert_eq!((c["case"].as_str(), c["assignment"].as_str()), (Some("tiny"), Some(assignment)));
        assert_eq!((c["pipeline"].as_str(), c["scheme"].as_str()), (Some("reproject"), Some("multi-source")));
        assert_eq!((c["sources_per_set"].as_u64(), c["spp"].as_u64()), (Some(1), Some(1)));
        assert_eq!(
            (c["denoise"].as_bool(), c["devices"].as_u64(), c["views"].as_u64()),
            (Some(true), Some(1), Some(2))
        );
        assert!(c["hole_fill_ms"].as_f64().unwrap().is_sign_positive(), "{c}");
        assert!(out.join(c["id"].as_str().unwrap()).join("render.json").is_file());
    }
    let points: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("points.json")).unwrap()).unwrap();
    let points = points["points"].as_array().unwrap();
    assert_eq!(points.len(), 2);
    for field in ["case", "assignment", "views", "devices", "missing", "hole_fill_ms"] {
        assert!(!points[0][field].is_null(), "points have `{field}`: {}", points[0]);
    }
    let md = std::fs::read_to_string(out.join("bench.md")).unwrap();
    assert!(md.contains("| tiny |") && md.contains("Per stage, ms per frame") && md.contains("| hole_fill |"), "{md}");
    assert!(md.contains("| multi-source, round-robin |") && md.contains("## Scaling over devices"), "{md}");
}

/// A cut matrix goes on: each cell is reported on stderr as it ends (stderr is a pipe here, so
/// no bar is drawn), and `--resume` keeps the cells bench.json has, runs the others, and
/// refuses a bench.json of other frames.
#[test]
fn a_resumed_matrix_keeps_the_cells_it_has() {
    let dir = scratch("bench", "resume");
    let out = dir.join("bench");
    let run = |spp: &str, frames: &str, resume: bool| {
        let mut args = vec![
            "bench",
            "--common",
            "--scene default --lf 2x1 --resolution 16x12 --spacing 0.05",
            "--pipelines",
            "path-trace",
            "--spp",
            spp,
            "--frames",
            frames,
            "--warmup",
            "0",
            "--out-dir",
            out.to_str().unwrap(),
        ];
        if resume {
            args.push("--resume");
        }
        parallax(&args)
    };
    let cells = |out: &std::path::Path| -> Vec<serde_json::Value> {
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
        json["cells"].as_array().unwrap().clone()
    };
    let first = run("1", "1", false);
    let stderr = String::from_utf8_lossy(&first.stderr);
    assert!(first.status.success(), "{stderr}");
    assert!(stderr.contains("cell 1/1 path-trace_multi-source_k1_spp1_dnon_d1: "), "{stderr}");
    let before = cells(&out);

    let second = run("1,2", "1", true);
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert!(second.status.success(), "{stderr}");
    assert!(stderr.contains("cell 1/2 path-trace_multi-source_k1_spp1_dnon_d1 (kept from bench.json)"), "{stderr}");
    assert!(stderr.contains("cell 2/2 path-trace_multi-source_k1_spp2_dnon_d1: ") && !stderr.contains("2 (kept"));
    let after = cells(&out);
    assert_eq!(after.len(), 2);
    assert_eq!(after[0], before[0], "the kept cell is the first run's, not a new measurement");
    assert_eq!(after[1]["ok"], true);

    let refused = run("1,2", "2", true);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("frames = 1, this run asks 2"), "{stderr}");
    assert_eq!(cells(&out), after, "a refused resume changes nothing");
}
