//! The GLSL that mirrors this crate (CWBVH traversal, scene layout, path tracer) must compile: glslc is the
//! project's shader compiler (apt package `glslc`, see shared/CRATES.md).

use std::path::Path;
use std::process::Command;

fn compile(entry: &str, defines: &[&str]) {
    let shaders = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders");
    let out = std::env::temp_dir().join(format!("parallax-scene-{}-{entry}.spv", std::process::id()));
    let glslc = std::env::var("GLSLC").unwrap_or_else(|_| "glslc".into());
    let result = Command::new(&glslc)
        .args(["-fshader-stage=compute", "--target-env=vulkan1.3", "-O", "-Werror"])
        .args(defines.iter().map(|d| format!("-D{d}")))
        .arg(shaders.join(entry))
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {glslc} (apt-get install glslc): {e}"));
    assert!(result.status.success(), "glslc failed on {entry}:\n{}", String::from_utf8_lossy(&result.stderr));
    let spv = std::fs::read(&out).unwrap();
    assert_eq!(&spv[..4], &[0x03, 0x02, 0x23, 0x07], "SPIR-V magic");
}

#[test]
fn path_tracer_compiles_with_and_without_textures() {
    compile("pt_trace.glsl", &[]);
    compile("pt_trace.glsl", &["PT_SCENE_NO_TEXTURES"]);
}

#[test]
fn bvh_raycast_compiles_with_and_without_textures() {
    compile("bvh_raycast.glsl", &[]);
    compile("bvh_raycast.glsl", &["PT_SCENE_NO_TEXTURES"]);
}
