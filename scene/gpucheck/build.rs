//! Compiles ../../shaders/bvh_raycast.glsl and pt_trace.glsl, with and without textures, with
//! glslc into OUT_DIR.

use std::path::PathBuf;
use std::process::Command;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let shaders = manifest.join("../../shaders");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    let glslc = std::env::var("GLSLC").unwrap_or_else(|_| "glslc".into());
    let variants = [
        ("bvh_raycast.glsl", "raycast.spv", true),
        ("pt_trace.glsl", "pt_trace.spv", true),
        ("bvh_raycast.glsl", "raycast_tex.spv", false),
        ("pt_trace.glsl", "pt_trace_tex.spv", false),
    ];
    for (src, spv, untextured) in variants {
        let define = if untextured { "-DPT_SCENE_NO_TEXTURES" } else { "-DPT_SCENE_TEXTURED" };
        let result = Command::new(&glslc)
            .args(["-fshader-stage=compute", "--target-env=vulkan1.3", "-O", "-Werror", define])
            .arg(shaders.join(src))
            .arg("-o")
            .arg(out_dir.join(spv))
            .output()
            .unwrap_or_else(|e| panic!("cannot run {glslc} (apt-get install glslc): {e}"));
        assert!(result.status.success(), "glslc on {src}: {}", String::from_utf8_lossy(&result.stderr));
    }
    println!("cargo:rerun-if-changed={}", shaders.display());
    for f in [
        "bvh_raycast.glsl",
        "bvh_traverse.glsl",
        "bvh_types.glsl",
        "pt_scene.glsl",
        "pt_trace.glsl",
        "pt_rng.glsl",
        "pt_bsdf.glsl",
        "pt_lights.glsl",
    ] {
        println!("cargo:rerun-if-changed={}", shaders.join(f).display());
    }
}
