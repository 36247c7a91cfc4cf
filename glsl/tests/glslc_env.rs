//! `GLSLC` pointing at a missing binary: what a build script sees. A test binary of its own:
//! it sets an environment variable, which must not leak into the other tests' process.

use std::path::Path;

use parallax_glsl::GlslError;

#[test]
fn glslc_variable_naming_a_missing_binary_gives_the_install_hint() {
    // SAFETY: this binary has this single test, so no other thread reads the environment.
    unsafe { std::env::set_var("GLSLC", "/nonexistent/parallax-glslc") };
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("parallax-glsl").join("glslc-env");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("empty.comp"), "#version 460\nlayout(local_size_x = 1) in;\nvoid main() {}\n").unwrap();

    let err = parallax_glsl::compile_dir(&dir, &[], &dir).unwrap_err();

    match &err {
        GlslError::MissingCompiler { glslc, .. } => assert_eq!(glslc, "/nonexistent/parallax-glslc"),
        other => panic!("expected GlslError::MissingCompiler, got {other:?}"),
    }
    assert!(err.to_string().contains("install it with `apt-get install glslc`"), "{err}");
}
