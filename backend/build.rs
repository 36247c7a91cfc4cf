//! Compiles every `shaders/*.{comp,vert,frag}` (GLSL 460, `#include` from `shaders/include`) to
//! SPIR-V with `glslc` and writes `shaders.rs` into OUT_DIR, which embeds them by name.
//!
//! glslc (Debian package `glslc`) is used instead of the shaderc crate: Debian's libshaderc does
//! not link and building it from source takes over ten minutes (see shared/CRATES.md).

use std::env;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let manifest = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let shader_dir = manifest.join("..").join("shaders");
    let include_dir = shader_dir.join("include");
    let out = PathBuf::from(env::var("OUT_DIR").expect("set by cargo"));
    let glslc = env::var("GLSLC").unwrap_or_else(|_| "glslc".into());
    println!("cargo:rerun-if-env-changed=GLSLC");
    println!("cargo:rerun-if-changed={}", shader_dir.display());
    println!("cargo:rerun-if-changed={}", include_dir.display());

    let mut sources: Vec<PathBuf> = std::fs::read_dir(&shader_dir)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", shader_dir.display()))
        .map(|entry| entry.expect("readable directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "comp" || e == "vert" || e == "frag"))
        .collect();
    sources.sort();

    let mut table = String::from("/// Embedded SPIR-V, by shader name (file stem).\n");
    table.push_str("pub const EMBEDDED: &[(&str, &[u8])] = &[\n");
    for src in &sources {
        let file = src.file_name().and_then(|s| s.to_str()).expect("UTF-8 shader file name");
        // Compute shaders are named by stem (`fill`), graphics stages by file name
        // (`raster_demo.vert`), so a pass's vertex and fragment shaders can share a stem.
        let stem = file.strip_suffix(".comp").unwrap_or(file);
        let spv = out.join(format!("{file}.spv"));
        let dep = out.join(format!("{file}.d"));
        compile(&glslc, src, &include_dir, &spv, &dep);
        for dependency in read_depfile(&dep) {
            println!("cargo:rerun-if-changed={dependency}");
        }
        writeln!(table, "    ({stem:?}, include_bytes!({:?})),", spv.display().to_string()).expect("write to String");
    }
    table.push_str("];\n");
    std::fs::write(out.join("shaders.rs"), table).expect("write shaders.rs");
}

fn compile(glslc: &str, src: &Path, include_dir: &Path, spv: &Path, dep: &Path) {
    let output = Command::new(glslc)
        .args(["--target-env=vulkan1.3", "-O", "-g", "-Werror"])
        .arg(format!("-I{}", include_dir.display()))
        .args(["-MD", "-MF"])
        .arg(dep)
        .arg(src)
        .arg("-o")
        .arg(spv)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run `{glslc}` ({e}): the shader compiler is missing; install it with \
                 `apt-get install glslc` (or point the GLSLC environment variable at one)"
            )
        });
    if !output.status.success() {
        panic!("glslc failed on {}:\n{}", src.display(), String::from_utf8_lossy(&output.stderr));
    }
}

/// Files named in a make-style depfile (`out.spv: a.comp include/b.glsl`).
fn read_depfile(dep: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(dep).unwrap_or_default();
    text.split_once(':')
        .map(|(_, deps)| deps.split_whitespace().filter(|d| *d != "\\").map(str::to_string).collect())
        .unwrap_or_default()
}
