//! `parallax bench` on lavapipe: a two-cell matrix runs end to end; the cell that cannot run
//! (more devices than views) is reported with its error and the other cell's figures, accuracy
//! against a reference included, are still written to bench.json with its documented fields.

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
    let common = format!("--scene default {}", lf.join(" "));
    let b = parallax(&[
        "bench",
        "--common",
        &common,
        "--pipelines",
        "reproject",
        "--devices",
        "1,3",
        "--fake-devices",
        "--frames",
        "2",
        "--warmup",
        "1",
        "--reference",
        reference.to_str().unwrap(),
        "--out-dir",
        out.to_str().unwrap(),
    ]);
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
    assert!(ok["flip"].as_f64().unwrap() > 0.0 && ok["flip"].as_f64().unwrap() < 1.0);
    assert_eq!(failed["ok"], false);
    assert!(failed["error"].as_str().unwrap().contains("exceeds the 2 views"), "{failed}");
    let points: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("points.json")).unwrap()).unwrap();
    assert_eq!(points["points"].as_array().unwrap().len(), 1, "a point per cell that ran");
    let md = std::fs::read_to_string(out.join("bench.md")).unwrap();
    assert!(md.contains("failed") && md.contains(ok["id"].as_str().unwrap()));
}
