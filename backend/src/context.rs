//! Choosing devices: `--gpus N` (N physical devices) or `--fake-devices N` (N logical devices on
//! one physical device).

use std::fmt;
use std::sync::Arc;

use ash::vk;

use crate::device::{Device, DeviceInfo};
use crate::error::{BackendError, Result, VkContext};
use crate::instance::{Instance, Validation, validation_from_env};

/// Which devices to run on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceSelection {
    /// N distinct physical devices (GPUs preferred over CPU implementations).
    Gpus(usize),
    /// N logical devices on the best physical device.
    FakeDevices(usize),
}

impl DeviceSelection {
    /// Number of logical devices this selection yields.
    pub fn count(self) -> usize {
        match self {
            Self::Gpus(n) | Self::FakeDevices(n) => n,
        }
    }
}

/// How to build a [`Context`].
#[derive(Clone, Debug)]
pub struct ContextDesc {
    pub selection: DeviceSelection,
    /// VK_LAYER_KHRONOS_validation level; its messages are collected, never just printed.
    pub validation: Validation,
}

impl ContextDesc {
    /// `selection` with validation as `PARALLAX_VALIDATION` says.
    pub fn from_env(selection: DeviceSelection) -> Self {
        Self { selection, validation: validation_from_env() }
    }
}

/// The instance and the chosen devices; device 0 is the primary (views are gathered there).
pub struct Context {
    pub(crate) instance: Arc<Instance>,
    pub(crate) devices: Vec<Arc<Device>>,
}

impl Context {
    /// Loads Vulkan and creates the devices `desc` asks for.
    pub fn new(desc: &ContextDesc) -> Result<Self> {
        let wanted = desc.selection.count();
        if wanted == 0 {
            return Err(BackendError::ZeroDevices);
        }
        let instance = Instance::new(desc.validation)?;
        let physical = unsafe { instance.raw.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")?;
        if physical.is_empty() {
            return Err(BackendError::NoDevice);
        }
        let ranked = rank_physical_devices(&instance, &physical);
        let need_host_import = wanted > 1;
        let mut devices = Vec::with_capacity(wanted);
        // Real GPUs: the n best-ranked; logical devices: n on the best-ranked one.
        let physical_indices: Vec<usize> = match desc.selection {
            DeviceSelection::Gpus(n) => {
                if ranked.len() < n {
                    return Err(BackendError::NotEnoughGpus { requested: n, available: ranked.len() });
                }
                ranked[..n].to_vec()
            }
            DeviceSelection::FakeDevices(n) => vec![ranked[0]; n],
        };
        for (index, &physical_index) in physical_indices.iter().enumerate() {
            devices.push(Device::new(&instance, physical[physical_index], index, physical_index, need_host_import)?);
        }
        let context = Self { instance, devices };
        context.check_validation()?;
        Ok(context)
    }

    /// The chosen devices, primary first.
    pub fn devices(&self) -> &[Arc<Device>] {
        &self.devices
    }

    /// Name, driver and API version of every chosen device.
    pub fn device_infos(&self) -> Vec<DeviceInfo> {
        self.devices.iter().map(|d| d.info.clone()).collect()
    }

    /// The instance (validation messages live there).
    pub fn instance(&self) -> &Arc<Instance> {
        &self.instance
    }

    /// Fails with [`BackendError::Validation`] if validation reported anything since the
    /// previous check.
    pub fn check_validation(&self) -> Result<()> {
        self.instance.check_validation()
    }

    /// Waits until every device is idle.
    pub fn wait_idle(&self) -> Result<()> {
        self.devices.iter().try_for_each(|d| d.wait_idle())
    }
}

impl fmt::Display for Context {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for d in &self.devices {
            let i = &d.info;
            writeln!(
                f,
                "device {}: {} (physical #{}, {}, driver {} {}, Vulkan {}, calibrated timestamps: {})",
                i.index,
                i.name,
                i.physical_index,
                i.device_type,
                i.driver,
                i.driver_info,
                i.api_version,
                if i.calibrated_timestamps { "yes" } else { "no" }
            )?;
        }
        Ok(())
    }
}

/// Physical devices in order of preference: discrete, integrated, virtual GPUs, then CPU
/// implementations, and those only when no GPU exists (so `--gpus 2` on a machine with two
/// NVIDIA GPUs and Mesa installed never picks llvmpipe).
fn rank_physical_devices(instance: &Instance, physical: &[vk::PhysicalDevice]) -> Vec<usize> {
    let rank = |ty: vk::PhysicalDeviceType| match ty {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 4,
        _ => 3,
    };
    let mut order: Vec<(usize, u32)> = physical
        .iter()
        .enumerate()
        .map(|(i, &pd)| {
            let props = unsafe { instance.raw.get_physical_device_properties(pd) };
            (i, rank(props.device_type))
        })
        .collect();
    order.sort_by_key(|&(i, r)| (r, i));
    let any_gpu = order.iter().any(|&(_, r)| r < 4);
    order.into_iter().filter(|&(_, r)| !any_gpu || r < 4).map(|(i, _)| i).collect()
}
