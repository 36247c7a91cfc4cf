//! The Vulkan instance: loader found at run time (`Entry::load`), optional Khronos validation
//! with a debug-utils messenger that collects every warning and error so that a run or a test
//! can fail on them instead of scrolling them past on stderr.

use std::ffi::{CStr, c_void};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

use ash::vk;

use crate::error::{BackendError, Result, VkContext};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Validation messages collected by the debug messenger, shared with its callback.
pub type MessageSink = Arc<Mutex<Vec<String>>>;

/// Owns the loader, the instance and the debug messenger. Devices keep an `Arc` to it, so it
/// is destroyed only after the last device.
pub struct Instance {
    pub(crate) entry: ash::Entry,
    pub(crate) raw: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    /// Kept alive for the messenger's user-data pointer; `None` without validation.
    messages: Option<Box<MessageSink>>,
}

/// How much the Khronos validation layer checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Validation {
    Off,
    /// Core (API usage) validation.
    Core,
    /// Core plus synchronisation validation (hazards between commands of one device).
    ///
    /// The layer Debian ships (1.3.239) reports `UNASSIGNED-VkSemaphore-state-timeout` ("most
    /// likely a validation bug", after a 10 s internal stall) when synchronisation validation
    /// sees host-signalled timeline semaphores waited on by another device's submissions, which
    /// is exactly the cross-device relay; so multi-device runs use [`Validation::Core`]. (The
    /// cause is the layer's lock around its blocking record of vkWaitSemaphores: see
    /// `HOST_WAIT_TIMEOUT_ID` below; the sync validation object always takes that lock, core
    /// validation only rarely meets it, on a loaded machine.)
    CoreAndSync,
}

/// Validation as asked for through the environment: `PARALLAX_VALIDATION=1` → core,
/// `PARALLAX_VALIDATION=sync` → core + synchronisation, unset/empty/`0` → off.
pub fn validation_from_env() -> Validation {
    match std::env::var("PARALLAX_VALIDATION").as_deref() {
        Ok("sync") => Validation::CoreAndSync,
        Ok("") | Ok("0") | Err(_) => Validation::Off,
        Ok(_) => Validation::Core,
    }
}

impl Instance {
    /// Loads the Vulkan loader and creates an instance, with the Khronos validation layer and a
    /// collecting messenger unless `validation` is off.
    pub fn new(validation: Validation) -> Result<Arc<Self>> {
        let entry = unsafe { ash::Entry::load() }.map_err(|e| BackendError::LoaderMissing(e.to_string()))?;

        let mut layers = Vec::new();
        let mut extensions = Vec::new();
        let enabled = validation != Validation::Off;
        if enabled {
            let available =
                unsafe { entry.enumerate_instance_layer_properties() }.vk("vkEnumerateInstanceLayerProperties")?;
            let Some(layer) = available.iter().find(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER)) else {
                return Err(BackendError::ValidationLayerMissing);
            };
            LAYER_SPEC_VERSION.store(layer.spec_version, Ordering::Relaxed);
            layers.push(VALIDATION_LAYER.as_ptr());
            extensions.push(ash::ext::debug_utils::NAME.as_ptr());
        }

        let app = vk::ApplicationInfo::default()
            .application_name(c"parallax")
            .engine_name(c"parallax")
            .api_version(vk::API_VERSION_1_3);
        // Synchronisation validation checks the barriers the executor records between ops.
        let enabled_features = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut validation_features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled_features);
        let mut info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&extensions);
        if validation == Validation::CoreAndSync {
            info = info.push_next(&mut validation_features);
        }
        let _turn = crate::lifetime_lock::hold();
        let raw = unsafe { entry.create_instance(&info, None) }.map_err(|result| match result {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => BackendError::NoDevice,
            result => BackendError::Vk { call: "vkCreateInstance", result },
        })?;

        let mut instance = Self { entry, raw, debug: None, messages: None };
        if enabled {
            instance.install_messenger()?;
        }
        Ok(Arc::new(instance))
    }

    fn install_messenger(&mut self) -> Result<()> {
        let sink: Box<MessageSink> = Box::new(Arc::new(Mutex::new(Vec::new())));
        let user_data = (&*sink as *const MessageSink).cast_mut().cast::<c_void>();
        let loader = ash::ext::debug_utils::Instance::new(&self.entry, &self.raw);
        let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::WARNING | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(collect_message))
            .user_data(user_data);
        let messenger =
            unsafe { loader.create_debug_utils_messenger(&info, None) }.vk("vkCreateDebugUtilsMessengerEXT")?;
        self.debug = Some((loader, messenger));
        self.messages = Some(sink);
        Ok(())
    }

    /// True when the validation layer and the collecting messenger are active.
    pub fn validation_enabled(&self) -> bool {
        self.messages.is_some()
    }

    /// Removes and returns the validation messages collected so far.
    pub fn take_validation_messages(&self) -> Vec<String> {
        match &self.messages {
            Some(sink) => std::mem::take(&mut *sink.lock().unwrap_or_else(|p| p.into_inner())),
            None => Vec::new(),
        }
    }

    /// Fails with [`BackendError::Validation`] if any message was collected since the last call.
    pub fn check_validation(&self) -> Result<()> {
        let messages = self.take_validation_messages();
        if messages.is_empty() { Ok(()) } else { Err(BackendError::Validation { messages }) }
    }

    /// The raw `ash` instance (for code that needs instance-level functions).
    pub fn raw(&self) -> &ash::Instance {
        &self.raw
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        let _turn = crate::lifetime_lock::hold();
        unsafe {
            if let Some((loader, messenger)) = self.debug.take() {
                loader.destroy_debug_utils_messenger(messenger, None);
            }
            self.raw.destroy_instance(None);
        }
    }
}

