//! One process-wide lock around creating and destroying Vulkan instances and devices.
//!
//! The loader and the validation layer keep process-global tables keyed by the addresses of
//! dispatchable handles. When one thread destroys a device while another creates one, the new
//! device can be given the freed address before the layer has finished forgetting the old one,
//! and the layer then loses the new device: later calls on it are reported as "Invalid
//! VkDevice" / "Couldn't find VkDevice Object" although the application did nothing wrong
//! (seen once in CI with Debian's layer 1.3.239, lavapipe tests creating and dropping contexts
//! in parallel threads; the same class of race as KhronosGroup/Vulkan-Loader issue 200).
//! Creating and destroying instances and devices is rare and cheap next to a frame, so they
//! simply take turns.

use std::sync::{Mutex, MutexGuard};

static LIFETIMES: Mutex<()> = Mutex::new(());

/// Held while an instance or device (and the messenger bound to an instance) is created or
/// destroyed.
pub(crate) fn hold() -> MutexGuard<'static, ()> {
    LIFETIMES.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
