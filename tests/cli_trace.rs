//! `parallax trace` on the GPU (lavapipe, two logical devices, validation on) writes the same
//! kinds of output as `--cpu`, and `parallax bench-rays` measures and writes its JSON.

mod common;

use common::scratch;

use std::process::Command;

fn parallax(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_parallax")).env("PARALLAX_VALIDATION", "1").args(args).output().unwrap()
}

#[test]
fn gpu_trace_writes_exr_and_png_like_the_cpu() {
    let dir = scratch("trace", "trace");
    for (name, device) in [("gpu", "--fake-devices=2"), ("cpu", "--cpu")] {
        let exr = dir.join(format!("{name}.exr"));
        let png = dir.join(format!("{name}.png"));
        let out = parallax(&[
            "trace",
            "--resolution",
            "20x12",
            "--spp",
            "2",
            "--layers",
            device,
            "--out",
            exr.to_str().unwrap(),
            "--png",
            png.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(std::fs::metadata(&exr).unwrap().len() > 0 && std::fs::metadata(&png).unwrap().len() > 0);
    }
}

#[test]
fn bench_rays_reports_the_three_batches() {
    let dir = scratch("trace", "bench-rays");
    let json = dir.join("rays.json");
    let out = parallax(&[
        "bench-rays",
        "--fake-devices",
        "1",
        "--resolution",
        "32x32",
        "--repeats",
        "2",
        "--schedule",
        "per-ray,persistent:16:8",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(report["triangles"], 1028);
    let schedules = report["schedules"].as_array().unwrap();
    assert_eq!(schedules.len(), 2, "{report}");
    for (entry, name) in schedules.iter().zip(["per-ray", "persistent:16:8"]) {
        assert_eq!(entry["schedule"], name);
        assert_eq!(entry["primary"]["rays"], 32 * 32);
        for batch in ["primary", "diffuse_bounce", "diffuse_bounce_any_hit"] {
            assert!(entry[batch]["rays_per_s"].as_f64().unwrap() > 0.0, "{batch}: {report}");
        }
    }
}
