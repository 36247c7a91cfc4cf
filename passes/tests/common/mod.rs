//! Shared set-up of the lavapipe tests: validation always on (any message fails the test).

#![allow(dead_code)]

use glam::Vec3;
use parallax_backend::{Context, ContextDesc, DeviceSelection, Validation};
use parallax_scene::{Camera, Scene, View};

/// `devices` logical devices on the first Vulkan device (lavapipe in CI), with core
/// validation; synchronisation validation too on one device (see the backend's Known limits).
pub fn context(devices: usize) -> Context {
    let validation = if devices == 1 { Validation::CoreAndSync } else { Validation::Core };
    Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(devices), validation })
        .expect("a Vulkan device (apt-get install mesa-vulkan-drivers) and validation layers")
}

/// `count` views of `scene`'s default camera, each moved sideways by 5 % of the scene's size.
pub fn views(scene: &Scene, count: u32, width: u32, height: u32) -> Vec<View> {
    let base = scene.default_camera();
    let (right, _, _) = base.basis();
    let step = 0.05 * scene.bounds().diagonal();
    (0..count)
        .map(|index| {
            let offset: Vec3 = right * step * index as f32;
            let camera = Camera { eye: base.eye + offset, ..base };
            View { camera, width, height, index }
        })
        .collect()
}
