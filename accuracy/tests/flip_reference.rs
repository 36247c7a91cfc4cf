//! Our FLIP (nv-flip 0.1.2, NVIDIA's C++ FLIP) against NVIDIA's reference implementation on a
//! fixed, committed pair of images: tests/data/flip/{reference,test}.png (66×50, 8-bit sRGB;
//! contact sheets of a 2×2 light field of the default scene at 64 and 16 spp).
//!
//! The expected value was computed with NVIDIA's official Python package, flip-evaluator 1.7
//! (PyPI), on 2026-12-01:
//! `flip_evaluator.evaluate("reference.png", "test.png", "LDR", applyMagma=False)` → mean
//! 0.1395563930273056 with its defaults (ppd 67.02064514160156).

use std::path::Path;

use parallax_accuracy::flip::{flip_rgb8, pixels_per_degree};

const FLIP_EVALUATOR_1_7_MEAN: f64 = 0.1395563930273056;

fn load(name: &str) -> (Vec<u8>, usize, usize) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/flip").join(name);
    let img = image::open(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
    let (w, h) = img.dimensions();
    (img.into_raw(), w as usize, h as usize)
}

#[test]
fn flip_matches_nvidia_flip_evaluator() {
    let (reference, w, h) = load("reference.png");
    let (test, tw, th) = load("test.png");
    assert_eq!((w, h), (tw, th));
    assert!((pixels_per_degree() as f64 - 67.02064514160156).abs() < 1e-4, "{}", pixels_per_degree());
    let ours = flip_rgb8(&reference, &test, w, h);
    assert!(
        (ours - FLIP_EVALUATOR_1_7_MEAN).abs() < 1e-3,
        "FLIP {ours} vs flip-evaluator 1.7's {FLIP_EVALUATOR_1_7_MEAN}"
    );
    eprintln!("FLIP {ours:.10} (nv-flip 0.1.2), flip-evaluator 1.7: {FLIP_EVALUATOR_1_7_MEAN:.10}");
    assert_eq!(flip_rgb8(&reference, &reference, w, h), 0.0);
}