/// Messages that are not faults. Every image lives in `GENERAL` layout on purpose (storage
/// writes, storage reads and copies all happen there, so passes never track layouts); the layer's
/// performance hint that copies would prefer TRANSFER_*_OPTIMAL says nothing about correctness.
const IGNORED_MESSAGE_IDS: &[&CStr] = &[c"UNASSIGNED-CoreValidation-DrawState-InvalidImageLayout"];

/// The layer's report of its own deadlock, before 1.3.261. Its vkWaitSemaphores post-record
/// waits (10 s at most) for the semaphore's timeline to be retired while holding the validation
/// object's lock, and retiring a submission that waited on a host-signalled semaphore needs the
/// vkSignalSemaphore post-record of the thread that signalled it, which needs that same lock.
/// The relay signals from its own thread, so when that thread is preempted between the driver's
/// signal and the layer's record (a loaded 2-core machine), the main thread's frame wait returns
/// and both stall until the layer gives up with this message. Fixed upstream by releasing the
/// lock around the blocking wait (KhronosGroup/Vulkan-ValidationLayers 680f84dc3, issue #4968,
/// first in 1.3.261); Debian 12 ships 1.3.239. Ignored there only, and only this id: newer
/// layers name their own internal errors differently, and any real fault is still reported.
const HOST_WAIT_TIMEOUT_ID: &CStr = c"UNASSIGNED-VkSemaphore-state-timeout";
const LAYER_WITH_HOST_WAIT_FIX: u32 = vk::make_api_version(0, 1, 3, 261);

/// The validation layer's spec version, read when the instance is created (0: not known).
static LAYER_SPEC_VERSION: AtomicU32 = AtomicU32::new(0);

/// Whether message `id` of a layer of `layer_version` says nothing about the program.
fn is_ignored(id: &CStr, layer_version: u32) -> bool {
    IGNORED_MESSAGE_IDS.contains(&id)
        || (id == HOST_WAIT_TIMEOUT_ID && layer_version != 0 && layer_version < LAYER_WITH_HOST_WAIT_FIX)
}

/// Debug-utils callback: records the message; never aborts the call (returns FALSE).
unsafe extern "system" fn collect_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    let text = if data.is_null() {
        String::from("<no message data>")
    } else {
        let data = unsafe { &*data };
        let id = unsafe { data.message_id_name_as_c_str() };
        if id.is_some_and(|id| is_ignored(id, LAYER_SPEC_VERSION.load(Ordering::Relaxed))) {
            return vk::FALSE;
        }
        let message = unsafe { data.message_as_c_str() }.map(|m| m.to_string_lossy().into_owned()).unwrap_or_default();
        format!("[{severity:?} {types:?}] {message}")
    };
    if !user.is_null() {
        let sink = unsafe { &*(user as *const MessageSink) };
        sink.lock().unwrap_or_else(|p| p.into_inner()).push(text);
    }
    vk::FALSE
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The layer's own timeout is ignored only before the version that fixed it, and nothing
    /// else with it.
    #[test]
    fn only_the_old_layers_host_wait_timeout_is_ignored() {
        let debian = vk::make_api_version(0, 1, 3, 239);
        let fixed = vk::make_api_version(0, 1, 3, 261);
        assert!(is_ignored(c"UNASSIGNED-VkSemaphore-state-timeout", debian));
        assert!(!is_ignored(c"UNASSIGNED-VkSemaphore-state-timeout", fixed));
        assert!(!is_ignored(c"UNASSIGNED-VkSemaphore-state-timeout", 0), "unknown version: reported");
        assert!(!is_ignored(c"INTERNAL-ERROR-VkSemaphore-state-timeout", debian));
        assert!(!is_ignored(c"UNASSIGNED-VkFence-state-timeout", debian));
        assert!(!is_ignored(c"VUID-vkCmdDispatch-None-02699", debian));
        assert!(is_ignored(c"UNASSIGNED-CoreValidation-DrawState-InvalidImageLayout", fixed));
    }
}
