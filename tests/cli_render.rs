//! `parallax render` end to end on lavapipe: a small light field of the default scene over 1 and
//! 2 logical devices under every scheme gives bit-identical views (the random numbers depend on
//! pixel, view, frame, sample and bounce, never on the device), with validation on.

mod common;

use common::scratch;

use std::path::Path;
use std::process::Command;

fn render(out: &Path, devices: &str, scheme: &str) {
    let status = Command::new(env!("CARGO_BIN_EXE_parallax"))
        .env("PARALLAX_VALIDATION", "1")
        .args(["render", "--lf", "4x2", "--resolution", "16x12", "--spacing", "0.05", "--spp", "2"])
        .args(["--fake-devices", devices, "--scheme", scheme, "--out-dir"])
        .arg(out)
        .output()
        .unwrap();
    assert!(status.status.success(), "{devices} devices, {scheme}: {}", String::from_utf8_lossy(&status.stderr));
}

#[test]
fn views_are_identical_on_any_number_of_devices_and_schemes() {
    let dir = scratch("render", "devices");
    let reference = dir.join("one");
    render(&reference, "1", "multi-source");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(reference.join("render.json")).unwrap()).unwrap();
    assert_eq!(json["plan"]["views"], 8);
    assert!(reference.join("lightfield.png").is_file());
    for (devices, scheme) in [("2", "multi-source"), ("2", "fine-all"), ("2", "fine-sources")] {
        let other = dir.join(format!("{devices}-{scheme}"));
        render(&other, devices, scheme);
        for v in 0..8 {
            let name = format!("view_{v:03}.exr");
            let a = std::fs::read(reference.join(&name)).unwrap();
            let b = std::fs::read(other.join(&name)).unwrap();
            assert!(a == b, "{name} differs between 1 device and {devices} devices under {scheme}");
        }
    }
}
