//! Without any Vulkan driver the backend names the package to install. A test binary of its
//! own: it points the loader at a driver list that does not exist, which must not leak into the
//! other tests' process.

use parallax_backend::{BackendError, Context, ContextDesc, DeviceSelection, Validation};

#[test]
fn no_driver_is_a_clear_error_naming_the_package() {
    // SAFETY: this binary has this single test, so no other thread reads the environment.
    unsafe {
        std::env::set_var("VK_ICD_FILENAMES", "/nonexistent/parallax-no-icd.json");
        std::env::set_var("VK_DRIVER_FILES", "/nonexistent/parallax-no-icd.json");
    }
    let err = Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(1), validation: Validation::Off })
        .err()
        .expect("no driver, no context");
    assert!(matches!(err, BackendError::NoDevice), "{err:?}");
    assert!(err.to_string().contains("mesa-vulkan-drivers"), "{err}");
}
